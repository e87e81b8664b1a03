//! The live demo (README command 1): profirust's DP master — a master nobody here wrote —
//! brings our slave to data exchange on a simulated RS485 line at 1.5 Mbit/s, then the two
//! exchange changing data; every step is printed readably.
//!
//! Run: `bash scripts/demo.sh` (or `cargo run -p host-tests --bin demo --target <host triple>`).

use host_tests::*;
use pbcard::card;
use pbcard::time::{Baudrate, Duration};
use profirust::dp::PeripheralEvent;

const SLAVE: u8 = 5;

fn main() {
    let rate = Baudrate::B1500k;
    let module = &card::MODULES[0];
    println!(
        "pbcard demo: profirust DP master #2 + our slave #{SLAVE} on a simulated line at {} bit/s",
        rate.bits_per_second()
    );
    println!("module: {} (Chk_Cfg {}), ident 0x{:04X}", module.name, hex(module.cfg), card::IDENT_NUMBER);
    let mut bus = SimBus::new(
        MasterConfig::new(rate).watchdog_ms(50),
        &[PeripheralConfig::card(SLAVE, module, rate)],
        vec![(SLAVE, EchoApp::default())],
    );

    println!("\n-- bring-up (master events and slave state as they happen)");
    let mut last_state = None;
    let up = bus.run_until(Duration::from_millis(500), |bus, r| {
        let t = bus.now_us();
        if let Some((a, ev)) = r.master_event {
            println!("{:>9} µs  master: #{a} {ev:?}", t);
        }
        let st = bus.slave(SLAVE).slave.state();
        if last_state != Some(st) {
            println!("{:>9} µs  slave:  state {st:?}", t);
            last_state = Some(st);
        }
        matches!(r.master_event, Some((SLAVE, PeripheralEvent::DataExchanged)))
    });
    if !up {
        eprintln!("the slave did not reach data exchange:\n{}", bus.report());
        std::process::exit(1);
    }

    println!("\n-- data exchange: master writes PI_Q, the slave application answers transform(PI_Q) one cycle later");
    let cycles = bus.exchange(SLAVE, 12, Duration::from_millis(200), |k| {
        let k = k as u16;
        let mut q = Vec::new();
        q.extend_from_slice(&0x047Fu16.to_be_bytes()); // a PROFIdrive STW1 "run"
        q.extend_from_slice(&(k * 0x0400).to_be_bytes()); // a rising speed setpoint
        q
    });
    let mut ok = true;
    for (k, c) in cycles.iter().enumerate() {
        let expect = if k == 0 { None } else { Some(transform(&cycles[k - 1].q_sent, module.inputs as usize)) };
        let good = expect.as_ref().is_none_or(|e| *e == c.i_received);
        ok &= good;
        println!(
            "{:>9} µs  cycle {k:>2}: PI_Q {}  →  PI_I {}  {}",
            c.t_us,
            hex(&c.q_sent),
            hex(&c.i_received),
            if k == 0 {
                "(warm-up)"
            } else if good {
                "ok"
            } else {
                "MISMATCH"
            }
        );
    }
    let ep = bus.slave(SLAVE);
    let (st, sl) = (ep.station.stats(), ep.slave.stats());
    println!(
        "\nslave counters: {} requests, {} FCB retries, {} FDL_Status, {} Data_Exchange, {} diag reads",
        st.requests, st.retries, st.fdl_status, sl.data_exchanges, sl.diag_reads
    );
    if !ok {
        std::process::exit(1);
    }
    println!("demo passed: every cycle checked");
}
