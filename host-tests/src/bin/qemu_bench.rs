//! The response-path benchmark: the firmware's `bench` build runs in QEMU with
//! `-icount shift=0,align=off,sleep=off`, where TIM2 (prescaler 0) advances by exactly one per
//! executed instruction. For every request it answers, the USART1 handler logs the TIM2
//! difference between its entry for the byte that completed the request and the write of the
//! first response byte into DR (`BENCH req <n> resp <m> instr <i>`). This program sends the
//! requests one at a time over the socket, collects those lines from the decoded defmt log
//! and prints a Markdown table (the README's "Benchmark" section).
//!
//! Measured path: RTIC handler entry → SR/DR read → `Node::on_byte` (framer, telegram decode
//! and checksum, FDL station, DP service, response staging) → `BusPort::start_tx` (copy into
//! the TX buffer) → first DR write. Not included: interrupt entry latency before the handler,
//! min_TSDR (the QEMU port does not wait: no line timing), the application's input update
//! (runs after the first byte is out). Instructions, not cycles: on the F411 (96 MHz, flash
//! wait states with the ART accelerator) a cycle count is at least this.
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

struct Script<S: std::io::Read + std::io::Write> {
    phy: StreamPhy<S>,
    fcb: bool,
    /// (label, request bytes, response bytes) per answered request, in order.
    sent: Vec<(String, usize, usize)>,
}

impl<S: std::io::Read + std::io::Write> Script<S> {
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

fn fail(what: &str) -> ! {
    if let Some(log) = LOG.get() {
        eprintln!("--- firmware log ---\n{}", log.lock().unwrap().join("\n"));
    }
    eprintln!("benchmark failed: {what}");
    std::process::exit(1);
}

fn main() {
    let elf = qemu::firmware_elf(Build::Bench);
    let q = Qemu::boot(&elf, &QemuOptions { icount: true, echo_log: None }).unwrap_or_else(|e| fail(&e.to_string()));
    let _ = LOG.set(q.log_handle());
    let mut phy = q.connect().unwrap_or_else(|e| fail(&e.to_string()));
    if let Err(e) = qemu::wait_for_answer(&mut phy, SLAVE, Duration::from_secs(30)) {
        fail(&e);
    }
    std::thread::sleep(Duration::from_millis(200));
    let bench_lines = |q: &Qemu| q.log().into_iter().filter(|l| l.contains("BENCH ")).collect::<Vec<_>>();
    let skip = bench_lines(&q).len(); // the ready probe's answers
    let mut s = Script { phy, fcb: false, sent: Vec::new() };

    for _ in 0..SAMPLES {
        s.raw("FDL_Status", &qemu::fdl_status_request(SLAVE, MASTER));
    }
    let by_ref = |r: u16| card::MODULES.iter().find(|m| m.reference == r).expect("module");
    // Standard telegram 1, PPO 1, PPO 2, PPO 5: 4, 12, 20, 28 bytes each way.
    for (i, module) in [by_ref(1), by_ref(101), by_ref(102), by_ref(105)].into_iter().enumerate() {
        let id = card::IDENT_NUMBER.to_be_bytes();
        // Lock_Req, WD off, min_TSDR 11, ident, no groups; default user parameters.
        let mut prm = vec![0x80, 0x01, 0x01, 11, id[0], id[1], 0x00];
        prm.extend_from_slice(&card::USER_PRM_DEFAULTS);
        let label = if i == 0 { "Set_Prm (Wait_Prm)" } else { "Set_Prm (new parameters in Data_Exch)" };
        s.srd(label, Some(61), &prm);
        s.srd(&format!("Chk_Cfg {} ({})", host_tests::hex(module.cfg), module.name), Some(62), module.cfg);
        s.srd("Slave_Diag", Some(60), &[]);
        let n: usize = module.outputs.into();
        for k in 0..SAMPLES {
            let out: Vec<u8> = (0..n).map(|i| (i * 7 + k * 13) as u8).collect();
            let resp = s.srd(&format!("Data_Exchange {n} out / {} in", module.inputs), None, &out);
            let pdu = host_tests::pdu_of(&resp).unwrap_or_else(|| fail("Data_Exchange answer without data"));
            if pdu.len() != module.inputs as usize {
                fail(&format!("Data_Exchange answered {} bytes, module has {}", pdu.len(), module.inputs));
            }
        }
    }
    // No module has 32 or 244 bytes: a Data_Exchange of that length is answered RS (the
    // request path up to the decision, with the checksum over the long frame).
    for n in [32usize, 244] {
        for k in 0..SAMPLES {
            let out: Vec<u8> = (0..n).map(|i| (i * 3 + k) as u8).collect();
            s.srd(&format!("Data_Exchange {n} out (no such module: RS)"), None, &out);
        }
    }
    for _ in 0..SAMPLES - 1 {
        s.srd("Slave_Diag", Some(60), &[]);
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
    let mut rows: Vec<(String, usize, usize, Vec<u32>)> = Vec::new();
    for (i, ((label, req, resp), line)) in s.sent.iter().zip(&lines[skip..]).enumerate() {
        let f: Vec<&str> = line.split_whitespace().collect();
        let pos = f.iter().position(|w| *w == "BENCH").unwrap_or_else(|| fail(line));
        let num = |k: usize| f.get(pos + k).and_then(|v| v.parse::<u32>().ok()).unwrap_or_else(|| fail(line));
        let (lreq, lresp, instr) = (num(2), num(4), num(6));
        if lreq as usize != *req || lresp as usize != *resp {
            fail(&format!("measurement {i} ({label}, {req}/{resp} bytes) does not match log line {line:?}"));
        }
        match rows.iter_mut().find(|r| r.0 == *label) {
            Some(r) => r.3.push(instr),
            None => rows.push((label.clone(), *req, *resp, vec![instr])),
        }
    }
    let stop = q.stop();
    if stop.iter().any(|l| l.contains("panic") || l.contains("HardFault")) {
        fail(&stop.join("\n"));
    }

    println!("QEMU netduinoplus2, `-icount shift=0,align=off,sleep=off`, firmware built with `--features bench`");
    println!(
        "(instructions from the USART1 handler entry for the last request byte to the first response byte in DR)\n"
    );
    println!("| request | frame bytes in → out | instructions | samples | ≥ µs at 96 MHz |");
    println!("|---|---:|---:|---:|---:|");
    for (label, req, resp, v) in &rows {
        let (lo, hi) = (v.iter().min().unwrap(), v.iter().max().unwrap());
        let instr = if lo == hi { format!("{lo}") } else { format!("{lo} – {hi}") };
        println!("| {label} | {req} → {resp} | {instr} | {} | {:.1} |", v.len(), *hi as f64 / 96.0);
    }
}
