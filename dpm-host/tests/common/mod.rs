//! The card side for the host tests: a pbcard `Node` on a scripted bus with the card-side
//! `Link` on a `SharedDpm` the `Host` reaches through its transport.
#![allow(dead_code)]

use dpm_host::{Duration, Instant, SharedDpm};
use pbcard::card;
use pbcard::dp::{DpSlave, DpState, Events};
use pbcard::dpm::Link;
use pbcard::fdl::telegram::{self, FunctionCode, Header};
use pbcard::node::Node;

pub const MASTER: u8 = 2;
pub const SLAVE: u8 = 5;

pub struct Card {
    pub node: Node,
    pub dpm: SharedDpm,
    pub link: Link,
    pub now: Instant,
    fcb: bool,
}

impl Card {
    pub fn new() -> Self {
        Card {
            node: Node::new(DpSlave::new(SLAVE)),
            dpm: SharedDpm::new(),
            link: Link::new(),
            now: Instant::from_millis(0),
            fcb: false,
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

    pub fn srd(&mut self, dsap: Option<u8>, pdu: &[u8]) -> Vec<u8> {
        self.fcb = !self.fcb;
        let hdr = Header {
            da: SLAVE,
            sa: MASTER,
            fc: FunctionCode::request(0xD, self.fcb, true),
            dsap,
            ssap: dsap.map(|_| 62),
        };
        let mut buf = [0u8; telegram::MAX_FRAME_LEN];
        let n = telegram::emit(&mut buf, &hdr, pdu).unwrap();
        let mut resp = None;
        for &b in &buf[..n] {
            if let Some(r) = self.node.on_byte(self.now, b) {
                resp = Some(r.to_vec());
            }
        }
        resp.expect("no response")
    }

    /// Set_Prm (watchdog 100 × 11 × 10 ms… as the pbcard tests) and Chk_Cfg for ST1: data
    /// exchange.
    pub fn bring_up(&mut self) {
        let mut prm = vec![0x88, 1, 100, 11, (card::IDENT_NUMBER >> 8) as u8, card::IDENT_NUMBER as u8, 0];
        prm.extend_from_slice(&card::USER_PRM_DEFAULTS);
        assert_eq!(self.srd(Some(61), &prm), [telegram::SC]);
        self.cycle(1);
        assert_eq!(self.srd(Some(62), card::MODULES[0].cfg), [telegram::SC]);
        self.cycle(1);
        assert_eq!(self.node.slave().state(), DpState::DataExch);
    }

    pub fn data_exchange(&mut self, out: &[u8]) -> Vec<u8> {
        let r = self.srd(None, out);
        r[telegram::pdu_range(r.len(), self.node.slave().input_len())].to_vec()
    }
}
