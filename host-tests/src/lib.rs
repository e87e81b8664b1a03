//! # host-tests — the pbcard slave core on a simulated PROFIBUS line, judged by a foreign master
//!
//! [`SimBus`] puts one DP master from the `profirust` crate (an implementation nobody on this
//! project wrote) and any number of [`SlaveEndpoint`]s — each one our
//! [`Framer`] → [`Station`] → [`DpSlave`] stack — on `profirust::phy::SimulatorPhy`, a
//! simulated RS485 line that moves 11-bit characters with the timing of the chosen rate and
//! **panics** when a station transmits while another one is still sending or before the
//! required idle time (11 bit times for a responder, 33 for the token holder).
//!
//! Time is simulated and deterministic: [`SimBus::step`] advances it by a fixed step of a few
//! bit times (at least 1 µs, the simulator's resolution), polls the master, then every slave
//! endpoint. A slave endpoint
//!
//! * reads the characters that completed on the line, feeds them to its [`Framer`] and tells
//!   the framer about idle line ([`Framer::idle`]) once the line has been silent for T_SYN;
//! * hands each complete frame to [`Station::on_frame`] and schedules the answer for the first
//!   step at least `DpSlave::min_tsdr()` bit times after the frame's last stop bit;
//! * asserts that the answer starts no later than [`card::max_tsdr`] — it panics with the
//!   recent bus trace otherwise (the upper bound used counts one step of uncertainty about
//!   when the request really ended, so the check is conservative);
//! * calls [`DpSlave::poll`] every step, collects [`Events`], and lets a [`SlaveApp`] (the
//!   simulated drive) react: [`EchoApp`] answers every output image with a transformed input
//!   image;
//! * can inject faults ([`Fault`]): drop or corrupt received frames or its own answers.
//!
//! The master can be paused ([`SimBus::set_master_paused`]) to let our DP watchdog expire.
//!
//! Each station is an [`Endpoint`] on its [`SimLine`] (receive, answer after min_TSDR, the
//! max_TSDR check, faults, trace): [`SlaveEndpoint`] holds the protocol parts above,
//! [`card_bus::CardEndpoint`] the shipped card (fast path, core, application with DPM and
//! simulated drive; `SimBus::cards`, judged in `tests/profirust_card.rs`).
//!
//! ## One-cycle lag of the input image
//!
//! Our slave answers Data_Exchange from a **pre-staged** frame: the answer to request *n*
//! carries the inputs staged before request *n* arrived. [`EchoApp`] stages
//! `transform(outputs_n)` right after request *n*, so the master receives
//! `transform(outputs_n)` in cycle *n + 1*. Tests check exactly that.

use std::collections::VecDeque;
use std::fmt::Write as _;

use pbcard::card;
use pbcard::dp::{DpSlave, DpState, Events};
use pbcard::fdl::framer::{Framer, Push};
use pbcard::fdl::station::Station;
use pbcard::fdl::telegram::{self, Decoded, RequestFunction, Telegram};
use pbcard::time::{Baudrate, BitTimes, Duration, Instant};
use profirust::dp::{DpMaster, Peripheral, PeripheralEvent, PeripheralHandle, PeripheralOptions};
use profirust::fdl::FdlActiveStation;
use profirust::phy::{ProfibusPhy, SimulatorPhy};

pub use pbcard;
pub use profirust;

pub mod c_host;
pub mod card_bus;
pub mod qemu;
pub mod scripted;
pub mod serial;

/// profirust's name for one of our rates.
pub fn profirust_rate(rate: Baudrate) -> profirust::Baudrate {
    use profirust::Baudrate as P;
    match rate {
        Baudrate::B12M => P::B12000000,
        Baudrate::B6M => P::B6000000,
        Baudrate::B3M => P::B3000000,
        Baudrate::B1500k => P::B1500000,
        Baudrate::B500k => P::B500000,
        Baudrate::B187500 => P::B187500,
        Baudrate::B93750 => P::B93750,
        Baudrate::B45450 => P::B45450,
        Baudrate::B19200 => P::B19200,
        Baudrate::B9600 => P::B9600,
    }
}

/// profirust's smallest slot time per rate (`ParametersBuilder::slot_bits` asserts it).
pub fn profirust_min_slot_bits(rate: Baudrate) -> u16 {
    match rate {
        Baudrate::B9600 | Baudrate::B19200 | Baudrate::B45450 | Baudrate::B93750 | Baudrate::B187500 => 100,
        Baudrate::B500k => 200,
        Baudrate::B1500k => 300,
        Baudrate::B3M => 400,
        Baudrate::B6M => 600,
        Baudrate::B12M => 1000,
    }
}

fn pr_instant(us: u64) -> profirust::time::Instant {
    profirust::time::Instant::from_micros(us as i64)
}

fn leak_name(s: String) -> &'static str {
    Box::leak(s.into_boxed_str())
}

fn leak_bytes(v: &[u8]) -> &'static [u8] {
    Box::leak(v.to_vec().into_boxed_slice())
}

/// Hex dump `10 02 08 49 53 16`.
pub fn hex(bytes: &[u8]) -> String {
    let mut s = String::with_capacity(bytes.len() * 3);
    for (i, b) in bytes.iter().enumerate() {
        if i > 0 {
            s.push(' ');
        }
        let _ = write!(s, "{b:02X}");
    }
    s
}

/// The data unit of a data telegram (`None` for token, SC or invalid bytes).
pub fn pdu_of(frame: &[u8]) -> Option<&[u8]> {
    match telegram::decode(frame) {
        Decoded::Frame(Telegram::Data(t), _) => Some(t.pdu),
        _ => None,
    }
}

/// Whether `frame` is a Data_Exchange request (SRD on the default SAP) addressed to `addr`.
pub fn is_data_exchange_request(frame: &[u8], addr: u8) -> bool {
    match telegram::decode(frame) {
        Decoded::Frame(Telegram::Data(t), _) => {
            t.da == addr
                && t.fc.is_request()
                && t.dsap.is_none()
                && matches!(t.fc.function(), RequestFunction::SrdLow | RequestFunction::SrdHigh)
        }
        _ => false,
    }
}

/// Whether `frame` is addressed to `addr` or broadcast (and is a data telegram).
fn addressed_to(frame: &[u8], addr: u8) -> bool {
    match telegram::decode(frame) {
        Decoded::Frame(Telegram::Data(t), _) => t.da == addr || t.da == telegram::BROADCAST,
        _ => false,
    }
}

// ---------------------------------------------------------------------------------------------
// Slave side
// ---------------------------------------------------------------------------------------------

/// One frame as a slave endpoint handled it (for [`SlaveApp::on_frame`]).
#[derive(Debug, Clone, Copy)]
pub struct FrameInfo<'a> {
    /// The request as received (after rx fault injection).
    pub request: &'a [u8],
    /// The answer the station produced (before tx fault injection), `None` when silent.
    pub response: Option<&'a [u8]>,
    /// The station answered it as an FCB retry (the DP layer was not called).
    pub retry: bool,
    /// It is a Data_Exchange request to this slave.
    pub data_exchange: bool,
}

/// The simulated device behind the DP slave (the drive application).
pub trait SlaveApp {
    /// After the station handled a frame addressed to this slave (or broadcast). Inputs set
    /// here are served with the **next** Data_Exchange (pre-staging).
    fn on_frame(&mut self, _now: Instant, _slave: &mut DpSlave, _frame: FrameInfo<'_>) {}
    /// Every step, after [`DpSlave::poll`] and [`DpSlave::take_events`].
    fn poll(&mut self, _now: Instant, _slave: &mut DpSlave, _events: Events) {}
}

/// A slave without application: inputs stay as they are.
#[derive(Debug, Default)]
pub struct NoApp;
impl SlaveApp for NoApp {}

/// The input image [`EchoApp`] answers to `outputs`, `len` bytes long: every byte depends on
/// the output bytes and on its position, so echo, shift and stale-data bugs all show.
pub fn transform(outputs: &[u8], len: usize) -> Vec<u8> {
    (0..len)
        .map(|i| {
            let o = if outputs.is_empty() { 0x5A } else { outputs[i % outputs.len()] };
            (!o).wrapping_add((i as u8).wrapping_mul(17))
        })
        .collect()
}

/// One Data_Exchange as [`EchoApp`] saw it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DxRecord {
    /// Simulated time (µs) the request completed.
    pub t_us: u64,
    /// [`DpSlave::outputs`] right after the request.
    pub outputs: Vec<u8>,
    /// The data unit of our answer (the inputs staged before this request).
    pub response_pdu: Vec<u8>,
    /// The inputs staged after this request (served with the next one).
    pub staged: Vec<u8>,
}

/// A drive that answers each output image with [`transform`]`(outputs)` and logs every
/// (non-retry) Data_Exchange.
#[derive(Debug, Default)]
pub struct EchoApp {
    /// Every Data_Exchange that reached the DP layer, in order.
    pub log: Vec<DxRecord>,
    /// Events seen (OR of all).
    pub events: Events,
}

impl SlaveApp for EchoApp {
    fn on_frame(&mut self, now: Instant, slave: &mut DpSlave, f: FrameInfo<'_>) {
        if !f.data_exchange || f.retry {
            return;
        }
        let outputs = slave.outputs().to_vec();
        let staged = transform(&outputs, slave.input_len());
        slave.set_inputs(&staged);
        self.log.push(DxRecord {
            t_us: now.as_micros(),
            outputs,
            response_pdu: f.response.and_then(pdu_of).map(<[u8]>::to_vec).unwrap_or_default(),
            staged,
        });
    }
    fn poll(&mut self, _now: Instant, _slave: &mut DpSlave, events: Events) {
        self.events |= events;
    }
}

/// What to do with a frame (fault injection).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fault {
    /// Pass it unchanged.
    Pass,
    /// Lose it: a received frame never reaches the station; an answer is not sent.
    Drop,
    /// XOR byte `index` with `xor`. A received frame reaches the station corrupted (it must
    /// reject it); an answer goes on the wire corrupted.
    Corrupt {
        /// byte index (clamped to the frame)
        index: usize,
        /// bit mask
        xor: u8,
    },
    /// Answers only: send this many bit times after the request's end instead of after
    /// min_TSDR (to prove the judges: too early panics in the simulator, later than max_TSDR
    /// in the harness).
    SendAfter(BitTimes),
}

/// Direction of a frame for a fault hook.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dir {
    /// A complete frame received by the slave endpoint (any frame on the line).
    Rx,
    /// An answer the slave endpoint is about to send.
    Tx,
}

/// A fault hook: `(direction, time in µs, frame) -> what to do`.
pub type FaultHook = Box<dyn FnMut(Dir, u64, &[u8]) -> Fault>;

/// One line of a bus trace.
#[derive(Debug, Clone)]
pub struct TraceEntry {
    /// Simulated time in µs.
    pub t_us: u64,
    /// What happened.
    pub what: String,
}

const TRACE_LEN: usize = 2000;
/// Trace entries shown in failure reports.
pub const TRACE_DUMP: usize = 80;

/// One station on the simulated line: what [`SimBus`] needs of it.
pub trait Endpoint {
    /// Its station address.
    fn address(&self) -> u8;
    /// One simulation step at `now_us`: line, protocol, timers, application; the DP events.
    fn poll(&mut self, now_us: u64) -> Events;
    /// Its DP state machine's state.
    fn dp_state(&self) -> DpState;
    /// Add a line to its trace.
    fn note(&mut self, t_us: u64, what: String);
    /// State, statistics and recent trace, for failure reports.
    fn report(&self) -> String;
}

/// What [`SimLine::receive`] saw in one step.
enum Rx {
    /// Nothing new (or our own answer still on the line).
    Nothing,
    /// The line has been idle for T_SYN or longer (reported once per idle period).
    Idle(BitTimes),
    /// Characters that completed since the last step.
    Bytes(Vec<u8>),
}

/// A slave's end of the simulated line: receive, answer after min_TSDR, the max_TSDR check,
/// fault injection and the trace — shared by [`SlaveEndpoint`] (the protocol parts) and
/// [`CardEndpoint`] (the shipped card).
pub struct SimLine {
    phy: SimulatorPhy,
    rate: Baudrate,
    step_us: u64,
    address: u8,
    fault: Option<FaultHook>,
    /// Answer waiting for min_TSDR: (bytes, due µs, request end µs).
    pending_tx: Option<(Vec<u8>, u64, u64)>,
    /// The min_TSDR the pending answer waits for (bit times).
    pending_min_tsdr: u32,
    /// End of the last character seen or sent (µs, step resolution).
    last_activity_us: u64,
    idle_reported: bool,
    transmitting: bool,
    rx_scratch: Vec<u8>,
    /// Answers sent, with the response delay upper bound (bit times) of each: min, max.
    pub tsdr_bits: Option<(u64, u64)>,
    /// Answers sent.
    pub answers: u64,
    /// Answers abandoned because the line became busy before min_TSDR had passed.
    pub answers_abandoned: u64,
    /// Recent frames and notes.
    pub trace: VecDeque<TraceEntry>,
}

impl SimLine {
    fn new(phy: SimulatorPhy, rate: Baudrate, step_us: u64, address: u8) -> Self {
        SimLine {
            phy,
            rate,
            step_us,
            address,
            fault: None,
            pending_tx: None,
            pending_min_tsdr: 0,
            last_activity_us: 0,
            idle_reported: false,
            transmitting: false,
            rx_scratch: Vec::with_capacity(512),
            tsdr_bits: None,
            answers: 0,
            answers_abandoned: 0,
            trace: VecDeque::with_capacity(TRACE_LEN),
        }
    }

    fn note(&mut self, t_us: u64, what: String) {
        if self.trace.len() == TRACE_LEN {
            self.trace.pop_front();
        }
        self.trace.push_back(TraceEntry { t_us, what });
    }

    /// The last `n` trace entries as text.
    fn dump_trace_last(&self, n: usize) -> String {
        let mut s = String::new();
        for e in self.trace.iter().skip(self.trace.len().saturating_sub(n)) {
            let _ = writeln!(s, "{:>12} µs  {}", e.t_us, e.what);
        }
        s
    }

    /// The characters that completed on the line since the last step (none while our own
    /// answer is on the line); a pending answer is abandoned when someone else talks first.
    fn receive(&mut self, now_us: u64) -> Rx {
        let pnow = pr_instant(now_us);
        self.transmitting = self.phy.poll_transmission(pnow);
        if self.transmitting {
            return Rx::Nothing;
        }
        let mut rx = std::mem::take(&mut self.rx_scratch);
        rx.clear();
        self.phy.receive_data(pnow, |buf| {
            rx.extend_from_slice(buf);
            (buf.len(), ())
        });
        if rx.is_empty() {
            self.rx_scratch = rx;
            let silent = self.rate.duration_to_bits(Duration::from_micros(now_us - self.last_activity_us));
            if !self.idle_reported && silent >= u64::from(BitTimes::TSYN.0) {
                self.idle_reported = true;
                return Rx::Idle(BitTimes(silent.min(u64::from(u32::MAX)) as u32));
            }
            return Rx::Nothing;
        }
        self.last_activity_us = now_us;
        self.idle_reported = false;
        if let Some((tx, _, _)) = self.pending_tx.take() {
            // Someone else started talking before our min_TSDR passed.
            self.answers_abandoned += 1;
            self.note(now_us, format!("ABANDONED answer {} (line busy)", hex(&tx)));
        }
        Rx::Bytes(rx)
    }

    /// The received-frame fault hook: `false` when the frame is to be dropped; it may corrupt
    /// `frame`.
    fn rx_fault(&mut self, now_us: u64, frame: &mut [u8]) -> bool {
        match self.fault.as_mut().map_or(Fault::Pass, |f| f(Dir::Rx, now_us, frame)) {
            Fault::Pass | Fault::SendAfter(_) => true,
            Fault::Drop => {
                self.note(now_us, "  (rx fault: frame dropped)".into());
                false
            }
            Fault::Corrupt { index, xor } => {
                let i = index.min(frame.len() - 1);
                frame[i] ^= xor;
                self.note(now_us, format!("  (rx fault: corrupted to {})", hex(frame)));
                true
            }
        }
    }

    /// Schedule `resp` for the first step `min_tsdr` bit times after the request that ended at
    /// `now_us` (the transmit fault hook may drop, corrupt or delay it).
    fn answer(&mut self, now_us: u64, mut resp: Vec<u8>, min_tsdr: BitTimes) {
        let mut delay = min_tsdr.0.max(BitTimes::MIN_TSDR_DEFAULT.0);
        match self.fault.as_mut().map_or(Fault::Pass, |f| f(Dir::Tx, now_us, &resp)) {
            Fault::Pass => {}
            Fault::SendAfter(bits) => {
                delay = bits.0;
                self.note(now_us, format!("  (tx fault: answer after {} bit times)", bits.0));
            }
            Fault::Drop => {
                self.note(now_us, format!("  (tx fault: answer {} dropped)", hex(&resp)));
                return;
            }
            Fault::Corrupt { index, xor } => {
                let i = index.min(resp.len() - 1);
                resp[i] ^= xor;
                self.note(now_us, "  (tx fault: answer corrupted)".into());
            }
        }
        let due = now_us + self.rate.bits_to_duration(delay).as_micros();
        // The judge's bound follows the slave's min_TSDR, not a fault's delay.
        self.pending_min_tsdr = min_tsdr.0.max(BitTimes::MIN_TSDR_DEFAULT.0);
        self.pending_tx = Some((resp, due, now_us));
    }

    /// A due answer goes on the line.
    fn send_due(&mut self, now_us: u64) {
        if self.transmitting {
            return;
        }
        if let Some((_, due, _)) = &self.pending_tx {
            if now_us >= *due {
                let (bytes, _, req_end) = self.pending_tx.take().unwrap();
                self.transmit(now_us, req_end, bytes);
            }
        }
    }

    fn transmit(&mut self, now_us: u64, req_end_us: u64, bytes: Vec<u8>) {
        // The request really ended somewhere in (req_end - step, req_end]: the delay upper bound
        // adds one step.
        let delay_us = now_us - req_end_us + self.step_us;
        let delay_bits = self.rate.duration_to_bits(Duration::from_micros(delay_us));
        // The latest start: the GSD's MaxTsdr — or min_TSDR when the master set it higher (the
        // slave may not answer before it; it then starts at min_TSDR, which the master's own
        // max_TSDR ≥ min_TSDR + 1 and slot time allow), plus the two steps of the simulation's
        // resolution (the due step and the bound's own step).
        let step_bits = self.rate.duration_to_bits(Duration::from_micros(self.step_us));
        let max = u64::from(card::max_tsdr(self.rate)).max(u64::from(self.pending_min_tsdr) + 2 * step_bits);
        if delay_bits > max {
            panic!(
                "slave #{} answered after up to {delay_bits} bit times > max_TSDR {max} at {:?}: {}\n{}",
                self.address,
                self.rate,
                hex(&bytes),
                self.dump_trace_last(TRACE_DUMP)
            );
        }
        let lo_bits = self.rate.duration_to_bits(Duration::from_micros(now_us - req_end_us));
        self.tsdr_bits = Some(match self.tsdr_bits {
            None => (lo_bits, delay_bits),
            Some((a, b)) => (a.min(lo_bits), b.max(delay_bits)),
        });
        self.note(now_us, format!("tx  {}   (tsdr {lo_bits}..{delay_bits} bits)", hex(&bytes)));
        let n = bytes.len();
        self.phy.transmit_data(pr_instant(now_us), |buf| {
            buf[..n].copy_from_slice(&bytes);
            (n, ())
        });
        self.answers += 1;
        self.last_activity_us = now_us + self.rate.bits_to_duration(11 * n as u32).as_micros();
        self.idle_reported = false;
    }
}

/// Our slave stack on one endpoint of the simulated line: the protocol parts (framer, FDL
/// station, DP slave) with a test application.
pub struct SlaveEndpoint<A: SlaveApp> {
    /// Its end of the line (answers, timing, trace).
    pub line: SimLine,
    /// The frame splitter (public for its statistics).
    pub framer: Framer,
    /// The FDL station (public for its statistics).
    pub station: Station,
    /// The DP slave under test.
    pub slave: DpSlave,
    /// The simulated device.
    pub app: A,
    /// Every non-empty [`Events`] with its time (µs).
    pub events: Vec<(u64, Events)>,
    /// OR of every event so far.
    pub events_seen: Events,
    last_state: DpState,
}

impl<A: SlaveApp> SlaveEndpoint<A> {
    fn new(line: SimLine, address: u8, app: A) -> Self {
        let slave = DpSlave::new(&card::SLAVE, address);
        let last_state = slave.state();
        SlaveEndpoint {
            line,
            framer: Framer::new(),
            station: Station::new(),
            slave,
            app,
            events: Vec::new(),
            events_seen: Events::empty(),
            last_state,
        }
    }

    /// Station address of the slave.
    pub fn address(&self) -> u8 {
        self.slave.address()
    }

    /// Install a fault hook (replaces any previous one).
    pub fn set_fault_hook(&mut self, hook: impl FnMut(Dir, u64, &[u8]) -> Fault + 'static) {
        self.line.fault = Some(Box::new(hook));
    }

    /// Remove the fault hook.
    pub fn clear_fault_hook(&mut self) {
        self.line.fault = None;
    }

    fn note(&mut self, t_us: u64, what: String) {
        self.line.note(t_us, what);
    }

    /// The recent trace as text (the last [`TRACE_DUMP`] entries).
    pub fn dump_trace(&self) -> String {
        self.dump_trace_last(TRACE_DUMP)
    }

    /// The last `n` trace entries as text.
    pub fn dump_trace_last(&self, n: usize) -> String {
        self.line.dump_trace_last(n)
    }

    fn poll(&mut self, now_us: u64) -> Events {
        let now = Instant::from_micros(now_us);
        match self.line.receive(now_us) {
            Rx::Nothing => {}
            Rx::Idle(bits) => self.framer.idle(bits),
            Rx::Bytes(rx) => {
                for &b in &rx {
                    match self.framer.push(b) {
                        Push::Pending => {}
                        Push::Dropped(e) => self.note(now_us, format!("framer dropped bytes: {e:?}")),
                        Push::Frame(_) => {
                            let frame = self.framer.frame().to_vec();
                            self.on_frame(now_us, now, frame);
                        }
                    }
                }
                self.line.rx_scratch = rx;
            }
        }
        self.line.send_due(now_us);

        // Timers and the application.
        self.slave.poll(now);
        let ev = self.slave.take_events();
        if !ev.is_empty() {
            self.events.push((now_us, ev));
            self.events_seen |= ev;
            self.note(now_us, format!("slave events {ev:?}"));
        }
        let st = self.slave.state();
        if st != self.last_state {
            self.note(now_us, format!("slave state {:?} -> {:?}", self.last_state, st));
            self.last_state = st;
        }
        self.app.poll(now, &mut self.slave, ev);
        ev
    }

    fn on_frame(&mut self, now_us: u64, now: Instant, mut frame: Vec<u8>) {
        let own = self.slave.address();
        let mine = addressed_to(&frame, own);
        if mine {
            self.note(now_us, format!("rx  {}", hex(&frame)));
        }
        if !self.line.rx_fault(now_us, &mut frame) {
            return;
        }
        let retries_before = self.station.stats().retries;
        let response = self.station.on_frame(now, &frame, &mut self.slave).map(<[u8]>::to_vec);
        let retry = self.station.stats().retries != retries_before;
        if mine {
            let dx = is_data_exchange_request(&frame, own);
            let info = FrameInfo { request: &frame, response: response.as_deref(), retry, data_exchange: dx };
            self.app.on_frame(now, &mut self.slave, info);
        } else if let Some(r) = &response {
            panic!(
                "slave #{own} answered a frame not addressed to it: {} -> {}\n{}",
                hex(&frame),
                hex(r),
                self.dump_trace()
            );
        }
        if let Some(resp) = response {
            self.line.answer(now_us, resp, self.slave.min_tsdr());
        }
    }
}

impl<A: SlaveApp> Endpoint for SlaveEndpoint<A> {
    fn address(&self) -> u8 {
        self.slave.address()
    }
    fn poll(&mut self, now_us: u64) -> Events {
        SlaveEndpoint::poll(self, now_us)
    }
    fn dp_state(&self) -> DpState {
        self.slave.state()
    }
    fn note(&mut self, t_us: u64, what: String) {
        self.line.note(t_us, what);
    }
    fn report(&self) -> String {
        format!(
            "slave #{}: state {:?}, master {:?}, events seen {:?}, framer {:?}, station {:?}, dp {:?}\n--- trace of #{} ---\n{}",
            self.address(),
            self.slave.state(),
            self.slave.master_address(),
            self.events_seen,
            self.framer.stats(),
            self.station.stats(),
            self.slave.stats(),
            self.address(),
            self.dump_trace()
        )
    }
}

// ---------------------------------------------------------------------------------------------
// Master side
// ---------------------------------------------------------------------------------------------

/// How the profirust master is set up.
#[derive(Debug, Clone)]
pub struct MasterConfig {
    /// Master station address (default 2).
    pub address: u8,
    /// Transmission rate.
    pub rate: Baudrate,
    /// Slot time; `None` = generous: max(profirust minimum, 2 × max_TSDR + 100).
    pub slot_bits: Option<u16>,
    /// Retries before a peripheral is considered offline (profirust: 1..=15, default here 1).
    pub max_retry_limit: u8,
    /// DP watchdog sent in Set_Prm (WD_On); `None` = off. profirust needs ≥ 10 ms.
    pub watchdog_ms: Option<u64>,
    /// Highest station address for the GAP poll; `None` = highest slave address + 1, so our
    /// slaves are FDL_Status-polled too.
    pub hsa: Option<u8>,
    /// Simulation step in bit times (rounded up to whole µs; default 2).
    pub step_bits: u32,
    /// min_TSDR the master puts in Set_Prm (`None` = profirust's default, 11).
    pub min_tsdr_bits: Option<u8>,
}

impl MasterConfig {
    /// Master #2 at `rate`, watchdog off, one retry.
    pub fn new(rate: Baudrate) -> Self {
        MasterConfig {
            address: 2,
            rate,
            slot_bits: None,
            max_retry_limit: 1,
            watchdog_ms: None,
            hsa: None,
            step_bits: 2,
            min_tsdr_bits: None,
        }
    }
    /// With the DP watchdog on.
    pub fn watchdog_ms(mut self, ms: u64) -> Self {
        self.watchdog_ms = Some(ms);
        self
    }
    /// With `n` retries.
    pub fn retries(mut self, n: u8) -> Self {
        self.max_retry_limit = n;
        self
    }
    /// The slot time this configuration gives.
    pub fn effective_slot_bits(&self) -> u16 {
        self.slot_bits.unwrap_or_else(|| profirust_min_slot_bits(self.rate).max(2 * card::max_tsdr(self.rate) + 100))
    }
}

/// One peripheral (slave) as the master is configured for it.
#[derive(Debug, Clone)]
pub struct PeripheralConfig {
    /// Slave address.
    pub address: u8,
    /// Ident number sent in Set_Prm.
    pub ident: u16,
    /// User_Prm_Data after the 7 standard Set_Prm octets.
    pub user_prm: Vec<u8>,
    /// Chk_Cfg data.
    pub cfg: Vec<u8>,
    /// Input bytes (PI_I length).
    pub inputs: usize,
    /// Output bytes (PI_Q length).
    pub outputs: usize,
    /// max_TSDR the master assumes (checked against the slot time by profirust).
    pub max_tsdr: u16,
    /// Extended diagnosis buffer (0 = none).
    pub diag_buffer: usize,
    /// Set_Prm Sync_Req.
    pub sync_mode: bool,
    /// Set_Prm Freeze_Req.
    pub freeze_mode: bool,
    /// Set_Prm Group_Ident.
    pub groups: u8,
    /// Fail-safe flag (profirust uses it in Clear, which it does not implement in 0.6).
    pub fail_safe: bool,
}

impl PeripheralConfig {
    /// The card with `module`, ident [`card::IDENT_NUMBER`], default user parameters and a
    /// diagnosis buffer of [`card::MAX_DIAG_DATA_LEN`].
    pub fn card(address: u8, module: &card::Module, rate: Baudrate) -> Self {
        PeripheralConfig {
            address,
            ident: card::IDENT_NUMBER,
            user_prm: card::USER_PRM_DEFAULTS.to_vec(),
            cfg: module.cfg.to_vec(),
            inputs: module.inputs as usize,
            outputs: module.outputs as usize,
            max_tsdr: card::max_tsdr(rate),
            diag_buffer: card::MAX_DIAG_DATA_LEN,
            sync_mode: false,
            freeze_mode: false,
            groups: 0,
            fail_safe: card::FAIL_SAFE,
        }
    }
}

/// What one [`SimBus::step`] produced.
#[derive(Debug, Clone, Default)]
pub struct StepReport {
    /// The master completed a DP cycle over all peripherals.
    pub cycle_completed: bool,
    /// A peripheral event of the master: (slave address, event).
    pub master_event: Option<(u8, PeripheralEvent)>,
    /// Non-empty slave events: (slave address, events).
    pub slave_events: Vec<(u8, Events)>,
}

/// A master event with its time.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MasterEvent {
    /// Simulated time in µs.
    pub t_us: u64,
    /// Peripheral address.
    pub address: u8,
    /// The event.
    pub event: PeripheralEvent,
}

/// One data-exchange cycle as the master saw it ([`SimBus::exchange`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CycleRecord {
    /// Simulated time in µs of the DataExchanged event.
    pub t_us: u64,
    /// PI_Q sent in this cycle.
    pub q_sent: Vec<u8>,
    /// PI_I received in this cycle.
    pub i_received: Vec<u8>,
}

/// The profirust master and our slaves on one simulated line.
pub struct SimBus<E: Endpoint> {
    rate: Baudrate,
    now_us: u64,
    step_us: u64,
    master_phy: SimulatorPhy,
    fdl: FdlActiveStation,
    dp: DpMaster<'static>,
    handles: Vec<(u8, PeripheralHandle)>,
    /// The slave endpoints, in the order given.
    pub slaves: Vec<E>,
    master_paused: bool,
    /// Every peripheral event of the master.
    pub master_events: Vec<MasterEvent>,
    /// DP cycles the master completed.
    pub cycles: u64,
    /// Steps taken.
    pub steps: u64,
}

impl<A: SlaveApp> SimBus<SlaveEndpoint<A>> {
    /// Build the line: the master with its peripherals, and one slave endpoint (the protocol
    /// parts with a test application) per `(address, app)`. The master is online and in
    /// Operate.
    pub fn new(master: MasterConfig, peripherals: &[PeripheralConfig], slaves: Vec<(u8, A)>) -> Self {
        let addresses: Vec<u8> = slaves.iter().map(|(a, _)| *a).collect();
        let mut apps = slaves.into_iter();
        SimBus::with_endpoints(master, peripherals, &addresses, |line, addr| {
            let (_, app) = apps.next().expect("one app per address");
            SlaveEndpoint::new(line, addr, app)
        })
    }
}

impl<E: Endpoint> SimBus<E> {
    /// Build the line: the master with its peripherals, and one endpoint per address, made by
    /// `make(line, address)` on its own end of the line. The master is online and in Operate.
    pub fn with_endpoints(
        master: MasterConfig,
        peripherals: &[PeripheralConfig],
        addresses: &[u8],
        mut make: impl FnMut(SimLine, u8) -> E,
    ) -> Self {
        let rate = master.rate;
        let prate = profirust_rate(rate);
        let step_us = rate.bits_to_duration(master.step_bits.max(1)).as_micros().max(1);
        let master_phy = SimulatorPhy::new(prate, "master");

        let mut dp = DpMaster::new(Vec::new());
        let mut handles = Vec::new();
        for p in peripherals {
            let options = PeripheralOptions {
                ident_number: p.ident,
                sync_mode: p.sync_mode,
                freeze_mode: p.freeze_mode,
                groups: p.groups,
                max_tsdr: p.max_tsdr,
                fail_safe: p.fail_safe,
                user_parameters: Some(leak_bytes(&p.user_prm)),
                config: Some(leak_bytes(&p.cfg)),
            };
            let mut per = Peripheral::new(p.address, options, vec![0u8; p.inputs], vec![0u8; p.outputs]);
            if p.diag_buffer > 0 {
                per = per.with_diag_buffer(vec![0u8; p.diag_buffer]);
            }
            handles.push((p.address, dp.add(per)));
        }

        let max_slave = addresses.iter().copied().chain(peripherals.iter().map(|p| p.address)).max().unwrap_or(0);
        let hsa = master.hsa.unwrap_or_else(|| (max_slave + 1).clamp(master.address + 1, 126));
        let mut builder = profirust::fdl::ParametersBuilder::new(master.address, prate);
        builder
            .slot_bits(master.effective_slot_bits())
            .max_retry_limit(master.max_retry_limit)
            .highest_station_address(hsa);
        if let Some(bits) = master.min_tsdr_bits {
            builder.min_tsdr(bits);
        }
        if let Some(ms) = master.watchdog_ms {
            builder.watchdog_timeout(profirust::time::Duration::from_millis(ms));
        }
        let mut fdl = FdlActiveStation::new(builder.build_verified(&dp));
        fdl.set_online();
        dp.enter_operate();

        let slaves = addresses
            .iter()
            .map(|&addr| {
                let phy = master_phy.duplicate(leak_name(format!("slave#{addr}")));
                make(SimLine::new(phy, rate, step_us, addr), addr)
            })
            .collect();

        SimBus {
            rate,
            now_us: 0,
            step_us,
            master_phy,
            fdl,
            dp,
            handles,
            slaves,
            master_paused: false,
            master_events: Vec::new(),
            cycles: 0,
            steps: 0,
        }
    }

    /// The rate of the line.
    pub fn rate(&self) -> Baudrate {
        self.rate
    }
    /// Simulated time in µs.
    pub fn now_us(&self) -> u64 {
        self.now_us
    }
    /// Simulation step in µs.
    pub fn step_us(&self) -> u64 {
        self.step_us
    }
    /// profirust's FDL parameters in force.
    pub fn fdl_parameters(&self) -> &profirust::fdl::Parameters {
        self.fdl.parameters()
    }

    /// Stop (`true`) or resume (`false`) polling the master: the line falls silent while the
    /// slaves keep running their timers.
    pub fn set_master_paused(&mut self, paused: bool) {
        self.master_paused = paused;
    }

    /// The master's view of the peripheral at `addr`.
    pub fn peripheral(&mut self, addr: u8) -> &mut Peripheral<'static> {
        let h = self.handles.iter().find(|(a, _)| *a == addr).expect("no peripheral at that address").1;
        self.dp.get_mut(h)
    }

    /// The slave endpoint at `addr`.
    pub fn slave(&mut self, addr: u8) -> &mut E {
        self.slaves.iter_mut().find(|s| s.address() == addr).expect("no slave at that address")
    }

    /// Master events for `addr`, in order.
    pub fn events_for(&self, addr: u8) -> Vec<PeripheralEvent> {
        self.master_events.iter().filter(|e| e.address == addr).map(|e| e.event).collect()
    }

    /// Advance simulated time by one step: master poll, then every slave endpoint.
    pub fn step(&mut self) -> StepReport {
        self.now_us += self.step_us;
        self.steps += 1;
        let now = pr_instant(self.now_us);
        self.master_phy.set_bus_time(now);
        let mut report = StepReport::default();
        if !self.master_paused {
            self.fdl.poll(now, &mut self.master_phy, &mut self.dp);
            let ev = self.dp.take_last_events();
            if ev.cycle_completed {
                self.cycles += 1;
                report.cycle_completed = true;
            }
            if let Some((h, e)) = ev.peripheral {
                let address = self.dp.get_mut(h).address();
                self.master_events.push(MasterEvent { t_us: self.now_us, address, event: e });
                report.master_event = Some((address, e));
                for s in self.slaves.iter_mut().filter(|s| s.address() == address) {
                    s.note(self.now_us, format!("MASTER EVENT {e:?}"));
                }
            }
        }
        for s in &mut self.slaves {
            let ev = s.poll(self.now_us);
            if !ev.is_empty() {
                report.slave_events.push((s.address(), ev));
            }
        }
        report
    }

    /// Step until `done` returns true or `limit` of simulated time has passed; returns whether
    /// `done` was reached.
    pub fn run_until(&mut self, limit: Duration, mut done: impl FnMut(&mut Self, &StepReport) -> bool) -> bool {
        let end = self.now_us + limit.as_micros();
        while self.now_us < end {
            let r = self.step();
            if done(self, &r) {
                return true;
            }
        }
        false
    }

    /// Like [`run_until`](Self::run_until), but panics with `what` and the traces on timeout.
    pub fn expect_until(&mut self, limit: Duration, what: &str, done: impl FnMut(&mut Self, &StepReport) -> bool) {
        if !self.run_until(limit, done) {
            panic!("timeout after {} ms waiting for: {what}\n{}", limit.as_millis(), self.report());
        }
    }

    /// Step for `d` of simulated time.
    pub fn run_for(&mut self, d: Duration) {
        let _ = self.run_until(d, |_, _| false);
    }

    /// Run until the master reports `event` for `addr`; panics with the traces on timeout.
    pub fn expect_event(&mut self, addr: u8, event: PeripheralEvent, limit: Duration) {
        self.expect_until(limit, &format!("{event:?} for #{addr}"), |_, r| r.master_event == Some((addr, event)));
    }

    /// Run until the master has exchanged data with `addr` and the slave is in DataExch.
    pub fn bring_up(&mut self, addr: u8, limit: Duration) {
        self.expect_until(limit, &format!("data exchange with #{addr}"), |bus, r| {
            matches!(r.master_event, Some((a, PeripheralEvent::DataExchanged)) if a == addr)
                && bus.slaves.iter().any(|s| s.address() == addr && s.dp_state() == DpState::DataExch)
        });
    }

    /// Exchange data with `addr` for `cycles` cycles: before each cycle *k* the master's PI_Q
    /// is set to `outputs(k)`; each DataExchanged event records (PI_Q sent, PI_I received).
    /// PI_Q is only changed right after a DataExchanged event (first after one warm-up
    /// cycle), so the next Data_Exchange certainly carries it. Returns on the event of the
    /// last cycle, before the master sends anything else: the slave's last Data_Exchange is the
    /// last recorded cycle. Data_Exchange retries (same FCB) do not count as cycles.
    pub fn exchange(
        &mut self,
        addr: u8,
        cycles: usize,
        limit: Duration,
        mut outputs: impl FnMut(usize) -> Vec<u8>,
    ) -> Vec<CycleRecord> {
        self.expect_until(
            limit,
            "warm-up data exchange",
            |_, r| matches!(r.master_event, Some((a, PeripheralEvent::DataExchanged)) if a == addr),
        );
        let mut current = outputs(0);
        self.peripheral(addr).pi_q_mut().copy_from_slice(&current);
        let mut log = Vec::with_capacity(cycles);
        let ok = self.run_until(limit, |bus, r| {
            if matches!(r.master_event, Some((a, PeripheralEvent::DataExchanged)) if a == addr) {
                let now = bus.now_us;
                let p = bus.peripheral(addr);
                log.push(CycleRecord { t_us: now, q_sent: current.clone(), i_received: p.pi_i().to_vec() });
                if log.len() == cycles {
                    return true;
                }
                current = outputs(log.len());
                p.pi_q_mut().copy_from_slice(&current);
            }
            false
        });
        if !ok {
            panic!(
                "timeout after {} ms: only {} of {cycles} cycles with #{addr}\n{}",
                limit.as_millis(),
                log.len(),
                self.report()
            );
        }
        log
    }

    /// Master events, slave states and the recent trace of every slave, as text.
    pub fn report(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "t = {} µs, rate {:?}, step {} µs, {} cycles, master events: {:?}",
            self.now_us,
            self.rate,
            self.step_us,
            self.cycles,
            self.master_events.iter().map(|e| (e.t_us, e.address, e.event)).collect::<Vec<_>>()
        );
        for sl in &self.slaves {
            let _ = writeln!(s, "{}", sl.report());
        }
        s
    }
}
