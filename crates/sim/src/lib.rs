//! pbcard's simulation (issue 13 items 1 and 4): the simulated drive behind the DPM's host
//! interface ([`drive`]) and the bench that wraps the shipped card with it
//! ([`bench::Application`]: the QEMU firmware, the F411 `sim-drive` board, the soft slave and
//! the host tests run it), with the rig of the tests that bring the whole card up under a
//! scripted master (`testkit`, feature `test-support`).
//!
//! It depends on the card (`pbcard`) and nothing depends on it but the tools, the tests and the
//! board crate's QEMU / `sim-drive` builds, so Cargo keeps the simulation out of the card. The
//! tests of the card that need the simulated drive — the card's conformance and Clear / Sync
//! suites, the profile defects replayed through the card, the DPM over the SPI loopback with
//! the card rig and the drive — are here (`card_tests`, `bench::tests`).
//! `no_std`, no `unsafe`, no allocation.
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod bench;
#[cfg(test)]
mod card_tests;
pub mod drive;
#[cfg(any(test, feature = "test-support"))]
pub mod testkit;

use pbcard::{app, card, dp, dpm, dpv1, fast, node, profile, time};
#[cfg(test)]
use pbcard::{fdl, phy, store};
