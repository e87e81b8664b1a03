//! The DPM's tests that run through this card's node, modules or scripted master
//! (`pbcard_dpm` cannot name the card, issue 13 item 4; those with the simulated drive are in
//! `pbcard-sim`, `crates/sim/src/card_tests/`).
mod gsd_telegrams;
mod v2_card;
