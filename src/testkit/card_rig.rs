//! The one card rig of the tests (issue 13 item 5): the shipped [`Node`], the application
//! behind it — any [`CardApp`], the trait the platforms' main loops run ([`crate::fast::tick`]):
//! the shipped card [`Card`], the bench's card with its simulated drive (`pbcard-sim`), a DPM
//! link on a host transport (`dpm-host`'s tests), a C drive that owns the card's bus
//! (`host-tests`' `c_host`), another product (`host-tests`' `porting`) —, the
//! [`ScriptedMaster`] and the card's clock. Requests go in byte by byte at the current time
//! ([`feed`]); it is a [`Rig`] (bring-up, Data_Exchange) whose [`settle`](Rig::settle) is one
//! 1 ms card step. What differs between the rigs of the crate tests, the workspace's test
//! crates and the fuzz targets is only the application each one names.

use super::{feed, Frame, Rig, ScriptedMaster};
use crate::app::Card;
use crate::dp::{DpState, Events};
use crate::fast::CardApp;
use crate::node::Node;
use crate::time::{Duration, Instant};

/// The shipped composition under test: a [`Node`] (this card's, [`crate::card::node`]), the
/// application `app` over it, a [`ScriptedMaster`], and a clock that [`step`](Self::step)
/// advances.
#[derive(Debug)]
pub struct CardRig<C> {
    /// The card's protocol stack.
    pub node: Node,
    /// The application behind the node ([`CardApp`]).
    pub app: C,
    /// The master's script.
    pub master: ScriptedMaster,
    /// The card's clock.
    pub now: Instant,
    /// Added to `now` before every request, the node's timers polled then
    /// ([`Node::poll`]); zero (the default): requests arrive at `now`.
    pub per_request: Duration,
}

impl<C: CardApp> CardRig<C> {
    /// `app` over this card's node at address `slave` ([`crate::card::SLAVE`]'s configuration),
    /// a master at `master`, time 0.
    pub fn new(app: C, master: u8, slave: u8) -> Self {
        Self::with_node(crate::card::node(crate::dp::DpSlave::new(&crate::card::SLAVE, slave)), app, master)
    }

    /// Another product's `node` (its own `SlaveConfig`, I&M, record handlers: docs/PORTING.md)
    /// with its application `app`, a master at `master` addressing the node's station address,
    /// time 0.
    pub fn with_node(node: Node, app: C, master: u8) -> Self {
        let slave = node.slave().address();
        CardRig {
            node,
            app,
            master: ScriptedMaster::new(master, slave),
            now: Instant::from_millis(0),
            per_request: Duration::ZERO,
        }
    }

    /// Advance the clock by `ms` and run one application step ([`CardApp::step`]).
    pub fn step(&mut self, ms: u64) -> Events {
        self.now = self.now + Duration::from_millis(ms);
        self.app.step(self.now, &mut self.node)
    }

    /// The node's DP-V1 work, if it has any, over the application's data records at the
    /// current time ([`Node::process_acyclic`], as [`crate::fast::tick`] does after a step).
    pub fn acyclic(&mut self) {
        if self.node.has_acyclic_work() {
            self.node.process_acyclic(self.now, &mut self.app.records(self.now));
        }
    }
}

impl CardRig<Card> {
    /// The shipped card alone (no drive behind its DPM: the test writes the host blocks).
    pub fn shipped(master: u8, slave: u8) -> Self {
        Self::new(Card::new(), master, slave)
    }
}

/// No application: the node alone behind the rig ([`NodeRig`]); a step polls the node's
/// timers, the DP-V1 work has no data records but the node's own (I&M).
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct NodeOnly;

impl CardApp for NodeOnly {
    type Records<'a> = crate::dpv1::records::NoRecords;
    fn step(&mut self, now: Instant, node: &mut Node) -> Events {
        node.poll(now)
    }
    fn records(&mut self, _now: Instant) -> Self::Records<'_> {
        crate::dpv1::records::NoRecords
    }
}

/// The card rig with the node alone and 500 µs between requests (each one after the node's
/// timers were polled): the rig of the node's own DP-V1 tests (`host-tests/tests/dpv1.rs`),
/// whose records and drive table the test holds.
pub type NodeRig = CardRig<NodeOnly>;

impl CardRig<NodeOnly> {
    /// This card's node at `slave`, a master at `master`, time 0, 500 µs between requests.
    pub fn node_only(master: u8, slave: u8) -> Self {
        let mut rig = Self::new(NodeOnly, master, slave);
        rig.per_request = Duration::from_micros(500);
        rig
    }
}

impl<C: CardApp> Rig for CardRig<C> {
    fn master(&mut self) -> &mut ScriptedMaster {
        &mut self.master
    }
    fn deliver(&mut self, frame: &[u8]) -> Option<Frame> {
        if self.per_request != Duration::ZERO {
            self.now = self.now + self.per_request;
            self.node.poll(self.now);
        }
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
