//! Every GSD module of this card has a DPM telegram of its size (moved from `pbcard_dpm`'s
//! tests: it needs `card::MODULES`).

use crate::card;
use crate::dpm::Telegram;

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
