//! pbcard's DP layers, a crate of their own so that Cargo keeps the direction of the stack
//! (issue 13 item 4; README "Layers"): they stand on `pbcard-fdl` alone and can name nothing
//! above — neither the node, the fast path, the profile, the DPM nor the card.
//!
//! * [`dp`] — the DP-V0 slave: state machine, Set_Prm, Chk_Cfg/Get_Cfg, diagnosis,
//!   Data_Exchange, Global_Control, Set_Slave_Add, watchdog and master lock (reference §3).
//! * [`dpv1`] — DP-V1 acyclic services: the PDU codec for MSAC_C1/C2, the connections, the
//!   record-handler seam and I&M (reference §4).
//!
//! `pbcard` re-exports both (`pbcard::dp`, `pbcard::dpv1`), so every path stays as it was.
//! The product's configuration ([`dp::SlaveConfig`], [`dpv1::im::ImDevice`]) is data handed
//! in by the composition; the tests of the DP layers with this card's configuration are in
//! `pbcard` (`src/dp_tests/`).

#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod dp;
pub mod dpv1;
/// The stand-in product of this crate's tests, for the tests of the crates above that need its
/// values but not the card (feature `test-support`).
#[cfg(any(test, feature = "test-support"))]
#[doc(hidden)]
pub mod test_card;

// The layer below, under the paths the modules have always used (`crate::fdl::…`,
// `crate::time::…`); not re-exported (`pbcard` exports `pbcard_fdl` itself).
use pbcard_fdl::{fdl, time};
