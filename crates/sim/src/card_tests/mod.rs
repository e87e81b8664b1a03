//! The card's tests that need the simulated drive or the bench (moved from `pbcard`, which
//! cannot name the simulation, issue 13 item 4): the benchmark modules through the whole card,
//! the profile defects replayed through the card and the drive (issue 15), and the DPM over the
//! SPI loopback with the card (`CardRig`) and the drive.
#[cfg(feature = "bench")]
mod bench_modules;
mod dpm_spi_card;
mod dpm_spi_cycle;
mod profile;
