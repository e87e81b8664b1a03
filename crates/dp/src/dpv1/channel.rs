//! One acyclic request/response relation: MSAC_C1, or one MSAC_C2 connection.
//!
//! DP-V1 separates "request received" from "response available" (reference §4.3): the
//! master sends the request PDU (SRD with data), the slave acknowledges it with SC and works
//! on it outside the interrupt path; the master then polls (SRD without data) and receives SC
//! until the response PDU is ready, then the response. The [`Channel`] keeps the request,
//! builds the complete response *frame* once ([`Channel::respond`]) and hands it out on the
//! next poll, so the decision path never copies a PDU. An FCB retry of a poll gets the same
//! frame again from the FDL station.

use super::pdu::{self, ErrorCode1, Function, Request, Response, MAX_PDU_LEN};
use super::records::RecordHandler;
use crate::fdl::telegram::{self, FunctionCode, Header, ResponseStatus, MAX_FRAME_LEN};
use crate::time::Instant;

/// Where a channel is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum ChannelState {
    /// No request outstanding.
    Idle,
    /// A request was acknowledged; its response is being prepared.
    Pending,
    /// The response frame is ready for the next poll.
    Ready,
}

/// What the FDL answers to a request or poll on the channel.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Answer {
    /// SC: request accepted / response not ready yet.
    NotReady,
    /// The response frame of this many bytes ([`Channel::frame`]).
    Frame(u16),
}

/// Counters of a channel.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct ChannelStats {
    /// Requests accepted.
    pub requests: u32,
    /// Polls answered "not ready".
    pub polls_not_ready: u32,
    /// Responses delivered.
    pub responses: u32,
    /// Error PDUs produced (negative responses).
    pub errors: u32,
    /// Requests that replaced a response the master never fetched.
    pub overwritten: u32,
}

/// One request/response relation.
#[derive(Debug, Clone)]
pub struct Channel {
    state: ChannelState,
    /// Who asked, and on which SAPs (for the response header).
    master: u8,
    own: u8,
    dsap: u8,
    ssap: u8,
    req: [u8; MAX_PDU_LEN],
    req_len: u8,
    frame: [u8; MAX_FRAME_LEN],
    frame_len: u16,
    stats: ChannelStats,
}

impl Default for Channel {
    fn default() -> Self {
        Self::new()
    }
}

impl Channel {
    /// An idle channel.
    pub const fn new() -> Self {
        Channel {
            state: ChannelState::Idle,
            master: 0,
            own: 0,
            dsap: 0,
            ssap: 0,
            req: [0; MAX_PDU_LEN],
            req_len: 0,
            frame: [0; MAX_FRAME_LEN],
            frame_len: 0,
            stats: ChannelStats { requests: 0, polls_not_ready: 0, responses: 0, errors: 0, overwritten: 0 },
        }
    }

    /// State.
    pub fn state(&self) -> ChannelState {
        self.state
    }
    /// Counters.
    pub fn stats(&self) -> ChannelStats {
        self.stats
    }
    /// Forget any request or response (the relation ended).
    pub fn reset(&mut self) {
        self.state = ChannelState::Idle;
    }

    /// A request (`pdu` not empty) or a poll (`pdu` empty) from `master` (its SSAP
    /// `master_sap`) to our `own` address and SAP `our_sap`.
    pub fn on_request(&mut self, master: u8, master_sap: u8, own: u8, our_sap: u8, pdu: &[u8]) -> Answer {
        self.on_request_as(master, master_sap, own, our_sap, pdu, true)
    }

    /// [`on_request`](Self::on_request), where `deliver` false means the line already
    /// answered this poll "not ready" (SC, `pbcard::fast`): a ready response stays for the
    /// next poll instead of being handed out on a frame nobody sees.
    ///
    /// Out of line: several tasks call it (footprint, issue 13 item 1).
    #[inline(never)]
    pub fn on_request_as(
        &mut self,
        master: u8,
        master_sap: u8,
        own: u8,
        our_sap: u8,
        pdu: &[u8],
        deliver: bool,
    ) -> Answer {
        if pdu.is_empty() {
            return match self.state {
                ChannelState::Ready if deliver => {
                    self.state = ChannelState::Idle;
                    self.stats.responses = self.stats.responses.wrapping_add(1);
                    Answer::Frame(self.frame_len)
                }
                ChannelState::Ready | ChannelState::Pending | ChannelState::Idle => {
                    self.stats.polls_not_ready = self.stats.polls_not_ready.wrapping_add(1);
                    Answer::NotReady
                }
            };
        }
        if self.state == ChannelState::Ready {
            self.stats.overwritten = self.stats.overwritten.wrapping_add(1);
        }
        let n = pdu.len().min(MAX_PDU_LEN);
        self.req[..n].copy_from_slice(&pdu[..n]);
        self.req_len = n as u8;
        (self.master, self.own, self.dsap, self.ssap) = (master, own, master_sap, our_sap);
        self.state = ChannelState::Pending;
        self.stats.requests = self.stats.requests.wrapping_add(1);
        Answer::NotReady
    }

    /// The request waiting for processing, if any.
    pub fn pending(&self) -> Option<&[u8]> {
        (self.state == ChannelState::Pending).then(|| &self.req[..self.req_len as usize])
    }

    /// Answer the pending request with a response PDU built by `build` into the ≤ 244-byte
    /// slice it is given (returns the PDU length). Nothing happens when no request is pending.
    pub fn respond(&mut self, build: impl FnOnce(&[u8], &mut [u8]) -> usize) {
        if self.state != ChannelState::Pending {
            return;
        }
        let hdr = Header {
            da: self.master,
            sa: self.own,
            fc: FunctionCode::response(ResponseStatus::Dl),
            dsap: Some(self.dsap),
            ssap: Some(self.ssap),
        };
        let mut pdu = [0u8; MAX_PDU_LEN];
        let req_len = self.req_len as usize;
        let n = build(&self.req[..req_len], &mut pdu).min(MAX_PDU_LEN);
        if n >= 2 && pdu[0] & pdu::ERROR_BIT != 0 {
            self.stats.errors = self.stats.errors.wrapping_add(1);
        }
        self.frame_len = telegram::emit(&mut self.frame, &hdr, &pdu[..n]).unwrap_or(0) as u16;
        self.state = ChannelState::Ready;
    }

    /// The response frame the next poll hands out, if one is ready (the fast path stages it).
    pub fn ready_frame(&self) -> Option<&[u8]> {
        (self.state == ChannelState::Ready).then(|| &self.frame[..(self.frame_len as usize).min(MAX_FRAME_LEN)])
    }

    /// The response frame.
    pub fn frame(&self, len: u16) -> &[u8] {
        &self.frame[..(len as usize).min(MAX_FRAME_LEN)]
    }
}

/// The MSAC_C1 / MSAC_C2 data services on a record handler: Read, Write and (C2)
/// Data_Transport; anything else gets the error PDU with `function | 0x80`. Returns the PDU
/// length written to `out`.
pub fn serve_records(
    now: Instant,
    req: &[u8],
    out: &mut [u8],
    records: &mut impl RecordHandler,
    allow_transport: bool,
) -> usize {
    // `function | 0x80, Error_Decode 0x80 (DP-V1), Error_Code_1, Error_Code_2 = 0`.
    let error = |out: &mut [u8], f: u8, ec: ErrorCode1| {
        out[..4].copy_from_slice(&[f | pdu::ERROR_BIT, pdu::ERROR_DECODE_DPV1, ec.0, 0]);
        4
    };
    match pdu::parse(req) {
        Ok(Request::Read(r)) => {
            let n = (r.length as usize).min(pdu::MAX_DATA_LEN);
            match records.read(now, r.slot, r.index, &mut out[4..4 + n]) {
                Ok(len) => pdu::emit_data_header(out, Function::Read, r.slot, r.index, len.min(n)).unwrap_or(0),
                Err(ec) => error(out, Function::Read as u8, ec),
            }
        }
        Ok(Request::Write(w)) => match records.write(now, w.slot, w.index, w.data) {
            Ok(()) => {
                Response::Write { slot: w.slot, index: w.index, length: w.data.len() as u8 }.emit(out).unwrap_or(0)
            }
            Err(ec) => error(out, Function::Write as u8, ec),
        },
        Ok(Request::DataTransport(d)) if allow_transport => {
            // Data_Transport = write then read of the same record in one PDU.
            let data_len = d.data.len();
            let mut tmp = [0u8; pdu::MAX_DATA_LEN];
            tmp[..data_len].copy_from_slice(d.data);
            match records.write(now, d.slot, d.index, &tmp[..data_len]) {
                Ok(()) => match records.read(now, d.slot, d.index, &mut out[4..4 + pdu::MAX_DATA_LEN]) {
                    Ok(len) => pdu::emit_data_header(out, Function::DataTransport, d.slot, d.index, len).unwrap_or(0),
                    Err(ec) => error(out, Function::DataTransport as u8, ec),
                },
                Err(ec) => error(out, Function::DataTransport as u8, ec),
            }
        }
        Ok(Request::AlarmAck(_)) => error(out, Function::AlarmAck as u8, ErrorCode1::STATE_CONFLICT),
        Ok(other) => error(out, other.function() as u8, ErrorCode1::FEATURE_NOT_SUPPORTED),
        Err(e) => {
            error(out, req.first().copied().unwrap_or(0), e.error_code1().unwrap_or(ErrorCode1::FEATURE_NOT_SUPPORTED))
        }
    }
}
