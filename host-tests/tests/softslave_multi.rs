//! Several stations in one soft slave (issue 14 item 1), judged by profirust's DP master with
//! three peripherals on one pseudo-terminal: all three reach data exchange, each one's
//! simulated drive follows its own setpoint, one station's DP watchdog expires (the master's
//! requests to it are cut off on the line) while the other two keep running — and the whole
//! run, recorded on the master's side in the bus monitor's capture format (bring-up, data
//! exchange, and at the end a DP-V1 record-47 parameter read by a scripted class-1 master, as
//! profirust has no DP-V1), decodes with `pbcard-monitor` with every request matched to its
//! response and no `Unknown`.
//!
//! Timing as in `softslave.rs`: a pseudo-terminal has no line timing, so slot times are long and
//! every wait is "until it holds" with deadlines of tens of seconds.

use std::sync::atomic::{AtomicBool, AtomicU8, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant as StdInstant};

use host_tests::serial::{Pty, PtyMaster, StreamPhy};
use host_tests::{profirust_rate, PeripheralConfig};
use pbcard::card;
use pbcard::fdl::telegram::{self, Decoded, FunctionCode, Header, RequestFunction, ResponseStatus, Telegram};
use pbcard::time::Baudrate;
use pbcard_monitor::capture::Writer;
use pbcard_monitor::product::Product;
use pbcard_softslave::Options;
use profirust::dp::{DpMaster, PeripheralHandle, PeripheralOptions};
use profirust::fdl::FdlActiveStation;
use profirust::phy::ProfibusPhy;

const RATE: Baudrate = Baudrate::B19200;
const MASTER: u8 = 2;
const STATIONS: [u8; 3] = [5, 6, 7];
const DEADLINE: Duration = Duration::from_secs(90);
const SLOT_BITS: u16 = 10_000;

/// The master's PHY: FDL_Status answers for the absent addresses (passive stations), a switch
/// that cuts one station off the line, and a recorder of every byte in the capture format.
struct Line<P> {
    inner: P,
    stations: Vec<u8>,
    answer: Vec<u8>,
    muted: Arc<AtomicU8>,
    t0: StdInstant,
    capture: Arc<Mutex<Writer<Vec<u8>>>>,
}

impl<P> Line<P> {
    fn record(&self, bytes: &[u8]) {
        let t = self.t0.elapsed().as_micros() as u64;
        let _ = self.capture.lock().unwrap().bytes(Some(t), bytes);
    }
}

fn passive_answer(frame: &[u8], stations: &[u8]) -> Option<Vec<u8>> {
    let Decoded::Frame(Telegram::Data(t), _) = telegram::decode(frame) else { return None };
    if stations.contains(&t.da) || t.da == telegram::BROADCAST || t.fc.function() != RequestFunction::FdlStatus {
        return None;
    }
    let hdr = Header { da: t.sa, sa: t.da, fc: FunctionCode::response(ResponseStatus::Ok), dsap: None, ssap: None };
    let mut out = [0u8; 16];
    let n = telegram::emit(&mut out, &hdr, &[]).ok()?;
    Some(out[..n].to_vec())
}

impl<P: ProfibusPhy> ProfibusPhy for Line<P> {
    fn poll_transmission(&mut self, now: profirust::time::Instant) -> bool {
        self.inner.poll_transmission(now)
    }

    fn transmit_data<F, R>(&mut self, now: profirust::time::Instant, f: F) -> R
    where
        F: FnOnce(&mut [u8]) -> (usize, R),
    {
        let muted = self.muted.load(Ordering::Relaxed);
        let (stations, answer) = (self.stations.clone(), &mut self.answer);
        let mut sent = Vec::new();
        let r = self.inner.transmit_data(now, |buf| {
            let (n, r) = f(buf);
            let da = match telegram::decode(&buf[..n]) {
                Decoded::Frame(Telegram::Data(t), _) => Some(t.da),
                _ => None,
            };
            if let Some(a) = passive_answer(&buf[..n], &stations) {
                sent = buf[..n].to_vec();
                sent.extend_from_slice(&a);
                *answer = a;
                (0, r)
            } else if da == Some(muted) {
                // Cut off: the station never hears it (nothing on the capture either, as a
                // monitor on the far side of a broken cable would see).
                (0, r)
            } else {
                sent = buf[..n].to_vec();
                (n, r)
            }
        });
        if !sent.is_empty() {
            self.record(&sent);
        }
        r
    }

    fn receive_data<F, R>(&mut self, now: profirust::time::Instant, f: F) -> R
    where
        F: FnOnce(&[u8]) -> (usize, R),
    {
        if !self.answer.is_empty() {
            let (drop, r) = f(&self.answer);
            self.answer.drain(..drop.min(self.answer.len()));
            return r;
        }
        let mut got = Vec::new();
        let r = self.inner.receive_data(now, |buf| {
            let (n, r) = f(buf);
            got = buf[..n].to_vec();
            (n, r)
        });
        if !got.is_empty() {
            self.record(&got);
        }
        r
    }
}

fn words(b: &[u8]) -> Vec<u16> {
    b.chunks(2).map(|w| u16::from_be_bytes([w[0], w[1]])).collect()
}

fn set_words(q: &mut [u8], w: &[u16]) {
    for (i, v) in w.iter().enumerate() {
        q[2 * i..2 * i + 2].copy_from_slice(&v.to_be_bytes());
    }
}

/// What a PLC program sends for ZSW1 to get the drive running (fault acknowledge, S1 → S2, run).
fn plc_stw1(zsw1: u16) -> u16 {
    if zsw1 & 0x0008 != 0 {
        0x04FE
    } else if zsw1 & 0x0001 == 0 {
        0x047E
    } else {
        0x047F
    }
}

#[test]
fn three_stations_in_one_soft_slave_run_independently_under_profirust() {
    let pty = Pty::open().expect("a pseudo-terminal pair");
    let dir = std::env::temp_dir().join(format!("pbcard-multi-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let cfg = dir.join("stations.toml");
    // Station 6 runs PPO 3 (STW/HSW), the others Standard telegram 1; all ramp in 300 ms.
    std::fs::write(
        &cfg,
        "ramp_ms = 300\n[[station]]\naddress = 5\nmodule = 1\n[[station]]\naddress = 6\nmodule = \"PPO 3, PZD-2/2\"\n\
         [[station]]\naddress = 7\nmodule = 1\n[station.params]\n100 = 85\n",
    )
    .unwrap();
    let mut opts = Options::new(pty.path().to_str().unwrap());
    opts.baud = RATE;
    opts.config = Some(cfg.to_str().unwrap().into());
    opts.pd_every = None;
    let stop = Arc::new(AtomicBool::new(false));
    let log = Arc::new(Mutex::new(Vec::<String>::new()));
    let (s, l) = (stop.clone(), log.clone());
    let slave = std::thread::spawn(move || {
        pbcard_softslave::run(&opts, &s, &mut |line| l.lock().unwrap().push(line.to_string()))
    });
    let logged = |needle: &str| log.lock().unwrap().iter().any(|l| l.contains(needle));
    let dump = || log.lock().unwrap().join("\n");

    // The master: three peripherals, a 4 s DP watchdog.
    let modules = [&card::MODULES[0], card::MODULES.iter().find(|m| m.reference == 103).unwrap(), &card::MODULES[0]];
    let mut dp = DpMaster::new(Vec::new());
    let mut handles: Vec<PeripheralHandle> = Vec::new();
    for (a, m) in STATIONS.iter().zip(modules) {
        let mut p = PeripheralConfig::card(*a, m, RATE);
        if *a == 5 {
            p.user_prm[0] = 0x80; // DPV1_Status_1: DPV1_Enable (the DP-V1 read at the end)
        }
        let options = PeripheralOptions {
            ident_number: p.ident,
            sync_mode: false,
            freeze_mode: false,
            groups: 0,
            max_tsdr: p.max_tsdr,
            fail_safe: p.fail_safe,
            user_parameters: Some(Box::leak(p.user_prm.into_boxed_slice())),
            config: Some(Box::leak(p.cfg.into_boxed_slice())),
        };
        let per = profirust::dp::Peripheral::new(*a, options, vec![0u8; p.inputs], vec![0u8; p.outputs])
            .with_diag_buffer(vec![0u8; card::MAX_DIAG_DATA_LEN]);
        handles.push(dp.add(per));
    }
    let mut b = profirust::fdl::ParametersBuilder::new(MASTER, profirust_rate(RATE));
    // Few retries: while station 7 is cut off, every request to it costs (1 + retries) slot times
    // of silence, and 5 and 6 must still be served within their watchdog.
    b.slot_bits(SLOT_BITS).max_retry_limit(3).highest_station_address(8);
    b.watchdog_timeout(profirust::time::Duration::from_millis(4000));
    let mut fdl = FdlActiveStation::new(b.build_verified(&dp));
    fdl.set_online();
    dp.enter_operate();
    let muted = Arc::new(AtomicU8::new(255));
    let t0 = StdInstant::now();
    let capture = Arc::new(Mutex::new(Writer::new(Vec::new(), Some(RATE)).unwrap()));
    let inner: StreamPhy<PtyMaster> = pty.into_phy();
    let mut phy = Line {
        inner,
        stations: STATIONS.to_vec(),
        answer: Vec::new(),
        muted: muted.clone(),
        t0,
        capture: capture.clone(),
    };
    // Skip profirust's listen-before-claiming-the-token time (nobody else is on this line).
    let mut clock = t0;
    let now = |c: StdInstant| profirust::time::Instant::from_micros(c.elapsed().as_micros() as i64);
    fdl.poll(now(clock), &mut phy, &mut dp);
    clock -= Duration::from_micros(fdl.parameters().token_lost_timeout().total_micros()) + Duration::from_millis(1);

    // Setpoints: 25 %, 50 %, 75 % (0x4000 = 100 %).
    let setpoints = [0x1000u16, 0x2000, 0x3000];
    let mut run = |dp: &mut DpMaster,
                   phy: &mut Line<StreamPhy<PtyMaster>>,
                   limit: Duration,
                   done: &mut dyn FnMut(&mut DpMaster) -> bool| {
        let end = StdInstant::now() + limit;
        while StdInstant::now() < end {
            fdl.poll(now(clock), phy, dp);
            let _ = dp.take_last_events();
            for (h, sp) in handles.iter().zip(setpoints) {
                let p = dp.get_mut(*h);
                let z = words(p.pi_i())[0];
                set_words(p.pi_q_mut(), &[plc_stw1(z), sp]);
            }
            if done(dp) {
                return true;
            }
            std::thread::sleep(Duration::from_micros(200));
        }
        false
    };
    let at_setpoint = |dp: &mut DpMaster, h: PeripheralHandle, sp: u16| {
        let p = dp.get_mut(h);
        let w = words(p.pi_i());
        p.is_running() && w[0] & 0x0007 == 0x0007 && w[1] == sp
    };
    let h = handles.clone();
    let all_run = run(&mut dp, &mut phy, DEADLINE, &mut |dp| (0..3).all(|i| at_setpoint(dp, h[i], setpoints[i])));
    if !all_run {
        let w: Vec<Vec<u16>> = h.iter().map(|x| words(dp.get_mut(*x).pi_i())).collect();
        panic!("not every drive at its own setpoint: inputs {w:04X?}\n{}", dump());
    }
    for a in STATIONS {
        assert!(logged(&format!("#{a} DP state Data_Exch: data exchange with master 2")), "#{a}\n{}", dump());
        assert!(logged(&format!("#{a} drive: S2 ready for switching on → S4 operation")), "#{a}\n{}", dump());
    }
    assert!(logged("#6 Chk_Cfg: PPO 3, PZD-2/2") && logged("#5 Chk_Cfg: Standard telegram 1"), "{}", dump());

    // Station 7 is cut off the line: its watchdog expires, its drive faults; 5 and 6 run on.
    muted.store(7, Ordering::Relaxed);
    let end = StdInstant::now() + DEADLINE;
    let mut others_ok = true;
    while !(logged("#7 watchdog expired") && logged("#7 drive: S4 operation → fault")) {
        assert!(StdInstant::now() < end, "#7 never watchdogged\n{}", dump());
        run(&mut dp, &mut phy, Duration::from_millis(50), &mut |_| false);
        others_ok &= at_setpoint(&mut dp, h[0], setpoints[0]) && at_setpoint(&mut dp, h[1], setpoints[1]);
    }
    assert!(others_ok, "5 and 6 stayed at their setpoints while 7 was cut off\n{}", dump());
    assert!(!logged("#5 watchdog expired") && !logged("#6 watchdog expired"), "{}", dump());
    // Back on the line: the master re-parameterises 7, the PLC acknowledges its fault, it runs.
    muted.store(255, Ordering::Relaxed);
    if !run(&mut dp, &mut phy, DEADLINE, &mut |dp| (0..3).all(|i| at_setpoint(dp, h[i], setpoints[i]))) {
        panic!("#7 did not come back\n{}", dump());
    }
    // profirust has no DP-V1: a scripted class-1 master on the same line reads PNU 918 of
    // station 5 through record 47 (DS_Write, polls, DS_Read, polls), recorded as well.
    std::thread::sleep(Duration::from_millis(200));
    let rest = phy.inner.take_received();
    phy.record(&rest);
    let mut script = pbcard::testkit::ScriptedMaster::new(MASTER, 5);
    let mut c1 = |phy: &mut Line<StreamPhy<PtyMaster>>, pdu: &[u8]| -> Vec<u8> {
        let mut data = pdu.to_vec();
        for _ in 0..50 {
            let f = script.request(MASTER, Some(51), Some(51), &data, true);
            phy.record(&f);
            let r = phy.inner.request(&f, Duration::from_secs(10)).unwrap().expect("an answer on SAP 51");
            phy.record(&r);
            if r != [telegram::SC] {
                return r;
            }
            data.clear(); // poll
            std::thread::sleep(Duration::from_millis(5));
        }
        panic!("no DP-V1 response\n{}", dump());
    };
    let w = c1(&mut phy, &[0x5F, 0x00, 0x2F, 0x0A, 0x01, 0x01, 0x01, 0x01, 0x10, 0x01, 0x03, 0x96, 0x00, 0x00]);
    assert!(w.len() > 6, "DS_Write answered: {w:02x?}");
    let r = c1(&mut phy, &[0x5E, 0x00, 0x2F, 0xF0]);
    assert!(r.len() > 12, "DS_Read answered with a parameter response: {r:02x?}");
    stop.store(true, Ordering::Relaxed);
    let summary = slave.join().unwrap().unwrap();
    assert_eq!(summary.stations.iter().map(|s| s.0).collect::<Vec<_>>(), STATIONS);
    assert!(summary.stations.iter().all(|s| s.1 > 10), "{summary:?}");

    // The recorded run through the bus monitor: every request answered except those to 7 while
    // it was cut off (which never reached the line), nothing unknown.
    let text = String::from_utf8(
        std::mem::replace(&mut *capture.lock().unwrap(), Writer::new(Vec::new(), None).unwrap()).into_inner(),
    )
    .unwrap();
    let _ = std::fs::write(dir.join("capture.txt"), &text);
    let (lines, mon) = pbcard_monitor::replay(Product::card(), &text, None);
    let unknown: Vec<String> = lines.iter().filter(|l| l.service == "Unknown").map(|l| l.text_line()).collect();
    assert!(unknown.is_empty(), "{unknown:#?}");
    let st = mon.stations();
    for a in STATIONS {
        let s = &st[&a];
        assert_eq!(s.state, "Data_Exch", "#{a}: {s:?}");
        assert!(s.data_exchanges > 10 && s.answered > 10, "#{a}: {s:?}");
        assert_eq!(s.missing, 0, "#{a}: every request on the line answered: {s:?}");
        assert_eq!(s.module.as_deref(), Some(if a == 6 { "PPO 3, PZD-2/2" } else { "Standard telegram 1, PZD-2/2" }));
    }
    let read = lines.iter().find(|l| l.request == Some("DS_Read") && l.sd == Some("SD2"));
    assert!(
        read.is_some_and(|l| l.text.ends_with("PNU 918 = Word 0x0005 (5)") && l.pnu == Some(918)),
        "the DP-V1 read decoded: {:?}",
        read.map(|l| l.text_line())
    );
    for svc in ["FDL_Status", "Slave_Diag", "Set_Prm", "Chk_Cfg", "Data_Exchange", "DS_Write", "DS_Read"] {
        assert!(lines.iter().any(|l| l.request == Some(svc)), "a {svc} response in the capture");
    }
    // Shown with --nocapture (README examples).
    println!("{}\n{}", dump(), mon.summary());
    let _ = std::fs::remove_dir_all(dir);
}
