//! The streaming receive seam (issue 11 items 1–2): telegrams handed to the line's decision
//! *while their bytes arrive*, so that the work left after the last byte does not grow with
//! the telegram's length — the way an SPC3 / VPC3+ checks DA and FCS on the fly and answers
//! within a few bit times of the end delimiter.
//!
//! The physical layer owns the cutting: it sees the bytes (one per receive interrupt on a
//! per-character port, or a piece of a DMA ring at each ring event), knows from the header
//! where a telegram ends (the length of SD1/SD3/SD4/SC, or LE + 6 for SD2, checked LE = LEr
//! and the repeated SD) and resynchronises after garbage, a character error or a gap. It
//! hands every telegram's bytes, in order and in pieces of any size, to a [`TelegramSink`]
//! — the protocol side (the fast path, `crate::fast`) implements it — and tells its driver
//! when the telegram's last byte went in, so the driver asks the sink for its decision at
//! once (end by length, not by an idle gap).
//!
//! Direction: this trait is defined here, in the lower layer, and implemented above
//! (ARCHITECTURE "data flows one way"); the physical layer never names the fast path.

/// The receiver of a telegram's bytes while they arrive.
///
/// Call order for one telegram: [`begin`](Self::begin), then [`bytes`](Self::bytes) as many
/// times as the pieces come (the first piece starts with the start delimiter; the pieces
/// together are exactly the telegram, by length), then either the driver's own "complete"
/// call on the implementing type (its decision) or [`abort`](Self::abort). A `begin` while
/// a telegram is in progress abandons that one as `abort` would. With a destination filter
/// ([`Stream::set_filter`]) another station's telegram whose header came in one piece is
/// never announced: the sink hears nothing of it (no `begin`, no `abort`).
pub trait TelegramSink {
    /// A new telegram starts: forget any partial state.
    fn begin(&mut self);
    /// The next bytes of the telegram in progress, in order (any split: one byte, a DMA
    /// half-ring, the two sides of a ring wrap).
    fn bytes(&mut self, bytes: &[u8]);
    /// The telegram in progress is lost (a character error, an idle gap inside it, a header
    /// that is no telegram): nothing of it may be answered or queued.
    fn abort(&mut self);
}

use super::line::{expected_len, Expect, RxStats};
use crate::fdl::telegram::{BROADCAST, SC, SD1, SD2, SD3, SD4};
use crate::time::BitTimes;

/// How a [`Stream`] finds the next telegram after a loss (reference §1.4).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum Resync {
    /// The port reports idle gaps ([`Stream::idle`]): after garbage, a character error or a
    /// cut telegram, only an idle of at least T_SYN (33 bit times) makes a start delimiter
    /// trustworthy again — the rule of [`super::line::Receiver`]. A real RS485 line.
    Gap,
    /// No gap information (a pseudo-terminal): after a loss the stream hunts for the next
    /// byte that can start a telegram, and retries inside the ≤ 4 header bytes it holds —
    /// the rule of [`crate::fdl::framer::Framer`].
    Hunt,
}

/// What one byte (or piece) meant for the driver.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum Step {
    /// Nothing to do: the bytes went into the telegram in progress, or were skipped while
    /// waiting for sync.
    Pending,
    /// The telegram's last byte (by its header's length) went into the sink: ask it for its
    /// decision now — the end of a request found by length, not by an idle gap.
    Complete,
    /// The last byte of a telegram skipped by the destination filter
    /// ([`Stream::set_filter`]): no decision. The sink got [`TelegramSink::abort`] at its DA
    /// if it had heard of the telegram (its `begin` comes only once the DA passed the filter
    /// when the header arrives in one piece, [`Stream::piece`]; a per-character port's sink
    /// has its `begin` at the start delimiter).
    Skipped,
    /// Bytes that are no telegram (an unknown start delimiter, an SD2 header with bad LE,
    /// LEr or repeated SD): the telegram in progress was aborted (counted as garbage; for the
    /// rate search, `Autobaud::on_garbage`).
    Garbage,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum State {
    /// Waiting for an idle ≥ T_SYN ([`Resync::Gap`] after a loss, a reset, at start).
    Unsynced,
    /// The next byte must be a start delimiter.
    Ready,
    /// After a loss ([`Resync::Hunt`]): skip bytes until a start delimiter.
    Hunting,
    /// A telegram in progress, its bytes go to the sink.
    Telegram,
    /// A telegram in progress for another station: counted down, not read.
    Skipping,
}

/// The streaming framer of a receive line (reference §1.4, §2.1): cuts the byte stream into
/// telegrams by their header's length (SD1 6, SD3 14, SD4 3, SC 1, SD2 LE + 6 once LE = LEr
/// and the repeated SD are in; [`expected_len`]) and hands each telegram's bytes to a
/// [`TelegramSink`] as they arrive — [`Stream::push`] for a per-character port,
/// [`Stream::piece`] for the pieces of a DMA ring. [`Step::Complete`] comes exactly with a
/// telegram's last byte. It keeps no copy of the telegram: only the ≤ 4 header bytes its
/// length needs, and the position in the telegram.
///
/// Losses: a character error ([`Stream::error`]), an idle gap inside a telegram
/// ([`Stream::idle`]) and bytes that are no telegram abort the telegram in progress
/// ([`TelegramSink::abort`]); the stream then resynchronises as its [`Resync`] says. Checksum
/// and end delimiter are the sink's to check (they are not needed for the length).
///
/// With a destination filter ([`Stream::set_filter`]) a telegram for another station is
/// dropped at its DA and its remaining bytes are only counted, never read (a DMA driver moves
/// its ring position without touching them). The sink's [`TelegramSink::begin`] comes at the
/// start delimiter when the header arrives byte by byte, but only once the DA passed the
/// filter when the header is in one piece ([`Stream::piece`]): another station's telegram
/// then costs the sink nothing, not even a `begin` / `abort` pair; the sink hears `abort`
/// only for a telegram it had a `begin` for.
#[derive(Debug, Clone)]
pub struct Stream {
    state: State,
    resync: Resync,
    head: [u8; 4],
    /// Bytes of the telegram in progress so far.
    pos: u16,
    /// Its length by the header, 0 while not known.
    len: u16,
    /// Index of its DA (0: none, SC).
    da_at: u8,
    /// Skip telegrams whose DA is neither this station nor the broadcast.
    filter: Option<u8>,
    /// The sink has had `begin` for the telegram in progress ([`Self::start_quiet`]).
    begun: bool,
    /// The current run of bytes skipped while unsynced is counted.
    noted: bool,
    stats: RxStats,
}

#[inline(always)]
fn is_start_delimiter(b: u8) -> bool {
    matches!(b, SD1 | SD2 | SD3 | SD4 | SC)
}

impl Stream {
    /// A stream after reset: with [`Resync::Gap`] nothing is accepted before the first T_SYN
    /// (as [`super::line::Receiver::new`]); with [`Resync::Hunt`] the first start delimiter
    /// starts a telegram (as [`crate::fdl::framer::Framer::new`]).
    pub const fn new(resync: Resync) -> Self {
        Stream {
            state: match resync {
                Resync::Gap => State::Unsynced,
                Resync::Hunt => State::Ready,
            },
            resync,
            head: [0; 4],
            pos: 0,
            len: 0,
            da_at: 0,
            filter: None,
            begun: false,
            noted: false,
            stats: RxStats { frames: 0, corrupt: 0, truncated: 0, garbage: 0, unsynced: 0, tsyn: 0 },
        }
    }

    /// Counters (as the DMA receiver's: `frames` counts every telegram cut, skipped ones too).
    pub fn stats(&self) -> RxStats {
        self.stats
    }

    /// Whether start delimiters are accepted (not waiting for T_SYN).
    pub fn is_synced(&self) -> bool {
        self.state != State::Unsynced
    }

    /// Whether a telegram is in progress (its start delimiter came, its last byte not yet).
    pub fn in_telegram(&self) -> bool {
        matches!(self.state, State::Telegram | State::Skipping)
    }

    /// Bytes still missing of the telegram in progress, once its length is known.
    pub fn remaining(&self) -> Option<usize> {
        match self.state {
            State::Telegram | State::Skipping if self.len != 0 => Some((self.len - self.pos) as usize),
            _ => None,
        }
    }

    /// Skip (abort at DA, then count down) telegrams whose destination address — the
    /// extension bit masked — is neither `own` nor the broadcast 127; `None`: every telegram
    /// goes to the sink (the rate search needs every valid telegram to lock).
    pub fn set_filter(&mut self, own: Option<u8>) {
        self.filter = own;
    }

    /// The receiver was restarted (rate change, ring overrun, flash stall): the telegram in
    /// progress is aborted (not counted) and the stream waits for T_SYN ([`Resync::Gap`]) or
    /// the next start delimiter ([`Resync::Hunt`]).
    pub fn reset<S: TelegramSink + ?Sized>(&mut self, sink: &mut S) {
        if self.state == State::Telegram {
            sink.abort();
        }
        self.lost();
        if self.resync == Resync::Hunt {
            self.state = State::Ready;
        }
    }

    /// The line was idle for `bits` bit times after the last character (an IDLE flag: 11; a
    /// quiet-line compare: T_SYN). A telegram in progress is cut off (aborted, counted as
    /// truncated); an idle ≥ T_SYN makes the next start delimiter trustworthy.
    pub fn idle<S: TelegramSink + ?Sized>(&mut self, bits: BitTimes, sink: &mut S) {
        if self.in_telegram() {
            if self.state == State::Telegram {
                sink.abort();
            }
            self.stats.truncated = self.stats.truncated.wrapping_add(1);
            match self.resync {
                Resync::Gap => self.lost(),
                Resync::Hunt => self.state = State::Ready,
            }
        }
        // The next bytes skipped while unsynced are a new run (one per segment, as counted
        // by the segment cutter).
        self.noted = false;
        if bits >= BitTimes::TSYN {
            self.stats.tsyn = self.stats.tsyn.wrapping_add(1);
            self.state = State::Ready;
        }
    }

    /// A character error (parity, framing, noise, overrun): the telegram in progress is
    /// aborted and counted as corrupt; then wait for T_SYN ([`Resync::Gap`], counted once per
    /// loss even between telegrams) or hunt ([`Resync::Hunt`]).
    pub fn error<S: TelegramSink + ?Sized>(&mut self, sink: &mut S) {
        if self.state == State::Telegram {
            sink.abort();
        }
        match self.resync {
            Resync::Gap => {
                if self.state != State::Unsynced {
                    self.stats.corrupt = self.stats.corrupt.wrapping_add(1);
                }
                self.lost();
            }
            Resync::Hunt => {
                if self.in_telegram() {
                    self.stats.corrupt = self.stats.corrupt.wrapping_add(1);
                }
                self.state = State::Hunting;
            }
        }
    }

    /// One received character (a per-character port: one receive interrupt each).
    #[inline]
    pub fn push<S: TelegramSink + ?Sized>(&mut self, byte: u8, sink: &mut S) -> Step {
        match self.state {
            State::Unsynced => {
                self.note_unsynced();
                Step::Pending
            }
            State::Ready | State::Hunting => self.start(byte, sink),
            State::Telegram => {
                if self.len == 0 || self.pos <= self.da_at as u16 {
                    self.header(byte, sink)
                } else {
                    sink.bytes(core::slice::from_ref(&byte));
                    self.advance(1)
                }
            }
            State::Skipping => self.advance(1),
        }
    }

    /// The next received bytes in one piece (a DMA ring's new bytes, each side of a wrap
    /// separately): returns how many were used and what they meant. It stops right after a
    /// telegram's last byte ([`Step::Complete`], [`Step::Skipped`]) or at [`Step::Garbage`],
    /// so the driver acts and then passes the rest (`&bytes[used..]`) again; otherwise it uses
    /// them all. After the header, a telegram's bytes go to the sink as one slice (no copy); a
    /// skipped telegram's are not read at all.
    pub fn piece<S: TelegramSink + ?Sized>(&mut self, bytes: &[u8], sink: &mut S) -> (usize, Step) {
        let mut used = 0;
        while used < bytes.len() {
            match self.state {
                State::Unsynced => {
                    self.note_unsynced();
                    return (bytes.len(), Step::Pending);
                }
                State::Hunting => match bytes[used..].iter().position(|&b| is_start_delimiter(b)) {
                    Some(k) => {
                        used += k;
                        self.start_quiet();
                        let (n, step) = self.header_fast(&bytes[used..], sink);
                        used += n;
                        if step != Step::Pending {
                            return (used, step);
                        }
                    }
                    None => return (bytes.len(), Step::Pending),
                },
                State::Ready if is_start_delimiter(bytes[used]) => {
                    self.start_quiet();
                    let (n, step) = self.header_fast(&bytes[used..], sink);
                    used += n;
                    if step != Step::Pending {
                        return (used, step);
                    }
                }
                State::Telegram | State::Skipping if self.len != 0 && self.pos > self.da_at as u16 => {
                    let left = (self.len - self.pos) as usize;
                    let take = left.min(bytes.len() - used);
                    if self.state == State::Telegram {
                        sink.bytes(&bytes[used..used + take]);
                    }
                    used += take;
                    let step = self.advance(take as u16);
                    if step != Step::Pending {
                        return (used, step);
                    }
                }
                State::Telegram => {
                    let (n, step) = self.header_fast(&bytes[used..], sink);
                    used += n;
                    if step != Step::Pending {
                        return (used, step);
                    }
                }
                _ => {
                    let step = self.push(bytes[used], sink);
                    used += 1;
                    if step != Step::Pending {
                        return (used, step);
                    }
                }
            }
        }
        (used, Step::Pending)
    }

    /// A start delimiter: a telegram begins (the sink's `begin`; the delimiter itself is the
    /// header's first byte).
    #[inline(always)]
    fn begin_telegram<S: TelegramSink + ?Sized>(&mut self, sink: &mut S) {
        self.start_quiet();
        self.begun = true;
        sink.begin();
    }

    /// A start delimiter at the front of a piece: a telegram begins, but the sink hears of
    /// it only once its destination passed the filter ([`Self::header_fast`]) — another
    /// station's telegram whose header is in one piece costs the sink nothing (issue 11, the
    /// CPU share of foreign traffic).
    #[inline(always)]
    fn start_quiet(&mut self) {
        self.state = State::Telegram;
        self.pos = 0;
        self.len = 0;
        self.da_at = 0;
        self.begun = false;
    }

    /// The sink's `begin` for the telegram in progress, if it has not had it.
    #[inline(always)]
    fn ensure_begun<S: TelegramSink + ?Sized>(&mut self, sink: &mut S) {
        if !self.begun {
            self.begun = true;
            sink.begin();
        }
    }

    /// The next bytes of a telegram whose header is still open (`State::Telegram`, the length
    /// or the DA not in yet; at its start right after [`Self::start_quiet`] — the sink has
    /// had no `begin` yet —, the start delimiter at `bytes[0]`): when they complete the
    /// header — the length (SD2: LE, LEr and
    /// the repeated SD, checked) and the DA —, the length and the destination filter are taken
    /// at once, and the telegram's bytes in `bytes` go to the sink as **one** slice. A DMA
    /// piece that holds a whole short request then costs one length check and one sink call
    /// (issue 11 at 12 Mbit/s). Otherwise, and for any header that is no telegram, byte by
    /// byte as [`Self::header_run`] (whose error handling is the one).
    fn header_fast<S: TelegramSink + ?Sized>(&mut self, bytes: &[u8], sink: &mut S) -> (usize, Step) {
        let pos = self.pos as usize;
        let sd = if pos == 0 { bytes.first().copied() } else { Some(self.head[0]) };
        let da_at: usize = match sd {
            Some(SD1) | Some(SD3) | Some(SD4) => 1,
            Some(SD2) => 4,
            _ => return self.header_slow(bytes, sink),
        };
        // The header is open: `pos <= da_at`, and `head[..pos]` holds its bytes so far.
        let Some(&da) = bytes.get(da_at.wrapping_sub(pos)) else { return self.header_slow(bytes, sink) };
        let n = if self.len != 0 {
            self.len as usize
        } else if pos == 0 {
            // The whole length part in this piece (the common case: no copy).
            match crate::fdl::telegram::frame_len(&bytes[..da_at]) {
                Ok(Some(n)) => n,
                _ => return self.header_slow(bytes, sink),
            }
        } else {
            let mut h = [0u8; 4];
            h[..pos].copy_from_slice(&self.head[..pos]);
            h[pos..da_at].copy_from_slice(&bytes[..da_at - pos]);
            match crate::fdl::telegram::frame_len(&h[..da_at]) {
                Ok(Some(n)) => n,
                _ => return self.header_slow(bytes, sink),
            }
        };
        // (`head` is not needed further: it serves the length and a bad header's resync.)
        self.len = n as u16;
        self.da_at = da_at as u8;
        let take = (n - pos).min(bytes.len());
        if let Some(own) = self.filter {
            let da = da & 0x7F;
            if da != own && da != BROADCAST {
                if self.begun {
                    sink.abort();
                }
                self.state = State::Skipping;
                return (take, self.advance(take as u16));
            }
        }
        self.ensure_begun(sink);
        sink.bytes(&bytes[..take]);
        (take, self.advance(take as u16))
    }

    /// [`Self::header_run`] once the sink has had its `begin`.
    fn header_slow<S: TelegramSink + ?Sized>(&mut self, bytes: &[u8], sink: &mut S) -> (usize, Step) {
        self.ensure_begun(sink);
        self.header_run(bytes, sink)
    }

    /// The header bytes at the front of `bytes` (while the length or the destination is not
    /// known; `State::Telegram`): the checks of [`Self::header`] byte by byte, but the bytes
    /// into the sink as **one** slice — at the end of the header, of the telegram or of
    /// `bytes` —, not one call per byte. A piece (the DMA mode's IDLE remainder) that holds a
    /// whole short request then costs the sink one call for its header (issue 11, the DMA
    /// rates). A foreign destination or a bad header aborts the sink as before (the bytes
    /// not yet handed over do not matter then). Returns the bytes used and the step.
    // Out of line: the slow path (a header split across pieces, a bad header), one copy.
    #[inline(never)]
    fn header_run<S: TelegramSink + ?Sized>(&mut self, bytes: &[u8], sink: &mut S) -> (usize, Step) {
        let mut k = 0;
        while k < bytes.len() && (self.len == 0 || self.pos <= self.da_at as u16) {
            k += 1;
            if let Some(step) = self.header_check(bytes[k - 1], sink) {
                return (k, step);
            }
            let step = self.advance(1);
            if step != Step::Pending {
                sink.bytes(&bytes[..k]);
                return (k, step);
            }
        }
        if k > 0 {
            sink.bytes(&bytes[..k]);
        }
        (k, Step::Pending)
    }

    fn start<S: TelegramSink + ?Sized>(&mut self, byte: u8, sink: &mut S) -> Step {
        if is_start_delimiter(byte) {
            self.begin_telegram(sink);
            return self.header(byte, sink);
        }
        if self.state == State::Hunting {
            return Step::Pending;
        }
        self.stats.garbage = self.stats.garbage.wrapping_add(1);
        match self.resync {
            Resync::Gap => self.lost(),
            Resync::Hunt => self.state = State::Hunting,
        }
        Step::Garbage
    }

    /// One byte while the length or the destination is not known yet.
    fn header<S: TelegramSink + ?Sized>(&mut self, byte: u8, sink: &mut S) -> Step {
        if let Some(step) = self.header_check(byte, sink) {
            return step;
        }
        sink.bytes(core::slice::from_ref(&byte));
        self.advance(1)
    }

    /// The stream's own work on a header byte (its length, its destination), shared by
    /// [`Self::header`] and [`Self::header_run`]: `Some(step)` when the byte ends the
    /// telegram for the sink — no frame (the sink aborted, [`Self::bad_header`]) or another
    /// station's destination under the filter (aborted, the rest skipped) —, `None` when the
    /// byte belongs to the sink (handed over by the caller, then `advance`).
    #[inline(always)]
    fn header_check<S: TelegramSink + ?Sized>(&mut self, byte: u8, sink: &mut S) -> Option<Step> {
        let i = self.pos as usize;
        if i < self.head.len() {
            self.head[i] = byte;
        }
        if self.len == 0 {
            match expected_len(&self.head[..i + 1]) {
                Expect::Len(n) => {
                    self.len = n as u16;
                    self.da_at = match self.head[0] {
                        SD1 | SD3 | SD4 => 1,
                        SD2 => 4,
                        _ => 0,
                    };
                }
                Expect::More(_) => {}
                Expect::NotAFrame => return Some(self.bad_header(i + 1, sink)),
            }
        }
        if self.da_at != 0 && i == self.da_at as usize {
            if let Some(own) = self.filter {
                let da = byte & 0x7F;
                if da != own && da != BROADCAST {
                    sink.abort();
                    self.state = State::Skipping;
                    return Some(self.advance(1));
                }
            }
        }
        None
    }

    /// The header bytes `head[..n]` are no telegram.
    fn bad_header<S: TelegramSink + ?Sized>(&mut self, n: usize, sink: &mut S) -> Step {
        sink.abort();
        self.stats.garbage = self.stats.garbage.wrapping_add(1);
        match self.resync {
            Resync::Gap => self.lost(),
            Resync::Hunt => {
                // As the framer: restart at the first later start delimiter whose bytes are
                // an incomplete telegram (a complete one inside garbage is not reported).
                self.state = State::Hunting;
                let head = self.head;
                let from = (1..n).find(|&k| {
                    is_start_delimiter(head[k])
                        && match expected_len(&head[k..n]) {
                            Expect::More(_) => true,
                            Expect::Len(m) => m > n - k,
                            Expect::NotAFrame => false,
                        }
                });
                if let Some(k) = from {
                    for &b in &head[k..n] {
                        let _ = self.push(b, sink);
                    }
                }
            }
        }
        Step::Garbage
    }

    #[inline(always)]
    fn advance(&mut self, n: u16) -> Step {
        self.pos += n;
        if self.len != 0 && self.pos >= self.len {
            self.stats.frames = self.stats.frames.wrapping_add(1);
            let step = if self.state == State::Telegram { Step::Complete } else { Step::Skipped };
            self.state = State::Ready;
            return step;
        }
        Step::Pending
    }

    fn lost(&mut self) {
        self.state = State::Unsynced;
        self.noted = false;
    }

    fn note_unsynced(&mut self) {
        if !self.noted {
            self.noted = true;
            self.stats.unsynced = self.stats.unsynced.wrapping_add(1);
        }
    }
}

#[cfg(test)]
#[path = "tests_stream.rs"]
mod tests;
