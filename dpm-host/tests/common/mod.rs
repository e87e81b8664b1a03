//! The card side for the host tests: a pbcard `Node` on a scripted bus with the card-side
//! `Link` on an image the `Host` reaches through its transport — chosen per test with [`Via`]:
//! the memory transport ([`SharedDpm`]) or the board's SPI frames ([`SpiHost`] over the
//! in-process card with the board's reply pipeline, [`Loopback`]). [`over_both!`] runs one
//! test body over each.
#![allow(dead_code)]

use std::cell::{RefCell, RefMut};
use std::rc::Rc;

use dpm_host::spi::{BusFault, CyclicRequest, Loopback, SpiBus, SpiHost};
use dpm_host::{Duration, Instant, SharedDpm, Transport, TransportError};
use pbcard::card;
use pbcard::dp::Events;
use pbcard::dpm::spi::cyclic::MAX_REPLY_DATA;
use pbcard::dpm::{Dpm, Link};
use pbcard::dpv1::records::NoRecords;
use pbcard::fast::CardApp;
use pbcard::node::Node;
use pbcard::testkit::{CardRig, Rig, SetPrm};

pub const MASTER: u8 = 2;
pub const SLAVE: u8 = 5;

/// How the `Host` reaches the card's image.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Via {
    /// The memory transport: the host reads and writes the image directly (`SharedDpm`).
    Memory,
    /// The board's SPI frames: `SpiHost` (READ / WRITE frames, each confirmed by its reply
    /// fetched in the next transaction) over `Loopback` (the card's `SpiSlave` and the board's
    /// reply pipeline in front of the image).
    Spi,
}

/// Runs a test body over each transport: `over_both! { fn name(via) { .. } }` is the module
/// `name` with the tests `memory` and `spi` (the test files say `#[macro_use] mod common;`).
macro_rules! over_both {
    ($(#[$m:meta])* fn $name:ident($via:ident) $body:block) => {
        $(#[$m])*
        mod $name {
            #[allow(unused_imports)]
            use super::*;
            fn run($via: crate::common::Via) $body
            #[test]
            fn memory() {
                run(crate::common::Via::Memory)
            }
            #[test]
            fn spi() {
                run(crate::common::Via::Spi)
            }
        }
    };
}

/// The loopback card shared by the card side (its image, between host calls) and the
/// `SpiHost` (its bus).
#[derive(Debug, Clone)]
pub struct SharedBus(pub Rc<RefCell<Loopback>>);

impl SpiBus for SharedBus {
    fn transfer(&mut self, mosi: &[u8], miso: &mut [u8]) -> Result<(), BusFault> {
        self.0.borrow_mut().transfer(mosi, miso)
    }
}

/// The card's image behind the chosen transport; the card side borrows it between host calls.
#[derive(Debug, Clone)]
pub enum Image {
    Memory(SharedDpm),
    Spi(SharedBus),
}

impl Image {
    pub fn new(via: Via, dpm: Dpm) -> Self {
        match via {
            Via::Memory => Image::Memory(SharedDpm::from(dpm)),
            Via::Spi => Image::Spi(SharedBus(Rc::new(RefCell::new(Loopback::new(dpm))))),
        }
    }

    /// The card's side of the image.
    pub fn borrow_mut(&self) -> RefMut<'_, Dpm> {
        match self {
            Image::Memory(m) => m.borrow_mut(),
            Image::Spi(b) => RefMut::map(b.0.borrow_mut(), |l| l.dpm_mut()),
        }
    }

    /// A new host-side transport onto this image (over SPI: a new `SpiHost`, TAGs from 0,
    /// as a restarted host).
    pub fn transport(&self) -> Wire {
        match self {
            Image::Memory(m) => Wire::Memory(m.clone()),
            Image::Spi(b) => Wire::Spi(Box::new(SpiHost::new(b.clone()))),
        }
    }

    /// The loopback card (SPI only).
    pub fn loopback(&self) -> Option<RefMut<'_, Loopback>> {
        match self {
            Image::Memory(_) => None,
            Image::Spi(b) => Some(b.0.borrow_mut()),
        }
    }

    /// Over SPI: proves the host's accesses crossed as frames — the card's `SpiSlave`
    /// accepted some and refused none (a test that went around the SPI frames fails here).
    pub fn assert_frames_crossed(&self) {
        if let Some(l) = self.loopback() {
            let s = l.slave().stats();
            assert!(s.frames_ok > 0, "no SPI frame reached the card: {s:?}");
            assert_eq!(s.refused(), 0, "SPI frames refused: {s:?}");
        }
    }
}

/// The host's transport: the memory one or the SPI frames.
#[derive(Debug)]
pub enum Wire {
    Memory(SharedDpm),
    Spi(Box<SpiHost<SharedBus>>),
}

impl Transport for Wire {
    fn read(&mut self, offset: u16, buf: &mut [u8]) -> Result<(), TransportError> {
        match self {
            Wire::Memory(m) => m.read(offset, buf),
            Wire::Spi(s) => Transport::read(&mut **s, offset, buf),
        }
    }
    fn write(&mut self, offset: u16, data: &[u8]) -> Result<(), TransportError> {
        match self {
            Wire::Memory(m) => m.write(offset, data),
            Wire::Spi(s) => Transport::write(&mut **s, offset, data),
        }
    }
    fn cyclic(
        &mut self,
        req: &CyclicRequest<'_>,
        out: &mut [u8; MAX_REPLY_DATA],
    ) -> Option<Result<pbcard::dpm::host::CyclicReceipt, TransportError>> {
        match self {
            Wire::Memory(m) => m.cyclic(req, out),
            Wire::Spi(s) => Transport::cyclic(&mut **s, req, out),
        }
    }
}

/// The card side of these tests: the card's DPM link alone, on an image behind the chosen
/// transport — a [`CardApp`] whose step is the node's timers, [`Link::publish`] and
/// [`Link::collect`] (no profile layer, no data records: the host's blocks are the test's).
pub struct LinkApp {
    pub dpm: Image,
    pub link: Link,
}

impl CardApp for LinkApp {
    type Records<'a> = NoRecords;

    fn step(&mut self, now: Instant, node: &mut Node) -> Events {
        let ev = node.poll(now);
        let mut dpm = self.dpm.borrow_mut();
        self.link.publish(node, ev, &mut dpm);
        self.link.collect(now, node, &dpm);
        ev
    }

    fn records(&mut self, _now: Instant) -> NoRecords {
        NoRecords
    }
}

/// The one card rig ([`CardRig`]: this card's node, the scripted master, the clock) with the
/// DPM link as its application; `card.app.link`, `card.app.dpm` are the card side's parts.
pub struct Card(pub CardRig<LinkApp>);

impl core::ops::Deref for Card {
    type Target = CardRig<LinkApp>;
    fn deref(&self) -> &CardRig<LinkApp> {
        &self.0
    }
}

impl core::ops::DerefMut for Card {
    fn deref_mut(&mut self) -> &mut CardRig<LinkApp> {
        &mut self.0
    }
}

impl Card {
    /// The card over the memory transport.
    pub fn new() -> Self {
        Self::via(Via::Memory)
    }

    /// The card with its image behind `via`.
    pub fn via(via: Via) -> Self {
        let app = LinkApp { dpm: Image::new(via, Dpm::new()), link: Link::new(pbcard::card::MODULES) };
        Card(CardRig::new(app, MASTER, SLAVE))
    }

    /// A host transport onto the card's image.
    pub fn transport(&self) -> Wire {
        self.app.dpm.transport()
    }

    /// One card cycle after `ms`: poll the node, publish to the image, collect from it.
    pub fn cycle(&mut self, ms: u64) -> Events {
        self.0.step(ms)
    }

    /// Only the collecting half (the card keeps reading but stops publishing CARD).
    pub fn collect_only(&mut self, ms: u64) {
        let r = &mut self.0;
        r.now = r.now + Duration::from_millis(ms);
        let dpm = r.app.dpm.borrow_mut();
        r.app.link.collect(r.now, &mut r.node, &dpm);
    }

    /// Set_Prm (watchdog 1 × 100 × 10 ms, as the pbcard tests) and Chk_Cfg for ST1: data
    /// exchange.
    pub fn bring_up(&mut self) {
        Rig::bring_up(&mut self.0, &SetPrm::CARD, card::MODULES[0].cfg);
    }

    pub fn data_exchange(&mut self, out: &[u8]) -> Vec<u8> {
        Rig::data_exchange(&mut self.0, out).to_vec()
    }
}

/// Every test on a card over SPI ends with [`Image::assert_frames_crossed`] (unless it failed
/// already).
impl Drop for Card {
    fn drop(&mut self) {
        if !std::thread::panicking() {
            self.app.dpm.assert_frames_crossed();
        }
    }
}
