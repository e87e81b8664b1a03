//! pbcard's drive profiles (issue 13 items 2 and 4): everything between the DP-V1 records and
//! cyclic data of the node (`pbcard_link::node`) and the drive-neutral command / status the
//! DPM carries to the drive's control board — the PROFIdrive profile, the WEG, VACON and INVT
//! variants, PKW, the card's own PNUs, the record handlers a product registers with the node
//! ([`profile`]).
//!
//! It depends on `pbcard-link`, `pbcard-dp` and `pbcard-fdl` only, so Cargo keeps it free of
//! the DPM, the card and the simulated drive (`pbcard`, which re-exports [`profile`] under the
//! same name). Its tests that need the card's configuration are in `pbcard`
//! (`src/profile_tests/`), those through the card and the simulated drive in `pbcard-sim`
//! (`crates/sim/src/card_tests/profile.rs`). `no_std`, no `unsafe`, no allocation.
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod profile;

#[cfg(any(test, feature = "test-support"))]
pub mod testkit;

use pbcard_dp::{dp, dpv1};
use pbcard_fdl::time;
use pbcard_link::node;
