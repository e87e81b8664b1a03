//! The DPM with this card's configuration (moved from `pbcard_dpm`'s tests: they need
//! `card::MODULES` and `card::IDENTITY`): every GSD module has a DPM telegram of its size, and
//! the image's IDENT block carries the card's ident number and this crate's version.

#[cfg_attr(feature = "bench", allow(unused_imports))]
use crate::card;
#[cfg_attr(feature = "bench", allow(unused_imports))]
use crate::dpm::Telegram;
use crate::dpm::{Dpm, CARD_TYPE};

#[test]
fn the_card_identity_names_its_ident_number_and_version() {
    let id = Dpm::with_identity(&card::IDENTITY).identity();
    assert_eq!((id.card_type, id.ident_number, id.serial), (CARD_TYPE, card::IDENT_NUMBER, 0));
    let v = |s: &str| s.parse::<u8>().unwrap();
    let version =
        [v(env!("CARGO_PKG_VERSION_MAJOR")), v(env!("CARGO_PKG_VERSION_MINOR")), v(env!("CARGO_PKG_VERSION_PATCH"))];
    assert_eq!(id.firmware, version, "pbcard's Cargo.toml version");
}

#[cfg(not(feature = "bench"))] // the bench-only modules are no GSD telegram
#[test]
fn every_gsd_module_has_a_telegram_of_its_size() {
    for m in card::MODULES {
        let t = Telegram::of_module(m).unwrap_or_else(|| panic!("{} has no telegram", m.name));
        assert_eq!(t.input_bytes(), m.inputs as usize, "{}", m.name);
        assert_eq!(t.output_bytes(), m.outputs as usize, "{}", m.name);
        assert_eq!(Telegram::from_code(t.code()), t);
    }
    assert_eq!(Telegram::from_code(0), Telegram::None);
    assert_eq!(Telegram::Standard(1).code(), 1);
    assert_eq!(Telegram::Ppo(4).code(), 0x8004);
}
