//! STM32F4 USART baud-rate divisor (pure arithmetic, no registers).
//!
//! Reference manual RM0383 §19.3.4: with OVER8 = 0 the receiver oversamples by 16 and
//! `BRR = round(pclk / baud)` (mantissa in BRR[15:4], a fraction in 1/16 steps in BRR[3:0]);
//! with OVER8 = 1 it oversamples by 8, the fraction has 1/8 steps in BRR[2:0] and BRR[3]
//! must be 0. Oversampling by 16 tolerates more clock deviation, so it is used whenever the
//! divisor allows it (pclk / baud ≥ 16); OVER8 only for the top rate (12 Mbit/s at 96 MHz).
//!
//! At PCLK2 = 96 MHz every PROFIBUS rate divides to ≤ 0.01 % error (reference §1.2).

/// The fastest rate the receiver accepts relative to the peripheral clock: pclk / 8.
const MIN_DIV_OVER8: u32 = 8;
/// Below pclk / 16 oversampling by 16 is possible.
const MIN_DIV_OVER16: u32 = 16;

/// Divisor register settings for `baud` at peripheral clock `pclk_hz`:
/// `Some((over8, brr))`, or `None` when the rate cannot be generated
/// (faster than pclk / 8, slower than the 12-bit mantissa allows, or zero).
pub const fn usart_brr(pclk_hz: u32, baud: u32) -> Option<(bool, u16)> {
    if baud == 0 {
        return None;
    }
    // round(pclk / baud) in units of 1/16 (OVER8 = 0) of the USARTDIV.
    let div16 = (pclk_hz as u64 + baud as u64 / 2) / baud as u64;
    if div16 >= MIN_DIV_OVER16 as u64 {
        if div16 > 0xFFFF {
            return None;
        }
        return Some((false, div16 as u16));
    }
    // round(pclk / baud) in units of 1/8 (OVER8 = 1): the same number, other layout.
    let div8 = div16;
    if div8 < MIN_DIV_OVER8 as u64 {
        return None;
    }
    let mantissa = div8 >> 3;
    let fraction = div8 & 0x7;
    Some((true, ((mantissa << 4) | fraction) as u16))
}

/// The rate actually produced by a divisor setting, in bit/s (rounded down).
#[cfg_attr(not(feature = "board-f411"), allow(dead_code))] // logged by the F411 board
pub const fn actual_baud(pclk_hz: u32, over8: bool, brr: u16) -> u32 {
    let div = if over8 {
        // mantissa * 8 + fraction (1/8 steps)
        ((brr as u32) >> 4) * 8 + (brr as u32 & 0x7)
    } else {
        brr as u32
    };
    if div == 0 {
        return 0;
    }
    pclk_hz / div
}

#[cfg(test)]
mod tests {
    use super::*;

    const PCLK: u32 = 96_000_000;
    const RATES: [u32; 10] =
        [12_000_000, 6_000_000, 3_000_000, 1_500_000, 500_000, 187_500, 93_750, 45_450, 19_200, 9_600];

    #[test]
    fn twelve_megabit_uses_over8_brr_1_0() {
        assert_eq!(usart_brr(PCLK, 12_000_000), Some((true, 0x10)));
    }

    #[test]
    fn six_megabit_and_below_oversample_by_16() {
        assert_eq!(usart_brr(PCLK, 6_000_000), Some((false, 16)));
        assert_eq!(usart_brr(PCLK, 1_500_000), Some((false, 64)));
        assert_eq!(usart_brr(PCLK, 9_600), Some((false, 10_000)));
    }

    #[test]
    fn all_profibus_rates_within_0_01_percent_at_96_mhz() {
        for baud in RATES {
            let (over8, brr) = usart_brr(PCLK, baud).expect("reachable");
            let actual = actual_baud(PCLK, over8, brr) as i64;
            let err_ppm = (actual - baud as i64).abs() * 1_000_000 / baud as i64;
            assert!(err_ppm <= 100, "{baud}: {actual} ({err_ppm} ppm)");
            if over8 {
                assert_eq!(brr & 0x8, 0, "BRR[3] must be 0 with OVER8");
            }
        }
    }

    #[test]
    fn unreachable_rates() {
        assert_eq!(usart_brr(84_000_000, 12_000_000), None);
        assert_eq!(usart_brr(PCLK, 0), None);
        assert_eq!(usart_brr(PCLK, 1_000), None); // mantissa overflows 12 bits
    }
}
