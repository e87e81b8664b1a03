//! The test support of the workspace's test crates and the fuzz targets: everything of
//! `pbcard::testkit` (the scripted class-1 master, the `Rig` trait, `NodeRig`, the one fake
//! drive parameter table `FakeDrive`), and [`CardRig`] — the shipped card with the bench's
//! simulated drive (or the card alone) under the scripted master, the one card rig (issue 13
//! item 5). Built only for `cfg(test)` or with the `test-support` feature.

pub use pbcard::testkit::*;

use crate::dp::DpState;
use crate::node::Node;
use crate::time::Instant;

/// The shipped composition under test: a [`Node`] and the [`Application`](crate::bench::Application)
/// over it (the card alone, [`card_only`](Self::card_only), or the card with the simulated
/// drive behind its DPM), a [`ScriptedMaster`], and a clock that [`step`](Self::step)
/// advances — the card rig of the crate's DPM / SPI tests and the fuzz targets that run the
/// whole card. Requests are fed byte by byte at the current time ([`feed`]); a [`Rig`]
/// (bring-up, Data_Exchange) whose [`settle`](Rig::settle) is one 1 ms application step.
#[derive(Debug)]
pub struct CardRig {
    /// The card's protocol stack.
    pub node: Node,
    /// The card (and the bench's drive, when there is one).
    pub app: crate::bench::Application,
    /// The master's script.
    pub master: ScriptedMaster,
    /// The card's clock.
    pub now: Instant,
}

impl CardRig {
    /// `app` over a node at `slave` (this card's `card::SLAVE`), a master at `master`, time 0.
    pub fn new(app: crate::bench::Application, master: u8, slave: u8) -> Self {
        CardRig {
            node: crate::card::node(crate::dp::DpSlave::new(&crate::card::SLAVE, slave)),
            app,
            master: ScriptedMaster::new(master, slave),
            now: Instant::from_millis(0),
        }
    }

    /// The card alone ([`Application::card_only`](crate::bench::Application::card_only)): the
    /// test writes the drive's blocks itself.
    pub fn card_only(master: u8, slave: u8) -> Self {
        Self::new(crate::bench::Application::card_only(), master, slave)
    }

    /// Advance the clock by `ms` and run one application step (DPM, profile, drive).
    pub fn step(&mut self, ms: u64) -> crate::dp::Events {
        self.now = self.now + crate::time::Duration::from_millis(ms);
        self.app.step(self.now, &mut self.node)
    }
}

impl Rig for CardRig {
    fn master(&mut self) -> &mut ScriptedMaster {
        &mut self.master
    }
    fn deliver(&mut self, frame: &[u8]) -> Option<Frame> {
        feed(&mut self.node, self.now, frame)
    }
    fn settle(&mut self) {
        self.step(1);
    }
    fn dp_state(&self) -> DpState {
        self.node.slave().state()
    }
    fn input_len(&self) -> usize {
        self.node.slave().input_len()
    }
}
