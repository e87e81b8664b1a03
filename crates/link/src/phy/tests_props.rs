//! Property tests of the DMA receiver's cutter ([`super::line`]) on arbitrary event streams,
//! the same model as the `phy_line` fuzz target (fuzz/fuzz_targets/phy_line.rs), and of
//! [`super::line::expected_len`] on the prefixes of every telegram (reference §1.4, §2.1).

use super::line::{expected_len, Expect, Receiver, RxStats, SegmentEnd};
use crate::fdl::telegram::{FunctionCode, Header, SC, SD4};
use crate::test_card as testkit;
use proptest::prelude::*;
use std::vec::Vec;

/// One event of the line as the DMA driver reports it.
#[derive(Debug, Clone)]
enum Event {
    /// Bytes between two IDLE events, with a character error flagged or not.
    Segment(Vec<u8>, bool),
    /// Telegrams back to back in one segment, then garbage bytes.
    Telegrams(Vec<Vec<u8>>, Vec<u8>),
    Tsyn,
    Reset,
}

fn telegram() -> impl Strategy<Value = Vec<u8>> {
    prop_oneof![
        Just(vec![SC]),
        (any::<u8>(), any::<u8>()).prop_map(|(da, sa)| vec![SD4, da, sa]),
        (0u8..128, 0u8..128, any::<u8>(), proptest::option::of(0u8..64), proptest::collection::vec(any::<u8>(), 0..60))
            .prop_map(|(da, sa, fc, dsap, pdu)| {
                let hdr = Header { da, sa, fc: FunctionCode(fc), dsap, ssap: dsap.map(|_| 62) };
                testkit::frame(&hdr, &pdu).to_vec()
            }),
    ]
}

fn event() -> impl Strategy<Value = Event> {
    prop_oneof![
        (proptest::collection::vec(any::<u8>(), 0..80), any::<bool>()).prop_map(|(b, c)| Event::Segment(b, c)),
        (proptest::collection::vec(telegram(), 1..5), proptest::collection::vec(any::<u8>(), 0..6))
            .prop_map(|(t, g)| Event::Telegrams(t, g)),
        Just(Event::Tsyn),
        Just(Event::Reset),
    ]
}

fn losses(s: RxStats) -> u32 {
    s.corrupt + s.truncated + s.garbage + s.unsynced
}

proptest! {
    /// Any stream of segments, character errors, T_SYN gaps and restarts: every telegram
    /// handed on has the length its header announces and the telegrams of a segment are its
    /// bytes from the start, in order; a clean segment is all telegrams; a dropped one hands on
    /// nothing; any loss counts exactly once and waits for T_SYN; well-formed telegrams on a
    /// synced line all come through.
    #[test]
    fn the_cutter_never_loses_step(events in proptest::collection::vec(event(), 0..40)) {
        let mut r = Receiver::new();
        for ev in events {
            let (bytes, corrupt, whole) = match ev {
                Event::Tsyn => {
                    r.on_tsyn();
                    prop_assert!(r.is_synced());
                    continue;
                }
                Event::Reset => {
                    r.reset();
                    prop_assert!(!r.is_synced());
                    continue;
                }
                Event::Segment(b, c) => (b, c, None),
                Event::Telegrams(t, g) => {
                    let mut b = t.concat();
                    b.extend_from_slice(&g);
                    (b, false, g.is_empty().then_some(t))
                }
            };
            let synced = r.is_synced();
            let before = r.stats();
            let mut got: Vec<Vec<u8>> = Vec::new();
            let mut lengths_ok = true;
            let end = r.segment(&bytes, corrupt, |f| {
                lengths_ok &= expected_len(f) == Expect::Len(f.len());
                got.push(f.to_vec());
            });
            let after = r.stats();
            prop_assert!(lengths_ok, "{:02x?}", got);
            let cut = got.concat();
            prop_assert!(bytes.starts_with(&cut));
            prop_assert_eq!(after.frames - before.frames, got.len() as u32);
            let lost = losses(after) - losses(before);
            match end {
                SegmentEnd::Clean => {
                    prop_assert_eq!(&cut, &bytes);
                    prop_assert_eq!(lost, 0);
                    prop_assert_eq!(r.is_synced(), synced);
                }
                SegmentEnd::Corrupt | SegmentEnd::Unsynced => {
                    prop_assert!(got.is_empty());
                    prop_assert_eq!(lost, 1);
                    prop_assert!(!r.is_synced());
                }
                SegmentEnd::Truncated | SegmentEnd::Garbage => {
                    prop_assert!(cut.len() < bytes.len());
                    prop_assert_eq!(lost, 1);
                    prop_assert!(!r.is_synced());
                }
            }
            if corrupt {
                prop_assert_eq!(end, SegmentEnd::Corrupt);
            } else if !synced && !bytes.is_empty() {
                prop_assert_eq!(end, SegmentEnd::Unsynced);
            } else if let Some(t) = whole {
                prop_assert_eq!(end, SegmentEnd::Clean);
                prop_assert_eq!(got, t);
            }
        }
    }

    /// Every prefix of a telegram either asks for more bytes or announces exactly the
    /// telegram's length: a DMA transfer sized from the header never cuts a telegram short
    /// or runs into the next one.
    #[test]
    fn prefixes_announce_the_whole_telegram(t in telegram(), tail in proptest::collection::vec(any::<u8>(), 0..8)) {
        let mut b = t.clone();
        b.extend_from_slice(&tail);
        for k in 0..=b.len() {
            match expected_len(&b[..k]) {
                Expect::Len(n) => prop_assert_eq!(n, t.len(), "prefix {:02x?}", &b[..k]),
                Expect::More(n) => prop_assert!(n > k && n <= t.len(), "prefix {:02x?} asks {}", &b[..k], n),
                Expect::NotAFrame => prop_assert!(false, "prefix {:02x?} of a telegram refused", &b[..k]),
            }
        }
    }
}
