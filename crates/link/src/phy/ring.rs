//! The reader side of a small circular DMA receive ring with half- and full-transfer events
//! (issue 11 item 2, the F411 at ≥ 3 Mbit/s): which ring bytes are new at each event — at
//! most two pieces, the two sides of a wrap, handed to [`super::stream::Stream::piece`]
//! in place, without a copy — and whether the DMA has lapped the reader (a handler too late:
//! bytes overwritten before they were read).
//!
//! The DMA writes the ring circularly and raises HT when its position reaches `N / 2` and TC
//! when it reaches `N` (= 0); the USART's IDLE flag ends a telegram in between. At every event
//! the driver reads (and clears) the pending HT / TC flags first, then the position (from
//! NDTR), and calls [`RingWalker::walk`]. The position alone is ambiguous by whole laps; the
//! flags tell the laps: every half boundary the position says was crossed must show its flag
//! once, now or (if it was crossed between the flag read and the position read) at the next
//! event. A flag without a crossing the position explains means a whole lap was missed;
//! both flags at one event mean the handler came at least half a ring late. Both are an
//! overrun: the telegram in progress is dropped and the receiver waits for T_SYN.

use core::ops::Range;

/// What one ring event makes readable.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Walk {
    /// The new bytes up to the ring's end (or all of them).
    pub first: Range<usize>,
    /// The new bytes after a wrap, from index 0 (empty without a wrap).
    pub second: Range<usize>,
    /// The DMA has (or may have) overwritten bytes before they were read: the pieces are not
    /// trustworthy; drop the telegram in progress and resynchronise.
    pub overrun: bool,
}

/// The reader of a circular DMA ring of `N` bytes (`N` even) with HT / TC events.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct RingWalker<const N: usize> {
    read: usize,
    /// Half boundaries crossed by the position whose HT flag has not been seen yet.
    owed_half: u8,
    /// Full boundaries (the wrap) crossed whose TC flag has not been seen yet.
    owed_full: u8,
}

impl<const N: usize> RingWalker<N> {
    const HALF: usize = N / 2;

    /// At index 0, nothing owed (after the DMA was started at index 0).
    pub const fn new() -> Self {
        RingWalker { read: 0, owed_half: 0, owed_full: 0 }
    }

    /// The ring index of the first byte not yet handed on.
    pub const fn position(&self) -> usize {
        self.read
    }

    /// The DMA was restarted at index 0 (rate switch, flash stall, after an overrun).
    pub fn restart(&mut self) {
        *self = Self::new();
    }

    /// One ring event: `half` / `full` = the HT / TC flags that were pending (read and
    /// cleared before `write` was read), `write` = the DMA's position (`N − NDTR`). Every byte
    /// from the read position up to `write` is new; the read position moves to `write`.
    pub fn walk(&mut self, half: bool, full: bool, write: usize) -> Walk {
        let write = write % N;
        let r = self.read;
        let d = (write + N - r) % N;
        let end = r + d;
        // Boundaries the position crossed in (r, r + d]: the half at N/2 (+ N) and the end.
        let crossed_half = (end >= Self::HALF && r < Self::HALF) || end >= N + Self::HALF;
        let crossed_full = end >= N;
        let mut owed_half = self.owed_half + u8::from(crossed_half);
        let mut owed_full = self.owed_full + u8::from(crossed_full);
        let mut overrun = half && full;
        if half {
            match owed_half.checked_sub(1) {
                Some(o) => owed_half = o,
                None => overrun = true,
            }
        }
        if full {
            match owed_full.checked_sub(1) {
                Some(o) => owed_full = o,
                None => overrun = true,
            }
        }
        self.read = write;
        if overrun {
            self.owed_half = 0;
            self.owed_full = 0;
        } else {
            // A flag may come one event after its crossing, never later.
            self.owed_half = owed_half.min(1);
            self.owed_full = owed_full.min(1);
        }
        let (first, second) = if end > N { (r..N, 0..end - N) } else { (r..end, 0..0) };
        Walk { first, second, overrun }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::vec::Vec;

    const N: usize = 32;

    /// The DMA and its event flags as the driver sees them.
    struct Dma {
        ring: [u8; N],
        written: usize,
        ht: bool,
        tc: bool,
    }

    impl Dma {
        fn new() -> Self {
            Dma { ring: [0; N], written: 0, ht: false, tc: false }
        }
        fn write(&mut self, b: u8) {
            self.ring[self.written % N] = b;
            self.written += 1;
            match self.written % N {
                0 => self.tc = true,
                x if x == N / 2 => self.ht = true,
                _ => {}
            }
        }
        /// The handler: flags read and cleared, then the position.
        fn event(&mut self, w: &mut RingWalker<N>, out: &mut Vec<u8>) -> bool {
            let (ht, tc) = (core::mem::take(&mut self.ht), core::mem::take(&mut self.tc));
            let walk = w.walk(ht, tc, self.written % N);
            if !walk.overrun {
                out.extend_from_slice(&self.ring[walk.first.clone()]);
                out.extend_from_slice(&self.ring[walk.second.clone()]);
            }
            walk.overrun
        }
    }

    #[test]
    fn positions_and_wrap() {
        let mut w = RingWalker::<N>::new();
        assert_eq!(w.walk(false, false, 5), Walk { first: 0..5, second: 0..0, overrun: false });
        assert_eq!(w.walk(true, false, 20), Walk { first: 5..20, second: 0..0, overrun: false });
        assert_eq!(w.walk(true, false, 3), Walk { first: 20..32, second: 0..3, overrun: true }, "HT twice");
        let mut w = RingWalker::<N>::new();
        w.walk(true, false, 20);
        // TC at the wrap, the position already 3 bytes on: two pieces.
        assert_eq!(w.walk(false, true, 3), Walk { first: 20..32, second: 0..3, overrun: false });
        assert_eq!(w.position(), 3);
        // Nothing new.
        assert_eq!(w.walk(false, false, 3), Walk { first: 3..3, second: 0..0, overrun: false });
        // A lap missed: HT flagged but the position says no half was crossed.
        assert!(w.walk(true, false, 10).overrun);
        w.restart();
        assert_eq!(w.position(), 0);
    }

    #[test]
    fn a_flag_one_event_late_is_no_overrun() {
        let mut w = RingWalker::<N>::new();
        // IDLE at 17: the position crossed N/2, but HT was read before it was set.
        assert!(!w.walk(false, false, 17).overrun);
        // The HT interrupt comes afterwards with nothing new.
        assert_eq!(w.walk(true, false, 17), Walk { first: 17..17, second: 0..0, overrun: false });
        // A second stale HT is a missed lap.
        assert!(w.walk(true, false, 17).overrun);
    }

    #[test]
    fn twelve_mbit_event_sequences() {
        // 12 Mbit/s: one character per 88 ticks at 96 MHz; HT/TC every 16 characters =
        // 1408 ticks. A 255-byte request, then IDLE; handlers with a latency in characters.
        let request: Vec<u8> = (0..255u32).map(|i| i as u8).collect();
        for latency in 0..16usize {
            let mut dma = Dma::new();
            let mut w = RingWalker::<N>::new();
            let mut out = Vec::new();
            let mut pending_at: Option<usize> = None;
            for (i, &b) in request.iter().enumerate() {
                dma.write(b);
                if dma.written.is_multiple_of(N / 2) {
                    pending_at = Some(i + latency);
                }
                if pending_at == Some(i) {
                    pending_at = None;
                    assert!(!dma.event(&mut w, &mut out), "latency {latency}");
                }
            }
            if pending_at.is_some() {
                assert!(!dma.event(&mut w, &mut out));
            }
            // IDLE.
            assert!(!dma.event(&mut w, &mut out));
            assert_eq!(out, request, "latency {latency}");
        }
    }

    /// A sink that keeps the telegrams completed (as the line's sink for the fast path).
    #[derive(Default)]
    struct Keep {
        cur: Vec<u8>,
        open: bool,
        done: Vec<(Vec<u8>, bool)>,
    }

    impl crate::phy::stream::TelegramSink for Keep {
        fn begin(&mut self) {
            self.cur.clear();
            self.open = true;
        }
        fn bytes(&mut self, b: &[u8]) {
            self.cur.extend_from_slice(b);
        }
        fn abort(&mut self) {
            self.open = false;
        }
    }

    /// 12 Mbit/s bus traffic through the 32-byte ring as the F411 driver walks it: HT/TC
    /// events with a handler latency, IDLE after every telegram (one character later), each
    /// event's pieces into the stream, a telegram completed inside the bytes decided as "not
    /// last", one completed at the last byte decided at the IDLE as "last". With the filter
    /// on, exactly the own and broadcast telegrams are completed, each at its own IDLE.
    #[test]
    fn twelve_mbit_bus_through_ring_and_stream() {
        use crate::fdl::telegram::{FunctionCode, Header};
        use crate::phy::stream::{Resync, Step, Stream};
        use crate::time::BitTimes;
        let tel = |da: u8, n: usize| {
            let hdr = Header { da, sa: 2, fc: FunctionCode(0x7D), dsap: None, ssap: None };
            crate::test_card::frame(&hdr, &std::vec![0x68u8; n]).to_vec()
        };
        let bus = [tel(5, 244), tel(9, 100), std::vec![0xDC, 9, 2], tel(5, 0), tel(127, 3), tel(8, 37), tel(5, 20)];
        for latency in [0usize, 3, 12] {
            let mut dma = Dma::new();
            let mut w = RingWalker::<N>::new();
            let mut stream = Stream::new(Resync::Gap);
            let mut sink = Keep::default();
            stream.idle(BitTimes::TSYN, &mut sink);
            stream.set_filter(Some(5));
            let mut pending = false;
            let mut skipped = 0;
            // One handler run: the pieces of this event through the stream.
            let mut run = |dma: &mut Dma, w: &mut RingWalker<N>, s: &mut Stream, k: &mut Keep, idle: bool| {
                let (ht, tc) = (core::mem::take(&mut dma.ht), core::mem::take(&mut dma.tc));
                let walk = w.walk(ht, tc, dma.written % N);
                assert!(!walk.overrun);
                if pending && !walk.first.is_empty() {
                    pending = false;
                    let t = core::mem::take(&mut k.cur);
                    k.done.push((t, false));
                }
                let last_first = walk.second.is_empty();
                for (range, last_piece) in [(walk.first, last_first), (walk.second, true)] {
                    let (mut at, end) = (range.start, range.end);
                    while at < end {
                        let (used, step) = s.piece(&dma.ring[at..end], k);
                        at += used;
                        match step {
                            Step::Complete if at < end || !last_piece => {
                                let t = core::mem::take(&mut k.cur);
                                k.done.push((t, false));
                            }
                            Step::Complete => pending = true,
                            Step::Skipped => skipped += 1,
                            _ => {}
                        }
                    }
                    if last_piece {
                        break;
                    }
                }
                if idle {
                    if pending {
                        pending = false;
                        let t = core::mem::take(&mut k.cur);
                        k.done.push((t, true));
                    }
                    s.idle(BitTimes::CHAR, k);
                }
            };
            let mut due: Vec<usize> = Vec::new();
            let mut i = 0usize;
            for t in &bus {
                for &b in t {
                    dma.write(b);
                    if dma.written.is_multiple_of(N / 2) {
                        due.push(i + latency);
                    }
                    while due.first() == Some(&i) {
                        due.remove(0);
                        run(&mut dma, &mut w, &mut stream, &mut sink, false);
                    }
                    i += 1;
                }
                // IDLE one character after the last stop bit; a late HT/TC handler first.
                while !due.is_empty() {
                    due.remove(0);
                    run(&mut dma, &mut w, &mut stream, &mut sink, false);
                }
                run(&mut dma, &mut w, &mut stream, &mut sink, true);
            }
            let want: Vec<(Vec<u8>, bool)> = [0usize, 3, 4, 6].iter().map(|&k| (bus[k].clone(), true)).collect();
            assert_eq!(sink.done, want, "latency {latency}");
            assert_eq!(skipped, 3);
        }
    }

    proptest! {
        /// Any handler latencies and IDLE events in between: every byte comes through exactly
        /// once, in order, while no two handlings are more than half a ring apart; when more
        /// than a whole ring was written between two handlings, it is always reported as an
        /// overrun.
        #[test]
        fn late_handlers_are_detected(
            latencies in proptest::collection::vec(0usize..80, 1..20),
            idles in proptest::collection::vec(0usize..60, 1..20),
        ) {
            let total = 400usize;
            let mut dma = Dma::new();
            let mut w = RingWalker::<N>::new();
            let mut out = Vec::new();
            let mut due: Vec<usize> = Vec::new();
            let (mut k, mut next_idle, mut j) = (0, idles[0], 0);
            let mut overrun = false;
            let (mut last, mut worst_gap) = (0usize, 0usize);
            let mut handle = |dma: &mut Dma, w: &mut RingWalker<N>, out: &mut Vec<u8>, overrun: &mut bool| {
                worst_gap = worst_gap.max(dma.written - last);
                last = dma.written;
                *overrun |= dma.event(w, out);
            };
            for i in 0..total {
                dma.write(i as u8);
                if dma.written.is_multiple_of(N / 2) {
                    due.push(i + latencies[k % latencies.len()]);
                    k += 1;
                }
                if i == next_idle {
                    j += 1;
                    next_idle = i + 1 + idles[j % idles.len()];
                    handle(&mut dma, &mut w, &mut out, &mut overrun);
                }
                while due.first() == Some(&i) {
                    due.remove(0);
                    handle(&mut dma, &mut w, &mut out, &mut overrun);
                }
            }
            handle(&mut dma, &mut w, &mut out, &mut overrun);
            if worst_gap <= N / 2 {
                prop_assert!(!overrun);
                let want: Vec<u8> = (0..total).map(|i| i as u8).collect();
                prop_assert_eq!(out, want);
            }
            if worst_gap > N {
                prop_assert!(overrun, "more than a ring between two handlings and not noticed");
            }
        }
    }
}
