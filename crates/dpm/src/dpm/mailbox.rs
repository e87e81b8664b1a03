//! The parameter mailbox: the card asks the drive for a parameter (read, write, read
//! description) and takes the answer later, asynchronously; the host serves the requests.
//!
//! Every request carries a new request identifier (`MBX_REQ.REQ_ID`, 1..=65535, skipping 0).
//! A response is taken only if `MBX_RSP.REQ_ID` names the outstanding request, so an answer
//! that arrives after its request timed out is never taken for the next request. A request
//! that is not answered within the timeout completes with [`TIMEOUT_ERROR`]; one submitted
//! while the drive's heartbeat is lost completes at once with [`DRIVE_LOST_ERROR`]. The card
//! never waits for the drive.

use super::{CardSide, HostSide, MailboxRequest, MailboxResponse, ParamValues, RequestKind};
use crate::profile::param::{ErrorValue, ParamAddress, ParamError, ParameterAccess, ValueBlock, ValueWriter};
use crate::time::{Duration, Instant};

/// `ERROR_INFO` of a request the drive did not answer in time.
pub const TIMEOUT_INFO: u16 = 0xDD01;
/// `ERROR_INFO` of a request refused because the drive's heartbeat is lost.
pub const DRIVE_LOST_INFO: u16 = 0xDD02;

/// The answer to a request the drive did not answer in time: PROFIdrive 0x11 "request cannot
/// be executed" (temporarily not possible) with additional info [`TIMEOUT_INFO`].
pub const TIMEOUT_ERROR: ParamError =
    ParamError { value: ErrorValue::NOT_EXECUTABLE, additional_info: Some(TIMEOUT_INFO) };
/// The answer to a request while the drive's heartbeat is lost: 0x11 with [`DRIVE_LOST_INFO`].
pub const DRIVE_LOST_ERROR: ParamError =
    ParamError { value: ErrorValue::NOT_EXECUTABLE, additional_info: Some(DRIVE_LOST_INFO) };

/// [`Mailbox::submit`] while a request is outstanding or an answer not yet taken.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MailboxBusy;

/// Counters of the [`Mailbox`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct MailboxStats {
    /// Requests written.
    pub requests: u32,
    /// Responses taken.
    pub responses: u32,
    /// Requests that timed out.
    pub timeouts: u32,
    /// Responses ignored: late or for an unknown request.
    pub late_responses: u32,
    /// MBX_RSP reads that saw a write in progress.
    pub torn_reads: u32,
    /// Requests refused because the drive was lost.
    pub refused: u32,
}

/// The card's side of the mailbox: one outstanding request at a time.
#[derive(Debug, Clone)]
pub struct Mailbox {
    timeout: Duration,
    last_id: u16,
    pending: Option<(u16, Instant)>,
    done: Option<(u16, Result<ParamValues, ParamError>)>,
    rsp_seq: u16,
    stats: MailboxStats,
}

impl Default for Mailbox {
    fn default() -> Self {
        Self::new(Self::DEFAULT_TIMEOUT)
    }
}

impl Mailbox {
    /// Half the DP-V1 C1 response timeout the GSD announces (1 s), so the card still answers
    /// the master in time.
    pub const DEFAULT_TIMEOUT: Duration = Duration::from_millis(500);

    /// A mailbox whose requests time out after `timeout`.
    pub const fn new(timeout: Duration) -> Self {
        Mailbox {
            timeout,
            last_id: 0,
            pending: None,
            done: None,
            rsp_seq: 0,
            stats: MailboxStats {
                requests: 0,
                responses: 0,
                timeouts: 0,
                late_responses: 0,
                torn_reads: 0,
                refused: 0,
            },
        }
    }

    #[cfg(test)]
    pub(super) fn last_id_for_test(&mut self, id: u16) {
        self.last_id = id;
    }

    /// Counters.
    pub fn stats(&self) -> MailboxStats {
        self.stats
    }

    /// Whether a request is outstanding or its answer not yet taken.
    pub fn is_busy(&self) -> bool {
        self.pending.is_some() || self.done.is_some()
    }

    /// The outstanding request's identifier.
    pub fn pending_id(&self) -> Option<u16> {
        self.pending.map(|(id, _)| id)
    }

    /// Write `req` (its `id` is replaced by a new identifier) to MBX_REQ; returns the id.
    /// With `drive_lost` the request is not written but completes at once with
    /// [`DRIVE_LOST_ERROR`].
    pub fn submit(
        &mut self,
        now: Instant,
        req: &MailboxRequest,
        drive_lost: bool,
        card: &mut CardSide<'_>,
    ) -> Result<u16, MailboxBusy> {
        if self.is_busy() {
            return Err(MailboxBusy);
        }
        self.last_id = super::next_seq(self.last_id);
        let id = self.last_id;
        if drive_lost {
            self.stats.refused = self.stats.refused.wrapping_add(1);
            self.done = Some((id, Err(DRIVE_LOST_ERROR)));
            return Ok(id);
        }
        card.write_request(&MailboxRequest { id, ..*req });
        self.pending = Some((id, now + self.timeout));
        self.stats.requests = self.stats.requests.wrapping_add(1);
        Ok(id)
    }

    /// Look at MBX_RSP and the clock: take the answer to the outstanding request, or time it
    /// out. Call it every card cycle.
    pub fn poll(&mut self, now: Instant, dpm: &super::Dpm) {
        match dpm.response() {
            Err(_) => self.stats.torn_reads = self.stats.torn_reads.wrapping_add(1),
            Ok((seq, rsp)) if seq != self.rsp_seq && seq != 0 => {
                self.rsp_seq = seq;
                match self.pending {
                    Some((id, _)) if rsp.id == id => {
                        self.pending = None;
                        self.done = Some((id, rsp.outcome));
                        self.stats.responses = self.stats.responses.wrapping_add(1);
                    }
                    _ => self.stats.late_responses = self.stats.late_responses.wrapping_add(1),
                }
            }
            Ok(_) => {}
        }
        if let Some((id, deadline)) = self.pending {
            if now >= deadline {
                self.pending = None;
                self.done = Some((id, Err(TIMEOUT_ERROR)));
                self.stats.timeouts = self.stats.timeouts.wrapping_add(1);
            }
        }
    }

    /// The drive's heartbeat was lost: complete the outstanding request with
    /// [`DRIVE_LOST_ERROR`].
    pub fn abort(&mut self) {
        if let Some((id, _)) = self.pending.take() {
            self.done = Some((id, Err(DRIVE_LOST_ERROR)));
        }
    }

    /// The id of the answer waiting to be taken, if any.
    pub fn answered(&self) -> Option<u16> {
        self.done.map(|(id, _)| id)
    }

    /// The answer to the last request, once (values, the drive's error, or the card's own
    /// timeout / drive-lost error).
    pub fn take(&mut self) -> Option<(u16, Result<ParamValues, ParamError>)> {
        self.done.take()
    }
}

/// The host's side: takes each new request once and answers it from a [`ParameterAccess`]
/// table (the drive's parameters).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct MailboxServer {
    last_id: u16,
}

impl MailboxServer {
    /// A server that has answered nothing.
    pub const fn new() -> Self {
        MailboxServer { last_id: 0 }
    }

    /// A new request in MBX_REQ, once (`None` if none, already taken, or torn: try again).
    pub fn fetch(&mut self, host: &HostSide<'_>) -> Option<MailboxRequest> {
        let req = host.read_request().ok().flatten()?;
        if req.id == self.last_id {
            return None;
        }
        self.last_id = req.id;
        Some(req)
    }

    /// Post the answer to request `id`.
    pub fn respond(host: &mut HostSide<'_>, id: u16, outcome: Result<ParamValues, ParamError>) -> u16 {
        host.write_response(&MailboxResponse { id, outcome })
    }

    /// Fetch a new request and answer it from `table` at once; returns the request id served.
    pub fn serve(&mut self, host: &mut HostSide<'_>, table: &mut impl ParameterAccess) -> Option<u16> {
        let req = self.fetch(host)?;
        let outcome = execute(&req, table);
        Self::respond(host, req.id, outcome);
        Some(req.id)
    }
}

/// Execute one mailbox request against `table`.
pub fn execute(req: &MailboxRequest, table: &mut impl ParameterAccess) -> Result<ParamValues, ParamError> {
    use crate::profile::param::Attribute;
    if !table.has_axis(req.axis) {
        return Err(ErrorValue::AXIS_NONEXISTENT.into());
    }
    let attribute = match req.kind {
        RequestKind::ReadDescription => Attribute::Description,
        _ => Attribute::Value,
    };
    let addr = ParamAddress { attribute, elements: req.count, pnu: req.pnu, subindex: req.subindex };
    let mut buf = [0u8; super::layout::MBX_CAPACITY];
    match req.kind {
        RequestKind::Write => {
            let v = &req.values;
            let block = ValueBlock { format: v.format, count: v.count, bytes: v.bytes() };
            match v.format.value_size() {
                Some(size) if size > 0 && size * v.count as usize == v.bytes().len() => {}
                Some(_) => return Err(ErrorValue::NUMBER_OF_VALUES_INCONSISTENT.into()),
                None => return Err(ErrorValue::ILLEGAL_FORMAT.into()),
            }
            if v.count != addr.count() {
                return Err(ErrorValue::NUMBER_OF_VALUES_INCONSISTENT.into());
            }
            table.write_value(req.axis, &addr, &block).map(|()| ParamValues::NONE)
        }
        RequestKind::Read | RequestKind::ReadDescription => {
            let mut w = ValueWriter::new(&mut buf);
            let r = if req.kind == RequestKind::Read {
                table.read_value(req.axis, &addr, &mut w)
            } else {
                table.read_description(req.axis, &addr, &mut w)
            };
            r?;
            if w.overflowed() {
                return Err(ErrorValue::RESPONSE_TOO_LONG.into());
            }
            let format = w.format().unwrap_or(crate::profile::param::Format::OCTET_STRING);
            let (count, len) = (w.count(), w.len());
            ParamValues::new(format, count, &buf[..len]).ok_or(ErrorValue::RESPONSE_TOO_LONG.into())
        }
    }
}
