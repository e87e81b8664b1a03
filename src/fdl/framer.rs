//! Byte stream → telegrams (reference §1.4).
//!
//! PROFIBUS telegrams delimit themselves by length, and no gap is allowed inside one. The
//! [`Framer`] collects bytes, asks [`telegram::decode`](super::telegram::decode) whether a
//! frame is complete, and hands complete frames to the caller. It resynchronises two ways:
//!
//! * **Gaps** — the receiver tells it about idle line ([`Framer::idle`]). A partial frame
//!   followed by idle is dropped (counted), and after corrupt input only an idle of at least
//!   T_SYN (33 bit times) makes a start delimiter trustworthy again.
//! * **Hunting** — when no gap information exists (a pseudo-terminal), after an invalid frame
//!   the framer drops one byte and tries again at the next byte that could start a frame.

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

/// Byte-stream framer with a buffer for the longest telegram.
#[derive(Debug, Clone)]
pub struct Framer {
    buf: [u8; MAX_FRAME_LEN],
    len: usize,
    /// Set after a complete frame was returned: the next push starts a new one.
    complete: bool,
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

    proptest::proptest! {
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
