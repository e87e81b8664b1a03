//! The independent judge on the shipped card: profirust 0.6's DP master brings the whole card
//! — the line's fast path, the core (`Node`) behind it, the card's `Application` with the DPM
//! and the simulated drive ([`host_tests::card_bus::CardEndpoint`]) — to data exchange on
//! profirust's timing-checking simulated line at 9.6 k / 187.5 k / 1.5 M / 12 Mbit/s, with the
//! slot time tightened to the GSD's MaxTsdr (T_SL = MaxTsdr + 60 bit times, or profirust's
//! minimum), and runs the drive as a PLC program would: STW1 047E (ready), 047F with 50 %
//! (the speed ramps up to the setpoint), 047E (ramp stop to standstill). Every answer is
//! checked to start within min_TSDR … `card::max_tsdr` of the request's end, and the master
//! must never lose the card.
//!
//! Run: `cargo test -p host-tests --target x86_64-unknown-linux-gnu --test profirust_card`.

use host_tests::card_bus::CardEndpoint;
use host_tests::profirust::dp::PeripheralEvent;
use host_tests::*;
use pbcard::card;
use pbcard::dp::DpState;
use pbcard::time::{Baudrate, Duration};
use pbcard_sim::drive::DriveConfig;

const SLAVE: u8 = 7;

fn words(b: &[u8]) -> Vec<u16> {
    b.chunks(2).map(|w| u16::from_be_bytes([w[0], w[1]])).collect()
}

fn bus(rate: Baudrate) -> SimBus<CardEndpoint> {
    let mut master = MasterConfig::new(rate).watchdog_ms(if rate == Baudrate::B9600 { 1000 } else { 200 });
    master.slot_bits = Some(profirust_min_slot_bits(rate).max(card::max_tsdr(rate) + 60));
    let drive = DriveConfig { ramp_time: Duration::from_millis(200), ..DriveConfig::DEFAULT };
    SimBus::cards(master, &[PeripheralConfig::card(SLAVE, &card::MODULES[0], rate)], &[(SLAVE, drive)])
}

/// Run until the card's inputs (ZSW1, NIST_A) satisfy `done`; the last inputs.
fn until(bus: &mut SimBus<CardEndpoint>, what: &str, ms: u64, done: impl Fn(u16, u16) -> bool) -> (u16, u16) {
    let mut last = (0, 0);
    bus.expect_until(Duration::from_millis(ms), what, |b, r| {
        if !matches!(r.master_event, Some((a, PeripheralEvent::DataExchanged)) if a == SLAVE) {
            return false;
        }
        let w = words(b.peripheral(SLAVE).pi_i());
        last = (w[0], w[1]);
        done(w[0], w[1])
    });
    last
}

fn set_outputs(bus: &mut SimBus<CardEndpoint>, stw1: u16, setpoint: u16) {
    let q = bus.peripheral(SLAVE).pi_q_mut();
    q[..2].copy_from_slice(&stw1.to_be_bytes());
    q[2..4].copy_from_slice(&setpoint.to_be_bytes());
}

fn plc_program(rate: Baudrate) {
    let mut bus = bus(rate);
    // Slow rates take longer per cycle: simulated time, not wall time.
    let slow = if rate == Baudrate::B9600 { 10 } else { 1 };
    bus.bring_up(SLAVE, Duration::from_millis(5_000 * slow));
    assert_eq!(
        bus.events_for(SLAVE)[..3],
        [PeripheralEvent::Online, PeripheralEvent::Configured, PeripheralEvent::DataExchanged]
    );
    assert_eq!(bus.slave(SLAVE).node.slave().master_address(), Some(2));
    // PROFIdrive (Standard telegram 1): 047E → ready to switch on (ZSW1 b0), 047F at 50 %.
    set_outputs(&mut bus, 0x047E, 0);
    until(&mut bus, "ZSW1 ready to switch on", 2_000 * slow, |zsw, _| zsw & 0x0001 != 0);
    set_outputs(&mut bus, 0x047F, 0x2000);
    let (zsw, nist) =
        until(&mut bus, "NIST_A at the 50 % setpoint", 4_000 * slow, |zsw, nist| zsw & 0x0004 != 0 && nist >= 0x1FF0);
    assert_ne!(zsw & 0x0100, 0, "ZSW1 b8 (at setpoint) with NIST_A {nist:#06X}");
    // The drive saw the outputs through the DPM.
    assert_eq!(bus.slave(SLAVE).app.dpm().outputs().unwrap().bytes()[..4], [0x04, 0x7F, 0x20, 0x00]);
    // OFF1: ramp stop to standstill.
    set_outputs(&mut bus, 0x047E, 0x2000);
    until(&mut bus, "standstill after OFF1", 4_000 * slow, |zsw, nist| zsw & 0x0004 == 0 && nist == 0);
    let ep = bus.slave(SLAVE);
    assert_eq!(ep.node.slave().state(), DpState::DataExch);
    assert_eq!(ep.line.answers_abandoned, 0);
    let (lo, hi) = ep.line.tsdr_bits.expect("answers");
    assert!(hi <= u64::from(card::max_tsdr(rate)), "{rate:?}: {hi} > MaxTsdr");
    assert!(!bus.events_for(SLAVE).contains(&PeripheralEvent::Offline), "{rate:?}: the master lost the card");
    println!(
        "{rate:?}: shipped card, slot time {} bit times, answers {}..{hi} bit times after the request (MaxTsdr {}), {} cycles",
        bus.fdl_parameters().slot_bits,
        lo,
        card::max_tsdr(rate),
        bus.cycles
    );
}

#[test]
fn the_shipped_card_runs_the_drive_at_9k6() {
    plc_program(Baudrate::B9600);
}

#[test]
fn the_shipped_card_runs_the_drive_at_187k5() {
    plc_program(Baudrate::B187500);
}

#[test]
fn the_shipped_card_runs_the_drive_at_1m5() {
    plc_program(Baudrate::B1500k);
}

#[test]
fn the_shipped_card_runs_the_drive_at_12m() {
    plc_program(Baudrate::B12M);
}
