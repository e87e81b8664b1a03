//! The telegram layouts of this card's GSD modules (`pbcard::card::MODULES`), OPTE3/E5 Tables
//! 17 and 37, CFW500 / CFW-11 and INVT word lists (moved from `pbcard_profile::profile::telegram`:
//! they need the card's configuration and the DPM's capacity, issue 13 item 4).

use crate::card;
use crate::profile::selection::Telegram;
use crate::profile::telegram::*;

fn layout(reference: u16) -> Layout {
    let m = card::MODULES.iter().find(|m| m.reference == reference).unwrap();
    Layout::of(Telegram::of_module(m).unwrap()).unwrap()
}

#[cfg(not(feature = "bench"))]
#[test]
fn every_module_has_a_layout_of_its_size() {
    for m in card::MODULES {
        let t = Telegram::of_module(m).unwrap_or_else(|| panic!("{}", m.name));
        let l = Layout::of(t).unwrap();
        assert_eq!(l.input_bytes(), m.inputs as usize, "{}", m.name);
        assert_eq!(l.output_bytes(), m.outputs as usize, "{}", m.name);
        assert!(l.pzd_in <= PZD_SIGNALS && l.programmable_in() <= MAX_PROGRAMMABLE, "{}", m.name);
        assert_eq!(Telegram::from_code(t.code()), t, "{}", m.name);
        // Every word is described, none beyond the image.
        for i in 0..l.pkw + l.pzd_out {
            assert!(l.output_word(i).is_some(), "{} out {i}", m.name);
        }
        for i in 0..l.pkw + l.pzd_in {
            assert!(l.input_word(i).is_some(), "{} in {i}", m.name);
        }
        assert_eq!(l.output_word(l.pkw + l.pzd_out), None);
        assert_eq!(l.input_word(l.pkw + l.pzd_in), None);
    }
}

#[test]
fn st20_words_as_opte3_table_17() {
    let l = layout(20);
    assert_eq!((l.pkw, l.pzd_out, l.pzd_in), (0, 2, 6));
    let inw: Vec<_> = (0..6).map(|i| l.input_word(i).unwrap()).collect();
    // OPTE3/E5 Table 17: ZSW1, NIST_A, IAIST_GLATT, ITIST_GLATT, PIST_GLATT, MELD_NAMUR.
    let st20 =
        [Word::Status, Word::MainActual, Word::OutputCurrent, Word::ActiveCurrent, Word::ActivePower, Word::MeldNamur];
    assert_eq!(inw, st20);
    assert_eq!(l.profile(DataProfile::Manufacturer), ProfileFamily::Profidrive41);
    let f = l.default_profile();
    assert_eq!(&l.setpoint_signals(f)[..3], &[1, 5, 0]);
    assert_eq!(&l.actual_signals(f)[..7], &[2, 57, 51, 52, 54, 58, 0]);
}

#[test]
fn st1_and_vacon_signals_as_opte3_table_37() {
    let f = ProfileFamily::Profidrive41;
    assert_eq!(&layout(1).setpoint_signals(f)[..3], &[1, 5, 0]);
    assert_eq!(&layout(1).actual_signals(f)[..3], &[2, 6, 0]);
    let l = layout(1139);
    assert_eq!(l.programmable_out(), 16);
    let s = l.setpoint_signals(f);
    assert_eq!(&s[..4], &[1, 5, 110, 111]);
    assert_eq!(&s[9..12], &[117, 148, 149]);
    assert_eq!(s[17], 155);
    let a = l.actual_signals(f);
    assert_eq!(&a[..4], &[2, 6, 100, 101]);
    assert_eq!(&a[9..11], &[107, 140]);
    assert_eq!(a[17], 147);
    assert_eq!(layout(1100).actual_signals(f)[6], 0);
}

#[test]
fn ppo_weg_and_invt() {
    let ppo2 = layout(102);
    assert_eq!(ppo2.output_word(0), Some(Word::Pkw(0)));
    assert_eq!(ppo2.output_word(4), Some(Word::Control));
    assert_eq!(ppo2.input_word(5), Some(Word::MainActual));
    assert_eq!(ppo2.input_word(6), Some(Word::Programmable(1)));
    assert_eq!(ppo2.default_profile(), ProfileFamily::Profidrive20);
    let weg = layout(2105);
    assert_eq!((weg.pzd_out, weg.programmable_in()), (5, 3));
    assert_eq!(weg.profile(DataProfile::Profidrive), ProfileFamily::WegProfidrive);
    assert_eq!(weg.default_profile(), ProfileFamily::WegManufacturer);
    assert_eq!(&weg.setpoint_signals(weg.default_profile())[..6], &[118, 120, 110, 111, 112, 0]);
    assert_eq!(&weg.actual_signals(ProfileFamily::WegProfidrive)[..3], &[2, 6, 100]);
    assert_eq!(layout(3107).pzd_in, 10);
    let invt = layout(4001);
    assert_eq!((invt.pkw, invt.pzd_out, invt.programmable_out()), (4, 12, 10));
    assert_eq!(invt.output_word(3), Some(Word::Pkw(3)));
    assert_eq!(invt.output_word(15), Some(Word::Programmable(10)));
    assert_eq!(invt.default_profile(), ProfileFamily::Invt);
    assert_eq!(&invt.actual_signals(ProfileFamily::Invt)[..3], &[119, 121, 100]);
}

proptest::proptest! {
    #[test]
    fn any_code_round_trips_and_never_panics(code in proptest::num::u16::ANY, i in 0usize..40) {
        let t = Telegram::from_code(code);
        proptest::prop_assert_eq!(Telegram::from_code(t.code()), t);
        if let Some(l) = Layout::of(t) {
            let _ = (l.input_word(i), l.output_word(i), l.setpoint_signals(l.default_profile()));
            proptest::prop_assert!(l.input_bytes() <= crate::dpm::layout::PD_CAPACITY);
        }
    }
}
