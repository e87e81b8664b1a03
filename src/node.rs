//! One PROFIBUS slave node as every platform runs it: [`Framer`] → [`Station`] → [`DpSlave`].
//!
//! The board firmware, the QEMU build, the soft slave and the host tests all drive the
//! protocol core through this one type, so the same code decides on every platform. The
//! platform only moves bytes and time: [`Node::on_byte`] for each received character (the
//! response it returns goes on the wire after [`Node::min_tsdr`]), [`Node::on_line_error`]
//! for a character with a parity/framing/noise/overrun error, [`Node::on_idle`] when the line
//! was idle, and [`Node::poll`] for the timers.

use crate::dp::{DpSlave, Events};
use crate::fdl::framer::{Framer, Push};
use crate::fdl::station::Station;
use crate::time::{BitTimes, Instant};

/// A slave node: framer, FDL station and DP slave.
#[derive(Debug, Clone)]
pub struct Node {
    framer: Framer,
    station: Station,
    slave: DpSlave,
}

impl Node {
    /// A node at station `address` (see [`DpSlave::with_address_lock`] for a stored one).
    pub fn new(slave: DpSlave) -> Self {
        Node { framer: Framer::new(), station: Station::new(), slave }
    }

    /// One received character; returns the response to send (after min_TSDR) when it
    /// completed a request that must be answered.
    pub fn on_byte(&mut self, now: Instant, byte: u8) -> Option<&[u8]> {
        match self.framer.push(byte) {
            Push::Frame(_) => self.station.on_frame(now, self.framer.frame(), &mut self.slave),
            Push::Pending | Push::Dropped(_) => None,
        }
    }

    /// A whole received telegram at once (a DMA receiver that delimited it itself).
    pub fn on_frame(&mut self, now: Instant, frame: &[u8]) -> Option<&[u8]> {
        self.station.on_frame(now, frame, &mut self.slave)
    }

    /// A character arrived with a parity, framing, noise or overrun error.
    pub fn on_line_error(&mut self) {
        self.framer.line_error();
    }

    /// The line was idle for `bits` bit times (a partial telegram is dropped; ≥ T_SYN
    /// resynchronises).
    pub fn on_idle(&mut self, bits: BitTimes) {
        self.framer.idle(bits);
    }

    /// Run the timers and return what happened since the last call. When the address
    /// changed (Set_Slave_Add), the FCB memory is reset here.
    pub fn poll(&mut self, now: Instant) -> Events {
        self.slave.poll(now);
        let ev = self.slave.take_events();
        if ev.contains(Events::ADDRESS_CHANGED) {
            self.station.reset();
        }
        ev
    }

    /// min_TSDR in force: wait at least this long after the request's last stop bit.
    pub fn min_tsdr(&self) -> BitTimes {
        self.slave.min_tsdr()
    }

    /// The DP slave (state, images, diagnosis).
    pub fn slave(&self) -> &DpSlave {
        &self.slave
    }
    /// The DP slave, mutable (inputs, extended diagnosis).
    pub fn slave_mut(&mut self) -> &mut DpSlave {
        &mut self.slave
    }
    /// The FDL station (counters).
    pub fn station(&self) -> &Station {
        &self.station
    }
    /// The framer (counters).
    pub fn framer(&self) -> &Framer {
        &self.framer
    }
}
