//! What the DMA line's interrupts compute, as pure functions on wrapping 32-bit timer values
//! (issue 11 item 2; reference §1.3 T_SYN / min_TSDR, §1.4): the per-rate tick table
//! ([`LineTicks`], computed once per rate, so the response path only adds and multiplies —
//! no division, no 64-bit division), the "already passed?" check of a timer compare
//! ([`compare_passed`]), the reader side of the circular receive ring ([`RingReader`], with
//! the restart after a flash stall) and the USART receive-interrupt gate that never needs a
//! CPU read of the data register ([`RxIrqGate`]).
//!
//! **End of a request** ([`RxMode`], [`RequestEnd`]). At ≤ 1.5 Mbit/s the board receives per
//! character and finds the end **by the header's length**: the streaming framer
//! ([`super::stream::Stream`]) completes the telegram at its last character, whose receive
//! interrupt is the decision's start ([`LineTicks::end_at_last_char`]: the stop bit ends
//! within one bit time of RXNE) — no IDLE wait. At ≥ 3 Mbit/s a DMA receiver learns of the end
//! from the USART's IDLE flag: one idle character (11 bit times of mark) after the last stop
//! bit, ±1 bit ([`super::line::IDLE_BITS`], [`super::line::IDLE_UNCERTAINTY_BITS`],
//! [`LineTicks::end_at_idle`]). Cost: 12 bit times after the request's last stop bit before
//! the decision starts (96 cycles at 12 Mbit/s), which min_TSDR ≥ 11 absorbs; what the
//! firmware adds after the event (interrupt entry, the remaining ring bytes, decision, DMA
//! start) comes on top.

use crate::time::{Baudrate, BitTimes};

use super::line::{reached, BitClock, IDLE_BITS, IDLE_UNCERTAINTY_BITS, TSYN_PROOF_BITS};

/// The line's fixed intervals at one rate in timer ticks, computed once per rate (at the
/// rate switch, [`LineTicks::new`]) from [`BitClock::ticks`] (which divides); the instants the
/// line interrupt needs are then one addition each ([`LineTicks::tsyn_check_at`],
/// [`LineTicks::response_not_before`], [`LineTicks::response_latest`]). min_TSDR, which a
/// Set_Prm may change at any time, is a 32 × 32 → 64-bit multiply and a shift
/// ([`LineTicks::ticks_of`]), never a division.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct LineTicks {
    /// Ticks per bit time, 16.16 fixed point, rounded up (a wait is never shorter).
    bit_q16: u32,
    /// IDLE flag → the latest the last stop bit can have been: ticks(IDLE_BITS − 1).
    idle_to_stop_latest: u32,
    /// IDLE flag → the earliest the last stop bit can have been: ticks(IDLE_BITS + 1).
    idle_to_stop_earliest: u32,
    /// IDLE flag → T_SYN check ([`BitClock::tsyn_check_at`]).
    tsyn_after_idle: u32,
    /// Our last stop bit (TC) → T_SYN check: ticks(TSYN_PROOF_BITS).
    tsyn_after_stop: u32,
    /// The standard's min_TSDR floor (11 bit times).
    min_tsdr_floor: u32,
}

impl LineTicks {
    /// The table for `rate` on `clock`. Divides: call it at the rate switch, not per
    /// telegram. Out of line (the board builds one table per rate at start: one copy).
    #[inline(never)]
    pub const fn new(clock: BitClock, rate: Baudrate) -> Self {
        let bps = rate.bits_per_second() as u64;
        let q16 = ((clock.hz as u64) << 16).div_ceil(bps);
        let bit_q16 = if q16 > u32::MAX as u64 { u32::MAX } else { q16 as u32 };
        LineTicks {
            bit_q16,
            idle_to_stop_latest: clock.ticks(rate, IDLE_BITS - IDLE_UNCERTAINTY_BITS),
            idle_to_stop_earliest: clock.ticks(rate, IDLE_BITS + IDLE_UNCERTAINTY_BITS),
            tsyn_after_idle: clock.ticks(rate, TSYN_PROOF_BITS - IDLE_BITS + IDLE_UNCERTAINTY_BITS),
            tsyn_after_stop: clock.ticks(rate, TSYN_PROOF_BITS),
            min_tsdr_floor: clock.ticks(rate, BitTimes::MIN_TSDR_DEFAULT.0),
        }
    }

    /// Ticks of `bits` bit times, rounded up: never fewer than [`BitClock::ticks`], at most
    /// one more (multiply and shift; `bits` up to 65 535).
    #[inline(always)]
    pub const fn ticks_of(&self, bits: u32) -> u32 {
        let bits = if bits > 0xFFFF { 0xFFFF } else { bits };
        ((bits as u64 * self.bit_q16 as u64 + 0xFFFF) >> 16) as u32
    }

    /// When a quiet line has proven T_SYN after an IDLE flag seen at `idle_seen`.
    #[inline(always)]
    pub const fn tsyn_check_at(&self, idle_seen: u32) -> u32 {
        idle_seen.wrapping_add(self.tsyn_after_idle)
    }

    /// When a quiet line has proven T_SYN after our own last stop bit (TC seen at `stop`).
    #[inline(always)]
    pub const fn tsyn_check_after_stop(&self, stop: u32) -> u32 {
        stop.wrapping_add(self.tsyn_after_stop)
    }

    /// The earliest instant a response may start: min_TSDR (at least 11) after the latest the
    /// request's last stop bit can have been ([`BitClock::response_not_before`]).
    #[inline(always)]
    pub const fn response_not_before(&self, idle_seen: u32, min_tsdr: BitTimes) -> u32 {
        let gap =
            if min_tsdr.0 <= BitTimes::MIN_TSDR_DEFAULT.0 { self.min_tsdr_floor } else { self.ticks_of(min_tsdr.0) };
        idle_seen.wrapping_sub(self.idle_to_stop_latest).wrapping_add(gap)
    }

    /// The latest instant a response may start: `max_tsdr` (the GSD's, `pbcard::card::max_tsdr`)
    /// after the earliest the last stop bit can have been ([`BitClock::response_latest`];
    /// at most one tick later than it).
    #[inline(always)]
    pub const fn response_latest(&self, idle_seen: u32, max_tsdr: BitTimes) -> u32 {
        idle_seen.wrapping_sub(self.idle_to_stop_earliest).wrapping_add(self.ticks_of(max_tsdr.0))
    }
}

impl LineTicks {
    /// Where the request's last stop bit is when its end was found **by length** in a
    /// per-character receive interrupt (RXNE of the last character, `Step::Complete` of
    /// [`super::stream::Stream::push`]) with the timer read at `seen`: no IDLE wait, so the
    /// response may start 11 bit times (one IDLE character) earlier than with
    /// [`LineTicks::end_at_idle`].
    #[inline(always)]
    pub const fn end_at_last_char(&self, seen: u32) -> RequestEnd {
        // RXNE is set while the stop bit is sampled: it ends within one bit time. An RXNE not
        // served within one character is an overrun (ORE) and drops the telegram, so the stop
        // bit ended at most one character before `seen`. (Multiply and shift, no division.)
        RequestEnd {
            stop_latest: seen.wrapping_add(self.ticks_of(1)),
            stop_earliest: seen.wrapping_sub(self.ticks_of(BitTimes::CHAR.0)),
        }
    }

    /// Where the last stop bit is when the end was found by the USART's IDLE flag, the timer
    /// read at `idle_seen` after it (a DMA receiver; module documentation).
    #[inline(always)]
    pub const fn end_at_idle(&self, idle_seen: u32) -> RequestEnd {
        RequestEnd {
            stop_latest: idle_seen.wrapping_sub(self.idle_to_stop_latest),
            stop_earliest: idle_seen.wrapping_sub(self.idle_to_stop_earliest),
        }
    }

    /// The earliest instant a response to the request ending at `end` may start: min_TSDR
    /// (at least 11 bit times) after the latest its stop bit can be.
    #[inline(always)]
    pub const fn not_before(&self, end: RequestEnd, min_tsdr: BitTimes) -> u32 {
        let gap =
            if min_tsdr.0 <= BitTimes::MIN_TSDR_DEFAULT.0 { self.min_tsdr_floor } else { self.ticks_of(min_tsdr.0) };
        end.stop_latest.wrapping_add(gap)
    }

    /// The latest instant it may start: `max_tsdr` after the earliest its stop bit can be.
    #[inline(always)]
    pub const fn latest(&self, end: RequestEnd, max_tsdr: BitTimes) -> u32 {
        end.stop_earliest.wrapping_add(self.ticks_of(max_tsdr.0))
    }
}

/// The bounds of a request's last stop bit on the bit timer (ticks), from the event that
/// found the request's end ([`LineTicks::end_at_last_char`], [`LineTicks::end_at_idle`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct RequestEnd {
    /// The stop bit has ended by then (min_TSDR counts from here).
    pub stop_latest: u32,
    /// The stop bit ended no earlier (max_TSDR counts from here).
    pub stop_earliest: u32,
}

/// How a board's USART receives at one rate (issue 11 item 2; README "The response path").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum RxMode {
    /// One receive interrupt per character (≤ 1.5 Mbit/s: ≥ 704 CPU cycles per character at
    /// 96 MHz), the CPU reads the data register, every character through
    /// [`super::stream::Stream::push`]: the end of a request is found by its header's length
    /// at its last character — no IDLE wait.
    PerChar,
    /// A circular receive DMA with half/full-transfer events (≥ 3 Mbit/s, where a per-character
    /// interrupt would cost ≥ 30 % of the CPU at 3 Mbit/s and more above): the ring's bytes go
    /// through [`super::stream::Stream::piece`] at each event ([`super::ring::RingWalker`]),
    /// and the end of a request is found by the USART's IDLE flag (11 + 1 bit times after the
    /// last stop bit).
    Dma,
}

impl RxMode {
    /// The fastest rate received per character.
    pub const PER_CHAR_MAX_BPS: u32 = 1_500_000;

    /// The mode at `rate`.
    pub const fn for_rate(rate: Baudrate) -> Self {
        if rate.bits_per_second() <= Self::PER_CHAR_MAX_BPS {
            RxMode::PerChar
        } else {
            RxMode::Dma
        }
    }
}

/// Whether a timer compare armed for `at` has already passed, from the counter value `now`
/// read **after** the compare register was written (within half the wrap period). An
/// up-counting timer's compare fires only when the counter *becomes* equal to it: one armed
/// in the past fires after the 32-bit wrap (44.7 s at 96 MHz). The board must then act at
/// once (a software compare event, TIMx_EGR.CCxG).
#[inline(always)]
pub const fn compare_passed(now: u32, at: u32) -> bool {
    reached(now, at)
}

/// The reader of a circular DMA receive ring of `N` bytes: the bytes from the last read
/// position up to the DMA's write position form one segment ([`RingReader::take`]). After the
/// DMA was stopped and restarted at index 0 (a rate switch, a flash stall) [`RingReader::restart`]
/// forgets everything before — the stale bytes are never cut, never answered.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct RingReader<const N: usize> {
    read: usize,
}

impl<const N: usize> RingReader<N> {
    /// At index 0.
    pub const fn new() -> Self {
        RingReader { read: 0 }
    }

    /// The ring position of the first byte not yet taken.
    pub const fn position(&self) -> usize {
        self.read
    }

    /// The bytes from the read position up to `write` (the DMA's write position, taken
    /// modulo `N`) into `out`: returns how many bytes the segment has and how many of them
    /// were copied (more than `out` holds: an overlong segment, no telegram). The read
    /// position moves to `write`.
    pub fn take(&mut self, ring: &[u8; N], write: usize, out: &mut [u8]) -> (usize, usize) {
        let write = write % N;
        let n = (write + N - self.read) % N;
        let copied = n.min(out.len());
        let first = copied.min(N - self.read);
        out[..first].copy_from_slice(&ring[self.read..self.read + first]);
        out[first..copied].copy_from_slice(&ring[..copied - first]);
        self.read = write;
        (n, copied)
    }

    /// The DMA was restarted at index 0: nothing before counts.
    pub fn restart(&mut self) {
        self.read = 0;
    }
}

/// The USART status bits the receive gate looks at (RM0383 §19.6.1 USART_SR).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct RxFlags {
    /// IDLE: an idle character after a stop bit.
    pub idle: bool,
    /// Any of PE, FE, NF, ORE.
    pub error: bool,
}

/// What the board programs after the gate moved: RXNEIE, IDLEIE and PEIE + EIE.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RxEnables {
    /// RXNEIE: one interrupt at the first character of the next segment.
    pub rxne: bool,
    /// IDLEIE: the end of the segment in progress.
    pub idle: bool,
    /// PEIE and EIE: character errors.
    pub errors: bool,
}

/// What one USART interrupt means for the receiver.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct RxIrq {
    /// A character error to count (the segment is corrupt).
    pub error: bool,
    /// The segment is complete: cut it now.
    pub segment_end: bool,
}

/// The USART receive interrupts of a DMA receiver without a CPU read of the data register
/// (issue 11 item 3f): on the STM32F4 the IDLE and error flags clear only by "a read of
/// USART_SR followed by a read of USART_DR" (RM0383 §19.6.1), and a CPU read of DR while the
/// DMA owns the receiver can take a character from under the DMA. So the CPU only reads SR;
/// the DMA's own read of DR for the next character completes the clearing sequence. Until
/// then the flag stays set, so its interrupt is disabled and the next character's RXNE
/// interrupt (one per segment: RXNEIE is switched off again at once) re-enables IDLE and the
/// errors — by then the stale flags are cleared.
///
/// States: *waiting for the first character* (RXNEIE on) → *in a segment* (IDLEIE, PEIE/EIE
/// on) → IDLE → waiting again. A character error disables PEIE/EIE for the rest of the segment
/// (the segment is dropped anyway; counted once). Not verified on silicon: it relies on the
/// DMA's DR read completing the SR → DR sequence, as the reference manual words it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RxIrqGate {
    in_segment: bool,
    errors: bool,
}

impl Default for RxIrqGate {
    fn default() -> Self {
        Self::new()
    }
}

impl RxIrqGate {
    /// After a receiver (re)start: waiting for the first character, errors enabled once it
    /// comes.
    pub const fn new() -> Self {
        RxIrqGate { in_segment: false, errors: false }
    }

    /// The interrupt enables for the current state.
    pub const fn enables(&self) -> RxEnables {
        RxEnables { rxne: !self.in_segment, idle: self.in_segment, errors: self.in_segment && self.errors }
    }

    /// One USART interrupt with the status `sr` (read once, by the CPU, never followed by a
    /// CPU read of DR).
    pub fn on_interrupt(&mut self, sr: RxFlags) -> RxIrq {
        let mut out = RxIrq::default();
        if !self.in_segment {
            // RXNE of the first character: the DMA has read DR after our last SR read, which
            // cleared IDLE and the error flags of the last segment. A flag still set was never
            // read before (e.g. IDLE after the receiver was switched back on): this SR read
            // arms its clearing; wait for the next character.
            if !sr.idle {
                self.in_segment = true;
                self.errors = true;
                if sr.error {
                    out.error = true;
                    self.errors = false;
                }
            }
            return out;
        }
        if self.errors && sr.error {
            out.error = true;
            self.errors = false;
        }
        if sr.idle {
            out.segment_end = true;
            self.in_segment = false;
        }
        out
    }

    /// After the segment was cut: if characters have arrived since its IDLE (`moved`) and
    /// IDLE reads clear again (`sr`), the next segment has begun — switch to it at once
    /// instead of waiting for an RXNE that has already passed.
    pub fn after_segment(&mut self, moved: bool, sr: RxFlags) {
        if !self.in_segment && moved && !sr.idle {
            self.in_segment = true;
            self.errors = !sr.error;
        }
    }

    /// The receiver was switched off (our response) or restarted: wait for a first character.
    pub fn restart(&mut self) {
        *self = Self::new();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const T: BitClock = BitClock { hz: 96_000_000 };

    #[test]
    fn the_table_matches_the_dividing_clock_on_every_rate() {
        for rate in Baudrate::ALL {
            let t = LineTicks::new(T, rate);
            for idle_seen in [0u32, 12_345, u32::MAX - 3] {
                assert_eq!(t.tsyn_check_at(idle_seen), T.tsyn_check_at(rate, idle_seen), "{rate:?}");
                for max in [60u32, 150, 1000] {
                    let exact = T.response_latest(rate, idle_seen, BitTimes(max));
                    assert!(t.response_latest(idle_seen, BitTimes(max)).wrapping_sub(exact) <= 1, "{rate:?} {max}");
                }
                for min in [0u32, 11, 12, 20, 150, 255] {
                    let exact = T.response_not_before(rate, idle_seen, BitTimes(min));
                    let fast = t.response_not_before(idle_seen, BitTimes(min));
                    // Never earlier than the exact value, at most one tick later.
                    assert!(fast.wrapping_sub(exact) <= 1, "{rate:?} {min}: {fast} vs {exact}");
                }
            }
            assert_eq!(t.tsyn_check_after_stop(7), 7 + T.ticks(rate, TSYN_PROOF_BITS));
        }
    }

    #[test]
    fn the_end_by_length_gains_the_idle_character() {
        for rate in Baudrate::ALL {
            let t = LineTicks::new(T, rate);
            let bit = T.ticks(rate, 1);
            // The last stop bit ends at tick 1 000 000 + bit: RXNE mid-stop-bit, served `lat` later (within the character);
            // IDLE one character after the stop bit.
            for lat in [0u32, bit, 9 * bit] {
                let stop = 1_000_000 + bit;
                let seen = 1_000_000 + bit / 2 + lat;
                let e = t.end_at_last_char(seen);
                assert!(e.stop_latest >= stop && e.stop_earliest <= stop, "{rate:?}");
                let idle = t.end_at_idle(stop + 11 * bit + lat);
                for min in [0u32, 11, 20] {
                    assert!(t.not_before(e, BitTimes(min)) >= stop + min.max(11) * bit);
                    // The same min_TSDR window (never later than by IDLE); what the end by length
                    // gains is the decision 11 bit times earlier (at RXNE, not at IDLE).
                    if lat == 0 {
                        assert!(t.not_before(e, BitTimes(min)) <= t.not_before(idle, BitTimes(min)));
                    }
                }
                assert!(t.latest(e, BitTimes(200)) <= stop + 200 * bit + 1);
                assert_eq!(
                    t.not_before(idle, BitTimes(20)),
                    t.response_not_before(stop + 11 * bit + lat, BitTimes(20))
                );
                assert_eq!(t.latest(idle, BitTimes(200)), t.response_latest(stop + 11 * bit + lat, BitTimes(200)));
            }
            let mode = RxMode::for_rate(rate);
            assert_eq!(mode == RxMode::PerChar, rate.bits_per_second() <= 1_500_000, "{rate:?}");
        }
    }

    #[test]
    fn ticks_of_never_short_at_most_one_long() {
        for rate in Baudrate::ALL {
            let t = LineTicks::new(T, rate);
            for bits in 0..=1000u32 {
                let exact = T.ticks(rate, bits);
                let fast = t.ticks_of(bits);
                assert!(fast >= exact && fast <= exact + 1, "{rate:?} {bits}: {fast} vs {exact}");
            }
        }
        // 12 Mbit/s at 96 MHz: exactly 8 ticks per bit.
        assert_eq!(LineTicks::new(T, Baudrate::B12M).ticks_of(33), 264);
    }

    #[test]
    fn a_compare_in_the_past_is_due_now_also_across_the_wrap() {
        assert!(compare_passed(100, 100));
        assert!(compare_passed(101, 100));
        assert!(!compare_passed(99, 100));
        // Armed just before the wrap, read just after it: passed.
        assert!(compare_passed(3, u32::MAX - 5));
        // Armed just after the wrap, read just before it: still ahead.
        assert!(!compare_passed(u32::MAX - 3, 10));
        // The segment copy took longer than T_SYN at 12 Mbit/s (the bug of issue 11): due.
        let t = LineTicks::new(T, Baudrate::B12M);
        let idle_seen = u32::MAX - 100;
        let at = t.tsyn_check_at(idle_seen);
        let after_copy = idle_seen.wrapping_add(37 * 11 * 8);
        assert!(compare_passed(after_copy, at));
        assert!(!compare_passed(idle_seen, at));
    }

    #[test]
    fn ring_segments_wrap_and_restart_forgets() {
        let mut ring = [0u8; 8];
        for (i, b) in ring.iter_mut().enumerate() {
            *b = i as u8;
        }
        let mut r = RingReader::<8>::new();
        let mut out = [0u8; 16];
        assert_eq!(r.take(&ring, 5, &mut out), (5, 5));
        assert_eq!(&out[..5], &[0, 1, 2, 3, 4]);
        // Across the end of the ring.
        assert_eq!(r.take(&ring, 2, &mut out), (5, 5));
        assert_eq!(&out[..5], &[5, 6, 7, 0, 1]);
        assert_eq!(r.take(&ring, 2, &mut out), (0, 0), "nothing new");
        // Longer than the output: counted, cut.
        let mut small = [0u8; 3];
        assert_eq!(r.take(&ring, 7, &mut small), (5, 3));
        assert_eq!(small, [2, 3, 4]);
        // NDTR reload reads as the full ring: write position N is index 0.
        assert_eq!(r.take(&ring, 8, &mut out), (1, 1));
        assert_eq!(r.position(), 0);
        // A restart (DMA at index 0 again) after bytes were received meanwhile: the stale bytes
        // before the restart are never handed out.
        r.take(&ring, 6, &mut out);
        r.restart();
        assert_eq!(r.position(), 0);
        assert_eq!(r.take(&ring, 2, &mut out), (2, 2));
        assert_eq!(&out[..2], &[0, 1]);
    }

    const IDLE: RxFlags = RxFlags { idle: true, error: false };
    const NONE: RxFlags = RxFlags { idle: false, error: false };
    const ERR: RxFlags = RxFlags { idle: false, error: true };

    #[test]
    fn the_rx_gate_never_needs_a_data_register_read() {
        let mut g = RxIrqGate::new();
        assert_eq!(g.enables(), RxEnables { rxne: true, idle: false, errors: false });
        // First character: the DMA read DR, IDLE is clear.
        assert_eq!(g.on_interrupt(NONE), RxIrq::default());
        assert_eq!(g.enables(), RxEnables { rxne: false, idle: true, errors: true });
        // End of the segment.
        assert_eq!(g.on_interrupt(IDLE), RxIrq { error: false, segment_end: true });
        assert_eq!(g.enables(), RxEnables { rxne: true, idle: false, errors: false });
        // IDLE still set at the next RXNE (never read before): wait for one more character.
        assert_eq!(g.on_interrupt(IDLE), RxIrq::default());
        assert!(g.enables().rxne);
        assert_eq!(g.on_interrupt(NONE), RxIrq::default());
        assert!(g.enables().idle);
    }

    #[test]
    fn the_rx_gate_counts_an_error_once_per_segment() {
        let mut g = RxIrqGate::new();
        g.on_interrupt(NONE);
        assert_eq!(g.on_interrupt(ERR), RxIrq { error: true, segment_end: false });
        assert!(!g.enables().errors, "no interrupt storm on a flag only the DMA can clear");
        // The stale error flag at the IDLE is not counted again.
        assert_eq!(g.on_interrupt(RxFlags { idle: true, error: true }), RxIrq { error: false, segment_end: true });
        // The next segment's first character: errors on again.
        g.on_interrupt(NONE);
        assert!(g.enables().errors);
        // An error with the first character itself.
        g.on_interrupt(IDLE);
        assert_eq!(g.on_interrupt(ERR), RxIrq { error: true, segment_end: false });
        assert!(g.enables().idle && !g.enables().errors);
    }

    #[test]
    fn the_rx_gate_catches_a_segment_that_began_during_the_cut() {
        let mut g = RxIrqGate::new();
        g.on_interrupt(NONE);
        g.on_interrupt(IDLE);
        // Nothing arrived: keep waiting for RXNE.
        g.after_segment(false, IDLE);
        assert!(g.enables().rxne);
        // Characters arrived but IDLE still reads set: not yet cleared, keep waiting.
        g.after_segment(true, IDLE);
        assert!(g.enables().rxne);
        // Characters arrived and IDLE is clear: in the next segment already.
        g.after_segment(true, NONE);
        assert_eq!(g.enables(), RxEnables { rxne: false, idle: true, errors: true });
        g.restart();
        assert_eq!(g, RxIrqGate::new());
    }
}
