//! # pbcard — the protocol core of a PROFIBUS DP-V1 slave option card for AC drives
//!
//! This library is the card's *sans-IO* protocol stack. It never touches a register or reads a
//! clock: bytes, gaps and time are handed in by the board support code (`crates/bsp`, the QEMU
//! build, the soft slave or the host tests), and responses come back as byte slices that the
//! caller puts on the wire.
//!
//! Data flows one way, and every lower layer defines the trait its upper layer implements:
//!
//! ```text
//! bytes ─▶ fdl::framer ─▶ fdl::telegram ─▶ fdl::station ─▶ dp::slave ─▶ (DP-V1 / profile / DPM)
//! ```
//!
//! * [`fdl`] — PROFIBUS layer 2 (FDL): frame formats SD1/SD2/SD3/SD4/SC, the checksum, the
//!   byte-stream framer, and the station that answers FDL_Status, handles FCB/FCV retries and
//!   dispatches SAPs (IEC 61158-4-3 / EN 50170 vol. 2, reference §2). The crate `pbcard-fdl`
//!   (`crates/fdl`), with [`time`].
//! * [`dp`] — the DP-V0 slave: state machine, Set_Prm, Chk_Cfg/Get_Cfg, diagnosis,
//!   Data_Exchange, Global_Control, Set_Slave_Add, watchdog and master lock (reference §3). The
//!   crate `pbcard-dp` (`crates/dp`), with [`dpv1`]; its tests with this card's configuration
//!   are here (`src/dp_tests/`).
//! * [`card`] — what this particular card is: ident number, modules, user parameters, limits.
//!   The GSD file in `gsd/` is tested against these constants.
//! * [`dpv1`] — DP-V1 acyclic services: the PDU codec for MSAC_C1/C2 (Read, Write,
//!   Data_Transport, Alarm_Ack, Initiate, Abort, Idle, RM), error codes, the 240-byte limit
//!   (reference §4). The crate `pbcard-dp` (`crates/dp`), with [`dp`].
//! * [`profile`] — drive profiles on top of DP-V1 records: PROFIdrive base-mode parameter access
//!   (record 47) and WEG's simple parameter access (record 48) (reference §5.1).
//! * [`fast`] — the ASIC-style split: the line's fast path answers from staged frames, the
//!   core ([`node::Node`]) works behind it in a lower task (issue 11). The crate `pbcard-link`
//!   (`crates/link`), with [`node`], [`phy`], [`store`] and [`led`]; its tests with this card's
//!   configuration are here (`src/link_tests/`).
//! * [`node`] — framer + station + slave as one object that every platform drives.
//! * [`dpm`] — the dual-port memory image shared with the drive's control board (layout,
//!   sequenced tear-free blocks, P0740 / P0963 status) and the card-side [`dpm::Link`].
//! * [`app`] — the card as it ships ([`app::Card`]): node-side DPM link, profile runtime,
//!   fail-safe and the card's DPM image in one step. The simulated drive and the bench that
//!   wraps the card with it are the crate `pbcard-sim` (`crates/sim`), above this one.
//! * [`led`] — the PS / BS / FS LED patterns (OPTE3/E5 §4.3) from the card's state.
//! * [`time`] — instants, durations and bit times (the crate `pbcard-fdl`, with [`fdl`]).
//! * [`phy`] — USART divisors per rate and the autobaud search / Baud_Control supervision (reference §1.2, §1.6).
//! * [`store`] — the station address and No_Add_Chg as a power-loss-safe journal in two flash sectors.
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod app;
pub mod card;
pub use pbcard_dp::dp;
#[cfg(test)]
mod dp_tests;
pub use pbcard_dpm::dpm;
#[cfg(test)]
mod dpm_tests;
pub use pbcard_dp::dpv1;
/// The ASIC-style split (issue 11): the crate `pbcard-link`'s [`pbcard_link::fast`], and
/// with the feature `test-support` the differential check of the split against the core alone
/// with this card (`fast::check`, here because it runs the card's configuration and records).
pub mod fast {
    pub use pbcard_link::fast::*;
    #[cfg(any(test, feature = "test-support"))]
    pub mod check;
}
pub use pbcard_fdl::fdl;
pub use pbcard_link::led;
#[cfg(test)]
mod link_tests;
pub use pbcard_link::node;
pub use pbcard_link::phy;
pub use pbcard_profile::profile;
#[cfg(test)]
mod profile_tests;
pub use pbcard_link::store;
#[cfg(any(test, feature = "test-support"))]
pub mod testkit;
pub use pbcard_fdl::time;
