//! The live demo (README command 1): the card firmware — the same RTIC application as on the
//! board, with the QEMU board module — boots in `qemu-system-arm -M netduinoplus2`;
//! profirust's DP master (a master nobody here wrote) on the host brings it to data exchange
//! through USART1 and runs the drive for a few seconds like a PLC program: control word and
//! speed setpoint out, status word and actual speed in, printed as they change, decoded. The
//! firmware's own log (defmt over semihosting, decoded by defmt-print) is interleaved, marked
//! `firmware |`.
//!
//! The drive is the firmware's simulated drive behind the DPM (`pbcard_sim::bench::Application`,
//! PROFIdrive state machine, 2 s ramp per 100 %). Every input image is checked
//! ([`DriveSession`]: state bits, PKW, PZD echo), each ramp must be monotonic and reach its
//! setpoint; the exit code says whether all was well.
//!
//! Run: `bash scripts/demo.sh` (builds the ELF with `scripts/qemu.sh build`, then
//! `cargo run -p host-tests --bin qemu_demo --target <host triple>`).

use std::time::Duration;

use host_tests::hex;
use host_tests::qemu::{
    self, monotonic, percent, stw1_meaning, zsw1_meaning, Build, DriveSession, LiveMaster, MasterSetup, Qemu,
    QemuOptions, Sample, SLAVE, ZSW1_S2, ZSW1_S4, ZSW1_STATE_MASK,
};
use pbcard::card;
use profirust::dp::PeripheralEvent;

/// Deadline of each step of the program (about a second each on an idle machine).
const DEADLINE: Duration = Duration::from_secs(60);
/// How long each reached state is kept before the next step.
const DWELL: Duration = Duration::from_millis(600);

/// What the PLC program waits for in one step.
#[derive(Debug, Clone, Copy)]
enum Until {
    /// S2 "ready to switch on", standstill.
    Ready,
    /// S4 "operation enabled" at the setpoint (ZSW1 b8), NIST_A = NSOLL_A.
    AtSetpoint,
}

/// The "PLC program": (STW1, NSOLL_A, what for, until).
const PROGRAM: &[(u16, i16, &str, Until)] = &[
    (0x047E, 0x2000, "switch on ready (from S1 a 0 in b0 is needed first)", Until::Ready),
    (0x047F, 0x2000, "run, setpoint 50 %", Until::AtSetpoint),
    (0x047F, 0x4000, "setpoint 100 %", Until::AtSetpoint),
    (0x047E, 0x4000, "OFF1: ramp stop to standstill", Until::Ready),
];

fn main() {
    let module = &card::MODULES[0];
    let elf = qemu::firmware_elf(Build::Qemu);
    println!("pbcard QEMU demo");
    println!(
        "  firmware: {} (RTIC app, board module crates/bsp/src/qemu.rs, simulated drive behind the DPM)",
        elf.display()
    );
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

fn line(x: &Sample) -> String {
    format!(
        "  {:>6.3} s  cycle {:>4} | out STW1 {:04X} NSOLL_A {:04X} ({:+6.1} %) | in ZSW1 {:04X} NIST_A {:04X} ({:+6.1} %)  {}",
        x.t.as_secs_f64(),
        x.cycle,
        x.stw1,
        x.nsoll as u16,
        percent(x.nsoll),
        x.zsw1,
        x.nist as u16,
        percent(x.nist),
        zsw1_meaning(x.zsw1, x.nist)
    )
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
    m.pause = Duration::from_millis(2); // a human-speed exchange

    println!("\n-- bring-up: Slave_Diag, Set_Prm (ident 0x{:04X}, WD 10 s), Chk_Cfg, Slave_Diag", card::IDENT_NUMBER);
    let up = m.run_until(DEADLINE, |m, e| {
        if let Some(e) = e {
            println!("  master   | {:>5} ms  #{SLAVE} {e:?}", m.ms());
        }
        e == Some(PeripheralEvent::DataExchanged)
    });
    if !up {
        eprintln!("the slave did not reach data exchange; master events {:?}", m.events);
        return 1;
    }

    println!("\n-- data exchange (out = STW1 NSOLL_A, in = ZSW1 NIST_A; 4000h = 100 % speed, ramp 2 s per 100 %)");
    let mut s = DriveSession::new(m, module);
    let mut speed = 0i16;
    for &(stw1, nsoll, what, until) in PROGRAM {
        println!(
            "  ---- PLC: STW1 {stw1:04X} ({}), NSOLL_A {nsoll:04X} ({:+.1} %): {what}",
            stw1_meaning(stw1),
            percent(nsoll)
        );
        let mut last: Option<Sample> = None;
        let mut print = |x: &Sample| {
            let due = last.is_none_or(|l| l.zsw1 != x.zsw1 || x.t >= l.t + Duration::from_millis(150));
            if due {
                println!("{}", line(x));
                last = Some(*x);
            }
        };
        let reached = |x: &Sample| match until {
            Until::Ready => x.zsw1 & ZSW1_STATE_MASK == ZSW1_S2 && x.nist == 0,
            Until::AtSetpoint => x.zsw1 & ZSW1_STATE_MASK == ZSW1_S4 && x.zsw1 & 0x0100 != 0 && x.nist == nsoll,
        };
        let result = (|| {
            let ramp = s.run(stw1, nsoll, DEADLINE, |x| {
                print(x);
                reached(x)
            })?;
            let target = if matches!(until, Until::Ready) { 0 } else { nsoll };
            let between = monotonic(&ramp, speed, target)?;
            if speed != target && between < 3 {
                return Err(format!("NIST_A jumped from {speed:+} to {target:+}"));
            }
            speed = target;
            let t_end = ramp.last().map_or(Duration::ZERO, |x| x.t) + DWELL;
            let kept = s.run(stw1, nsoll, DEADLINE, |x| {
                print(x);
                x.t >= t_end
            })?;
            match kept.iter().find(|x| !reached(x)) {
                Some(x) => Err(format!("the state did not hold: {}", line(x))),
                None => Ok(()),
            }
        })();
        if let Err(e) = result {
            eprintln!("demo FAILED: {e}");
            return 1;
        }
    }
    let stats = s.master.phy.stats();
    let secs = s.elapsed().as_secs_f64();
    println!(
        "\n{} cycles checked ({:.0}/s); line: {} telegrams out, {} bytes out, {} bytes in",
        s.cycles,
        s.cycles as f64 / secs.max(0.001),
        stats.tx_telegrams,
        stats.tx_bytes,
        stats.rx_bytes
    );
    println!(
        "demo passed: ready, 50 %, 100 % and back to standstill, every ramp monotonic, every input image checked; \
         QEMU stopped"
    );
    0
}
