//! Tests of the streaming framer [`super::Stream`]: the telegram kinds, the exact completion
//! byte, the destination filter, and property tests against the DMA receiver's cutter
//! ([`crate::phy::line::Receiver`], gap resync) and the byte framer
//! ([`crate::fdl::framer::Framer`], hunting) on random streams in every chunking.

use super::{Resync, Step, Stream, TelegramSink};
use crate::fdl::framer::{Framer, Push};
use crate::fdl::telegram::{decode, Decoded, FunctionCode, Header, BROADCAST, SC, SD1, SD2, SD3, SD4};
use crate::phy::line::Receiver;
use crate::test_card as testkit;
use crate::time::BitTimes;
use proptest::prelude::*;
use std::vec::Vec;

/// A sink that records what it was told and checks the call order.
#[derive(Debug, Default)]
struct Rec {
    cur: Option<Vec<u8>>,
    done: Vec<Vec<u8>>,
    aborts: usize,
    /// `bytes` calls.
    calls: usize,
    /// Bytes outside begin..end, abort without begin, completion without a telegram.
    violations: usize,
}

impl TelegramSink for Rec {
    fn begin(&mut self) {
        self.cur = Some(Vec::new());
    }
    fn bytes(&mut self, bytes: &[u8]) {
        assert!(!bytes.is_empty(), "empty piece");
        self.calls += 1;
        match &mut self.cur {
            Some(v) => v.extend_from_slice(bytes),
            None => self.violations += 1,
        }
    }
    fn abort(&mut self) {
        if self.cur.take().is_none() {
            self.violations += 1;
        }
        self.aborts += 1;
    }
}

impl Rec {
    /// The driver's "complete" call.
    fn complete(&mut self) {
        match self.cur.take() {
            Some(v) => self.done.push(v),
            None => self.violations += 1,
        }
    }
}

fn frame(da: u8, pdu: &[u8]) -> Vec<u8> {
    let hdr = Header { da, sa: 2, fc: FunctionCode(0x7D), dsap: None, ssap: None };
    testkit::frame(&hdr, pdu).to_vec()
}

/// Feed `bytes` one per call; the index of every completion.
fn push_all(s: &mut Stream, rec: &mut Rec, bytes: &[u8]) -> Vec<(usize, Step)> {
    let mut ends = Vec::new();
    for (i, &b) in bytes.iter().enumerate() {
        let step = s.push(b, rec);
        if step == Step::Complete {
            rec.complete();
        }
        if step != Step::Pending {
            ends.push((i, step));
        }
    }
    ends
}

/// Feed `bytes` in pieces of the sizes in `chunks` (cycled), as a DMA ring would.
fn piece_all(s: &mut Stream, rec: &mut Rec, bytes: &[u8], chunks: &[usize], ci: &mut usize) -> Vec<Step> {
    let mut steps = Vec::new();
    let mut rest = bytes;
    while !rest.is_empty() {
        let n = chunks[*ci % chunks.len()].clamp(1, rest.len());
        *ci += 1;
        let mut chunk = &rest[..n];
        rest = &rest[n..];
        while !chunk.is_empty() {
            let (used, step) = s.piece(chunk, rec);
            assert!(used >= 1 && used <= chunk.len());
            if step == Step::Complete {
                rec.complete();
            }
            if step != Step::Pending {
                steps.push(step);
            } else {
                assert_eq!(used, chunk.len(), "Pending uses the whole piece");
            }
            chunk = &chunk[used..];
        }
    }
    steps
}

fn synced() -> Stream {
    let mut s = Stream::new(Resync::Gap);
    s.idle(BitTimes::TSYN, &mut Rec::default());
    s
}

#[test]
fn every_kind_completes_exactly_at_its_last_byte() {
    let token = vec![SD4, 3, 2];
    let sd1 = frame(9, &[]);
    let sd2 = frame(9, &[1, 2, 3]);
    let sd3 = frame(9, &[0; 8]);
    let long = frame(9, &[0x68; 246]);
    assert_eq!((sd1[0], sd2[0], sd3[0], long.len()), (SD1, SD2, SD3, 255));
    for f in [&token, &vec![SC], &sd1, &sd2, &sd3, &long] {
        let mut s = synced();
        let mut rec = Rec::default();
        assert_eq!(push_all(&mut s, &mut rec, f), vec![(f.len() - 1, Step::Complete)]);
        assert_eq!(rec.done, vec![f.clone()]);
        assert_eq!(s.remaining(), None);
        assert!(!s.in_telegram());
    }
    // Back to back in one piece: the piece stops at each end.
    let all = [&sd2[..], &token[..], &[SC][..], &long[..]].concat();
    let mut s = synced();
    let mut rec = Rec::default();
    let (used, step) = s.piece(&all, &mut rec);
    assert_eq!((used, step), (sd2.len(), Step::Complete));
    rec.complete();
    let steps = piece_all(&mut s, &mut rec, &all[used..], &[200], &mut 0);
    assert_eq!(steps, vec![Step::Complete; 3]);
    assert_eq!(rec.done, vec![sd2.clone(), token.clone(), vec![SC], long.clone()]);
    assert_eq!(s.stats().frames, 4);
    assert_eq!(rec.violations, 0);
}

/// A piece that starts a telegram with its whole header (a DMA piece at IDLE holding a short
/// request) costs the sink one call for the whole telegram; a header split across pieces
/// is completed from the next piece in one call as well.
#[test]
fn a_whole_header_in_a_piece_is_one_sink_call() {
    let sd2 = {
        let hdr = Header { da: 0x85, sa: 0x82, fc: FunctionCode(0x7D), dsap: Some(50), ssap: Some(51) };
        testkit::frame(&hdr, &[]).to_vec()
    };
    for f in [frame(5, &[]), frame(5, &[1, 2, 3, 4]), sd2] {
        for split in 0..f.len() {
            let mut s = synced();
            s.set_filter(Some(5));
            let mut rec = Rec::default();
            let chunks = if split == 0 { vec![f.len()] } else { vec![split, f.len()] };
            let steps = piece_all(&mut s, &mut rec, &f, &chunks, &mut 0);
            assert_eq!(steps, [Step::Complete], "{f:02x?} split at {split}");
            assert_eq!(rec.done, std::slice::from_ref(&f));
            // SD2 needs 5 header bytes before the sink hears of it: a first piece of fewer
            // goes in one call of its own (`header_run`), the rest in one more.
            let want = if split == 0 { 1 } else { 2 };
            assert_eq!(rec.calls, want, "{f:02x?} split at {split}");
        }
        // Another station's: skipped at its DA, the sink never hears of it (no begin).
        let mut s = synced();
        s.set_filter(Some(9));
        let mut rec = Rec::default();
        assert_eq!(piece_all(&mut s, &mut rec, &f, &[f.len()], &mut 0), [Step::Skipped]);
        assert_eq!((rec.calls, rec.aborts, rec.cur.is_none()), (0, 0, true));
    }
}

#[test]
fn remaining_counts_down_once_the_length_is_known() {
    let f = frame(9, &[1, 2, 3]);
    let mut s = synced();
    let mut rec = Rec::default();
    for (i, &b) in f.iter().enumerate().take(f.len() - 1) {
        s.push(b, &mut rec);
        let want = if i < 3 { None } else { Some(f.len() - 1 - i) };
        assert_eq!(s.remaining(), want, "after byte {i}");
    }
}

#[test]
fn nothing_before_the_first_tsyn_and_after_a_loss() {
    let f = frame(5, &[1, 2]);
    let mut s = Stream::new(Resync::Gap);
    let mut rec = Rec::default();
    assert!(push_all(&mut s, &mut rec, &f).is_empty());
    s.idle(BitTimes(11), &mut rec);
    assert!(push_all(&mut s, &mut rec, &f).is_empty(), "11 bit times are no T_SYN");
    s.idle(BitTimes(33), &mut rec);
    assert_eq!(push_all(&mut s, &mut rec, &f).len(), 1);
    // A character error in the middle: aborted, then deaf until T_SYN.
    push_all(&mut s, &mut rec, &f[..4]);
    s.error(&mut rec);
    assert_eq!(rec.aborts, 1);
    assert!(push_all(&mut s, &mut rec, &f[4..]).is_empty());
    s.idle(BitTimes(20), &mut rec);
    assert!(push_all(&mut s, &mut rec, &f).is_empty());
    s.idle(BitTimes(40), &mut rec);
    assert_eq!(push_all(&mut s, &mut rec, &f).len(), 1);
    // A gap inside a telegram cuts it.
    push_all(&mut s, &mut rec, &f[..3]);
    s.idle(BitTimes(11), &mut rec);
    assert_eq!(rec.aborts, 2);
    let st = s.stats();
    assert_eq!((st.frames, st.corrupt, st.truncated, st.unsynced), (2, 1, 1, 4));
    assert_eq!(rec.done.len(), 2);
    assert_eq!(rec.violations, 0);
}

#[test]
fn bad_sd2_headers_are_garbage_at_the_byte_that_shows_it() {
    for (bad, at) in [(&[SD2, 3][..], 1), (&[SD2, 5, 6][..], 2), (&[SD2, 5, 5, SD1][..], 3), (&[0x00][..], 0)] {
        let mut s = synced();
        let mut rec = Rec::default();
        assert_eq!(push_all(&mut s, &mut rec, bad), vec![(at, Step::Garbage)], "{bad:02x?}");
        assert!(!s.is_synced());
        assert_eq!(s.stats().garbage, 1);
        assert_eq!(rec.aborts, usize::from(at > 0));
    }
}

#[test]
fn hunting_retries_inside_the_header() {
    // SD2 with LE = 0x10 (valid), LEr = 0x10, then not SD2: restart at LE = SD1? No: 0x10 is
    // SD1, so the framer restarts there with [SD1, 0x10, x] and goes on.
    let f = frame(0x10, &[]);
    assert_eq!(&f[..2], &[SD1, 0x10]);
    let mut stream = vec![SD2, SD1, 0x10];
    stream.extend_from_slice(&f[2..]);
    // [SD2, 0x10, 0x10, x]: x ≠ SD2 → garbage, restart at index 1 = [SD1, 0x10, x].
    let mut s = Stream::new(Resync::Hunt);
    let mut rec = Rec::default();
    let mut framer = Framer::new();
    let mut want = Vec::new();
    for &b in &stream {
        if let Push::Frame(n) = framer.push(b) {
            want.push(framer.frame()[..n].to_vec());
        }
    }
    push_all(&mut s, &mut rec, &stream);
    assert_eq!(rec.done, want);
    assert_eq!(want, vec![f.clone()]);
}

#[test]
fn the_filter_skips_other_stations_without_reading_them() {
    let mine = frame(5, &[1, 2, 3]);
    let ext = frame(5 | 0x80, &[1]);
    let bc = frame(BROADCAST, &[4]);
    let other = frame(6, &[7; 100]);
    let token = [SD4, 6, 2];
    let mut s = synced();
    s.set_filter(Some(5));
    let mut rec = Rec::default();
    let all = [&other[..], &mine[..], &token[..], &ext[..], &[SC][..], &bc[..], &other[..]].concat();
    let steps = piece_all(&mut s, &mut rec, &all, &[32], &mut 0);
    use Step::{Complete as C, Skipped as K};
    assert_eq!(steps, vec![K, C, K, C, C, C, K]);
    assert_eq!(rec.done, vec![mine.clone(), ext.clone(), vec![SC], bc.clone()]);
    assert_eq!(rec.violations, 0);
    // A skipped telegram whose header is in one piece never reaches the sink (no begin, no
    // abort); one whose header is split hands the sink its header up to the DA, then aborts.
    let mut rec = Rec::default();
    let mut s = synced();
    s.set_filter(Some(5));
    let (used, step) = s.piece(&other[..10], &mut rec);
    assert_eq!((used, step), (10, Step::Pending));
    assert_eq!((rec.cur.clone(), rec.aborts, rec.calls), (None, 0, 0));
    let mut split = synced();
    split.set_filter(Some(5));
    let mut rec2 = Rec::default();
    assert_eq!(split.piece(&other[..2], &mut rec2), (2, Step::Pending));
    assert_eq!(split.piece(&other[2..10], &mut rec2), (8, Step::Pending));
    assert_eq!((rec2.cur.clone(), rec2.aborts), (None, 1));
    assert_eq!(s.remaining(), Some(other.len() - 10));
    s.set_filter(None);
    assert_eq!(s.piece(&other[10..], &mut rec), (other.len() - 10, Step::Skipped));
}

#[test]
fn a_reset_aborts_and_waits() {
    let f = frame(5, &[1, 2]);
    let mut s = synced();
    let mut rec = Rec::default();
    push_all(&mut s, &mut rec, &f[..5]);
    s.reset(&mut rec);
    assert_eq!(rec.aborts, 1);
    assert!(!s.is_synced());
    assert!(push_all(&mut s, &mut rec, &f).is_empty());
}

/// A telegram as the bus carries it (any address, any function code: the cutter checks
/// lengths only).
fn telegram() -> impl Strategy<Value = Vec<u8>> {
    prop_oneof![
        Just(vec![SC]),
        (any::<u8>(), any::<u8>()).prop_map(|(da, sa)| vec![SD4, da, sa]),
        (
            any::<u8>(),
            0u8..128,
            any::<u8>(),
            proptest::option::of(0u8..64),
            proptest::collection::vec(any::<u8>(), 0..60)
        )
            .prop_map(|(da, sa, fc, dsap, pdu)| {
                let hdr = Header { da, sa, fc: FunctionCode(fc), dsap, ssap: dsap.map(|_| 62) };
                testkit::frame(&hdr, &pdu).to_vec()
            }),
        proptest::collection::vec(any::<u8>(), 240..=244).prop_map(|pdu| frame(5, &pdu)),
    ]
}

/// One thing on the line, as a driver reports it.
#[derive(Debug, Clone)]
enum Ev {
    Bytes(Vec<u8>),
    Error,
    Idle(u32),
}

fn gap_event() -> impl Strategy<Value = Ev> {
    prop_oneof![
        6 => telegram().prop_map(Ev::Bytes),
        1 => (telegram(), any::<prop::sample::Index>()).prop_map(|(t, k)| Ev::Bytes(t[..k.index(t.len())].to_vec())),
        1 => proptest::collection::vec(any::<u8>(), 1..12).prop_map(Ev::Bytes),
        1 => Just(Ev::Error),
        4 => (11u32..=50).prop_map(Ev::Idle),
    ]
}

/// The DA of a telegram (extension bit masked), as the filter sees it.
fn dest(f: &[u8]) -> Option<u8> {
    match f[0] {
        SD1 | SD3 | SD4 => Some(f[1] & 0x7F),
        SD2 => Some(f[4] & 0x7F),
        _ => None,
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    /// On a gap line, the stream in any chunking (one byte per call or DMA pieces) completes
    /// exactly the telegrams the segment cutter hands on, in order — with a character error
    /// modelled as the segment cut there and the receiver restarted —, skips exactly the
    /// other stations' ones with a filter, and a dropped telegram is never completed.
    #[test]
    fn gap_resync_equals_the_segment_cutter(
        events in proptest::collection::vec(gap_event(), 0..40),
        chunks in proptest::collection::vec(1usize..40, 1..8),
        per_char in any::<bool>(),
        filter in proptest::option::of(0u8..3),
    ) {
        // The oracle.
        let mut r = Receiver::new();
        let mut want: Vec<Vec<u8>> = Vec::new();
        let mut seg: Vec<u8> = Vec::new();
        let mut dead = false;
        // The stream.
        let mut s = Stream::new(Resync::Gap);
        s.set_filter(filter);
        let mut rec = Rec::default();
        let mut skipped = 0usize;
        let mut ci = 0;
        for ev in &events {
            match ev {
                Ev::Bytes(b) => {
                    if !dead {
                        seg.extend_from_slice(b);
                    }
                    let steps: Vec<Step> = if per_char {
                        push_all(&mut s, &mut rec, b).into_iter().map(|(_, st)| st).collect()
                    } else {
                        piece_all(&mut s, &mut rec, b, &chunks, &mut ci)
                    };
                    skipped += steps.iter().filter(|&&st| st == Step::Skipped).count();
                }
                Ev::Error => {
                    if !dead {
                        r.segment(&seg, false, |f| want.push(f.to_vec()));
                        r.reset();
                        dead = true;
                    }
                    s.error(&mut rec);
                }
                Ev::Idle(bits) => {
                    if !dead {
                        r.segment(&seg, false, |f| want.push(f.to_vec()));
                    }
                    seg.clear();
                    dead = false;
                    if *bits >= 33 {
                        r.on_tsyn();
                    }
                    s.idle(BitTimes(*bits), &mut rec);
                    prop_assert!(rec.cur.is_none(), "an idle leaves no telegram open");
                }
            }
        }
        // The end of the stream is a segment's end.
        if !dead {
            r.segment(&seg, false, |f| want.push(f.to_vec()));
        }
        s.idle(BitTimes(11), &mut rec);
        let (kept, others): (Vec<Vec<u8>>, Vec<Vec<u8>>) = want.into_iter().partition(|f| match (filter, dest(f)) {
            (Some(own), Some(da)) => da == own || da == BROADCAST,
            _ => true,
        });
        prop_assert_eq!(&rec.done, &kept);
        prop_assert_eq!(skipped, others.len());
        prop_assert_eq!(rec.violations, 0);
    }
}

/// A telegram the framer accepts (valid addresses, function code and checksum).
fn valid_telegram() -> impl Strategy<Value = Vec<u8>> {
    telegram().prop_filter("valid", |t| matches!(decode(t), Decoded::Frame(_, n) if n == t.len()))
}

fn hunt_event() -> impl Strategy<Value = Vec<Ev>> {
    let not_sd = any::<u8>().prop_filter("no start delimiter", |b| !matches!(*b, SD1 | SD2 | SD3 | SD4 | SC));
    prop_oneof![
        6 => valid_telegram().prop_map(|t| vec![Ev::Bytes(t)]),
        // Cut off by a gap.
        1 => (valid_telegram(), any::<prop::sample::Index>(), 0u32..50).prop_filter_map("cut", |(t, k, bits)| {
            let k = k.index(t.len());
            (k > 0).then(|| vec![Ev::Bytes(t[..k].to_vec()), Ev::Idle(bits)])
        }),
        // A character error: the rest of that telegram never arrives.
        1 => (valid_telegram(), any::<prop::sample::Index>())
            .prop_map(|(t, k)| vec![Ev::Bytes(t[..k.index(t.len())].to_vec()), Ev::Error]),
        1 => proptest::collection::vec(not_sd, 1..8).prop_map(|g| vec![Ev::Bytes(g)]),
        2 => (0u32..50).prop_map(|b| vec![Ev::Idle(b)]),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    /// Without gap information (hunting), the stream completes the same valid telegrams as
    /// the byte framer, in order, in any chunking: after garbage, character errors and cut
    /// telegrams. (Garbage that looks like a telegram by its length is the sink's to refuse
    /// by its checksum; the framer rescans inside it, the stream — which keeps no copy —
    /// cannot, so such garbage is not generated here; the gap line never needs it.)
    #[test]
    fn hunt_resync_equals_the_framer(
        events in proptest::collection::vec(hunt_event(), 0..30),
        chunks in proptest::collection::vec(1usize..40, 1..8),
        per_char in any::<bool>(),
    ) {
        let mut framer = Framer::new();
        let mut want: Vec<Vec<u8>> = Vec::new();
        let mut s = Stream::new(Resync::Hunt);
        let mut rec = Rec::default();
        let mut ci = 0;
        for ev in events.iter().flatten() {
            match ev {
                Ev::Bytes(b) => {
                    for &x in b {
                        if let Push::Frame(n) = framer.push(x) {
                            want.push(framer.frame()[..n].to_vec());
                        }
                    }
                    if per_char {
                        push_all(&mut s, &mut rec, b);
                    } else {
                        piece_all(&mut s, &mut rec, b, &chunks, &mut ci);
                    }
                }
                Ev::Error => {
                    framer.line_error();
                    s.error(&mut rec);
                }
                Ev::Idle(bits) => {
                    framer.idle(BitTimes(*bits));
                    s.idle(BitTimes(*bits), &mut rec);
                }
            }
        }
        let got: Vec<Vec<u8>> =
            rec.done.iter().filter(|f| matches!(decode(f), Decoded::Frame(_, n) if n == f.len())).cloned().collect();
        prop_assert_eq!(got, want);
        prop_assert_eq!(rec.violations, 0);
    }

    /// Random bytes in any mode and chunking: nothing panics, every completed telegram has
    /// the length its header announces, and the sink's call order holds.
    #[test]
    fn random_bytes(bytes in proptest::collection::vec(any::<u8>(), 0..600),
                    chunks in proptest::collection::vec(1usize..40, 1..8), hunt in any::<bool>()) {
        let mut s = Stream::new(if hunt { Resync::Hunt } else { Resync::Gap });
        let mut rec = Rec::default();
        s.idle(BitTimes::TSYN, &mut rec);
        piece_all(&mut s, &mut rec, &bytes, &chunks, &mut 0);
        for f in &rec.done {
            prop_assert_eq!(crate::phy::line::expected_len(f), crate::phy::line::Expect::Len(f.len()));
        }
        prop_assert_eq!(rec.violations, 0);
    }
}
