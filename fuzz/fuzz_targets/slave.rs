//! A whole `DpSlave` behind an FDL `Station`, brought to data exchange with a valid
//! Set_Prm / Chk_Cfg (as in src/dp_tests/slave.rs), then driven by a sequence of operations derived
//! from the fuzz input: requests with fuzz-chosen SAPs, function codes, FCB/FCV, source and
//! destination addresses and PDUs; templates of the DP services with fuzzed fields; raw
//! frames; FCB retries; time steps (watchdog); application actions (set_inputs, set_ext_diag,
//! set_stat_diag, take_events).
//!
//! Checks after every frame: no panic; every response decodes as a valid frame of exactly its
//! length, is a short acknowledge or a response frame from our address to the requester
//! (Data_Exchange answers carry `input_len()` bytes, diagnosis answers six well-formed
//! standard octets); nothing answers a broadcast or another station; `outputs().len() ==
//! output_len()` and `inputs().len() == input_len()`; outputs are zero outside data exchange;
//! data exchange implies a locking master and a module. An immediate FCB retry (same bytes, FCV = 1, SRD)
//! gets the previous answer byte for byte, whatever the application did in between.
#![no_main]

#[path = "common/src.rs"]
#[macro_use]
mod src;

use libfuzzer_sys::fuzz_target;
use pbcard::card;
use pbcard::dp::{DpSlave, DpState};
use pbcard::fdl::station::Station;
use pbcard::fdl::telegram::{self, Decoded, FunctionCode, Header, RequestFunction, Telegram, MAX_FRAME_LEN};
use pbcard::testkit::{self, ScriptedMaster, SetPrm, SAP_MASTER};
use pbcard::time::Instant;
use src::Src;

const ME: u8 = 8;
const M1: u8 = 2;
const M2: u8 = 3;

struct Bus {
    station: Station,
    slave: DpSlave,
    master: ScriptedMaster,
    now: u64,
    /// The last frame handed to the station and its answer (for the retry check).
    last: Option<(Vec<u8>, Option<Vec<u8>>)>,
}

impl Bus {
    fn deliver(&mut self, frame: &[u8]) -> Option<Vec<u8>> {
        self.now += 200;
        let now = Instant::from_micros(self.now);
        self.slave.poll(now);
        let own = self.slave.address();
        let resp = self.station.on_frame(now, frame, &mut self.slave).map(|r| r.to_vec());
        trace!(
            "t={}us {frame:02x?} -> {resp:02x?}  [{:?} master {:?} out {:02x?} in {:02x?}]",
            self.now,
            self.slave.state(),
            self.slave.master_address(),
            self.slave.outputs(),
            self.slave.inputs()
        );
        // The station decodes the telegram at the start of `frame` and ignores trailing bytes.
        let req = match telegram::decode(frame) {
            Decoded::Frame(Telegram::Data(t), _) => Some(t),
            _ => None,
        };
        if let Some(r) = &resp {
            let req = req.unwrap_or_else(|| panic!("answer {r:02x?} to a non-telegram {frame:02x?}"));
            assert_eq!(req.da, own, "answer {r:02x?} to a frame for station {} (we are {own})", req.da);
            match telegram::decode(r) {
                Decoded::Frame(Telegram::ShortAck, 1) => {}
                Decoded::Frame(Telegram::Data(t), n) if n == r.len() => {
                    assert_eq!(t.sa, own, "answer {r:02x?} not from our address {own}");
                    assert_eq!(t.da, req.sa, "answer {r:02x?} not to the requester {}", req.sa);
                    assert!(!t.fc.is_request(), "answer {r:02x?} has a request FC");
                    match (t.dsap, t.ssap) {
                        // Data_Exchange: the configured inputs, DL or DH.
                        (None, None) if !t.pdu.is_empty() => {
                            assert_eq!(t.pdu.len(), self.slave.input_len(), "Data_Exchange answer {r:02x?}");
                            assert!(matches!(t.fc.0, 0x08 | 0x0A), "Data_Exchange answer {r:02x?}");
                        }
                        // Slave_Diag: six standard octets (Status_2 b2 = 1, our ident) + blocks.
                        (_, Some(60)) => {
                            let p = t.pdu;
                            assert!(p.len() >= 6 && p.len() <= card::MAX_DIAG_DATA_LEN, "diag answer {r:02x?}");
                            assert!(p[1] & 0x04 != 0, "diag answer {r:02x?}: Status_2 b2 not set");
                            assert_eq!(p[4..6], card::IDENT_NUMBER.to_be_bytes(), "diag answer {r:02x?}");
                        }
                        _ => {}
                    }
                }
                other => panic!("slave sent {r:02x?} = {other:?} for request {frame:02x?}"),
            }
        }
        self.check();
        self.last = Some((frame.to_vec(), resp.clone()));
        resp
    }

    fn check(&self) {
        let s = &self.slave;
        assert_eq!(s.outputs().len(), s.output_len());
        assert_eq!(s.inputs().len(), s.input_len());
        assert!(s.address() <= card::MAX_STATION_ADDRESS);
        if s.state() == DpState::DataExch {
            assert!(s.master_address().is_some() && s.module().is_some(), "Data_Exch without master/module");
        } else {
            assert!(s.outputs().iter().all(|&b| b == 0), "outputs {:02x?} outside Data_Exch", s.outputs());
        }
    }

    fn emit(&mut self, hdr: &Header, pdu: &[u8]) -> Option<Vec<u8>> {
        let f = testkit::try_frame(hdr, pdu).ok()?;
        self.deliver(&f)
    }

    /// SRD high from `sa` with FCB toggled and FCV = 1 (as a master in data exchange).
    fn req(&mut self, sa: u8, dsap: Option<u8>, pdu: &[u8]) -> Option<Vec<u8>> {
        self.master.slave = self.slave.address();
        let f = self.master.try_request(sa, dsap, dsap.map(|_| SAP_MASTER), pdu, true).ok()?;
        self.deliver(&f)
    }

    /// Repeat the last frame; if it was an SRD to us with FCV = 1 that got an answer, the
    /// station must answer the retry with the same bytes.
    fn retry(&mut self) {
        let Some((frame, prev)) = self.last.clone() else { return };
        let own = self.slave.address();
        let is_retry = match telegram::decode(&frame) {
            Decoded::Frame(Telegram::Data(t), _) => {
                t.da == own
                    && t.fc.is_request()
                    && t.fc.fcv()
                    && matches!(t.fc.function(), RequestFunction::SrdLow | RequestFunction::SrdHigh)
            }
            _ => false,
        };
        let again = self.deliver(&frame);
        if is_retry && prev.is_some() {
            assert_eq!(again, prev, "FCB retry of {frame:02x?} answered differently");
        }
    }
}

fn pick_sa(b: u8) -> u8 {
    match b % 8 {
        0..=3 => M1,
        4 | 5 => M2,
        _ => b >> 1,
    }
}

fn pick_da(bus: &Bus, b: u8) -> u8 {
    match b % 16 {
        0 => telegram::BROADCAST,
        1 => b >> 1,
        2 => ME,
        _ => bus.slave.address(),
    }
}

fn pick_sap(b: u8) -> Option<u8> {
    match b % 16 {
        0..=2 => None,
        3..=10 => Some(55 + (b % 16) - 3),
        _ => Some((b >> 2) & 0x3F),
    }
}

const FUNCTIONS: [u8; 12] = [0x0D, 0x0C, 0x06, 0x04, 0x09, 0x03, 0x05, 0x07, 0x0E, 0x0F, 0x00, 0x01];

fn set_prm_pdu(status: u8, wd1: u8, wd2: u8, tsdr: u8, group: u8, user: &[u8]) -> Vec<u8> {
    let id = card::IDENT_NUMBER.to_be_bytes();
    let mut p = vec![status, wd1, wd2, tsdr, id[0], id[1], group];
    p.extend_from_slice(user);
    p
}

fuzz_target!(|data: &[u8]| {
    let mut src = Src::new(data);
    let mut bus = Bus {
        station: Station::new(),
        slave: DpSlave::new(&pbcard::card::SLAVE, ME),
        master: ScriptedMaster::new(M1, ME),
        now: 0,
        last: None,
    };

    // Bring-up as in src/dp_tests/slave.rs: Set_Prm (Lock, optional Sync/Freeze, WD 1 s or 100 ms)
    // and Chk_Cfg for a fuzz-chosen module.
    let b0 = src.u8();
    let status = [0x88, 0xB8, 0x80, 0xB0, 0x98, 0xA8][(b0 % 6) as usize];
    let mut user = card::USER_PRM_DEFAULTS;
    if b0 & 0x80 != 0 {
        user[0] = 0x04; // WD_Base_1ms
    }
    let module = &card::MODULES[(src.u8() as usize) % card::MODULES.len()];
    let p = SetPrm::CARD.station_status(status).wd_factors(10, 10).group(0x01).user(user).pdu();
    assert_eq!(bus.req(M1, Some(61), &p), Some(vec![telegram::SC]));
    assert_eq!(bus.req(M1, Some(62), module.cfg), Some(vec![telegram::SC]));
    assert_eq!(bus.slave.state(), DpState::DataExch);
    assert_eq!(bus.slave.output_len(), module.outputs as usize);

    let mut steps = 0;
    while !src.is_empty() && steps < 400 {
        steps += 1;
        let op = src.u8();
        match op % 16 {
            // A request with every field chosen by the input.
            0..=2 => {
                let sa = pick_sa(src.u8());
                let da = pick_da(&bus, src.u8());
                let fb = src.u8();
                let func = if fb & 0x0F == 0x0F { src.u8() & 0x0F } else { FUNCTIONS[(fb & 0x0F) as usize % 12] };
                let mut fc = FunctionCode::request(func, fb & 0x20 != 0, fb & 0x10 != 0);
                if fb & 0xC0 == 0xC0 {
                    fc = FunctionCode(src.u8()); // anything, responses included
                }
                let sb = src.u8();
                let dsap = pick_sap(sb);
                let ssap = match sb >> 6 {
                    0 => None,
                    1 => Some(src.u8() & 0x3F),
                    _ => dsap.map(|_| 62),
                };
                let lb = src.u8();
                let len = if lb & 0x80 != 0 { lb as usize + 100 } else { (lb & 0x3F) as usize };
                let len = len.min(telegram::MAX_DU_LEN - 2);
                let pdu = src.bytes(len).to_vec();
                bus.emit(&Header { da, sa, fc, dsap, ssap }, &pdu);
            }
            // Data_Exchange from the locking master (right length mostly).
            3 | 4 => {
                let n = match src.u8() % 8 {
                    0 => 0,
                    1 => src.u8() as usize % 40,
                    _ => bus.slave.output_len(),
                };
                let pdu = src.bytes(n).to_vec();
                let sa = if op & 0x80 != 0 { pick_sa(src.u8()) } else { M1 };
                bus.req(sa, None, &pdu);
            }
            // Set_Prm with fuzzed fields.
            5 => {
                let sa = pick_sa(src.u8());
                let st = src.u8();
                let status = if st & 1 != 0 { st } else { st & 0xF8 };
                let (wd1, wd2, tsdr, group) = (src.u8() % 8, src.u8() % 8, src.u8(), src.u8());
                let ub = src.u8();
                let user: Vec<u8> = if ub & 1 == 0 {
                    card::USER_PRM_DEFAULTS[..(ub as usize >> 1) % 6].to_vec()
                } else {
                    src.bytes((ub as usize >> 1) % 8).to_vec()
                };
                let p = set_prm_pdu(status, wd1, wd2, tsdr, group, &user);
                bus.req(sa, Some(61), &p);
            }
            // Chk_Cfg: a module of the card or fuzz bytes.
            6 => {
                let sa = pick_sa(src.u8());
                let c = src.u8();
                let cfg: Vec<u8> = if c & 0x80 == 0 {
                    card::MODULES[c as usize % card::MODULES.len()].cfg.to_vec()
                } else {
                    src.bytes((c & 0x0F) as usize).to_vec()
                };
                bus.req(sa, Some(62), &cfg);
            }
            // Global_Control (SDN), broadcast or to us.
            7 => {
                let sa = pick_sa(src.u8());
                let db = src.u8();
                let da = if db & 1 == 0 { telegram::BROADCAST } else { pick_da(&bus, db >> 1) };
                let n = if db & 0x80 != 0 { (src.u8() % 4) as usize } else { 2 };
                let pdu = src.bytes(n).to_vec();
                let fc = FunctionCode::request(if db & 0x40 != 0 { 0x04 } else { 0x06 }, false, false);
                bus.emit(&Header { da, sa, fc, dsap: Some(58), ssap: Some(62) }, &pdu);
            }
            // Set_Slave_Add (right ident mostly).
            8 => {
                let sa = pick_sa(src.u8());
                let id = card::IDENT_NUMBER.to_be_bytes();
                let (addr, flag, ib) = (src.u8(), src.u8() & 1, src.u8());
                let pdu = if ib & 7 == 0 { vec![addr, ib, id[1], flag] } else { vec![addr, id[0], id[1], flag] };
                bus.req(sa, Some(55), &pdu);
            }
            // Slave_Diag / Get_Cfg / Rd_Inp / Rd_Outp from any master.
            9 => {
                let sa = pick_sa(src.u8());
                let sap = [60, 59, 56, 57][(src.u8() % 4) as usize];
                bus.req(sa, Some(sap), &[]);
            }
            // FCB retry of the last frame.
            10 => {
                trace!("retry");
                bus.retry();
            }
            // Time passes (watchdog), then poll.
            11 => {
                let step = u64::from(src.u8()) << (src.u8() % 24);
                bus.now = bus.now.saturating_add(step);
                bus.slave.poll(Instant::from_micros(bus.now));
                trace!("t={}us poll: {:?}", bus.now, bus.slave.state());
                bus.check();
            }
            // Application: new inputs.
            12 => {
                let n = src.u8() as usize % 40;
                let d = src.bytes(n).to_vec();
                bus.slave.set_inputs(&d);
                trace!("set_inputs {d:02x?}");
                bus.check();
            }
            // Application: extended diagnosis (a valid block sequence or fuzz bytes).
            13 => {
                let b = src.u8();
                let blocks: Vec<u8> = if b & 1 == 0 {
                    let mut v = vec![];
                    for _ in 0..(b >> 1) % 6 {
                        match src.u8() % 3 {
                            0 => {
                                let l = 2 + src.u8() as usize % 6;
                                v.push(l as u8);
                                v.extend((1..l).map(|i| i as u8));
                            }
                            1 => v.extend_from_slice(&[0x42, src.u8()]),
                            _ => v.extend_from_slice(&[0x80 | (src.u8() & 0x3F), 0x41, 0x25]),
                        }
                    }
                    v
                } else {
                    src.bytes((b >> 1) as usize % 70).to_vec()
                };
                let r = bus.slave.set_ext_diag(&blocks, b & 2 != 0);
                trace!("set_ext_diag {blocks:02x?} -> {r:?}");
                bus.check();
            }
            // Application: Stat_Diag, events.
            14 => {
                bus.slave.set_stat_diag(op & 0x10 != 0);
                let ev = bus.slave.take_events();
                trace!("set_stat_diag {}, events {ev:?}", op & 0x10 != 0);
                let _ = bus.slave.standard_diag().encode();
                bus.check();
            }
            // A raw frame; with bit 4 set, FCS and ED are repaired so it passes the checks
            // that come after them (extension bytes, addressing).
            _ => {
                let n = src.u8() as usize % (MAX_FRAME_LEN + 8);
                let mut f = src.bytes(n).to_vec();
                if op & 0x10 != 0 {
                    src::repair_frame(&mut f);
                }
                bus.deliver(&f);
            }
        }
    }
});
