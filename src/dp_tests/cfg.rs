//! Chk_Cfg (`dp::cfg`) against this card's module table and Chk_Cfg policy.

use crate::card;
use crate::dp::cfg::*;

/// The card's module table.
fn check(cfg: &[u8]) -> Result<&'static Module, CfgError> {
    crate::dp::cfg::check(cfg, card::MODULES)
}

fn splits_into_modules(cfg: &[u8]) -> bool {
    crate::dp::cfg::splits_into_modules(cfg, card::MODULES)
}

/// [`check`], then the card's policy with `operate_mode` in its User_Prm_Data.
fn check_for_mode(cfg: &[u8], operate_mode: u8) -> Result<&'static Module, CfgError> {
    let m = check(cfg)?;
    let mut user = card::USER_PRM_DEFAULTS;
    user[card::PRM_OPERATE_MODE.offset] = operate_mode;
    card::SLAVE.cfg_policy.check_cfg(m, &user)?;
    Ok(m)
}

#[test]
fn module_table_is_consistent() {
    for m in card::MODULES {
        let io = io_lengths(m.cfg).unwrap();
        assert_eq!((io.inputs, io.outputs), (m.inputs as usize, m.outputs as usize), "{}", m.name);
        assert_eq!(check(m.cfg), Ok(m));
    }
}

#[test]
fn reference_examples() {
    assert_eq!(io_lengths(&[0xF1]), Ok(IoLengths { inputs: 4, outputs: 4 }));
    assert_eq!(io_lengths(&[0xC0, 0xC1, 0xC5]), Ok(IoLengths { inputs: 12, outputs: 4 }));
    assert_eq!(io_lengths(&[0x10, 0x20]), Ok(IoLengths { inputs: 1, outputs: 1 }));
    assert_eq!(io_lengths(&[0xC3, 0xC1]), Err(CfgError::Malformed));
    assert_eq!(io_lengths(&[]), Err(CfgError::Malformed));
    assert_eq!(check(&[0xF2]), Err(CfgError::NoSuchModule));
}

#[test]
fn no_module_is_another_or_a_concatenation() {
    for (i, a) in card::MODULES.iter().enumerate() {
        for b in &card::MODULES[i + 1..] {
            assert!(!a.cfg.starts_with(b.cfg) && !b.cfg.starts_with(a.cfg), "{} / {}", a.name, b.name);
        }
        // A module's bytes are never read as two modules.
        assert!(!splits_into_modules(a.cfg), "{}", a.name);
    }
}

// The bench build's 244-byte module with any other is refused for its length first (a
// different error), so these two hold for the GSD's modules.
#[cfg(not(feature = "bench"))]
#[test]
fn one_drive_module_only() {
    let st1 = card::MODULES[0];
    for m in card::MODULES {
        let two = [st1.cfg, m.cfg].concat();
        assert_eq!(check(&two), Err(CfgError::MoreThanOneDriveModule), "ST1 + {}", m.name);
        let three = [m.cfg, m.cfg, st1.cfg].concat();
        if io_lengths(&three).is_ok() {
            assert_eq!(check(&three), Err(CfgError::MoreThanOneDriveModule), "{} twice + ST1", m.name);
        }
    }
    // PPO 1 = F3 F1 is one module, not "PKW" + PPO 3.
    assert_eq!(check(&[0xF3, 0xF1]).map(|m| m.reference), Ok(101));
    // A module plus an unknown identifier is no module at all.
    assert_eq!(check(&[0xF1, 0xF2]), Err(CfgError::NoSuchModule));
    assert_eq!(check(&[]), Err(CfgError::Malformed));
}

#[test]
fn st20_only_in_profidrive_mode() {
    let st20 = card::MODULES.iter().find(|m| m.reference == 20).unwrap();
    for mode in 0..=3 {
        let want = if mode >= 2 { Err(CfgError::NotAllowedInOperateMode) } else { Ok(st20) };
        assert_eq!(check_for_mode(st20.cfg, mode), want, "mode {mode}");
        for m in card::MODULES.iter().filter(|m| m.reference != 20) {
            assert_eq!(check_for_mode(m.cfg, mode), Ok(m), "{} in mode {mode}", m.name);
        }
    }
}

proptest::proptest! {
    #[test]
    fn never_panics(bytes in proptest::collection::vec(proptest::num::u8::ANY, 0..260)) {
        let _ = check(&bytes);
        for mode in 0..=4 {
            let _ = check_for_mode(&bytes, mode);
        }
    }

    #[cfg(not(feature = "bench"))]
    #[test]
    fn accepted_bytes_are_exactly_one_module(i in 0..card::MODULES.len(), j in 0..card::MODULES.len()) {
        let m = &card::MODULES[i];
        proptest::prop_assert_eq!(check(m.cfg), Ok(m));
        let two = [m.cfg, card::MODULES[j].cfg].concat();
        proptest::prop_assert_eq!(check(&two), Err(CfgError::MoreThanOneDriveModule));
    }
}
