//! Board support: the hardware edge of the firmware, the only place with registers and
//! `unsafe` (ARCHITECTURE §3). The RTIC app in `main.rs` talks to the board only through the
//! small traits below, so that the later boards implement the same shape:
//!
//! * [`f411::DmaLine`] (feature `board-f411`) — USART1 + DMA2 (circular receive ring cut into
//!   telegrams at IDLE, transmit DMA), TIM5 as the bit timer (T_SYN proof, min_TSDR start by
//!   compare), DE on PA8, autobaud through [`f411::DmaLine::set_baud`]; the address journal's
//!   flash ([`flash`]), LEDs and IWDG, and the panic / HardFault path ([`fault`]);
//! * [`qemu::QemuUsart1`] (feature `qemu`) — QEMU netduinoplus2: one interrupt per byte (a
//!   [`BusPort`]), no IDLE flag, no DMA, no line timing, HSI clock.
//!
//! Each board module offers `NAME`, `Board` and `init(device, SYST, rate) -> Board`; the
//! line differs (per byte on QEMU, per telegram on the F411), so `main.rs` has one line
//! block per board and shares everything above the line (node, application, DP-V1 task).
//!
//! Only `main.rs` declares this module: it is never compiled for the host.

pub mod clock;
pub mod divisor;
#[cfg(feature = "board-f411")]
pub mod f411;
#[cfg(feature = "board-f411")]
pub mod fault;
#[cfg(feature = "board-f411")]
pub mod flash;
#[cfg(feature = "qemu")]
pub mod qemu;
/// The DPM transport to the drive's control board: SPI2 slave + DMA1 (issue 7 item 4).
#[cfg(feature = "board-f411")]
pub mod spi;

/// The board this firmware is built for (cargo feature `board-f411` or `qemu`).
#[cfg(feature = "board-f411")]
pub use f411 as board;
/// The board this firmware is built for (cargo feature `board-f411` or `qemu`).
#[cfg(feature = "qemu")]
pub use qemu as board;

use pbcard::time::{Baudrate, BitTimes, Instant};

/// A monotonic clock in microseconds that does not wrap in the product's lifetime.
pub trait Clock {
    /// The current time.
    fn now(&self) -> Instant;
}

/// The RS485 transceiver's driver enable (RTS / DE). The F4 USART has no hardware DE: a GPIO.
/// (QEMU has no GPIO: its port has no DE.)
#[cfg_attr(not(feature = "board-f411"), allow(dead_code))]
pub trait DriverEnable {
    /// Drive the bus (called just before the first start bit of a response).
    fn enable(&mut self);
    /// Release the bus (called after the last stop bit, from USART TC).
    fn disable(&mut self);
}

/// What went wrong with one received character; the character is dropped (per-byte ports).
#[cfg_attr(feature = "board-f411", allow(dead_code))]
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, defmt::Format)]
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

/// What a [`BusPort`] has to report, in line order.
#[cfg_attr(feature = "board-f411", allow(dead_code))]
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub enum LineEvent {
    /// One error-free character.
    Byte {
        /// the data octet (the parity bit already checked and stripped)
        byte: u8,
        /// when the character was complete (as close to its stop bit as the port can tell)
        at: Instant,
        /// idle line measured before this character, in bit times; 0 when back to back or
        /// unknown. A port reports only gaps it is sure of (≥ T_SYN + one character for a
        /// per-byte port, whose timestamps jitter by the interrupt latency).
        idle_before: BitTimes,
    },
    /// A character with a line error was dropped: the telegram it belonged to is lost.
    Error(LineError),
    /// The response started by [`BusPort::start_tx`] is completely on the wire (last stop
    /// bit sent) and the driver is released.
    TxDone,
}

/// Why a response could not be started.
#[cfg_attr(feature = "board-f411", allow(dead_code))]
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub enum TxError {
    /// A response is still being sent.
    Busy,
    /// Empty, or longer than the port's transmit buffer (one PROFIBUS telegram, 255 octets).
    BadLength,
}

/// The rate cannot be generated from the port's clock.
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub struct UnsupportedRate(pub Baudrate);

/// The PROFIBUS line: an 11-bit-character UART (8 data, even parity, 1 stop) on RS485, one
/// character at a time (the QEMU board; the F411's DMA line works per telegram).
#[cfg_attr(feature = "board-f411", allow(dead_code))]
///
/// Interrupt-driven ports are serviced from their interrupt handler by calling
/// [`poll_event`](BusPort::poll_event) until it returns `None`.
pub trait BusPort {
    /// Switch the line to `rate` (autobaud steps through [`Baudrate::ALL`]). Drops any
    /// character in flight and aborts a running response.
    fn set_baud(&mut self, rate: Baudrate) -> Result<(), UnsupportedRate>;

    /// The current line rate.
    fn baud(&self) -> Baudrate;

    /// Send one response telegram. The port copies `bytes`, keeps the line idle until at
    /// least `min_gap` bit times (min_TSDR) have passed since the last stop bit it received,
    /// enables the driver, sends the characters back to back, and releases the driver after
    /// the last stop bit ([`LineEvent::TxDone`]). (The QEMU line stages its answers for a
    /// quiet window instead, `QemuUsart1::stage_tx`.)
    #[cfg_attr(feature = "qemu", allow(dead_code))]
    fn start_tx(&mut self, bytes: &[u8], min_gap: BitTimes) -> Result<(), TxError>;

    /// True from [`start_tx`](BusPort::start_tx) until [`LineEvent::TxDone`] (autobaud must
    /// not switch the rate under a running response).
    #[allow(dead_code)] // first user: the autobaud layer
    fn tx_busy(&self) -> bool;

    /// Service the hardware: the next event, or `None` when nothing (more) is pending.
    /// Transmit progress (the next character, driver release) happens inside this call.
    fn poll_event(&mut self) -> Option<LineEvent>;
}
