//! The live demo (README command 1): the card firmware — the same RTIC application as on the
//! board, with the QEMU board module — boots in `qemu-system-arm -M netduinoplus2`;
//! profirust's DP master (a master nobody here wrote) on the host brings it to data exchange
//! through USART1 and runs the "drive" for a few seconds: control word and speed setpoint
//! out, status word and actual speed in, printed as they change. The firmware's own log
//! (defmt over semihosting, decoded by defmt-print) is interleaved, marked `firmware |`.
//!
//! The inputs come from the firmware's placeholder drive (`Loopback` in `src/main.rs`: NIST
//! ramps towards NSOLL per Data_Exchange); every cycle is checked against a host model of it.
//!
//! Run: `bash scripts/demo.sh` (builds the ELF with `scripts/qemu.sh build`, then
//! `cargo run -p host-tests --bin qemu_demo --target <host triple>`).

use std::time::{Duration, Instant};

use host_tests::qemu::{self, Build, LiveMaster, MasterSetup, Qemu, QemuOptions, SLAVE};
use host_tests::{hex, CycleRecord};
use pbcard::card;
use profirust::dp::PeripheralEvent;

/// How long the drive runs.
const RUN: Duration = Duration::from_secs(6);

/// The "PLC program": (from second, STW1, NSOLL_A, what).
const SCRIPT: &[(f64, u16, i16, &str)] = &[
    (0.0, 0x047E, 0, "ready (ON not set): drive stopped"),
    (1.0, 0x047F, 0x4000, "run, setpoint +16384 (100 %)"),
    (2.5, 0x047F, -0x2000, "reverse, setpoint -8192 (-50 %)"),
    (4.0, 0x047F, 0x1000, "setpoint +4096 (25 %)"),
    (5.0, 0x047E, 0x1000, "ON removed: ramp down to standstill"),
];

fn step_at(t: f64) -> &'static (f64, u16, i16, &'static str) {
    SCRIPT.iter().rev().find(|s| t >= s.0).unwrap_or(&SCRIPT[0])
}

fn main() {
    let module = &card::MODULES[0];
    let elf = qemu::firmware_elf(Build::Qemu);
    println!("pbcard QEMU demo");
    println!("  firmware: {} (RTIC app, board module bsp/qemu.rs)", elf.display());
    println!("  machine:  qemu-system-arm -M netduinoplus2 (STM32F405), USART1 on a Unix socket");
    println!(
        "  master:   profirust DP master #{} on the host; slave #{SLAVE}, module \"{}\" (Chk_Cfg {})\n",
        qemu::MASTER,
        module.name,
        hex(module.cfg)
    );
    let q = match Qemu::boot(&elf, &QemuOptions { icount: false, echo_log: Some("  firmware | ".into()) }) {
        Ok(q) => q,
        Err(e) => {
            eprintln!("cannot start QEMU: {e}");
            std::process::exit(1);
        }
    };
    let code = run(&q, module);
    let log = q.stop();
    if code != 0 {
        eprintln!("--- firmware log ---\n{}", log.join("\n"));
    }
    std::process::exit(code);
}

fn run(q: &Qemu, module: &card::Module) -> i32 {
    let mut phy = match q.connect() {
        Ok(p) => p,
        Err(e) => {
            eprintln!("cannot connect to USART1: {e}");
            return 1;
        }
    };
    // The firmware logs its boot lines first; give them a moment so the output reads in order.
    q.wait_log("DP state", Duration::from_secs(5));
    match qemu::wait_for_answer(&mut phy, SLAVE, Duration::from_secs(20)) {
        Ok(t) => println!("  master   | slave #{SLAVE} answers FDL_Status ({} ms after boot)", t.as_millis()),
        Err(e) => {
            eprintln!("{e}");
            return 1;
        }
    }
    let mut m = LiveMaster::new(phy, SLAVE, module, &MasterSetup::default());
    m.pause = Duration::from_millis(2); // a human-speed exchange (≈ 50 cycles/s)

    println!("\n-- bring-up: Slave_Diag, Set_Prm (ident 0x{:04X}, WD 10 s), Chk_Cfg, Slave_Diag", card::IDENT_NUMBER);
    let up = m.run_until(Duration::from_secs(30), |m, e| {
        if let Some(e) = e {
            println!("  master   | {:>5} ms  #{SLAVE} {e:?}", m.ms());
        }
        e == Some(PeripheralEvent::DataExchanged)
    });
    if !up {
        eprintln!("the slave did not reach data exchange; master events {:?}", m.events);
        return 1;
    }

    println!(
        "\n-- data exchange for {} s (PI_Q = STW1 NSOLL_A out, PI_I = ZSW1 NIST_A in, one cycle later)",
        RUN.as_secs()
    );
    let t0 = Instant::now();
    let mut cycles: Vec<CycleRecord> = Vec::new();
    let mut current = vec![0u8; module.outputs.into()];
    let mut last_print = 0.0f64;
    let mut last_zsw = None;
    let mut last_step = None;
    let mut offline = false;
    m.run_until(RUN + Duration::from_secs(5), |m, e| {
        let t = t0.elapsed().as_secs_f64();
        match e {
            Some(PeripheralEvent::DataExchanged) => {
                let p = m.peripheral();
                let pi_i = p.pi_i().to_vec();
                cycles.push(CycleRecord { t_us: (t * 1e6) as u64, q_sent: current.clone(), i_received: pi_i.clone() });
                let (zsw1, nist) = (u16::from_be_bytes([pi_i[0], pi_i[1]]), i16::from_be_bytes([pi_i[2], pi_i[3]]));
                let (stw1, nsoll) =
                    (u16::from_be_bytes([current[0], current[1]]), i16::from_be_bytes([current[2], current[3]]));
                if t - last_print >= 0.1 || last_zsw != Some(zsw1) {
                    println!(
                        "  {:>6.3} s  cycle {:>4} | out STW1 {stw1:04X}  NSOLL_A {nsoll:>+6} | in ZSW1 {zsw1:04X}  NIST_A {nist:>+6}{}",
                        t,
                        cycles.len(),
                        if zsw1 & 0x0400 != 0 { "  (at setpoint)" } else { "" }
                    );
                    last_print = t;
                    last_zsw = Some(zsw1);
                }
                let s = step_at(t);
                if last_step != Some(s.0.to_bits()) {
                    println!("  ---- PLC: STW1 {:04X}, NSOLL_A {:+}: {}", s.1, s.2, s.3);
                    last_step = Some(s.0.to_bits());
                }
                current[..2].copy_from_slice(&s.1.to_be_bytes());
                current[2..4].copy_from_slice(&s.2.to_be_bytes());
                p.pi_q_mut().copy_from_slice(&current);
            }
            Some(PeripheralEvent::Offline) => offline = true,
            Some(other) => println!("  master   | {:>5} ms  #{SLAVE} {other:?}", m.ms()),
            None => {}
        }
        offline || t0.elapsed() >= RUN
    });
    let secs = t0.elapsed().as_secs_f64();
    // Cycle 0 answers the bring-up's first Data_Exchange, which carried an all-zero PI_Q.
    let check = qemu::check_against_model(module, &cycles);
    let stats = m.phy.stats();
    println!(
        "\n{} cycles in {:.1} s ({:.0}/s); line: {} telegrams out, {} bytes out, {} bytes in",
        cycles.len(),
        secs,
        cycles.len() as f64 / secs,
        stats.tx_telegrams,
        stats.tx_bytes,
        stats.rx_bytes
    );
    match (offline, check) {
        (true, _) => {
            eprintln!("the master lost the slave: {:?}", m.events);
            1
        }
        (false, Err(e)) => {
            eprintln!("{e}");
            1
        }
        (false, Ok(())) => {
            println!("demo passed: every input image is what the firmware's application must produce; QEMU stopped");
            0
        }
    }
}
