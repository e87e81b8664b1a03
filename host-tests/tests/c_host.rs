//! The C reference host end to end (issue 16 item 5): `c-host/src/pbcard_host.c` and a small C
//! drive (`c-host/test/drive.c`), compiled with the system C compiler, drive the card through
//! the SPI frames of `docs/SPI.md` — the C host's transfer callback is the card's own SPI
//! slave with the board's reply pipeline (`Loopback` inside `Application::card_only`, the
//! board firmware's application). A scripted DP master brings the card up and exchanges
//! ST1 / DP-V1 telegrams with it; the test checks bytes on both sides: open, CONFIG (the
//! start-up gate opens), STW1 / setpoint reaching the C drive, its actual speed reaching the
//! master, a parameter read and write answered by the C drive through the CYCLIC exchange's
//! mailbox fragments, a fault and a warning of the C drive seen by the master (ZSW1, Ext_Diag,
//! PNU 947), a card restart
//! seen by BOOT_ID, and the per-cycle budget.

use host_tests::c_host::{config, result, CDrive};
use pbcard::card;
use pbcard::dp::diag::Status1;
use pbcard::dp::{DpSlave, Events};
use pbcard::dpm::spi::{crc16, BusFault, SpiBus};
use pbcard::fast::CardApp;
use pbcard::fdl::telegram;
use pbcard::node::Node;
use pbcard::testkit::{CardRig, Rig, SetPrm};
use pbcard::time::{Baudrate, Instant};
use pbcard_sim::bench::Application;

const MASTER: u8 = 2;
const SLAVE: u8 = 5;
/// The drive's SPI clock (the budget's time base) and its per-cycle SPI budget.
const SCK_HZ: u32 = 10_000_000;
const BUDGET_US: u32 = 1000;

/// The card as the C host's SPI bus: the board firmware's application (card only), whose
/// in-process SPI slave owns the DPM image.
struct Card {
    app: Application,
}

impl SpiBus for Card {
    fn transfer(&mut self, mosi: &[u8], miso: &mut [u8]) -> Result<(), BusFault> {
        self.app.host_mut().transport_mut().bus_mut().transfer(mosi, miso)
    }
}

fn card(boot_id: u16) -> Card {
    let mut app = Application::card_only();
    app.set_baudrate(Some(Baudrate::B1500k));
    app.link_mut().set_boot_id(boot_id);
    Card { app }
}

/// The card side of the bench: the card's application inside the C drive's SPI bus (the C
/// drive owns the card), one C drive cycle after every card step, within its budget.
struct CHost {
    drive: CDrive<Card>,
    budget_us: u32,
    results: Vec<i32>,
    /// (transactions, bytes) of every call.
    traffic: Vec<(u32, u32)>,
}

impl CardApp for CHost {
    type Records<'a> = <Application as CardApp>::Records<'a>;

    /// One card step, then one C drive cycle.
    fn step(&mut self, now: Instant, node: &mut Node) -> Events {
        let ev = self.drive.bus_mut().app.step(now, node);
        let ms = (now.as_micros() / 1000) as u32;
        let r = self.drive.step(ms, self.budget_us);
        self.results.push(r);
        let (tx, bytes, used) = self.drive.last_traffic();
        self.traffic.push((tx, bytes));
        assert!(used <= self.budget_us, "a cycle used {used} µs of a {} µs budget", self.budget_us);
        ev
    }

    fn records(&mut self, now: Instant) -> Self::Records<'_> {
        self.drive.bus_mut().app.records(now)
    }
}

/// The one card rig ([`CardRig`]) with the C drive behind the card: `b.app` is the [`CHost`].
struct Bench(CardRig<CHost>);

impl core::ops::Deref for Bench {
    type Target = CardRig<CHost>;
    fn deref(&self) -> &CardRig<CHost> {
        &self.0
    }
}

impl core::ops::DerefMut for Bench {
    fn deref_mut(&mut self) -> &mut CardRig<CHost> {
        &mut self.0
    }
}

impl Bench {
    fn new() -> Self {
        let host = CHost {
            drive: CDrive::new(card(0x1111), SCK_HZ, 0),
            budget_us: BUDGET_US,
            results: vec![],
            traffic: vec![],
        };
        Bench(CardRig::new(host, MASTER, SLAVE))
    }

    fn app(&mut self) -> &mut Application {
        &mut self.0.app.drive.bus_mut().app
    }

    /// `n` milliseconds: each one card step, then one C drive cycle.
    fn run(&mut self, n: u32) {
        for _ in 0..n {
            self.0.step(1);
        }
    }

    /// One MSAC_C1 request and the DP-V1 task over the mailbox-backed parameters; the
    /// response PDU of the poll that follows.
    fn c1(&mut self, pdu: &[u8]) -> Vec<u8> {
        let r = &mut self.0;
        let f = r.master.request(MASTER, Some(51), Some(51), pdu, true);
        assert_eq!(r.deliver(&f).as_deref(), Some(&[telegram::SC][..]));
        r.node.process_acyclic(r.now, &mut r.app.records(r.now));
        let f = r.master.request(MASTER, Some(51), Some(51), &[], true);
        let resp = r.deliver(&f).expect("a response");
        assert_eq!(resp[0], 0x68, "a response PDU: {resp:02X?}");
        resp[9..resp.len() - 2].to_vec()
    }
}

fn words(b: &[u8]) -> Vec<u16> {
    b.chunks(2).map(|w| u16::from_be_bytes([w[0], w[1]])).collect()
}

#[test]
fn the_c_host_drives_the_card_end_to_end() {
    let mut b = Bench::new();
    assert_eq!(b.app.drive.crc16(b"123456789"), crc16(b"123456789"), "the C CRC is the card's");
    // Open (header, STATUS, the host blocks' counters), CONFIG written and taken over.
    b.run(10);
    assert_eq!(b.app.drive.boot(), (0x1111, true));
    assert_eq!(b.app.drive.counts().1, 1, "opened once");
    assert_eq!(b.app.drive.config_outcome(), config::ACCEPTED);
    assert!(!b.app().link().gated(), "the drive's CONFIG opened the start-up gate");
    assert!(b.app.drive.card().0, "the card's heartbeat is seen");

    // The master brings the card up (DP-V1 on) and runs ST1: STW1 0x047E, then 0x047F with
    // 50 % setpoint.
    b.bring_up(&SetPrm::CARD.dpv1_status_1(0x80), card::MODULES[0].cfg);
    let sp = 0x2000u16;
    let mut q = [0x04, 0x7E, (sp >> 8) as u8, sp as u8];
    for _ in 0..5 {
        b.data_exchange(&q);
        b.run(2);
    }
    q[1] = 0x7F;
    let mut inputs = vec![];
    for _ in 0..30 {
        inputs = b.data_exchange(&q).to_vec();
        b.run(2);
    }
    let (flags, setpoint) = b.app.drive.command();
    assert_eq!(flags & 1, 1, "RUN reached the C drive (DRIVE_CMD.FLAGS {flags:04X})");
    assert_eq!(setpoint, sp as i16, "the setpoint reached the C drive");
    assert_eq!(b.app.drive.speed(), sp as i16, "the C drive ran up (0x100 per ms)");
    let w = words(&inputs);
    assert_eq!(w[1], sp, "NIST_A from the C drive's DRIVE_STATE reaches the master");
    assert_eq!(w[0] & 0x0007, 0x0007, "ZSW1: ready, ready to operate, operation enabled ({:04X})", w[0]);

    // The steady state: one transaction of ≤ 64 bytes per drive cycle.
    let (tx, bytes, used) = b.app.drive.last_traffic();
    assert_eq!(tx, 1, "one CYCLIC transaction per cycle");
    assert!(bytes <= 64, "{bytes} bytes per cycle");
    println!("C host, ST1 steady state: {tx} transaction, {bytes} bytes, {used} µs at {} MHz", SCK_HZ / 1_000_000);

    // A DP-V1 parameter read of the drive's PNU 100: the card's mailbox, the C drive's answer,
    // through the CYCLIC exchange's fragments: every cycle one transaction of ≤ 64 bytes.
    let before = b.app.drive.mailbox().0;
    let from = b.app.traffic.len();
    let req = [1, 1, 1, 1, 0x10, 1, 0, 100, 0, 0];
    assert_eq!(b.c1(&[&[0x5F, 0, 47, req.len() as u8][..], &req].concat()), [0x5F, 0, 47, req.len() as u8]);
    let mut answer = vec![];
    for _ in 0..10 {
        b.run(1);
        let r = b.c1(&[0x5E, 0, 47, 240]);
        if r[0] == 0x5E {
            answer = r[4..].to_vec();
            break;
        }
    }
    assert_eq!(answer, [1, 1, 1, 1, 0x42, 1, 0, 50], "PNU 100 = 50 from the C drive");
    assert_eq!(b.app.drive.mailbox().0, before + 1, "one request taken");
    // The C host counts the answer written once the reply confirms its tail fragment.
    b.run(2);
    assert_eq!(b.app.drive.mailbox().1, before + 1, "one answer written");
    // A write of PNU 101 through the mailbox reaches the C drive's table.
    let req = [2, 2, 1, 1, 0x10, 1, 0, 101, 0, 0, 0x42, 1, 0x01, 0x23];
    assert_eq!(b.c1(&[&[0x5F, 0, 47, req.len() as u8][..], &req].concat()), [0x5F, 0, 47, req.len() as u8]);
    for _ in 0..10 {
        b.run(1);
        let r = b.c1(&[0x5E, 0, 47, 240]);
        if r[0] == 0x5E {
            assert_eq!(r[4..], [2, 2, 1, 1], "write done");
            break;
        }
    }
    assert_eq!(b.app.drive.value(1), 0x0123);
    b.run(3);
    let mbx = &b.app.traffic[from..];
    assert!(mbx.iter().all(|&(tx, bytes)| tx == 1 && bytes <= 64), "mailbox cycles: {mbx:?}");
    assert!(mbx.iter().any(|&(_, bytes)| bytes > 42), "fragments rode along: {mbx:?}");
    println!(
        "C host, ST1 with a parameter read and write in flight: {} cycles, at most {} bytes, one transaction each",
        mbx.len(),
        mbx.iter().map(|t| t.1).max().unwrap()
    );

    // The C drive trips (fault 0x2310, overcurrent): DRIVE.FAULT_CODE and DRIVE_STATE. The
    // master sees ZSW1's fault bit, the card's Ext_Diag (Station_Status_1 b3), and the fault in
    // the product's fault buffer, PNU 947 element 0 (record 47); the motor stops.
    let writes = b.app.drive.steady_bytes_and_drive_writes().1;
    b.app.drive.set_fault(0x2310);
    b.run(3);
    assert_eq!(b.app.drive.steady_bytes_and_drive_writes().1, writes + 1, "DRIVE written whole once");
    for _ in 0..3 {
        inputs = b.data_exchange(&q).to_vec();
        b.run(2);
    }
    let zsw1 = words(&inputs)[0];
    assert_eq!(zsw1 & 0x0008, 0x0008, "ZSW1 b3 fault ({zsw1:04X})");
    assert_eq!(zsw1 & 0x0004, 0, "not in operation ({zsw1:04X})");
    assert!(b.node.slave().standard_diag().status1.contains(Status1::EXT_DIAG), "Ext_Diag for the drive fault");
    let req = [3, 1, 1, 1, 0x10, 1, 0x03, 0xB3, 0, 0];
    assert_eq!(b.c1(&[&[0x5F, 0, 47, req.len() as u8][..], &req].concat()), [0x5F, 0, 47, req.len() as u8]);
    let r = b.c1(&[0x5E, 0, 47, 240]);
    assert_eq!(r[0], 0x5E, "PNU 947 answered by the card: {r:02X?}");
    assert_eq!(r[4..8], [3, 1, 1, 1], "{r:02X?}");
    assert_eq!(r[r.len() - 2..], [0x23, 0x10], "PNU 947[0] = the C drive's fault: {r:02X?}");
    // A warning beside it (0x0F01): ZSW1 b7; the fault cleared in the drive and acknowledged
    // by the master (STW1 b7 edge): ZSW1 b3 and Ext_Diag go.
    b.app.drive.set_warning(0x0F01);
    b.app.drive.set_fault(0);
    b.run(3);
    for stw1 in [0xFE, 0x7E, 0x7E, 0x7F, 0x7F] {
        q[1] = stw1;
        inputs = b.data_exchange(&q).to_vec();
        b.run(2);
    }
    let zsw1 = words(&inputs)[0];
    assert_eq!(zsw1 & 0x0088, 0x0080, "ZSW1 b7 warning, b3 fault gone ({zsw1:04X})");
    assert!(!b.node.slave().standard_diag().status1.contains(Status1::EXT_DIAG), "no Ext_Diag for a warning");
    assert_eq!(b.app().link().drive_report().warning_code, 0x0F01, "DRIVE.WARNING_CODE from the C host");
    assert_eq!(b.app().link().drive_report().fault_count, 1, "one fault reported");
    b.app.drive.set_warning(0);
    b.run(3);

    // A parameter read while every other reply of the card comes late (the board's frame task
    // missed the next NSS fall): the C host's fragments are confirmed only by the reply to the
    // request that carried them, so the answer is still exactly the drive's.
    let late = b.app().host().transport().bus().pipeline().late;
    let req = [4, 1, 1, 1, 0x10, 1, 0, 101, 0, 0];
    assert_eq!(b.c1(&[&[0x5F, 0, 47, req.len() as u8][..], &req].concat()), [0x5F, 0, 47, req.len() as u8]);
    let mut answer = vec![];
    for i in 0..40 {
        if i % 2 == 0 {
            b.app().host_mut().transport_mut().bus_mut().set_late(1);
        }
        b.run(1);
        let r = b.c1(&[0x5E, 0, 47, 240]);
        if r[0] == 0x5E {
            answer = r[4..].to_vec();
            break;
        }
    }
    assert_eq!(answer, [4, 1, 1, 1, 0x42, 1, 0x01, 0x23], "PNU 101 = 0x0123 through late replies");
    assert!(b.app().host().transport().bus().pipeline().late > late, "replies came late");
    b.run(3);

    // The card restarts (a new BOOT_ID, a fresh image and DP slave): the C host sees it,
    // opens again and rewrites CONFIG, so the start-up gate opens again.
    b.app.drive.bus_mut().app = card(0x2222).app;
    b.node = pbcard::card::node(DpSlave::new(&pbcard::card::SLAVE, SLAVE));
    b.run(10);
    let (restarts, opens, _, _) = b.app.drive.counts();
    assert_eq!((restarts, opens), (1, 2), "one restart seen, opened again");
    assert_eq!(b.app.drive.boot(), (0x2222, true));
    assert_eq!(b.app.drive.config_outcome(), config::ACCEPTED, "CONFIG rewritten to the restarted card");
    assert!(!b.app().link().gated());
    b.bring_up(&SetPrm::CARD.dpv1_status_1(0x80), card::MODULES[0].cfg);
    for stw1 in [0x7E, 0x7E, 0x7E].into_iter().chain([0x7F; 30]) {
        q[1] = stw1;
        inputs = b.data_exchange(&q).to_vec();
        b.run(2);
    }
    assert_eq!(words(&inputs)[1], sp, "the restarted card serves the C drive's speed");

    // A budget for one short transaction: the steady state still fits, the C host never
    // goes beyond it (checked in every `run`).
    b.app.budget_us = 60;
    b.run(20);
    assert_eq!(*b.app.results.last().unwrap(), result::OK);
    let (tx, bytes, used) = b.app.drive.last_traffic();
    assert_eq!((tx, bytes), (1, 42));
    assert!(used <= 60);
    // No budget: nothing is sent, nothing blocks.
    b.app.budget_us = 0;
    b.run(1);
    assert_eq!(*b.app.results.last().unwrap(), result::BUDGET);
    assert_eq!(b.app.drive.last_traffic(), (0, 0, 0));
    let (max_tx, max_us) = b.app.drive.max_traffic();
    println!("C host: at most {max_tx} transactions / {max_us} µs in one call (budget {BUDGET_US} µs)");
    assert!(b.app.results.iter().all(|&r| r != result::NO_REPLY), "never without a reply: {:?}", b.app.results);
    let _ = result::OPENING;
}
