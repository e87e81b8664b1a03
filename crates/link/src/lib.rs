//! pbcard's line side (issue 13 items 1 and 4): everything between the bytes on the RS485
//! line and the DP / DP-V1 services, below the product.
//!
//! * [`phy`] — the byte stream cut into telegrams, the bit timing (T_SDR, T_SYN), autobaud, the
//!   rate link between the line and the rate keeper, the small board traits of the line.
//! * [`node`] — the station: FDL, the DP-V0 slave and DP-V1 (MSAC_C1, MSAC_C2, the resource
//!   manager) composed, with the record-handler seam a product implements.
//! * [`fast`] — the ASIC-style split (issue 11): the fast path answers at the line interrupt
//!   from pre-staged frames, the core link runs the node afterwards.
//! * [`store`] — the flash journal (station address, I&M1–4).
//! * [`led`] — the PS / BS / FS LED logic (OPTE3/E5 §4.3).
//!
//! It depends on `pbcard-dp` and `pbcard-fdl` only, so Cargo keeps it free of the profile, the
//! DPM and the card (`pbcard`), which re-exports its modules under the same names; its
//! optimisation level is its own, opt-level 2 (the response path; the card above it stays at
//! 2 too, root `Cargo.toml`, README "Footprint"). `no_std`, no `unsafe`, no allocation.
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod fast;
pub mod led;
pub mod node;
pub mod phy;
pub mod store;
/// The stand-in station of the line side's tests, for the tests of the crates above that need
/// a station but not the card (feature `test-support`).
#[cfg(any(test, feature = "test-support"))]
#[doc(hidden)]
pub mod test_card;

use pbcard_dp::{dp, dpv1};
use pbcard_fdl::{fdl, time};
