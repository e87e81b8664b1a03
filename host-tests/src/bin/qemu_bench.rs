//! The response-path benchmark: the firmware's `bench` build runs in QEMU with
//! `-icount shift=0,align=off,sleep=off`, where TIM2 (prescaler 0) advances by exactly one per
//! executed instruction. For every request it answers, the USART1 handler logs the TIM2
//! difference between its entry for the byte that completed the request and the write of the
//! first response byte into DR (`BENCH req <n> resp <m> instr <i>`). This program sends the
//! requests one at a time over the socket — DP-V0 bring-up and Data_Exchange for four GSD
//! modules (4, 12, 20, 28 bytes each way) and the bench build's two extra modules (32 and 244
//! bytes each way, [`BENCH_MODULES`]), then an MSAC_C2 connection and MSAC_C1 (SAP 51), each
//! reading PNU 918 through record 47 — collects those lines from the
//! decoded defmt log and prints a Markdown table (the README's "Benchmark" section).
//!
//! Measured path: RTIC handler entry → SR/DR read → `Node::on_byte` (framer, telegram decode
//! and checksum, FDL station, DP or DP-V1 service, response staging) → `QemuUsart1::stage_tx`
//! (copy into the TX buffer) → first DR write. Not included: interrupt entry latency before
//! the handler, min_TSDR (the QEMU port does not wait: no line timing), the application's
//! input update and the DP-V1 work (lower-priority tasks, after the first byte is out).
//! Instructions, not cycles: on the F411 (96 MHz, flash wait states with the ART accelerator)
//! a cycle count is at least this.
//!
//! A second table gives the largest instruction counts of the lower-priority work done with
//! the Node locked (`LOCK <what> <n>` lines: the two locked parts of the application step,
//! `Application::snapshot` and `Application::apply`, and `Node::process_acyclic`): the time
//! the response decision (and on QEMU USART1) is masked, which delays a response and which a
//! per-character receiver must survive without overrun. The unlocked middle of the step
//! (`UNLOCKED app.step`: DPM publish, simulated drive, profile cycle, PKW, DRIVE_CMD) is
//! listed for comparison; it is preempted by the line and the decision (their instructions
//! are counted in it too).
//!
//! Run: `bash scripts/qemu.sh bench`.

use std::sync::{Arc, Mutex, OnceLock};
use std::time::Duration;

use host_tests::qemu::{self, Build, Qemu, QemuOptions, MASTER, SLAVE};
use host_tests::serial::StreamPhy;
use pbcard::card;
use pbcard::fdl::telegram::{FunctionCode, Header};

/// SRD with high priority (FDL function code 0x0D).
const SRD_HIGH: u8 = 0x0D;
/// Samples per request kind.
const SAMPLES: usize = 10;
/// The class-2 master of the DP-V1 requests.
const C2_MASTER: u8 = 10;
/// The `bench` build's modules (`card::BENCH_32`, `card::BENCH_244`; not in the GSD, and not
/// compiled into the `pbcard` this program links, which has no `bench` feature): name, cfg,
/// input and output bytes. Checked against `dp::cfg::io_lengths` before use.
const BENCH_MODULES: [(&str, &[u8], u8, u8); 2] = [
    ("Bench 32/32, bench build only", &[0xFF], 32, 32),
    ("Bench 244/244, bench build only", &[0xC0, 0xFF, 0xFF, 0xC0, 0xF9, 0xF9], 244, 244),
];

struct Script<S: std::io::Read + std::io::Write> {
    phy: StreamPhy<S>,
    fcb: bool,
    c2_fcb: bool,
    /// (label, request bytes, response bytes) per answered request, in order.
    sent: Vec<(String, usize, usize)>,
}

impl<S: std::io::Read + std::io::Write> Script<S> {
    /// An SRD from the class-2 master #[`C2_MASTER`] (SSAP 50) to `dsap`, with its own FCB.
    fn c2(&mut self, label: &str, dsap: u8, pdu: &[u8]) -> Vec<u8> {
        self.c2_fcb = !self.c2_fcb;
        let h = Header {
            da: SLAVE,
            sa: C2_MASTER,
            fc: FunctionCode::request(SRD_HIGH, self.c2_fcb, true),
            dsap: Some(dsap),
            ssap: Some(50),
        };
        self.raw(label, &qemu::frame(&h, pdu))
    }

    /// An MSAC_C1 SRD from the class-1 master (SSAP and DSAP 51), on its FCB.
    fn c1(&mut self, label: &str, pdu: &[u8]) -> Vec<u8> {
        self.fcb = !self.fcb;
        let h = Header {
            da: SLAVE,
            sa: MASTER,
            fc: FunctionCode::request(SRD_HIGH, self.fcb, true),
            dsap: Some(51),
            ssap: Some(51),
        };
        self.raw(label, &qemu::frame(&h, pdu))
    }

    fn srd(&mut self, label: &str, dsap: Option<u8>, pdu: &[u8]) -> Vec<u8> {
        self.fcb = !self.fcb;
        let h = Header {
            da: SLAVE,
            sa: MASTER,
            fc: FunctionCode::request(SRD_HIGH, self.fcb, true),
            dsap,
            ssap: dsap.map(|_| 62),
        };
        self.raw(label, &qemu::frame(&h, pdu))
    }

    fn raw(&mut self, label: &str, req: &[u8]) -> Vec<u8> {
        let resp = match self.phy.request(req, Duration::from_secs(10)) {
            Ok(Some(r)) => r,
            Ok(None) => fail(&format!("{label}: no answer to {}", host_tests::hex(req))),
            Err(e) => fail(&format!("{label}: {e}")),
        };
        self.sent.push((label.to_string(), req.len(), resp.len()));
        resp
    }
}

/// The firmware log, printed when the benchmark fails.
static LOG: OnceLock<Arc<Mutex<Vec<String>>>> = OnceLock::new();

/// A row of the bench build's own modules (not a request the shipped card can get).
fn bench_only(l: &str) -> bool {
    l.contains("bench build only")
        || l.starts_with("Data_Exchange 32 out / 32 in")
        || l.starts_with("Data_Exchange 244 out / 244 in")
}

/// The samples' range as a table cell: `lo – hi`, or one figure.
fn span(v: &[u32]) -> String {
    let (lo, hi) = (v.iter().min().unwrap(), v.iter().max().unwrap());
    if lo == hi {
        format!("{lo}")
    } else {
        format!("{lo} – {hi}")
    }
}

fn fail(what: &str) -> ! {
    if let Some(log) = LOG.get() {
        eprintln!("--- firmware log ---\n{}", log.lock().unwrap().join("\n"));
    }
    eprintln!("benchmark failed: {what}");
    std::process::exit(1);
}

fn main() {
    // `--dma`: the bench-dma build, the F411's DMA receive emulated (`bsp::qemu::DmaEmu`).
    let dma = std::env::args().any(|a| a == "--dma");
    let elf = qemu::firmware_elf(if dma { Build::BenchDma } else { Build::Bench });
    let q = Qemu::boot(&elf, &QemuOptions { icount: true, echo_log: None }).unwrap_or_else(|e| fail(&e.to_string()));
    let _ = LOG.set(q.log_handle());
    let mut phy = q.connect().unwrap_or_else(|e| fail(&e.to_string()));
    if let Err(e) = qemu::wait_for_answer(&mut phy, SLAVE, Duration::from_secs(30)) {
        fail(&e);
    }
    std::thread::sleep(Duration::from_millis(200));
    let bench_lines = |q: &Qemu| q.log().into_iter().filter(|l| l.contains("BENCH ")).collect::<Vec<_>>();
    let skip = bench_lines(&q).len(); // the ready probe's answers
    let mut s = Script { phy, fcb: false, c2_fcb: false, sent: Vec::new() };

    for _ in 0..SAMPLES {
        s.raw("FDL_Status", &qemu::fdl_status_request(SLAVE, MASTER));
    }
    let by_ref = |r: u16| card::MODULES.iter().find(|m| m.reference == r).expect("module");
    // Standard telegram 1, PPO 1, PPO 2, PPO 5: 4, 12, 20, 28 bytes each way (GSD modules).
    let gsd = [by_ref(1), by_ref(101), by_ref(102), by_ref(105)].map(|m| (m.name, m.cfg, m.inputs, m.outputs));
    for (i, &(name, cfg, inputs, outputs)) in gsd.iter().chain(&BENCH_MODULES).enumerate() {
        let io = pbcard::dp::cfg::io_lengths(cfg).unwrap_or_else(|e| fail(&format!("{name}: {e:?}")));
        if (io.inputs, io.outputs) != (inputs.into(), outputs.into()) {
            fail(&format!("{name}: cfg {} means {io:?}", host_tests::hex(cfg)));
        }
        let id = card::IDENT_NUMBER.to_be_bytes();
        // Lock_Req, WD off, min_TSDR 11, ident, no groups; default user parameters.
        let mut prm = vec![0x80, 0x01, 0x01, 11, id[0], id[1], 0x00];
        prm.extend_from_slice(&card::USER_PRM_DEFAULTS);
        let label = if i == 0 { "Set_Prm (Wait_Prm)" } else { "Set_Prm (new parameters in Data_Exch)" };
        s.srd(label, Some(61), &prm);
        s.srd(&format!("Chk_Cfg {} ({name})", host_tests::hex(cfg)), Some(62), cfg);
        s.srd("Slave_Diag", Some(60), &[]);
        let n: usize = outputs.into();
        for k in 0..SAMPLES {
            let out: Vec<u8> = (0..n).map(|i| (i * 7 + k * 13) as u8).collect();
            let resp = s.srd(&format!("Data_Exchange {n} out / {inputs} in"), None, &out);
            let pdu = host_tests::pdu_of(&resp).unwrap_or_else(|| fail("Data_Exchange answer without data"));
            if pdu.len() != inputs as usize {
                fail(&format!("Data_Exchange answered {} bytes, module has {inputs}", pdu.len()));
            }
        }
        if i == gsd.len() - 1 {
            // A Data_Exchange without outputs (SD1, the fail-safe Clear): answered with the
            // staged inputs; the next one with outputs ends the fail-safe state.
            for _ in 0..SAMPLES {
                let resp = s.srd("Data_Exchange 0 out (SD1: fail-safe Clear)", None, &[]);
                if host_tests::pdu_of(&resp).map(<[u8]>::len) != Some(inputs.into()) {
                    fail(&format!("fail-safe Data_Exchange answered {}", host_tests::hex(&resp)));
                }
            }
            // A Data_Exchange of the wrong length (32 or 244 bytes to PPO 5) is answered RS:
            // the request path up to the decision, with the checksum over the long frame.
            for n in [32usize, 244] {
                for k in 0..SAMPLES {
                    let out: Vec<u8> = (0..n).map(|i| (i * 3 + k) as u8).collect();
                    s.srd(&format!("Data_Exchange {n} out to PPO 5 (wrong length: RS)"), None, &out);
                }
            }
        }
    }
    // Other stations' traffic (nothing answers): Data_Exchange of 244 and 32 bytes from the
    // master to station SLAVE - 1, for the per-character cost of a foreign telegram (the
    // `STREAM other` lines); each followed by a request to the card, so the line is known to
    // have taken it.
    for k in 0..SAMPLES {
        for n in [244usize, 32] {
            let h = Header {
                da: SLAVE - 1,
                sa: MASTER,
                fc: FunctionCode::request(SRD_HIGH, k % 2 == 0, true),
                dsap: None,
                ssap: None,
            };
            let out: Vec<u8> = (0..n).map(|i| (i + k) as u8).collect();
            if let Err(e) = s.phy.send(&qemu::frame(&h, &out)) {
                fail(&format!("foreign telegram: {e}"));
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        s.srd("Slave_Diag", Some(60), &[]);
    }
    for _ in 0..SAMPLES - 1 {
        s.srd("Slave_Diag", Some(60), &[]);
    }
    // DP-V1 MSAC_C2: connect (Send_Timeout 60 s), then read PNU 918 through record 47 —
    // DS_Write of the parameter request, DS_Read of the response — each acknowledged with SC
    // and worked on by the firmware's middle-priority task before the master's poll.
    let initiate = [0x57, 0, 0, 0, 0x17, 0x70, 0x01, 0x00, 0, 0, 0, 0, 0, 2, 0, 2, 0, 0, 0, 0];
    let rm = s.c2("MSAC_C2 Initiate.req to the resource manager (RM PDU)", 49, &initiate);
    let sap = match host_tests::pdu_of(&rm) {
        Some(&[0x56, sap, _, _]) => sap,
        _ => fail(&format!("RM answer {}", host_tests::hex(&rm))),
    };
    s.c2("MSAC_C2 Initiate.req (SC)", sap, &initiate);
    // Poll until the response is there (with -icount the task has always run by then).
    let poll = |s: &mut Script<_>, what: &str| {
        for _ in 0..100 {
            let r = s.c2(&format!("MSAC_C2 poll → {what}"), sap, &[]);
            if host_tests::pdu_of(&r).is_some_and(|p| !p.is_empty()) {
                return r;
            }
            s.sent.last_mut().expect("sent").0 = "MSAC_C2 poll → not ready (SC)".into();
        }
        fail("no MSAC_C2 response after 100 polls")
    };
    poll(&mut s, "Initiate.res");
    for k in 1..=SAMPLES as u8 {
        s.c2(
            "MSAC_C2 DS_Write record 47, read PNU 918 (SC)",
            sap,
            &[0x5F, 0, 47, 10, k, 1, 1, 1, 0x10, 1, 0x03, 0x96, 0, 0],
        );
        poll(&mut s, "DS_Write.res");
        s.c2("MSAC_C2 DS_Read record 47 (SC)", sap, &[0x5E, 0, 47, 240]);
        let r = poll(&mut s, "DS_Read.res, PNU 918 = 126");
        if host_tests::pdu_of(&r) != Some(&[0x5E, 0, 47, 8, k, 1, 1, 1, 0x42, 1, 0, SLAVE][..]) {
            fail(&format!("PNU 918 read: {}", host_tests::hex(&r)));
        }
    }

    // DP-V1 MSAC_C1 (SAP 51) from the class-1 master: parameterised again with DPV1_Enable
    // (DPV1_Status_1 b7) and Standard telegram 1, then PNU 918 through record 47 — DS_Write,
    // DS_Read, each acknowledged SC by the line and answered on a later poll from the staging.
    let st1 = by_ref(1);
    let id = card::IDENT_NUMBER.to_be_bytes();
    let mut prm = vec![0x80, 0x01, 0x01, 11, id[0], id[1], 0x00];
    prm.extend_from_slice(&card::USER_PRM_DEFAULTS);
    prm[7] |= 0x80;
    s.srd("Set_Prm (new parameters in Data_Exch)", Some(61), &prm);
    s.srd(&format!("Chk_Cfg {} ({})", host_tests::hex(st1.cfg), st1.name), Some(62), st1.cfg);
    s.srd("Slave_Diag", Some(60), &[]);
    let c1_poll = |s: &mut Script<_>, what: &str| {
        for _ in 0..100 {
            let r = s.c1(&format!("MSAC_C1 poll → {what}"), &[]);
            if host_tests::pdu_of(&r).is_some_and(|p| !p.is_empty()) {
                return r;
            }
            s.sent.last_mut().expect("sent").0 = "MSAC_C1 poll → not ready (SC)".into();
        }
        fail("no MSAC_C1 response after 100 polls")
    };
    for k in 1..=SAMPLES as u8 {
        s.c1(
            "MSAC_C1 DS_Write record 47, read PNU 918 (SC)",
            &[0x5F, 0, 47, 10, k, 1, 1, 1, 0x10, 1, 0x03, 0x96, 0, 0],
        );
        c1_poll(&mut s, "DS_Write.res");
        s.c1("MSAC_C1 DS_Read record 47 (SC)", &[0x5E, 0, 47, 240]);
        let r = c1_poll(&mut s, "DS_Read.res, PNU 918 = 126");
        if host_tests::pdu_of(&r) != Some(&[0x5E, 0, 47, 8, k, 1, 1, 1, 0x42, 1, 0, SLAVE][..]) {
            fail(&format!("MSAC_C1 PNU 918 read: {}", host_tests::hex(&r)));
        }
    }

    // Collect the measurements (the log trails the answers slightly).
    let want = skip + s.sent.len();
    let deadline = std::time::Instant::now() + Duration::from_secs(20);
    let mut lines = bench_lines(&q);
    while lines.len() < want && std::time::Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(50));
        lines = bench_lines(&q);
    }
    if lines.len() < want {
        fail(&format!("{} BENCH lines, expected {want}:\n{}", lines.len(), q.log().join("\n")));
    }
    // Rows in first-seen order, samples merged by label; every log line must match the
    // request/response lengths of the exchange it belongs to.
    let mut rows: Vec<(String, usize, usize, Vec<u32>, String)> = Vec::new();
    for (i, ((label, req, resp), line)) in s.sent.iter().zip(&lines[skip..]).enumerate() {
        let f: Vec<&str> = line.split_whitespace().collect();
        let pos = f.iter().position(|w| *w == "BENCH").unwrap_or_else(|| fail(line));
        let num = |k: usize| f.get(pos + k).and_then(|v| v.parse::<u32>().ok()).unwrap_or_else(|| fail(line));
        let (lreq, lresp, instr) = (num(2), num(4), num(6));
        // `fast`: answered by the fast path at the line; `core`: left to the core (DP-V1).
        let path = f.get(pos + 7).copied().unwrap_or("fast").to_string();
        if lreq as usize != *req || lresp as usize != *resp {
            fail(&format!("measurement {i} ({label}, {req}/{resp} bytes) does not match log line {line:?}"));
        }
        match rows.iter_mut().find(|r| r.0 == *label) {
            Some(r) => r.3.push(instr),
            None => rows.push((label.clone(), *req, *resp, vec![instr], path)),
        }
    }
    let stop = q.stop();
    if std::env::var_os("PBCARD_BENCH_LOG").is_some() {
        for l in &stop {
            eprintln!("{l}");
        }
    }
    if stop.iter().any(|l| l.contains("panic") || l.contains("HardFault")) {
        fail(&stop.join("\n"));
    }
    if dma {
        dma_report(&rows, &stop);
        return;
    }
    // The lower-priority work under the Node lock (USART1 masked): `LOCK <what> <n> ...`, and
    // the unlocked middle of the step: `UNLOCKED <what> <n> ...`.
    let mut locks: Vec<(String, Vec<u32>)> = Vec::new();
    for l in &stop {
        let f: Vec<&str> = l.split_whitespace().collect();
        let Some(pos) = f.iter().position(|w| *w == "LOCK" || *w == "UNLOCKED") else { continue };
        let (Some(what), Some(n)) = (f.get(pos + 1), f.get(pos + 2).and_then(|v| v.parse::<u32>().ok())) else {
            fail(l)
        };
        let what = format!("{} {what}", f[pos]);
        match locks.iter_mut().find(|r| r.0 == what) {
            Some(r) => r.1.push(n),
            None => locks.push((what, vec![n])),
        }
    }
    // The core's work per queued telegram (`CORE step <n> instructions`), in queue order: every
    // request but FDL_Status (which the fast path answers without queueing) is one step.
    let core_steps: Vec<u32> = stop
        .iter()
        .filter_map(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            let pos = f.windows(2).position(|w| w == ["CORE", "step"])?;
            f.get(pos + 2)?.parse().ok()
        })
        .collect();
    let queued: Vec<&String> = s.sent.iter().map(|r| &r.0).filter(|l| *l != "FDL_Status").collect();
    let mut core_rows: Vec<(String, Vec<u32>)> = Vec::new();
    if core_steps.len() >= queued.len() {
        // The first steps belong to the ready probe (skipped), the rest pair with the requests.
        let from = core_steps.len() - queued.len();
        for (label, n) in queued.iter().zip(&core_steps[from..]) {
            match core_rows.iter_mut().find(|r| r.0 == **label) {
                Some(r) => r.1.push(*n),
                None => core_rows.push(((*label).clone(), vec![*n])),
            }
        }
    }
    // Critical sections the lower tasks still take (every interrupt masked, so also the fast
    // path): `CS <what> <n> instructions` lines of the bench build.
    let mut sections: Vec<(String, u32)> = Vec::new();
    for l in &stop {
        let f: Vec<&str> = l.split_whitespace().collect();
        let Some(pos) = f.iter().position(|w| *w == "CS") else { continue };
        let (Some(what), Some(n)) = (f.get(pos + 1), f.get(pos + 2).and_then(|v| v.parse::<u32>().ok())) else {
            continue;
        };
        match sections.iter_mut().find(|r| r.0 == *what) {
            Some(r) => r.1 = r.1.max(n),
            None => sections.push((what.to_string(), n)),
        }
    }
    for what in ["LOCK app.snapshot", "LOCK app.apply", "UNLOCKED app.step", "LOCK process_acyclic"] {
        if !locks.iter().any(|r| r.0 == what) {
            fail(&format!("no {what} line in the firmware log"));
        }
    }
    locks.sort_by_key(|r| r.0.starts_with("UNLOCKED"));

    println!("QEMU netduinoplus2, `-icount shift=0,align=off,sleep=off`, firmware built with `--features bench`");
    println!(
        "(instructions from the USART1 handler entry for the last request byte to the first response byte in DR)\n"
    );
    println!("| request | answered by | frame bytes in → out | instructions | samples | ≥ µs at 96 MHz |");
    println!("|---|---|---:|---:|---:|---:|");
    for (label, req, resp, v, path) in &rows {
        let (instr, hi) = (span(v), *v.iter().max().unwrap());
        let by = if path == "core" { "via core (DP-V1, through the line)" } else { "fast path" };
        println!("| {label} | {by} | {req} → {resp} | {instr} | {} | {:.1} |", v.len(), hi as f64 / 96.0);
    }
    println!("\n(the core's work per queued telegram, after the answer: `CoreLink::step` = `Node::on_frame` + republishing the staging)\n");
    println!("| queued request | core instructions | samples |");
    println!("|---|---:|---:|");
    for (label, v) in &core_rows {
        let instr = span(v);
        println!("| {label} | {instr} | {} |", v.len());
    }
    println!("\n(critical sections a lower task still imposes on the fast path: every interrupt masked)\n");
    println!("| critical section | instructions (max) |");
    println!("|---|---:|");
    for (what, n) in &sections {
        let name = match what.as_str() {
            "clock.now" => {
                "`SysTickClock::now` (`interrupt::free` around the SysTick reads; housekeeping, DP-V1 task, core)"
            }
            "defmt" => {
                "one defmt log line over semihosting (the QEMU logger's critical section; the F411 logs over RTT)"
            }
            other => other,
        };
        println!("| {name} | {n} |");
    }
    println!(
        "\n(lower-priority work with the Node locked: on QEMU this masks the core task only, not the fast path; counted without masking interrupts)\n"
    );
    println!("| under the Node lock | instructions (max) | ≥ µs at 96 MHz | characters at 1.5 Mbit/s |");
    println!("|---|---:|---:|---:|");
    for (what, v) in &locks {
        let max = *v.iter().max().unwrap();
        let task = match what.as_str() {
            "LOCK app.snapshot" => {
                "`Application::snapshot` (housekeeping step: node timers, copy of state and outputs)"
            }
            "LOCK app.apply" => "`Application::apply` (housekeeping step: diagnosis and input image into the slave)",
            "LOCK process_acyclic" => "`Node::process_acyclic` (DP-V1 task), PNU 918 read",
            "UNLOCKED app.step" => {
                "(not locked, for comparison: publish + drive + collect of the step, preemptions included)"
            }
            other => other,
        };
        let us = max as f64 / 96.0;
        println!("| {task} | {max} | {us:.1} | {:.1} |", us / (11.0 / 1.5));
    }
    // The shipped card: every row but the bench build's own modules (their Chk_Cfg and
    // Data_Exchange); the line or the core answering. A Data_Exchange of 244 bytes to PPO 5
    // (RS) is a request the shipped card can get, so it counts.
    let shipped = rows
        .iter()
        .filter(|r| !bench_only(&r.0))
        .map(|r| (*r.3.iter().max().unwrap(), &r.0))
        .max_by_key(|r| r.0)
        .unwrap_or_else(|| fail("no answer"));
    println!("\nworst shipped card: {} instructions ({})", shipped.0, shipped.1);
    let worst = rows
        .iter()
        .filter(|r| r.4 != "core")
        .map(|r| (*r.3.iter().max().unwrap(), &r.0))
        .max_by_key(|r| r.0)
        .unwrap_or_else(|| fail("no fast-path answer"));
    // The budget card::max_tsdr is derived from (card::LINE_BUDGET_INSTRUCTIONS): the worst
    // request the shipped card can get, whichever path answers it.
    if shipped.0 > card::LINE_BUDGET_INSTRUCTIONS {
        fail(&format!(
            "worst shipped card {} instructions ({}) exceeds card::LINE_BUDGET_INSTRUCTIONS = {}",
            shipped.0,
            shipped.1,
            card::LINE_BUDGET_INSTRUCTIONS
        ));
    }
    println!("worst fast path: {} instructions ({})", worst.0, worst.1);
    if worst.0 > card::LINE_BUDGET_INSTRUCTIONS {
        fail(&format!(
            "worst fast path {} instructions ({}) exceeds card::LINE_BUDGET_INSTRUCTIONS = {}",
            worst.0,
            worst.1,
            card::LINE_BUDGET_INSTRUCTIONS
        ));
    }
    streaming(&stop);
}

/// The streaming receive's per-character costs (`STREAM <us|other> len <n> head <h> char <c>
/// sink <s> end <e>` lines of the bench build, one per telegram of 32 bytes or more: the
/// largest counts of its characters 1–16 (the header, with the prepared answer), of its later
/// characters (the character's event: status and data register, clock, cut, sink) and of the
/// cut and sink alone; the last character's handler), the F411 cycle model from them and the
/// CPU share of a saturated 12 Mbit/s bus of other stations' traffic.
fn streaming(log: &[String]) {
    /// (who, len, head, char, sink, end) of one `STREAM` line.
    type StreamRow = (String, u32, u32, u32, u32, u32);
    let rows: Vec<StreamRow> = log
        .iter()
        .filter_map(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            let p = f.iter().position(|w| *w == "STREAM")?;
            let n = |k: usize| f.get(p + k).and_then(|v| v.parse::<u32>().ok());
            Some((f.get(p + 1)?.to_string(), n(3)?, n(5)?, n(7)?, n(9)?, n(11)?))
        })
        .collect();
    let max = |who: &str, min_len: u32, pick: fn(&StreamRow) -> u32| {
        rows.iter().filter(|r| r.0 == who && r.1 >= min_len).map(pick).max()
    };
    let (Some(char_us), Some(sink_us), Some(head_us)) =
        (max("us", 200, |r| r.3), max("us", 200, |r| r.4), max("us", 200, |r| r.2))
    else {
        fail("no STREAM line of a long Data_Exchange to the card in the firmware log")
    };
    let (Some(char_other), Some(sink_other), Some(end_other)) =
        (max("other", 200, |r| r.3), max("other", 200, |r| r.4), max("other", 32, |r| r.5))
    else {
        fail("no STREAM line of another station's telegram in the firmware log")
    };
    println!("\n(the streaming receive per character: instructions, largest of every telegram ≥ 200 bytes)\n");
    println!("| character | event (SR, DR, clock, cut, sink) | cut + sink alone |");
    println!("|---|---:|---:|");
    println!("| Data_Exchange 244/244 to the card, characters 17 … 251 | {char_us} | {sink_us} |");
    println!("| Data_Exchange 244/244 to the card, characters 1 … 16 (header: the answer prepared) | {head_us} | |");
    println!("| Data_Exchange 244 to another station, characters 17 … 251 | {char_other} | {sink_other} |");
    println!("| another station's telegram, last character (`finish`: counted, dropped) | {end_other} | |");
    println!("per-character streaming cost: {sink_us} instructions (Data_Exchange 244 out / 244 in, cut + sink)");
    if sink_us > card::STREAM_CHAR_INSTRUCTIONS {
        fail(&format!(
            "per-character streaming cost {sink_us} exceeds card::STREAM_CHAR_INSTRUCTIONS = {}",
            card::STREAM_CHAR_INSTRUCTIONS
        ));
    }
    println!("\n(F411 cycle model, `card::modelled_tsdr` of card::LINE_BUDGET_INSTRUCTIONS = {} per character and card::DMA_FINISH_INSTRUCTIONS = {} + card::F411_IDLE_ENTRY_INSTRUCTIONS = {} in DMA mode (`qemu_bench --dma`); bit times)\n", card::LINE_BUDGET_INSTRUCTIONS, card::DMA_FINISH_INSTRUCTIONS, card::F411_IDLE_ENTRY_INSTRUCTIONS);
    println!("| rate | receive | modelled | customary | GSD MaxTsdr |");
    println!("|---|---|---:|---:|---:|");
    for rate in pbcard::time::Baudrate::ALL.iter().rev() {
        let how = if card::per_character(*rate) { "per character, end by length" } else { "DMA ring, IDLE" };
        println!(
            "| {} bit/s | {how} | {} | {} | {} |",
            rate.bits_per_second(),
            card::modelled_tsdr(*rate, card::budget_instructions(*rate)),
            card::customary_max_tsdr(*rate),
            card::max_tsdr(*rate)
        );
    }
    // The CPU share of other stations' traffic in the DMA mode: `qemu_bench --dma`, from the
    // measured chunk costs.
}

/// The `--dma` run (`bench-dma` build, the F411's DMA receive emulated by
/// `bsp::qemu::DmaEmu`): per request the instructions from the IDLE interrupt's entry to the
/// first response byte — the remainder of 1 … 16 characters through `Stream::piece`,
/// `FastPath::finish`, the answer staged —, the cost of a 16-byte chunk (`CHUNK <us|other> len
/// <n> chunk <c> end <e>` lines, one per telegram with a chunk: longer than 16 bytes; the worst
/// chunk interrupt against the ring's lap at 12 Mbit/s), the DMA rates' cycle
/// model and the CPU share of other stations' traffic from these measurements.
fn dma_report(rows: &[(String, usize, usize, Vec<u32>, String)], log: &[String]) {
    println!("QEMU netduinoplus2, `-icount shift=0,align=off,sleep=off`, firmware built with `--features bench-dma`");
    println!("(the F411's DMA receive emulated: characters to the fast path in 16-byte chunks, the rest at the telegram's end;");
    println!(
        " instructions from the IDLE interrupt's entry — the last character — to the first response byte in DR)\n"
    );
    println!("| request | frame bytes in → out | instructions | samples |");
    println!("|---|---:|---:|---:|");
    for (label, req, resp, v, _) in rows {
        let instr = span(v);
        println!("| {label} | {req} → {resp} | {instr} | {} |", v.len());
    }
    let worst = rows
        .iter()
        .filter(|r| !bench_only(&r.0) && r.4 != "core")
        .map(|r| (*r.3.iter().max().unwrap(), &r.0))
        .max_by_key(|r| r.0)
        .unwrap_or_else(|| fail("no fast-path answer"));
    println!("\nworst DMA-mode finish: {} instructions ({})", worst.0, worst.1);
    if worst.0 > card::DMA_FINISH_INSTRUCTIONS {
        fail(&format!(
            "worst DMA-mode finish {} instructions ({}) exceeds card::DMA_FINISH_INSTRUCTIONS = {}",
            worst.0,
            worst.1,
            card::DMA_FINISH_INSTRUCTIONS
        ));
    }
    /// (who, len, first, chunk, end, low) of one `CHUNK` line.
    type ChunkRow = (String, u32, u32, u32, u32, u32);
    let chunks: Vec<ChunkRow> = log
        .iter()
        .filter_map(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            let p = f.iter().position(|w| *w == "CHUNK")?;
            let n = |k: usize| f.get(p + k).and_then(|v| v.parse::<u32>().ok());
            Some((f.get(p + 1)?.to_string(), n(3)?, n(5)?, n(7)?, n(11)?, n(9)?))
        })
        .collect();
    let max =
        |who: &str, pick: fn(&ChunkRow) -> u32| chunks.iter().filter(|r| r.0 == who && r.1 >= 200).map(pick).max();
    let low = |who: &str| chunks.iter().filter(|r| r.0 == who && r.1 >= 200).map(|r| r.5).min();
    let low_us = low("us").unwrap_or(0);
    // The mean first chunk of other stations' telegrams (every length): the typical header's
    // cost, the odd SysTick preemption and header split across a chunk boundary included.
    let firsts: Vec<u32> = chunks.iter().filter(|r| r.0 == "other").map(|r| r.2).collect();
    let mean_first_other = (firsts.iter().sum::<u32>()).div_ceil(firsts.len().max(1) as u32);
    let (Some(first_us), Some(chunk_us), Some(first_other), Some(chunk_other), Some(end_other), Some(low_other)) = (
        max("us", |r| r.2),
        max("us", |r| r.3),
        max("other", |r| r.2),
        max("other", |r| r.3),
        max("other", |r| r.4),
        low("other"),
    ) else {
        fail("no CHUNK lines of a long Data_Exchange to the card and to another station in the firmware log")
    };
    println!("\n(the chunk interrupts: `Stream::piece` of 16 characters into the fast path's sink; largest of every telegram ≥ 200 bytes)\n");
    println!("| piece | instructions |");
    println!("|---|---:|");
    println!("| the first chunk of a Data_Exchange 244/244 to the card (header: `begin`, the answer prepared) | {first_us} |");
    println!("| a later 16-byte chunk of a Data_Exchange 244/244 to the card: lowest – highest (the header and the prepared answer when a chunk boundary fell inside the header; a SysTick preemption) | {low_us} – {chunk_us} |");
    println!(
        "| the first chunk of a Data_Exchange 244 to another station (header: its DA, then skipped) | {first_other} |"
    );
    println!("| the first chunk of another station's telegram, mean of {} (41 and 253 bytes; the sink hears nothing of it when its header is in the chunk) | {mean_first_other} |", firsts.len());
    println!("| a later 16-byte chunk of a Data_Exchange 244 to another station (skipped by length): lowest – highest (a SysTick preemption) | {low_other} – {chunk_other} |");
    println!("| another station's telegram at IDLE (the remainder, `finish`: counted, dropped) | {end_other} |");
    // Every chunk interrupt of every telegram with one (longer than a chunk; its first chunk
    // carries the header, the sink's `begin` and a prepared answer) against the ring's lap:
    // a handler slower than that lets the DMA overwrite bytes not yet read (an overrun).
    let Some((worst_chunk, who, len)) = chunks.iter().map(|r| (r.2.max(r.3), &r.0, r.1)).max_by_key(|r| r.0) else {
        fail("no CHUNK lines in the firmware log")
    };
    let (cycles, lap) = (card::chunk_cycles(worst_chunk), card::ring_lap_cycles(pbcard::time::Baudrate::B12M));
    println!(
        "\nworst chunk interrupt: {worst_chunk} instructions (a {len}-byte telegram to {}): {cycles} cycles on the F411 \
         (card::chunk_cycles: entry + (N + card::F411_CHUNK_ENTRY_INSTRUCTIONS) × CPI 3/2), the {}-byte ring's lap at \
         12 Mbit/s {lap} cycles (card::ring_lap_cycles)",
        if who == "us" { "the card" } else { "another station" },
        card::DMA_RING
    );
    if cycles >= lap {
        fail(&format!(
            "a chunk interrupt of {cycles} cycles would let the DMA lap the ring ({lap} cycles at 12 Mbit/s)"
        ));
    }
    println!("\n(F411 cycle model of the DMA rates: {} bit times to IDLE, then the interrupt entry and (card::DMA_FINISH_INSTRUCTIONS = {} + the handler's own register work card::F411_IDLE_ENTRY_INSTRUCTIONS = {}, estimated) × CPI 3/2 + DMA start, + 20 %)\n", card::IDLE_DETECT_BITS, card::DMA_FINISH_INSTRUCTIONS, card::F411_IDLE_ENTRY_INSTRUCTIONS);
    println!("| rate | modelled | customary | GSD MaxTsdr |");
    println!("|---|---:|---:|---:|");
    for rate in pbcard::time::Baudrate::ALL.iter().rev().filter(|r| !card::per_character(**r)) {
        println!(
            "| {} bit/s | {} | {} | {} |",
            rate.bits_per_second(),
            card::modelled_tsdr(*rate, card::DMA_FINISH_INSTRUCTIONS),
            card::customary_max_tsdr(*rate),
            card::max_tsdr(*rate)
        );
    }
    // Per telegram: its chunks at the later chunks' cost, and once the first chunk's surplus
    // (the header) and the IDLE interrupt.
    let chunk = low_other + card::F411_CHUNK_ENTRY_INSTRUCTIONS;
    let surplus = mean_first_other.saturating_sub(low_other);
    let idle = end_other + surplus + card::F411_IDLE_ENTRY_INSTRUCTIONS;
    println!("\n(CPU share of a saturated 12 Mbit/s bus of other stations' telegrams, `card::foreign_load_per_mille` of the measured costs: a chunk interrupt {low_other} (the lowest: the load is the typical chunk's) + card::F411_CHUNK_ENTRY_INSTRUCTIONS = {} (its register work, estimated); per telegram once the header's surplus {surplus} (the mean first chunk's) and the IDLE interrupt {end_other} + card::F411_IDLE_ENTRY_INSTRUCTIONS = {} (estimated); 33 idle bits before every telegram, CPI 1.5, entry 12 cycles)\n", card::F411_CHUNK_ENTRY_INSTRUCTIONS, card::F411_IDLE_ENTRY_INSTRUCTIONS);
    println!("| telegram mix (all for other stations) | CPU share |");
    println!("|---|---:|");
    for (what, len) in [
        ("tokens and SD1 status telegrams (6 bytes)", 6u32),
        ("Data_Exchange 32/32 cycles (41-byte telegrams)", 41),
        ("Data_Exchange 244/244 cycles (253-byte telegrams)", 253),
    ] {
        let share = card::foreign_load_per_mille(pbcard::time::Baudrate::B12M, len, chunk, idle);
        println!("| {what} | {:.1} % |", f64::from(share) / 10.0);
    }
}
