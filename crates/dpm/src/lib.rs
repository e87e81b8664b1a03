//! pbcard's dual-port memory (issue 13 items 2 and 4): the image the card shares with the
//! drive's control board — its layout, the sequenced tear-free blocks, the parameter mailbox,
//! the card-side [`dpm::Link`] from the node's cyclic data and events to the image, the SPI
//! frames that carry it, and the host's reference implementation (`dpm::host`, what a drive
//! maker ports; the `dpm-host` crate re-exports it) ([`dpm`]).
//!
//! It depends on `pbcard-profile`, `pbcard-link`, `pbcard-dp` and `pbcard-fdl` only, so Cargo
//! keeps it free of the card and the simulated drive (`pbcard`, which re-exports [`dpm`] under
//! the same name). Its tests that need the card's configuration or the scripted master are in
//! `pbcard` (`src/dpm_tests/`), those with the simulated drive in `pbcard-sim`
//! (`crates/sim/src/card_tests/`). `no_std`, no `unsafe`, no allocation.
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod dpm;

use pbcard_dp::{dp, dpv1};
use pbcard_fdl::{fdl, time};
use pbcard_link::node;
use pbcard_profile::profile;
