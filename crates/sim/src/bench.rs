//! The bench ([`Application`]): the shipped card ([`Card`]) whose DPM image lives behind the
//! host-side reference implementation (`dpm::host`, issue 7 item 5) over the SPI frame
//! transport (`dpm::spi::SpiHost`) to an in-process card (`dpm::spi::Loopback`, which owns the
//! card's DPM image), and a [`SimDrive`] on that host: the same code and the same frames a drive
//! maker's control board uses on the wire (issue 7: "the QEMU build and the soft slave use an
//! in-process transport with the same frames"). The QEMU firmware, the F411 with the
//! `sim-drive` feature, the soft slave and the host tests run it; it dereferences to its
//! [`Card`], so every card method is an application method.
//!
//! ```text
//! Application: Card::step_publish ─▶ SimDrive::step over dpm::host::Host (reads DRIVE_CMD, runs
//!              the drive model, writes DRIVE_STATE, DRIVE, serves the mailbox) ─▶ Card::step_collect
//! ```

use core::ops::{Deref, DerefMut};

use crate::app::{Card, DriveHost};
use crate::dp::Events;
use crate::dpm::host::{Host, Options, Transport};
use crate::dpm::spi::{Loopback, SpiHost};
use crate::dpm::{Dpm, MailboxParams};
use crate::drive::params::DriveTable;
use crate::drive::{DriveConfig, SimDrive};
use crate::node::Node;
use crate::profile::records::WithTable;
use crate::time::Instant;

/// The simulated drive, and whether it runs: in [card-only](Application::card_only) mode it
/// is kept (for the accessors) but never stepped, so the host blocks are written only by the
/// drive's control board through the SPI transport.
#[derive(Debug, Clone)]
struct DriveSlot {
    sim: SimDrive,
    runs: bool,
}

impl DriveSlot {
    fn step<T: Transport>(&mut self, now: Instant, host: &mut Host<T>) {
        if self.runs {
            self.sim.step(now, host);
        }
    }
}

/// The bench: a [`Card`] whose DPM image sits behind the drive's host interface
/// ([`DriveHost`], the in-process SPI frames), and a simulated drive on that host. Every
/// [`Card`] method is reachable through `Deref`; [`step`](Self::step) adds the drive's part.
#[derive(Debug, Clone)]
pub struct Application {
    card: Card<DriveHost>,
    drive: DriveSlot,
}

/// The bench (card + simulated drive) in a main loop: [`Application::step`] (the drive
/// included) and the card's records.
impl crate::fast::CardApp for Application {
    type Records<'a> = WithTable<'a, MailboxParams<'a>>;
    fn step(&mut self, now: Instant, node: &mut Node) -> Events {
        Application::step(self, now, node)
    }
    fn records(&mut self, now: Instant) -> Self::Records<'_> {
        self.card.records(now)
    }
}

impl Deref for Application {
    type Target = Card<DriveHost>;
    fn deref(&self) -> &Card<DriveHost> {
        &self.card
    }
}

impl DerefMut for Application {
    fn deref_mut(&mut self) -> &mut Card<DriveHost> {
        &mut self.card
    }
}

impl Application {
    /// A fresh image (P0740 "inactive" until the first step), the profile layer without a
    /// telegram, and a simulated drive at standstill that runs in every step over the SPI
    /// frames (the QEMU firmware, the soft slave, the host tests, a bench board without a
    /// drive).
    pub fn new(drive: DriveConfig) -> Self {
        Self::build(SimDrive::new(drive), true)
    }

    /// The card alone behind the bench's host interface: no simulated drive runs, the host
    /// blocks (INPUTS, DRIVE, CONFIG, MBX_RSP, DRIVE_STATE) are written only by the drive's
    /// control board (the tests' SPI master) through [`dpm_mut`](Card::dpm_mut) or
    /// [`host_mut`](Self::host_mut). The board firmware runs [`Card::new`] instead.
    pub fn card_only() -> Self {
        let mut app = Self::build(SimDrive::new(DriveConfig::DEFAULT), false);
        // Issue 16: no parameterisation before the drive has written a valid CONFIG.
        app.card.link_mut().set_startup_gate(true);
        app
    }

    fn build(sim: SimDrive, runs: bool) -> Self {
        // The simulated drive runs on `Host::cycle` (its status and command in CYCLIC
        // exchanges) with its mailbox on block accesses: a parameter job answered within one
        // card step, as the tests of the card's parameter access count them (the fragments of
        // the CYCLIC exchange take several drive cycles a job, `docs/SPI.md`). A card-only
        // host is the drive maker's: everything in the CYCLIC exchange.
        let opts = if runs { Options { cyclic_mailbox: false, ..Options::DEFAULT } } else { Options::DEFAULT };
        let host = match Host::open(SpiHost::new(Loopback::new(Dpm::with_identity(&crate::card::IDENTITY))), opts) {
            Ok(h) => h,
            // A fresh image always carries the current header, and the loopback card answers
            // every well-formed frame.
            Err(_) => unreachable!("a fresh DPM image opens"),
        };
        Application { card: Card::with_image(host), drive: DriveSlot { sim, runs } }
    }

    /// The card.
    pub fn card(&self) -> &Card<DriveHost> {
        &self.card
    }
    /// The card, writable.
    pub fn card_mut(&mut self) -> &mut Card<DriveHost> {
        &mut self.card
    }

    /// Stop (false) or restart the simulated drive's steps: a drive whose control board
    /// stopped (its heartbeat stands still — fault injection for the drive-lost image).
    pub fn set_drive_runs(&mut self, runs: bool) {
        self.drive.runs = runs;
    }

    /// Whether the simulated drive runs in the steps (false in [card-only](Self::card_only)
    /// mode).
    pub fn simulates_drive(&self) -> bool {
        self.drive.runs
    }

    /// Whether the simulated drive answers the parameter mailbox (default yes; off: a drive
    /// whose control board does not answer — fault injection).
    pub fn set_serve_parameters(&mut self, on: bool) {
        self.drive.sim.set_serve_parameters(on);
    }

    /// The simulated drive's parameter table.
    pub fn drive_params(&self) -> &DriveTable {
        self.drive.sim.params()
    }

    /// Run the node's timers, publish the card's state and the master's outputs, run the
    /// drive (which also answers a parameter mailbox request), take the drive's state through
    /// the profile layer into the next input image and the profile's command into DRIVE_CMD,
    /// and serve a PKW job. Returns the node's events (for logs and LEDs). Call it often
    /// (every few ms, and after each received telegram if the platform can): the answer to
    /// Data_Exchange *n* carries the drive's reaction to the outputs of an earlier cycle.
    pub fn step(&mut self, now: Instant, node: &mut Node) -> Events {
        let events = self.card.step_publish(now, node);
        self.step_drive(now);
        self.card.step_collect(now, node);
        events
    }

    /// The middle of [`step`](Self::step), without the node: the simulated drive reads
    /// DRIVE_CMD, runs, writes DRIVE_STATE and serves the parameter mailbox.
    pub fn step_drive(&mut self, now: Instant) {
        self.drive.step(now, self.card.image_mut());
    }

    /// The drive's host interface (the reference implementation the simulated drive runs,
    /// over the SPI frames to the in-process card).
    pub fn host(&self) -> &DriveHost {
        self.card.image()
    }
    /// The drive's host interface, writable: what the drive's control board does besides the
    /// simulated drive's cycle (write CONFIG, …), for tests and tools.
    pub fn host_mut(&mut self) -> &mut DriveHost {
        self.card.image_mut()
    }
    /// The simulated drive (at standstill, never stepped, in card-only mode).
    pub fn drive(&self) -> &SimDrive {
        &self.drive.sim
    }
    /// The simulated drive, mutable (inject a fault, a warning).
    pub fn drive_mut(&mut self) -> &mut SimDrive {
        &mut self.drive.sim
    }
}

#[cfg(test)]
pub(crate) mod tests;
