//! The DP parameter parsers on untrusted PDUs: Set_Prm, Chk_Cfg, extended diagnosis blocks,
//! Set_Slave_Add, Global_Control, the DP-V1 diagnosis blocks made of the drive's blocks. No
//! panic, and what they accept is consistent.
#![no_main]

use libfuzzer_sys::fuzz_target;
use pbcard::card;
use pbcard::dp::cfg;
use pbcard::dp::diag::validate_ext_diag;
use pbcard::dp::global_control::GlobalControl;
use pbcard::dp::prm::{LockRequest, SetPrm, StationStatus};
use pbcard::dp::slave_add::SetSlaveAdd;

fuzz_target!(|data: &[u8]| {
    if let Ok(p) = SetPrm::parse(data, &card::SLAVE) {
        assert_eq!(data.len(), 7 + card::USER_PRM_LEN);
        assert_eq!(u16::from_be_bytes([data[4], data[5]]), card::IDENT_NUMBER);
        assert_eq!(p.watchdog().is_some(), p.status.contains(StationStatus::WD_ON));
        assert_eq!(&p.user[..], &data[7..]);
    }
    // The lock table (reference §3.3): only Lock 1 / Unlock 0 is a parameterization.
    match LockRequest::of(data) {
        None => assert!(data.len() < 7),
        Some(LockRequest::Lock) => assert_eq!(data[0] & 0xC0, 0x80),
        Some(LockRequest::Unlock) => assert_eq!(data[0] & 0x40, 0x40),
        Some(LockRequest::MinTsdrOnly(t)) => {
            assert_eq!(data[0] & 0xC0, 0);
            assert_eq!(t.is_none(), data[3] == 0);
        }
    }
    let io = cfg::io_lengths(data);
    if let Ok(io) = io {
        assert!(!data.is_empty() && io.inputs <= 244 && io.outputs <= 244);
    }
    if let Ok(m) = cfg::check(data, card::MODULES) {
        assert_eq!(m.cfg, data);
        let io = io.expect("check accepted what io_lengths refused");
        assert_eq!((io.inputs, io.outputs), (m.inputs as usize, m.outputs as usize));
    }
    // The drive's blocks (untrusted DPM bytes) in the DP-V1 format, with and without an alarm.
    let mut out = [0u8; card::MAX_EXT_DIAG_LEN];
    let alarm = pbcard::dp::alarm::Alarm { seq: data.len() as u8 % 32, kind: 1, fault_code: 0x2310, delivered: false };
    for a in [None, Some(&alarm)] {
        let n = pbcard::dp::alarm::device_block(data, true, a, &mut out);
        if validate_ext_diag(data, card::MAX_EXT_DIAG_LEN).is_ok() && data.len() <= 32 {
            assert!(
                validate_ext_diag(&out[..n], card::MAX_EXT_DIAG_LEN).is_ok(),
                "DP-V1 blocks malformed: {:02x?}",
                &out[..n]
            );
        }
    }
    if validate_ext_diag(data, card::MAX_EXT_DIAG_LEN).is_ok() {
        assert!(data.len() <= card::MAX_EXT_DIAG_LEN);
        // The slave takes exactly what the validator accepts.
        let mut s = pbcard::dp::DpSlave::new(&card::SLAVE, 8);
        s.set_ext_diag(data, true).expect("set_ext_diag refused validated blocks");
    }
    if let Ok(a) = SetSlaveAdd::parse(data, card::IDENT_NUMBER) {
        assert!(a.address <= 125 && data.len() >= 4);
    }
    if let Some(gc) = GlobalControl::parse(data) {
        assert_eq!(data.len(), 2);
        assert_eq!(gc.command.bits() | gc.reserved, data[0]);
        let _ = gc.selects(data[1]);
    }
});
