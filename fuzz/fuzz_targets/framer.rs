//! The byte-stream `Framer` on arbitrary bytes with arbitrary idle gaps in between.
//!
//! Input encoding, repeated: a control byte `c`;
//! * `c >= 0xC0`: the line is idle for `(c & 0x3F)` bit times (crosses T_SYN = 33), or for
//!   `c & 0x3F == 0x3F` a long gap;
//! * otherwise the next `c + 1` bytes (or what is left) are pushed one by one.
//!
//! Checks: no panic; every yielded frame decodes as a valid telegram of exactly its length;
//! a valid frame sent right after an idle gap (or at start) is yielded intact.
#![no_main]

use libfuzzer_sys::fuzz_target;
use pbcard::fdl::framer::{Framer, Push};
use pbcard::fdl::telegram::{self, Decoded, MAX_FRAME_LEN};
use pbcard::time::BitTimes;

fuzz_target!(|data: &[u8]| {
    let mut f = Framer::new();
    let mut yielded: u32 = 0;
    // True at start and after an idle gap: the framer must find a frame at the next byte.
    let mut after_gap = true;
    let mut i = 0;
    while i < data.len() {
        let c = data[i];
        i += 1;
        if c >= 0xC0 {
            let bits = match c & 0x3F {
                0x3F => 10_000,
                b => u32::from(b),
            };
            f.idle(BitTimes(bits));
            assert!(f.pending().is_empty() && f.frame().is_empty());
            after_gap = true;
            continue;
        }
        let end = (i + c as usize + 1).min(data.len());
        let chunk = &data[i..end];
        i = end;
        // A frame at the start of this chunk, right after a gap, must come out whole.
        let expect = if after_gap {
            match telegram::decode(chunk) {
                Decoded::Frame(_, n) => Some(n),
                _ => None,
            }
        } else {
            None
        };
        after_gap = false;
        for (k, &b) in chunk.iter().enumerate() {
            let r = f.push(b);
            assert!(f.pending().len() < MAX_FRAME_LEN, "pending {} bytes", f.pending().len());
            match r {
                Push::Frame(n) => {
                    yielded += 1;
                    let fr = f.frame();
                    assert_eq!(fr.len(), n, "Push::Frame({n}) but frame() has {} bytes", fr.len());
                    match telegram::decode(fr) {
                        Decoded::Frame(_, m) => assert_eq!(m, n, "yielded {fr:02x?} decodes to {m} bytes"),
                        other => panic!("yielded {fr:02x?} which decodes as {other:?}"),
                    }
                    assert_eq!(telegram::frame_len(fr), Ok(Some(n)));
                    assert!(f.pending().is_empty());
                }
                Push::Pending | Push::Dropped(_) => assert!(f.frame().is_empty()),
            }
            if let Some(n) = expect {
                if k + 1 == n {
                    assert_eq!(r, Push::Frame(n), "valid frame after a gap not yielded: {:02x?}", &chunk[..n]);
                    assert_eq!(f.frame(), &chunk[..n]);
                } else if k + 1 < n {
                    assert_eq!(r, Push::Pending, "valid frame after a gap cut at byte {k}: {:02x?}", &chunk[..n]);
                }
            }
        }
    }
    assert_eq!(f.stats().frames, yielded);
    // `feed` agrees with `push` on the same stream without gaps.
    let mut g = Framer::new();
    let mut fed = 0u32;
    g.feed(data, |fr| {
        fed += 1;
        assert!(matches!(telegram::decode(fr), Decoded::Frame(_, m) if m == fr.len()), "feed yielded {fr:02x?}");
    });
    assert_eq!(g.stats().frames, fed);
});
