//! The monitor judged on telegrams the project's own card produces and on the manuals' byte
//! examples:
//!
//! * a capture *recorded* from the card's shipped stack (`Node` + `Application`, the soft slave's
//!   core) talking to the scripted DP master of `pbcard::testkit` on a simulated 19.2 kbit/s line
//!   with exact times: bring-up, data exchange, a DP-V1 record-47 parameter read, Global_Control,
//!   one lost answer and its retry — replayed from the capture format and decoded with every
//!   request matched to its response and no `Unknown`;
//! * a second recorded session with I&M (an I&M1 write, I&M0 / I&M1 reads over MSAC_C1 and over
//!   an MSAC_C2 connection, each with its own call) and MSAC_C2 Data_Transport of record 47 and
//!   of I&M1, its decoded lines asserted field by field;
//! * garbage between frames, and the same bytes as raw input (cut by syntax, no times);
//! * the VACON OPTE3/E5 §6.4.4 and WEG CFW-11 §4.2.5 parameter-access examples decoded field by
//!   field.

use pbcard::card;
use pbcard::fdl::telegram::{FunctionCode, Header, ResponseStatus};
use pbcard::testkit::{self, CardRig, Rig, SetPrm};
use pbcard::time::{Baudrate, BitTimes, Duration, Instant};
use pbcard_monitor::capture::Writer;
use pbcard_monitor::product::Product;
use pbcard_monitor::{decode_raw, replay, Line};
use pbcard_sim::bench::Application;
use pbcard_sim::drive::DriveConfig;

const RATE: Baudrate = Baudrate::B19200;
const MASTER: u8 = 2;
const SLAVE: u8 = 5;

/// The card on a simulated line with exact times, every byte written to a capture: the one
/// card rig (`CardRig`: the shipped node, the bench's card and drive, the scripted master, the
/// clock) with the line's capture around it.
struct Bus {
    rig: CardRig<Application>,
    capture: Writer<Vec<u8>>,
    /// Every telegram on the line, in order (the raw byte stream).
    raw: Vec<u8>,
}

impl Bus {
    fn new() -> Self {
        let mut app = Application::new(DriveConfig::DEFAULT);
        app.set_baudrate(Some(RATE));
        let mut rig = CardRig::new(app, MASTER, SLAVE);
        rig.now = Instant::from_micros(1_000_000);
        Bus { rig, capture: Writer::new(Vec::new(), Some(RATE)).unwrap(), raw: Vec::new() }
    }

    /// The line's clock advanced by `bits` bit times.
    fn wait(&mut self, bits: u32) {
        self.rig.now = self.rig.now + Duration::from_micros(Self::us(bits));
    }

    fn us(bits: u32) -> u64 {
        RATE.bits_to_duration(bits).as_micros()
    }

    fn put(&mut self, bytes: &[u8]) {
        self.wait(11 * bytes.len() as u32);
        self.capture.bytes(Some(self.rig.now.as_micros()), bytes).unwrap();
        self.raw.extend_from_slice(bytes);
    }

    /// A request on the line; the card's answer after its min_TSDR (unless `lose` it).
    fn send(&mut self, frame: &[u8], lose: bool) -> Option<Vec<u8>> {
        self.put(frame);
        let answer = self.rig.deliver(frame).map(|f| f.to_vec());
        if let Some(a) = &answer {
            self.wait(self.rig.node.min_tsdr().0);
            if lose {
                // The answer is lost on the line: the master hears nothing within its slot time.
                self.wait(11 * a.len() as u32);
            } else {
                self.put(a);
            }
        }
        // The line is idle before the next request; the card runs its cycle.
        self.wait(100);
        self.rig.node.on_idle(BitTimes(100));
        self.rig.step(0);
        self.rig.acyclic();
        answer
    }

    fn srd(&mut self, dsap: Option<u8>, pdu: &[u8]) -> Vec<u8> {
        let f = self.rig.master.srd(dsap, pdu);
        self.send(&f, false).expect("an answer")
    }

    /// A DP-V1 MSAC_C1 request (SAP 51 ↔ 51), then polls until the response PDU comes.
    fn c1(&mut self, pdu: &[u8]) -> Vec<u8> {
        let f = self.rig.master.request(MASTER, Some(51), Some(51), pdu, true);
        let r = self.send(&f, false).expect("an answer");
        assert_eq!(r, [0xE5], "the request is acknowledged with SC");
        for _ in 0..20 {
            let poll = self.rig.master.request(MASTER, Some(51), Some(51), &[], true);
            let r = self.send(&poll, false).expect("an answer");
            if r != [0xE5] {
                return r;
            }
        }
        panic!("no DP-V1 response");
    }
}

/// Record the session; its capture text and raw bytes.
fn session() -> (String, Vec<u8>) {
    let mut b = Bus::new();
    // FDL_Status: the master's GAP poll.
    let fdl = testkit::frame(
        &Header { da: SLAVE, sa: MASTER, fc: FunctionCode::request(0x9, false, false), dsap: None, ssap: None },
        &[],
    );
    assert!(b.send(&fdl, false).is_some());
    b.srd(Some(60), &[]);
    // Set_Prm with DPV1_Enable, Lock_Req, WD_On (1 × 100 × 10 ms); Chk_Cfg Standard telegram 1.
    b.srd(Some(61), &SetPrm::CARD.dpv1_status_1(0x80).pdu());
    b.srd(Some(62), card::MODULES[0].cfg);
    b.srd(Some(60), &[]);
    // Data exchange: STW1 047E then 047F with 50 % setpoint.
    for k in 0..6 {
        let stw: u16 = if k < 2 { 0x047E } else { 0x047F };
        let mut out = stw.to_be_bytes().to_vec();
        out.extend_from_slice(&0x2000u16.to_be_bytes());
        b.srd(None, &out);
    }
    // One lost answer and the master's retry (same FCB: the card answers from its stored response).
    let dx = b.rig.master.srd(None, &[0x04, 0x7F, 0x20, 0x00]);
    assert!(b.send(&dx, true).is_some());
    assert!(b.send(&dx, false).is_some());
    // DP-V1: read PNU 918 (station address) through record 47 (VACON Table 55 shape, axis 1).
    let write = [0x5F, 0x00, 0x2F, 0x0A, 0x01, 0x01, 0x01, 0x01, 0x10, 0x01, 0x03, 0x96, 0x00, 0x00];
    let ack = b.c1(&write);
    assert_eq!(ack[ack.len() - 6..ack.len() - 2], [0x5F, 0x00, 0x2F, 0x0A], "write acknowledged");
    let resp = b.c1(&[0x5E, 0x00, 0x2F, 0xF0]);
    assert!(resp.len() > 12, "a parameter response");
    b.srd(None, &[0x04, 0x7F, 0x20, 0x00]);
    // Global_Control Clear_Data to all (SDN broadcast, no answer).
    let gc = testkit::frame(
        &Header { da: 127, sa: MASTER, fc: FunctionCode::request(0x6, false, false), dsap: Some(58), ssap: Some(62) },
        &[0x02, 0x00],
    );
    assert!(b.send(&gc, false).is_none());
    let text = String::from_utf8(b.capture.into_inner()).unwrap();
    (text, b.raw)
}

fn find<'a>(lines: &'a [Line], pred: impl Fn(&Line) -> bool, what: &str) -> &'a Line {
    lines.iter().find(|l| pred(l)).unwrap_or_else(|| panic!("no line {what}:\n{}", dump(lines)))
}

fn dump(lines: &[Line]) -> String {
    lines.iter().map(Line::text_line).collect::<Vec<_>>().join("\n")
}

#[test]
fn a_recorded_card_session_replays_with_every_request_matched() {
    let (text, _) = session();
    let (lines, mon) = replay(Product::card(), &text, None);
    let all = dump(&lines);
    // Nothing unknown, nothing garbage; exactly the one lost answer is missing.
    assert!(lines.iter().all(|l| l.service != "Unknown" && l.kind != "garbage"), "{all}");
    let missing: Vec<&Line> = lines.iter().filter(|l| l.kind == "no_response").collect();
    assert_eq!(missing.len(), 1, "{all}");
    assert_eq!(missing[0].service, "Data_Exchange");
    let st = &mon.stations()[&SLAVE];
    assert_eq!(
        (st.requests, st.answered + st.missing, st.missing, st.retries),
        (st.requests, st.requests, 1, 1),
        "{all}"
    );
    assert_eq!(st.state, "Data_Exch");
    assert_eq!(st.module.as_deref(), Some("Standard telegram 1, PZD-2/2"));
    assert_eq!(st.late, 0, "{all}");
    // Every response time is the card's min_TSDR (11 bit) within the µs rounding.
    assert!(st.tsdr_bits.n >= 15 && st.tsdr_bits.min >= 10 && st.tsdr_bits.max <= 12, "{:?}\n{all}", st.tsdr_bits);
    // Data_Exchange every 11 bytes out + 11 back + gaps: the cycle is measured.
    assert!(st.cycle_us.n >= 6 && st.cycle_us.min > 0, "{:?}", st.cycle_us);

    // Field by field.
    let fdl = find(&lines, |l| l.request == Some("FDL_Status"), "FDL_Status response");
    assert_eq!((fdl.sd, fdl.fc.as_deref()), (Some("SD1"), Some("OK")));
    assert!(fdl.text.contains("station type: slave"));
    let diag = find(&lines, |l| l.request == Some("Slave_Diag"), "Slave_Diag response");
    assert!(diag.text.contains("Station_status_1 02 (Station_Not_Ready)"), "{}", diag.text);
    assert!(diag.text.contains("Station_status_2 05 (Prm_Req)"), "{}", diag.text);
    assert!(diag.text.contains("Master_Add none, Ident_Number 0x0F11"), "{}", diag.text);
    let prm = find(&lines, |l| l.service == "Set_Prm", "Set_Prm");
    assert_eq!((prm.dsap, prm.ssap), (Some(61), Some(62)));
    for part in [
        "Station_Status 88 (Lock_Req WD_On)",
        "watchdog 1×100×10 ms = 1000 ms",
        "min_TSDR 11 bit",
        "Ident_Number 0x0F11, Group_Ident 0x00",
        "DPV1_Status 80 (DPV1_Enable) 00 (-) 00 (Alarm_Mode 1; -)",
        "Operate mode = 0, Communication loss reaction = 0",
    ] {
        assert!(prm.text.contains(part), "'{part}' in {}", prm.text);
    }
    assert!(!prm.text.contains("refuses"), "{}", prm.text);
    let cfg = find(&lines, |l| l.service == "Chk_Cfg", "Chk_Cfg");
    assert!(
        cfg.text
            .contains("C3 C1 C1 FD 00 01 = module \"Standard telegram 1, PZD-2/2\", inputs 4 bytes, outputs 4 bytes"),
        "{}",
        cfg.text
    );
    let dx = find(&lines, |l| l.service == "Data_Exchange" && l.text.contains("047F"), "Data_Exchange 047F");
    assert!(
        dx.text.contains("STW1 047F (ON No_OFF2 No_OFF3 Enable_operation Enable_ramp Unfreeze_ramp Enable_setpoint Control_by_PLC), NSOLL_A 2000 (+50.0 %)"),
        "{}",
        dx.text
    );
    let running =
        find(&lines, |l| l.request == Some("Data_Exchange") && l.text.contains("Operation_enabled"), "ZSW1 running");
    assert!(running.text.starts_with("inputs ZSW1 "), "{}", running.text);
    assert_eq!(running.fc.as_deref(), Some("DL"));
    let retry = find(&lines, |l| l.retry, "retry");
    assert_eq!(retry.service, "Data_Exchange");
    // DP-V1: the record-47 write, the polls, the read with PNU 918's value (the station address).
    let w = find(&lines, |l| l.service == "DS_Write" && !l.poll, "DS_Write");
    assert_eq!((w.slot, w.index, w.pnu, w.dsap), (Some(0), Some(47), Some(918), Some(51)));
    assert!(
        w.text.contains("PROFIdrive request parameter, ref 1, axis 1: PNU 918 (station address) value"),
        "{}",
        w.text
    );
    let r = find(&lines, |l| l.request == Some("DS_Read") && l.sd == Some("SD2"), "DS_Read response");
    assert_eq!((r.index, r.pnu), (Some(47), Some(918)));
    assert!(
        r.text.contains("PROFIdrive response 01 request parameter ok, ref 1, axis 1, 1 parameters: PNU 918 = "),
        "{}",
        r.text
    );
    assert!(r.text.ends_with(&format!("PNU 918 = Word 0x{SLAVE:04X} ({SLAVE})")), "{}", r.text);
    assert!(lines.iter().any(|l| l.poll && l.service == "DS_Read"), "{all}");
    let gc = find(&lines, |l| l.service == "Global_Control", "Global_Control");
    assert!(gc.text.contains("Control_Command 02 (Clear_Data), Group_Select 00 (all groups)"), "{}", gc.text);

    // JSON carries the fields the issue names.
    let j: serde_json::Value = serde_json::from_str(&w.json()).unwrap();
    for k in ["t", "sd", "da", "sa", "fc", "service", "dsap", "ssap", "slot", "index", "pnu"] {
        assert!(j.get(k).is_some(), "{k} in {j}");
    }
    assert_eq!(j["service"], "DS_Write");
    let summary = mon.summary();
    assert!(summary.contains("Data_Exch"), "{summary}");
}

#[test]
fn raw_bytes_with_garbage_between_frames_are_cut_by_syntax() {
    let (_, raw) = session();
    // Garbage before, between (a broken telegram, noise) and a truncated telegram at the end.
    let mut bytes = vec![0x00, 0xFF, 0x42];
    let split = raw.iter().position(|&b| b == 0x68).unwrap();
    bytes.extend_from_slice(&raw[..split]);
    bytes.extend_from_slice(&[0x68, 0x05, 0x06, 0x68, 0x13]);
    bytes.extend_from_slice(&raw[split..]);
    bytes.extend_from_slice(&[0x68, 0x09, 0x09]);
    let (lines, mon) = decode_raw(Product::card(), None, &bytes);
    let all = dump(&lines);
    let garbage: Vec<&Line> = lines.iter().filter(|l| l.kind == "garbage").collect();
    assert_eq!(garbage.len(), 3, "{all}");
    assert!(garbage[0].text.contains("no start delimiter"), "{}", garbage[0].text);
    assert!(garbage[1].text.contains("LengthMismatch"), "{}", garbage[1].text);
    assert!(garbage[2].text.contains("truncated"), "{}", garbage[2].text);
    // Every telegram of the session is still found and matched.
    let st = &mon.stations()[&SLAVE];
    assert_eq!((st.missing, st.retries), (1, 1), "{all}");
    assert!(lines.iter().filter(|l| l.kind == "telegram").all(|l| l.service != "Unknown"), "{all}");
    // Without times there is no timing judgement.
    assert!(lines.iter().all(|l| l.t.is_none() && l.tsdr_bits.is_none()));
}

#[test]
fn a_corrupt_capture_line_is_shown_and_the_replay_goes_on() {
    let (text, _) = session();
    let mut lines_in: Vec<&str> = text.lines().collect();
    lines_in.insert(5, "12.x 10 02");
    lines_in.insert(7, "3.000000 !");
    let (lines, mon) = replay(Product::card(), &lines_in.join("\n"), None);
    assert!(lines.iter().any(|l| l.error.as_deref().is_some_and(|e| e.starts_with("capture line 6"))));
    assert!(lines.iter().any(|l| l.error.as_deref().is_some_and(|e| e.contains("character error"))));
    assert!(mon.stations()[&SLAVE].answered > 10);
}

fn c1_frame(request: bool, pdu: &[u8]) -> Vec<u8> {
    let hdr = if request {
        Header { da: 3, sa: MASTER, fc: FunctionCode::request(0xD, true, true), dsap: Some(51), ssap: Some(51) }
    } else {
        Header { da: MASTER, sa: 3, fc: FunctionCode::response(ResponseStatus::Dl), dsap: Some(51), ssap: Some(51) }
    };
    testkit::frame(&hdr, pdu).to_vec()
}

/// The request's PDU and the response PDU through the monitor: the response line's text.
fn exchange(write: &[u8], read_resp: &[u8]) -> (String, String) {
    let mut bytes = c1_frame(true, write);
    bytes.push(0xE5);
    bytes.extend(c1_frame(true, &[0x5E, 0x00, 0x2F, 0xF0]));
    bytes.push(0xE5);
    bytes.extend(c1_frame(true, &[]));
    bytes.extend(c1_frame(false, read_resp));
    let (lines, _) = decode_raw(Product::card(), None, &bytes);
    assert!(lines.iter().all(|l| l.service != "Unknown"), "{}", dump(&lines));
    (lines[0].text.clone(), lines.last().unwrap().text.clone())
}

#[test]
fn vacon_opte3_e5_6_4_4_parameter_access_field_by_field() {
    // §6.4.4.1 Table 55 / §6.4.4.2 Table 58: read PNU 918 → 3.
    let (req, resp) = exchange(
        &[0x5F, 0x00, 0x2F, 0x0A, 0x01, 0x01, 0x01, 0x01, 0x10, 0x01, 0x03, 0x96, 0x00, 0x00],
        &[0x5E, 0x00, 0x2F, 0x08, 0x01, 0x01, 0x01, 0x01, 0x42, 0x01, 0x00, 0x03],
    );
    assert_eq!(req, "MSAC_C1 slot 0 index 47 length 10: PROFIdrive request parameter, ref 1, axis 1: PNU 918 (station address) value");
    assert_eq!(resp, "slot 0 index 47 length 8: PROFIdrive response 01 request parameter ok, ref 1, axis 1, 1 parameters: PNU 918 = Word 0x0003 (3)");
    // §6.4.4.5 Table 67 / §6.4.4.6 Table 70: PNU 900 → error 0x00.
    let (_, resp) = exchange(
        &[0x5F, 0x00, 0x2F, 0x0A, 0x03, 0x01, 0x01, 0x01, 0x10, 0x01, 0x03, 0x84, 0x00, 0x00],
        &[0x5E, 0x00, 0x2F, 0x08, 0x03, 0x81, 0x01, 0x01, 0x44, 0x01, 0x00, 0x00],
    );
    assert!(resp.ends_with("81 request parameter NEGATIVE, ref 3, axis 1, 1 parameters: PNU 900 = error 0x00 impermissible parameter number"), "{resp}");
    // §6.4.4.7 Table 71 / 74: drive parameter ID 103 through PNU 10001 → 30.
    let (req, resp) = exchange(
        &[0x5F, 0x00, 0x2F, 0x0A, 0x04, 0x01, 0x01, 0x01, 0x10, 0x01, 0x27, 0x11, 0x00, 0x67],
        &[0x5E, 0x00, 0x2F, 0x08, 0x04, 0x01, 0x01, 0x01, 0x42, 0x01, 0x00, 0x1E],
    );
    assert!(req.ends_with("PNU 10001[103] (drive parameter (application ID in the subindex)) value"), "{req}");
    assert!(resp.ends_with("PNU 10001 = Word 0x001E (30)"), "{resp}");
    // §6.4.4.8 Table 75 / 78: change ID 103 to 40; the positive change response is the header.
    let (req, resp) = exchange(
        &[0x5F, 0x00, 0x2F, 0x0E, 0x05, 0x02, 0x01, 0x01, 0x10, 0x01, 0x27, 0x11, 0x00, 0x67, 0x42, 0x01, 0x00, 0x28],
        &[0x5E, 0x00, 0x2F, 0x04, 0x05, 0x02, 0x01, 0x01],
    );
    assert!(
        req.contains("change parameter, ref 5, axis 1: PNU 10001[103]") && req.ends_with("value := Word 0x0028 (40)"),
        "{req}"
    );
    assert!(resp.ends_with("02 change parameter ok, ref 5, axis 1, 1 parameters"), "{resp}");
    // §6.4.4.9 Table 79 / 82: change to 0 → error 0x02.
    let (_, resp) = exchange(
        &[0x5F, 0x00, 0x2F, 0x0E, 0x06, 0x02, 0x01, 0x01, 0x10, 0x01, 0x27, 0x11, 0x00, 0x67, 0x42, 0x01, 0x00, 0x00],
        &[0x5E, 0x00, 0x2F, 0x08, 0x06, 0x82, 0x01, 0x01, 0x44, 0x01, 0x00, 0x02],
    );
    assert!(resp.ends_with("82 change parameter NEGATIVE, ref 6, axis 1, 1 parameters: PNU 10001 = error 0x02 low or high limit exceeded"), "{resp}");
    // A negative DP-V1 response (VACON Table 46): DE 80 B0 00 → invalid index.
    let (_, resp) = exchange(
        &[0x5F, 0x00, 0x2F, 0x0A, 0x01, 0x01, 0x01, 0x01, 0x10, 0x01, 0x03, 0x96, 0x00, 0x00],
        &[0xDE, 0x80, 0xB0, 0x00],
    );
    assert_eq!(
        resp,
        "NEGATIVE DS_Read: Error_Decode 80 (DP-V1), Error_Code_1 B0 (access: invalid index), Error_Code_2 00"
    );
}

#[test]
fn weg_cfw11_4_2_5_examples_field_by_field() {
    let ds_write = |d: &[u8]| [&[0x5F, 0x00, 0x2F, d.len() as u8][..], d].concat();
    let ds_resp = |d: &[u8]| [&[0x5E, 0x00, 0x2F, d.len() as u8][..], d].concat();
    // Exemplo 1: read P0002 and P0003; positive: 100 rpm, 5,0 A.
    let read = [0x01, 0x01, 0x00, 0x02, 0x10, 0x01, 0x00, 0x02, 0x00, 0x00, 0x10, 0x01, 0x00, 0x03, 0x00, 0x00];
    let (req, resp) =
        exchange(&ds_write(&read), &ds_resp(&[0x01, 0x01, 0x00, 0x02, 0x42, 0x01, 0x00, 0x64, 0x42, 0x01, 0x00, 0x32]));
    assert!(req.ends_with("request parameter, ref 1, axis 0: PNU 2 value; PNU 3 value"), "{req}");
    assert!(resp.ends_with("2 parameters: PNU 2 = Word 0x0064 (100); PNU 3 = Word 0x0032 (50)"), "{resp}");
    // Exemplo 1 negative: P0003 does not exist.
    let (_, resp) =
        exchange(&ds_write(&read), &ds_resp(&[0x01, 0x81, 0x00, 0x02, 0x42, 0x01, 0x00, 0x64, 0x44, 0x01, 0x00, 0x00]));
    assert!(resp.ends_with("PNU 2 = Word 0x0064 (100); PNU 3 = error 0x00 impermissible parameter number"), "{resp}");
    // Exemplo 2: change P0100 to 85; negative: out of limits.
    let change = [0x01, 0x02, 0x00, 0x01, 0x10, 0x01, 0x00, 0x64, 0x00, 0x00, 0x42, 0x01, 0x00, 0x55];
    let (req, resp) = exchange(&ds_write(&change), &ds_resp(&[0x01, 0x82, 0x00, 0x01, 0x44, 0x01, 0x00, 0x02]));
    assert!(req.ends_with("change parameter, ref 1, axis 0: PNU 100 value := Word 0x0055 (85)"), "{req}");
    assert!(resp.ends_with("PNU 100 = error 0x02 low or high limit exceeded"), "{resp}");
}

/// The PDU of a DP-V1 answer frame (`E5` = none yet).
fn answer_pdu(frame: &[u8]) -> Option<Vec<u8>> {
    match pbcard::fdl::telegram::decode(frame) {
        pbcard::fdl::telegram::Decoded::Frame(pbcard::fdl::telegram::Telegram::Data(d), _) => Some(d.pdu.to_vec()),
        _ => None,
    }
}

/// The class-2 master of the I&M session.
const C2_MASTER: u8 = 10;

impl Bus {
    /// A DP-V1 request from `sa` to `dsap` (SSAP `ssap`), then polls until the response PDU.
    fn dpv1(&mut self, sa: u8, dsap: u8, ssap: u8, pdu: &[u8]) -> Vec<u8> {
        let f = self.rig.master.request(sa, Some(dsap), Some(ssap), pdu, true);
        let mut r = self.send(&f, false).expect("an answer");
        for _ in 0..20 {
            if r != [0xE5] {
                return answer_pdu(&r).expect("a data telegram");
            }
            let poll = self.rig.master.request(sa, Some(dsap), Some(ssap), &[], true);
            r = self.send(&poll, false).expect("an answer");
        }
        panic!("no DP-V1 response");
    }
}

/// Initiate.req: Send_Timeout 3 s, Read/Write supported, 2-byte address blocks (API 0, SCL 0).
const INITIATE: [u8; 20] = [0x57, 0, 0, 0, 0x01, 0x2C, 0x01, 0x00, 0, 0, 0, 0, 0, 2, 0, 2, 0, 0, 0, 0];

/// `08 00 FI_Index`, then (for a write) the 10-byte header and `content` blank-padded to 54.
fn im_call(fi: u16, content: Option<&[u8]>) -> Vec<u8> {
    let mut d = vec![0x08, 0x00];
    d.extend_from_slice(&fi.to_be_bytes());
    if let Some(c) = content {
        d.extend_from_slice(&[0; 10]);
        let mut c = c.to_vec();
        c.resize(54, b' ');
        d.extend_from_slice(&c);
    }
    d
}

fn ds_write(index: u8, data: &[u8]) -> Vec<u8> {
    [&[0x5F, 0x00, index, data.len() as u8][..], data].concat()
}

const TAG: &str = "TAG_FUNCTION \"Pump 3 main drive\", TAG_LOCATION \"Hall B, rack 7\"";

/// A card session with I&M and MSAC_C2, recorded: an I&M1 write, I&M0 and I&M1 reads over
/// MSAC_C1 and over an MSAC_C2 connection (each relation with its own call), and an MSAC_C2
/// Data_Transport of record 47 and of I&M1. The card's answers are checked on the way.
fn im_session() -> (String, Vec<u8>) {
    let mut b = Bus::new();
    b.srd(Some(60), &[]);
    b.srd(Some(61), &SetPrm::CARD.dpv1_status_1(0x80).pdu());
    b.srd(Some(62), card::MODULES[0].cfg);
    b.srd(None, &[0x04, 0x7E, 0x00, 0x00]);
    let mut tags = b"Pump 3 main drive".to_vec();
    tags.resize(32, b' ');
    tags.extend_from_slice(b"Hall B, rack 7");
    // MSAC_C1: write I&M1, select and read I&M0, select and read I&M1.
    let c1 = |b: &mut Bus, pdu: &[u8]| b.dpv1(MASTER, 51, 51, pdu);
    assert_eq!(c1(&mut b, &ds_write(255, &im_call(65001, Some(&tags)))), [0x5F, 0x00, 0xFF, 68], "I&M1 written");
    assert_eq!(c1(&mut b, &ds_write(255, &im_call(65000, None))), [0x5F, 0x00, 0xFF, 4]);
    let im0 = c1(&mut b, &[0x5E, 0x00, 0xFF, 0xF0]);
    assert_eq!(im0[..8], [0x5E, 0x00, 0xFF, 68, 0x08, 0x00, 0xFD, 0xE8], "I&M0 with its call header");
    assert_eq!(c1(&mut b, &ds_write(255, &im_call(65001, None))), [0x5F, 0x00, 0xFF, 4]);
    let im1 = c1(&mut b, &[0x5E, 0x00, 0xFF, 0xF0]);
    assert_eq!(im1[4..8], [0x08, 0x00, 0xFD, 0xE9]);
    assert_eq!(im1[18..18 + 54], tags.iter().copied().chain(std::iter::repeat(b' ')).take(54).collect::<Vec<_>>());
    // MSAC_C2: the resource manager, the connection, then I&M0 selected on it while MSAC_C1
    // keeps I&M1 selected.
    let rm = b.dpv1(C2_MASTER, 49, 50, &INITIATE);
    assert_eq!((rm.len(), rm[0]), (4, 0x56), "RM: continue on a server SAP");
    let sap = rm[1];
    assert_eq!(b.dpv1(C2_MASTER, sap, 50, &INITIATE)[0], 0x57, "Initiate.res");
    let c2 = |b: &mut Bus, pdu: &[u8]| b.dpv1(C2_MASTER, sap, 50, pdu);
    assert_eq!(c2(&mut b, &ds_write(255, &im_call(65000, None))), [0x5F, 0x00, 0xFF, 4]);
    assert_eq!(c2(&mut b, &[0x5E, 0x00, 0xFF, 0xF0])[4..8], [0x08, 0x00, 0xFD, 0xE8], "C2: I&M0");
    assert_eq!(c1(&mut b, &[0x5E, 0x00, 0xFF, 0xF0])[4..8], [0x08, 0x00, 0xFD, 0xE9], "C1 still I&M1");
    assert_eq!(c2(&mut b, &ds_write(255, &im_call(65001, None))), [0x5F, 0x00, 0xFF, 4]);
    assert_eq!(c2(&mut b, &[0x5E, 0x00, 0xFF, 0xF0]), im1, "C2: I&M1");
    // Data_Transport (write + read in one PDU): record 47 reads PNU 918; I&M1 with its call.
    let dt = c2(&mut b, &[0x51, 0x00, 0x2F, 0x0A, 0x07, 0x01, 0x01, 0x01, 0x10, 0x01, 0x03, 0x96, 0x00, 0x00]);
    assert_eq!(dt, [0x51, 0x00, 0x2F, 0x08, 0x07, 0x01, 0x01, 0x01, 0x42, 0x01, 0x00, SLAVE], "PNU 918 = 5");
    let dt = c2(&mut b, &[&[0x51, 0x00, 0xFF, 0x04][..], &im_call(65001, None)].concat());
    assert_eq!(dt[..8], [0x51, 0x00, 0xFF, 68, 0x08, 0x00, 0xFD, 0xE9]);
    // The master closes the connection (Abort, acknowledged with SC).
    let abort = b.rig.master.request(C2_MASTER, Some(sap), Some(50), &[0x58, 0x00, 0x20, 0x00], true);
    assert_eq!(b.send(&abort, false).as_deref(), Some(&[0xE5][..]));
    let text = String::from_utf8(b.capture.into_inner()).unwrap();
    (text, b.raw)
}

#[test]
fn a_recorded_im_and_class2_session_decodes_field_by_field() {
    let (text, raw) = im_session();
    let (lines, mon) = replay(Product::card(), &text, None);
    let all = dump(&lines);
    assert!(lines.iter().all(|l| l.service != "Unknown" && l.kind == "telegram"), "{all}");
    let st = &mon.stations()[&SLAVE];
    assert_eq!((st.missing, st.answered, st.errors), (0, st.requests, 0), "{all}");
    assert!(!all.contains("NOT the record") && !all.contains("no call seen"), "{all}");
    // The raw bytes decode to the same texts.
    let (raw_lines, _) = decode_raw(Product::card(), None, &raw);
    let texts = |l: &[Line]| l.iter().map(|l| l.text.clone()).collect::<Vec<_>>();
    assert_eq!(texts(&lines), texts(&raw_lines));

    let requests = |sa: u8, service: &str| -> Vec<&Line> {
        lines.iter().filter(|l| l.sa == Some(sa) && l.service == service && l.request.is_none() && !l.poll).collect()
    };
    let responses = |da: u8, service: &str| -> Vec<&Line> {
        lines.iter().filter(|l| l.da == Some(da) && l.request == Some(service) && l.sd != Some("SC")).collect()
    };
    // MSAC_C1: the I&M1 write, field by field.
    let w = requests(MASTER, "DS_Write");
    assert_eq!(w.len(), 3, "{all}");
    assert_eq!((w[0].slot, w[0].index, w[0].dsap, w[0].ssap), (Some(0), Some(255), Some(51), Some(51)));
    assert_eq!(
        w[0].text,
        format!("MSAC_C1 slot 0 index 255 length 68: I&M function call, IM_Index 65001: I&M1: {TAG}")
    );
    assert_eq!(
        w[1].text,
        "MSAC_C1 slot 0 index 255 length 4: I&M function call, IM_Index 65000 (I&M0): selected for the next read"
    );
    assert_eq!(
        w[2].text,
        "MSAC_C1 slot 0 index 255 length 4: I&M function call, IM_Index 65001 (I&M1): selected for the next read"
    );
    let wr = responses(MASTER, "DS_Write");
    assert_eq!(wr[0].text, "slot 0 index 255 length 68 written");
    assert_eq!((wr[0].index, wr[0].dsap, wr[0].ssap), (Some(255), Some(51), Some(51)));
    // MSAC_C1 reads: I&M0 (the card's identity), I&M1, and I&M1 again after MSAC_C2's call.
    let r = responses(MASTER, "DS_Read");
    assert_eq!(r.len(), 3, "{all}");
    let im0 = &r[0].text;
    assert!(
        im0.starts_with(&format!(
            "slot 0 index 255 length 68: IM_Index 65000: I&M0: MANUFACTURER_ID {}, ORDER_ID \"{}\", SERIAL_NUMBER \"",
            card::IM_MANUFACTURER_ID,
            card::IM_ORDER_ID
        )),
        "{im0}"
    );
    let sw = card::IM_SOFTWARE_REVISION;
    for part in [
        format!("SOFTWARE_REVISION {}{}.{}.{}", sw[0] as char, sw[1], sw[2], sw[3]),
        "REV_COUNTER 0, PROFILE_ID 0x3A00, PROFILE_SPECIFIC_TYPE 0, IM_VERSION 1.1, IM_SUPPORTED 0x000F".into(),
    ] {
        assert!(im0.contains(&part), "'{part}' in {im0}");
    }
    assert_eq!(r[1].text, format!("slot 0 index 255 length 68: IM_Index 65001: I&M1: {TAG}"));
    assert_eq!(r[2].text, r[1].text, "MSAC_C1 keeps its own call");
    assert_eq!((r[1].slot, r[1].index), (Some(0), Some(255)));
    // MSAC_C2: the connection, its own calls and reads.
    let init = requests(C2_MASTER, "Initiate");
    assert_eq!(init.len(), 2, "{all}");
    assert_eq!(init[0].dsap, Some(49));
    assert!(init[0].text.starts_with("MSAC_C2 resource manager Send_Timeout 3000 ms"), "{}", init[0].text);
    let sap = init[1].dsap.expect("the server SAP");
    assert!(responses(C2_MASTER, "Initiate")[0].text.starts_with(&format!("resource manager: continue on SAP {sap}")));
    let w = requests(C2_MASTER, "DS_Write");
    assert_eq!(
        w[0].text,
        "MSAC_C2 slot 0 index 255 length 4: I&M function call, IM_Index 65000 (I&M0): selected for the next read"
    );
    assert_eq!(w[0].dsap, Some(sap));
    let r2 = responses(C2_MASTER, "DS_Read");
    assert_eq!(r2.len(), 2, "{all}");
    assert_eq!(r2[0].text, im0.as_str(), "the same I&M0 over MSAC_C2");
    assert_eq!(r2[0].ssap, Some(sap));
    assert_eq!(r2[1].text, format!("slot 0 index 255 length 68: IM_Index 65001: I&M1: {TAG}"));
    // Data_Transport: record 47 as the record-47 decoder shows it on MSAC_C1, and I&M1.
    let dt = requests(C2_MASTER, "Data_Transport");
    assert_eq!(dt.len(), 2, "{all}");
    assert_eq!(
        dt[0].text,
        "MSAC_C2 slot 0 index 47 length 10: PROFIdrive request parameter, ref 7, axis 1: PNU 918 (station address) value"
    );
    assert_eq!((dt[0].slot, dt[0].index, dt[0].pnu), (Some(0), Some(47), Some(918)));
    assert_eq!(
        dt[1].text,
        "MSAC_C2 slot 0 index 255 length 4: I&M function call, IM_Index 65001 (I&M1): selected for the next read"
    );
    let dtr = responses(C2_MASTER, "Data_Transport");
    assert_eq!(
        dtr[0].text,
        format!("slot 0 index 47 length 8: PROFIdrive response 01 request parameter ok, ref 7, axis 1, 1 parameters: PNU 918 = Word 0x{SLAVE:04X} ({SLAVE})")
    );
    assert_eq!(
        (dtr[0].service, dtr[0].index, dtr[0].pnu, dtr[0].error.as_deref()),
        ("Response", Some(47), Some(918), None)
    );
    assert!(
        dtr[0].text_line().contains(" Response(Data_Transport) slot 0 index 47 length 8: "),
        "{}",
        dtr[0].text_line()
    );
    assert_eq!(dtr[1].text, format!("slot 0 index 255 length 68: IM_Index 65001: I&M1: {TAG}"));
    let abort = requests(C2_MASTER, "Abort");
    assert_eq!(abort.len(), 1, "{all}");
    // JSON: the Data_Transport response carries the fields the issue names.
    let j: serde_json::Value = serde_json::from_str(&dtr[0].json()).unwrap();
    assert_eq!(
        (j["request"].as_str(), j["index"].as_u64(), j["pnu"].as_u64()),
        (Some("Data_Transport"), Some(47), Some(918))
    );
}

/// A DP-V1 frame between master `m` (SAP `msap`) and station 3 (SAP `sap`).
fn dpv1_frame(m: u8, msap: u8, sap: u8, request: bool, pdu: &[u8]) -> Vec<u8> {
    let hdr = if request {
        Header { da: 3, sa: m, fc: FunctionCode::request(0xD, true, true), dsap: Some(sap), ssap: Some(msap) }
    } else {
        Header { da: m, sa: 3, fc: FunctionCode::response(ResponseStatus::Dl), dsap: Some(msap), ssap: Some(sap) }
    };
    testkit::frame(&hdr, pdu).to_vec()
}

#[test]
fn a_device_answering_bare_im_records_is_decoded_by_the_call_of_each_relation() {
    // A 64-byte record after a zero header: `fields` blank-padded to 54.
    let rec = |fields: &str| {
        let mut r = vec![0u8; 10];
        r.extend_from_slice(fields.as_bytes());
        r.resize(64, b' ');
        r
    };
    let read = [0x5E, 0x00, 0xFF, 0xF0];
    let answer = |data: &[u8]| [&[0x5E, 0x00, 0xFF, data.len() as u8][..], data].concat();
    let (c1, c2) = ((MASTER, 51, 51), (10, 50, 40));
    let mut bytes = Vec::new();
    let mut x = |(m, msap, sap): (u8, u8, u8), req: &[u8], resp: Option<&[u8]>| {
        bytes.extend(dpv1_frame(m, msap, sap, true, req));
        match resp {
            Some(r) => bytes.extend(dpv1_frame(m, msap, sap, false, r)),
            None => bytes.push(0xE5),
        }
    };
    // MSAC_C1 selects I&M1, the MSAC_C2 connection I&M3; each read answers the bare record.
    x(c1, &[0x5F, 0x00, 0xFF, 0x04, 0x08, 0x00, 0xFD, 0xE9], Some(&[0x5F, 0x00, 0xFF, 0x04]));
    x(c2, &[0x5F, 0x00, 0xFF, 0x04, 0x08, 0x00, 0xFD, 0xEB], Some(&[0x5F, 0x00, 0xFF, 0x04]));
    let mut im1 = b"F".to_vec();
    im1.resize(32, b' ');
    im1.extend_from_slice(b"L");
    x(c1, &read, Some(&answer(&rec(std::str::from_utf8(&im1).unwrap()))));
    x(c2, &read, Some(&answer(&rec("D"))));
    // A refused call selects nothing: MSAC_C1 stays on I&M1, and an answer with another
    // record's header is flagged.
    x(c1, &[0x5F, 0x00, 0xFF, 0x04, 0x08, 0x00, 0xFD, 0xF0], Some(&[0xDF, 0x80, 0xB0, 0x00]));
    x(c1, &read, Some(&answer(&[&[0x08, 0x00, 0xFD, 0xEB][..], &rec("D")].concat())));
    // The connection closes; its next read has no call.
    x(c2, &[0x58, 0x00, 0x20, 0x00], None);
    x(c2, &read, Some(&answer(&rec(""))));
    let (lines, _) = decode_raw(Product::card(), None, &bytes);
    let all = dump(&lines);
    assert!(lines.iter().all(|l| l.service != "Unknown" && l.kind == "telegram"), "{all}");
    let reads: Vec<&str> = lines.iter().filter(|l| l.request == Some("DS_Read")).map(|l| l.text.as_str()).collect();
    assert_eq!(
        reads,
        [
            "slot 0 index 255 length 64: IM_Index 65001 (the call on this relation), without call header: I&M1: TAG_FUNCTION \"F\", TAG_LOCATION \"L\"",
            "slot 0 index 255 length 64: IM_Index 65003 (the call on this relation), without call header: I&M3: DESCRIPTOR \"D\"",
            "slot 0 index 255 length 68: IM_Index 65003: I&M3: DESCRIPTOR \"D\" (NOT the record the call on this relation selected, IM_Index 65001)",
            "slot 0 index 255 length 64: no call seen on this relation, read as I&M0: I&M0: MANUFACTURER_ID 8224, ORDER_ID \"\", SERIAL_NUMBER \"\", HARDWARE_REVISION 8224, SOFTWARE_REVISION ?32.32.32, REV_COUNTER 8224, PROFILE_ID 0x2020, PROFILE_SPECIFIC_TYPE 8224, IM_VERSION 32.32, IM_SUPPORTED 0x2020",
        ],
        "{all}"
    );
    let refused = find(&lines, |l| l.request == Some("DS_Write") && l.error.is_some(), "the refused call");
    assert!(refused.text.contains("Error_Code_1 B0 (access: invalid index)"), "{}", refused.text);
}

#[test]
#[ignore = "prints the decoded session (README example): cargo test -p pbcard-monitor --test replay -- --ignored --nocapture"]
fn print_the_session() {
    let (text, _) = session();
    println!("{text}");
    let (lines, mon) = replay(Product::card(), &text, None);
    println!("{}\n{}", dump(&lines), mon.summary());
    let (text, _) = im_session();
    let (lines, _) = replay(Product::card(), &text, None);
    println!("{}", dump(&lines));
}
