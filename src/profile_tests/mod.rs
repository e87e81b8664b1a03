//! The profile's tests that run through the shipped card (`pbcard_profile` cannot name the
//! card or the simulated drive, issue 13 item 4).
mod telegram;
