//! MSAC_C2: connections from class-2 masters (reference §4.1, §4.5, §4.6).
//!
//! A class-2 master (engineering tool, drive commissioning software) opens a connection in two
//! steps: an Initiate.req on the **resource manager** SAP 49, answered *immediately* with the
//! RM PDU `56 server_sap poll_timeout(BE)` that names a free connection SAP, then the same
//! Initiate.req again on that SAP. The connection then carries Read / Write / Data_Transport
//! and Idle until either side aborts it or its Send_Timeout expires. [`C2`] manages `N`
//! connections on SAPs 48, 47, … (profichip allocates from 48 downward), independent of the
//! cyclic DP state and of the master lock.
//!
//! # What the FDL answers ([`C2Answer`])
//!
//! | request | answer |
//! |---|---|
//! | SAP 49, SRD with an Initiate.req, a connection free | the RM PDU, SD2 DL (DSAP = master's SSAP, SSAP 49) |
//! | SAP 49, Initiate.req, all connections in use | SD1 **RR** (no resources), counted in [`C2Stats::refused`] |
//! | SAP 49, anything else (another PDU, no SSAP, a poll) | SD1 RS |
//! | connection SAP, a request PDU from its master | SC; the response is fetched by a later poll |
//! | connection SAP, a poll (no PDU) from its master | the response frame when ready, else SC |
//! | connection SAP after a slave-side abort | the Abort PDU `58 00 1r 00`, then the SAP is closed |
//! | connection SAP, the master's Abort PDU | SC for SRD, nothing for SDN; the SAP is closed |
//! | connection SAP, another master (address or SSAP) | SD1 RS, counted in [`C2Stats::foreign`] |
//! | closed connection SAP | SD1 RS |
//! | any SDN except the master's Abort; any broadcast | nothing |
//!
//! # Request/poll (choice)
//!
//! Every request on a connection SAP is acknowledged with SC and answered on the master's next
//! poll, as profichip's VPC3+ firmware does (the ASIC acknowledges from an empty reply buffer,
//! the firmware later provides the response PDU — `FDL_RespProvide`). The connection's
//! [`Channel`] keeps the response frame; a poll after it was fetched gets SC again and nothing
//! is executed twice (an FCB retry of the fetching poll is the [`Station`]'s business: it
//! repeats the frame).
//!
//! * Initiate.res and the Idle response are built at once in [`C2::on_request`] (a bounded
//!   copy of at most 244 bytes), so opening and keeping a connection alive do not depend on the
//!   main loop.
//! * Read / Write / Data_Transport stay pending until [`C2::process`] runs them on a
//!   [`RecordHandler`] through [`serve_records`] (Data_Transport allowed). The FDL decision path
//!   never calls into the records.
//! * A slave-side abort (a request that is not allowed) is also acknowledged with SC; the Abort
//!   PDU answers the master's **next** request or poll on that SAP, after which the SAP is
//!   closed — again as profichip places its disconnect PDU in the reply buffer and disables the
//!   SAP after it was sent. When the master never comes back, the aborting connection is closed
//!   after one more Send_Timeout (profichip's second timer expiry).
//!
//! # Connection monitoring
//!
//! The connection uses `max(own minimum, requested Send_Timeout)` (unit 10 ms \[M\]); every frame
//! from the connection's master on its SAP (request or poll) restarts the timer. On expiry the
//! connection is aborted with reason 3 (timeout). The own minimum defaults to
//! [`DEFAULT_MIN_SEND_TIMEOUT`] = 100 (1 s), profichip's value at ≥ 1.5 Mbit/s (it uses 0xC8 at
//! 500 kbit/s and 0x190 at ≤ 187.5 kbit/s — [`C2::set_min_send_timeout`]). profichip writes the
//! same value into the RM PDU's Poll_Timeout (`FDL_SetPollTimeOutIsr(wSendTimeOut)`), and so do
//! we; a reservation made by the RM expires when the master has not sent its Initiate.req on
//! the server SAP within that time (profichip keeps it forever; a lost master would then hold
//! a connection until reset).
//!
//! # Abort reasons (choices, after profichip's `dp_msac2.c`)
//!
//! | cause | Reason_Code |
//! |---|---|
//! | Send_Timeout expired | 3 timeout |
//! | malformed Initiate: S_Len/D_Len inconsistent; destination API ≠ 0 | 7 invalid additional address information |
//! | malformed Initiate / Idle / Abort (wrong size) | 2 invalid request PDU ([`pdu::PduError::abort_reason`]) |
//! | anything but Initiate on a freshly reserved SAP (e.g. Read before Initiate) | 2 invalid request PDU |
//! | Initiate again, Alarm_Ack, unknown function on an open connection | 2 invalid request PDU |
//!
//! profichip answers every "invalid service for this state" with reason 2 (`MSAC_C2_ABT_FE`,
//! "changed V302 PNO testcase, wrong function number"); reason 1 (sequence error) is never sent.
//! Malformed Read / Write / Data_Transport are *not* aborts: [`serve_records`] answers them
//! with the DP-V1 error PDU (e.g. `DE 80 B3 00` for a Read of length 0).
//!
//! The Abort PDU is 4 bytes, `58 00 (0x10 | reason) 00`: subnet 0 (none), instance MSAC_C2,
//! the detail byte 0 ([`pdu::Abort`]'s emitter always sends 4 bytes).
//!
//! [`Station`]: crate::fdl::station::Station

use super::channel::{self, serve_records, Channel};
use super::pdu::{self, Abort, AbortReason, Function, InitiateResponse, Instance, Request, Response, Subnet};
use super::records::RecordHandler;
use crate::fdl::station::Reply;
use crate::fdl::telegram::{self, DataTelegram, FunctionCode, Header, RequestFunction, ResponseStatus};
use crate::time::{Duration, Instant};

/// The resource manager's SAP.
pub const RM_SAP: u8 = 49;
/// The first connection SAP; connection `i` uses SAP `48 − i`.
pub const HIGHEST_SAP: u8 = 48;
/// Own minimum Send_Timeout and the RM Poll_Timeout, unit 10 ms: 100 = 1 s (profichip
/// `MSAC_C2_TIMEOUT_1_5MBAUD` = 0x64; the unit of the RM field is \[U\]).
pub const DEFAULT_MIN_SEND_TIMEOUT: u16 = 100;
/// Max_Len_Data_Unit of the Initiate.res: the 244-byte C2 buffer − 4 (GSD `C2_Max_Data_Len`).
pub const MAX_LEN_DATA_UNIT: u8 = pdu::MAX_DATA_LEN as u8;
/// Features_Supported_1/2 of the Initiate.res: b0 = Read/Write supported.
pub const FEATURES_SUPPORTED: [u8; 2] = [0x01, 0x00];
/// Profile_Features_Supported_1/2 of the Initiate.res: none.
pub const PROFILE_FEATURES_SUPPORTED: [u8; 2] = [0x00, 0x00];

/// The RM and Abort frames: SD2 with DSAP, SSAP and a 4-byte PDU.
const SCRATCH_LEN: usize = telegram::encoded_len(2, 4);

/// What the FDL answers to a request routed to [`C2::on_request`]; see the module table.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum C2Answer {
    /// SC: request accepted, or no response ready yet.
    NotReady,
    /// The frame staged in buffer `id` ([`C2::frame`]): `0..N` a connection's response, `N` the
    /// RM / Abort frame.
    Frame {
        /// buffer id
        id: u8,
        /// frame length in bytes
        len: u16,
    },
    /// An SD1 frame with this status (RS: SAP closed or not for this master; RR: no free connection).
    Status(ResponseStatus),
    /// No answer (SDN, broadcast).
    Silent,
}

impl From<C2Answer> for Reply {
    fn from(a: C2Answer) -> Reply {
        match a {
            C2Answer::NotReady => Reply::ShortAck,
            C2Answer::Frame { id, len } => Reply::Frame { id, len },
            C2Answer::Status(s) => Reply::Status(s),
            C2Answer::Silent => Reply::Silent,
        }
    }
}

/// Where one connection is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum ConnectionState {
    /// Free; its SAP answers RS.
    Closed,
    /// Given to a master by the RM; waiting for its Initiate.req on the SAP.
    Reserved,
    /// Initiated; Send_Timeout monitoring runs.
    Open,
    /// Aborted by the slave; the Abort PDU answers the master's next frame on the SAP.
    Aborting(AbortReason),
}

/// A snapshot of one connection (for diagnostics / the DPM status block).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct ConnectionInfo {
    /// The connection SAP.
    pub sap: u8,
    /// State.
    pub state: ConnectionState,
    /// The master's address (meaningless when closed).
    pub master: u8,
    /// The master's SAP (meaningless when closed).
    pub master_sap: u8,
    /// The Send_Timeout in force, unit 10 ms.
    pub send_timeout: u16,
}

/// Counters of the connection manager.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct C2Stats {
    /// RM answers (connections reserved).
    pub reserved: u32,
    /// Connections opened (Initiate.res produced).
    pub initiates: u32,
    /// Initiate.req on the RM refused with RR (all connections in use).
    pub refused: u32,
    /// Frames on SAP 49 other than an SRD Initiate.req from a master SAP (answered RS).
    pub rm_rejected: u32,
    /// Reservations that expired without an Initiate.req on the server SAP.
    pub reservations_expired: u32,
    /// Send_Timeout expiries (also counted in `aborts[3]`).
    pub timeouts: u32,
    /// Slave-side aborts by Reason_Code (index = reason, 0..15).
    pub aborts: [u32; 16],
    /// Abort PDUs delivered to the master.
    pub aborts_sent: u32,
    /// Abort PDUs received from masters.
    pub master_aborts: u32,
    /// Connections replaced because their master started a new one from the same SAP.
    pub replaced: u32,
    /// Requests on a connection SAP from another master (address or SSAP), answered RS.
    pub foreign: u32,
    /// Requests on a closed connection SAP, answered RS.
    pub closed_sap: u32,
    /// SDN frames on connection SAPs that carried no Abort (ignored).
    pub ignored: u32,
}

#[derive(Debug, Clone)]
struct Conn {
    state: ConnectionState,
    master: u8,
    master_sap: u8,
    /// Effective Send_Timeout, 10 ms units.
    send_timeout: u16,
    deadline: Instant,
    channel: Channel,
    /// The relation ended (abort, timeout, replaced) since [`C2::take_ended`].
    ended: bool,
}

impl Conn {
    const CLOSED: Conn = Conn {
        state: ConnectionState::Closed,
        master: 0,
        master_sap: 0,
        send_timeout: 0,
        deadline: Instant::from_micros(0),
        channel: Channel::new(),
        ended: false,
    };

    fn close(&mut self) {
        if matches!(self.state, ConnectionState::Open | ConnectionState::Aborting(_)) {
            self.ended = true;
        }
        self.state = ConnectionState::Closed;
        self.channel.reset();
    }
}

/// A Send_Timeout value (10 ms units) as a duration.
const fn units(t: u16) -> Duration {
    Duration::from_millis(t as u64 * 10)
}

const fn no_service(srd: bool) -> C2Answer {
    if srd {
        C2Answer::Status(ResponseStatus::Rs)
    } else {
        C2Answer::Silent
    }
}

/// The MSAC_C2 connection manager for `N` connections (GSD `C2_Max_Count_Channels`, 1..=49).
#[derive(Debug, Clone)]
pub struct C2<const N: usize> {
    conns: [Conn; N],
    min_send_timeout: u16,
    /// Profile_Ident_Number of every Initiate.res.
    profile_ident_number: u16,
    /// The RM / Abort frame (buffer id `N`).
    scratch: [u8; SCRATCH_LEN],
    stats: C2Stats,
}

impl<const N: usize> C2<N> {
    const VALID_N: () = assert!(N >= 1 && N <= HIGHEST_SAP as usize + 1, "1..=49 MSAC_C2 connections");

    /// All connections closed, own minimum Send_Timeout [`DEFAULT_MIN_SEND_TIMEOUT`].
    /// `profile_ident_number` is the Profile_Ident_Number every Initiate.res carries: the
    /// application profile the product's GSD states (this card: PROFIdrive 0x3A00,
    /// `card::PROFILE_IDENT_NUMBER`), whatever the master asked for (a master that sends 0
    /// learns the slave's profile from the answer; reference §4.5).
    pub const fn new(profile_ident_number: u16) -> Self {
        #[allow(clippy::let_unit_value)]
        let () = Self::VALID_N;
        C2 {
            conns: [Conn::CLOSED; N],
            min_send_timeout: DEFAULT_MIN_SEND_TIMEOUT,
            profile_ident_number,
            scratch: [0; SCRATCH_LEN],
            stats: C2Stats {
                reserved: 0,
                initiates: 0,
                refused: 0,
                rm_rejected: 0,
                reservations_expired: 0,
                timeouts: 0,
                aborts: [0; 16],
                aborts_sent: 0,
                master_aborts: 0,
                replaced: 0,
                foreign: 0,
                closed_sap: 0,
                ignored: 0,
            },
        }
    }

    /// Set the own minimum Send_Timeout, also sent as the RM Poll_Timeout (unit 10 ms, at least
    /// 1; profichip: 100 at ≥ 1.5 Mbit/s, 200 at 500 kbit/s, 400 at ≤ 187.5 kbit/s). Applies to
    /// connections initiated afterwards.
    pub fn set_min_send_timeout(&mut self, units: u16) {
        self.min_send_timeout = units.max(1);
    }

    /// The own minimum Send_Timeout (unit 10 ms).
    pub const fn min_send_timeout(&self) -> u16 {
        self.min_send_timeout
    }

    /// Whether frames to `sap` belong here: the RM SAP 49 and the `N` connection SAPs 48, 47, ….
    pub const fn owns_sap(&self, sap: u8) -> bool {
        sap == RM_SAP || Self::index_of(sap).is_some()
    }

    /// The SAP of connection `index` (`48 − index`).
    pub const fn sap_of(index: usize) -> u8 {
        HIGHEST_SAP - index as u8
    }

    const fn index_of(sap: u8) -> Option<usize> {
        if sap > HIGHEST_SAP {
            return None;
        }
        let i = (HIGHEST_SAP - sap) as usize;
        if i < N {
            Some(i)
        } else {
            None
        }
    }

    /// Counters.
    pub fn stats(&self) -> C2Stats {
        self.stats
    }

    /// Connection `index` (0..N), if it exists.
    pub fn connection(&self, index: usize) -> Option<ConnectionInfo> {
        self.conns.get(index).map(|c| ConnectionInfo {
            sap: Self::sap_of(index),
            state: c.state,
            master: c.master,
            master_sap: c.master_sap,
            send_timeout: c.send_timeout,
        })
    }

    /// Connection `index`'s timer: the Send_Timeout deadline (Open), the reservation's
    /// (Reserved) or the pending Abort's (Aborting) — what the fast path needs to foresee
    /// the expiry [`poll`](Self::poll) would apply at a later frame.
    pub fn deadline(&self, index: usize) -> Option<Instant> {
        self.conns.get(index).map(|c| c.deadline)
    }

    /// The response frame the next poll on connection `index` gets (an Open connection's
    /// ready response), if any.
    pub fn ready_frame(&self, index: usize) -> Option<&[u8]> {
        self.conns.get(index).filter(|c| c.state == ConnectionState::Open).and_then(|c| c.channel.ready_frame())
    }

    /// Close every connection without telling the masters (bus lost, address changed).
    pub fn reset(&mut self) {
        self.conns.iter_mut().for_each(Conn::close);
    }

    /// The connections whose application relation ended since the last call (bit `i` =
    /// connection `i`: aborted by either side, Send_Timeout expired, replaced, reset): the
    /// record handler forgets their per-relation state (a record-47 response or job), so a
    /// new connection on the same SAP never reads a stale answer.
    pub fn take_ended(&mut self) -> u64 {
        let mut mask = 0;
        for (i, c) in self.conns.iter_mut().enumerate() {
            if core::mem::take(&mut c.ended) {
                mask |= 1 << i;
            }
        }
        mask
    }

    /// Whether a Read / Write / Data_Transport waits for [`process`](Self::process).
    #[inline(never)]
    pub fn has_pending(&self) -> bool {
        self.conns.iter().any(|c| c.state == ConnectionState::Open && c.channel.pending().is_some())
    }

    /// The earliest instant at which [`poll`](Self::poll) has something to do (a reservation,
    /// Send_Timeout or pending Abort expiring), if any.
    pub fn next_deadline(&self) -> Option<Instant> {
        self.conns.iter().filter(|c| c.state != ConnectionState::Closed).map(|c| c.deadline).min()
    }

    /// A request whose DSAP [`owns_sap`](Self::owns_sap) says is ours, addressed to this
    /// station (`own`). Cheap: never calls the record handler; at most copies one PDU.
    pub fn on_request(&mut self, now: Instant, own: u8, req: &DataTelegram<'_>) -> C2Answer {
        self.on_request_as(now, own, req, true)
    }

    /// [`on_request`](Self::on_request); `deliver` false: the line already answered this
    /// frame with SC (`pbcard::fast`), so no response frame is handed out on it — a ready
    /// response or a slave-side Abort PDU stays for the master's next frame on the SAP.
    pub fn on_request_as(&mut self, now: Instant, own: u8, req: &DataTelegram<'_>, deliver: bool) -> C2Answer {
        if req.da == telegram::BROADCAST {
            return C2Answer::Silent;
        }
        let srd = matches!(req.fc.function(), RequestFunction::SrdLow | RequestFunction::SrdHigh);
        match req.dsap {
            Some(RM_SAP) => self.on_rm(now, own, req, srd),
            Some(sap) => match Self::index_of(sap) {
                Some(i) => self.on_connection(now, own, i, req, srd, deliver),
                None => no_service(srd),
            },
            None => no_service(srd),
        }
    }

    /// Run the pending Read / Write / Data_Transport requests on `records`; their responses
    /// go out on the masters' next polls.
    pub fn process(&mut self, now: Instant, records: &mut impl RecordHandler) {
        for (i, c) in self.conns.iter_mut().enumerate() {
            if c.state == ConnectionState::Open && c.channel.pending().is_some() {
                records.set_relation(super::records::relation_c2(i));
                c.channel.respond(|req, out| serve_records(now, req, out, records, true));
            }
        }
    }

    /// Supervise the timers: expired reservations close, an expired Send_Timeout aborts the
    /// connection (reason 3), an Abort the master never fetched closes the SAP. Also done
    /// lazily on every request, so calling this late only delays the bookkeeping.
    ///
    /// Out of line: the core task and the housekeeping step both call it (footprint, issue 13 item 1).
    #[inline(never)]
    pub fn poll(&mut self, now: Instant) {
        for i in 0..N {
            self.expire(i, now);
        }
    }

    /// The bytes of a frame announced by [`C2Answer::Frame`].
    pub fn frame(&self, id: u8, len: u16) -> &[u8] {
        let id = id as usize;
        if id < N {
            self.conns[id].channel.frame(len)
        } else if id == N {
            &self.scratch[..(len as usize).min(SCRATCH_LEN)]
        } else {
            &[]
        }
    }

    #[inline(never)]
    fn expire(&mut self, i: usize, now: Instant) {
        let c = &mut self.conns[i];
        // At most two steps: Open → Aborting → Closed when nobody looked for a long time.
        loop {
            if now < c.deadline {
                return;
            }
            match c.state {
                ConnectionState::Closed => return,
                ConnectionState::Reserved => {
                    self.stats.reservations_expired = self.stats.reservations_expired.wrapping_add(1);
                    c.close();
                }
                ConnectionState::Open => {
                    self.stats.timeouts = self.stats.timeouts.wrapping_add(1);
                    let r = AbortReason::Timeout.bits() as usize;
                    self.stats.aborts[r] = self.stats.aborts[r].wrapping_add(1);
                    c.channel.reset();
                    c.ended = true;
                    c.state = ConnectionState::Aborting(AbortReason::Timeout);
                    c.deadline = c.deadline + units(c.send_timeout);
                }
                ConnectionState::Aborting(_) => c.close(),
            }
        }
    }

    fn on_rm(&mut self, now: Instant, own: u8, req: &DataTelegram<'_>, srd: bool) -> C2Answer {
        let is_initiate = req.pdu.first() == Some(&Function::Initiate.code());
        let (true, true, Some(master_sap)) = (srd, is_initiate, req.ssap) else {
            self.stats.rm_rejected = self.stats.rm_rejected.wrapping_add(1);
            return no_service(srd);
        };
        self.poll(now);
        // A master that starts again from the same SAP has forgotten its old connection.
        let same = self
            .conns
            .iter()
            .position(|c| c.state != ConnectionState::Closed && (c.master, c.master_sap) == (req.sa, master_sap));
        if let Some(i) = same {
            if self.conns[i].state != ConnectionState::Reserved {
                self.stats.replaced = self.stats.replaced.wrapping_add(1);
            }
        }
        let Some(i) = same.or_else(|| self.conns.iter().position(|c| c.state == ConnectionState::Closed)) else {
            // All connections in use: FDL "no resources" (SD1 RR) rather than an Abort, which
            // would need a connection. profichip's RM SAP without a free connection has no
            // indication buffer, which the VPC3+ answers on its own [U: RR or RS].
            self.stats.refused = self.stats.refused.wrapping_add(1);
            return C2Answer::Status(ResponseStatus::Rr);
        };
        let c = &mut self.conns[i];
        c.close();
        c.state = ConnectionState::Reserved;
        (c.master, c.master_sap, c.send_timeout) = (req.sa, master_sap, self.min_send_timeout);
        c.deadline = now + units(self.min_send_timeout);
        self.stats.reserved = self.stats.reserved.wrapping_add(1);
        let rm = Response::ResourceManager { server_sap: Self::sap_of(i), poll_timeout: self.min_send_timeout };
        self.emit_scratch(own, req, RM_SAP, &rm)
    }

    fn on_connection(
        &mut self,
        now: Instant,
        own: u8,
        i: usize,
        req: &DataTelegram<'_>,
        srd: bool,
        deliver: bool,
    ) -> C2Answer {
        self.expire(i, now);
        let sap = Self::sap_of(i);
        let profile_ident_number = self.profile_ident_number;
        let c = &mut self.conns[i];
        if c.state == ConnectionState::Closed {
            self.stats.closed_sap = self.stats.closed_sap.wrapping_add(1);
            return no_service(srd);
        }
        if req.sa != c.master || req.ssap != Some(c.master_sap) {
            self.stats.foreign = self.stats.foreign.wrapping_add(1);
            return no_service(srd);
        }
        let parsed = (!req.pdu.is_empty()).then(|| pdu::parse(req.pdu));
        if let Some(Ok(Request::Abort(_))) = parsed {
            // The master closes: usually SRD (FDL acknowledges with SC, no response PDU) or SDN.
            self.stats.master_aborts = self.stats.master_aborts.wrapping_add(1);
            c.close();
            return if srd { C2Answer::NotReady } else { C2Answer::Silent };
        }
        if !srd {
            self.stats.ignored = self.stats.ignored.wrapping_add(1);
            return C2Answer::Silent;
        }
        let reason = match (c.state, parsed) {
            (ConnectionState::Closed, _) => return no_service(srd),
            (ConnectionState::Aborting(_), _) if !deliver => {
                // The line answered SC: the Abort PDU waits for the next frame.
                c.deadline = now + units(c.send_timeout);
                return C2Answer::NotReady;
            }
            (ConnectionState::Aborting(reason), _) => {
                c.close();
                self.stats.aborts_sent = self.stats.aborts_sent.wrapping_add(1);
                let abort = Abort { subnet: Subnet::None, instance: Instance::MsacC2, reason, detail: Some(0) };
                return self.emit_scratch(own, req, sap, &Response::Abort(abort));
            }
            (ConnectionState::Reserved, Some(Ok(Request::Initiate(init)))) => {
                if init.destination.api() != 0 {
                    // One application process (API 0), as profichip's sample user code.
                    AbortReason::InvalidAddressInfo
                } else {
                    let send_timeout = init.send_timeout.max(c.send_timeout);
                    c.state = ConnectionState::Open;
                    c.send_timeout = send_timeout;
                    c.deadline = now + units(send_timeout);
                    c.channel.on_request(req.sa, c.master_sap, own, sap, req.pdu);
                    c.channel.respond(|r, out| initiate_response(r, out, profile_ident_number));
                    self.stats.initiates = self.stats.initiates.wrapping_add(1);
                    return C2Answer::NotReady;
                }
            }
            (ConnectionState::Reserved, Some(Err(e))) => e.abort_reason().unwrap_or(AbortReason::InvalidRequestPdu),
            (ConnectionState::Reserved, _) => AbortReason::InvalidRequestPdu,
            (ConnectionState::Open, parsed) => {
                c.deadline = now + units(c.send_timeout);
                match parsed {
                    None => {
                        return match c.channel.on_request_as(req.sa, c.master_sap, own, sap, &[], deliver) {
                            channel::Answer::NotReady => C2Answer::NotReady,
                            channel::Answer::Frame(len) => C2Answer::Frame { id: i as u8, len },
                        };
                    }
                    Some(Ok(Request::Read(_) | Request::Write(_) | Request::DataTransport(_))) => {
                        c.channel.on_request(req.sa, c.master_sap, own, sap, req.pdu);
                        return C2Answer::NotReady;
                    }
                    Some(Err(e))
                        if matches!(e.function(), Some(Function::Read | Function::Write | Function::DataTransport)) =>
                    {
                        // serve_records answers with the DP-V1 error PDU.
                        c.channel.on_request(req.sa, c.master_sap, own, sap, req.pdu);
                        return C2Answer::NotReady;
                    }
                    Some(Ok(Request::Idle)) => {
                        c.channel.on_request(req.sa, c.master_sap, own, sap, req.pdu);
                        c.channel.respond(|_, out| Response::Idle.emit(out).unwrap_or(0));
                        return C2Answer::NotReady;
                    }
                    Some(Err(e)) => e.abort_reason().unwrap_or(AbortReason::InvalidRequestPdu),
                    Some(Ok(_)) => AbortReason::InvalidRequestPdu,
                }
            }
        };
        // Slave-side abort: acknowledge now, the Abort PDU answers the next frame.
        let r = reason.bits() as usize;
        self.stats.aborts[r] = self.stats.aborts[r].wrapping_add(1);
        c.channel.reset();
        c.state = ConnectionState::Aborting(reason);
        c.deadline = now + units(c.send_timeout);
        C2Answer::NotReady
    }

    /// Stage a 4-byte PDU answer to `req` in the scratch buffer.
    fn emit_scratch(&mut self, own: u8, req: &DataTelegram<'_>, our_sap: u8, resp: &Response<'_>) -> C2Answer {
        match emit_short_response(&mut self.scratch, own, req, our_sap, resp) {
            Some(len) => C2Answer::Frame { id: N as u8, len: len as u16 },
            None => C2Answer::Status(ResponseStatus::Rr),
        }
    }
}

/// A short DP-V1 response PDU (at most 4 octets: an Abort, an error PDU) as the SD2 data answer
/// (DL) from `our_sap` to the SAP `req` came from, into `buf`: the frame's length, `None` when
/// `buf` cannot hold it (the caller answers RR, no resources). Shared by the connection SAPs
/// here and the line's staged answers (`fast::dpv1`).
pub fn emit_short_response(
    buf: &mut [u8],
    own: u8,
    req: &DataTelegram<'_>,
    our_sap: u8,
    resp: &Response<'_>,
) -> Option<usize> {
    let mut pdu = [0u8; 4];
    let n = resp.emit(&mut pdu).unwrap_or(0);
    let hdr = Header {
        da: req.sa,
        sa: own,
        fc: FunctionCode::response(ResponseStatus::Dl),
        dsap: req.ssap,
        ssap: Some(our_sap),
    };
    telegram::emit(buf, &hdr, &pdu[..n]).ok()
}

/// Initiate.res to the stored Initiate.req (S and D blocks swapped).
fn initiate_response(req: &[u8], out: &mut [u8], profile_ident_number: u16) -> usize {
    match pdu::parse(req) {
        Ok(Request::Initiate(init)) => Response::Initiate(InitiateResponse::answering(
            &init,
            MAX_LEN_DATA_UNIT,
            FEATURES_SUPPORTED,
            PROFILE_FEATURES_SUPPORTED,
            profile_ident_number,
        ))
        .emit(out)
        .unwrap_or(0),
        _ => 0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dpv1::pdu::{AddressBlock, ErrorCode1, InitiateRequest, ReadRequest};
    use crate::fdl::telegram::{DataFormat, Decoded, Telegram};
    use proptest::prelude::*;

    const OWN: u8 = 8;

    /// A record store: slot 0, indices 0..4, up to 32 bytes each.
    #[derive(Default)]
    struct Mem {
        rec: [[u8; 32]; 4],
        len: [usize; 4],
        reads: u32,
        writes: u32,
    }

    impl RecordHandler for Mem {
        fn read(&mut self, _: Instant, slot: u8, index: u8, out: &mut [u8]) -> Result<usize, ErrorCode1> {
            if slot != 0 || index >= 4 {
                return Err(ErrorCode1::INVALID_INDEX);
            }
            self.reads += 1;
            let n = self.len[index as usize].min(out.len());
            out[..n].copy_from_slice(&self.rec[index as usize][..n]);
            Ok(n)
        }
        fn write(&mut self, _: Instant, slot: u8, index: u8, data: &[u8]) -> Result<(), ErrorCode1> {
            if slot != 0 || index >= 4 {
                return Err(ErrorCode1::INVALID_INDEX);
            }
            if data.len() > 32 {
                return Err(ErrorCode1::WRITE_LENGTH_ERROR);
            }
            self.writes += 1;
            self.rec[index as usize][..data.len()].copy_from_slice(data);
            self.len[index as usize] = data.len();
            Ok(())
        }
    }

    fn initiate_bytes(send_timeout: u16, s_len: u8, d_api: u8) -> Vec<u8> {
        let req = InitiateRequest {
            send_timeout,
            features_supported: [1, 0],
            profile_features_supported: [0, 0],
            profile_ident_number: 0,
            source: AddressBlock { kind: 0, bytes: &[0, 0] },
            destination: AddressBlock { kind: 0, bytes: &[d_api, 0] },
        };
        let mut out = vec![0u8; 64];
        let n = req.emit(&mut out).unwrap();
        out.truncate(n);
        out[13] = s_len;
        out
    }

    fn emit_req(r: Request<'_>) -> Vec<u8> {
        let mut out = vec![0u8; 260];
        let n = r.emit(&mut out).unwrap();
        out.truncate(n);
        out
    }

    struct Bus {
        c2: C2<2>,
        mem: Mem,
        now: Instant,
    }

    impl Bus {
        fn new() -> Self {
            Bus {
                c2: C2::new(crate::test_card::PROFILE_IDENT_NUMBER),
                mem: Mem::default(),
                now: Instant::from_millis(1_000),
            }
        }
        fn advance(&mut self, ms: u64) {
            self.now = self.now + Duration::from_millis(ms);
        }
        fn send(&mut self, fc_fn: u8, master: u8, ssap: Option<u8>, dsap: u8, pdu: &[u8]) -> C2Answer {
            let t = DataTelegram {
                format: DataFormat::Sd2,
                da: OWN,
                sa: master,
                fc: FunctionCode::request(fc_fn, false, true),
                dsap: Some(dsap),
                ssap,
                pdu,
            };
            let a = self.c2.on_request(self.now, OWN, &t);
            if let C2Answer::Frame { id, len } = a {
                check_frame(self.c2.frame(id, len), &t);
            }
            a
        }
        fn srd(&mut self, master: u8, ssap: u8, dsap: u8, pdu: &[u8]) -> C2Answer {
            self.send(0x0C, master, Some(ssap), dsap, pdu)
        }
        /// The PDU of a frame answer.
        fn pdu(&self, a: C2Answer) -> Vec<u8> {
            let C2Answer::Frame { id, len } = a else { panic!("expected a frame, got {a:?}") };
            let Decoded::Frame(Telegram::Data(t), _) = telegram::decode(self.c2.frame(id, len)) else { panic!() };
            t.pdu.to_vec()
        }
        /// RM + Initiate on the server SAP + poll for Initiate.res; returns the SAP.
        fn connect(&mut self, master: u8, ssap: u8, send_timeout: u16) -> u8 {
            let init = initiate_bytes(send_timeout, 2, 0);
            let rm = self.srd(master, ssap, RM_SAP, &init);
            let rm = self.pdu(rm);
            assert_eq!(rm[0], 0x56);
            assert_eq!(&rm[2..], &DEFAULT_MIN_SEND_TIMEOUT.to_be_bytes());
            let sap = rm[1];
            assert_eq!(self.srd(master, ssap, sap, &init), C2Answer::NotReady);
            let res = self.srd(master, ssap, sap, &[]);
            let res = self.pdu(res);
            let Ok(Response::Initiate(r)) = Response::parse(&res) else { panic!("{res:02X?}") };
            assert_eq!((r.max_len_data_unit, r.features_supported), (240, [1, 0]));
            assert_eq!(r.source.bytes, &[0, 0]);
            sap
        }
        /// Request, process, poll: the response PDU.
        fn transact(&mut self, master: u8, ssap: u8, sap: u8, req: &[u8]) -> Vec<u8> {
            assert_eq!(self.srd(master, ssap, sap, req), C2Answer::NotReady);
            self.c2.process(self.now, &mut self.mem);
            let a = self.srd(master, ssap, sap, &[]);
            self.pdu(a)
        }
        fn state(&self, sap: u8) -> ConnectionState {
            self.c2.connection((HIGHEST_SAP - sap) as usize).unwrap().state
        }
    }

    /// Every frame decodes, answers the requester's SSAP from the requested SAP, and carries a
    /// valid response PDU.
    fn check_frame(frame: &[u8], req: &DataTelegram<'_>) {
        let Decoded::Frame(Telegram::Data(t), n) = telegram::decode(frame) else { panic!("{frame:02X?}") };
        assert_eq!(n, frame.len());
        assert_eq!((t.da, t.sa, t.fc), (req.sa, OWN, FunctionCode::response(ResponseStatus::Dl)));
        assert_eq!((t.dsap, t.ssap), (req.ssap, req.dsap));
        assert!(Response::parse(t.pdu).is_ok(), "{:02X?}", t.pdu);
    }

    #[test]
    fn sap_ownership() {
        let c2 = C2::<2>::new(crate::test_card::PROFILE_IDENT_NUMBER);
        assert!(c2.owns_sap(49) && c2.owns_sap(48) && c2.owns_sap(47));
        assert!(!c2.owns_sap(46) && !c2.owns_sap(50) && !c2.owns_sap(51) && !c2.owns_sap(0));
        assert!(C2::<49>::new(crate::test_card::PROFILE_IDENT_NUMBER).owns_sap(0));
        assert_eq!(Reply::from(C2Answer::NotReady), Reply::ShortAck);
    }

    #[test]
    fn two_masters_read_and_write_at_once() {
        let mut b = Bus::new();
        let s2 = b.connect(2, 40, 300);
        let s3 = b.connect(3, 41, 300);
        assert_eq!((s2, s3), (48, 47));
        assert_eq!(b.c2.stats().initiates, 2);

        // Interleaved: both requests pending at once, one process() serves both.
        let write = emit_req(Request::Write(pdu::DataRequest { slot: 0, index: 1, data: &[1, 2, 3] }));
        let read = emit_req(Request::Read(ReadRequest { slot: 0, index: 1, length: 240 }));
        b.mem.write(b.now, 0, 1, &[9]).unwrap();
        assert_eq!(b.srd(2, 40, s2, &write), C2Answer::NotReady);
        assert_eq!(b.srd(3, 41, s3, &read), C2Answer::NotReady);
        assert!(b.c2.has_pending());
        assert_eq!(b.srd(3, 41, s3, &[]), C2Answer::NotReady, "nothing before process()");
        b.c2.process(b.now, &mut b.mem);
        assert!(!b.c2.has_pending());
        let r3 = b.srd(3, 41, s3, &[]);
        assert!(matches!(r3, C2Answer::Frame { id: 1, .. }));
        let r2 = b.srd(2, 40, s2, &[]);
        assert!(matches!(r2, C2Answer::Frame { id: 0, .. }));
        assert_eq!(b.pdu(r2), [0x5F, 0, 1, 3]);
        // The read ran after the write (connection order) and sees its data.
        assert_eq!(b.pdu(r3), [0x5E, 0, 1, 3, 1, 2, 3]);

        // Data_Transport = write + read of the record; errors come back as DP-V1 error PDUs.
        let dt = emit_req(Request::DataTransport(pdu::DataRequest { slot: 0, index: 2, data: &[7, 7] }));
        assert_eq!(b.transact(3, 41, s3, &dt), [0x51, 0, 2, 2, 7, 7]);
        let bad = emit_req(Request::Read(ReadRequest { slot: 0, index: 9, length: 4 }));
        assert_eq!(b.transact(2, 40, s2, &bad), [0xDE, 0x80, 0xB0, 0]);
        // A malformed Read (length 0) is an error PDU, not an abort.
        assert_eq!(b.transact(2, 40, s2, &[0x5E, 0, 1, 0]), [0xDE, 0x80, 0xB3, 0]);
        assert_eq!((b.state(s2), b.state(s3)), (ConnectionState::Open, ConnectionState::Open));
    }

    #[test]
    fn third_initiate_refused_with_rr() {
        let mut b = Bus::new();
        let s2 = b.connect(2, 40, 300);
        b.connect(3, 41, 300);
        let init = initiate_bytes(300, 2, 0);
        assert_eq!(b.srd(4, 40, RM_SAP, &init), C2Answer::Status(ResponseStatus::Rr));
        assert_eq!(b.c2.stats().refused, 1);
        // Other PDUs, SDN, a poll or a missing SSAP on the RM: RS / nothing.
        let read = emit_req(Request::Read(ReadRequest { slot: 0, index: 1, length: 4 }));
        assert_eq!(b.srd(4, 40, RM_SAP, &read), C2Answer::Status(ResponseStatus::Rs));
        assert_eq!(b.srd(4, 40, RM_SAP, &[]), C2Answer::Status(ResponseStatus::Rs));
        assert_eq!(b.send(0x0C, 4, None, RM_SAP, &init), C2Answer::Status(ResponseStatus::Rs));
        assert_eq!(b.send(0x04, 4, Some(40), RM_SAP, &init), C2Answer::Silent);
        assert_eq!(b.c2.stats().rm_rejected, 4);
        // The open connections are untouched.
        b.mem.write(b.now, 0, 0, &[5]).unwrap();
        assert_eq!(b.transact(2, 40, s2, &read), [0x5E, 0, 1, 0]);
        // After one closes, the fourth master gets its SAP.
        assert_eq!(b.srd(2, 40, s2, &[0x58, 0, 0x20, 0]), C2Answer::NotReady);
        assert_eq!(b.connect(4, 40, 300), 48);
    }

    #[test]
    fn send_timeout_expiry_aborts_then_rs() {
        let mut b = Bus::new();
        let sap = b.connect(2, 40, 200); // 2 s
        b.advance(1_999);
        b.c2.poll(b.now);
        assert_eq!(b.state(sap), ConnectionState::Open);
        assert_eq!(b.c2.next_deadline(), Some(b.now + Duration::from_millis(1)));
        b.advance(1);
        b.c2.poll(b.now);
        assert_eq!(b.state(sap), ConnectionState::Aborting(AbortReason::Timeout));
        assert_eq!(b.c2.stats().timeouts, 1);
        assert_eq!(b.c2.stats().aborts[3], 1);
        // The master's next request gets the Abort (instance MSAC_C2, reason 3), then RS.
        let read = emit_req(Request::Read(ReadRequest { slot: 0, index: 1, length: 4 }));
        let a = b.srd(2, 40, sap, &read);
        assert_eq!(b.pdu(a), [0x58, 0x00, 0x13, 0x00]);
        assert_eq!(b.srd(2, 40, sap, &read), C2Answer::Status(ResponseStatus::Rs));
        assert_eq!(b.srd(2, 40, sap, &[]), C2Answer::Status(ResponseStatus::Rs));
        assert_eq!(b.c2.stats().aborts_sent, 1);
        assert_eq!(b.c2.stats().closed_sap, 2);
    }

    #[test]
    fn own_minimum_send_timeout_and_lazy_expiry() {
        let mut b = Bus::new();
        let sap = b.connect(2, 40, 10); // asks for 100 ms, gets the own minimum 1 s
        assert_eq!(b.c2.connection(0).unwrap().send_timeout, DEFAULT_MIN_SEND_TIMEOUT);
        b.advance(900);
        assert_eq!(b.srd(2, 40, sap, &[]), C2Answer::NotReady, "a poll keeps it alive too");
        b.advance(999);
        assert_eq!(b.srd(2, 40, sap, &[0x48, 0]), C2Answer::NotReady);
        // Without poll(): expiry is noticed by the next request.
        b.advance(1_000);
        let a = b.srd(2, 40, sap, &[]);
        assert_eq!(b.pdu(a), [0x58, 0x00, 0x13, 0x00]);
        // A master that never fetches the Abort: the SAP closes one more Send_Timeout later.
        let sap = b.connect(2, 40, 100);
        b.advance(10_000);
        b.c2.poll(b.now);
        assert_eq!(b.state(sap), ConnectionState::Closed);
        assert_eq!(b.c2.next_deadline(), None);
    }

    #[test]
    fn idle_keeps_alive() {
        let mut b = Bus::new();
        let sap = b.connect(2, 40, 100);
        for _ in 0..20 {
            b.advance(800);
            b.c2.poll(b.now);
            assert_eq!(b.srd(2, 40, sap, &[0x48, 0x00]), C2Answer::NotReady);
            let a = b.srd(2, 40, sap, &[]);
            assert_eq!(b.pdu(a), [0x48, 0x00]);
        }
        assert_eq!(b.state(sap), ConnectionState::Open);
        assert_eq!(b.c2.stats().timeouts, 0);
        // One-byte Idle too; a 3-byte Idle is a malformed PDU → abort reason 2.
        assert_eq!(b.srd(2, 40, sap, &[0x48]), C2Answer::NotReady);
        assert_eq!(b.srd(2, 40, sap, &[0x48, 0, 0]), C2Answer::NotReady);
        let a = b.srd(2, 40, sap, &[]);
        assert_eq!(b.pdu(a), [0x58, 0x00, 0x12, 0x00]);
    }

    #[test]
    fn master_abort_closes() {
        let mut b = Bus::new();
        let sap = b.connect(2, 40, 300);
        // SRD: SC, no response PDU.
        assert_eq!(b.srd(2, 40, sap, &[0x58, 0x01, 0x20, 0x00]), C2Answer::NotReady);
        assert_eq!(b.state(sap), ConnectionState::Closed);
        assert_eq!(b.srd(2, 40, sap, &[]), C2Answer::Status(ResponseStatus::Rs));
        // SDN (3-byte form): nothing, closed.
        let sap = b.connect(2, 40, 300);
        assert_eq!(b.send(0x04, 2, Some(40), sap, &[0x58, 0x00, 0x20]), C2Answer::Silent);
        assert_eq!(b.state(sap), ConnectionState::Closed);
        assert_eq!(b.c2.stats().master_aborts, 2);
        // Other SDN frames on a connection SAP are ignored.
        let sap = b.connect(2, 40, 300);
        assert_eq!(b.send(0x04, 2, Some(40), sap, &[0x48, 0]), C2Answer::Silent);
        assert_eq!(b.state(sap), ConnectionState::Open);
        assert_eq!(b.c2.stats().ignored, 1);
    }

    #[test]
    fn initiate_with_bad_address_lengths_aborts() {
        let mut b = Bus::new();
        let bad = initiate_bytes(300, 3, 0); // S_Len 3 with S_Type 0
        let rm = b.srd(2, 40, RM_SAP, &bad);
        let sap = b.pdu(rm)[1];
        assert_eq!(b.srd(2, 40, sap, &bad), C2Answer::NotReady);
        assert_eq!(b.state(sap), ConnectionState::Aborting(AbortReason::InvalidAddressInfo));
        let a = b.srd(2, 40, sap, &[]);
        assert_eq!(b.pdu(a), [0x58, 0x00, 0x17, 0x00]);
        assert_eq!(b.srd(2, 40, sap, &[]), C2Answer::Status(ResponseStatus::Rs));
        // Destination API ≠ 0: also reason 7.
        let api = initiate_bytes(300, 2, 1);
        let rm = b.srd(2, 40, RM_SAP, &api);
        let sap = b.pdu(rm)[1];
        assert_eq!(b.srd(2, 40, sap, &api), C2Answer::NotReady);
        let a = b.srd(2, 40, sap, &[]);
        assert_eq!(b.pdu(a), [0x58, 0x00, 0x17, 0x00]);
        // Too short: reason 2.
        let rm = b.srd(2, 40, RM_SAP, &api[..15]);
        let sap = b.pdu(rm)[1];
        assert_eq!(b.srd(2, 40, sap, &api[..15]), C2Answer::NotReady);
        let a = b.srd(2, 40, sap, &[]);
        assert_eq!(b.pdu(a), [0x58, 0x00, 0x12, 0x00]);
        assert_eq!((b.c2.stats().aborts[7], b.c2.stats().aborts[2], b.c2.stats().initiates), (2, 1, 0));
    }

    #[test]
    fn read_before_initiate_aborts() {
        let mut b = Bus::new();
        let init = initiate_bytes(300, 2, 0);
        let rm = b.srd(2, 40, RM_SAP, &init);
        let sap = b.pdu(rm)[1];
        assert_eq!(b.state(sap), ConnectionState::Reserved);
        // Another master (or the same master from another SAP) on the reserved SAP: RS, no harm.
        assert_eq!(b.srd(3, 40, sap, &init), C2Answer::Status(ResponseStatus::Rs));
        assert_eq!(b.srd(2, 41, sap, &init), C2Answer::Status(ResponseStatus::Rs));
        assert_eq!(b.c2.stats().foreign, 2);
        assert_eq!(b.state(sap), ConnectionState::Reserved);
        // Read before Initiate: reason 2 (profichip answers any wrong function on a fresh SAP so).
        let read = emit_req(Request::Read(ReadRequest { slot: 0, index: 1, length: 4 }));
        assert_eq!(b.srd(2, 40, sap, &read), C2Answer::NotReady);
        let a = b.srd(2, 40, sap, &[]);
        assert_eq!(b.pdu(a), [0x58, 0x00, 0x12, 0x00]);
        assert_eq!(b.srd(2, 40, sap, &init), C2Answer::Status(ResponseStatus::Rs));
        assert_eq!(b.mem.reads, 0);
        // A second Initiate on an open connection: reason 2 as well.
        let sap = b.connect(2, 40, 300);
        assert_eq!(b.srd(2, 40, sap, &init), C2Answer::NotReady);
        let a = b.srd(2, 40, sap, &[]);
        assert_eq!(b.pdu(a), [0x58, 0x00, 0x12, 0x00]);
    }

    #[test]
    fn reservation_expires_and_same_master_restarts() {
        let mut b = Bus::new();
        let init = initiate_bytes(300, 2, 0);
        let rm = b.srd(2, 40, RM_SAP, &init);
        let sap = b.pdu(rm)[1];
        b.advance(1_000);
        b.c2.poll(b.now);
        assert_eq!(b.state(sap), ConnectionState::Closed);
        assert_eq!(b.c2.stats().reservations_expired, 1);
        assert_eq!(b.srd(2, 40, sap, &init), C2Answer::Status(ResponseStatus::Rs));
        // A master that starts over from the same SAP gets its connection back, not a second one.
        let first = b.connect(2, 40, 300);
        let again = b.connect(2, 40, 300);
        assert_eq!(first, again);
        assert_eq!(b.c2.stats().replaced, 1);
        assert_eq!(b.state(47), ConnectionState::Closed);
    }

    #[test]
    fn fetched_response_is_not_repeated_or_reexecuted() {
        let mut b = Bus::new();
        let sap = b.connect(2, 40, 300);
        let read = emit_req(Request::Read(ReadRequest { slot: 0, index: 0, length: 8 }));
        assert_eq!(b.transact(2, 40, sap, &read), [0x5E, 0, 0, 0]);
        assert_eq!(b.srd(2, 40, sap, &[]), C2Answer::NotReady);
        b.c2.process(b.now, &mut b.mem);
        assert_eq!(b.srd(2, 40, sap, &[]), C2Answer::NotReady);
        assert_eq!(b.mem.reads, 1);
        // The Initiate.res too: one poll fetches it, the next gets SC.
        let sap = b.connect(3, 41, 300);
        assert_eq!(b.srd(3, 41, sap, &[]), C2Answer::NotReady);
    }

    #[test]
    fn foreign_master_on_open_connection() {
        let mut b = Bus::new();
        let sap = b.connect(2, 40, 300);
        let read = emit_req(Request::Read(ReadRequest { slot: 0, index: 0, length: 8 }));
        assert_eq!(b.srd(5, 40, sap, &read), C2Answer::Status(ResponseStatus::Rs));
        assert_eq!(b.srd(5, 40, sap, &[0x58, 0, 0x20, 0]), C2Answer::Status(ResponseStatus::Rs));
        assert_eq!(b.send(0x0C, 2, None, sap, &read), C2Answer::Status(ResponseStatus::Rs));
        assert_eq!(b.c2.stats().foreign, 3);
        assert_eq!(b.transact(2, 40, sap, &read), [0x5E, 0, 0, 0]);
        // Reset closes everything.
        b.c2.reset();
        assert_eq!(b.srd(2, 40, sap, &read), C2Answer::Status(ResponseStatus::Rs));
    }

    #[derive(Debug, Clone)]
    enum Op {
        Frame {
            sdn: bool,
            master: u8,
            ssap: Option<u8>,
            dsap: u8,
            pdu: Vec<u8>,
        },
        /// RM + Initiate on the granted SAP (so that open connections are common).
        Connect {
            master: u8,
            ssap: u8,
            send_timeout: u16,
        },
        Process,
        Poll,
        Advance(u16),
    }

    fn arb_pdu() -> impl Strategy<Value = Vec<u8>> {
        prop_oneof![
            Just(vec![]),
            (any::<u16>(), 1u8..4, 0u8..2).prop_map(|(t, s, a)| initiate_bytes(t % 400, s, a)),
            (0u8..2, 0u8..6, 0u8..=241).prop_map(|(s, i, l)| vec![0x5E, s, i, l]),
            (0u8..6, proptest::collection::vec(any::<u8>(), 0..80)).prop_map(|(i, d)| {
                let mut v = vec![0x5F, 0, i, d.len() as u8];
                v.extend(d);
                v
            }),
            (0u8..6, proptest::collection::vec(any::<u8>(), 1..80)).prop_map(|(i, d)| {
                let mut v = vec![0x51, 0, i, d.len() as u8];
                v.extend(d);
                v
            }),
            Just(vec![0x48, 0]),
            Just(vec![0x58, 0, 0x20, 0]),
            Just(vec![0x5C, 1, 1, 0]),
            proptest::collection::vec(any::<u8>(), 0..40),
        ]
    }

    fn arb_op() -> impl Strategy<Value = Op> {
        prop_oneof![
            6 => (
                proptest::bool::weighted(0.1),
                1u8..5,
                prop_oneof![8 => (40u8..43).prop_map(Some), 1 => Just(None), 1 => (0u8..64).prop_map(Some)],
                prop_oneof![Just(49u8), Just(48), Just(47), Just(46), 0u8..64],
                arb_pdu()
            )
                .prop_map(|(sdn, master, ssap, dsap, pdu)| Op::Frame { sdn, master, ssap, dsap, pdu }),
            2 => (1u8..5, 40u8..43, 0u16..300).prop_map(|(master, ssap, send_timeout)| Op::Connect { master, ssap, send_timeout }),
            1 => Just(Op::Process),
            1 => Just(Op::Poll),
            1 => (0u16..3000).prop_map(Op::Advance),
        ]
    }

    proptest! {
        #[test]
        fn random_traffic_never_panics(ops in proptest::collection::vec(arb_op(), 1..120)) {
            let mut b = Bus::new();
            for op in ops {
                match op {
                    Op::Frame { sdn, master, ssap, dsap, pdu } => {
                        if !b.c2.owns_sap(dsap) {
                            continue;
                        }
                        let a = b.send(if sdn { 0x04 } else { 0x0C }, master, ssap, dsap, &pdu);
                        if sdn {
                            prop_assert_eq!(a, C2Answer::Silent);
                        }
                        if let C2Answer::Frame { id, len } = a {
                            prop_assert!(id <= 2);
                            prop_assert_eq!(b.c2.frame(id, len).len(), len as usize);
                        }
                    }
                    Op::Connect { master, ssap, send_timeout } => {
                        let init = initiate_bytes(send_timeout, 2, 0);
                        match b.srd(master, ssap, RM_SAP, &init) {
                            a @ C2Answer::Frame { .. } => {
                                let sap = b.pdu(a)[1];
                                prop_assert!(sap == 48 || sap == 47);
                                prop_assert_eq!(b.srd(master, ssap, sap, &init), C2Answer::NotReady);
                                prop_assert_eq!(b.state(sap), ConnectionState::Open);
                            }
                            a => prop_assert_eq!(a, C2Answer::Status(ResponseStatus::Rr)),
                        }
                    }
                    Op::Process => b.c2.process(b.now, &mut b.mem),
                    Op::Poll => b.c2.poll(b.now),
                    Op::Advance(ms) => b.advance(ms as u64),
                }
                for i in 0..2 {
                    let c = b.c2.connection(i).unwrap();
                    prop_assert_eq!(c.sap, 48 - i as u8);
                    if c.state == ConnectionState::Open {
                        prop_assert!(c.send_timeout >= DEFAULT_MIN_SEND_TIMEOUT);
                    }
                }
            }
        }
    }
}
