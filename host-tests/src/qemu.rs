//! The firmware in QEMU, driven from the host: boot `qemu-system-arm -M netduinoplus2` with
//! USART1 on a Unix socket, collect the firmware's defmt log (decoded by `defmt-print`), and
//! run profirust's DP master against it in wall-clock time ([`LiveMaster`]) or send scripted
//! requests ([`StreamPhy::request`]).
//!
//! Used by `tests/qemu.rs` (end-to-end test), `src/bin/qemu_demo.rs` (README command 1) and
//! `src/bin/qemu_bench.rs` (the instruction-count benchmark). The ELFs are built by
//! `scripts/qemu.sh build` into `target/qemu/` ([`firmware_elf`]).
//!
//! Timing: nothing here depends on how fast the machine is. QEMU (without `-icount`) runs the
//! firmware in real time, the master uses `std::time::Instant`, and the master's slot time
//! (160 ms), retries (15) and the DP watchdog (10 s) are far beyond any scheduling delay;
//! bytes sent before the firmware has enabled its USART are lost, so [`wait_for_answer`]
//! polls FDL_Status until the slave answers before the master starts.

use std::io::{self, BufRead, BufReader, Read};
use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use pbcard::card;
use pbcard::fdl::telegram::{self, FunctionCode, Header};
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

/// The firmware's placeholder drive (`Loopback` in `src/main.rs`), modelled on the host so
/// that every input image can be predicted from the outputs sent before it.
#[derive(Debug, Clone)]
pub struct LoopbackModel {
    nist: i16,
    pzd: usize,
    len: usize,
}

impl LoopbackModel {
    /// NIST_A change per Data_Exchange (`Loopback::RAMP`).
    pub const RAMP: i32 = 0x0200;

    /// For `module`, from the reset state.
    pub fn new(module: &card::Module) -> Self {
        LoopbackModel { nist: 0, pzd: if module.cfg.first() == Some(&0xF3) { 8 } else { 0 }, len: module.inputs.into() }
    }

    /// Offset of STW1/ZSW1 in the images.
    pub fn pzd(&self) -> usize {
        self.pzd
    }

    /// The input image the firmware stages after a Data_Exchange carrying `outputs`.
    pub fn step(&mut self, outputs: &[u8]) -> Vec<u8> {
        let mut inp = vec![0u8; self.len];
        let m = outputs.len().min(self.len);
        inp[..m].copy_from_slice(&outputs[..m]);
        let p = self.pzd;
        if outputs.len() >= p + 4 && self.len >= p + 4 {
            let stw1 = u16::from_be_bytes([outputs[p], outputs[p + 1]]);
            let nsoll = i16::from_be_bytes([outputs[p + 2], outputs[p + 3]]);
            let plc = stw1 & 0x0400 != 0;
            let enabled = plc && stw1 & 0x000F == 0x000F;
            let target = if enabled { i32::from(nsoll) } else { 0 };
            let nist = i32::from(self.nist);
            self.nist = (nist + (target - nist).clamp(-Self::RAMP, Self::RAMP)) as i16;
            let zsw1: u16 = if !plc {
                0x0040
            } else {
                let bit = |on: bool, b: u16| if on { 1u16 << b } else { 0 };
                bit(stw1 & 1 != 0, 0)
                    | bit(stw1 & 7 == 7, 1)
                    | bit(enabled, 2)
                    | bit(stw1 & 2 != 0, 4)
                    | bit(stw1 & 4 != 0, 5)
                    | bit(true, 8)
                    | bit(true, 9)
                    | bit(enabled && i32::from(self.nist) == target, 10)
            };
            inp[p..p + 2].copy_from_slice(&zsw1.to_be_bytes());
            inp[p + 2..p + 4].copy_from_slice(&self.nist.to_be_bytes());
        }
        inp
    }
}

/// Check `cycles` against the model: PI_I of cycle k is what the firmware staged after
/// cycle k − 1 (after the warm-up cycles with all-zero outputs for cycle 0).
pub fn check_against_model(module: &card::Module, cycles: &[CycleRecord]) -> Result<(), String> {
    let mut model = LoopbackModel::new(module);
    let mut expect = model.step(&vec![0u8; module.outputs.into()]);
    for (k, c) in cycles.iter().enumerate() {
        if c.i_received != expect {
            return Err(format!(
                "cycle {k}: PI_I {} but the firmware's application should have staged {} (PI_Q of cycle {} was {})",
                hex(&c.i_received),
                hex(&expect),
                k as i64 - 1,
                if k > 0 { hex(&cycles[k - 1].q_sent) } else { "zeros".into() }
            ));
        }
        expect = model.step(&c.q_sent);
    }
    Ok(())
}

/// A drive-like output pattern for cycle `k` of `n`: stopped, then run at +0x4000, reverse to
/// −0x2000, stop again; every byte beyond the first PZD words changes every cycle.
pub fn drive_outputs(module: &card::Module, k: usize, n: usize) -> Vec<u8> {
    let len: usize = module.outputs.into();
    let p = LoopbackModel::new(module).pzd();
    let mut q: Vec<u8> =
        (0..len).map(|i| (k as u8).wrapping_mul(37).wrapping_add((i as u8).wrapping_mul(11))).collect();
    let phase = k * 8 / n.max(1);
    let (stw1, nsoll): (u16, i16) = match phase {
        0 => (0x047E, 0x4000), // ready, not running
        1..=3 => (0x047F, 0x4000),
        4..=5 => (0x047F, -0x2000),
        _ => (0x047E, 0),
    };
    q[p..p + 2].copy_from_slice(&stw1.to_be_bytes());
    q[p + 2..p + 4].copy_from_slice(&nsoll.to_be_bytes());
    q
}
