//! The SPI frame task's own image (issue 16 item 3, docs/SPI.md "Pipelining": the master
//! leaves the card [`super::T_READY_US`] µs between two transactions). On the board the frame
//! task must answer within that gap whatever the application step is doing, so it does not
//! share the application's image and its lock: it owns a [`WireImage`] — a copy of the DPM
//! image and the [`SpiSlave`] protocol state — and runs above the step. The two images meet
//! in [`WireImage::hand_over`], one short copy after each application step (the blocks the
//! card writes go to the wire image, the blocks the host writes come back), a few
//! microseconds under the frame task's lock instead of the whole step.
//!
//! Consistency is kept: every block is copied whole in one go, so a sequenced block is as
//! consistent in the copy as it was in the source, and the host sees the card's blocks of
//! one step together (the CYCLIC reply carries them from one image). The price is at most
//! one step (1 ms) of extra latency in each direction, which the figures of the README's
//! setpoint latency already allow for (the card's step was not in them).

use super::{SpiSlave, SpiStats, MAX_REPLY};
use crate::dpm::layout::{Writer, SPANS};
use crate::dpm::Dpm;

/// The frame task's image and protocol state (see the module docs).
#[derive(Debug, Clone)]
pub struct WireImage {
    dpm: Dpm,
    slave: SpiSlave,
    hand_overs: u32,
}

impl Default for WireImage {
    fn default() -> Self {
        Self::new()
    }
}

impl WireImage {
    /// A fresh image ([`Dpm::new`]) until the first hand-over, no frame seen.
    pub fn new() -> Self {
        WireImage { dpm: Dpm::new(), slave: SpiSlave::new(), hand_overs: 0 }
    }

    /// One transaction (`SpiSlave::handle` on this image): the reply's length.
    pub fn handle(&mut self, rx: &[u8], reply: &mut [u8; MAX_REPLY]) -> usize {
        self.slave.handle(rx, &mut self.dpm, reply)
    }

    /// Rebuild an armed CYCLIC reply from this image (`SpiSlave::refresh`).
    pub fn refresh(&mut self, reply: &mut [u8; MAX_REPLY]) -> Option<usize> {
        self.slave.refresh(&self.dpm, reply)
    }

    /// The IRQ line: events pending in this image.
    pub fn irq(&self) -> bool {
        self.slave.irq(&self.dpm)
    }

    /// The protocol counters.
    pub fn stats(&self) -> SpiStats {
        self.slave.stats()
    }

    /// The image the frames see.
    pub fn dpm(&self) -> &Dpm {
        &self.dpm
    }

    /// Hand-overs so far.
    pub fn hand_overs(&self) -> u32 {
        self.hand_overs
    }

    /// After an application step on `card` (the application's image): the blocks the card
    /// writes (HEADER, STATUS, OUTPUTS, IDENT, CARD, MBX_REQ, DRIVE_CMD) to this image, the
    /// blocks the host writes (INPUTS, DRIVE, CONFIG, MBX_RSP, DRIVE_STATE, DEVICE) back to
    /// `card`, each block whole.
    pub fn hand_over(&mut self, card: &mut Dpm) {
        let (wire, app) = (self.dpm.as_bytes_mut(), card.as_bytes_mut());
        for b in &SPANS {
            let r = b.start..b.start + b.len;
            match b.writer {
                Writer::Card => wire[r.clone()].copy_from_slice(&app[r]),
                Writer::Host => app[r.clone()].copy_from_slice(&wire[r]),
            }
        }
        self.hand_overs = self.hand_overs.wrapping_add(1);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dpm::host::{Host, Options};
    use crate::dpm::spi::{SpiBus, SpiHost, MAX_REPLY};
    use crate::dpm::{layout, Link};
    use crate::time::Instant;
    use pbcard_link::test_card;

    /// The wire image with the board's pipeline depth 1, simply (every reply in time).
    struct Wire<'a> {
        w: &'a mut WireImage,
        reply: [u8; MAX_REPLY],
        len: usize,
    }

    impl SpiBus for Wire<'_> {
        fn transfer(&mut self, mosi: &[u8], miso: &mut [u8]) -> Result<(), crate::dpm::spi::BusFault> {
            let k = self.len.min(miso.len());
            miso[..k].copy_from_slice(&self.reply[..k]);
            miso[k..].fill(0);
            self.len = self.w.handle(mosi, &mut self.reply);
            Ok(())
        }
    }

    #[test]
    fn the_host_and_the_card_meet_through_the_hand_over() {
        let mut card = Dpm::new();
        let mut link = Link::new(test_card::SLAVE.modules);
        let mut node = test_card::node(crate::dp::DpSlave::new(&test_card::SLAVE, 5));
        let ev = node.poll(Instant::from_millis(0));
        link.publish(&mut node, ev, &mut card);
        let mut wire = WireImage::new();
        wire.hand_over(&mut card);
        assert_eq!(wire.dpm().as_bytes()[..layout::header::LEN], card.as_bytes()[..layout::header::LEN]);
        // The host writes INPUTS-side blocks over the frames: they reach the card's image only
        // at the hand-over; the card's blocks reach the wire the same way.
        {
            let mut host =
                Host::open(SpiHost::new(Wire { w: &mut wire, reply: [0; MAX_REPLY], len: 0 }), Options::DEFAULT)
                    .expect("opens");
            host.write_config(&crate::dpm::HostConfig::DEFAULT).unwrap();
        }
        let cfg = layout::config::START;
        assert_eq!(card.as_bytes()[cfg..cfg + 2], [0, 0], "not yet");
        assert_ne!(wire.dpm().as_bytes()[cfg..cfg + 2], [0, 0]);
        wire.hand_over(&mut card);
        assert_eq!(
            card.as_bytes()[cfg..cfg + layout::config::LEN],
            wire.dpm().as_bytes()[cfg..cfg + layout::config::LEN]
        );
        assert_eq!(wire.hand_overs(), 2);
        assert!(wire.stats().frames_ok > 0 && wire.stats().refused() == 0);
    }
}
