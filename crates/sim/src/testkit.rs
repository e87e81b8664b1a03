//! The test support of the workspace's test crates and the fuzz targets: everything of
//! `pbcard::testkit` (the scripted class-1 master, the `Rig` trait, the one card rig
//! `CardRig` — `NodeRig` its node-alone form — and the one fake drive parameter table `FakeDrive`). The bench's card — the
//! shipped card with the simulated drive behind its DPM, [`Application`](crate::bench::Application)
//! — is a `CardApp`, so `CardRig::new(Application::new(..), master, slave)` (or
//! `Application::card_only()`) is the card rig of the crate's DPM / SPI tests, the monitor's
//! replay and the host tests that run the whole card (issue 13 item 5). Built only for
//! `cfg(test)` or with the `test-support` feature.

pub use pbcard::testkit::*;
