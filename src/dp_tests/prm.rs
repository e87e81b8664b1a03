//! Set_Prm (`dp::prm`) checked against this card's configuration (`card::SLAVE`: ident
//! number, User_Prm_Data), built by the scripted master's [`crate::testkit::SetPrm::CARD`].

use crate::card;
use crate::dp::prm::*;
use crate::time::{BitTimes, Duration};

/// Set_Prm checked for the card.
fn parse(pdu: &[u8]) -> Result<SetPrm, PrmError> {
    SetPrm::parse(pdu, &card::SLAVE)
}

fn prm(status: u8, user: &[u8]) -> Vec<u8> {
    let p = crate::testkit::SetPrm::CARD.station_status(status).wd_factors(1, 99).group(0x22).user_bytes(user);
    p.pdu().to_vec()
}

#[test]
fn felser_example_shape() {
    // B8 01 63 0B <ident> 22: Lock + Sync + Freeze + WD_On, WD 1 × 99 × 10 ms (reference §3.3).
    let p = parse(&prm(0xB8, &card::USER_PRM_DEFAULTS)).unwrap();
    assert!(p.status.contains(StationStatus::LOCK_REQ | StationStatus::SYNC_REQ | StationStatus::FREEZE_REQ));
    assert_eq!(p.watchdog(), Some(Duration::from_millis(990)));
    assert_eq!(p.min_tsdr, Some(BitTimes(11)));
    assert_eq!(p.group_ident, 0x22);
    assert_eq!(p.user, card::USER_PRM_DEFAULTS);
}

#[test]
fn wd_base_1ms() {
    let p = parse(&prm(0x88, &[0x04, 0, 0, 1, 2])).unwrap();
    assert_eq!(p.watchdog(), Some(Duration::from_millis(99)));
    assert_eq!(p.user[3..], [1, 2]);
}

#[test]
fn faults() {
    let d = card::USER_PRM_DEFAULTS;
    assert_eq!(parse(&[0x88, 1, 1]), Err(PrmError::Length(3)));
    assert_eq!(parse(&prm(0x88, &[0, 0, 0, 0, 0, 0])), Err(PrmError::Length(13)));
    assert_eq!(parse(&prm(0x89, &d)), Err(PrmError::ReservedStationStatus(0x89)));
    let mut bad_ident = prm(0x88, &d);
    bad_ident[5] ^= 1;
    assert!(matches!(parse(&bad_ident), Err(PrmError::Ident(_))));
    let mut wd0 = prm(0x88, &d);
    wd0[1] = 0;
    assert_eq!(parse(&wd0), Err(PrmError::WatchdogFactor));
    assert!(matches!(parse(&prm(0x88, &[0x20, 0, 0, 0, 0])), Err(PrmError::Dpv1Status { byte: 1, .. })));
    assert!(matches!(parse(&prm(0x88, &[0, 1, 0, 0, 0])), Err(PrmError::Dpv1Status { byte: 2, .. })));
    // Alarms: the diagnostic alarm with DPV1_Enable only; every other alarm type refused.
    assert!(parse(&prm(0x88, &[0x80, 0x20, 0x03, 0, 0])).is_ok());
    assert!(matches!(parse(&prm(0x88, &[0x00, 0x20, 0, 0, 0])), Err(PrmError::Dpv1Status { byte: 2, .. })));
    for other in [0x80, 0x40, 0x10, 0x08, 0x04] {
        assert_eq!(parse(&prm(0x88, &[0x80, other, 0, 0, 0])), Err(PrmError::Dpv1Status { byte: 2, value: other }));
    }
    assert!(matches!(parse(&prm(0x88, &[0x80, 0x20, 0x08, 0, 0])), Err(PrmError::Dpv1Status { byte: 3, .. })));
    assert_eq!(parse(&prm(0x88, &[0, 0, 0, 4, 0])), Err(PrmError::UserPrm { offset: 3, value: 4 }));
    assert_eq!(parse(&prm(0x88, &[0, 0, 0, 0, 8])), Err(PrmError::UserPrm { offset: 4, value: 8 }));
}

/// Issue 12 item 4g: every length but the GSD's is a Prm_Fault, none is padded.
#[test]
fn user_prm_data_must_have_the_gsd_length() {
    for n in 0..card::USER_PRM_LEN {
        let p = prm(0x88, &card::USER_PRM_DEFAULTS[..n]);
        assert_eq!(parse(&p), Err(PrmError::Length(7 + n)), "{n} user octets");
    }
    assert!(parse(&prm(0x88, &card::USER_PRM_DEFAULTS)).is_ok());
}

#[test]
fn lock_table() {
    let mut foreign = prm(0x00, &[0xFF, 0xFF]);
    foreign[4] ^= 0x55;
    foreign[3] = 40;
    assert_eq!(LockRequest::of(&foreign), Some(LockRequest::MinTsdrOnly(Some(BitTimes(40)))));
    foreign[3] = 0;
    assert_eq!(LockRequest::of(&foreign), Some(LockRequest::MinTsdrOnly(None)));
    foreign[0] = 0x40;
    assert_eq!(LockRequest::of(&foreign), Some(LockRequest::Unlock));
    foreign[0] = 0xC0;
    assert_eq!(LockRequest::of(&foreign), Some(LockRequest::Unlock));
    foreign[0] = 0x88;
    assert_eq!(LockRequest::of(&foreign), Some(LockRequest::Lock));
    assert_eq!(LockRequest::of(&foreign[..6]), None);
    assert_eq!(min_tsdr_of(3), Some(BitTimes(11)));
}

proptest::proptest! {
    #[test]
    fn never_panics(bytes in proptest::collection::vec(proptest::num::u8::ANY, 0..260)) {
        let _ = parse(&bytes);
        let _ = LockRequest::of(&bytes);
    }
}
