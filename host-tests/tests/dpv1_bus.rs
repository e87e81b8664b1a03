//! Our own class-1 and class-2 DP-V1 test master on profirust's simulated line (no profirust
//! master): the slave is a whole [`Node`] with the simulated drive ([`Application`]) behind the
//! DPM, so drive parameters go through the DPM mailbox. Time is simulated in 1 µs steps.
//!
//! * The slave answers after min_TSDR bit times of idle line after the request's last stop bit
//!   (the simulator panics on an early transmitter); the master measures on the line when each
//!   answer starts and asserts min_TSDR ≤ delay ≤ [`card::max_tsdr`].
//! * The master leaves at least T_SYN (33 bit times) of idle line before every request.
//! * The slave's main loop runs every millisecond: [`Application::step`], then
//!   [`Node::process_acyclic`] over the mailbox-backed parameters (as the soft slave does).

use host_tests::scripted::Ans;
use host_tests::{hex, profirust_rate};
use pbcard::card;
use pbcard::dp::{DpSlave, DpState};
use pbcard::fdl::telegram;
use pbcard::node::Node;
use pbcard::testkit::{ScriptedMaster, SetPrm};
use pbcard::time::{Baudrate, BitTimes, Instant};
use pbcard_sim::bench::Application;
use pbcard_sim::drive::DriveConfig;
use profirust::phy::{ProfibusPhy, SimulatorPhy};

const ME: u8 = 3;
const M1: u8 = 2;
const RATES: [Baudrate; 2] = [Baudrate::B1500k, Baudrate::B12M];
const TSYN: u64 = 33;
const MIN_TSDR: u64 = 11;
const B5_READ: [u8; 4] = [0xDE, 0x80, 0xB5, 0x00];
/// DS_Write refused with 0xC2 "resource busy" while another relation's job runs.
const BUSY_WRITE: [u8; 4] = [0xDF, 0x80, 0xC2, 0x00];
const B5_WRITE: [u8; 4] = [0xDF, 0x80, 0xB5, 0x00];

fn pr(us: u64) -> profirust::time::Instant {
    profirust::time::Instant::from_micros(us as i64)
}

fn bps(rate: Baudrate) -> u64 {
    u64::from(rate.bits_per_second())
}

/// The shortest whole number of µs that holds `bits` bit times.
fn ceil_us(rate: Baudrate, bits: u64) -> u64 {
    (bits * 1_000_000).div_ceil(bps(rate))
}

/// Our slave: a [`Node`] and the simulated drive on one end of the line.
struct Slave {
    phy: SimulatorPhy,
    rate: Baudrate,
    node: Node,
    app: Application,
    /// Answer waiting for min_TSDR: (bytes, due µs).
    pending: Option<(Vec<u8>, u64)>,
    last_activity_us: u64,
    idle_reported: bool,
    next_tick_us: u64,
    /// Drop (do not send) the next answer for which this returns true (one shot).
    drop_if: Option<fn(&[u8]) -> bool>,
    dropped: Vec<Vec<u8>>,
    answers: u64,
}

impl Slave {
    fn poll(&mut self, now_us: u64) {
        let pnow = pr(now_us);
        let now = Instant::from_micros(now_us);
        if !self.phy.poll_transmission(pnow) {
            let mut rx = Vec::new();
            self.phy.receive_data(pnow, |buf| {
                rx.extend_from_slice(buf);
                (buf.len(), ())
            });
            if rx.is_empty() {
                let silent = (now_us - self.last_activity_us.min(now_us)) * bps(self.rate) / 1_000_000;
                if !self.idle_reported && silent >= TSYN {
                    self.node.on_idle(BitTimes(silent.min(u64::from(u32::MAX)) as u32));
                    self.idle_reported = true;
                }
            } else {
                self.last_activity_us = now_us;
                self.idle_reported = false;
                assert!(self.pending.is_none(), "line busy before our answer went out");
                for b in rx {
                    if let Some(r) = self.node.on_byte(now, b).map(<[u8]>::to_vec) {
                        let wait = u64::from(self.node.min_tsdr().0).max(MIN_TSDR);
                        self.pending = Some((r, now_us + ceil_us(self.rate, wait)));
                    }
                }
            }
            if self.pending.as_ref().is_some_and(|(_, due)| now_us >= *due) {
                let (bytes, _) = self.pending.take().unwrap();
                if self.drop_if.is_some_and(|f| f(&bytes)) {
                    self.drop_if = None;
                    self.dropped.push(bytes);
                } else {
                    let n = bytes.len();
                    self.phy.transmit_data(pnow, |buf| {
                        buf[..n].copy_from_slice(&bytes);
                        (n, ())
                    });
                    self.answers += 1;
                    self.last_activity_us = now_us + ceil_us(self.rate, 11 * n as u64);
                    self.idle_reported = false;
                }
            }
        }
        if now_us >= self.next_tick_us {
            self.next_tick_us = now_us + 1000;
            self.app.step(now, &mut self.node);
            if self.node.has_acyclic_work() {
                self.node.process_acyclic(now, &mut self.app.records(now));
            }
        }
    }
}

/// Our test master (any number of master addresses) and the slave on one simulated line.
struct Bus {
    rate: Baudrate,
    now_us: u64,
    phy: SimulatorPhy,
    slave: Slave,
    master: ScriptedMaster,
    /// End of the last character on the line as the master knows it.
    line_end_us: u64,
    /// Measured answer delays (bit times after the request's last stop bit): min, max.
    tsdr: (u64, u64),
    min_idle_bits: u64,
    last_raw: Vec<u8>,
    cyclic: bool,
    dx_count: u32,
}

impl Bus {
    fn new(rate: Baudrate) -> Self {
        let phy = SimulatorPhy::new(profirust_rate(rate), "master");
        let sphy = phy.duplicate("slave#3");
        let mut app = Application::new(DriveConfig::DEFAULT);
        app.set_baudrate(Some(rate));
        let mut node = pbcard::card::node(DpSlave::new(&pbcard::card::SLAVE, ME));
        node.set_baudrate(Some(rate));
        let slave = Slave {
            phy: sphy,
            rate,
            node,
            app,
            pending: None,
            last_activity_us: 0,
            idle_reported: false,
            next_tick_us: 0,
            drop_if: None,
            dropped: Vec::new(),
            answers: 0,
        };
        Bus {
            rate,
            now_us: 0,
            phy,
            slave,
            master: ScriptedMaster::new(M1, ME),
            line_end_us: 0,
            tsdr: (u64::MAX, 0),
            min_idle_bits: u64::MAX,
            last_raw: Vec::new(),
            cyclic: false,
            dx_count: 0,
        }
    }

    /// A lone master passes the token to itself (SD4 `DC 02 02`): the simulator then knows the
    /// token holder and judges our answers by min_TSDR (a short acknowledgement carries no
    /// address and would otherwise be judged as the token holder's frame).
    fn token(&mut self) {
        while self.now_us < self.line_end_us + ceil_us(self.rate, TSYN) {
            self.step(1);
        }
        let tx = self.now_us;
        self.phy.transmit_data(pr(tx), |buf| {
            buf[..3].copy_from_slice(&[0xDC, M1, M1]);
            (3, ())
        });
        self.line_end_us = tx + ceil_us(self.rate, 33);
    }

    fn step(&mut self, us: u64) {
        self.now_us += us;
        self.phy.set_bus_time(pr(self.now_us));
        self.slave.poll(self.now_us);
    }

    /// Let `us` of simulated time pass (coarse steps for long silences).
    fn idle(&mut self, us: u64) {
        let end = self.now_us + us;
        let step = if us > 10_000 { 100 } else { 1 };
        while self.now_us < end {
            self.step(step.min(end - self.now_us));
        }
    }

    fn bits_between(&self, from_us: u64, to_us: u64) -> (u64, u64) {
        let num = (to_us - from_us) * bps(self.rate);
        (num / 1_000_000, num.div_ceil(1_000_000))
    }

    /// Send `frame` after T_SYN of idle line; the raw answer, or `None` after the slot time.
    fn transact_raw(&mut self, frame: &[u8]) -> Option<Vec<u8>> {
        while self.now_us < self.line_end_us + ceil_us(self.rate, TSYN) {
            self.step(1);
        }
        let idle_bits = self.bits_between(self.line_end_us, self.now_us).0;
        assert!(idle_bits >= TSYN, "master sent after {idle_bits} bit times of idle line");
        self.min_idle_bits = self.min_idle_bits.min(idle_bits);
        let tx = self.now_us;
        let n = frame.len();
        self.phy.transmit_data(pr(tx), |buf| {
            buf[..n].copy_from_slice(frame);
            (n, ())
        });
        let req_bits = 11 * n as u64;
        self.line_end_us = tx + ceil_us(self.rate, req_bits);
        let max_tsdr = u64::from(card::max_tsdr(self.rate));
        let deadline = tx + ceil_us(self.rate, req_bits + 2 * max_tsdr + 100);
        let char_us = ceil_us(self.rate, 11);
        let mut rx: Vec<u8> = Vec::new();
        loop {
            self.step(1);
            let now = self.now_us;
            if self.phy.poll_transmission(pr(now)) {
                continue;
            }
            let before = rx.len();
            self.phy.receive_data(pr(now), |buf| {
                rx.extend_from_slice(buf);
                (buf.len(), ())
            });
            if rx.len() > before {
                self.line_end_us = now;
                if before == 0 {
                    // With 1 µs steps the first character completed exactly now: the answer
                    // started char_us earlier.
                    let start = now - char_us;
                    let (lo, hi) = self.bits_between(tx, start);
                    let (lo, hi) = (lo - req_bits, hi - req_bits);
                    assert!(
                        lo >= MIN_TSDR && hi <= max_tsdr,
                        "answer {} to {} started {lo}..{hi} bit times after the request at {:?}",
                        hex(&rx),
                        hex(frame),
                        self.rate
                    );
                    self.tsdr = (self.tsdr.0.min(lo), self.tsdr.1.max(hi));
                }
            }
            if let Some(&first) = rx.first() {
                let len = match first {
                    telegram::SC => 1,
                    0x10 => 6,
                    0xA2 => 14,
                    0x68 if rx.len() >= 2 => usize::from(rx[1]) + 6,
                    0x68 => continue,
                    other => panic!("invalid start delimiter {other:02X} in {}", hex(&rx)),
                };
                if rx.len() >= len {
                    assert_eq!(rx.len(), len, "one answer: {}", hex(&rx));
                    return Some(rx);
                }
            } else if now >= deadline {
                return None;
            }
        }
    }

    fn frame(&mut self, sa: u8, dsap: Option<u8>, ssap: Option<u8>, pdu: &[u8], toggle: bool) -> Vec<u8> {
        self.master.request(sa, dsap, ssap, pdu, toggle).to_vec()
    }

    /// The answer to `frame` (none within the slot time: [`Ans::None`]).
    fn exchange(&mut self, frame: &[u8]) -> Ans {
        let Some(r) = self.transact_raw(frame) else { return Ans::None };
        self.last_raw = r.clone();
        Ans::of(frame, Some(&r), None)
    }

    fn send(&mut self, sa: u8, dsap: Option<u8>, ssap: Option<u8>, pdu: &[u8]) -> Ans {
        let f = self.frame(sa, dsap, ssap, pdu, true);
        self.exchange(&f)
    }

    fn bring_up(&mut self) {
        // DPV1_Status_1: DPV1_Enable.
        let prm = SetPrm::CARD.watchdog(10, 10).min_tsdr(MIN_TSDR as u8).dpv1_status_1(0x80).pdu();
        assert_eq!(self.send(M1, Some(61), Some(62), &prm), Ans::Sc, "Set_Prm");
        assert_eq!(self.send(M1, Some(62), Some(62), card::MODULES[0].cfg), Ans::Sc, "Chk_Cfg");
        assert_eq!(self.slave.node.slave().state(), DpState::DataExch);
        self.cyclic = true;
        for _ in 0..3 {
            self.dx();
        }
    }

    /// One Data_Exchange (STW1 0x047E, speed 0) when the slave is brought up.
    fn dx(&mut self) {
        if !self.cyclic {
            return;
        }
        match self.send(M1, None, None, &[0x04, 0x7E, 0, 0]) {
            Ans::Pdu(p) => assert_eq!(p.len(), card::MODULES[0].inputs as usize, "inputs {}", hex(&p)),
            other => panic!(
                "Data_Exchange: {other:?} at {} µs, state {:?}, station {:?}, framer {:?}, pending {:?}",
                self.now_us,
                self.slave.node.slave().state(),
                self.slave.node.station().stats(),
                self.slave.node.framer().stats(),
                self.slave.pending
            ),
        }
        self.dx_count += 1;
    }

    fn c2(&mut self, sa: u8, sap: u8, pdu: &[u8]) -> Ans {
        self.send(sa, Some(sap), Some(50), pdu)
    }

    /// RM on SAP 49 → RM PDU naming the server SAP (the Initiate on it follows separately).
    fn rm(&mut self, sa: u8, send_timeout: u16) -> u8 {
        match self.c2(sa, 49, &initiate(send_timeout)) {
            Ans::Pdu(p) => {
                assert_eq!((p.len(), p[0]), (4, 0x56), "RM PDU 56 sap poll_timeout");
                p[1]
            }
            other => panic!("RM answer {other:?}"),
        }
    }

    fn initiate_on(&mut self, sa: u8, sap: u8, send_timeout: u16) {
        assert_eq!(self.c2(sa, sap, &initiate(send_timeout)), Ans::Sc);
        match self.c2(sa, sap, &[]) {
            Ans::Pdu(p) => assert_eq!(p[0], 0x57, "Initiate.res"),
            other => panic!("Initiate.res {other:?}"),
        }
    }

    fn finish(&self) {
        let max = u64::from(card::max_tsdr(self.rate));
        assert!(self.tsdr.0 >= MIN_TSDR && self.tsdr.1 <= max, "{:?}", self.tsdr);
        assert!(self.min_idle_bits >= TSYN);
        println!(
            "{:?}: {} answers, TSDR {}..{} bit times (max_TSDR {max}), min idle {} bit times, {} Data_Exchange, t = {} µs",
            self.rate,
            self.slave.answers,
            self.tsdr.0,
            self.tsdr.1,
            self.min_idle_bits,
            self.dx_count,
            self.now_us
        );
    }
}

/// Initiate.req: Send_Timeout (10 ms units), Read/Write supported, S and D type 0 with
/// 2-byte address blocks (API 0, SCL 0).
fn initiate(send_timeout: u16) -> Vec<u8> {
    let t = send_timeout.to_be_bytes();
    vec![0x57, 0, 0, 0, t[0], t[1], 0x01, 0x00, 0, 0, 0, 0, 0, 2, 0, 2, 0, 0, 0, 0]
}

/// One DS_Write of record 47 + DS_Read, over MSAC_C1 (SAP 51/51) or a C2 connection, advanced
/// one frame at a time so several jobs (and Data_Exchange) interleave on the line.
struct Job {
    sa: u8,
    dsap: u8,
    ssap: u8,
    write: Vec<u8>,
    phase: u8,
    result: Option<Vec<u8>>,
    sc_polls: u32,
    b5: u32,
}

impl Job {
    fn new(sa: u8, dsap: u8, ssap: u8, req: &[u8]) -> Self {
        let write = [&[0x5F, 0, 47, req.len() as u8][..], req].concat();
        Job { sa, dsap, ssap, write, phase: 0, result: None, sc_polls: 0, b5: 0 }
    }
    fn c1(req: &[u8]) -> Self {
        Job::new(M1, 51, 51, req)
    }

    fn done(&self) -> bool {
        self.result.is_some()
    }

    fn advance(&mut self, bus: &mut Bus) {
        let (sa, d, s) = (self.sa, Some(self.dsap), Some(self.ssap));
        match self.phase {
            0 => {
                assert_eq!(bus.send(sa, d, s, &self.write.clone()), Ans::Sc, "DS_Write acknowledged");
                self.phase = 1;
            }
            1 | 3 => match bus.send(sa, d, s, &[]) {
                Ans::Sc => self.sc_polls += 1,
                Ans::Pdu(p) if self.phase == 1 && (p == B5_WRITE || p == BUSY_WRITE) => {
                    // Another relation's job is waiting for the drive: repeat the DS_Write.
                    self.b5 += 1;
                    self.phase = 0;
                }
                Ans::Pdu(p) if self.phase == 1 => {
                    assert_eq!(p, self.write[..4], "write response");
                    self.phase = 2;
                }
                Ans::Pdu(p) if p == B5_READ => {
                    self.b5 += 1;
                    self.phase = 2;
                }
                Ans::Pdu(p) => {
                    assert_eq!((&p[..3], usize::from(p[3])), (&[0x5E, 0, 47][..], p.len() - 4), "read response");
                    self.result = Some(p[4..].to_vec());
                    self.phase = 4;
                }
                other => panic!("poll: {other:?}"),
            },
            2 => {
                assert_eq!(bus.send(sa, d, s, &[0x5E, 0, 47, 240]), Ans::Sc, "DS_Read acknowledged");
                self.phase = 3;
            }
            _ => {}
        }
    }

    /// Run to the end with a Data_Exchange after every frame; the parameter response.
    fn run(mut self, bus: &mut Bus) -> (Vec<u8>, Job) {
        for _ in 0..2000 {
            if self.done() {
                return (self.result.clone().unwrap(), self);
            }
            self.advance(bus);
            bus.dx();
        }
        panic!("job {} never finished", hex(&self.write));
    }
}

fn mailbox_requests(bus: &Bus) -> u32 {
    bus.slave.app.link().mailbox().stats().requests
}

/// Class 1: bring-up with DPV1_Enable, Data_Exchange interleaved with DS_Write / polls /
/// DS_Read of record 47 changing drive parameters through the DPM mailbox, reading PNU 918.
#[test]
fn class1_parameters_through_the_mailbox_on_the_line() {
    for rate in RATES {
        let mut b = Bus::new(rate);
        b.idle(200);
        b.token();
        // Before Set_Prm, MSAC_C1 is closed: RS.
        assert_eq!(b.send(M1, Some(51), Some(51), &[0x5E, 0, 47, 240]), Ans::Sd1(0x03));
        b.bring_up();
        let before = mailbox_requests(&b);
        // Change P100 = 1000 and P101 = 70: two mailbox requests, one after the other.
        let req = [7, 2, 1, 2, 0x10, 1, 0, 100, 0, 0, 0x10, 1, 0, 101, 0, 0, 0x42, 1, 0x03, 0xE8, 0x42, 1, 0, 70];
        let (r, job) = Job::c1(&req).run(&mut b);
        assert_eq!(r, [7, 2, 1, 2]);
        assert!(job.sc_polls >= 1, "polls answered SC while the request waits for the DP-V1 task");
        assert!(job.b5 >= 1, "DS_Read answered 0xB5 while the drive works");
        assert_eq!(b.slave.app.drive_params().get(100, 0), Some(1000));
        assert_eq!(b.slave.app.drive_params().get(101, 0), Some(70));
        assert_eq!(mailbox_requests(&b) - before, 2, "each write once");
        // Read P100 (the drive's) and PNU 918 (the card's station address) in one request.
        let (r, _) = Job::c1(&[8, 1, 1, 2, 0x10, 1, 0, 100, 0, 0, 0x10, 1, 0x03, 0x96, 0, 0]).run(&mut b);
        assert_eq!(r, [8, 1, 1, 2, 0x42, 1, 0x03, 0xE8, 0x42, 1, 0, ME]);
        // VACON §6.4.4.1: PNU 918 alone.
        let (r, _) = Job::c1(&[1, 1, 1, 1, 0x10, 1, 0x03, 0x96, 0, 0]).run(&mut b);
        assert_eq!(r, [1, 1, 1, 1, 0x42, 1, 0, ME]);
        assert!(b.dx_count >= 10, "{}", b.dx_count);
        assert_eq!(b.slave.node.slave().state(), DpState::DataExch);
        b.finish();
    }
}

/// A dropped answer to a DS_Write and to the poll that fetches its response: the master
/// repeats the same frame (same FCB) and gets the same bytes; the write is executed once.
#[test]
fn fcb_retries_on_the_line() {
    for rate in RATES {
        let mut b = Bus::new(rate);
        b.idle(200);
        b.token();
        b.bring_up();
        let before = mailbox_requests(&b);
        let retries = b.slave.node.station().stats().retries;
        let req = [0x5F, 0, 47, 14, 9, 2, 1, 1, 0x10, 1, 0, 100, 0, 0, 0x42, 1, 0, 85];
        // DS_Write: the SC is lost on the line.
        b.slave.drop_if = Some(|_| true);
        let f = b.frame(M1, Some(51), Some(51), &req, true);
        assert_eq!(b.exchange(&f), Ans::None, "answer dropped");
        assert_eq!(b.slave.dropped.last().unwrap(), &[telegram::SC]);
        // The retry follows at once (after the slot time and T_SYN), as FDL repeats.
        assert_eq!(b.exchange(&f), Ans::Sc, "retry answered");
        // Polls until the write response; its frame is lost once.
        // (an SD2 with SAPs: DA carries the extension bit; Data_Exchange answers pass.)
        b.slave.drop_if = Some(|r| r[0] == 0x68 && r[4] & 0x80 != 0);
        let mut fetched = None;
        for _ in 0..200 {
            b.dx();
            let p = b.frame(M1, Some(51), Some(51), &[], true);
            match b.exchange(&p) {
                Ans::Sc => {}
                Ans::None => {
                    let lost = b.slave.dropped.last().unwrap().clone();
                    let again = b.exchange(&p);
                    assert_eq!(b.last_raw, lost, "the retried poll gets the same frame");
                    fetched = Some(again);
                    break;
                }
                other => panic!("poll: {other:?}"),
            }
        }
        assert_eq!(fetched, Some(Ans::Pdu(vec![0x5F, 0, 47, 14])));
        assert!(b.slave.node.station().stats().retries >= retries + 2);
        // The read completes the job: executed once.
        let mut job = Job::c1(&[]);
        job.phase = 2;
        let (r, _) = job.run(&mut b);
        assert_eq!(r, [9, 2, 1, 1]);
        assert_eq!(b.slave.app.drive_params().get(100, 0), Some(85));
        assert_eq!(mailbox_requests(&b) - before, 1, "the write reached the drive once");
        b.finish();
    }
}

/// Class-1 bring-up, then two class-2 masters (#10, #11) open connections at once (RM on SAP
/// 49, Initiate on the named SAP) and #10 writes P9901[2..4] = 100, 200, 300.
fn two_connections(rate: Baudrate) -> (Bus, u8, u8) {
    let mut b = Bus::new(rate);
    b.idle(200);
    b.token();
    b.bring_up();
    let a = b.rm(10, 300);
    b.dx();
    let c = b.rm(11, 300);
    assert_ne!(a, c);
    b.initiate_on(10, a, 300);
    b.dx();
    b.initiate_on(11, c, 300);
    let w = [5, 2, 1, 1, 0x10, 3, 0x26, 0xAD, 0, 2, 0x42, 3, 0, 100, 0, 200, 0x01, 0x2C];
    let (r, _) = Job::new(10, a, 50, &w).run(&mut b);
    assert_eq!(r, [5, 2, 1, 1]);
    (b, a, c)
}

/// Both connections stay open and are polled in turn while the other one reads P9901
/// subindexes through the mailbox (with Data_Exchange in between); then #10 aborts.
#[test]
fn two_class2_connections_at_once_on_the_line() {
    for rate in RATES {
        let (mut b, a, c) = two_connections(rate);
        let mut ja = Job::new(10, a, 50, &[10, 1, 1, 1, 0x10, 1, 0x26, 0xAD, 0, 2]);
        for _ in 0..2000 {
            if ja.done() {
                break;
            }
            ja.advance(&mut b);
            assert_eq!(b.c2(11, c, &[]), Ans::Sc, "#11 polls its idle connection");
            b.dx();
        }
        assert_eq!(ja.result.as_deref(), Some(&[10, 1, 1, 1, 0x42, 1, 0, 100][..]));
        let mut jc = Job::new(11, c, 50, &[11, 1, 1, 1, 0x10, 2, 0x26, 0xAD, 0, 3]);
        for _ in 0..2000 {
            if jc.done() {
                break;
            }
            jc.advance(&mut b);
            assert_eq!(b.c2(10, a, &[]), Ans::Sc, "#10 polls its idle connection");
            b.dx();
        }
        assert_eq!(jc.result.as_deref(), Some(&[11, 1, 1, 1, 0x42, 2, 0, 200, 0x01, 0x2C][..]));
        assert!(ja.sc_polls + jc.sc_polls + ja.b5 + jc.b5 >= 1, "polls answered SC while busy");
        // Another master on a connection's SAP: RS.
        assert_eq!(b.c2(12, a, &[0x5E, 0, 47, 240]), Ans::Sd1(0x03));
        // Abort by #10: SC, then the SAP is closed (RS); #11 goes on.
        assert_eq!(b.c2(10, a, &[0x58, 0x00, 0x20, 0x00]), Ans::Sc);
        assert_eq!(b.c2(10, a, &[0x5E, 0, 47, 240]), Ans::Sd1(0x03));
        let (r, _) = Job::new(11, c, 50, &[12, 1, 1, 1, 0x10, 1, 0x03, 0x96, 0, 0]).run(&mut b);
        assert_eq!(r, [12, 1, 1, 1, 0x42, 1, 0, ME]);
        // The freed connection is given out again.
        assert_eq!(b.rm(12, 300), a);
        assert_eq!(b.slave.node.slave().state(), DpState::DataExch);
        b.finish();
    }
}

/// Both connections with a record-47 job in flight at the same time: each must get its own
/// response (or 0xC2 "resource busy" at its DS_Write while the other job runs, repeated by the
/// master) — never the other's. (Found on this line: record 47 used to be one job shared by
/// every relation, and #10's DS_Read returned #11's response.)
#[test]
fn two_class2_jobs_overlapping_on_the_line() {
    for rate in RATES {
        let (mut b, a, c) = two_connections(rate);
        let mut ja = Job::new(10, a, 50, &[10, 1, 1, 1, 0x10, 1, 0x26, 0xAD, 0, 2]);
        let mut jc = Job::new(11, c, 50, &[11, 1, 1, 1, 0x10, 2, 0x26, 0xAD, 0, 3]);
        for _ in 0..2000 {
            if ja.done() && jc.done() {
                break;
            }
            ja.advance(&mut b);
            jc.advance(&mut b);
            b.dx();
        }
        assert_eq!(ja.result.as_deref(), Some(&[10, 1, 1, 1, 0x42, 1, 0, 100][..]));
        assert_eq!(jc.result.as_deref(), Some(&[11, 1, 1, 1, 0x42, 2, 0, 200, 0x01, 0x2C][..]));
        b.finish();
    }
}

/// Send_Timeout (1 s) expires while the class-2 master is silent: its next poll gets the Abort
/// PDU (reason 3, timeout), the one after that RS.
#[test]
fn class2_send_timeout_on_the_line() {
    for rate in RATES {
        let mut b = Bus::new(rate);
        b.idle(200);
        b.token();
        let sap = b.rm(10, 100);
        b.initiate_on(10, sap, 100);
        let (r, _) = Job::new(10, sap, 50, &[1, 1, 1, 1, 0x10, 1, 0x03, 0x96, 0, 0]).run(&mut b);
        assert_eq!(r, [1, 1, 1, 1, 0x42, 1, 0, ME]);
        // 0.9 s of silence: still open.
        b.idle(900_000);
        assert_eq!(b.c2(10, sap, &[]), Ans::Sc, "idle poll within Send_Timeout");
        // 1.05 s of silence: aborted by the slave.
        b.idle(1_050_000);
        match b.c2(10, sap, &[]) {
            Ans::Pdu(p) => assert_eq!((p[0], p[2] & 0x0F), (0x58, 3), "Abort, reason 3 timeout: {}", hex(&p)),
            other => panic!("after the timeout: {other:?}"),
        }
        assert_eq!(b.c2(10, sap, &[0x5E, 0, 47, 240]), Ans::Sd1(0x03));
        b.finish();
    }
}
