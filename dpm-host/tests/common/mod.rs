//! The card side for the host tests: a pbcard `Node` on a scripted bus with the card-side
//! `Link` on a `SharedDpm` the `Host` reaches through its transport.
#![allow(dead_code)]

use dpm_host::{Duration, Instant, SharedDpm};
use pbcard::card;
use pbcard::dp::{DpSlave, DpState, Events};
use pbcard::dpm::Link;
use pbcard::node::Node;
use pbcard::testkit::{self, Frame, Rig, ScriptedMaster, SetPrm};

pub const MASTER: u8 = 2;
pub const SLAVE: u8 = 5;

pub struct Card {
    pub node: Node,
    pub dpm: SharedDpm,
    pub link: Link,
    pub now: Instant,
    master: ScriptedMaster,
}

impl Card {
    pub fn new() -> Self {
        Card {
            node: Node::new(DpSlave::new(SLAVE)),
            dpm: SharedDpm::new(),
            link: Link::new(),
            now: Instant::from_millis(0),
            master: ScriptedMaster::new(MASTER, SLAVE),
        }
    }

    /// One card cycle after `ms`: poll the node, publish to the image, collect from it.
    pub fn cycle(&mut self, ms: u64) -> Events {
        self.now = self.now + Duration::from_millis(ms);
        let ev = self.node.poll(self.now);
        let mut dpm = self.dpm.borrow_mut();
        self.link.publish(&mut self.node, ev, &mut dpm);
        self.link.collect(self.now, &mut self.node, &dpm);
        ev
    }

    /// Only the collecting half (the card keeps reading but stops publishing CARD).
    pub fn collect_only(&mut self, ms: u64) {
        self.now = self.now + Duration::from_millis(ms);
        let dpm = self.dpm.borrow_mut();
        self.link.collect(self.now, &mut self.node, &dpm);
    }

    /// Set_Prm (watchdog 1 × 100 × 10 ms, as the pbcard tests) and Chk_Cfg for ST1: data
    /// exchange.
    pub fn bring_up(&mut self) {
        Rig::bring_up(self, &SetPrm::CARD, card::MODULES[0].cfg);
    }

    pub fn data_exchange(&mut self, out: &[u8]) -> Vec<u8> {
        Rig::data_exchange(self, out).to_vec()
    }
}

impl Rig for Card {
    fn master(&mut self) -> &mut ScriptedMaster {
        &mut self.master
    }
    fn deliver(&mut self, frame: &[u8]) -> Option<Frame> {
        testkit::feed(&mut self.node, self.now, frame)
    }
    fn settle(&mut self) {
        self.cycle(1);
    }
    fn dp_state(&self) -> DpState {
        self.node.slave().state()
    }
    fn input_len(&self) -> usize {
        self.node.slave().input_len()
    }
}
