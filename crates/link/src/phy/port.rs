//! The board contract of the PROFIBUS line (issue 13 item 3): the small traits every platform
//! implements for its RS485 port — the STM32F411's DMA line (`crates/bsp/src/f411.rs` `DmaLine`), QEMU's
//! per-character USART (`crates/bsp/src/qemu.rs` `QemuUsart1`) and the soft slave's serial port
//! (`softslave/src/serial.rs` `Port`). They describe what the platforms do, not a new line:
//!
//! | trait | what it is | who calls it |
//! |---|---|---|
//! | [`LineRate`] | the USART's rate (autobaud steps through [`Baudrate::ALL`]) | the line's own code (F411: the TIM5 interrupt carrying out a `phy::rate_link` switch) |
//! | [`DriverEnable`] | the transceiver's DE (RTS) | the transmitter, just before the first start bit and after the last stop bit |
//! | [`BitTimer`] | a free-running 32-bit counter of the line's time, with "reached?" | the line interrupt / the host loop, for min_TSDR, max_TSDR and T_SYN |
//! | [`Transmitter`] | send one response at (or after) a bit-timer instant, DE around it | the fast path's answer path (line priority) |
//! | [`CharReceiver`] | per-character ports: the next received character, error or end of a response | the port's interrupt handler / the host loop, until `None` |
//!
//! **Common rules.** No method blocks waiting for the line (the soft slave's documented
//! exceptions: a host process has no compare interrupt and no transmit-complete event).
//! Time is an argument or a reading of the port's own [`BitTimer`], never a global. On the
//! firmware every method runs at the line's priority (16, the USART1 and TIM5 interrupts):
//! no lower task calls them (lower tasks reach the line through atomics and mailboxes,
//! `phy::rate_link`, the board's `control`). A per-telegram DMA port (the F411) does not
//! implement [`CharReceiver`]: its receive side is [`super::line::Receiver`] fed at IDLE.

use super::line::{reached, BitClock};
use crate::time::{Baudrate, BitTimes, Instant};

/// The rate cannot be generated from the port's clock.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct UnsupportedRate(pub Baudrate);

/// The line's rate: an 11-bit-character UART (8 data bits, even parity, 1 stop bit).
pub trait LineRate {
    /// The rate the port runs at.
    fn rate(&self) -> Baudrate;

    /// Switch to `rate`: aborts a response in flight (DE released), drops any character in
    /// flight and whatever was received but not yet handed on; the receiver waits for T_SYN
    /// again. On error the old rate stays. Not under a running response unless aborting it
    /// is meant (autobaud switches only while [`Transmitter::tx_busy`] is false).
    fn set_rate(&mut self, rate: Baudrate) -> Result<(), UnsupportedRate>;
}

/// The RS485 transceiver's driver enable (RTS / DE). The STM32F4 USART has no hardware DE: a
/// GPIO (F411 PA8). A port whose adapter switches direction itself implements both as no-ops.
pub trait DriverEnable {
    /// Drive the bus: called just before the first start bit of a response.
    fn enable(&mut self);
    /// Release the bus: called after the last stop bit (F411: from USART TC).
    fn disable(&mut self);
}

/// The bit timer: a free-running up-counting 32-bit counter, [`BitTimer::clock`] ticks per
/// second, wrapping (differences are valid for half the wrap period). The line's instants
/// ([`BitClock::response_not_before`], [`BitClock::tsyn_check_at`], …) are values of it.
pub trait BitTimer {
    /// The counter's rate (F411: TIM5 at the timer clock; a port without a hardware bit timer
    /// counts microseconds, 1 MHz).
    fn clock(&self) -> BitClock;

    /// The counter now (a register read, no side effect).
    fn ticks(&self) -> u32;

    /// Whether the counter has reached `at` (the "already passed?" check before and after
    /// arming a compare, [`super::timing::compare_passed`]).
    fn reached(&self, at: u32) -> bool {
        reached(self.ticks(), at)
    }
}

/// Why a response could not be started.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum TxError {
    /// A response is still being sent (or waits for its start).
    Busy,
    /// Empty, or longer than the port's transmit buffer (one PROFIBUS telegram, 255 octets).
    BadLength,
}

/// The transmitter: one response telegram at a time.
pub trait Transmitter {
    /// Send `bytes` (one telegram): the port copies them and returns at once. The first start
    /// bit goes out when the [`BitTimer`] has reached `not_before` — at once if it already
    /// has (the caller computed it: min_TSDR after the request's last stop bit,
    /// [`BitClock::response_not_before`]). [`DriverEnable::enable`] just before, the
    /// characters back to back, [`DriverEnable::disable`] after the last stop bit. The
    /// decision whether to answer at all (line active since the request, max_TSDR) is the
    /// caller's ([`super::line::tx_plan`]); a delayed start still drops the response when a
    /// character arrived before it (the line was not idle after the request).
    fn start_tx(&mut self, bytes: &[u8], not_before: u32) -> Result<(), TxError>;

    /// True from [`start_tx`](Transmitter::start_tx) until the last stop bit is out and the
    /// driver released ([`LineEvent::TxDone`] on a per-character port): the rate must not be
    /// switched under it, and a second response is refused ([`TxError::Busy`]).
    fn tx_busy(&self) -> bool;
}

/// What went wrong with one received character; the character is dropped (per-character
/// ports).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct LineError {
    /// Even parity did not match (PE).
    pub parity: bool,
    /// No stop bit where one was expected (FE): wrong rate, break, collision.
    pub framing: bool,
    /// The start bit or data bits were sampled inconsistently (NF).
    pub noise: bool,
    /// A character was lost because the previous one had not been read (ORE).
    pub overrun: bool,
}

/// What a [`CharReceiver`] reports, in line order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum LineEvent {
    /// One error-free character.
    Byte {
        /// the data octet (the parity bit already checked and stripped)
        byte: u8,
        /// when the character was complete (as close to its stop bit as the port can tell)
        at: Instant,
        /// idle line measured before this character, in bit times; 0 when back to back or
        /// unknown. A port reports only gaps it is sure of (≥ T_SYN + one character for a
        /// per-character port, whose timestamps jitter by the interrupt latency).
        idle_before: BitTimes,
    },
    /// A character with a line error was dropped: the telegram it belonged to is lost.
    Error(LineError),
    /// The response started by [`Transmitter::start_tx`] is completely on the wire (last stop
    /// bit sent) and the driver is released.
    TxDone,
}

/// A per-character receiver (QEMU's USART, the soft slave's tty). Serviced from the port's
/// interrupt handler (or the host loop) by calling [`poll_event`](CharReceiver::poll_event)
/// until it returns `None`.
pub trait CharReceiver {
    /// Service the port: the next event, or `None` when nothing (more) is pending. Transmit
    /// progress of an interrupt-driven port (the next character, the driver release) happens
    /// inside this call. Never waits for a character.
    fn poll_event(&mut self) -> Option<LineEvent>;
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A bit timer over a fixed counter value.
    struct At(u32);

    impl BitTimer for At {
        fn clock(&self) -> BitClock {
            BitClock { hz: 1_000_000 }
        }
        fn ticks(&self) -> u32 {
            self.0
        }
    }

    #[test]
    fn reached_wraps() {
        assert!(At(10).reached(10));
        assert!(At(11).reached(10));
        assert!(!At(9).reached(10));
        // Across the counter's wrap.
        assert!(At(5).reached(u32::MAX - 5));
        assert!(!At(u32::MAX - 5).reached(5));
    }
}
