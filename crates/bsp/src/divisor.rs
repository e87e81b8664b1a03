//! The USART divisor as the board code needs it: a thin adapter over the protocol library's
//! `pbcard::phy::divisor` (the one implementation, host-tested for all ten rates at 96 MHz).

use pbcard::phy::divisor::{self, Divisor};

/// Divisor register settings for `baud` at peripheral clock `pclk_hz`: `Some((over8, brr))`,
/// or `None` when the rate cannot be generated (zero, or faster than pclk / 8).
pub const fn usart_brr(pclk_hz: u32, baud: u32) -> Option<(bool, u16)> {
    if baud == 0 || baud > pclk_hz / 8 {
        return None;
    }
    let d = divisor::usart_divisor(pclk_hz, baud);
    Some((d.over8, d.brr))
}

/// The bit rate the register values give, in bit/s (rounded down; logged by the F411 board).
#[cfg_attr(not(feature = "board-f411"), allow(dead_code))]
pub fn actual_baud(pclk_hz: u32, over8: bool, brr: u16) -> u32 {
    let r = divisor::actual_baud(pclk_hz, Divisor { over8, brr });
    r.num / r.den
}
