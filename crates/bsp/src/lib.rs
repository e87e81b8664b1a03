//! Board support (`pbcard-bsp`): the hardware edge of the firmware, the only crate with
//! registers and `unsafe` (ARCHITECTURE §3). The RTIC app (`pbcard-firmware`, `firmware/src/main.rs`) talks to the board only through the
//! board contract's traits of the library (README "Hardware"), so that the later boards — and
//! the soft slave's serial port — implement the same shape: the line `pbcard::phy::port`
//! ([`LineRate`], [`DriverEnable`], [`BitTimer`], [`Transmitter`], [`CharReceiver`]), the
//! flash `pbcard::store::Flash`, the DPM transport `pbcard::dpm::spi::SlavePort`; the
//! protocol clock is [`Clock`].
//!
//! * [`f411::DmaLine`] (feature `board-f411`) — USART1 + DMA2 (circular receive ring cut into
//!   telegrams at IDLE, transmit DMA), TIM5 as the bit timer (T_SYN proof, min_TSDR start by
//!   compare), DE on PA8, autobaud through [`LineRate::set_rate`]; the address journal's
//!   flash ([`flash`]), the DPM's SPI slave ([`spi`]), LEDs and IWDG, and the panic /
//!   HardFault path ([`fault`]);
//! * [`qemu::QemuUsart1`] (feature `qemu`) — QEMU netduinoplus2: one interrupt per byte (a
//!   [`CharReceiver`]), no IDLE flag, no DMA, no line timing (the [`BitTimer`] counts the
//!   protocol clock's microseconds), no DE, HSI clock, no flash store, the DPM in-process.
//!
//! Each board module offers `NAME`, `Board` and `init(device, SYST, rate) -> Board`; the
//! line differs (per byte on QEMU, per telegram on the F411), so `main.rs` has one line
//! block per board and shares everything above the line (node, application, DP-V1 task).
//!
//! On the host the crate is empty (the workspace's `cargo test` builds every member): the
//! hardware crates are target-gated.

#![cfg_attr(target_os = "none", no_std)]
#![cfg(target_os = "none")]

#[cfg(all(feature = "board-f411", feature = "qemu"))]
compile_error!("features `board-f411` and `qemu` are exclusive: the firmware chooses one board");

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

use pbcard::time::Instant;

/// What runs behind the node: the bench with the simulated drive (QEMU, and the F411 with
/// `sim-drive`: [`pbcard_sim::bench::Application`]).
#[cfg(any(feature = "qemu", feature = "sim-drive"))]
pub type CardApp = pbcard_sim::bench::Application;
/// What runs behind the node: the card alone (the F411 with a drive: [`pbcard::app::Card`];
/// no simulated drive is linked).
#[cfg(not(any(feature = "qemu", feature = "sim-drive")))]
pub type CardApp = pbcard::app::Card;

/// A monotonic clock in microseconds that does not wrap in the product's lifetime.
pub trait Clock {
    /// The current time.
    fn now(&self) -> Instant;
}

// The line's contract (issue 13 item 3) lives in the library, so that the soft slave's serial
// port implements the same traits: `pbcard::phy::port` (README "Hardware"). Each board uses
// some of them.
#[allow(unused_imports)]
pub use pbcard::phy::port::{
    BitTimer, CharReceiver, DriverEnable, LineError, LineEvent, LineRate, Transmitter, TxError, UnsupportedRate,
};
