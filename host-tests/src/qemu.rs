//! The firmware in QEMU, driven from the host: boot `qemu-system-arm -M netduinoplus2` with
//! USART1 on a Unix socket, collect the firmware's defmt log (decoded by `defmt-print`), and
//! run profirust's DP master against it in wall-clock time ([`LiveMaster`]) or send scripted
//! requests ([`StreamPhy::request`]). [`DriveSession`] is a PLC program on that master for the
//! firmware's application — the simulated drive behind the DPM (`pbcard_sim::bench::Application`) —
//! that checks every input image against what that drive may answer.
//!
//! Used by `tests/qemu.rs` (end-to-end test), `src/bin/qemu_demo.rs` (README command 1) and
//! `src/bin/qemu_bench.rs` (the instruction-count benchmark). The ELFs are built by
//! `scripts/qemu.sh build` into `target/qemu/` ([`firmware_elf`]).
//!
//! Timing: nothing here depends on how fast the machine is. QEMU (without `-icount`) runs the
//! firmware in real time, the master uses `std::time::Instant`, and the master's slot time
//! (160 ms), retries (15) and the DP watchdog (10 s) are far beyond any scheduling delay;
//! bytes sent before the firmware has enabled its USART are lost, so [`wait_for_answer`]
//! polls FDL_Status until the slave answers before the master starts. The drive's ramp runs on
//! the firmware's clock, so the drive checks are about states, order and direction, never
//! about how many cycles something takes.

use std::io::{self, BufRead, BufReader, Read};
use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use pbcard::card;
use pbcard::dpm::Telegram;
use pbcard::fdl::telegram::{self, FunctionCode, Header};
use pbcard::profile::profidrive::{Stw1, Zsw1};
use profirust::dp::{DpMaster, Peripheral, PeripheralEvent, PeripheralHandle, PeripheralOptions};
use profirust::fdl::FdlActiveStation;

use crate::serial::StreamPhy;
use crate::{hex, CycleRecord};

/// The station address of the firmware (its factory default until the address store exists).
pub const SLAVE: u8 = card::DEFAULT_ADDRESS;
/// The host master's address.
pub const MASTER: u8 = 2;

/// Which firmware build.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Build {
    /// `--features qemu`: the demo and end-to-end build.
    Qemu,
    /// `--features bench`: logs TIM2 instruction counts per response.
    Bench,
    /// `--features bench-dma`: the same with the F411's DMA receive emulated (16-byte chunks,
    /// the rest at the telegram's end: `bsp::qemu::DmaEmu`).
    BenchDma,
}

/// The workspace's `target/` (or `$CARGO_TARGET_DIR`, relative to the workspace root).
pub fn target_dir() -> PathBuf {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    match std::env::var_os("CARGO_TARGET_DIR") {
        Some(d) => root.join(d), // an absolute path replaces the root
        None => root.join("target"),
    }
}

/// Where `scripts/qemu.sh build` puts the ELF of `build` (overridden by `PBCARD_QEMU_ELF` /
/// `PBCARD_BENCH_ELF`).
pub fn firmware_elf(build: Build) -> PathBuf {
    let (var, name) = match build {
        Build::Qemu => ("PBCARD_QEMU_ELF", "pbcard-qemu.elf"),
        Build::Bench => ("PBCARD_BENCH_ELF", "pbcard-bench.elf"),
        Build::BenchDma => ("PBCARD_BENCH_DMA_ELF", "pbcard-bench-dma.elf"),
    };
    std::env::var_os(var).map(PathBuf::from).unwrap_or_else(|| target_dir().join("qemu").join(name))
}

/// `defmt-print` from `PATH` or `$CARGO_HOME/bin`, if installed.
pub fn defmt_print() -> Option<PathBuf> {
    let candidates = [
        Some(PathBuf::from("defmt-print")),
        std::env::var_os("CARGO_HOME").map(|h| PathBuf::from(h).join("bin/defmt-print")),
        std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cargo/bin/defmt-print")),
    ];
    candidates.into_iter().flatten().find(|p| {
        Command::new(p).arg("--version").stdout(Stdio::null()).stderr(Stdio::null()).status().is_ok_and(|s| s.success())
    })
}

/// How to boot QEMU.
#[derive(Debug, Clone, Default)]
pub struct QemuOptions {
    /// `-icount shift=0,align=off,sleep=off`: one instruction = 1 ns of virtual time, TIM2
    /// counts instructions (benchmark). Without it the firmware runs in real time.
    pub icount: bool,
    /// Print each firmware log line as it arrives, prefixed with this.
    pub echo_log: Option<String>,
}

static INSTANCE: AtomicUsize = AtomicUsize::new(0);

/// A running QEMU with the firmware; killed on drop.
pub struct Qemu {
    child: Child,
    printer: Option<Child>,
    log: Arc<Mutex<Vec<String>>>,
    readers: Vec<JoinHandle<()>>,
    dir: PathBuf,
    exit: Option<std::process::ExitStatus>,
}

impl Qemu {
    /// Boot `elf` on netduinoplus2 with USART1 on a fresh Unix socket, semihosting on; the
    /// firmware's defmt output goes through `defmt-print` into [`log`](Qemu::log) (raw byte
    /// counts only when defmt-print is not installed).
    pub fn boot(elf: &Path, opts: &QemuOptions) -> io::Result<Qemu> {
        if !elf.exists() {
            return Err(io::Error::new(
                io::ErrorKind::NotFound,
                format!("{} not found: build it with `bash scripts/qemu.sh build`", elf.display()),
            ));
        }
        let dir = std::env::temp_dir().join(format!(
            "pbcard-qemu-{}-{}",
            std::process::id(),
            INSTANCE.fetch_add(1, Ordering::Relaxed)
        ));
        std::fs::create_dir_all(&dir)?;
        let sock = dir.join("usart1.sock");
        let mut cmd = Command::new("qemu-system-arm");
        cmd.args(["-M", "netduinoplus2", "-display", "none", "-monitor", "none", "-nodefaults"])
            .args(["-semihosting-config", "enable=on,target=native"])
            .arg("-serial")
            .arg(format!("unix:{},server=on,wait=off", sock.display()))
            .arg("-kernel")
            .arg(elf);
        if opts.icount {
            cmd.args(["-icount", "shift=0,align=off,sleep=off"]);
        }
        cmd.stdin(Stdio::null()).stdout(Stdio::piped()).stderr(Stdio::piped());
        let mut child = cmd.spawn().map_err(|e| {
            io::Error::new(e.kind(), format!("qemu-system-arm: {e} (install it: bash scripts/setup.sh)"))
        })?;
        let log = Arc::new(Mutex::new(Vec::new()));
        let mut readers = Vec::new();
        let qemu_out = child.stdout.take().expect("piped");
        let qemu_err = child.stderr.take().expect("piped");
        readers.push(spawn_lines(qemu_err, "qemu: ", log.clone(), opts.echo_log.clone()));
        let printer = match defmt_print() {
            Some(dp) => {
                let mut p = Command::new(dp)
                    .arg("-e")
                    .arg(elf)
                    .stdin(Stdio::from(qemu_out))
                    .stdout(Stdio::piped())
                    .stderr(Stdio::piped())
                    .spawn()?;
                readers.push(spawn_lines(p.stdout.take().expect("piped"), "", log.clone(), opts.echo_log.clone()));
                readers.push(spawn_lines(
                    p.stderr.take().expect("piped"),
                    "defmt-print: ",
                    log.clone(),
                    opts.echo_log.clone(),
                ));
                Some(p)
            }
            None => {
                let log2 = log.clone();
                readers.push(std::thread::spawn(move || {
                    let mut r = qemu_out;
                    let mut buf = [0u8; 4096];
                    let mut total = 0usize;
                    while let Ok(n) = r.read(&mut buf) {
                        if n == 0 {
                            break;
                        }
                        total += n;
                    }
                    log2.lock()
                        .unwrap()
                        .push(format!("({total} bytes of defmt log; install defmt-print to read them)"));
                }));
                None
            }
        };
        Ok(Qemu { child, printer, log, readers, dir, exit: None })
    }

    /// The socket of USART1.
    pub fn socket_path(&self) -> PathBuf {
        self.dir.join("usart1.sock")
    }

    /// Connect a PHY to USART1 (QEMU creates the socket at start-up; waits up to 10 s).
    pub fn connect(&self) -> io::Result<StreamPhy<UnixStream>> {
        StreamPhy::connect_unix(self.socket_path(), Duration::from_secs(10))
    }

    /// The firmware log so far (decoded defmt lines, QEMU's own messages prefixed `qemu:`).
    pub fn log(&self) -> Vec<String> {
        self.log.lock().unwrap().clone()
    }

    /// The log, shared (it keeps filling while QEMU runs).
    pub fn log_handle(&self) -> Arc<Mutex<Vec<String>>> {
        self.log.clone()
    }

    /// Number of log lines so far.
    pub fn log_len(&self) -> usize {
        self.log.lock().unwrap().len()
    }

    /// Wait until a log line contains `needle`; false on timeout.
    pub fn wait_log(&self, needle: &str, timeout: Duration) -> bool {
        let deadline = Instant::now() + timeout;
        while Instant::now() < deadline {
            if self.log.lock().unwrap().iter().any(|l| l.contains(needle)) {
                return true;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        false
    }

    /// `Err` with the exit status when QEMU has ended (a firmware panic or HardFault exits
    /// through semihosting with code 1).
    pub fn check_running(&mut self) -> Result<(), String> {
        if self.exit.is_none() {
            self.exit = self.child.try_wait().ok().flatten();
        }
        match self.exit {
            None => Ok(()),
            Some(st) => Err(format!("QEMU ended by itself: {st}")),
        }
    }

    /// Stop QEMU (if still running) and return the complete log.
    pub fn stop(mut self) -> Vec<String> {
        self.shutdown();
        self.log()
    }

    fn shutdown(&mut self) {
        if self.exit.is_none() {
            let _ = self.child.kill();
            self.exit = self.child.wait().ok();
        }
        if let Some(mut p) = self.printer.take() {
            // defmt-print ends at the end of its input; do not wait forever.
            let deadline = Instant::now() + Duration::from_secs(2);
            while Instant::now() < deadline {
                if let Ok(Some(_)) = p.try_wait() {
                    break;
                }
                std::thread::sleep(Duration::from_millis(10));
            }
            let _ = p.kill();
            let _ = p.wait();
        }
        for r in self.readers.drain(..) {
            let _ = r.join();
        }
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

impl Drop for Qemu {
    fn drop(&mut self) {
        self.shutdown();
    }
}

fn spawn_lines(
    r: impl Read + Send + 'static,
    prefix: &'static str,
    log: Arc<Mutex<Vec<String>>>,
    echo: Option<String>,
) -> JoinHandle<()> {
    std::thread::spawn(move || {
        for line in BufReader::new(r).lines() {
            let Ok(line) = line else { break };
            let line = format!("{prefix}{line}");
            if let Some(e) = &echo {
                println!("{e}{line}");
            }
            log.lock().unwrap().push(line);
        }
    })
}

/// An FDL_Status request (SD1, FC 0x49) from `sa` to `da`.
pub fn fdl_status_request(da: u8, sa: u8) -> Vec<u8> {
    frame(&Header { da, sa, fc: FunctionCode(0x49), dsap: None, ssap: None }, &[])
}

/// Emit a telegram.
pub fn frame(h: &Header, pdu: &[u8]) -> Vec<u8> {
    let mut out = [0u8; telegram::MAX_FRAME_LEN];
    let n = telegram::emit(&mut out, h, pdu).expect("telegram fits");
    out[..n].to_vec()
}

/// The "ready sign": send FDL_Status to `addr` every 50 ms until an answer comes back (the
/// firmware's USART is enabled and the node answers). Returns the time it took.
pub fn wait_for_answer<S: std::io::Read + std::io::Write>(
    phy: &mut StreamPhy<S>,
    addr: u8,
    timeout: Duration,
) -> Result<Duration, String> {
    let t0 = Instant::now();
    let req = fdl_status_request(addr, MASTER);
    while t0.elapsed() < timeout {
        match phy.request(&req, Duration::from_millis(50)) {
            Ok(Some(_)) => {
                // Let a possibly duplicated answer arrive, then start from a quiet line.
                std::thread::sleep(Duration::from_millis(20));
                let _ = phy.take_received();
                return Ok(t0.elapsed());
            }
            Ok(None) => {}
            Err(e) => return Err(format!("USART1 socket: {e}")),
        }
    }
    Err(format!("no answer to FDL_Status from #{addr} within {timeout:?}"))
}

/// How the wall-clock master is set up: generous everywhere (module documentation).
#[derive(Debug, Clone)]
pub struct MasterSetup {
    /// The rate profirust computes its bit times with (QEMU ignores rates).
    pub rate: profirust::Baudrate,
    /// Slot time in bit times of `rate`.
    pub slot_bits: u16,
    /// Retries per telegram.
    pub retries: u8,
    /// DP watchdog put into Set_Prm.
    pub watchdog: Option<Duration>,
}

impl Default for MasterSetup {
    fn default() -> Self {
        MasterSetup {
            rate: profirust::Baudrate::B187500,
            slot_bits: 30_000, // 160 ms
            retries: 15,
            watchdog: Some(Duration::from_secs(10)),
        }
    }
}

/// profirust's DP master (#[`MASTER`]) on a [`StreamPhy`], one peripheral, wall-clock time.
pub struct LiveMaster<S: std::io::Read + std::io::Write> {
    /// The PHY (for its counters).
    pub phy: StreamPhy<S>,
    fdl: FdlActiveStation,
    dp: DpMaster<'static>,
    handle: PeripheralHandle,
    addr: u8,
    epoch: Instant,
    /// Master time = wall clock since `epoch` + `warp` (see [`LiveMaster::poll`]).
    warp: Duration,
    warped_tx: u64,
    slot: Duration,
    /// Every master event for the peripheral: (ms since start, event).
    pub events: Vec<(u64, PeripheralEvent)>,
    /// DP cycles completed.
    pub cycles: u64,
    /// Pause after each poll (default 100 µs; the demo slows the exchange down with more).
    pub pause: Duration,
}

impl<S: std::io::Read + std::io::Write> LiveMaster<S> {
    /// A master for the card at `addr` with `module` and the default user parameters.
    pub fn new(phy: StreamPhy<S>, addr: u8, module: &card::Module, setup: &MasterSetup) -> Self {
        let options = PeripheralOptions {
            ident_number: card::IDENT_NUMBER,
            user_parameters: Some(Box::leak(card::USER_PRM_DEFAULTS.to_vec().into_boxed_slice())),
            config: Some(module.cfg),
            max_tsdr: card::max_tsdr(pbcard::time::Baudrate::B187500),
            fail_safe: card::FAIL_SAFE,
            ..Default::default()
        };
        let mut dp = DpMaster::new(Vec::new());
        let per = Peripheral::new(addr, options, vec![0u8; module.inputs.into()], vec![0u8; module.outputs.into()])
            .with_diag_buffer(vec![0u8; card::MAX_DIAG_DATA_LEN]);
        let handle = dp.add(per);
        let mut b = profirust::fdl::ParametersBuilder::new(MASTER, setup.rate);
        b.slot_bits(setup.slot_bits).max_retry_limit(setup.retries).highest_station_address(MASTER + 1);
        b.gap_wait_rotations(100);
        if let Some(wd) = setup.watchdog {
            b.watchdog_timeout(profirust::time::Duration::from_millis(wd.as_millis() as u64));
        }
        let params = b.build_verified(&dp);
        let slot = Duration::from_micros(params.slot_time().total_micros());
        // Nobody else is on this line: skip the listen-before-claiming-the-token time.
        let warp = Duration::from_micros(params.token_lost_timeout().total_micros()) + Duration::from_millis(1);
        let mut fdl = FdlActiveStation::new(params);
        fdl.set_online();
        dp.enter_operate();
        LiveMaster {
            phy,
            fdl,
            dp,
            handle,
            addr,
            epoch: Instant::now(),
            warp: Duration::ZERO,
            warped_tx: 0,
            slot,
            events: Vec::new(),
            cycles: 0,
            pause: Duration::from_micros(100),
        }
        .with_startup_warp(warp)
    }

    fn with_startup_warp(mut self, warp: Duration) -> Self {
        self.poll(); // the master starts listening "now"…
        self.warp += warp; // …and has heard a silent line for the token-lost timeout
        self
    }

    /// Milliseconds since the master started.
    pub fn ms(&self) -> u64 {
        self.epoch.elapsed().as_millis() as u64
    }

    /// The master's view of the slave.
    pub fn peripheral(&mut self) -> &mut Peripheral<'static> {
        self.dp.get_mut(self.handle)
    }

    /// The master's clock: wall clock plus the skipped silent waits.
    fn master_now(&self) -> profirust::time::Instant {
        profirust::time::Instant::from_micros((self.epoch.elapsed() + self.warp).as_micros() as i64)
    }

    /// One poll of the master (then a 100 µs pause); the peripheral event, if any.
    ///
    /// Known-silent waits are skipped by advancing the master's clock: profirust 0.6's GAP
    /// poll never ends with a single master (next station = itself), so every token
    /// rotation sends FDL_Status to one of the addresses 0..=HSA-1, none of which is
    /// occupied here; waiting out the (generous) slot time for each would throttle the
    /// exchange to a few cycles per second. Requests to the slave are never affected.
    pub fn poll(&mut self) -> Option<PeripheralEvent> {
        let now = self.master_now();
        self.fdl.poll(now, &mut self.phy, &mut self.dp);
        let sent = self.phy.stats().tx_telegrams;
        if sent != self.warped_tx {
            self.warped_tx = sent;
            let t = self.phy.last_tx();
            // SD1 FDL_Status request (FC 0x49) to an address other than the slave's.
            if t.len() == 6 && t[0] == telegram::SD1 && t[3] == 0x49 && t[1] != self.addr {
                self.warp += self.slot + Duration::from_millis(2);
            }
        }
        let ev = self.dp.take_last_events();
        if ev.cycle_completed {
            self.cycles += 1;
        }
        let pe = ev.peripheral.map(|(_, e)| e);
        if let Some(e) = pe {
            self.events.push((self.ms(), e));
        }
        std::thread::sleep(self.pause);
        pe
    }

    /// Poll until `done` (given the event of each poll) returns true; false on timeout.
    pub fn run_until(
        &mut self,
        timeout: Duration,
        mut done: impl FnMut(&mut Self, Option<PeripheralEvent>) -> bool,
    ) -> bool {
        let deadline = Instant::now() + timeout;
        while Instant::now() < deadline {
            let e = self.poll();
            if done(self, e) {
                return true;
            }
        }
        false
    }

    /// Until the first Data_Exchange.
    pub fn bring_up(&mut self, timeout: Duration) -> Result<(), String> {
        if self.run_until(timeout, |_, e| e == Some(PeripheralEvent::DataExchanged)) {
            Ok(())
        } else {
            Err(format!("no data exchange with #{} within {timeout:?}; events {:?}", self.addr, self.events))
        }
    }

    /// `cycles` Data_Exchange cycles: PI_Q of cycle k is `outputs(k)`, changed only right
    /// after a DataExchanged event (the next request certainly carries it; one warm-up cycle
    /// first). Returns (PI_Q sent, PI_I received) per cycle.
    pub fn exchange(
        &mut self,
        cycles: usize,
        timeout: Duration,
        mut outputs: impl FnMut(usize) -> Vec<u8>,
    ) -> Result<Vec<CycleRecord>, String> {
        let start = Instant::now();
        if !self.run_until(timeout, |_, e| e == Some(PeripheralEvent::DataExchanged)) {
            return Err(format!("no warm-up data exchange; events {:?}", self.events));
        }
        let mut current = outputs(0);
        self.peripheral().pi_q_mut().copy_from_slice(&current);
        let mut log = Vec::with_capacity(cycles);
        let rest = timeout.saturating_sub(start.elapsed());
        let ok = self.run_until(rest, |m, e| {
            match e {
                Some(PeripheralEvent::DataExchanged) => {
                    let t_us = m.epoch.elapsed().as_micros() as u64;
                    let p = m.peripheral();
                    log.push(CycleRecord { t_us, q_sent: current.clone(), i_received: p.pi_i().to_vec() });
                    if log.len() == cycles {
                        return true;
                    }
                    current = outputs(log.len());
                    p.pi_q_mut().copy_from_slice(&current);
                }
                Some(PeripheralEvent::Offline) => return true,
                _ => {}
            }
            false
        });
        if !ok || log.len() < cycles {
            return Err(format!(
                "only {} of {cycles} cycles (timeout {timeout:?}); last events {:?}",
                log.len(),
                &self.events[self.events.len().saturating_sub(10)..]
            ));
        }
        Ok(log)
    }
}

// ---------------------------------------------------------------------------------------------
// The firmware's application: the simulated drive behind the DPM (pbcard_sim::bench::Application).
// ---------------------------------------------------------------------------------------------

/// 100 % speed in the N2 coding of NSOLL_A / NIST_A.
pub const SPEED_100: i16 = 0x4000;

/// An N2 speed in percent of the reference speed.
pub fn percent(n2: i16) -> f64 {
    f64::from(n2) * 100.0 / f64::from(SPEED_100)
}

/// What a control word asks the drive for (PROFIdrive, `pbcard::profile::profidrive`).
pub fn stw1_meaning(stw1: u16) -> &'static str {
    let s = Stw1::from_bits_retain(stw1);
    if !s.contains(Stw1::CONTROL_BY_PLC) {
        "not valid (b10 = 0)"
    } else if !s.contains(Stw1::NO_COAST_STOP) {
        "OFF2: coast stop"
    } else if !s.contains(Stw1::NO_QUICK_STOP) {
        "OFF3: quick stop"
    } else if !s.contains(Stw1::ON) {
        "OFF1: ready / ramp stop"
    } else if !s.contains(Stw1::ENABLE_OPERATION) {
        "ON, operation disabled"
    } else {
        "ON: run"
    }
}

/// The drive state a status word shows, with the "at setpoint" (b8), "100 % reached" (b10)
/// and warning (b7) bits. S3 and S5 look alike in ZSW1 (b0 b1); a non-zero speed tells S5.
pub fn zsw1_meaning(zsw1: u16, nist: i16) -> String {
    let z = Zsw1::from_bits_retain(zsw1);
    let mut s = String::from(if zsw1 == 0 {
        "no answer yet"
    } else if z.contains(Zsw1::FAULT) {
        "fault"
    } else if z.contains(Zsw1::SWITCHING_ON_INHIBITED) {
        "switching on inhibited"
    } else if z.contains(Zsw1::OPERATION_ENABLED) {
        "operation enabled"
    } else if z.contains(Zsw1::READY_TO_OPERATE) && nist != 0 {
        "switching off (ramp)"
    } else if z.contains(Zsw1::READY_TO_OPERATE) {
        "switched on"
    } else if z.contains(Zsw1::READY_TO_SWITCH_ON) {
        "ready to switch on"
    } else {
        "(no state bit)"
    });
    if z.contains(Zsw1::AT_SETPOINT) {
        s.push_str(", at setpoint");
    }
    if z.contains(Zsw1::SPEED_REACHED) {
        s.push_str(", 100 % reached");
    }
    if z.contains(Zsw1::WARNING) {
        s.push_str(", warning");
    }
    s
}

/// ZSW1 patterns (masked with [`ZSW1_STATE_MASK`]) of the states the tests drive through;
/// b4/b5 mirror STW1 b1/b2 (set in 0x047E / 0x047F), b9 "control requested" is always set.
pub const ZSW1_STATE_MASK: u16 = 0x027F;
/// S1 switching on inhibited, before any valid control word: b6 b9.
pub const ZSW1_S1: u16 = 0x0240;
/// S2 ready for switching on: b0 b4 b5 b9.
pub const ZSW1_S2: u16 = 0x0231;
/// S3 switched on or S5 switching off: b0 b1 b4 b5 b9.
pub const ZSW1_S3_S5: u16 = 0x0233;
/// S4 operation enabled: b0 b1 b2 b4 b5 b9.
pub const ZSW1_S4: u16 = 0x0237;

fn word(b: &[u8], i: usize) -> u16 {
    u16::from_be_bytes([b[2 * i], b[2 * i + 1]])
}

/// Where the drive's words are in a module's process data (PKW first for PPO 1/2/5, then
/// STW1/ZSW1, NSOLL_A/NIST_A, PZD3…), and the output images the tests send.
#[derive(Debug, Clone)]
pub struct DriveImage {
    pkw: usize,
    pzd: usize,
}

impl DriveImage {
    /// The layout of `module` (Standard telegram 1 or a PPO type).
    pub fn new(module: &card::Module) -> Self {
        let t = Telegram::of_module(module).expect("a drive telegram");
        assert_eq!(usize::from(module.outputs), 2 * (t.pkw_words() + t.pzd_words()));
        DriveImage { pkw: t.pkw_words(), pzd: t.pzd_words() }
    }

    /// Word index of STW1 / ZSW1 (NSOLL_A / NIST_A follow).
    pub fn pzd1(&self) -> usize {
        self.pkw
    }

    /// Image length in bytes (both ways).
    pub fn len(&self) -> usize {
        2 * (self.pkw + self.pzd)
    }

    /// Never empty (at least STW1 and NSOLL_A).
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Outputs: PKW all zero (no parameter request), STW1, NSOLL_A, and PZD3… made from `tag`
    /// (distinct per cycle, so that their echo tells which outputs the drive answered).
    pub fn outputs(&self, stw1: u16, nsoll: i16, tag: u16) -> Vec<u8> {
        let mut w = vec![0u16; self.pkw + self.pzd];
        w[self.pkw] = stw1;
        w[self.pkw + 1] = nsoll as u16;
        for (i, x) in w.iter_mut().enumerate().skip(self.pkw + 2) {
            *x = tag.rotate_left(3 * i as u32) ^ (0x0101 * i as u16);
        }
        w.iter().flat_map(|x| x.to_be_bytes()).collect()
    }

    /// STW1 of an output image.
    pub fn stw1(&self, outputs: &[u8]) -> u16 {
        word(outputs, self.pkw)
    }
    /// NSOLL_A of an output image.
    pub fn nsoll(&self, outputs: &[u8]) -> i16 {
        word(outputs, self.pkw + 1) as i16
    }
    /// ZSW1 of an input image.
    pub fn zsw1(&self, inputs: &[u8]) -> u16 {
        word(inputs, self.pkw)
    }
    /// NIST_A of an input image.
    pub fn nist(&self, inputs: &[u8]) -> i16 {
        word(inputs, self.pkw + 1) as i16
    }
    /// The echoed words PZD3… (empty for Standard telegram 1, PPO 1 and 3).
    fn echo<'a>(&self, image: &'a [u8]) -> &'a [u8] {
        &image[2 * (self.pkw + 2)..]
    }
}

/// One Data_Exchange cycle as the PLC program sees it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Sample {
    /// Since the [`DriveSession`] started.
    pub t: Duration,
    /// Cycles of the session so far, this one included.
    pub cycle: usize,
    /// STW1 sent in this cycle.
    pub stw1: u16,
    /// NSOLL_A sent in this cycle.
    pub nsoll: i16,
    /// ZSW1 received in this cycle.
    pub zsw1: u16,
    /// NIST_A received in this cycle.
    pub nist: i16,
}

/// A PLC program on the [`LiveMaster`] that runs the firmware's simulated drive, checking
/// every input image against what that drive may answer — whatever the timing, since the
/// drive runs on the firmware's clock (every millisecond and after each Data_Exchange) and
/// its ramp depends on time, not on cycles:
///
/// * the length of the module, PKW all zero (no parameter request is sent);
/// * all zero only until the drive's first answer (the input image of a new telegram);
/// * ZSW1 shows one state of the PROFIdrive diagram (S1, S2, S3/S5, S4; a fault fails), b9
///   "control requested" always, b4/b5 once past S1, b8 "at setpoint" only in S4, b10
///   exactly when |NIST_A| ≥ 100 %, NIST_A ≠ 0 only with the motor powered (b0 b1);
/// * PZD3… (PPO 2/4/5/6) echo an earlier output image — never the one of the request they
///   answer (pre-staged, one cycle late at least), never one older than an echo already seen
///   (in order, never torn).
///
/// The ramp's direction and end points are the callers' checks ([`monotonic`]).
pub struct DriveSession<S: std::io::Read + std::io::Write> {
    /// The master.
    pub master: LiveMaster<S>,
    /// The module's layout.
    pub image: DriveImage,
    /// Output images in the order sent; `[0]` stands for the all-zero outputs of the bring-up.
    sent: Vec<Vec<u8>>,
    echo_from: usize,
    answered: bool,
    /// Largest distance in cycles between outputs and their echo in the inputs (PPO 2/4/5/6).
    pub max_echo_lag: usize,
    /// Cycles checked.
    pub cycles: usize,
    t0: Instant,
}

impl<S: std::io::Read + std::io::Write> DriveSession<S> {
    /// Start on a master in data exchange with all-zero outputs (as after
    /// [`LiveMaster::bring_up`]).
    pub fn new(mut master: LiveMaster<S>, module: &card::Module) -> Self {
        let image = DriveImage::new(module);
        let zeros = vec![0u8; image.len()];
        master.peripheral().pi_q_mut().copy_from_slice(&zeros);
        DriveSession {
            master,
            image,
            sent: vec![zeros],
            echo_from: 0,
            answered: false,
            max_echo_lag: 0,
            cycles: 0,
            t0: Instant::now(),
        }
    }

    /// Send STW1 / NSOLL_A from the next cycle on and poll until `done` holds for a cycle (it
    /// sees every checked [`Sample`]); returns the samples. `Err` on a failed check, when the
    /// master loses the slave, or after `timeout`.
    pub fn run(
        &mut self,
        stw1: u16,
        nsoll: i16,
        timeout: Duration,
        mut done: impl FnMut(&Sample) -> bool,
    ) -> Result<Vec<Sample>, String> {
        let deadline = Instant::now() + timeout;
        let mut samples: Vec<Sample> = Vec::new();
        loop {
            if Instant::now() > deadline {
                let tail = &samples[samples.len().saturating_sub(5)..];
                return Err(format!(
                    "STW1 {stw1:04X} NSOLL_A {nsoll:+}: the expected state did not come within {timeout:?} \
                     ({} cycles); last samples {tail:04X?}",
                    samples.len()
                ));
            }
            match self.master.poll() {
                Some(PeripheralEvent::DataExchanged) => {
                    // This cycle's request carried the last image sent.
                    let q = self.sent.last().expect("sent").clone();
                    let i = self.master.peripheral().pi_i().to_vec();
                    self.cycles += 1;
                    if let Err(e) = self.check(&i) {
                        return Err(format!(
                            "cycle {} (STW1 {:04X} NSOLL_A {:+} sent): PI_I {}: {e}",
                            self.cycles,
                            self.image.stw1(&q),
                            self.image.nsoll(&q),
                            hex(&i)
                        ));
                    }
                    let s = Sample {
                        t: self.t0.elapsed(),
                        cycle: self.cycles,
                        stw1: self.image.stw1(&q),
                        nsoll: self.image.nsoll(&q),
                        zsw1: self.image.zsw1(&i),
                        nist: self.image.nist(&i),
                    };
                    samples.push(s);
                    // The next request carries the new outputs (PI_Q is read when it is built).
                    let tag = self.sent.len() as u16;
                    let out = self.image.outputs(stw1, nsoll, tag);
                    self.master.peripheral().pi_q_mut().copy_from_slice(&out);
                    self.sent.push(out);
                    if done(&s) {
                        return Ok(samples);
                    }
                }
                Some(PeripheralEvent::Offline) => {
                    return Err(format!("the master lost the slave; events {:?}", self.master.events));
                }
                _ => {}
            }
        }
    }

    /// Time since the session started.
    pub fn elapsed(&self) -> Duration {
        self.t0.elapsed()
    }

    /// Keep STW1 / NSOLL_A for `cycles` more cycles; every sample must satisfy `ok`.
    pub fn hold(
        &mut self,
        stw1: u16,
        nsoll: i16,
        cycles: usize,
        timeout: Duration,
        what: &str,
        ok: impl Fn(&Sample) -> bool,
    ) -> Result<Vec<Sample>, String> {
        let mut n = 0;
        let samples = self.run(stw1, nsoll, timeout, |_| {
            n += 1;
            n >= cycles
        })?;
        match samples.iter().find(|s| !ok(s)) {
            Some(bad) => Err(format!("STW1 {stw1:04X} NSOLL_A {nsoll:+}, {what}: not so in {bad:04X?}")),
            None => Ok(samples),
        }
    }

    /// The input image checks of the type documentation.
    fn check(&mut self, i: &[u8]) -> Result<(), String> {
        let img = &self.image;
        if i.len() != img.len() {
            return Err(format!("{} bytes, the module has {}", i.len(), img.len()));
        }
        if i.iter().all(|&b| b == 0) {
            return if self.answered { Err("all zero after the drive had answered".into()) } else { Ok(()) };
        }
        self.answered = true;
        if i[..2 * img.pkw].iter().any(|&b| b != 0) {
            return Err("PKW not zero (no parameter request was sent)".into());
        }
        // PZD3…: the echo of an earlier output image, in order.
        if !img.echo(i).is_empty() {
            let newest = self.sent.len().saturating_sub(2); // not the request this answers
            let found = (self.echo_from..=newest).find(|&j| img.echo(&self.sent[j]) == img.echo(i));
            match found {
                Some(j) => {
                    self.echo_from = j;
                    self.max_echo_lag = self.max_echo_lag.max(self.sent.len() - 1 - j);
                }
                None => {
                    return Err(format!(
                        "PZD3… {} echo no output image sent between #{} and #{newest} (the last one echoed \
                         before, and the one before this request)",
                        hex(img.echo(i)),
                        self.echo_from
                    ))
                }
            }
        }
        let (zsw1, nist) = (img.zsw1(i), img.nist(i));
        let z = Zsw1::from_bits_retain(zsw1);
        let state = zsw1 & 0x004F;
        if z.contains(Zsw1::FAULT) {
            return Err(format!("ZSW1 {zsw1:04X}: the drive is in fault"));
        }
        if ![0x0040, 0x0001, 0x0003, 0x0007].contains(&state) {
            return Err(format!("ZSW1 {zsw1:04X}: b0 b1 b2 b6 show no state of the PROFIdrive diagram"));
        }
        if !z.contains(Zsw1::CONTROL_REQUESTED) {
            return Err(format!("ZSW1 {zsw1:04X}: b9 control requested missing"));
        }
        if state != 0x0040 && zsw1 & 0x0030 != 0x0030 {
            return Err(format!("ZSW1 {zsw1:04X}: past S1, but b4/b5 (no OFF2/OFF3) not set"));
        }
        if z.contains(Zsw1::AT_SETPOINT) && state != 0x0007 {
            return Err(format!("ZSW1 {zsw1:04X}: b8 at setpoint outside S4"));
        }
        if z.contains(Zsw1::SPEED_REACHED) != (i32::from(nist).abs() >= i32::from(SPEED_100)) {
            return Err(format!("ZSW1 {zsw1:04X}: b10 does not match NIST_A {nist:+}"));
        }
        if nist != 0 && state & 0x0003 != 0x0003 {
            return Err(format!("NIST_A {nist:+} with ZSW1 {zsw1:04X}: speed without the motor powered"));
        }
        Ok(())
    }
}

/// Whether NIST_A of `samples` only moves toward `to` (never away, never past it), and how
/// many distinct values lie strictly between `from` and `to` (a ramp, not a jump).
pub fn monotonic(samples: &[Sample], from: i16, to: i16) -> Result<usize, String> {
    let (lo, hi) = (from.min(to), from.max(to));
    let mut last = from;
    let mut between = std::collections::BTreeSet::new();
    for s in samples {
        let n = s.nist;
        let backwards = if to >= from { n < last } else { n > last };
        if n < lo || n > hi || backwards {
            return Err(format!(
                "NIST_A {n:+} after {last:+} in cycle {}: not monotonic from {from:+} to {to:+}",
                s.cycle
            ));
        }
        if n != lo && n != hi {
            between.insert(n);
        }
        last = n;
    }
    Ok(between.len())
}
