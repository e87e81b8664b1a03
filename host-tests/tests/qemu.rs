//! End to end: the real firmware (the RTIC application with the QEMU board module, built by
//! `scripts/qemu.sh build`) boots in `qemu-system-arm -M netduinoplus2`; profirust's DP master
//! on the host talks to its USART1 through a Unix socket ([`host_tests::serial::StreamPhy`]),
//! brings it to data exchange and checks hundreds of cycles of changing outputs against the
//! inputs the firmware's application (the placeholder drive `Loopback` in `src/main.rs`) must
//! produce from them, cycle by cycle.
//!
//! Nothing depends on the machine's speed: wall-clock master with a 160 ms slot time and 15
//! retries, DP watchdog 10 s, a ready probe before the master starts (see
//! `host_tests::qemu`).
//!
//! Without the ELF (or without QEMU) the tests are skipped with a note, unless
//! `PBCARD_QEMU_REQUIRED=1` (set by `scripts/test.sh`, so CI cannot skip them).
//!
//! Run: `bash scripts/qemu.sh test`

use std::time::Duration;

use host_tests::qemu::{self, Build, LiveMaster, MasterSetup, Qemu, QemuOptions, SLAVE};
use pbcard::card;
use profirust::dp::PeripheralEvent;

fn boot() -> Option<Qemu> {
    let elf = qemu::firmware_elf(Build::Qemu);
    let required = std::env::var("PBCARD_QEMU_REQUIRED").is_ok_and(|v| v == "1");
    match Qemu::boot(&elf, &QemuOptions::default()) {
        Ok(q) => Some(q),
        Err(e) if !required => {
            eprintln!("SKIPPED (set PBCARD_QEMU_REQUIRED=1 to fail instead): {e}");
            None
        }
        Err(e) => panic!("cannot boot the firmware in QEMU: {e}"),
    }
}

fn fail(q: Qemu, master_events: &[(u64, PeripheralEvent)], what: String) -> ! {
    let log = q.stop();
    panic!("{what}\nmaster events (ms, event): {master_events:?}\n--- firmware log ---\n{}", log.join("\n"));
}

/// Bring-up and `cycles` checked cycles with `module`.
fn data_exchange(module: &card::Module, cycles: usize) {
    let Some(mut q) = boot() else { return };
    let mut phy = match q.connect() {
        Ok(p) => p,
        Err(e) => fail(q, &[], format!("connect to USART1: {e}")),
    };
    let ready = match qemu::wait_for_answer(&mut phy, SLAVE, Duration::from_secs(20)) {
        Ok(t) => t,
        Err(e) => fail(q, &[], e),
    };
    let mut m = LiveMaster::new(phy, SLAVE, module, &MasterSetup::default());
    if let Err(e) = m.bring_up(Duration::from_secs(60)) {
        let ev = m.events.clone();
        fail(q, &ev, e);
    }
    let t_up = m.ms();
    let n = cycles;
    let log = match m.exchange(n, Duration::from_secs(120), |k| qemu::drive_outputs(module, k, n)) {
        Ok(l) => l,
        Err(e) => {
            let ev = m.events.clone();
            fail(q, &ev, e);
        }
    };
    let t_end = m.ms();
    if let Err(e) = qemu::check_against_model(module, &log) {
        let ev = m.events.clone();
        fail(q, &ev, e);
    }
    if let Err(e) = q.check_running() {
        let ev = m.events.clone();
        fail(q, &ev, e);
    }
    let first = m.events.iter().map(|e| e.1).take(3).collect::<Vec<_>>();
    if first != [PeripheralEvent::Online, PeripheralEvent::Configured, PeripheralEvent::DataExchanged]
        || m.events.iter().any(|e| e.1 == PeripheralEvent::Offline)
    {
        let ev = m.events.clone();
        fail(q, &ev, "unexpected master events".into());
    }
    // The ramp really ran: the last "run" phase reached the negative setpoint.
    let p = qemu::LoopbackModel::new(module).pzd();
    let nist = |c: &host_tests::CycleRecord| i16::from_be_bytes([c.i_received[p + 2], c.i_received[p + 3]]);
    assert!(
        log.iter().any(|c| nist(c) == 0x4000) && log.iter().any(|c| nist(c) == -0x2000),
        "ramp did not reach the setpoints"
    );
    let stats = m.phy.stats();
    let fw = q.stop();
    // With defmt-print installed the log is decoded: the firmware saw the same bring-up.
    if fw.iter().any(|l| l.contains("pbcard: station")) {
        assert!(fw.iter().any(|l| l.contains("DP state DataExch, master 2")), "firmware log: {fw:#?}");
    }
    assert!(!fw.iter().any(|l| l.contains("panic") || l.contains("HardFault")), "firmware log: {fw:#?}");
    println!(
        "{}: slave ready after {} ms, data exchange after {t_up} ms, {n} cycles checked in {} ms ({:.2} ms/cycle), \
         {} telegrams / {} bytes out, {} bytes in, {} stale bytes dropped",
        module.name,
        ready.as_millis(),
        t_end - t_up,
        (t_end - t_up) as f64 / n as f64,
        stats.tx_telegrams,
        stats.tx_bytes,
        stats.rx_bytes,
        stats.rx_dropped
    );
}

#[test]
fn standard_telegram_1_brought_up_and_1000_cycles_checked() {
    data_exchange(&card::MODULES[0], 1000);
}

#[test]
fn ppo5_28_bytes_brought_up_and_500_cycles_checked() {
    let ppo5 = card::MODULES.iter().find(|m| m.reference == 105).expect("PPO 5 in card::MODULES");
    data_exchange(ppo5, 500);
}
