//! A whole `Node` (framer → station → DP slave + MSAC_C1 + MSAC_C2 + drive records) brought to
//! data exchange with DPV1_Enable (Set_Prm User_Prm byte 0 = 0x80, as in
//! host-tests/tests/dpv1.rs), then driven by a sequence of operations derived from the fuzz
//! input: MSAC_C1 requests and polls on SAP 51 (from the locking master, other masters, wrong
//! SSAPs); MSAC_C2 Initiate on the resource manager SAP 49 and on the connection SAPs 48/47,
//! requests, polls, Idle, Abort (SRD and SDN) from several class-2 masters and SSAPs; FCB
//! retries; time steps with `Node::poll` (watchdog, Send_Timeout); `Node::process_acyclic`
//! against the fake drive table of `pbcard::testkit::FakeDrive` (behind the card's own PNUs); DP
//! cyclic traffic; re-parameterisation (with or without DPV1_Enable); free-form requests.
//! Frames go in whole (`on_frame`) or byte by byte through the framer (`on_byte`).
//!
//! Checks after every frame: no panic; every answer decodes as one valid frame of exactly its
//! length: a short acknowledge, or a response from our address to the requester; nothing
//! answers a broadcast, another station's frame or bytes that are no single telegram. Answers
//! on the DP-V1 SAPs (51, 49, 48, 47) carry the request's SAPs swapped and a PDU that
//! `Response::parse` accepts (or the 4-byte DP-V1 error PDU): the RM PDU `56 sap 00 64` names
//! a connection SAP; a C1 / C2 response answers the function of the last request that SAP
//! acknowledged (or is a C2 Abort). An FCB retry the station recognises gets the previous
//! answer byte for byte. `process_acyclic` leaves no work behind. The DP images keep their
//! sizes, and data exchange implies a locking master and a module.
#![no_main]

#[path = "common/src.rs"]
#[macro_use]
mod src;

use libfuzzer_sys::fuzz_target;
use pbcard::card;
use pbcard::dp::{DpSlave, DpState};
use pbcard::dpv1::c1::C1;
use pbcard::dpv1::pdu::{Function, Response, ERROR_BIT, ERROR_DECODE_DPV1};
use pbcard::fdl::telegram::{self, Decoded, FunctionCode, Header, RequestFunction, Telegram, MAX_FRAME_LEN};
use pbcard::node::Node;
use pbcard::profile::records::CardRecords;
use pbcard::testkit::FakeDrive;
use pbcard::testkit::{self, ScriptedMaster, SetPrm};
use pbcard::time::{BitTimes, Instant};
use src::Src;

const ME: u8 = 5;
/// The class-1 master that parameterises the slave (and owns MSAC_C1).
const M1: u8 = 2;
/// Another class-1 master.
const M2: u8 = 3;
/// Class-2 masters (M1 may open MSAC_C2 connections too).
const C2_MASTERS: [u8; 4] = [10, 11, 12, M1];
/// The SSAP the class-2 masters use.
const C2_SSAP: u8 = 50;
const C1_SAP: u8 = 51;
const RM_SAP: u8 = 49;
/// The connection SAPs of the card's `C2_MAX_COUNT_CHANNELS` = 2 connections.
const CONN_SAPS: [u8; 2] = [48, 47];

fn is_dpv1_sap(sap: u8) -> bool {
    sap == C1_SAP || sap == RM_SAP || CONN_SAPS.contains(&sap)
}

/// Known bug (reported, crates/dp/src/dpv1/c1.rs): `C1::on_request` does not look at the function code
/// or the destination address, so an SDN — even a broadcast — on SAP 51 from the locking
/// master with SSAP 51 is taken as a request (replacing the pending one; an empty one consumes
/// a ready response, which is then lost). While this is `true`, the target models that
/// behaviour instead of failing on it; set it to `false` once C1 ignores SDN and broadcasts.
const KNOWN_BUG_C1_TAKES_SDN: bool = false;

/// Known bug (reported, crates/dp/src/dpv1/c1.rs): `C1` notices that it closed only when it is called
/// (`on_request`, `process`). When the slave leaves data exchange and is parameterised again
/// (possibly by another master) before the next MSAC_C1 frame, the request in flight
/// survives: it is executed in the new session and its response — addressed to the old
/// master — answers the new master's poll. While this is `true`, such stale C1 answers are
/// traced instead of failing; set it to `false` once C1 drops them.
const KNOWN_BUG_C1_STALE_REQUEST: bool = false;

/// Request functions after which the station remembers its answer for an FCB retry.
fn sets_last(f: RequestFunction) -> bool {
    matches!(
        f,
        RequestFunction::SrdLow
            | RequestFunction::SrdHigh
            | RequestFunction::SdaLow
            | RequestFunction::SdaHigh
            | RequestFunction::Msrd
            | RequestFunction::Ident
            | RequestFunction::LsapStatus
    )
}

struct Bus {
    node: Node,
    /// The card's data records (records 47 / 48), owned by the application.
    records: CardRecords,
    table: FakeDrive,
    master: ScriptedMaster,
    now: u64,
    /// Feed frames byte by byte through the framer instead of whole.
    bytewise: bool,
    /// The last frame delivered (for the retry operation).
    last_frame: Option<Vec<u8>>,
    /// The answer to the last request that made the station remember its answer.
    last_answer: Option<Option<Vec<u8>>>,
    /// First byte of the last request PDU each DP-V1 SAP acknowledged with SC.
    acked: [Option<u8>; 64],
    /// Counts the times MSAC_C1 was seen closed after being open (a new C1 session).
    c1_epoch: u32,
    c1_was_open: bool,
    /// `c1_epoch` when SAP 51 acknowledged its last request.
    c1_acked_epoch: u32,
    /// The server SAP the RM last named to each class-2 master.
    rm_sap: [Option<u8>; 4],
}

impl Bus {
    fn own(&self) -> u8 {
        self.node.slave().address()
    }

    fn deliver(&mut self, frame: &[u8]) -> Option<Vec<u8>> {
        self.now += 300;
        let now = Instant::from_micros(self.now);
        let own = self.own();
        let retries = self.node.station().stats().retries;
        let (c1_open, master) = (C1::is_open(self.node.slave()), self.node.slave().master_address());
        let req = match telegram::decode(frame) {
            Decoded::Frame(Telegram::Data(t), n) if n == frame.len() => Some(t),
            _ => None,
        };
        let resp = if self.bytewise && matches!(telegram::decode(frame), Decoded::Frame(_, n) if n == frame.len()) {
            // After an idle of T_SYN the framer must find exactly this frame at its last byte.
            self.node.on_idle(BitTimes(33));
            let mut ans = None;
            for (i, &b) in frame.iter().enumerate() {
                if let Some(r) = self.node.on_byte(now, b) {
                    assert_eq!(i + 1, frame.len(), "answer {r:02x?} after byte {i} of {frame:02x?}");
                    ans = Some(r.to_vec());
                }
            }
            ans
        } else {
            self.node.on_frame(now, frame).map(|r| r.to_vec())
        };
        let is_retry = self.node.station().stats().retries != retries;
        if KNOWN_BUG_C1_TAKES_SDN && c1_open {
            if let Some(t) = req.filter(|t| {
                t.fc.is_request()
                    && matches!(t.fc.function(), RequestFunction::SdnLow | RequestFunction::SdnHigh)
                    && (t.da == own || t.da == telegram::BROADCAST)
                    && (t.dsap, t.ssap) == (Some(C1_SAP), Some(C1_SAP))
                    && Some(t.sa) == master
                    && !t.pdu.is_empty()
            }) {
                self.acked[C1_SAP as usize] = Some(t.pdu[0]);
                self.c1_acked_epoch = self.c1_epoch;
            }
        }
        trace!("t={}us {frame:02x?} -> {resp:02x?}{}", self.now, if is_retry { " (retry)" } else { "" });
        self.last_frame = Some(frame.to_vec());

        if let Some(r) = &resp {
            let req = req.unwrap_or_else(|| panic!("answer {r:02x?} to {frame:02x?}, no single data telegram"));
            assert_eq!(req.da, own, "answer {r:02x?} to a frame for station {} (we are {own})", req.da);
            assert!(req.fc.is_request(), "answer {r:02x?} to the response {frame:02x?}");
            match telegram::decode(r) {
                Decoded::Frame(Telegram::ShortAck, 1) => {}
                Decoded::Frame(Telegram::Data(t), n) if n == r.len() => {
                    assert_eq!(t.sa, own, "answer {r:02x?} not from our address {own}");
                    let c1_pdu = req.dsap == Some(C1_SAP) && !t.pdu.is_empty();
                    if KNOWN_BUG_C1_STALE_REQUEST && c1_pdu && t.da != req.sa {
                        trace!("known bug: stale C1 answer {r:02x?} to {}", req.sa);
                    } else {
                        assert_eq!(t.da, req.sa, "answer {r:02x?} not to the requester {}", req.sa);
                    }
                    assert!(!t.fc.is_request(), "answer {r:02x?} has a request FC");
                    if let Some(sap) = req.dsap.filter(|&s| is_dpv1_sap(s)) {
                        if t.dsap.is_some() || t.ssap.is_some() || !t.pdu.is_empty() {
                            assert_eq!((t.dsap, t.ssap), (req.ssap, req.dsap), "SAPs of {r:02x?} to {frame:02x?}");
                            self.check_dpv1_answer(sap, req.sa, t.pdu, is_retry);
                        }
                    }
                }
                other => panic!("node sent {r:02x?} = {other:?} for {frame:02x?}"),
            }
        }

        // A frame the station refuses before its retry memory — a reserved FC (bit 7) or an
        // impossible source (SA 127 or our own address) — neither is a retry nor replaces the
        // last answer an FCB retry repeats (`fdl::station`'s table).
        let refused = |t: &telegram::DataTelegram<'_>| t.fc.0 & 0x80 != 0 || t.sa == telegram::BROADCAST || t.sa == own;
        if let Some(t) = req.filter(|t| t.da == own && t.fc.is_request() && !refused(t)) {
            let f = t.fc.function();
            if is_retry {
                let prev = self.last_answer.clone().expect("a retry without a previous answer");
                assert_eq!(resp, prev, "FCB retry of {frame:02x?} answered differently");
            } else if sets_last(f) {
                // An SC to a DP-V1 request PDU: this is what the SAP's next response answers.
                if resp.as_deref() == Some(&[telegram::SC][..]) && !t.pdu.is_empty() {
                    if let Some(s) = t.dsap.filter(|&s| s == C1_SAP || CONN_SAPS.contains(&s)) {
                        self.acked[s as usize] = Some(t.pdu[0]);
                        if s == C1_SAP {
                            self.c1_acked_epoch = self.c1_epoch;
                        }
                    }
                }
            }
            if sets_last(f) {
                self.last_answer = Some(resp.clone());
            }
        }
        self.check();
        resp
    }

    fn check_dpv1_answer(&mut self, sap: u8, master: u8, pdu: &[u8], is_retry: bool) {
        assert!(!pdu.is_empty(), "empty DP-V1 PDU on SAP {sap}");
        let parsed = Response::parse(pdu);
        if sap == RM_SAP {
            match parsed {
                Ok(Response::ResourceManager { server_sap, poll_timeout }) => {
                    assert!(CONN_SAPS.contains(&server_sap) && poll_timeout > 0, "RM PDU {pdu:02x?}");
                    if let Some(k) = C2_MASTERS.iter().position(|&m| m == master) {
                        self.rm_sap[k] = Some(server_sap);
                    }
                }
                other => panic!("RM answered {pdu:02x?} = {other:?}"),
            }
            return;
        }
        if parsed.is_err() {
            assert!(
                pdu.len() == 4 && pdu[0] & ERROR_BIT != 0 && pdu[1] == ERROR_DECODE_DPV1 && pdu[3] == 0,
                "SAP {sap} answered {pdu:02x?}: {parsed:?}"
            );
        }
        assert!(!matches!(parsed, Ok(Response::ResourceManager { .. })), "RM PDU on SAP {sap}");
        if is_retry {
            return;
        }
        if sap == C1_SAP && self.c1_acked_epoch != self.c1_epoch {
            if !KNOWN_BUG_C1_STALE_REQUEST {
                panic!("SAP 51 answered {pdu:02x?} to a request acknowledged before MSAC_C1 closed and reopened");
            }
            trace!("known bug: stale C1 response {pdu:02x?}");
            return;
        }
        let abort = pdu[0] == Function::Abort.code() && sap != C1_SAP;
        if !abort {
            let acked = self.acked[sap as usize];
            assert!(
                acked.is_some_and(|a| a & !ERROR_BIT == pdu[0] & !ERROR_BIT),
                "SAP {sap} answered {pdu:02x?}, the last request acknowledged there began {acked:02x?}"
            );
        }
    }

    fn check(&mut self) {
        let open = C1::is_open(self.node.slave());
        if self.c1_was_open && !open {
            self.c1_epoch += 1;
        }
        self.c1_was_open = open;
        let s = self.node.slave();
        assert_eq!(s.outputs().len(), s.output_len());
        assert_eq!(s.inputs().len(), s.input_len());
        assert!(s.address() <= card::MAX_STATION_ADDRESS);
        if s.state() == DpState::DataExch {
            assert!(s.master_address().is_some() && s.module().is_some(), "Data_Exch without master/module");
        }
    }

    fn emit(&mut self, hdr: &Header, pdu: &[u8]) -> Option<Vec<u8>> {
        let f = testkit::try_frame(hdr, pdu).ok()?;
        self.deliver(&f)
    }

    /// SRD high from `sa` with FCB toggled and FCV = 1.
    fn req(&mut self, sa: u8, dsap: Option<u8>, ssap: Option<u8>, pdu: &[u8]) -> Option<Vec<u8>> {
        self.master.slave = self.own();
        let f = self.master.try_request(sa, dsap, ssap, pdu, true).ok()?;
        self.deliver(&f)
    }

    fn process(&mut self) {
        let now = Instant::from_micros(self.now);
        self.node.process_acyclic(now, &mut self.records.with(&mut self.table));
        trace!("t={}us process_acyclic", self.now);
        assert!(!self.node.has_acyclic_work(), "work left after process_acyclic");
    }

    /// Set_Prm (with `dpv1_status_1` as User_Prm byte 0) and Chk_Cfg from `sa`.
    fn parameterise(&mut self, sa: u8, status: u8, dpv1_status_1: u8, module: usize) -> bool {
        let prm = SetPrm::CARD.station_status(status).wd_factors(10, 10).dpv1_status_1(dpv1_status_1).pdu();
        let sc = Some(vec![telegram::SC]);
        let a = self.req(sa, Some(61), Some(62), &prm);
        let b = self.req(sa, Some(62), Some(62), card::MODULES[module % card::MODULES.len()].cfg);
        a == sc && b == sc
    }
}

/// A PROFIdrive parameter request (record 47 data) built from the input.
fn param_request(src: &mut Src) -> Vec<u8> {
    const PNUS: [u16; 16] = [1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 918, 964, 965, 947, 980, 0];
    let h = src.u8();
    let id = match h & 3 {
        0 | 1 => 1,
        2 => 2,
        _ => src.u8(),
    };
    let count = if h & 0x80 != 0 { src.u8() } else { 1 + (h >> 2) % 4 };
    let axis = [1, 0, 1, 2][((h >> 4) & 3) as usize];
    let mut addrs = vec![];
    let mut values = vec![];
    for _ in 0..count.min(40) {
        let a = src.u8();
        let attribute = match a & 7 {
            0..=3 => 0x10,
            4 => 0x20,
            5 => 0x30,
            6 => 0x40,
            _ => src.u8(),
        };
        let elements = match (a >> 3) & 3 {
            0 => 1,
            1 => 0,
            2 => src.u8() % 12,
            _ => src.u8(),
        };
        let pnu = match PNUS[(a >> 5) as usize * 2 % 16 + (src.u8() & 1) as usize] {
            0 => src.u16(),
            p => p,
        };
        let subindex = match src.u8() {
            b @ 0..=0xEF => u16::from(b % 12),
            _ => src.u16(),
        };
        addrs.extend_from_slice(&[attribute, elements]);
        addrs.extend_from_slice(&pnu.to_be_bytes());
        addrs.extend_from_slice(&subindex.to_be_bytes());
        if id == 2 {
            let f = src.u8();
            let (format, size) = match f & 7 {
                0 | 1 => (0x42, 2),
                2 => (0x06, 2),
                3 => (0x43, 4),
                4 => (0x08, 4),
                5 => (0x41, 1),
                6 => (0x03, 2),
                _ => (src.u8(), 1 + (f >> 6) as usize),
            };
            let n = if f & 0x08 != 0 { src.u8() % 8 } else { elements.max(1) };
            values.extend_from_slice(&[format, n]);
            let len = size * n as usize;
            let mut v = src.bytes(len).to_vec();
            v.resize(len, 0);
            values.extend_from_slice(&v);
            if len & 1 == 1 {
                values.push(0);
            }
        }
    }
    let mut p = vec![src.u8() | 1, id, axis, count];
    p.extend_from_slice(&addrs);
    p.extend_from_slice(&values);
    p.truncate(240);
    p
}

/// A DP-V1 request PDU: mostly Read / Write / Data_Transport of records 47 and 48.
fn record_pdu(src: &mut Src) -> Vec<u8> {
    let k = src.u8();
    let slot = if k & 0x80 != 0 { src.u8() } else { 0 };
    let index = match (k >> 4) & 7 {
        0..=3 => 47,
        4 | 5 => 48,
        _ => src.u8(),
    };
    let with_data = |f: u8, data: Vec<u8>| {
        let mut p = vec![f, slot, index, data.len() as u8];
        p.extend_from_slice(&data);
        p
    };
    match k & 0x0F {
        0..=3 => vec![0x5E, slot, index, if k & 0x40 != 0 { src.u8() } else { 240 }],
        4..=7 => with_data(0x5F, param_request(src)),
        8 => {
            let n = if src.u8() & 1 == 0 { 2 } else { 4 };
            with_data(0x5F, src.bytes(n).to_vec())
        }
        9 => with_data(0x51, param_request(src)),
        10 => vec![0x5C, slot, src.u8(), src.u8()],
        11 => vec![0x48, 0],
        12 => vec![0x58, src.u8() % 3, src.u8() & 0x3F, 0],
        13 => initiate_pdu(src),
        _ => {
            let n = src.u8() as usize;
            src.bytes(n).to_vec()
        }
    }
}

/// An Initiate.req, mostly well-formed.
fn initiate_pdu(src: &mut Src) -> Vec<u8> {
    let b = src.u8();
    let st: u16 = match b & 3 {
        0 => 300,
        1 => 0,
        2 => u16::from(src.u8()),
        _ => src.u16(),
    };
    let block = |src: &mut Src, typed: bool| -> (u8, Vec<u8>) {
        if typed {
            let mut v = vec![src.u8() & 1, 0, 1, 2, 3, 4, 5, 6];
            let mac = src.u8() as usize % 5;
            v.extend_from_slice(src.bytes(mac));
            (1, v)
        } else {
            (0, vec![0, 0])
        }
    };
    let (s_type, s) = block(src, b & 0x04 != 0);
    let (d_type, mut d) = block(src, b & 0x08 != 0);
    if b & 0x40 != 0 {
        d[0] = src.u8(); // destination API ≠ 0 is refused
    }
    let mut p = vec![0x57, 0, 0, 0, (st >> 8) as u8, st as u8, 0x01, 0x00, 0, 0, 0, 0];
    p.extend_from_slice(&[s_type, s.len() as u8, d_type, d.len() as u8]);
    p.extend_from_slice(&s);
    p.extend_from_slice(&d);
    if b & 0x10 != 0 && !p.is_empty() {
        let i = src.u8() as usize % p.len();
        p[i] = src.u8();
    }
    if b & 0x20 != 0 {
        let n = src.u8() as usize % (p.len() + 1);
        p.truncate(n);
    }
    p
}

fn c2_master(b: u8) -> (usize, u8) {
    let k = (b % 4) as usize;
    (k, C2_MASTERS[k])
}

fn c2_ssap(src: &mut Src, b: u8) -> Option<u8> {
    match b >> 5 {
        0..=4 => Some(C2_SSAP),
        5 => Some(src.u8() & 0x3F),
        6 => Some(C1_SAP),
        _ => None,
    }
}

fn conn_sap(bus: &Bus, k: usize, b: u8) -> u8 {
    match (b >> 2) % 8 {
        0..=3 => bus.rm_sap[k].unwrap_or(48),
        4 => 48,
        5 => 47,
        6 => 46,
        _ => b >> 2,
    }
}

fn any_sap(src: &mut Src, b: u8) -> Option<u8> {
    match b % 12 {
        0 => None,
        1 => Some(C1_SAP),
        2 => Some(RM_SAP),
        3 | 4 => Some(CONN_SAPS[(b & 1) as usize]),
        5 => Some(46),
        6 => Some(60),
        7 => Some(61),
        8 => Some(62),
        9 => Some(50),
        _ => Some(src.u8() & 0x3F),
    }
}

fuzz_target!(|data: &[u8]| {
    let mut src = Src::new(data);
    let mut bus = Bus {
        node: pbcard::card::node(DpSlave::new(&pbcard::card::SLAVE, ME)),
        records: CardRecords::new(&pbcard::card::RECORDS),
        table: FakeDrive::new(),
        master: ScriptedMaster::new(M1, ME),
        now: 1_000,
        bytewise: false,
        last_frame: None,
        last_answer: None,
        acked: [None; 64],
        c1_epoch: 0,
        c1_was_open: false,
        c1_acked_epoch: 0,
        rm_sap: [None; 4],
    };

    // Bring-up as in host-tests/tests/dpv1.rs: Set_Prm (Lock, WD 1 s, DPV1_Enable) + Chk_Cfg.
    let module = src.u8() as usize;
    assert!(bus.parameterise(M1, 0x88, 0x80, module), "bring-up refused");
    assert_eq!(bus.node.slave().state(), DpState::DataExch);

    let mut steps = 0;
    while !src.is_empty() && steps < 300 {
        steps += 1;
        let op = src.u8();
        match op % 16 {
            // MSAC_C1 request from the locking master.
            0 | 1 => {
                let pdu = record_pdu(&mut src);
                bus.req(M1, Some(C1_SAP), Some(C1_SAP), &pdu);
            }
            // MSAC_C1 poll.
            2 => {
                bus.req(M1, Some(C1_SAP), Some(C1_SAP), &[]);
            }
            // SAP 51 from someone else or with another SSAP; request or poll.
            3 => {
                let b = src.u8();
                let sa = match b & 3 {
                    0 => M2,
                    1 => C2_MASTERS[(b >> 2) as usize % 3],
                    2 => M1,
                    _ => src.u8() & 0x7F,
                };
                let ssap = match (b >> 2) & 3 {
                    0 => Some(C1_SAP),
                    1 => Some(62),
                    2 => None,
                    _ => Some(src.u8() & 0x3F),
                };
                let pdu = if b & 0x40 != 0 { vec![] } else { record_pdu(&mut src) };
                bus.req(sa, Some(C1_SAP), ssap, &pdu);
            }
            // MSAC_C2: Initiate.req to the resource manager.
            4 => {
                let b = src.u8();
                let (_, sa) = c2_master(b);
                let ssap = c2_ssap(&mut src, b);
                let pdu = if b & 0x04 != 0 && b & 0x08 != 0 { record_pdu(&mut src) } else { initiate_pdu(&mut src) };
                bus.req(sa, Some(RM_SAP), ssap, &pdu);
            }
            // MSAC_C2: a whole connect (RM, Initiate on the server SAP, poll for Initiate.res).
            5 => {
                let b = src.u8();
                let (k, sa) = c2_master(b);
                let st = if b & 0x80 != 0 { u16::from(src.u8()) } else { 300 };
                let t = st.to_be_bytes();
                let init = [0x57, 0, 0, 0, t[0], t[1], 0x01, 0x00, 0, 0, 0, 0, 0, 2, 0, 2, 0, 0, 0, 0];
                bus.req(sa, Some(RM_SAP), Some(C2_SSAP), &init);
                if let Some(sap) = bus.rm_sap[k] {
                    bus.req(sa, Some(sap), Some(C2_SSAP), &init);
                    if b & 0x40 == 0 {
                        bus.req(sa, Some(sap), Some(C2_SSAP), &[]);
                    }
                }
            }
            // MSAC_C2: a request on a connection SAP.
            6 => {
                let b = src.u8();
                let (k, sa) = c2_master(b);
                let sap = conn_sap(&bus, k, b);
                let ssap = if b & 0x80 != 0 {
                    let sb = src.u8();
                    c2_ssap(&mut src, sb)
                } else {
                    Some(C2_SSAP)
                };
                let pdu = if src.u8().is_multiple_of(4) { initiate_pdu(&mut src) } else { record_pdu(&mut src) };
                bus.req(sa, Some(sap), ssap, &pdu);
            }
            // MSAC_C2: a poll on a connection SAP.
            7 => {
                let b = src.u8();
                let (k, sa) = c2_master(b);
                let sap = conn_sap(&bus, k, b);
                bus.req(sa, Some(sap), Some(C2_SSAP), &[]);
            }
            // SDN (Abort or anything) to a DP-V1 SAP, to us or broadcast.
            8 => {
                let b = src.u8();
                let (k, sa) = c2_master(b);
                let dsap = if b & 0x04 != 0 { any_sap(&mut src, b >> 3) } else { Some(conn_sap(&bus, k, b)) };
                let pdu = match (b >> 5) & 3 {
                    0 | 1 => vec![0x58, 0, 0x20 | (src.u8() & 0x0F), 0],
                    2 => record_pdu(&mut src),
                    _ => vec![],
                };
                let da = if b & 0x80 != 0 { telegram::BROADCAST } else { bus.own() };
                let fc = FunctionCode::request(if src.u8() & 1 == 0 { 0x04 } else { 0x06 }, false, false);
                bus.emit(&Header { da, sa, fc, dsap, ssap: Some(C2_SSAP) }, &pdu);
            }
            // The last frame again (an FCB retry when it was an SRD with FCV).
            9 => {
                if let Some(f) = bus.last_frame.clone() {
                    trace!("retry");
                    bus.deliver(&f);
                }
            }
            // Time passes (watchdog, Send_Timeout, reservations), then poll.
            10 => {
                let step = u64::from(src.u8()) << (src.u8() % 24);
                bus.now = bus.now.saturating_add(step);
                let ev = bus.node.poll(Instant::from_micros(bus.now));
                trace!("t={}us poll: {:?} {ev:?}", bus.now, bus.node.slave().state());
                bus.check();
            }
            // The DP-V1 task.
            11 => bus.process(),
            // Cyclic DP: Data_Exchange from the locking master, or a diagnosis read.
            12 => {
                let b = src.u8();
                if b & 1 == 0 {
                    let n = bus.node.slave().output_len();
                    let mut out = src.bytes(n).to_vec();
                    out.resize(n, 0);
                    bus.req(M1, None, None, &out);
                } else {
                    let sa = [M1, M2, 10, 11][((b >> 1) & 3) as usize];
                    let dsap = [60, 59, 56, 57][((b >> 3) & 3) as usize];
                    bus.req(sa, Some(dsap), Some(62), &[]);
                }
            }
            // Set_Prm + Chk_Cfg again (another master, without DPV1_Enable, 1 ms WD base …).
            13 => {
                let b = src.u8();
                let sa = if b & 1 == 0 { M1 } else { M2 };
                let status = if b & 2 == 0 { 0x88 } else { 0x80 | (src.u8() & 0x70) };
                let dpv1 = match (b >> 2) & 3 {
                    0 => 0x80,
                    1 => 0x00,
                    2 => 0x84,
                    _ => src.u8(),
                };
                let module = src.u8() as usize;
                bus.parameterise(sa, status, dpv1, module);
            }
            // A free-form request: any station, function, FCB/FCV, SAPs and PDU.
            14 => {
                let sa = src.u8() & 0x7F;
                let db = src.u8();
                let da = match db % 8 {
                    0 => telegram::BROADCAST,
                    1 => db >> 1,
                    _ => bus.own(),
                };
                let fb = src.u8();
                let mut fc = FunctionCode::request(fb & 0x0F, fb & 0x20 != 0, fb & 0x10 != 0);
                if fb & 0xC0 == 0xC0 {
                    fc = FunctionCode(src.u8());
                }
                let sb = src.u8();
                let dsap = any_sap(&mut src, sb);
                let ssap = if sb & 0x80 != 0 {
                    let b = src.u8();
                    any_sap(&mut src, b)
                } else {
                    Some(C2_SSAP)
                };
                let pdu = if sb & 0x40 != 0 {
                    let n = src.u8() as usize % (telegram::MAX_DU_LEN - 1);
                    src.bytes(n).to_vec()
                } else {
                    record_pdu(&mut src)
                };
                bus.emit(&Header { da, sa, fc, dsap, ssap }, &pdu);
            }
            // Framer on/off; raw bytes to the node.
            _ => {
                let b = src.u8();
                if b & 1 == 0 {
                    bus.bytewise = !bus.bytewise;
                    trace!("bytewise {}", bus.bytewise);
                } else {
                    let n = src.u8() as usize % (MAX_FRAME_LEN + 8);
                    let mut f = src.bytes(n).to_vec();
                    if b & 2 != 0 {
                        // Repair FCS and ED so that the frame gets past them.
                        src::repair_frame(&mut f);
                    }
                    bus.deliver(&f);
                }
            }
        }
    }
    // Whatever was left: let the task run and every master poll once more.
    bus.process();
    bus.req(M1, Some(C1_SAP), Some(C1_SAP), &[]);
    for (k, &m) in C2_MASTERS.iter().enumerate() {
        if let Some(sap) = bus.rm_sap[k] {
            bus.req(m, Some(sap), Some(C2_SSAP), &[]);
        }
    }
});
