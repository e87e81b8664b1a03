//! MSAC_C1: the class-1 master's acyclic channel on SAP 51 (reference §4.1–4.3).
//!
//! Open while the DP slave is in Data_Exch after a Set_Prm with DPV1_Enable, and only for
//! the locking master (request SSAP 51, the master's MS1 SAP). Anything else on SAP 51 gets
//! RS (SAP not activated). Leaving data exchange closes the channel and drops a request or
//! response in flight; the relation's record state goes with it ([`C1::take_ended`]).

use super::channel::{serve_records, Answer, Channel};
use super::records::RecordHandler;
use crate::dp::prm::Dpv1Status1;
use crate::dp::{DpSlave, DpState};
use crate::fdl::telegram::DataTelegram;
use crate::time::Instant;

/// The slave's MSAC_C1 SAP.
pub const SAP: u8 = 51;

/// Counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct C1Stats {
    /// Requests refused with RS (channel closed, not the locking master, wrong SSAP).
    pub refused: u32,
    /// Times the channel was closed with a request or response in flight.
    pub dropped: u32,
}

/// The MSAC_C1 service.
#[derive(Debug, Clone, Default)]
pub struct C1 {
    channel: Channel,
    open: bool,
    /// The channel closed since [`C1::take_ended`].
    ended: bool,
    stats: C1Stats,
}

impl C1 {
    /// A closed channel.
    pub const fn new() -> Self {
        C1 { channel: Channel::new(), open: false, ended: false, stats: C1Stats { refused: 0, dropped: 0 } }
    }

    /// Whether the channel is open for `dp`'s locking master.
    pub fn is_open(dp: &DpSlave) -> bool {
        dp.state() == DpState::DataExch
            && dp.parameters().is_some_and(|p| p.dpv1_status_1.contains(Dpv1Status1::DPV1_ENABLE))
    }

    /// A request or poll on SAP 51. `None` = refuse with RS.
    pub fn on_request(&mut self, req: &DataTelegram<'_>, dp: &DpSlave) -> Option<Answer> {
        self.on_request_as(req, dp, true)
    }

    /// [`on_request`](Self::on_request); `deliver` false: the line already answered this
    /// frame with SC ([`Channel::on_request_as`]).
    pub fn on_request_as(&mut self, req: &DataTelegram<'_>, dp: &DpSlave, deliver: bool) -> Option<Answer> {
        self.track(dp);
        if !self.open || dp.master_address() != Some(req.sa) || req.ssap != Some(SAP) {
            self.stats.refused = self.stats.refused.wrapping_add(1);
            return None;
        }
        Some(self.channel.on_request_as(req.sa, SAP, dp.address(), SAP, req.pdu, deliver))
    }

    /// Work on a pending request (the middle-priority task; host: every poll). An Alarm_Ack
    /// goes to the DP slave's alarm state machine ([`crate::dp::alarm`]): the same four bytes
    /// back, or `DC 80 B2|B5 00` for an ack that names no outstanding alarm.
    pub fn process(&mut self, now: Instant, dp: &mut DpSlave, records: &mut impl RecordHandler) {
        self.track(dp);
        if self.channel.pending().is_some() {
            records.set_relation(super::records::RELATION_C1);
            self.channel.respond(|req, out| match super::pdu::parse(req) {
                Ok(super::pdu::Request::AlarmAck(a)) => alarm_ack(dp, &a, out),
                _ => serve_records(now, req, out, records, false),
            });
        }
    }

    /// Whether a request waits for [`process`](Self::process).
    pub fn has_pending(&self) -> bool {
        self.channel.pending().is_some()
    }

    /// The response frame the next poll of the locking master gets, if one is ready.
    pub fn ready_frame(&self) -> Option<&[u8]> {
        self.channel.ready_frame()
    }

    /// The response frame handed out by [`on_request`](Self::on_request).
    pub fn frame(&self, len: u16) -> &[u8] {
        self.channel.frame(len)
    }

    /// Counters.
    pub fn stats(&self) -> C1Stats {
        self.stats
    }

    /// Open / close with the DP state. The node calls it after every DP request and every
    /// timer run, so a request in flight never survives a new parameterization.
    ///
    /// Out of line: called from the core task, the step and the DP-V1 task (footprint, issue 13 item 1).
    #[inline(never)]
    pub fn track(&mut self, dp: &DpSlave) {
        let open = Self::is_open(dp);
        if self.open && !open {
            if self.channel.state() != super::channel::ChannelState::Idle {
                self.stats.dropped = self.stats.dropped.wrapping_add(1);
            }
            self.channel.reset();
            self.ended = true;
        }
        self.open = open;
    }

    /// Whether the relation ended (data exchange left) since the last call: the record
    /// handler then forgets the relation's state (a record-47 response or job).
    pub fn take_ended(&mut self) -> bool {
        core::mem::take(&mut self.ended)
    }
}

/// Alarm_Ack `5C slot type specifier` → the DP slave; the response PDU into `out`.
fn alarm_ack(dp: &mut DpSlave, a: &super::pdu::AlarmAck, out: &mut [u8]) -> usize {
    use super::pdu::{ErrorCode1, Function, ERROR_BIT, ERROR_DECODE_DPV1};
    use crate::dp::alarm::{Ack, AckError};
    let ack = Ack { slot: a.slot, alarm_type: a.alarm_type, specifier: a.specifier };
    let pdu = match dp.alarm_ack(&ack) {
        Ok(()) => [Function::AlarmAck as u8, a.slot, a.alarm_type, a.specifier],
        Err(e) => {
            let ec = match e {
                AckError::Slot(_) => ErrorCode1::INVALID_SLOT,
                _ => ErrorCode1::STATE_CONFLICT,
            };
            [Function::AlarmAck as u8 | ERROR_BIT, ERROR_DECODE_DPV1, ec.0, 0]
        }
    };
    out[..4].copy_from_slice(&pdu);
    4
}
