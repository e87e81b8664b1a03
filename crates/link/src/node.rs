//! One PROFIBUS slave node as every platform runs it: [`Framer`] → [`Station`] → [`DpSlave`]
//! and the DP-V1 services ([`C1`], [`C2`]) with the I&M records in front of the application's
//! data records ([`DataRecords`]).
//!
//! The board firmware, the QEMU build, the soft slave and the host tests all drive the
//! protocol core through this one type, so the same code decides on every platform. The
//! platform only moves bytes and time: [`Node::on_byte`] for each received character (the
//! response it returns goes on the wire after [`Node::min_tsdr`]), [`Node::on_line_error`]
//! for a character with a parity/framing/noise/overrun error, [`Node::on_idle`] when the line
//! was idle, and [`Node::poll`] for the timers. DP-V1 requests are acknowledged on the
//! decision path and worked on by [`Node::process_acyclic`] (the middle-priority task of the
//! firmware) over the data records the application owns and passes in (the way smoltcp's
//! `Interface::poll` takes the application's sockets): the node keeps no profile state; the
//! card's composition passes the PROFIdrive records 47 / 48 (`profile::records::CardRecords`
//! bound to the drive's parameter table).

use crate::dp::{DpSlave, Events, Module};
use crate::dpv1::c1::{self, C1};
use crate::dpv1::c2::{C2Answer, C2};
use crate::dpv1::channel::Answer;
use crate::dpv1::im::{Im, ImDevice};
use crate::dpv1::records::{relation_c2, NoRecords, RecordHandler, RELATION_C1};
use crate::fdl::framer::{Framer, Push};
use crate::fdl::station::{FdlApplication, Reply, Station, Tx};
use crate::fdl::telegram::{DataTelegram, RequestFunction, ResponseStatus};
use crate::phy::line::{classify, RateControl};
use crate::time::{Baudrate, BitTimes, Instant};

/// A slave node: framer, FDL station and DP slave.
#[derive(Debug, Clone)]
pub struct Node {
    framer: Framer,
    station: Station,
    slave: DpSlave,
    c1: C1,
    c2: C2<C2_CHANNELS>,
    /// I&M0–I&M4 at slot 0 / index 255, in front of the application's [`DataRecords`].
    im: Im,
    baudrate: Option<Baudrate>,
    /// [`DataRecords::is_busy`] of the records the last [`Node::process_acyclic`] served (a
    /// job's state changes only there), for [`Node::has_acyclic_work`].
    records_busy: bool,
}

/// What the node knows of the station when [`Node::process_acyclic`] starts: the context a
/// data record may depend on (the card's PNUs 918, 922, 963 …).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StationInfo {
    /// The station address (Set_Slave_Add / the stored one).
    pub address: u8,
    /// The module the drive selected ([`DpSlave::required_module`]; Chk_Cfg can only select
    /// it), else the module of the last Chk_Cfg ([`DpSlave::module`]); `None` before any.
    pub module: Option<&'static Module>,
    /// The rate the platform listens at ([`Node::set_baudrate`]; `None` while searching).
    pub baudrate: Option<Baudrate>,
}

/// The application's DP-V1 data records as [`Node::process_acyclic`] serves them: the
/// DP-V1 services Read (DS_Read, function 0x5E) and Write (DS_Write, 0x5F) of a data record
/// addressed by slot and index over MSAC_C1 and MSAC_C2 (IEC 61158-6 DP-V1; reference §4.2).
/// A failed access returns its Error_Code_1 ([`ErrorCode1`](crate::dpv1::pdu::ErrorCode1), class | code, e.g. 0xB0 invalid
/// index, 0xB2 invalid slot, 0xB5 state conflict, 0xC2 resource busy); the channel answers it
/// as the error PDU `function | 0x80, Error_Decode 0x80 (DP-V1), Error_Code_1, Error_Code_2 0`.
///
/// The node serves I&M (slot 0 / index 255, [`Im`]) itself and hands every other access to
/// these records ([`RecordHandler::read`] / [`RecordHandler::write`], with
/// [`RecordHandler::set_relation`] before the accesses of each relation). The application owns
/// them and passes them to every [`Node::process_acyclic`] call (the card: PROFIdrive records
/// 47 / 48 over its PNUs and the drive's parameters, `profile::records::CardRecords`);
/// [`NoRecords`] answers every access 0xB2.
pub trait DataRecords: RecordHandler {
    /// Before the waiting requests of one [`Node::process_acyclic`] are served (only when
    /// there is work): the station's context, and the time to go on with a job that waits
    /// for values ([`is_busy`](Self::is_busy)). Default: nothing.
    fn begin(&mut self, now: Instant, station: &StationInfo) {
        let _ = (now, station);
    }

    /// The application relation `relation` ended ([`RELATION_C1`]: MSAC_C1 left data
    /// exchange; [`relation_c2`]`(n)`: MSAC_C2 connection n was aborted or timed out): forget
    /// its per-relation state before a request of a new relation is served. Default: nothing.
    fn end_relation(&mut self, relation: u8) {
        let _ = relation;
    }

    /// Whether a job waits without a request (a record whose values an asynchronous table has
    /// not delivered yet): the node reports work ([`Node::has_acyclic_work`]) until it is
    /// done. Default: never.
    fn is_busy(&self) -> bool {
        false
    }
}

impl DataRecords for NoRecords {}

/// The MSAC_C2 connections a node keeps (GSD `C2_Max_Count_Channels`, which the card states as
/// `pbcard::card::C2_MAX_COUNT_CHANNELS`, checked equal at compile time): one MSAC_C2 SAP, timer and
/// I&M / record relation each.
pub const C2_CHANNELS: usize = 2;

/// Frame id of the MSAC_C1 response (the DP slave uses ids below it).
const C1_FRAME: u8 = 8;
/// Frame ids of MSAC_C2 start here.
const C2_FRAMES: u8 = 16;

/// Routes each request to the DP slave or to the DP-V1 services by its DSAP.
struct Router<'a> {
    dp: &'a mut DpSlave,
    c1: &'a mut C1,
    c2: &'a mut C2<C2_CHANNELS>,
    /// False: the fast path already answered this DP-V1 frame with SC (hand out nothing).
    deliver: bool,
}

impl FdlApplication for Router<'_> {
    fn address(&self) -> u8 {
        self.dp.address()
    }

    fn on_request(&mut self, now: Instant, req: &DataTelegram<'_>) -> Reply {
        match req.dsap {
            // MSAC_C1 is SRD only: an SDN (or a broadcast) on SAP 51 is no request and must not
            // replace or consume one.
            Some(c1::SAP) if !matches!(req.fc.function(), RequestFunction::SrdLow | RequestFunction::SrdHigh) => {
                Reply::Silent
            }
            Some(c1::SAP) => {
                // Any request of the locking master keeps the DP watchdog running.
                self.dp.on_retry(now, req);
                match self.c1.on_request_as(req, self.dp, self.deliver) {
                    None => Reply::Status(ResponseStatus::Rs),
                    Some(Answer::NotReady) => Reply::ShortAck,
                    Some(Answer::Frame(len)) => Reply::Frame { id: C1_FRAME, len },
                }
            }
            // MSAC_C2: independent of the cyclic state and of the master lock.
            Some(sap) if self.c2.owns_sap(sap) => {
                match self.c2.on_request_as(now, self.dp.address(), req, self.deliver) {
                    C2Answer::Frame { id, len } => Reply::Frame { id: C2_FRAMES + id, len },
                    other => other.into(),
                }
            }
            _ => {
                let reply = self.dp.on_request(now, req);
                // A DP service may have ended the MSAC_C1 session (Set_Prm, Chk_Cfg).
                self.c1.track(self.dp);
                reply
            }
        }
    }

    fn on_retry(&mut self, now: Instant, req: &DataTelegram<'_>) {
        self.dp.on_retry(now, req);
    }

    fn frame(&self, id: u8, len: u16) -> &[u8] {
        frame_of(self.dp, self.c1, self.c2, id, len)
    }
}

fn frame_of<'a>(dp: &'a DpSlave, c1: &'a C1, c2: &'a C2<C2_CHANNELS>, id: u8, len: u16) -> &'a [u8] {
    match id {
        C1_FRAME => c1.frame(len),
        id if id >= C2_FRAMES => c2.frame(id - C2_FRAMES, len),
        id => dp.frame(id, len),
    }
}

impl Node {
    /// A node over `slave` (see [`DpSlave::with_address_lock`] for a stored address) for the
    /// product `device` (its I&M0 values, [`ImDevice`]) whose MSAC_C2 Initiate.res carries
    /// `profile_ident_number` (the GSD's application profile, reference §4.5). The card's
    /// `pbcard::card::node(slave)` (the product's configuration) passes its own.
    ///
    /// Out of line: builds a large value in place (inlined into the start, every store needs its own stack address; footprint, issue 13 item 1).
    #[inline(never)]
    pub const fn with_device(slave: DpSlave, device: &'static ImDevice, profile_ident_number: u16) -> Self {
        Node {
            framer: Framer::new(),
            station: Station::new(),
            slave,
            c1: C1::new(),
            c2: C2::new(profile_ident_number),
            im: Im::new(device),
            baudrate: None,
            records_busy: false,
        }
    }

    /// One received character; returns the response to send (after min_TSDR) when it
    /// completed a request that must be answered.
    pub fn on_byte(&mut self, now: Instant, byte: u8) -> Option<&[u8]> {
        match self.framer.push(byte) {
            Push::Frame(_) => {
                let mut router = Router { dp: &mut self.slave, c1: &mut self.c1, c2: &mut self.c2, deliver: true };
                let tx = self.station.decide(now, self.framer.frame(), &mut router)?;
                self.track_relations();
                Some(self.bytes(tx))
            }
            Push::Pending | Push::Dropped(_) => None,
        }
    }

    /// A whole received telegram at once (a DMA receiver that delimited it itself).
    pub fn on_frame(&mut self, now: Instant, frame: &[u8]) -> Option<&[u8]> {
        self.on_frame_as(now, frame, true)
    }

    /// [`on_frame`](Self::on_frame) for a telegram the fast path ([`crate::fast`]) already
    /// answered: `deliver` false when it answered a DP-V1 request or poll with SC ("not
    /// ready"), so the MSAC_C1 / MSAC_C2 channel keeps a response that became ready meanwhile
    /// (or a pending Abort PDU) for the master's next poll instead of spending it on this
    /// frame — a response is never lost.
    pub fn on_frame_as(&mut self, now: Instant, frame: &[u8], deliver: bool) -> Option<&[u8]> {
        let mut router = Router { dp: &mut self.slave, c1: &mut self.c1, c2: &mut self.c2, deliver };
        let tx = self.station.decide(now, frame, &mut router)?;
        self.track_relations();
        Some(self.bytes(tx))
    }

    /// Forget the I&M call of a relation that ended (MSAC_C1 closed with data exchange, an
    /// MSAC_C2 connection no longer open).
    #[inline(never)]
    fn track_relations(&mut self) {
        if !C1::is_open(&self.slave) {
            self.im.end_relation(RELATION_C1);
        }
        for n in 0..C2_CHANNELS {
            if self.c2.connection(n).is_none_or(|c| c.state != crate::dpv1::c2::ConnectionState::Open) {
                self.im.end_relation(relation_c2(n));
            }
        }
    }

    /// The I&M function (I&M0–I&M4, [`crate::dpv1::im`]): load the stored I&M1–4 at boot
    /// ([`Im::set_data`]), give it the drive's identity ([`Im::set_ident`]), and persist what
    /// [`Im::take_changed`] returns.
    pub fn im_mut(&mut self) -> &mut Im {
        &mut self.im
    }
    /// The I&M function.
    pub fn im(&self) -> &Im {
        &self.im
    }

    fn bytes(&self, tx: Tx) -> &[u8] {
        let (dp, c1, c2) = (&self.slave, &self.c1, &self.c2);
        self.station.bytes(tx, |id, len| frame_of(dp, c1, c2, id, len))
    }

    /// The rate the platform listens at (`None` while searching): PNU 963.
    pub fn set_baudrate(&mut self, rate: Option<Baudrate>) {
        self.baudrate = rate;
    }

    /// Whether a DP-V1 request waits for [`process_acyclic`](Self::process_acyclic), or a job
    /// of the data records it served last ([`DataRecords::is_busy`], e.g. a record-47 job for
    /// the drive's values; call it again then).
    pub fn has_acyclic_work(&self) -> bool {
        self.c1.has_pending() || self.c2.has_pending() || self.records_busy
    }

    /// Work on waiting DP-V1 requests (DS_Read / DS_Write of data records over MSAC_C1 and
    /// MSAC_C2): I&M at slot 0 / index 255, every other record from the application's
    /// `records` ([`DataRecords`]; the card: PROFIdrive record 47 and WEG record 48 at slots 0
    /// and 1 over the card's own PNUs in front of the drive's parameters). The response is
    /// handed out at the master's next poll. A job the records report busy
    /// ([`DataRecords::is_busy`], a record-47 job whose values an asynchronous table has not
    /// delivered yet) keeps [`has_acyclic_work`](Self::has_acyclic_work) true; it is taken up
    /// again ([`DataRecords::begin`]) on every call until it is complete.
    pub fn process_acyclic(&mut self, now: Instant, records: &mut impl DataRecords) {
        self.end_relations(records);
        let work = self.c1.has_pending() || self.c2.has_pending() || records.is_busy();
        if work {
            let station = StationInfo {
                address: self.slave.address(),
                module: self.slave.required_module().or(self.slave.module()),
                baudrate: self.baudrate,
            };
            records.begin(now, &station);
            self.track_relations();
            let mut records = self.im.with(records);
            self.c1.process(now, &mut self.slave, &mut records);
            self.c2.process(now, &mut records);
        }
        self.records_busy = records.is_busy();
    }

    /// Forget the record state of every relation that ended since the last call (before any
    /// request of a new relation is served).
    fn end_relations(&mut self, records: &mut impl DataRecords) {
        if self.c1.take_ended() {
            records.end_relation(RELATION_C1);
        }
        let mut ended = self.c2.take_ended();
        while ended != 0 {
            let i = ended.trailing_zeros() as usize;
            ended &= ended - 1;
            records.end_relation(relation_c2(i));
        }
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
        self.c1.track(&self.slave);
        self.c2.poll(now);
        self.track_relations();
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
    /// The MSAC_C1 service (state, the ready response).
    pub fn c1(&self) -> &C1 {
        &self.c1
    }
    /// The MSAC_C2 connections (states, timers, ready responses).
    pub fn c2(&self) -> &C2<C2_CHANNELS> {
        &self.c2
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

/// The decision for one telegram the line delimited in one task, as the F411 firmware's decision
/// task ran it before the split (moved here from `phy::line`, which no longer names the node:
/// the line is below it; the split F411 does the same with `fast::FastPath` and
/// `phy::rate_link`, whose gate mirrors the rate check here): the node decides ([`Node::on_frame`]: no answer for other stations, broadcasts,
/// tokens, corrupt frames); an answered request is a valid SD1/SD2/SD3 telegram to us, which
/// locks the search and retriggers Baud_Control; every other telegram is classified for the
/// rate control ([`crate::phy::line::classify`]). The answer is returned only while the rate is locked — the
/// driver sends exactly that, after min_TSDR ([`crate::phy::line::tx_plan`]).
pub fn answer<'n>(node: &'n mut Node, rate: &mut impl RateControl, now: Instant, frame: &[u8]) -> Option<&'n [u8]> {
    let own = node.slave().address();
    match node.on_frame(now, frame) {
        Some(resp) => {
            rate.on_frame(now, true, true);
            rate.detected().map(|_| resp)
        }
        None => {
            let c = classify(frame, own);
            if c.invalid {
                rate.on_garbage(now);
            } else {
                rate.on_frame(now, c.ok_sd123, c.to_us);
            }
            None
        }
    }
}
