//! pbcard's bottom layer, a crate of its own so that Cargo keeps the direction of the stack
//! (issue 13 item 4; README "Layers"): nothing here can name DP, DP-V1, the profile or the
//! card.
//!
//! * [`time`] — time as the protocol core sees it: the caller's [`time::Instant`], durations,
//!   [`time::Baudrate`] and [`time::BitTimes`] (reference §1.3).
//! * [`fdl`] — PROFIBUS layer 2 for a passive station: telegram codec, framer, station
//!   (reference §1.4, §2).
//!
//! `pbcard` re-exports both (`pbcard::time`, `pbcard::fdl`), so every path stays as it was.

#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod fdl;
pub mod time;
