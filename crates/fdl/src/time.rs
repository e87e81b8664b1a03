//! Time as the protocol core sees it: a monotonic [`Instant`] in microseconds handed in by the
//! caller, [`Duration`]s between them, and [`BitTimes`] (the unit of every FDL timing parameter:
//! TSYN, min_TSDR, max_TSDR, slot time — reference §1.3).

use core::ops::{Add, Sub};

/// A point in time, in microseconds since an arbitrary origin chosen by the caller.
///
/// The core never reads a clock: every entry point takes `now: Instant`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct Instant(u64);

impl Instant {
    /// The instant `micros` microseconds after the origin.
    pub const fn from_micros(micros: u64) -> Self {
        Instant(micros)
    }
    /// The instant `millis` milliseconds after the origin.
    pub const fn from_millis(millis: u64) -> Self {
        Instant(millis * 1000)
    }
    /// Microseconds since the origin.
    pub const fn as_micros(self) -> u64 {
        self.0
    }
    /// Time elapsed since `earlier`, zero if `earlier` is in the future.
    pub const fn saturating_since(self, earlier: Instant) -> Duration {
        Duration(self.0.saturating_sub(earlier.0))
    }
}

/// A span of time in microseconds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct Duration(u64);

impl Duration {
    /// Zero.
    pub const ZERO: Duration = Duration(0);
    /// `micros` microseconds.
    pub const fn from_micros(micros: u64) -> Self {
        Duration(micros)
    }
    /// `millis` milliseconds.
    pub const fn from_millis(millis: u64) -> Self {
        Duration(millis * 1000)
    }
    /// In microseconds.
    pub const fn as_micros(self) -> u64 {
        self.0
    }
    /// In whole milliseconds (rounded down).
    pub const fn as_millis(self) -> u64 {
        self.0 / 1000
    }
}

impl Add<Duration> for Instant {
    type Output = Instant;
    fn add(self, d: Duration) -> Instant {
        Instant(self.0.saturating_add(d.0))
    }
}

impl Sub<Instant> for Instant {
    type Output = Duration;
    fn sub(self, earlier: Instant) -> Duration {
        self.saturating_since(earlier)
    }
}

/// The ten PROFIBUS DP transmission rates over RS485 (reference §1.2), in the order the
/// autobaud search visits them (highest first). The discriminant is the P0963 / SPC3
/// baud-rate status code (0 = 12 Mbit/s … 9 = 9.6 kbit/s).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[allow(missing_docs)]
pub enum Baudrate {
    B12M = 0,
    B6M = 1,
    B3M = 2,
    B1500k = 3,
    B500k = 4,
    B187500 = 5,
    B93750 = 6,
    B45450 = 7,
    B19200 = 8,
    B9600 = 9,
}

impl Baudrate {
    /// All rates, highest first (the autobaud search order).
    pub const ALL: [Baudrate; 10] = [
        Baudrate::B12M,
        Baudrate::B6M,
        Baudrate::B3M,
        Baudrate::B1500k,
        Baudrate::B500k,
        Baudrate::B187500,
        Baudrate::B93750,
        Baudrate::B45450,
        Baudrate::B19200,
        Baudrate::B9600,
    ];

    /// Bits per second.
    pub const fn bits_per_second(self) -> u32 {
        match self {
            Baudrate::B12M => 12_000_000,
            Baudrate::B6M => 6_000_000,
            Baudrate::B3M => 3_000_000,
            Baudrate::B1500k => 1_500_000,
            Baudrate::B500k => 500_000,
            Baudrate::B187500 => 187_500,
            Baudrate::B93750 => 93_750,
            Baudrate::B45450 => 45_450,
            Baudrate::B19200 => 19_200,
            Baudrate::B9600 => 9_600,
        }
    }

    /// The baud-rate code of the manuals' P0963 parameter (CFW500 §4, "detected baud rate"):
    /// 0 = 9.6k, 1 = 19.2k, 2 = 93.75k, 3 = 187.5k, 4 = 500k, 5 = not detected,
    /// 6 = 1.5M, 7 = 3M, 8 = 6M, 9 = 12M, 10 = reserved, 11 = 45.45k.
    pub const fn p0963_code(self) -> u8 {
        match self {
            Baudrate::B9600 => 0,
            Baudrate::B19200 => 1,
            Baudrate::B93750 => 2,
            Baudrate::B187500 => 3,
            Baudrate::B500k => 4,
            Baudrate::B1500k => 6,
            Baudrate::B3M => 7,
            Baudrate::B6M => 8,
            Baudrate::B12M => 9,
            Baudrate::B45450 => 11,
        }
    }

    /// Duration of `bits` bit times at this rate, rounded up to whole microseconds.
    pub const fn bits_to_duration(self, bits: u32) -> Duration {
        let bps = self.bits_per_second() as u64;
        Duration((bits as u64 * 1_000_000).div_ceil(bps))
    }

    /// Bit times elapsed in `d` at this rate (rounded down; saturates instead of overflowing
    /// for durations beyond ≈ 48 000 years at 12 Mbit/s, e.g. a capture file's wild timestamp).
    pub const fn duration_to_bits(self, d: Duration) -> u64 {
        let bps = self.bits_per_second() as u64;
        let (s, us) = (d.as_micros() / 1_000_000, d.as_micros() % 1_000_000);
        // floor((s·10⁶ + us)·bps / 10⁶) = s·bps + floor(us·bps / 10⁶): exact, no overflow.
        s.saturating_mul(bps).saturating_add(us * bps / 1_000_000)
    }
}

/// A count of bit times `t_bit` (reference §1.3): the unit of TSYN, min_TSDR and max_TSDR.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct BitTimes(pub u32);

impl BitTimes {
    /// T_SYN: the 33 bit times of idle line that precede every request (reference §1.1).
    pub const TSYN: BitTimes = BitTimes(33);
    /// The default and smallest min_TSDR (11 bit times, reference §1.3).
    pub const MIN_TSDR_DEFAULT: BitTimes = BitTimes(11);
    /// One UART character: start + 8 data + even parity + stop (reference §1.1).
    pub const CHAR: BitTimes = BitTimes(11);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bit_time_conversions() {
        assert_eq!(Baudrate::B9600.bits_to_duration(33), Duration::from_micros(3438));
        assert_eq!(Baudrate::B12M.bits_to_duration(12), Duration::from_micros(1));
        assert_eq!(Baudrate::B1500k.duration_to_bits(Duration::from_millis(1)), 1500);
        assert_eq!(Baudrate::B12M.duration_to_bits(Duration::from_micros(2_500_001)), 30_000_012);
        assert_eq!(Baudrate::B9600.duration_to_bits(Duration::from_micros(1_999_999)), 19_199);
    }

    /// The monitor_capture fuzz target found it: a capture's huge timestamp overflowed the
    /// multiplication. Now it saturates; the conversion stays exact below it.
    #[test]
    fn duration_to_bits_never_overflows() {
        for b in Baudrate::ALL {
            for us in [u64::MAX, u64::MAX / 3, 123_456_789_012, 999_999] {
                let exact = u128::from(us) * u128::from(b.bits_per_second()) / 1_000_000;
                let want = u64::try_from(exact).unwrap_or(u64::MAX);
                assert_eq!(b.duration_to_bits(Duration::from_micros(us)), want, "{b:?} {us}");
            }
        }
    }

    #[test]
    fn p0963_codes_are_distinct() {
        let mut seen = [false; 16];
        for b in Baudrate::ALL {
            assert!(!seen[b.p0963_code() as usize]);
            seen[b.p0963_code() as usize] = true;
        }
    }
}
