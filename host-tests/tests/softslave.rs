//! End to end over a real (pseudo-)terminal: the soft slave (`pbcard-softslave` as a library
//! call in a thread: the same Node + DPM + simulated drive as the firmware) on one end of a
//! pseudo-terminal pair, profirust's DP master — a master nobody here wrote — on the other.
//!
//! A pseudo-terminal has no line timing, so nothing here may depend on it:
//!
//! * the slot time is 10000 bit times (0.52 s at 19.2 kbit/s) with 15 retries, so a test
//!   machine may stall either side for 8 s and only slows the test (a longer slot time makes
//!   profirust's start-up, which waits 10 slot times for a token, slower still);
//! * the DP watchdog is off except in the watchdog test, which only waits *longer* than it;
//! * every wait is "until a condition holds", with deadlines of tens of seconds.
//!
//! profirust, as the only master, polls every GAP address (its own included) once per token
//! rotation with FDL_Status and waits a slot time for each missing station. [`GapResponder`]
//! therefore answers FDL_Status for every address but the soft slave's itself, as passive
//! stations on a real line would, so no rotation waits a slot time; everything for the soft slave's
//! address goes over the pseudo-terminal.
//!
//! Debugging: `--nocapture` prints the soft slave's log of the Standard Telegram 1 test;
//! `PBCARD_SOFTSLAVE_VERBOSE=1` adds every telegram to it, `PBCARD_PHY_TRACE=1` prints the
//! master's side.

mod families;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant as StdInstant};

use host_tests::serial::{Pty, PtyMaster, StreamPhy};
use host_tests::{hex, profirust_rate, PeripheralConfig};
use pbcard::card;
use pbcard::fdl::telegram::{self, Decoded, FunctionCode, Header, RequestFunction, ResponseStatus, Telegram};
use pbcard::time::Baudrate;
use pbcard_softslave::{Options, Summary};
use profirust::dp::{DpMaster, Peripheral, PeripheralEvent, PeripheralHandle, PeripheralOptions};
use profirust::fdl::FdlActiveStation;
use profirust::phy::ProfibusPhy;

const RATE: Baudrate = Baudrate::B19200;
const MASTER: u8 = 2;
const SLAVE: u8 = 5;
const DEADLINE: Duration = Duration::from_secs(60);
const SLOT_BITS: u16 = 10_000;

// ---------------------------------------------------------------------------------------------
// The master's PHY: host_tests::serial's pseudo-terminal PHY, plus the passive stations.
// ---------------------------------------------------------------------------------------------

/// Answers FDL_Status for every address but the soft slave's (a passive station there), and
/// passes everything else to the pseudo-terminal.
struct GapResponder<P> {
    inner: P,
    slave: u8,
    answer: Vec<u8>,
}

/// The FDL_Status answer of a passive station to `frame`, unless it is for `slave`.
fn passive_station_answer(frame: &[u8], slave: u8) -> Option<Vec<u8>> {
    let Decoded::Frame(Telegram::Data(t), _) = telegram::decode(frame) else { return None };
    if t.da == slave || t.da == telegram::BROADCAST || t.fc.function() != RequestFunction::FdlStatus {
        return None;
    }
    let hdr = Header { da: t.sa, sa: t.da, fc: FunctionCode::response(ResponseStatus::Ok), dsap: None, ssap: None };
    let mut out = [0u8; 16];
    let n = telegram::emit(&mut out, &hdr, &[]).ok()?;
    Some(out[..n].to_vec())
}

impl<P: ProfibusPhy> ProfibusPhy for GapResponder<P> {
    fn poll_transmission(&mut self, now: profirust::time::Instant) -> bool {
        self.inner.poll_transmission(now)
    }

    fn transmit_data<F, R>(&mut self, now: profirust::time::Instant, f: F) -> R
    where
        F: FnOnce(&mut [u8]) -> (usize, R),
    {
        let (slave, answer) = (self.slave, &mut self.answer);
        self.inner.transmit_data(now, |buf| {
            let (n, r) = f(buf);
            match passive_station_answer(&buf[..n], slave) {
                Some(a) => {
                    *answer = a;
                    (0, r)
                }
                None => (n, r),
            }
        })
    }

    fn receive_data<F, R>(&mut self, now: profirust::time::Instant, f: F) -> R
    where
        F: FnOnce(&[u8]) -> (usize, R),
    {
        if self.answer.is_empty() {
            return self.inner.receive_data(now, f);
        }
        let (drop, r) = f(&self.answer);
        self.answer.drain(..drop.min(self.answer.len()));
        r
    }
}

// ---------------------------------------------------------------------------------------------
// The two ends.
// ---------------------------------------------------------------------------------------------

/// The soft slave running in a thread; stopped (and joined) on drop.
struct SoftSlave {
    stop: Arc<AtomicBool>,
    log: Arc<Mutex<Vec<String>>>,
    thread: Option<JoinHandle<std::io::Result<Summary>>>,
}

impl SoftSlave {
    fn start(device: &str, ramp_ms: u64) -> Self {
        let mut opts = Options::new(device);
        opts.baud = RATE;
        opts.address = SLAVE;
        opts.ramp = Duration::from_millis(ramp_ms);
        opts.pd_every = Some(Duration::from_millis(500));
        opts.verbose = std::env::var_os("PBCARD_SOFTSLAVE_VERBOSE").is_some();
        let stop = Arc::new(AtomicBool::new(false));
        let log = Arc::new(Mutex::new(Vec::new()));
        let (s, l) = (stop.clone(), log.clone());
        let thread = std::thread::spawn(move || {
            pbcard_softslave::run(&opts, &s, &mut |line| l.lock().unwrap().push(line.to_string()))
        });
        SoftSlave { stop, log, thread: Some(thread) }
    }

    fn logged(&self, needle: &str) -> bool {
        self.log.lock().unwrap().iter().any(|l| l.contains(needle))
    }

    fn dump(&self) -> String {
        self.log.lock().unwrap().join("\n")
    }

    fn finish(mut self) -> Summary {
        self.stop.store(true, Ordering::Relaxed);
        let r = self.thread.take().unwrap().join().expect("soft slave thread panicked");
        r.unwrap_or_else(|e| panic!("soft slave failed: {e}\n{}", self.dump()))
    }
}

impl Drop for SoftSlave {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

struct Master {
    fdl: FdlActiveStation,
    dp: DpMaster<'static>,
    handle: PeripheralHandle,
    phy: GapResponder<StreamPhy<PtyMaster>>,
    t0: StdInstant,
    events: Vec<PeripheralEvent>,
    cycles: u64,
}

impl Master {
    fn new(pty: Pty, module: &card::Module, watchdog: Option<Duration>) -> Self {
        let phy = GapResponder { inner: pty.into_phy(), slave: SLAVE, answer: Vec::new() };
        Self::on(phy, module, watchdog)
    }

    /// A new master (a new Set_Prm / Chk_Cfg) for `module` on the line of an earlier one.
    fn on(phy: GapResponder<StreamPhy<PtyMaster>>, module: &card::Module, watchdog: Option<Duration>) -> Self {
        let p = PeripheralConfig::card(SLAVE, module, RATE);
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
        let mut dp = DpMaster::new(Vec::new());
        let per = Peripheral::new(SLAVE, options, vec![0u8; p.inputs], vec![0u8; p.outputs])
            .with_diag_buffer(vec![0u8; card::MAX_DIAG_DATA_LEN]);
        let handle = dp.add(per);
        let mut b = profirust::fdl::ParametersBuilder::new(MASTER, profirust_rate(RATE));
        b.slot_bits(SLOT_BITS).max_retry_limit(15).highest_station_address(SLAVE + 1);
        if let Some(w) = watchdog {
            b.watchdog_timeout(profirust::time::Duration::from_millis(w.as_millis() as u64));
        }
        let mut fdl = FdlActiveStation::new(b.build_verified(&dp));
        fdl.set_online();
        dp.enter_operate();
        Master { fdl, dp, handle, phy, t0: StdInstant::now(), events: Vec::new(), cycles: 0 }
    }

    /// Nobody else is on this line: skip profirust's listen-before-claiming-the-token time
    /// (10 slot times, 5.2 s here) by moving the master's clock past it after a first poll.
    fn skip_token_wait(mut self) -> Self {
        let now = profirust::time::Instant::from_micros(self.t0.elapsed().as_micros() as i64);
        self.fdl.poll(now, &mut self.phy, &mut self.dp);
        let wait = Duration::from_micros(self.fdl.parameters().token_lost_timeout().total_micros());
        self.t0 -= wait + Duration::from_millis(1);
        self
    }

    fn peripheral(&mut self) -> &mut Peripheral<'static> {
        self.dp.get_mut(self.handle)
    }

    /// Poll until `done` holds (checked after every DataExchanged); false at the deadline.
    fn run_until(&mut self, limit: Duration, mut done: impl FnMut(&mut Peripheral<'static>) -> bool) -> bool {
        let end = StdInstant::now() + limit;
        while StdInstant::now() < end {
            let now = profirust::time::Instant::from_micros(self.t0.elapsed().as_micros() as i64);
            self.fdl.poll(now, &mut self.phy, &mut self.dp);
            let ev = self.dp.take_last_events();
            if let Some((_, e)) = ev.peripheral {
                self.events.push(e);
                if e == PeripheralEvent::DataExchanged {
                    self.cycles += 1;
                    if done(self.dp.get_mut(self.handle)) {
                        return true;
                    }
                }
            }
            std::thread::sleep(Duration::from_micros(200));
        }
        false
    }

    /// Keep the master polling for `d` (nothing to wait for).
    fn run_for(&mut self, d: Duration) {
        let _ = self.run_until(d, |_| false);
    }

    fn summary(&self) -> String {
        let mut ev = self.events.clone();
        ev.dedup();
        format!("master: {} cycles, events (deduplicated) {ev:?}", self.cycles)
    }
}

fn words(b: &[u8]) -> Vec<u16> {
    b.chunks(2).map(|w| u16::from_be_bytes([w[0], w[1]])).collect()
}

fn set_words(q: &mut [u8], at: usize, w: &[u16]) {
    for (i, v) in w.iter().enumerate() {
        q[2 * (at + i)..2 * (at + i) + 2].copy_from_slice(&v.to_be_bytes());
    }
}

fn setup(module: &card::Module, ramp_ms: u64, watchdog: Option<Duration>) -> (SoftSlave, Master) {
    let pty = Pty::open().expect("create a pseudo-terminal pair");
    let slave = SoftSlave::start(pty.path().to_str().expect("a UTF-8 pty path"), ramp_ms);
    let master = Master::new(pty, module, watchdog);
    (slave, master)
}

fn fail(what: &str, slave: &SoftSlave, master: &Master) -> ! {
    panic!("{what}\n{}\n-- soft slave log --\n{}", master.summary(), slave.dump());
}

/// Bring the drive from S1 to S2 with 0x047E at word `at` (after the PKW).
fn switch_on_ready(slave: &SoftSlave, m: &mut Master, at: usize, setpoint: u16) {
    let ok = m.run_until(DEADLINE, |p| {
        set_words(p.pi_q_mut(), at, &[0x047E, setpoint]);
        let z = words(p.pi_i())[at];
        z & 0x0047 == 0x0001
    });
    if !ok {
        fail("the drive did not become ready to switch on (ZSW1 b0, not b6) with STW1 0x047E", slave, m);
    }
}

#[test]
fn standard_telegram_1_drive_runs_and_ramps_to_the_setpoint() {
    let module = &card::MODULES[0];
    let (slave, mut m) = setup(module, 2000, None);
    if !m.run_until(DEADLINE, |p| p.is_running()) {
        fail("no data exchange", &slave, &m);
    }
    let setpoint = 0x2000u16; // 50 % of the reference speed
    switch_on_ready(&slave, &mut m, 0, setpoint);
    assert!(words(m.peripheral().pi_i())[1] == 0, "standstill before 0x047F");

    // 0x047F: S4; NIST_A ramps up (2 s per 100 %: about 1 s to 50 %) and never falls.
    let mut samples: Vec<u16> = Vec::new();
    let ok = m.run_until(DEADLINE, |p| {
        set_words(p.pi_q_mut(), 0, &[0x047F, setpoint]);
        let w = words(p.pi_i());
        if w[0] & 0x0004 != 0 {
            samples.push(w[1]);
        }
        w[0] & 0x0107 == 0x0107 && w[1] == setpoint
    });
    if !ok {
        fail(&format!("no operation at setpoint; NIST_A samples {samples:04X?}"), &slave, &m);
    }
    assert!(samples.windows(2).all(|w| w[0] <= w[1]), "NIST_A must rise monotonically: {samples:04X?}");
    let between = samples.iter().filter(|&&n| n > 0 && n < setpoint).count();
    assert!(between >= 3, "the speed ramps through intermediate values: {samples:04X?}\n{}", slave.dump());
    let zsw1 = words(m.peripheral().pi_i())[0];
    assert_eq!(zsw1 & 0x0277, 0x0237, "ZSW1 {zsw1:04X}: S4, no OFF2/OFF3, control requested");

    // 0x047E: ramp stop to standstill, back in S2.
    let ok = m.run_until(DEADLINE, |p| {
        set_words(p.pi_q_mut(), 0, &[0x047E, setpoint]);
        let w = words(p.pi_i());
        w[0] & 0x0047 == 0x0001 && w[1] == 0
    });
    if !ok {
        fail("0x047E did not ramp the drive down to S2", &slave, &m);
    }
    m.run_for(Duration::from_millis(600)); // one more process-data log line

    for line in [
        "Set_Prm accepted from master 2",
        "Chk_Cfg: Standard telegram 1",
        "DP state Data_Exch: data exchange with master 2",
        "P0740 = 6 (online)",
        "drive: S2 ready for switching on → S4 operation (STW1 047F",
        "drive: S4 operation → S5 switching off (ramp stop)",
        "PD out STW1 047E NSOLL_A 2000 (+50.0 %) | in ZSW1",
    ] {
        assert!(slave.logged(line), "the log shows '{line}':\n{}", slave.dump());
    }
    println!("{}", slave.dump()); // shown with --nocapture
    let s = slave.finish();
    println!("{s:?}");
    assert!(s.data_exchanges > 10, "{s:?}");
}

#[test]
fn ppo_module_comes_up_with_zsw_hiw_after_the_pkw() {
    let module = card::MODULES.iter().find(|m| m.name.starts_with("PPO 2")).expect("PPO 2 in the GSD");
    let (slave, mut m) = setup(module, 500, None);
    if !m.run_until(DEADLINE, |p| p.is_running()) {
        fail("no data exchange with PPO 2", &slave, &m);
    }
    // PKW (4 words) | STW HSW PZD3..PZD6.
    let extra = [0x1111u16, 0x2222, 0x3333, 0x4444];
    let ok = m.run_until(DEADLINE, |p| {
        set_words(p.pi_q_mut(), 6, &extra);
        set_words(p.pi_q_mut(), 4, &[0x047E, 0x1000]);
        words(p.pi_i())[6..] == extra
    });
    if !ok {
        fail("PZD3..6 are not echoed", &slave, &m);
    }
    switch_on_ready(&slave, &mut m, 4, 0x1000);
    let ok = m.run_until(DEADLINE, |p| {
        set_words(p.pi_q_mut(), 4, &[0x047F, 0x1000]);
        let w = words(p.pi_i());
        w[4] & 0x0107 == 0x0107 && w[5] == 0x1000
    });
    if !ok {
        fail("PPO 2: no operation at the setpoint", &slave, &m);
    }
    let w = words(m.peripheral().pi_i());
    assert_eq!(&w[..4], &[0, 0, 0, 0], "PKW answered with zeros: {}", hex(m.peripheral().pi_i()));
    assert!(slave.logged("Chk_Cfg: PPO 2, PKW + PZD-6/6 (F3 F5)"), "{}", slave.dump());
    slave.finish();
}

/// What a PLC program sends for ZSW1 `zsw1` to get the drive running: acknowledge a fault
/// (0x04FE: b7 edge), leave S1 (0x047E), run (0x047F).
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
fn watchdog_expiry_is_logged_and_faults_the_running_drive() {
    let module = &card::MODULES[0];
    let (slave, mut m) = setup(module, 200, Some(Duration::from_millis(1000)));
    let running = |p: &mut Peripheral<'static>| {
        let z = words(p.pi_i())[0];
        set_words(p.pi_q_mut(), 0, &[plc_stw1(z), 0x1000]);
        p.is_running() && z & 0x0004 != 0
    };
    if !m.run_until(DEADLINE, running) {
        fail("the drive did not run", &slave, &m);
    }
    // The master goes silent for longer than the 1 s watchdog.
    let end = StdInstant::now() + DEADLINE;
    while !(slave.logged("watchdog expired") && slave.logged("S4 operation → fault")) {
        if StdInstant::now() > end {
            fail("no watchdog expiry logged", &slave, &m);
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    // F239 (0xEF): the drive's "fault" action with A139 offline (CFW500 §6).
    assert!(slave.logged("drive fault 00EF (fieldbus: communication lost)"), "{}", slave.dump());
    assert!(slave.logged("P0740 = 2 (offline)"), "{}", slave.dump());
    // The master comes back; the PLC acknowledges the fault (b7 edge) and runs the drive again.
    if !m.run_until(DEADLINE, running) {
        fail("the drive did not run again after the master came back", &slave, &m);
    }
    // The acknowledge (b7 edge) resets the drive's fault; the profile leaves fault for S1 / S2.
    assert!(slave.logged("drive: fault → S"), "{}", slave.dump());
    slave.finish();
}

/// Issue 6 "the soft slave runs any of these telegrams": one soft slave, re-parameterised
/// module after module by a new master on the same line (Set_Prm / Chk_Cfg again) — ST20,
/// VACON 139, PPO 6, CFW500 108, CFW-11 107, INVT — each run up to its setpoint with the
/// programmable words echoed and stopped, through its own control profile (the drive's fault
/// from leaving data exchange acknowledged with the family's reset).
#[test]
fn every_family_runs_the_drive_on_one_soft_slave() {
    use families::{FamilyDrive, Phase};
    let pty = Pty::open().expect("create a pseudo-terminal pair");
    // A 2 s ramp (0.5 s to the 25 % setpoint): enough master cycles for intermediate values
    // even when a loaded machine stretches the cycle to ~100 ms (500 ms gave 2 samples there).
    let slave = SoftSlave::start(pty.path().to_str().expect("a UTF-8 pty path"), 2000);
    let mut phy = GapResponder { inner: pty.into_phy(), slave: SLAVE, answer: Vec::new() };
    for reference in [20u16, 1139, 106, 2108, 3107, 4001] {
        let mut plc = FamilyDrive::new(reference, 25);
        let mut m = Master::on(phy, plc.module, None).skip_token_wait();
        if !m.run_until(DEADLINE, |p| p.is_running()) {
            fail(&format!("{}: no data exchange", plc.module.name), &slave, &m);
        }
        for phase in [Phase::Run, Phase::Stop] {
            plc.start(phase);
            let mut err = None;
            let ok = m.run_until(DEADLINE, |p| {
                let i = p.pi_i().to_vec();
                match plc.next(&i, phase) {
                    Ok((q, done)) => {
                        p.pi_q_mut().copy_from_slice(&q);
                        done
                    }
                    Err(e) => {
                        err = Some(e);
                        true
                    }
                }
            });
            if let Some(e) = err {
                fail(&e, &slave, &m);
            }
            if !ok {
                fail(&format!("{}: {phase:?} not done; actuals {:?}", plc.module.name, plc.actuals), &slave, &m);
            }
            if phase == Phase::Run {
                if let Err(e) = plc.check_ramp() {
                    fail(&e, &slave, &m);
                }
            }
        }
        assert!(slave.logged(&format!("Chk_Cfg: {}", plc.module.name)), "{}", slave.dump());
        println!("{}: {} cycles, {} fault acknowledges", plc.module.name, plc.cycles, plc.resets);
        phy = m.phy;
    }
    slave.finish();
}

/// Issue 12 item 4e (station part): the soft slave never answers a request from SA 127 (the
/// broadcast address), from its own address, or with FC bit 7 set; it answers the same
/// requests from a master's address.
#[test]
fn impossible_sources_and_reserved_fc_are_never_answered() {
    let pty = Pty::open().expect("create a pseudo-terminal pair");
    let slave = SoftSlave::start(pty.path().to_str().expect("a UTF-8 pty path"), 2000);
    let mut phy = pty.into_phy();
    let sd1 = |sa: u8, fc: u8| {
        let mut f = vec![0x10, SLAVE, sa, fc, 0, 0x16];
        f[4] = SLAVE.wrapping_add(sa).wrapping_add(fc);
        f
    };
    let diag = |sa: u8| {
        let hdr = Header { da: SLAVE, sa, fc: FunctionCode(0x6C), dsap: Some(60), ssap: Some(62) };
        let mut out = [0u8; telegram::MAX_FRAME_LEN];
        let n = telegram::emit(&mut out, &hdr, &[]).expect("telegram fits");
        out[..n].to_vec()
    };
    // The soft slave is up when it answers FDL_Status from the master.
    let t0 = StdInstant::now();
    let answer = loop {
        if let Some(a) = phy.request(&sd1(MASTER, 0x49), Duration::from_millis(200)).unwrap() {
            break a;
        }
        assert!(t0.elapsed() < DEADLINE, "no answer from the soft slave\n{}", slave.dump());
    };
    assert_eq!(answer, [0x10, MASTER, SLAVE, 0x00, MASTER + SLAVE, 0x16]);
    std::thread::sleep(Duration::from_millis(50));
    let _ = phy.take_received();
    let never: [(&str, Vec<u8>); 6] = [
        ("FDL_Status from SA 127", sd1(127, 0x49)),
        ("FDL_Status from our own address", sd1(SLAVE, 0x49)),
        ("FDL_Status with FC b7", sd1(MASTER, 0xC9)),
        ("Slave_Diag from SA 127", diag(127)),
        ("Slave_Diag from our own address", diag(SLAVE)),
        ("Slave_Diag with FC b7", {
            let mut f = diag(MASTER);
            f[6] |= 0x80;
            let n = f.len();
            f[n - 2] = f[4..n - 2].iter().fold(0u8, |s, &b| s.wrapping_add(b));
            f
        }),
    ];
    for (what, frame) in &never {
        let r = phy.request(frame, Duration::from_millis(300)).unwrap();
        assert_eq!(r, None, "{what} ({}) was answered\n{}", hex(frame), slave.dump());
        std::thread::sleep(Duration::from_millis(50));
    }
    // The same requests from the master are answered.
    assert!(phy.request(&diag(MASTER), Duration::from_secs(5)).unwrap().is_some(), "Slave_Diag from the master");
    let summary = slave.finish();
    assert_eq!(summary.responses, 2, "only the two requests from the master were answered");
}

/// Issue 12 item 4e (line part): a request followed without an idle line by more bytes
/// (`10 05 02 49 50 16 00 11 22` in one write) is not answered — the line was not idle for
/// T_SYN after it (reference §1.4), as the F411's `tx_plan` drops it (`TxDrop::LineActive`) —
/// and the drop is counted; the same request alone is answered before and after.
#[test]
fn a_request_followed_without_a_gap_is_not_answered() {
    let pty = Pty::open().expect("create a pseudo-terminal pair");
    let slave = SoftSlave::start(pty.path().to_str().expect("a UTF-8 pty path"), 2000);
    let mut phy = pty.into_phy();
    let status = [0x10, SLAVE, MASTER, 0x49, SLAVE + MASTER + 0x49, 0x16];
    let answer = [0x10, MASTER, SLAVE, 0x00, MASTER + SLAVE, 0x16];
    let t0 = StdInstant::now();
    let first = loop {
        if let Some(a) = phy.request(&status, Duration::from_millis(200)).unwrap() {
            break a;
        }
        assert!(t0.elapsed() < DEADLINE, "no answer from the soft slave\n{}", slave.dump());
    };
    assert_eq!(first, answer);
    std::thread::sleep(Duration::from_millis(50));
    let _ = phy.take_received();
    let mut run_on = status.to_vec();
    run_on.extend_from_slice(&[0x00, 0x11, 0x22]);
    for _ in 0..3 {
        let r = phy.request(&run_on, Duration::from_millis(300)).unwrap();
        assert_eq!(r, None, "{} was answered\n{}", hex(&run_on), slave.dump());
        std::thread::sleep(Duration::from_millis(50));
    }
    // The normal case: the clean request is answered again (the bytes after the last one were
    // cut away by the idle line), three times in a row.
    for _ in 0..3 {
        let r = phy.request(&status, Duration::from_secs(5)).unwrap();
        assert_eq!(r.as_deref(), Some(&answer[..]), "the clean FDL_Status after the run-on ones\n{}", slave.dump());
    }
    let summary = slave.finish();
    assert_eq!(summary.responses, 4, "only the clean requests were answered");
    assert_eq!(summary.dropped_line_active, 3, "every run-on request counted");
}
