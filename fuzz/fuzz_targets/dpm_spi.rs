//! The DPM SPI transport (`pbcard::dpm::spi`): the card's frame parser on arbitrary
//! transactions, and the host's reply decoder on arbitrary MISO bytes.
//!
//! Input encoding: a control byte `c`, then the transaction bytes.
//! * `c & 1 == 0`: the bytes go to `SpiSlave::handle` as one transaction; with `c & 2` a
//!   valid CRC is written over the frame's announced CRC position first (so the checks
//!   behind the CRC are reached, not just the CRC itself).
//! * `c & 1 == 1`: the bytes go to `SpiHostCodec::decode` as MISO, and to
//!   `CyclicReply::decode` as CYCLIC reply DATA.
//!
//! Checks: no panic; exactly one counter moves per transaction; the reply decodes, echoes
//! the request, and is never longer than `MAX_REPLY`; the image changes only through an
//! accepted WRITE, only in its range, only in host-written blocks, and to the frame's data.
#![no_main]

use libfuzzer_sys::fuzz_target;
use pbcard::dpm::spi::cyclic::CyclicReply;
use pbcard::dpm::spi::{
    crc16, host_writable, parse_request, Command, ResultCode, SpiHostCodec, SpiSlave, MAX_REPLY, REQUEST_HEADER,
};
use pbcard::dpm::{Dpm, IMAGE_SIZE};

fuzz_target!(|data: &[u8]| {
    let Some((&c, rest)) = data.split_first() else { return };
    if c & 1 == 1 {
        if let Ok(r) = SpiHostCodec::decode(rest) {
            assert!(r.data.len() + 10 <= rest.len());
        }
        // The host's CYCLIC reply parser on the same bytes as DATA.
        if let Some(r) = CyclicReply::decode(rest) {
            assert_eq!(20 + r.command.len() + r.request.len(), rest.len());
        }
        return;
    }
    let mut rx = rest.to_vec();
    if c & 2 != 0 && rx.len() >= REQUEST_HEADER + 2 {
        let len = u16::from_be_bytes([rx[4], rx[5]]);
        let n = Command::from_code(rx[0]).map_or(0, |cmd| cmd.data_len(len));
        if rx.len() >= REQUEST_HEADER + n + 2 {
            let crc = crc16(&rx[..REQUEST_HEADER + n]);
            rx[REQUEST_HEADER + n..REQUEST_HEADER + n + 2].copy_from_slice(&crc.to_be_bytes());
        }
    }
    let mut dpm = Dpm::new();
    for (i, b) in dpm.as_bytes_mut().iter_mut().enumerate() {
        *b = (i as u8).wrapping_mul(13) ^ 0x5C;
    }
    let before = dpm.clone();
    let mut slave = SpiSlave::new();
    let mut reply = [0u8; MAX_REPLY];
    let n = slave.handle(&rx, &mut dpm, &mut reply);
    assert!(n <= MAX_REPLY);
    let r = SpiHostCodec::decode(&reply[..n]).expect("the card's own reply decodes");
    let s = slave.stats();
    assert_eq!(s.frames_ok.wrapping_add(s.refused()), 1);
    assert_eq!(r.cmd, rx.first().copied().unwrap_or(0));
    let parsed = parse_request(&rx);
    assert_eq!(parsed.is_ok(), r.result == ResultCode::Ok);
    let changed: Vec<usize> = (0..IMAGE_SIZE).filter(|&i| before.as_bytes()[i] != dpm.as_bytes()[i]).collect();
    if let Ok(req) = parsed {
        assert_eq!(r.tag, req.tag);
        if req.cmd == Command::Write {
            let a = usize::from(req.addr);
            assert!(host_writable(a, req.data.len()));
            assert_eq!(&dpm.as_bytes()[a..a + req.data.len()], req.data);
            assert!(changed.iter().all(|i| (a..a + req.data.len()).contains(i)));
            return;
        }
        if req.cmd == Command::Cyclic {
            // Only host-written bytes change (DRIVE, DRIVE_STATE, MBX_RSP); the reply is one.
            assert!(changed.iter().all(|&i| host_writable(i, 1)));
            assert!(CyclicReply::decode(r.data).is_some());
            return;
        }
        if req.cmd == Command::Read {
            let a = usize::from(req.addr);
            assert_eq!(r.data, &before.as_bytes()[a..a + usize::from(req.len)]);
        }
    }
    assert!(changed.is_empty(), "no accepted WRITE, yet bytes {changed:?} changed");
});
