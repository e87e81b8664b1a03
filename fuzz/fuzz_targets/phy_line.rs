//! The DMA receiver's telegram cutter (`pbcard::phy::line::Receiver`) on an arbitrary stream
//! of IDLE-delimited segments, character errors, T_SYN gaps and restarts, with every
//! telegram it hands on answered by a whole `Node` through `node::answer` (the decision
//! the firmware's task makes).
//!
//! Input: a sequence of operations, each a control byte `c`:
//! * `c >> 6 == 0`: a segment of the next `(c & 0x3F) + 1` input bytes.
//! * `c >> 6 == 1`: the same with a character error flagged (the segment is dropped).
//! * `c >> 6 == 2`: `c & 1` — a T_SYN gap (`on_tsyn`) or a receiver restart (`reset`).
//! * `c >> 6 == 3`: a segment of `(c & 3) + 1` well-formed telegrams (header byte, PDU
//!   length and PDU from the input; SD1 / SD2 / SD3 by length, SC, token SD4), then, with
//!   `c & 4`, `(c >> 3) & 7` garbage bytes from the input.
//!
//! Checks: no panic; every telegram handed on has exactly the length its first bytes announce
//! (`expected_len`); the telegrams of a segment are its bytes from the start, in order, back
//! to back; a `Clean` segment is all telegrams, a dropped one (`Corrupt`, `Unsynced`) hands on
//! none; after anything but `Clean` the receiver waits for T_SYN; exactly one counter moves
//! per non-empty segment (plus `frames` per telegram); a segment of well-formed telegrams on a
//! synced line hands on exactly those; every answer of the node is one valid telegram.
#![no_main]

#[path = "common/src.rs"]
mod src;

use libfuzzer_sys::fuzz_target;
use pbcard::dp::DpSlave;
use pbcard::fdl::telegram::{self, Decoded, FunctionCode, Header, Telegram};
use pbcard::node::answer;
use pbcard::phy::line::{expected_len, Expect, RateControl, Receiver, RxStats, SegmentEnd};
use pbcard::testkit;
use pbcard::time::{Baudrate, Instant};
use src::Src;

const ME: u8 = 5;

/// A rate fixed at 1.5 Mbit/s (QEMU's rate control): answers always go out.
struct Fixed;

impl RateControl for Fixed {
    fn on_frame(&mut self, _: Instant, _: bool, _: bool) {}
    fn on_garbage(&mut self, _: Instant) {}
    fn detected(&self) -> Option<Baudrate> {
        Some(Baudrate::B1500k)
    }
}

/// One well-formed telegram from the input: a request to us or another station, an SC, a
/// token.
fn telegram_from(src: &mut Src<'_>) -> Vec<u8> {
    let kind = src.u8();
    match kind % 8 {
        0 => vec![telegram::SC],
        1 => vec![telegram::SD4, kind >> 1, src.u8() & 0x7F],
        _ => {
            let da = if kind & 0x10 != 0 { ME } else { src.u8() & 0x7F };
            let sa = src.u8() & 0x7F;
            let fc = FunctionCode(src.u8());
            let dsap = (kind & 0x20 != 0).then(|| src.u8() & 0x3F);
            let ssap = dsap.map(|_| 62);
            let n = usize::from(src.u8() % 40);
            let pdu = src.bytes(n).to_vec();
            testkit::frame(&Header { da, sa, fc, dsap, ssap }, &pdu).to_vec()
        }
    }
}

fn moved(a: RxStats, b: RxStats) -> u32 {
    (b.corrupt - a.corrupt) + (b.truncated - a.truncated) + (b.garbage - a.garbage) + (b.unsynced - a.unsynced)
}

fuzz_target!(|data: &[u8]| {
    let mut src = Src::new(data);
    let mut rx = Receiver::new();
    let mut node = pbcard::card::node(DpSlave::new(&pbcard::card::SLAVE, ME));
    let mut now_us = 0u64;
    while !src.is_empty() {
        let c = src.u8();
        let (bytes, corrupt, whole) = match c >> 6 {
            0 => (src.bytes(usize::from(c & 0x3F) + 1).to_vec(), false, None),
            1 => (src.bytes(usize::from(c & 0x3F)).to_vec(), true, None),
            2 => {
                if c & 1 == 0 {
                    let t = rx.stats().tsyn;
                    rx.on_tsyn();
                    assert!(rx.is_synced() && rx.stats().tsyn == t.wrapping_add(1));
                } else {
                    rx.reset();
                    assert!(!rx.is_synced());
                }
                continue;
            }
            _ => {
                let frames: Vec<Vec<u8>> = (0..=(c & 3)).map(|_| telegram_from(&mut src)).collect();
                let mut b = frames.concat();
                let garbage = c & 4 != 0;
                if garbage {
                    b.extend_from_slice(src.bytes(usize::from((c >> 3) & 7)));
                }
                (b, false, (!garbage).then_some(frames))
            }
        };
        let synced = rx.is_synced();
        let before = rx.stats();
        let mut got: Vec<Vec<u8>> = Vec::new();
        let end = rx.segment(&bytes, corrupt, |f| {
            assert_eq!(expected_len(f), Expect::Len(f.len()), "handed on {f:02x?}");
            got.push(f.to_vec());
        });
        let after = rx.stats();
        let cut = got.concat();
        assert!(bytes.starts_with(&cut), "telegrams {got:02x?} are not the start of {bytes:02x?}");
        assert_eq!(after.frames - before.frames, got.len() as u32);
        assert_eq!(after.tsyn, before.tsyn);
        match end {
            SegmentEnd::Clean => {
                assert_eq!(cut, bytes, "clean segment {bytes:02x?} cut into {got:02x?}");
                assert_eq!(moved(before, after), 0);
                assert_eq!(rx.is_synced(), synced);
            }
            SegmentEnd::Corrupt | SegmentEnd::Unsynced => {
                assert!(got.is_empty());
                assert_eq!(end == SegmentEnd::Corrupt, corrupt);
                assert_eq!(moved(before, after), 1);
                assert!(!rx.is_synced());
            }
            SegmentEnd::Truncated | SegmentEnd::Garbage => {
                assert!(cut.len() < bytes.len());
                assert_eq!(moved(before, after), 1);
                assert!(!rx.is_synced());
            }
        }
        if corrupt {
            assert_eq!(end, SegmentEnd::Corrupt);
        } else if !synced && !bytes.is_empty() {
            assert_eq!(end, SegmentEnd::Unsynced);
        } else if let Some(frames) = whole {
            assert_eq!(end, SegmentEnd::Clean);
            assert_eq!(got, frames);
        }
        for f in &got {
            now_us += 300;
            let now = Instant::from_micros(now_us);
            node.poll(now);
            if let Some(r) = answer(&mut node, &mut Fixed, now, f) {
                match telegram::decode(r) {
                    Decoded::Frame(Telegram::ShortAck | Telegram::Data(_), n) if n == r.len() => {}
                    other => panic!("answer {r:02x?} = {other:?} to {f:02x?}"),
                }
            }
        }
    }
});
