//! The DPM's tests that run through this card's node, modules, scripted master or simulated
//! drive (`pbcard_dpm` cannot name the card, issue 13 item 4).
mod gsd_telegrams;
mod v2_card;
