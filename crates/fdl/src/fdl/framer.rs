//! Byte stream → telegrams (reference §1.4).
//!
//! PROFIBUS telegrams delimit themselves by length, and no gap is allowed inside one. The
//! [`Framer`] collects bytes, asks [`telegram::decode`] whether a
//! frame is complete, and hands complete frames to the caller. It resynchronises two ways:
//!
//! * **Gaps** — the receiver tells it about idle line ([`Framer::idle`]). A partial frame
//!   followed by idle is dropped (counted), and after corrupt input only an idle of at least
//!   T_SYN (33 bit times) makes a start delimiter trustworthy again.
//! * **Hunting** — when no gap information exists (a pseudo-terminal), after an invalid frame
//!   the framer drops one byte and tries again at the next byte that could start a frame.
//!
//! **Cutting only** ([`Framer::cut`], issue 11): for a receiver that hands the bytes to a
//! `TelegramSink` (`pbcard::phy::stream`, the layer above) as they arrive, the framer only finds
//! where a telegram starts and ends — from the header's length
//! ([`telegram::frame_len`]), without decoding, so its work per
//! byte, the last one included, does not grow with the telegram; the checksum and the rest
//! are the sink's. After a bad header it hunts for the next start delimiter.

use super::telegram::{self, Decoded, FrameError, MAX_FRAME_LEN};
use crate::time::BitTimes;

/// Counters of what the framer saw (shown in diagnosis statistics / the DPM status block).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct FramerStats {
    /// Complete, valid telegrams of any kind.
    pub frames: u32,
    /// Invalid telegrams (checksum, delimiters, lengths, addressing).
    pub corrupt: u32,
    /// Partial telegrams cut off by an idle gap.
    pub truncated: u32,
    /// Bytes thrown away while hunting for a start delimiter.
    pub skipped_bytes: u32,
}

/// What became of one [`Framer::push`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Push {
    /// Byte stored; the frame is not complete yet (or the framer is waiting for sync).
    Pending,
    /// A complete frame of this many bytes is in [`Framer::frame`] until the next push.
    Frame(usize),
    /// The bytes so far were not a telegram and were dropped.
    Dropped(FrameError),
}

/// What one received byte is to the telegram stream ([`Framer::cut`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Cut {
    /// No telegram's byte (hunting for a start delimiter after a bad header).
    Skip,
    /// A byte of a telegram: `first` — it starts one (begin the sink before passing it);
    /// `last` — the header's length ends the telegram with it (finish after passing it).
    Byte {
        /// The telegram's first byte (its start delimiter).
        first: bool,
        /// The telegram's last byte by length.
        last: bool,
    },
    /// The header is no telegram's (SD2 LE out of range, LE ≠ LEr, the repeated SD): the
    /// telegram in progress — this byte included — is dropped (abort the sink).
    Dropped(FrameError),
}

/// Byte-stream framer with a buffer for the longest telegram.
#[derive(Debug, Clone)]
pub struct Framer {
    buf: [u8; MAX_FRAME_LEN],
    len: usize,
    /// Set after a complete frame was returned: the next push starts a new one.
    complete: bool,
    /// [`Framer::cut`]: the telegram's length from its header (0 while unknown).
    expect: usize,
    /// After corrupt input: true until a byte that may start a frame arrives (hunting) or
    /// an idle ≥ TSYN is reported.
    hunting: bool,
    stats: FramerStats,
}

impl Default for Framer {
    fn default() -> Self {
        Self::new()
    }
}

impl Framer {
    /// An empty framer, synchronised (the caller starts it after an idle line).
    pub const fn new() -> Self {
        Framer {
            buf: [0; MAX_FRAME_LEN],
            len: 0,
            complete: false,
            expect: 0,
            hunting: false,
            stats: FramerStats { frames: 0, corrupt: 0, truncated: 0, skipped_bytes: 0 },
        }
    }

    /// Counters.
    pub fn stats(&self) -> FramerStats {
        self.stats
    }

    /// Bytes of the telegram being received (for a DMA receiver that needs to know).
    pub fn pending(&self) -> &[u8] {
        if self.complete {
            &[]
        } else {
            &self.buf[..self.len]
        }
    }

    /// Bytes of the telegram being received, or of the one just completed (both modes).
    pub fn telegram_len(&self) -> usize {
        self.len
    }

    /// The complete frame after [`Push::Frame`].
    pub fn frame(&self) -> &[u8] {
        if self.complete {
            &self.buf[..self.len]
        } else {
            &[]
        }
    }

    /// The line was idle for `bits` bit times. A partial frame is dropped; an idle of at
    /// least T_SYN ends hunting.
    pub fn idle(&mut self, bits: BitTimes) {
        if !self.complete && self.len > 0 {
            self.stats.truncated = self.stats.truncated.wrapping_add(1);
        }
        self.len = 0;
        self.complete = false;
        if bits >= BitTimes::TSYN {
            self.hunting = false;
        }
    }

    /// The receiver reported a character error (parity, framing, noise, overrun): the
    /// telegram in progress is corrupt. It is dropped (counted) and the framer hunts for the
    /// next start delimiter after idle line.
    pub fn line_error(&mut self) {
        if !self.complete && self.len > 0 {
            self.stats.corrupt = self.stats.corrupt.wrapping_add(1);
        }
        self.len = 0;
        self.complete = false;
        self.hunting = true;
    }

    /// Feed one received byte.
    pub fn push(&mut self, byte: u8) -> Push {
        if self.complete {
            self.complete = false;
            self.len = 0;
        }
        if self.len == 0 && self.hunting {
            if !is_start_delimiter(byte) {
                self.stats.skipped_bytes = self.stats.skipped_bytes.wrapping_add(1);
                return Push::Pending;
            }
            self.hunting = false;
        }
        self.buf[self.len] = byte;
        self.len += 1;
        match telegram::decode(&self.buf[..self.len]) {
            Decoded::Incomplete => Push::Pending,
            Decoded::Frame(_, n) => {
                debug_assert_eq!(n, self.len);
                self.complete = true;
                self.stats.frames = self.stats.frames.wrapping_add(1);
                Push::Frame(n)
            }
            Decoded::Invalid(e) => {
                self.stats.corrupt = self.stats.corrupt.wrapping_add(1);
                self.resync();
                Push::Dropped(e)
            }
        }
    }

    /// Cut the stream without decoding (see the module docs): what `byte` is to the
    /// telegrams. The framer keeps only the header's first bytes; [`frame`](Self::frame)
    /// and [`pending`](Self::pending) are the header's bytes in this mode. A telegram ends
    /// by its header's length; one cut short by a gap is dropped by [`idle`](Self::idle)
    /// (counted) and one hit by a character error by [`line_error`](Self::line_error) — the
    /// caller aborts its sink then. [`FramerStats::frames`] counts the telegrams cut (their
    /// checksums are not the framer's to check), [`FramerStats::corrupt`] the bad headers.
    pub fn cut(&mut self, byte: u8) -> Cut {
        if self.complete {
            self.complete = false;
            self.len = 0;
        }
        let first = self.len == 0;
        if first {
            if !is_start_delimiter(byte) {
                self.stats.skipped_bytes = self.stats.skipped_bytes.wrapping_add(1);
                self.hunting = true;
                return Cut::Skip;
            }
            self.hunting = false;
        }
        self.len += 1;
        // The header's first four bytes give the length (SD2: SD LE LEr SD); after them only
        // a count.
        if self.len <= 4 {
            self.buf[self.len - 1] = byte;
            self.expect = match telegram::frame_len(&self.buf[..self.len]) {
                Ok(Some(n)) => n,
                Ok(None) => 0,
                Err(e) => {
                    self.stats.corrupt = self.stats.corrupt.wrapping_add(1);
                    self.len = 0;
                    self.hunting = true;
                    return Cut::Dropped(e);
                }
            };
        }
        let last = self.len == self.expect;
        if last {
            self.complete = true;
            self.stats.frames = self.stats.frames.wrapping_add(1);
        }
        Cut::Byte { first, last }
    }

    /// Feed many bytes; `on_frame` sees every complete frame.
    pub fn feed(&mut self, bytes: &[u8], mut on_frame: impl FnMut(&[u8])) {
        for &b in bytes {
            if let Push::Frame(n) = self.push(b) {
                on_frame(&self.buf[..n]);
            }
        }
    }

    /// After invalid bytes: look for a later start delimiter inside what was buffered and
    /// re-decode from there; otherwise hunt.
    fn resync(&mut self) {
        let mut start = 1;
        while start < self.len {
            if is_start_delimiter(self.buf[start]) {
                match telegram::decode(&self.buf[start..self.len]) {
                    Decoded::Incomplete => break,
                    // A complete frame inside garbage cannot be reported without losing the
                    // push protocol's "one frame per byte" rule; it is rare and counted.
                    Decoded::Frame(..) | Decoded::Invalid(_) => {}
                }
            }
            start += 1;
        }
        self.stats.skipped_bytes = self.stats.skipped_bytes.wrapping_add(start as u32);
        self.buf.copy_within(start..self.len, 0);
        self.len -= start;
        self.hunting = self.len == 0;
    }
}

fn is_start_delimiter(b: u8) -> bool {
    matches!(b, telegram::SD1 | telegram::SD2 | telegram::SD3 | telegram::SD4 | telegram::SC)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fdl::telegram::{emit, FunctionCode, Header};

    fn frame(da: u8, pdu: &[u8]) -> ([u8; MAX_FRAME_LEN], usize) {
        let mut out = [0u8; MAX_FRAME_LEN];
        let hdr = Header { da, sa: 2, fc: FunctionCode(0x7D), dsap: None, ssap: None };
        let n = emit(&mut out, &hdr, pdu).unwrap();
        (out, n)
    }

    fn collect(f: &mut Framer, bytes: &[u8]) -> Vec<Vec<u8>> {
        let mut v = Vec::new();
        f.feed(bytes, |fr| v.push(fr.to_vec()));
        v
    }

    #[test]
    fn back_to_back_frames() {
        let (a, na) = frame(8, &[1, 2, 3]);
        let (b, nb) = frame(9, &[]);
        let mut stream = a[..na].to_vec();
        stream.extend_from_slice(&[0xDC, 0x03, 0x02, 0xE5]);
        stream.extend_from_slice(&b[..nb]);
        let mut f = Framer::new();
        let got = collect(&mut f, &stream);
        assert_eq!(got.len(), 4);
        assert_eq!(got[0], &a[..na]);
        assert_eq!(got[3], &b[..nb]);
        assert_eq!(f.stats().frames, 4);
    }

    #[test]
    fn noise_then_frame_resynchronises() {
        let (a, na) = frame(8, &[1, 2, 3, 4, 5]);
        let mut stream = vec![0x00, 0xFF, 0x68, 0x99, 0x12, 0x10, 0x33];
        stream.extend_from_slice(&a[..na]);
        let mut f = Framer::new();
        let got = collect(&mut f, &stream);
        assert_eq!(got.last().unwrap(), &a[..na]);
        assert!(f.stats().corrupt > 0);
    }

    #[test]
    fn truncated_frame_dropped_by_gap() {
        let (a, na) = frame(8, &[1, 2, 3, 4, 5]);
        let mut f = Framer::new();
        assert!(collect(&mut f, &a[..na - 3]).is_empty());
        f.idle(BitTimes(33));
        assert_eq!(collect(&mut f, &a[..na]), vec![a[..na].to_vec()]);
        assert_eq!(f.stats().truncated, 1);
    }

    #[test]
    fn corrupt_checksum_is_counted_and_next_frame_found() {
        let (mut a, na) = frame(8, &[1, 2, 3]);
        a[na - 2] ^= 0x01;
        let (b, nb) = frame(8, &[4]);
        let mut stream = a[..na].to_vec();
        stream.extend_from_slice(&b[..nb]);
        let mut f = Framer::new();
        let got = collect(&mut f, &stream);
        assert_eq!(got, vec![b[..nb].to_vec()]);
        assert_eq!(f.stats().corrupt, 1);
    }

    /// Cutting finds the same telegrams as decoding in a clean stream, each begun at its
    /// start delimiter and ended at its last byte by length; a bad header is dropped and the
    /// next telegram found.
    #[test]
    fn cut_by_length() {
        let (a, na) = frame(8, &[1, 2, 3]);
        let (b, nb) = frame(9, &[]);
        let mut stream = a[..na].to_vec();
        stream.extend_from_slice(&[0xDC, 0x03, 0x02, 0xE5]);
        stream.extend_from_slice(&[0x00, 0x68, 0x03, 0x03]);
        stream.extend_from_slice(&b[..nb]);
        let mut f = Framer::new();
        let mut frames = Vec::new();
        let mut cur = Vec::new();
        let mut dropped = 0;
        for &byte in &stream {
            match f.cut(byte) {
                Cut::Skip => {}
                Cut::Dropped(_) => {
                    dropped += 1;
                    cur.clear();
                }
                Cut::Byte { first, last } => {
                    assert_eq!(first, cur.is_empty());
                    cur.push(byte);
                    if last {
                        frames.push(core::mem::take(&mut cur));
                    }
                }
            }
        }
        assert_eq!(frames, vec![a[..na].to_vec(), vec![0xDC, 3, 2], vec![0xE5], b[..nb].to_vec()]);
        assert_eq!(dropped, 1);
        assert_eq!(f.stats().frames, 4);
        assert_eq!(f.stats().corrupt, 1);
    }

    proptest::proptest! {
        /// Cutting never panics and never reports a telegram longer than the longest.
        #[test]
        fn cut_any_bytes(bytes in proptest::collection::vec(proptest::num::u8::ANY, 0..1000)) {
            let mut f = Framer::new();
            let mut n = 0usize;
            for &b in &bytes {
                match f.cut(b) {
                    Cut::Byte { first, last } => {
                        if first { n = 0; }
                        n += 1;
                        proptest::prop_assert!(n <= MAX_FRAME_LEN);
                        if last { n = 0; }
                    }
                    Cut::Skip | Cut::Dropped(_) => n = 0,
                }
            }
        }

        /// Garbage before a gap never hides the frame after it, and nothing panics.
        #[test]
        fn garbage_gap_frame(garbage in proptest::collection::vec(proptest::num::u8::ANY, 0..400),
                             pdu in proptest::collection::vec(proptest::num::u8::ANY, 0..244)) {
            let (a, na) = frame(8, &pdu);
            let mut f = Framer::new();
            let _ = collect(&mut f, &garbage);
            f.idle(BitTimes(33));
            let got = collect(&mut f, &a[..na]);
            proptest::prop_assert_eq!(got, vec![a[..na].to_vec()]);
        }
    }
}
