//! The decisions of a DMA receiver and of the bit timer, without the hardware (reference §1.4
//! "character and telegram timing", §1.3 T_SYN / min_TSDR; ARCHITECTURE §4).
//!
//! A DMA receiver does not see characters one by one: the USART writes them into a buffer, and
//! the board learns about them at a few events only — the USART's IDLE flag (the line stayed
//! idle for one character = 11 bit times after a stop bit), character errors (PE, FE, NF,
//! ORE), and bit-timer compares. This module turns those events into telegrams and times:
//!
//! * [`expected_len`] — the length of a telegram from its first bytes (SD1 6, SD3 14, SD4 3,
//!   SC 1, SD2 LE + 6 once LE, LEr and the repeated SD are in).
//! * [`Receiver`] — cuts the bytes between two IDLE events (a *segment*) into telegrams,
//!   drops segments with character errors, truncated telegrams and garbage, and after such a
//!   loss accepts telegrams again only after an idle of at least T_SYN (33 bit times)
//!   ([`Receiver::on_tsyn`]). Every telegram of the bus goes through it — requests for other
//!   stations, tokens, responses of other slaves — so the receiver never loses step.
//! * [`BitClock`] — bit times as ticks of a free-running 32-bit timer (TIM5 at 96 MHz on the
//!   F411), and the three instants the board programs its compares with:
//!   [`BitClock::response_not_before`] (min_TSDR after the request's last stop bit),
//!   [`BitClock::tsyn_check_at`] (when a quiet line proves T_SYN) and
//!   [`BitClock::response_latest`] (max_TSDR of the GSD, `pbcard::card::max_tsdr`).
//! * [`tx_plan`] — start the pre-staged response now, at a timer compare, or not at all.
//! * [`classify`] — what a telegram means for the baud-rate search and supervision
//!   ([`super::autobaud::Autobaud::on_frame`]).
//!
//! **Where the IDLE flag puts the last stop bit.** The USART sets IDLE after one complete idle
//! character (11 bit times of mark) following the last stop bit; its bit sampling puts the
//! flag within ±1 bit time of that ([`IDLE_BITS`], [`IDLE_UNCERTAINTY_BITS`]). The timer is read
//! in the interrupt, after the flag: so `idle_seen − (IDLE_BITS − IDLE_UNCERTAINTY_BITS)` is a
//! time *at or after* the last stop bit, and every "not before" computed from it is safe.
//!
//! **Why IDLE is a telegram boundary.** PROFIBUS allows no idle inside a telegram (reference
//! §1.4), and every telegram is followed by at least min_TSDR ≥ 11 bit times (before a
//! response) or T_ID ≥ 33 bit times (after a response, SC or token): one IDLE per telegram.
//! Back-to-back telegrams without that gap would break the standard; they are still cut
//! correctly by length.

use super::autobaud::Autobaud;
use crate::fdl::telegram::{self, Decoded, Telegram};
use crate::time::{Baudrate, BitTimes, Instant};

/// Bit times of idle line after the last stop bit at which the USART raises IDLE (one idle
/// 11-bit character).
pub const IDLE_BITS: u32 = BitTimes::CHAR.0;
/// How far the IDLE flag may be from [`IDLE_BITS`] (start-bit detection and mid-bit sampling).
pub const IDLE_UNCERTAINTY_BITS: u32 = 1;
/// Idle bit times a quiet line must show after the last stop bit before T_SYN is taken as
/// proven: T_SYN plus one character, because a character whose start bit came before T_SYN is
/// invisible to a DMA receiver until its stop bit.
pub const TSYN_PROOF_BITS: u32 = BitTimes::TSYN.0 + BitTimes::CHAR.0;

/// What the first bytes of a telegram tell about its length.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum Expect {
    /// The telegram is this many bytes long (start delimiter included).
    Len(usize),
    /// At least this many bytes are needed to know the length (SD2 before LE, LEr and the
    /// repeated SD are in).
    More(usize),
    /// The bytes cannot start a telegram (unknown start delimiter, SD2 with LE out of
    /// 4..=249, LE ≠ LEr, or no repeated SD).
    NotAFrame,
}

/// The length of the telegram starting at `head[0]` (reference §2.1): SD1 6, SD3 14, SD4 3,
/// SC 1, SD2 LE + 6. The same checks as [`telegram::frame_len`], which the framer uses.
pub fn expected_len(head: &[u8]) -> Expect {
    match telegram::frame_len(head) {
        Ok(Some(n)) => Expect::Len(n),
        Ok(None) if head.is_empty() => Expect::More(1),
        Ok(None) => Expect::More(4),
        Err(_) => Expect::NotAFrame,
    }
}

/// Counters of the DMA receiver (diagnosis; later in the DPM status block).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct RxStats {
    /// Telegrams handed on (any kind, any address; the checksum is checked later).
    pub frames: u32,
    /// Segments dropped because a character had a parity/framing/noise/overrun error.
    pub corrupt: u32,
    /// Segments that ended inside a telegram (a gap in a telegram).
    pub truncated: u32,
    /// Segments whose bytes were no telegram.
    pub garbage: u32,
    /// Segments dropped while waiting for T_SYN after a loss, a reset or a rate change.
    pub unsynced: u32,
    /// Idle gaps of at least T_SYN seen.
    pub tsyn: u32,
}

impl RxStats {
    /// Telegrams lost on the line, for `STATUS.CORRUPT_FRAMES` (DPM layout, docs/DPM.md;
    /// `pbcard::dpm::Link::set_line_errors`): segments with a character error (parity,
    /// framing, noise, overrun), telegrams cut off by an idle line, and bytes that could not
    /// start a telegram (wrapping sum). Segments dropped only while waiting for T_SYN are not
    /// counted: the loss that made the receiver wait is. Telegrams with a wrong checksum are
    /// counted by the FDL station ([`crate::fdl::station::StationStats::invalid`]).
    pub const fn lost_frames(&self) -> u32 {
        self.corrupt.wrapping_add(self.truncated).wrapping_add(self.garbage)
    }
}

/// How a segment ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum SegmentEnd {
    /// All bytes were whole telegrams (possibly none: an empty segment).
    Clean,
    /// Dropped: a character error in the segment.
    Corrupt,
    /// The last telegram was cut off by the idle line (the telegrams before it were handed on).
    Truncated,
    /// Bytes that cannot start a telegram (the telegrams before them were handed on).
    Garbage,
    /// Dropped: the receiver waits for T_SYN.
    Unsynced,
}

/// The telegram cutter of a DMA receiver (see the module documentation).
#[derive(Debug, Clone, Default)]
pub struct Receiver {
    synced: bool,
    stats: RxStats,
}

impl Receiver {
    /// A receiver after reset: nothing is accepted before the first T_SYN.
    pub const fn new() -> Self {
        Receiver {
            synced: false,
            stats: RxStats { frames: 0, corrupt: 0, truncated: 0, garbage: 0, unsynced: 0, tsyn: 0 },
        }
    }

    /// Whether telegrams are accepted (a T_SYN has been seen since the last loss).
    pub fn is_synced(&self) -> bool {
        self.synced
    }

    /// Counters.
    pub fn stats(&self) -> RxStats {
        self.stats
    }

    /// The receiver was restarted (rate change, buffer overrun, flash stall): wait for T_SYN.
    pub fn reset(&mut self) {
        self.synced = false;
    }

    /// The line was idle for at least T_SYN after the last stop bit: the next start delimiter
    /// is trustworthy.
    pub fn on_tsyn(&mut self) {
        self.stats.tsyn = self.stats.tsyn.wrapping_add(1);
        self.synced = true;
    }

    /// The bytes received between two IDLE events; `corrupt` when a character error was
    /// flagged meanwhile. Every whole telegram is passed to `on_frame` in line order; the
    /// return value says how the segment ended. Anything but [`SegmentEnd::Clean`] drops the
    /// rest and waits for T_SYN.
    pub fn segment(&mut self, bytes: &[u8], corrupt: bool, mut on_frame: impl FnMut(&[u8])) -> SegmentEnd {
        // A character error counts even when no byte of the segment reached the buffer (the
        // error handling may have taken the only one).
        if corrupt {
            self.stats.corrupt = self.stats.corrupt.wrapping_add(1);
            self.synced = false;
            return SegmentEnd::Corrupt;
        }
        if bytes.is_empty() {
            return SegmentEnd::Clean;
        }
        if !self.synced {
            self.stats.unsynced = self.stats.unsynced.wrapping_add(1);
            return SegmentEnd::Unsynced;
        }
        let mut rest = bytes;
        while !rest.is_empty() {
            match expected_len(rest) {
                Expect::Len(n) if n <= rest.len() => {
                    self.stats.frames = self.stats.frames.wrapping_add(1);
                    on_frame(&rest[..n]);
                    rest = &rest[n..];
                }
                Expect::Len(_) | Expect::More(_) => {
                    self.stats.truncated = self.stats.truncated.wrapping_add(1);
                    self.synced = false;
                    return SegmentEnd::Truncated;
                }
                Expect::NotAFrame => {
                    self.stats.garbage = self.stats.garbage.wrapping_add(1);
                    self.synced = false;
                    return SegmentEnd::Garbage;
                }
            }
        }
        SegmentEnd::Clean
    }
}

/// A free-running up-counting 32-bit timer as the bit timer: `hz` ticks per second. All
/// instants are raw counter values; differences are taken with wrapping arithmetic (valid for
/// half the wrap period, 22 s at 96 MHz).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct BitClock {
    /// Timer ticks per second.
    pub hz: u32,
}

impl BitClock {
    /// Ticks of `bits` bit times at `rate`, rounded up (a wait is never shorter than asked).
    /// Out of line: it divides (the rate switch's tables, [`super::timing::LineTicks::new`],
    /// not per telegram), and inlined LLVM specialises the 64-bit division for every rate of
    /// every caller (2 KiB of flash).
    #[inline(never)]
    pub const fn ticks(self, rate: Baudrate, bits: u32) -> u32 {
        let bps = rate.bits_per_second() as u64;
        let t = (bits as u64 * self.hz as u64).div_ceil(bps);
        if t > u32::MAX as u64 / 2 {
            u32::MAX / 2
        } else {
            t as u32
        }
    }

    /// Whole bit times in `ticks` at `rate`, rounded down.
    pub const fn bits(self, rate: Baudrate, ticks: u32) -> u32 {
        (ticks as u64 * rate.bits_per_second() as u64 / self.hz as u64) as u32
    }

    /// The latest instant the request's last stop bit can have ended, from the timer value
    /// read after the IDLE flag (module documentation).
    pub const fn last_stop_at(self, rate: Baudrate, idle_seen: u32) -> u32 {
        idle_seen.wrapping_sub(self.ticks(rate, IDLE_BITS - IDLE_UNCERTAINTY_BITS))
    }

    /// The earliest instant a response may start: min_TSDR after the last stop bit (at least
    /// [`BitTimes::MIN_TSDR_DEFAULT`], the standard's floor).
    pub const fn response_not_before(self, rate: Baudrate, idle_seen: u32, min_tsdr: BitTimes) -> u32 {
        let gap = if min_tsdr.0 < BitTimes::MIN_TSDR_DEFAULT.0 { BitTimes::MIN_TSDR_DEFAULT.0 } else { min_tsdr.0 };
        self.last_stop_at(rate, idle_seen).wrapping_add(self.ticks(rate, gap))
    }

    /// The latest instant a response may start: the GSD's max_TSDR after the last stop bit,
    /// counted from the *earliest* the stop bit can have been.
    pub const fn response_latest(self, rate: Baudrate, idle_seen: u32, max_tsdr: BitTimes) -> u32 {
        let last_stop_earliest = idle_seen.wrapping_sub(self.ticks(rate, IDLE_BITS + IDLE_UNCERTAINTY_BITS));
        last_stop_earliest.wrapping_add(self.ticks(rate, max_tsdr.0))
    }

    /// When to look again: if no character has arrived by then, the line has been idle for at
    /// least T_SYN after the last stop bit ([`TSYN_PROOF_BITS`] counted from the latest the
    /// stop bit can have been).
    pub const fn tsyn_check_at(self, rate: Baudrate, idle_seen: u32) -> u32 {
        // last stop ≤ idle_seen − (IDLE_BITS − 1), so check at idle_seen + TSYN_PROOF − IDLE + 1.
        let after_idle = TSYN_PROOF_BITS - IDLE_BITS + IDLE_UNCERTAINTY_BITS;
        idle_seen.wrapping_add(self.ticks(rate, after_idle))
    }
}

/// `a` is at or after `b` on a wrapping 32-bit timer (within half the wrap period).
pub const fn reached(a: u32, b: u32) -> bool {
    (a.wrapping_sub(b) as i32) >= 0
}

/// What to do with a response the protocol core returned.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum TxPlan {
    /// min_TSDR has passed: drive the bus and start now.
    Now,
    /// Arm the timer compare for this instant and start there.
    At(u32),
    /// Do not send (the reason is counted).
    Drop(TxDrop),
}

/// Why a response is not sent.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum TxDrop {
    /// Characters arrived after the request: the master has moved on (or it was not a request
    /// to us at all); answering now would collide.
    LineActive,
    /// Later than the GSD's max_TSDR: the master may already be repeating the request.
    TooLate,
    /// A response is still on the wire.
    Busy,
}

/// The transmit decision for a response ready at `now` (all timer ticks): `line_quiet` = no
/// character has arrived since the request's IDLE, `tx_busy` = a response is still being sent.
pub const fn tx_plan(now: u32, not_before: u32, latest: u32, line_quiet: bool, tx_busy: bool) -> TxPlan {
    if tx_busy {
        TxPlan::Drop(TxDrop::Busy)
    } else if !line_quiet {
        TxPlan::Drop(TxDrop::LineActive)
    } else if reached(now, not_before) {
        if reached(latest, now) {
            TxPlan::Now
        } else {
            TxPlan::Drop(TxDrop::TooLate)
        }
    } else {
        TxPlan::At(not_before)
    }
}

/// What one telegram means for the baud-rate search and supervision.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct FrameClass {
    /// An error-free SD1/SD2/SD3 telegram (any address): locks the search.
    pub ok_sd123: bool,
    /// Such a telegram addressed to `own` (not the broadcast): retriggers Baud_Control.
    pub to_us: bool,
    /// Not a valid telegram (checksum, delimiters): [`super::autobaud::Autobaud::on_garbage`].
    pub invalid: bool,
}

/// Classify one telegram cut by the [`Receiver`] for station `own` (the address extension bit
/// of DA is ignored, as the FDL station does).
pub fn classify(frame: &[u8], own: u8) -> FrameClass {
    match telegram::decode(frame) {
        Decoded::Frame(Telegram::Data(t), n) if n == frame.len() => {
            FrameClass { ok_sd123: true, to_us: t.da == own, invalid: false }
        }
        Decoded::Frame(_, n) if n == frame.len() => FrameClass::default(),
        _ => FrameClass { invalid: true, ..FrameClass::default() },
    }
}

/// The rate control a telegram is reported to: the ASIC-style search and supervision
/// ([`Autobaud`]) on a real line, a fixed rate where there is no line timing (QEMU).
pub trait RateControl {
    /// A telegram at the current rate (see [`Autobaud::on_frame`]).
    fn on_frame(&mut self, now: Instant, ok_sd123: bool, to_us: bool);
    /// A character error or an invalid telegram (see [`Autobaud::on_garbage`]).
    fn on_garbage(&mut self, now: Instant);
    /// The locked rate; responses go out only while there is one.
    fn detected(&self) -> Option<Baudrate>;
}

impl RateControl for Autobaud {
    fn on_frame(&mut self, now: Instant, ok_sd123: bool, to_us: bool) {
        Autobaud::on_frame(self, now, ok_sd123, to_us);
    }
    fn on_garbage(&mut self, now: Instant) {
        Autobaud::on_garbage(self, now);
    }
    fn detected(&self) -> Option<Baudrate> {
        Autobaud::detected(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fdl::telegram::{emit, FunctionCode, Header, MAX_FRAME_LEN, SC, SD1, SD2, SD3, SD4};
    use crate::node::answer;
    use proptest::prelude::*;
    use std::vec::Vec;

    fn frame(da: u8, pdu: &[u8]) -> Vec<u8> {
        let mut out = [0u8; MAX_FRAME_LEN];
        let hdr = Header { da, sa: 2, fc: FunctionCode(0x7D), dsap: None, ssap: None };
        let n = emit(&mut out, &hdr, pdu).unwrap();
        out[..n].to_vec()
    }

    fn cut(r: &mut Receiver, bytes: &[u8], corrupt: bool) -> (Vec<Vec<u8>>, SegmentEnd) {
        let mut v = Vec::new();
        let end = r.segment(bytes, corrupt, |f| v.push(f.to_vec()));
        (v, end)
    }

    fn synced() -> Receiver {
        let mut r = Receiver::new();
        r.on_tsyn();
        r
    }

    #[test]
    fn lengths_from_the_first_bytes() {
        assert_eq!(expected_len(&[]), Expect::More(1));
        assert_eq!(expected_len(&[SD1]), Expect::Len(6));
        assert_eq!(expected_len(&[SD3]), Expect::Len(14));
        assert_eq!(expected_len(&[SD4]), Expect::Len(3));
        assert_eq!(expected_len(&[SC]), Expect::Len(1));
        assert_eq!(expected_len(&[SD2]), Expect::More(4));
        assert_eq!(expected_len(&[SD2, 5]), Expect::More(4));
        assert_eq!(expected_len(&[SD2, 5, 5]), Expect::More(4));
        assert_eq!(expected_len(&[SD2, 5, 5, SD2]), Expect::Len(11));
        assert_eq!(expected_len(&[SD2, 249, 249, SD2]), Expect::Len(255));
        assert_eq!(expected_len(&[SD2, 4, 4, SD2]), Expect::Len(10));
        assert_eq!(expected_len(&[SD2, 3]), Expect::NotAFrame);
        assert_eq!(expected_len(&[SD2, 250]), Expect::NotAFrame);
        assert_eq!(expected_len(&[SD2, 5, 6]), Expect::NotAFrame);
        assert_eq!(expected_len(&[SD2, 5, 5, 0x10]), Expect::NotAFrame);
        assert_eq!(expected_len(&[0x00]), Expect::NotAFrame);
        assert_eq!(expected_len(&[0x16]), Expect::NotAFrame);
    }

    #[test]
    fn nothing_before_the_first_tsyn() {
        let mut r = Receiver::new();
        let f = frame(5, &[1, 2]);
        assert_eq!(cut(&mut r, &f, false), (vec![], SegmentEnd::Unsynced));
        r.on_tsyn();
        assert_eq!(cut(&mut r, &f, false), (vec![f.clone()], SegmentEnd::Clean));
        assert_eq!(r.stats().unsynced, 1);
        assert_eq!(r.stats().frames, 1);
    }

    #[test]
    fn every_kind_of_telegram_is_cut_and_handed_on() {
        let mut r = synced();
        let token = [SD4, 3, 2];
        let sd1 = frame(9, &[]);
        let sd2 = frame(9, &[1, 2, 3]);
        let sd3 = frame(9, &[0; 8]);
        assert_eq!(sd1[0], SD1);
        assert_eq!(sd3[0], SD3);
        for f in [&token[..], &[SC][..], &sd1, &sd2, &sd3] {
            assert_eq!(cut(&mut r, f, false), (vec![f.to_vec()], SegmentEnd::Clean));
        }
        // Back to back without IDLE between them (not standard, still cut by length).
        let both = [&sd2[..], &token[..], &[SC][..]].concat();
        assert_eq!(cut(&mut r, &both, false).0, vec![sd2.clone(), token.to_vec(), vec![SC]]);
        assert!(r.is_synced());
    }

    #[test]
    fn a_character_error_drops_the_segment_until_tsyn() {
        let mut r = synced();
        let f = frame(5, &[1, 2, 3]);
        assert_eq!(cut(&mut r, &f, true), (vec![], SegmentEnd::Corrupt));
        // The next telegram 11 bit times later is not trusted (no T_SYN in between) ...
        assert_eq!(cut(&mut r, &f, false), (vec![], SegmentEnd::Unsynced));
        // ... the one after a T_SYN gap is.
        r.on_tsyn();
        assert_eq!(cut(&mut r, &f, false).0, vec![f.clone()]);
        assert_eq!(r.stats().corrupt, 1);
        // An error whose only character never reached the ring still desynchronises.
        assert_eq!(cut(&mut r, &[], true), (vec![], SegmentEnd::Corrupt));
        assert!(!r.is_synced());
    }

    #[test]
    fn lost_frames_count_errors_cuts_and_garbage_not_the_wait_for_tsyn() {
        let mut r = synced();
        let f = frame(5, &[1, 2, 3]);
        cut(&mut r, &f, true); // character error
        cut(&mut r, &f, false); // unsynced: not a loss of its own
        r.on_tsyn();
        cut(&mut r, &f[..3], false); // truncated
        r.on_tsyn();
        cut(&mut r, &[0x00], false); // garbage
        r.on_tsyn();
        cut(&mut r, &f, false); // clean
        let s = r.stats();
        assert_eq!((s.corrupt, s.unsynced, s.truncated, s.garbage, s.frames), (1, 1, 1, 1, 1));
        assert_eq!(s.lost_frames(), 3);
        let wrap = RxStats { corrupt: u32::MAX, garbage: 2, ..RxStats::default() };
        assert_eq!(wrap.lost_frames(), 1);
    }

    #[test]
    fn truncated_and_garbage_segments_desynchronise() {
        let mut r = synced();
        let f = frame(5, &[1, 2, 3]);
        assert_eq!(cut(&mut r, &f[..f.len() - 1], false), (vec![], SegmentEnd::Truncated));
        assert!(!r.is_synced());
        r.on_tsyn();
        let g = [&f[..], &[0x00, 0x01][..]].concat();
        assert_eq!(cut(&mut r, &g, false), (vec![f.clone()], SegmentEnd::Garbage));
        assert!(!r.is_synced());
        r.on_tsyn();
        assert_eq!(cut(&mut r, &[], false), (vec![], SegmentEnd::Clean));
        assert!(r.is_synced(), "an empty segment changes nothing");
        r.reset();
        assert!(!r.is_synced());
    }

    proptest! {
        /// Any bus traffic cut into segments: every handed-on frame is exactly one telegram
        /// of the stream in order, nothing panics, and after garbage a T_SYN and a clean
        /// frame always come through.
        #[test]
        fn segments_never_lose_step(
            pdus in proptest::collection::vec(proptest::collection::vec(any::<u8>(), 0..60), 1..8),
            garbage in proptest::collection::vec(any::<u8>(), 0..40),
            corrupt_at in proptest::option::of(0usize..8),
        ) {
            let mut r = synced();
            let frames: Vec<Vec<u8>> = pdus.iter().enumerate().map(|(i, p)| frame(i as u8, p)).collect();
            for (i, f) in frames.iter().enumerate() {
                let bad = corrupt_at == Some(i);
                let (got, end) = cut(&mut r, f, bad);
                if bad {
                    prop_assert_eq!(end, SegmentEnd::Corrupt);
                    prop_assert!(got.is_empty());
                    r.on_tsyn();
                } else {
                    prop_assert_eq!(got, vec![f.clone()]);
                }
            }
            let _ = cut(&mut r, &garbage, false);
            r.on_tsyn();
            let last = frame(7, &[1, 2, 3]);
            prop_assert_eq!(cut(&mut r, &last, false).0, vec![last.clone()]);
        }

        /// Random bytes never panic the cutter and every frame it hands on has the length its
        /// header announces.
        #[test]
        fn random_bytes(bytes in proptest::collection::vec(any::<u8>(), 0..600)) {
            let mut r = synced();
            let mut ok = true;
            r.segment(&bytes, false, |f| ok &= expected_len(f) == Expect::Len(f.len()));
            prop_assert!(ok);
        }
    }

    const T: BitClock = BitClock { hz: 96_000_000 };

    #[test]
    fn bit_times_in_timer_ticks() {
        assert_eq!(T.ticks(Baudrate::B12M, 1), 8);
        assert_eq!(T.ticks(Baudrate::B12M, 33), 264);
        assert_eq!(T.ticks(Baudrate::B1500k, 11), 704);
        assert_eq!(T.ticks(Baudrate::B9600, 1), 10_000);
        // 45.45 kbit/s: 96 MHz / 45 450 = 2112.2 → rounded up.
        assert_eq!(T.ticks(Baudrate::B45450, 1), 2113);
        for rate in Baudrate::ALL {
            for bits in [1, 11, 33, 255, 800] {
                let t = T.ticks(rate, bits);
                assert!(T.bits(rate, t) >= bits, "{rate:?} {bits}");
                assert!(T.bits(rate, t.saturating_sub(1)) <= bits);
            }
        }
    }

    #[test]
    fn min_tsdr_is_kept_from_the_latest_stop_bit() {
        for rate in Baudrate::ALL {
            let bit = T.ticks(rate, 1);
            // The IDLE flag came exactly 11 bits after the stop bit at tick 1000 and the
            // interrupt read the timer `lat` ticks later.
            for lat in [0u32, 12, 200] {
                let stop = 1000u32;
                let idle_seen = stop + 11 * bit + lat;
                for min in [0u32, 11, 12, 20, 255] {
                    let nb = T.response_not_before(rate, idle_seen, BitTimes(min));
                    // Never earlier than min_TSDR (≥ 11) after the true stop bit, even when IDLE
                    // came one bit early.
                    let true_stop_latest = idle_seen - lat - 10 * bit;
                    assert!(nb >= true_stop_latest + min.max(11) * bit - bit, "{rate:?} lat {lat} min {min}");
                    assert!(nb >= stop + min.max(11) * bit);
                    // At most the IDLE uncertainty plus the read latency late.
                    assert!(nb <= stop + (min.max(11) + 1) * bit + lat + 1);
                }
            }
        }
    }

    #[test]
    fn tsyn_proof_waits_for_a_whole_character_after_tsyn() {
        for rate in Baudrate::ALL {
            let bit = T.ticks(rate, 1);
            let idle_seen = 50_000 + 11 * bit;
            let at = T.tsyn_check_at(rate, idle_seen);
            // Even if the stop bit was 1 bit later than IDLE implies, T_SYN + 1 char of quiet.
            let latest_stop = idle_seen - T.ticks(rate, 10);
            assert!(T.bits(rate, at - latest_stop) >= 33 + 11, "{rate:?}");
            assert!(at - idle_seen <= 35 * bit);
        }
    }

    #[test]
    fn the_transmit_decision() {
        let rate = Baudrate::B1500k;
        let idle_seen = 10_000u32;
        let nb = T.response_not_before(rate, idle_seen, BitTimes(20));
        let latest = T.response_latest(rate, idle_seen, BitTimes(150));
        assert!(latest > nb);
        assert_eq!(tx_plan(idle_seen, nb, latest, true, false), TxPlan::At(nb));
        assert_eq!(tx_plan(nb, nb, latest, true, false), TxPlan::Now);
        assert_eq!(tx_plan(latest, nb, latest, true, false), TxPlan::Now);
        assert_eq!(tx_plan(latest + 1, nb, latest, true, false), TxPlan::Drop(TxDrop::TooLate));
        assert_eq!(tx_plan(nb, nb, latest, false, false), TxPlan::Drop(TxDrop::LineActive));
        assert_eq!(tx_plan(nb, nb, latest, true, true), TxPlan::Drop(TxDrop::Busy));
        // Across the timer's wrap.
        let w = u32::MAX - 10;
        let nb = T.response_not_before(rate, w, BitTimes(11));
        let latest = T.response_latest(rate, w, BitTimes(150));
        assert!(nb < 1000 && latest < 100_000, "wrapped");
        assert_eq!(tx_plan(w, nb, latest, true, false), TxPlan::At(nb));
        assert_eq!(tx_plan(nb.wrapping_add(5), nb, latest, true, false), TxPlan::Now);
        assert!(reached(5, u32::MAX - 5));
        assert!(!reached(u32::MAX - 5, 5));
    }

    #[test]
    fn classification_for_autobaud() {
        let f = frame(5, &[1, 2, 3]);
        assert_eq!(classify(&f, 5), FrameClass { ok_sd123: true, to_us: true, invalid: false });
        assert_eq!(classify(&f, 6), FrameClass { ok_sd123: true, to_us: false, invalid: false });
        assert_eq!(classify(&frame(127, &[]), 5), FrameClass { ok_sd123: true, to_us: false, invalid: false });
        assert_eq!(classify(&[SD4, 5, 2], 5), FrameClass::default());
        assert_eq!(classify(&[SC], 5), FrameClass::default());
        let mut bad = f.clone();
        let n = bad.len();
        bad[n - 2] ^= 1;
        assert_eq!(classify(&bad, 5), FrameClass { ok_sd123: false, to_us: false, invalid: true });
        assert!(classify(&f[..n - 1], 5).invalid);
    }

    fn sd1(da: u8, fc: u8) -> Vec<u8> {
        let mut out = [0u8; MAX_FRAME_LEN];
        let hdr = Header { da, sa: 2, fc: FunctionCode(fc), dsap: None, ssap: None };
        let n = emit(&mut out, &hdr, &[]).unwrap();
        out[..n].to_vec()
    }

    #[test]
    fn answers_only_own_valid_requests_and_only_while_locked() {
        use crate::dp::DpSlave;
        use crate::phy::autobaud::Supervision;
        let t0 = Instant::from_millis(0);
        let mut node = crate::test_card::node(DpSlave::new(&crate::test_card::SLAVE, 5));
        let mut ab = Autobaud::new(t0);
        let fdl_status = sd1(5, 0x49);
        // Traffic for others, a token, SC, a broadcast: never an answer.
        assert!(answer(&mut node, &mut ab, t0, &[SD4, 3, 2]).is_none());
        assert!(answer(&mut node, &mut ab, t0, &[SC]).is_none());
        assert_eq!(ab.state(), Supervision::BaudSearch, "tokens and SC do not lock");
        let mut bad = fdl_status.clone();
        bad[4] ^= 0x40;
        assert!(answer(&mut node, &mut ab, t0, &bad).is_none(), "corrupt: no answer");
        assert_eq!(ab.stats().garbage, 1);
        assert_eq!(ab.state(), Supervision::BaudSearch);
        assert!(answer(&mut node, &mut ab, t0, &sd1(127, 0x46)).is_none(), "broadcast SDN: no answer");
        assert_eq!(ab.state(), Supervision::BaudControl, "a valid SD1 to anyone locks");
        // Locked: FDL_Status to us is answered.
        let t1 = Instant::from_millis(1000);
        let r = answer(&mut node, &mut ab, t1, &fdl_status).map(|r| r.to_vec());
        assert_eq!(r.as_deref().map(|r| r[0]), Some(SD1));
        // Baud_Control expires without own frames: searching, nothing is answered until a
        // frame relocks — and an own request relocks and is answered at once.
        let late = Instant::from_millis(1000 + 2560 + 1);
        assert_eq!(ab.poll(late), None);
        assert_eq!(ab.detected(), None);
        assert!(answer(&mut node, &mut ab, late, &sd1(9, 0x49)).is_none());
        assert_eq!(ab.detected(), Some(Baudrate::B12M), "relocked by a valid frame for another station");
        let late2 = Instant::from_millis(1000 + 2 * 2560 + 2);
        assert_eq!(ab.poll(late2), None);
        assert_eq!(ab.detected(), None);
        assert!(answer(&mut node, &mut ab, late2, &fdl_status).is_some(), "own request: lock + answer");
    }

    /// A rate control that never locks: the answer is withheld (the node still decided).
    struct NeverLocked;
    impl RateControl for NeverLocked {
        fn on_frame(&mut self, _: Instant, _: bool, _: bool) {}
        fn on_garbage(&mut self, _: Instant) {}
        fn detected(&self) -> Option<Baudrate> {
            None
        }
    }

    #[test]
    fn nothing_is_sent_without_a_rate() {
        use crate::dp::DpSlave;
        let mut node = crate::test_card::node(DpSlave::new(&crate::test_card::SLAVE, 5));
        assert!(answer(&mut node, &mut NeverLocked, Instant::from_millis(0), &sd1(5, 0x49)).is_none());
        assert_eq!(node.station().stats().fdl_status, 1, "the station saw the request");
    }

    /// The DMA receiver's path on a simulated line for every rate: segments cut at IDLE,
    /// garbage and corrupt segments while listening at a wrong rate, then the autobaud locks
    /// on the first clean telegram after T_SYN at the right rate.
    #[test]
    fn dma_receiver_and_autobaud_lock_on_every_rate() {
        use crate::dp::DpSlave;
        for (k, right) in Baudrate::ALL.iter().enumerate() {
            let mut now = Instant::from_millis(0);
            let mut ab = Autobaud::new(now);
            let mut rx = Receiver::new();
            let mut node = crate::test_card::node(DpSlave::new(&crate::test_card::SLAVE, 5));
            let req = sd1(5, 0x49);
            let mut answered = false;
            // A full scan lasts 1.533 s: every rate is reached within it.
            for _ in 0..1600 {
                let at_right_rate = ab.rate() == *right;
                // One bus cycle as the receiver sees it: garbage with errors at a wrong rate,
                // the telegram at the right one, then a T_SYN gap.
                let mut frames = Vec::new();
                if at_right_rate {
                    rx.segment(&req, false, |f| frames.push(f.to_vec()));
                } else {
                    rx.segment(&[0xFF, 0x00, 0x13], true, |f| frames.push(f.to_vec()));
                    ab.on_garbage(now);
                }
                rx.on_tsyn();
                for f in &frames {
                    if answer(&mut node, &mut ab, now, f).is_some() {
                        answered = true;
                    }
                }
                if answered {
                    break;
                }
                now = now + crate::time::Duration::from_millis(1);
                if ab.poll(now).is_some() {
                    rx.reset();
                }
            }
            assert!(answered, "{right:?}: locked and answered");
            assert_eq!(ab.detected(), Some(*right));
            assert_eq!(ab.stats().search_steps as usize % Baudrate::ALL.len(), k);
        }
    }
}
