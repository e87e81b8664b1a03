//! Line bytes → telegrams and garbage, cut by syntax (reference §1.4, §2.1).
//!
//! A listener cannot trust gaps alone (USB adapters and pseudo-terminals deliver bytes in
//! chunks of their own), so telegrams are cut the way they delimit themselves: a start
//! delimiter, the length it implies, checksum and end delimiter, all checked by the project's
//! [`telegram::decode`]. Bytes that start no valid telegram are collected as garbage and shown
//! with the first reason a telegram was refused. A silence longer than the gap threshold
//! ([`Cutter::gap`]) or a character error ([`Cutter::line_error`]) ends a partial telegram.

use pbcard::fdl::telegram::{self, Decoded, FrameError};

/// What the cutter found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Cut {
    /// A valid telegram; `t_us` is when its last byte arrived.
    Frame {
        /// The telegram bytes.
        bytes: Vec<u8>,
        /// Time of the last byte, µs.
        t_us: Option<u64>,
    },
    /// Bytes that are no telegram.
    Garbage {
        /// The bytes.
        bytes: Vec<u8>,
        /// Time of the last byte, µs.
        t_us: Option<u64>,
        /// Why they are none.
        why: Why,
    },
}

/// Why bytes were garbage.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Why {
    /// No start delimiter where a telegram should begin.
    NoStartDelimiter,
    /// A telegram started but was invalid.
    Invalid(FrameError),
    /// A telegram cut off by a gap, a character error or the end of the input.
    Truncated,
    /// A character error (parity, framing) hit these bytes.
    LineError,
}

fn is_start_delimiter(b: u8) -> bool {
    matches!(b, telegram::SD1 | telegram::SD2 | telegram::SD3 | telegram::SD4 | telegram::SC)
}

/// The syntax cutter.
#[derive(Debug, Default)]
pub struct Cutter {
    buf: Vec<u8>,
    garbage: Vec<u8>,
    why: Option<Why>,
    t_us: Option<u64>,
    /// Time of the last garbage byte.
    garbage_t: Option<u64>,
}

impl Cutter {
    /// An empty cutter.
    pub fn new() -> Self {
        Self::default()
    }

    /// Bytes read at `t_us`; every complete telegram or garbage run goes to `out`.
    pub fn push(&mut self, t_us: Option<u64>, bytes: &[u8], out: &mut Vec<Cut>) {
        self.t_us = t_us;
        for &b in bytes {
            self.buf.push(b);
            self.drain(out);
        }
    }

    fn drain(&mut self, out: &mut Vec<Cut>) {
        loop {
            while let Some(&b) = self.buf.first() {
                if is_start_delimiter(b) {
                    break;
                }
                self.buf.remove(0);
                self.add_garbage(b, Why::NoStartDelimiter);
            }
            if self.buf.is_empty() {
                return;
            }
            match telegram::decode(&self.buf) {
                Decoded::Incomplete => return,
                Decoded::Frame(_, n) => {
                    self.flush_garbage(out);
                    let bytes: Vec<u8> = self.buf.drain(..n).collect();
                    out.push(Cut::Frame { bytes, t_us: self.t_us });
                }
                Decoded::Invalid(e) => {
                    let b = self.buf.remove(0);
                    self.add_garbage(b, Why::Invalid(e));
                }
            }
        }
    }

    fn add_garbage(&mut self, b: u8, why: Why) {
        self.garbage.push(b);
        self.garbage_t = self.t_us;
        // The most telling reason: an invalid telegram beats a byte without a delimiter.
        if self.why.is_none() || matches!((self.why, why), (Some(Why::NoStartDelimiter), Why::Invalid(_))) {
            self.why = Some(why);
        }
    }

    fn flush_garbage(&mut self, out: &mut Vec<Cut>) {
        if !self.garbage.is_empty() {
            let why = self.why.take().unwrap_or(Why::NoStartDelimiter);
            out.push(Cut::Garbage { bytes: std::mem::take(&mut self.garbage), t_us: self.garbage_t, why });
        }
        self.why = None;
    }

    fn cut_partial(&mut self, why: Why, out: &mut Vec<Cut>) {
        if !self.buf.is_empty() {
            let partial = std::mem::take(&mut self.buf);
            self.garbage.extend(partial);
            self.garbage_t = self.t_us;
            if !matches!(self.why, Some(Why::Invalid(_))) {
                self.why = Some(why);
            }
        }
        self.flush_garbage(out);
    }

    /// The line was silent longer than the gap threshold: a partial telegram is truncated.
    pub fn gap(&mut self, out: &mut Vec<Cut>) {
        self.cut_partial(Why::Truncated, out);
    }

    /// A character error at `t_us`: the telegram in progress is corrupt.
    pub fn line_error(&mut self, t_us: Option<u64>, out: &mut Vec<Cut>) {
        self.t_us = t_us.or(self.t_us);
        if self.buf.is_empty() && self.garbage.is_empty() {
            out.push(Cut::Garbage { bytes: Vec::new(), t_us: self.t_us, why: Why::LineError });
            return;
        }
        self.cut_partial(Why::LineError, out);
    }

    /// The end of the input.
    pub fn finish(&mut self, out: &mut Vec<Cut>) {
        self.cut_partial(Why::Truncated, out);
    }

    /// Bytes of the telegram in progress.
    pub fn pending(&self) -> usize {
        self.buf.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cut(chunks: &[&[u8]]) -> Vec<Cut> {
        let mut c = Cutter::new();
        let mut out = Vec::new();
        for ch in chunks {
            c.push(None, ch, &mut out);
        }
        c.finish(&mut out);
        out
    }

    fn frame(b: &[u8]) -> Cut {
        Cut::Frame { bytes: b.to_vec(), t_us: None }
    }

    #[test]
    fn frames_garbage_and_truncation() {
        let sd1 = [0x10, 0x05, 0x02, 0x49, 0x50, 0x16];
        let out = cut(&[&[0x00, 0xFF], &sd1[..3], &sd1[3..], &[0xE5, 0x10, 0x05]]);
        assert_eq!(
            out,
            [
                Cut::Garbage { bytes: vec![0, 0xFF], t_us: None, why: Why::NoStartDelimiter },
                frame(&sd1),
                frame(&[0xE5]),
                Cut::Garbage { bytes: vec![0x10, 0x05], t_us: None, why: Why::Truncated },
            ]
        );
        // A bad checksum: the frame is garbage, the next one is found.
        let mut bad = sd1;
        bad[4] ^= 1;
        let out = cut(&[&bad, &sd1]);
        assert_eq!(out.last(), Some(&frame(&sd1)));
        assert!(matches!(out[0], Cut::Garbage { why: Why::Invalid(FrameError::Checksum { .. }), .. }));
    }
}
