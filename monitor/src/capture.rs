//! The monitor's capture format: timestamped chunks of line bytes, one per text line.
//!
//! ```text
//! # pbcard-monitor capture 1
//! rate 19200
//! 0.000000 10 05 02 49 50 16
//! 0.001146 00 05 02 00 07 16
//! 0.003021 !
//! - 68 05 05 68 85 82 6D 3C 3E 56 16
//! ```
//!
//! * `#` starts a comment; the first line `# pbcard-monitor capture 1` names the format (the
//!   monitor recognises a capture file by it) and its version.
//! * `rate N` — the transmission rate in bit/s from here on (one of the ten PROFIBUS rates).
//! * `T HEX…` — bytes received at time `T` (seconds since the start of the capture, a decimal
//!   with up to 9 fraction digits; `-` when the time is unknown, e.g. bytes from a file). `T` is
//!   when the *last* byte of the chunk was read: a serial device delivers several bytes per read,
//!   so the time of a byte inside a chunk is not known more precisely.
//! * `T !` — a character error (parity, framing, overrun) at `T`: the telegram in progress is
//!   corrupt.
//!
//! [`parse_line`] reads one line of untrusted text and never panics; [`Writer`] writes the format.

use core::fmt;
use std::io::{self, Write};

use pbcard::time::Baudrate;

/// The first line of every capture file.
pub const HEADER: &str = "# pbcard-monitor capture 1";

/// One line of a capture.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Record {
    /// An empty line or a comment.
    Comment,
    /// `rate N`.
    Rate(Baudrate),
    /// `T HEX…`.
    Bytes {
        /// Time in µs since the start of the capture, `None` for `-`.
        t_us: Option<u64>,
        /// The bytes.
        bytes: Vec<u8>,
    },
    /// `T !`: a character error.
    LineError {
        /// Time in µs, `None` for `-`.
        t_us: Option<u64>,
    },
}

/// Why a line is not a capture record.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CaptureError {
    /// `rate` with a value that is no PROFIBUS rate.
    Rate(String),
    /// The time field is neither `-` nor a decimal number of seconds.
    Time(String),
    /// A byte field that is not two hex digits.
    Byte(String),
    /// A time without bytes (or `!`).
    Empty,
}

impl fmt::Display for CaptureError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CaptureError::Rate(s) => write!(f, "rate '{s}' is no PROFIBUS rate"),
            CaptureError::Time(s) => write!(f, "time '{s}' is not seconds (e.g. 12.000125) or '-'"),
            CaptureError::Byte(s) => write!(f, "'{s}' is not a hex byte"),
            CaptureError::Empty => write!(f, "a time without bytes"),
        }
    }
}

impl std::error::Error for CaptureError {}

/// Seconds with up to 9 fraction digits → µs (rounded down), or `None` for `-`.
fn parse_time(s: &str) -> Result<Option<u64>, CaptureError> {
    if s == "-" {
        return Ok(None);
    }
    let bad = || CaptureError::Time(s.chars().take(40).collect());
    let (int, frac) = s.split_once('.').unwrap_or((s, ""));
    if int.is_empty() || int.len() > 12 || frac.len() > 9 {
        return Err(bad());
    }
    if !int.bytes().chain(frac.bytes()).all(|b| b.is_ascii_digit()) {
        return Err(bad());
    }
    let secs: u64 = int.parse().map_err(|_| bad())?;
    let mut us = 0u64;
    for (i, b) in frac.bytes().take(6).enumerate() {
        us += u64::from(b - b'0') * 10u64.pow(5 - i as u32);
    }
    secs.checked_mul(1_000_000).and_then(|v| v.checked_add(us)).map(Some).ok_or_else(bad)
}

/// Parse one line of a capture.
pub fn parse_line(line: &str) -> Result<Record, CaptureError> {
    let line = line.trim();
    if line.is_empty() || line.starts_with('#') {
        return Ok(Record::Comment);
    }
    let mut fields = line.split_ascii_whitespace();
    let first = fields.next().unwrap_or("");
    if first == "rate" {
        let v = fields.next().unwrap_or("");
        return match v.parse::<u32>().ok().and_then(|n| Baudrate::ALL.into_iter().find(|r| r.bits_per_second() == n)) {
            Some(r) if fields.next().is_none() => Ok(Record::Rate(r)),
            _ => Err(CaptureError::Rate(v.chars().take(40).collect())),
        };
    }
    let t_us = parse_time(first)?;
    let mut bytes = Vec::new();
    let mut error = false;
    for f in fields {
        if f == "!" {
            error = true;
            continue;
        }
        match (f.len(), u8::from_str_radix(f, 16)) {
            (2, Ok(b)) if f.bytes().all(|c| c.is_ascii_hexdigit()) => bytes.push(b),
            _ => return Err(CaptureError::Byte(f.chars().take(40).collect())),
        }
    }
    match (error, bytes.is_empty()) {
        (true, true) => Ok(Record::LineError { t_us }),
        (true, false) => Err(CaptureError::Byte("!".into())),
        (false, true) => Err(CaptureError::Empty),
        (false, false) => Ok(Record::Bytes { t_us, bytes }),
    }
}

/// `12.000125` / `-`.
pub fn format_time(t_us: Option<u64>) -> String {
    match t_us {
        Some(t) => format!("{}.{:06}", t / 1_000_000, t % 1_000_000),
        None => "-".into(),
    }
}

/// Writes a capture.
pub struct Writer<W: Write> {
    out: W,
}

impl<W: Write> Writer<W> {
    /// Start a capture: the header and, when known, the rate.
    pub fn new(mut out: W, rate: Option<Baudrate>) -> io::Result<Self> {
        writeln!(out, "{HEADER}")?;
        if let Some(r) = rate {
            writeln!(out, "rate {}", r.bits_per_second())?;
        }
        Ok(Writer { out })
    }

    /// A chunk of bytes read at `t_us`.
    pub fn bytes(&mut self, t_us: Option<u64>, bytes: &[u8]) -> io::Result<()> {
        if bytes.is_empty() {
            return Ok(());
        }
        writeln!(self.out, "{} {}", format_time(t_us), pbcard_softslave::hex(bytes))
    }

    /// A character error at `t_us`.
    pub fn line_error(&mut self, t_us: Option<u64>) -> io::Result<()> {
        writeln!(self.out, "{} !", format_time(t_us))
    }

    /// Flush the output.
    pub fn flush(&mut self) -> io::Result<()> {
        self.out.flush()
    }

    /// The output back.
    pub fn into_inner(self) -> W {
        self.out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn records() {
        assert_eq!(parse_line(HEADER), Ok(Record::Comment));
        assert_eq!(parse_line("  "), Ok(Record::Comment));
        assert_eq!(parse_line("rate 1500000"), Ok(Record::Rate(Baudrate::B1500k)));
        assert!(parse_line("rate 115200").is_err());
        assert_eq!(
            parse_line("12.000125 10 05 02 49 50 16"),
            Ok(Record::Bytes { t_us: Some(12_000_125), bytes: vec![0x10, 5, 2, 0x49, 0x50, 0x16] })
        );
        assert_eq!(parse_line("- e5"), Ok(Record::Bytes { t_us: None, bytes: vec![0xE5] }));
        assert_eq!(parse_line("3.5 !"), Ok(Record::LineError { t_us: Some(3_500_000) }));
        assert_eq!(parse_line("3"), Err(CaptureError::Empty));
        assert!(parse_line("x 10").is_err());
        assert!(parse_line("1.0 1").is_err());
        assert!(parse_line("1.0 +1").is_err());
        assert!(parse_line("1.0 10 !").is_err());
    }

    #[test]
    fn writer_round_trips() {
        let mut w = Writer::new(Vec::new(), Some(Baudrate::B19200)).unwrap();
        w.bytes(Some(1_234_567), &[0x10, 0x7F]).unwrap();
        w.line_error(None).unwrap();
        let text = String::from_utf8(w.into_inner()).unwrap();
        let recs: Vec<_> = text.lines().map(|l| parse_line(l).unwrap()).collect();
        assert_eq!(
            recs,
            [
                Record::Comment,
                Record::Rate(Baudrate::B19200),
                Record::Bytes { t_us: Some(1_234_567), bytes: vec![0x10, 0x7F] },
                Record::LineError { t_us: None },
            ]
        );
    }

    proptest! {
        #[test]
        fn any_text_parses_or_fails_cleanly(s in "\\PC{0,60}") {
            let _ = parse_line(&s);
        }

        #[test]
        fn written_chunks_read_back(t in proptest::option::of(0u64..1u64 << 50), bytes in proptest::collection::vec(any::<u8>(), 1..40)) {
            let mut w = Writer { out: Vec::new() };
            w.bytes(t, &bytes).unwrap();
            let text = String::from_utf8(w.into_inner()).unwrap();
            prop_assert_eq!(parse_line(&text), Ok(Record::Bytes { t_us: t, bytes }));
        }
    }
}
