//! Unit tests of the line side (`crates/link`, the crate `pbcard-link`) that need this card's
//! configuration, records or scripted master (`card`, `testkit`, `profile`, `drive`), all above
//! the line side, so they live in pbcard (issue 13 item 4, as `dp_tests` for `pbcard-dp`).

mod fast;
mod fast_lean;
