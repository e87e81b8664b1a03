//! STM32F4 USART baud-rate divisors (reference §1.2; RM0383 §19.3.4 "Fractional baud rate
//! generation").
//!
//! The USART divides its kernel clock (PCLK2 for USART1/USART6) by `USARTDIV`:
//!
//! * **OVER8 = 0** (16× oversampling): `baud = pclk / (16 · USARTDIV)`. `BRR[15:4]` is the
//!   mantissa of USARTDIV and `BRR[3:0]` its fraction in 1/16 steps, so BRR equals
//!   `pclk / baud` rounded — the number of PCLK cycles per bit.
//! * **OVER8 = 1** (8× oversampling): `baud = pclk / (8 · USARTDIV)`. `BRR[15:4]` is the
//!   mantissa, `BRR[2:0]` the fraction in 1/8 steps and `BRR[3]` must be 0. The receiver's
//!   tolerance to clock deviation is lower, so it is used only when 16× cannot reach the rate
//!   (`pclk / 16 < baud`).
//!
//! In both modes the divisor is a whole number of PCLK cycles per bit
//! ([`Divisor::clocks_per_bit`]), so [`actual_baud`] is the exact rational `pclk / cycles`.
//!
//! At [`PCLK2_HZ`] = 96 MHz every PROFIBUS rate is exact except 45.45 kbit/s, which comes out
//! at 96 MHz / 2112 = 45 454.5 baud (+100.01 ppm). That is the nominal rate itself: PROFIBUS
//! defines "45.45 kbit/s" as 12 MHz / 264 (reference §1.2, last note), which the ASICs produce.

use crate::time::Baudrate;

/// PCLK2 of the reference board (STM32F411CE, PLL at 96 MHz, APB2 prescaler 1): the clock of
/// USART1 and USART6.
pub const PCLK2_HZ: u32 = 96_000_000;

/// The USART settings for one rate: the OVER8 bit of CR1 and the BRR register value.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct Divisor {
    /// CR1.OVER8: oversampling by 8 (`true`) or by 16 (`false`).
    pub over8: bool,
    /// The BRR register value.
    pub brr: u16,
}

impl Divisor {
    /// PCLK cycles per bit (`16 · USARTDIV` with OVER8 = 0, `8 · USARTDIV` with OVER8 = 1).
    pub const fn clocks_per_bit(self) -> u32 {
        if self.over8 {
            ((self.brr as u32 >> 4) << 3) | (self.brr as u32 & 0x7)
        } else {
            self.brr as u32
        }
    }
}

/// The divisor the USART needs for `baud` at a kernel clock of `pclk_hz`: 16× oversampling
/// unless `pclk_hz / 16 < baud`, the cycles per bit rounded to the nearest whole PCLK cycle.
///
/// Out-of-range requests saturate instead of failing (the function is `const` and used for
/// tables): a rate above `pclk / 8` gets the fastest setting (OVER8 = 1, USARTDIV = 1.0), a
/// rate too low for a 12-bit mantissa gets BRR = 0xFFFF, and `baud = 0` is treated as 1.
/// Check the result with [`error_ppm`].
pub const fn usart_divisor(pclk_hz: u32, baud: u32) -> Divisor {
    let baud = if baud == 0 { 1 } else { baud };
    // Cycles per bit, rounded to nearest.
    let cycles = (pclk_hz as u64 + baud as u64 / 2) / baud as u64;
    if (pclk_hz / 16) >= baud {
        // OVER8 = 0: BRR = 16 · USARTDIV = cycles; mantissa ≥ 1 is guaranteed by pclk/16 ≥ baud.
        let brr = if cycles > 0xFFFF { 0xFFFF } else { cycles as u16 };
        Divisor { over8: false, brr }
    } else {
        // OVER8 = 1: cycles = 8 · USARTDIV; here cycles < 32, and at least 8 (USARTDIV ≥ 1).
        let cycles = if cycles < 8 { 8 } else { cycles as u16 };
        Divisor { over8: true, brr: ((cycles >> 3) << 4) | (cycles & 0x7) }
    }
}

/// The divisor for a PROFIBUS rate on the reference board ([`PCLK2_HZ`]).
pub const fn divisor_for(rate: Baudrate) -> Divisor {
    usart_divisor(PCLK2_HZ, rate.bits_per_second())
}

/// An exact baud rate as the fraction `num / den` bits per second.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct Ratio {
    /// Numerator (the kernel clock in Hz).
    pub num: u32,
    /// Denominator (kernel clock cycles per bit, never 0).
    pub den: u32,
}

/// The rate the USART really runs at with divisor `d`: `pclk_hz / d.clocks_per_bit()` (a
/// zero divisor, which the hardware does not allow, is treated as 1).
pub const fn actual_baud(pclk_hz: u32, d: Divisor) -> Ratio {
    let den = d.clocks_per_bit();
    Ratio { num: pclk_hz, den: if den == 0 { 1 } else { den } }
}

/// Deviation of the actual rate from `baud` in parts per million, rounded half away from zero
/// (positive: the USART is faster than nominal).
pub const fn error_ppm(pclk_hz: u32, d: Divisor, baud: u32) -> i64 {
    let r = actual_baud(pclk_hz, d);
    let baud = if baud == 0 { 1 } else { baud };
    // (num/den − baud) / baud · 1e6 = (num − baud·den) · 1e6 / (baud·den)
    let diff = r.num as i64 - baud as i64 * r.den as i64;
    let q = baud as i64 * r.den as i64;
    let scaled = diff * 1_000_000;
    if scaled >= 0 {
        (scaled + q / 2) / q
    } else {
        -((-scaled + q / 2) / q)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The table of reference §1.2 for PCLK 96 MHz, in OVER8 = 1 units (8 · USARTDIV):
    /// 1250, 625, 264, 128, 64, 24, 8, 4, 2, 1 — here as cycles per bit (× 8) plus the
    /// expected OVER8 choice and BRR of [`usart_divisor`], and the exact error in ppm.
    const TABLE_96M: [(Baudrate, u32, bool, u16, i64); 10] = [
        (Baudrate::B12M, 8, true, 0x0010, 0),
        (Baudrate::B6M, 16, false, 0x0010, 0),
        (Baudrate::B3M, 32, false, 0x0020, 0),
        (Baudrate::B1500k, 64, false, 0x0040, 0),
        (Baudrate::B500k, 192, false, 0x00C0, 0),
        (Baudrate::B187500, 512, false, 0x0200, 0),
        (Baudrate::B93750, 1024, false, 0x0400, 0),
        (Baudrate::B45450, 2112, false, 0x0840, 100),
        (Baudrate::B19200, 5000, false, 0x1388, 0),
        (Baudrate::B9600, 10000, false, 0x2710, 0),
    ];

    #[test]
    fn reference_table_at_96_mhz() {
        for (rate, cycles, over8, brr, ppm) in TABLE_96M {
            let d = divisor_for(rate);
            assert_eq!(d, Divisor { over8, brr }, "{rate:?}");
            assert_eq!(d.clocks_per_bit(), cycles, "{rate:?}");
            // The reference table lists 8 · USARTDIV (OVER8 = 1 units).
            assert_eq!(cycles % 8, 0);
            assert_eq!(error_ppm(PCLK2_HZ, d, rate.bits_per_second()), ppm, "{rate:?}");
            let r = actual_baud(PCLK2_HZ, d);
            assert_eq!(r, Ratio { num: PCLK2_HZ, den: cycles });
        }
    }

    #[test]
    fn all_rates_within_one_hundredth_percent() {
        for rate in Baudrate::ALL {
            let d = divisor_for(rate);
            let r = actual_baud(PCLK2_HZ, d);
            let baud = rate.bits_per_second() as u64;
            // |num/den − baud| / baud ≤ 1/10000, exactly: |num − baud·den| · 10000 ≤ baud·den.
            let diff = (r.num as u64).abs_diff(baud * r.den as u64);
            if rate == Baudrate::B45450 {
                // 96e6/2112 = 45454.54…: +1/9999 = 0.010001 % — the "0.01 %" of the table is
                // this value rounded; it is exactly the nominal 12 MHz / 264.
                assert_eq!(r.num as u64 * 9999, 10000 * baud * r.den as u64);
                assert_eq!(diff * 9999, baud * r.den as u64);
                assert_eq!(r.num as u64 * 264, 12_000_000 * r.den as u64);
            } else {
                assert!(diff * 10000 <= baud * r.den as u64, "{rate:?}");
                assert_eq!(diff, 0, "{rate:?} is exact at 96 MHz");
            }
        }
    }

    #[test]
    fn twelve_megabit_needs_over8() {
        assert_eq!(usart_divisor(96_000_000, 12_000_000), Divisor { over8: true, brr: 0x10 });
        // 84 MHz (F407): 12 M is out of reach (needs USARTDIV 0.875) → saturates to 1.0 = 10.5 M.
        let d = usart_divisor(84_000_000, 12_000_000);
        assert_eq!(d, Divisor { over8: true, brr: 0x10 });
        assert_eq!(error_ppm(84_000_000, d, 12_000_000), -125_000);
        // 6 M at 84 MHz: 14 cycles = USARTDIV 1.75 with OVER8 (BRR 0x16).
        assert_eq!(usart_divisor(84_000_000, 6_000_000), Divisor { over8: true, brr: 0x16 });
    }

    #[test]
    fn other_clocks_match_reference_table() {
        // 84 MHz column: 9.6 k = 1093.75 (OVER8 units) = 8750 cycles, exact.
        let d = usart_divisor(84_000_000, 9600);
        assert_eq!(d.clocks_per_bit(), 8750);
        assert_eq!(error_ppm(84_000_000, d, 9600), 0);
        // 90 MHz, 19.2 k: 586.000 (OVER8 units) → 4688 cycles, −0.011 %.
        let d = usart_divisor(90_000_000, 19200);
        assert_eq!(d.clocks_per_bit(), 4688);
        assert_eq!(error_ppm(90_000_000, d, 19200), -107);
        // 100 MHz, 187.5 k: 533 cycles (66.625 in OVER8 units), +0.0625 % (table: +0.06 %).
        let d = usart_divisor(100_000_000, 187_500);
        assert_eq!(d.clocks_per_bit(), 533);
        assert_eq!(error_ppm(100_000_000, d, 187_500), 625);
    }

    #[test]
    fn saturation() {
        assert_eq!(usart_divisor(96_000_000, 0).brr, 0xFFFF);
        assert_eq!(usart_divisor(96_000_000, 100).brr, 0xFFFF);
        assert_eq!(usart_divisor(96_000_000, 50_000_000), Divisor { over8: true, brr: 0x10 });
    }

    proptest::proptest! {
        /// Whatever the clock and rate, the BRR encoding is legal (BRR[3] = 0 with OVER8,
        /// mantissa ≥ 1) and, where reachable, the divisor is the nearest one.
        #[test]
        fn divisor_is_legal_and_nearest(pclk in 1_000_000u32..=200_000_000, baud in 1200u32..=12_500_000) {
            let d = usart_divisor(pclk, baud);
            proptest::prop_assert!(d.brr >> 4 >= 1);
            if d.over8 {
                proptest::prop_assert_eq!(d.brr & 0x8, 0);
                proptest::prop_assert!(pclk / 16 < baud);
            }
            let c = d.clocks_per_bit() as u64;
            let (p, b) = (pclk as u64, baud as u64);
            let reachable = p / b >= 8 && (d.over8 || p / b <= 0xFFFF);
            if reachable {
                // |p/c − b| is minimal: 2·|p − b·c| ≤ b.
                proptest::prop_assert!(2 * p.abs_diff(b * c) <= b, "pclk {} baud {} cycles {}", p, b, c);
            }
        }
    }
}
