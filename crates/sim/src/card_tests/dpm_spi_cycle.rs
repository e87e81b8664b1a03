//! Issue 16 item 2 through the shipped card: the CYCLIC exchange of one drive cycle between
//! the card (`Application::card_only`, its DP slave in data exchange with ST1 / PPO 5 under
//! the scripted master) and a drive running the reference host's [`Host::cycle`] over the
//! real frames (`SpiHost` → `Loopback` with the board's reply pipeline). The benchmark
//! `cyclic_exchange_figures` prints transactions, bytes and setpoint latency per drive cycle
//! (`cargo test -p pbcard-sim --lib --target x86_64-unknown-linux-gnu cyclic_exchange_figures -- --nocapture`).

use crate::bench::Application;
use crate::card::{self, Module};
use crate::dp::DpSlave;
use crate::dpm::host::Cycle;
use crate::dpm::spi::cyclic::{CyclicReply, CyclicRequest};
use crate::dpm::{DriveStateImage, HostConfig};
use crate::node::Node;
use crate::profile::drive_if::{DriveStatus, StatusFlags};
use crate::testkit::{feed, CardRig, Rig, SetPrm};
use crate::time::{Duration, Instant};

const MASTER: u8 = 2;
const SLAVE: u8 = 5;
/// The drive cycle of the benchmark.
const DRIVE_CYCLE_US: u64 = 1000;
/// SPI clock of the latency figure.
const SCK_HZ: u64 = 10_000_000;

fn module(reference: u16) -> &'static Module {
    card::MODULES.iter().find(|m| m.reference == reference).unwrap()
}

/// The card in data exchange with `m`, the drive's CONFIG written (start-up gate).
fn rig(m: &Module) -> CardRig<Application> {
    let mut r = CardRig::new(Application::card_only(), MASTER, SLAVE);
    r.settle();
    r.app.host_mut().write_config(&HostConfig::DEFAULT).unwrap();
    r.settle();
    r.bring_up(&SetPrm::CARD.dpv1_status_1(0x80), m.cfg);
    r
}

/// The drive's answer to a command: running at the setpoint, extra words echoed.
fn state_for(c: &Cycle, last: &mut DriveStateImage) -> DriveStateImage {
    if let Some((_, cmd)) = c.command {
        *last = DriveStateImage {
            status: DriveStatus {
                flags: StatusFlags::READY | StatusFlags::RUNNING,
                speed: cmd.command.speed_setpoint,
                ..DriveStatus::default()
            },
            inputs_seq: 0,
            extra: cmd.extra,
        };
    }
    *last
}

/// Outputs of module `m` with setpoint `sp` (STW1 047F; PPO 5: PKW zero, PZD3.. = `i`).
fn outputs(m: &Module, sp: i16) -> Vec<u8> {
    let mut o = vec![0u8; usize::from(m.outputs)];
    let at = if m.reference == 105 { 8 } else { 0 };
    o[at..at + 2].copy_from_slice(&0x047Fu16.to_be_bytes());
    o[at + 2..at + 4].copy_from_slice(&sp.to_be_bytes());
    for (i, w) in o[at + 4..].chunks_mut(2).enumerate() {
        w.copy_from_slice(&(0x100 + i as u16).to_be_bytes());
    }
    o
}

#[derive(Debug, Default)]
struct Figures {
    cycles: u32,
    transactions: u32,
    bytes: u32,
    max_transactions: u32,
    /// Most bytes of a one-transaction cycle.
    max_bytes: u32,
    /// Cycles that took two transactions (the first: no reply pending yet).
    two_transaction_cycles: u32,
    /// Cycles longer than the idle cycle: they carried a mailbox fragment.
    mailbox_cycles: u32,
    /// Parameter requests the drive answered (the card's own reads after the selection and
    /// the master's record-47 read and write).
    served: u32,
    /// Drive cycles from the record-47 write request to its answer at the master, and from
    /// the read request to its answer.
    record47_cycles: (u32, u32),
    latency_us: f64,
}

/// The drive's parameter PNU 100 (a word), served through the mailbox.
const PNU: u16 = 100;

/// The MSAC_C1 exchange of these tests on the card rig.
trait C1 {
    /// One MSAC_C1 request to the card and the DP-V1 task over the mailbox-backed
    /// parameters; the response PDU of the poll that follows.
    fn c1(&mut self, pdu: &[u8]) -> Vec<u8>;
}

impl C1 for CardRig<Application> {
    fn c1(&mut self, pdu: &[u8]) -> Vec<u8> {
        let f = self.master.request(MASTER, Some(51), Some(51), pdu, true);
        assert_eq!(feed(&mut self.node, self.now, &f).as_deref(), Some(&[crate::fdl::telegram::SC][..]));
        let now = self.now;
        self.node.process_acyclic(now, &mut self.app.records(now));
        let f = self.master.request(MASTER, Some(51), Some(51), &[], true);
        let r = feed(&mut self.node, self.now, &f).expect("a response");
        r[9..r.len() - 2].to_vec()
    }
}

/// Run the drive at a 1 ms cycle with a new setpoint every 7.3 ms (all phases against the
/// drive cycle): per cycle transactions and bytes (every cycle, from the first, the card's
/// speed-reference reads after the selection included), a record-47 write and read of a
/// drive parameter through the mailbox, and the worst time from the Data_Exchange with a
/// new setpoint until the drive holds another setpoint than before (the drive cycle it comes
/// with, plus that cycle's transaction at 10 MHz).
fn run(m: &Module) -> Figures {
    use crate::dpm::host::Answer;
    use crate::dpm::{MailboxRequest, ParamValues, RequestKind};
    use crate::profile::param::{ErrorValue, Format, ParamError};
    let mut r = rig(m);
    let mut last = DriveStateImage::EMPTY;
    let t0 = r.now;
    let mut f = Figures::default();
    let mut sp: i16 = 0x1000;
    let mut dx_at: Option<(u64, i16)> = None;
    let mut next_dx = 2_300u64;
    let mut worst = 0u64;
    // The setpoint the drive holds (a new Data_Exchange changes it: scaled per profile).
    let mut seen = 0i16;
    let mut prev = Cycle { poll: r.app.host_mut().poll(r.now), command: None, comm: None, cyclic: false };
    let mut value = 0x0050u16;
    // Record 47 (PROFIdrive parameter access): a write of PNU 100 at 10 ms, a read 5 ms after
    // its answer.
    let write = [0x11u8, 2, 1, 1, 0x10, 1, 0, PNU as u8, 0, 0, 0x42, 1, 0x12, 0x34];
    let read = [0x12u8, 1, 1, 1, 0x10, 1, 0, PNU as u8, 0, 0];
    let mut pending: Option<(u64, u8)> = None;
    let mut read_at = u64::MAX;
    let mut idle_bytes = u32::MAX;
    // Simulated time in µs from t0, in 100 µs steps: Data_Exchange + card step whenever due,
    // a drive cycle every DRIVE_CYCLE_US.
    for tick in 0..30_000u64 {
        let us = tick * 100;
        let now = t0 + Duration::from_micros(us);
        r.now = now;
        if us >= next_dx {
            sp = if sp == 0x1000 { 0x2000 } else { 0x1000 };
            let pdu = outputs(m, sp);
            r.data_exchange(&pdu);
            r.app.step(now, &mut r.node);
            if dx_at.is_none() {
                dx_at = Some((us, seen));
            }
            next_dx += 7_300;
        }
        if us % 1000 == 500 {
            // The card's 1 ms housekeeping step, between drive cycles.
            r.app.step(now, &mut r.node);
            // The master's record-47 requests and the poll for their answers.
            if let Some((at, reference)) = pending {
                let a = r.c1(&[0x5E, 0, 47, 240]);
                if a[0] == 0x5E {
                    let cycles = ((us - at) / DRIVE_CYCLE_US) as u32;
                    if reference == write[0] {
                        assert_eq!(a[4..], [0x11, 2, 1, 1], "write done");
                        f.record47_cycles.0 = cycles;
                        read_at = us + 5_000;
                    } else {
                        assert_eq!(a[4..], [0x12, 1, 1, 1, 0x42, 1, 0x12, 0x34], "PNU 100 read back");
                        f.record47_cycles.1 = cycles;
                    }
                    pending = None;
                }
            } else if us == 10_500 || us == read_at {
                let q: &[u8] = if us == 10_500 { &write } else { &read };
                let w = r.c1(&[&[0x5F, 0, 47, q.len() as u8][..], q].concat());
                assert_eq!(w, [0x5F, 0, 47, q.len() as u8]);
                pending = Some((us, q[0]));
            }
        }
        if us % DRIVE_CYCLE_US == 0 {
            let state = state_for(&prev, &mut last);
            let (t_before, b_before) = r.app.host().transport().traffic();
            let c = r.app.host_mut().cycle(now, &state);
            // The drive serves its mailbox as a real one does: PNU 100 a word; the card's
            // speed-reference reads after the selection (issue 15 item 10) name parameters
            // this drive does not have. A drive that never answers would have the card repeat
            // the read after every mailbox timeout.
            let mut server = |q: &MailboxRequest| {
                f.served += 1;
                if q.pnu != PNU {
                    return Answer::Now(Err(ParamError {
                        value: ErrorValue::IMPERMISSIBLE_PARAMETER_NUMBER,
                        additional_info: None,
                    }));
                }
                if q.kind == RequestKind::Write {
                    value = u16::from_be_bytes([q.values.bytes()[0], q.values.bytes()[1]]);
                    return Answer::Now(Ok(ParamValues::NONE));
                }
                Answer::Now(Ok(ParamValues::new(Format::WORD, 1, &value.to_be_bytes()).unwrap()))
            };
            r.app.host_mut().serve_parameters(&mut server).unwrap();
            let (t_after, b_after) = r.app.host().transport().traffic();
            let (dt, db) = (t_after - t_before, b_after - b_before);
            f.cycles += 1;
            f.transactions += dt;
            f.bytes += db;
            f.max_transactions = f.max_transactions.max(dt);
            assert!(dt <= 2, "cycle {}: {dt} transactions", f.cycles);
            if dt == 2 {
                f.two_transaction_cycles += 1;
            } else {
                f.max_bytes = f.max_bytes.max(db);
                if db > idle_bytes {
                    f.mailbox_cycles += 1;
                }
                idle_bytes = idle_bytes.min(db);
            }
            assert!(c.cyclic && c.poll.error.is_none(), "{c:?}");
            if let (Some((at, want)), Some((_, cmd))) = (dx_at, c.command) {
                if cmd.command.speed_setpoint != want {
                    let clock_us = u64::from(db) * 8 * 1_000_000 / SCK_HZ;
                    worst = worst.max(us - at + clock_us);
                    dx_at = None;
                }
            }
            if let Some((_, cmd)) = c.command {
                seen = cmd.command.speed_setpoint;
            }
            prev = c;
        }
    }
    assert_eq!(r.app.host().stats().transport_errors, 0);
    assert!(pending.is_none() && f.record47_cycles.0 > 0 && f.record47_cycles.1 > 0, "{f:?}");
    assert_eq!(value, 0x1234, "the record-47 write reached the drive");
    // The drive's answer reached the master: the input image carries the echoed speed.
    let pdu = r.data_exchange(&outputs(m, sp));
    let at = if m.reference == 105 { 8 } else { 0 };
    assert_eq!(pdu.len(), usize::from(m.inputs));
    let nist = i16::from_be_bytes([pdu[at + 2], pdu[at + 3]]);
    assert!((nist - sp).abs() <= 0x222, "NIST {nist:#x} follows NSOLL {sp:#x}");
    f.latency_us = worst as f64;
    f
}

#[test]
fn cyclic_exchange_figures() {
    let mut out = String::from(
        "drive cycle over the SPI frames (Host::cycle → SpiHost → Loopback, board pipeline), 1 ms drive cycle, 10 MHz SCK, \
         every cycle from the first (the card's speed-reference reads and a record-47 write and read through the mailbox included)\n\
         | telegram | transactions / cycle (max) | bytes / cycle (max) | cycles with a mailbox fragment | record-47 write / read answered after | setpoint latency, worst |\n|---|---|---|---|---|---|\n",
    );
    for (name, reference) in [("ST1", 1u16), ("PPO 5", 105)] {
        let f = run(module(reference));
        let avg_t = f64::from(f.transactions) / f64::from(f.cycles);
        let avg_b = f64::from(f.bytes) / f64::from(f.cycles);
        out += &format!(
            "| {name} | {avg_t:.3} ({}, the first cycle only) | {avg_b:.1} ({}) | {} of {} ({} requests served) | {} / {} drive cycles | {:.0} µs |\n",
            f.max_transactions,
            f.max_bytes,
            f.mailbox_cycles,
            f.cycles,
            f.served,
            f.record47_cycles.0,
            f.record47_cycles.1,
            f.latency_us
        );
        assert!(f.max_transactions <= 2, "{name}: {f:?}");
        assert_eq!(f.two_transaction_cycles, 1, "{name}: only the first cycle has no reply pending: {f:?}");
        assert!(f.max_bytes <= 64, "{name}: {f:?}");
        assert!(f.mailbox_cycles > 0 && f.served >= 2, "{name}: the mailbox was exercised: {f:?}");
        assert!(f.latency_us <= (DRIVE_CYCLE_US + 500) as f64, "{name}: {f:?}");
    }
    out += "| Anybus CompactCom 40 (issue 16) | 1 | ≈ 34 | – | – | ≈ 14 µs per transaction at 20 MHz |\n";
    println!("{out}");
}

#[test]
fn cyclic_request_and_reply_grammar() {
    let state = [7u8; 16];
    let rsp = [1u8, 2, 3];
    let req = CyclicRequest { heartbeat: 5, drive_seq: 6, state_seq: 7, state: &state, rsp: (4, &rsp), req: (2, 10) };
    let mut d = [0u8; 64];
    let n = req.encode(&mut d);
    assert_eq!(n, req.len());
    assert_eq!(CyclicRequest::parse(&d[..n]), Some(req));
    // Every length that disagrees is refused.
    assert_eq!(CyclicRequest::parse(&d[..n - 1]), None);
    let mut bad = d;
    bad[6] = 200;
    assert_eq!(CyclicRequest::parse(&bad[..n]), None);
    let mut bad = d;
    bad[9] = 140; // fragment beyond MBX_REQ
    assert_eq!(CyclicRequest::parse(&bad[..n]), None);
    assert_eq!(CyclicReply::decode(&[0; 19]), None);
}

// ---------------------------------------------------------------------------------------
// Host restarts at every transaction boundary; arbitrary MISO; the CYCLIC parsers

use crate::dp::Events;
use crate::dpm::host::{Host, Options};
use crate::dpm::spi::{BusFault, Loopback, SpiBus, SpiHost};
use crate::dpm::{Dpm, Link};
use proptest::prelude::*;

/// A bus in front of the loopback card that dies after `left` more transactions (the host
/// restarts there: power cut, watchdog, a new program).
struct Cut {
    card: Loopback,
    left: Option<u32>,
}

impl SpiBus for Cut {
    fn transfer(&mut self, mosi: &[u8], miso: &mut [u8]) -> Result<(), BusFault> {
        match &mut self.left {
            Some(0) => return Err(BusFault),
            Some(n) => *n -= 1,
            None => {}
        }
        self.card.transfer(mosi, miso)
    }
}

fn card_step(link: &mut Link, node: &mut Node, host: &mut Host<SpiHost<Cut>>, now: Instant) {
    let dpm = &mut host.transport_mut().bus_mut().card;
    link.publish(node, Events::empty(), dpm.dpm_mut());
    link.publish_command(&crate::dpm::DriveCommandImage::default(), dpm.dpm_mut());
    link.collect(now, node, dpm.dpm());
}

fn state(speed: i16) -> DriveStateImage {
    DriveStateImage {
        status: DriveStatus { flags: StatusFlags::READY, speed, ..DriveStatus::default() },
        ..DriveStateImage::EMPTY
    }
}

#[test]
fn a_host_restart_at_every_transaction_boundary_recovers_without_a_stale_reply() {
    let cfg = HostConfig { station_address: 9, ..HostConfig::DEFAULT };
    for k in 0..16u32 {
        let (mut link, mut node) =
            (Link::new(crate::card::MODULES), crate::card::node(DpSlave::new(&crate::card::SLAVE, SLAVE)));
        link.set_startup_gate(true);
        let bus = Cut { card: Loopback::new(Dpm::new()), left: None };
        let mut host = Host::open(SpiHost::new(bus), Options::DEFAULT).unwrap();
        let mut now = Instant::from_millis(0);
        card_step(&mut link, &mut node, &mut host, now);
        host.write_config(&cfg).unwrap();
        for i in 0..3 {
            now = now + Duration::from_millis(1);
            card_step(&mut link, &mut node, &mut host, now);
            host.cycle(now, &state(100 + i));
        }
        // The old host dies after k more transactions, in the middle of whatever it does.
        host.transport_mut().bus_mut().left = Some(k);
        for i in 0..4 {
            host.cycle(now, &state(200 + i));
            let _ = host.write_config(&cfg);
            let _ = host.serve_parameters(&mut |_: &_| crate::dpm::host::Answer::Later);
        }
        let card = host.into_transport().into_bus().card;
        // The new host: open, CONFIG again, cycles; everything it takes is the card's.
        let mut host = Host::open(SpiHost::new(Cut { card, left: None }), Options::DEFAULT)
            .unwrap_or_else(|e| panic!("k {k}: {e:?}"));
        host.write_config(&cfg).unwrap();
        for i in 0..5 {
            now = now + Duration::from_millis(1);
            card_step(&mut link, &mut node, &mut host, now);
            let c = host.cycle(now, &state(300 + i));
            if i > 0 {
                assert!(c.cyclic && c.poll.error.is_none() && c.command.is_some(), "k {k} cycle {i}: {c:?}");
            }
        }
        card_step(&mut link, &mut node, &mut host, now);
        assert_eq!(link.read_drive_state(host.transport().bus().card.dpm()).status.speed, 304, "k {k}");
        assert!(node.slave().is_ready() && node.slave().address() == 9, "k {k}");
    }
}

/// A bus whose MISO is whatever the test gives.
struct Noise(Vec<u8>);

impl SpiBus for Noise {
    fn transfer(&mut self, _mosi: &[u8], miso: &mut [u8]) -> Result<(), BusFault> {
        for (i, b) in miso.iter_mut().enumerate() {
            *b = self.0.get(i).copied().unwrap_or(0);
        }
        Ok(())
    }
}

proptest! {
    #[test]
    fn the_host_never_panics_nor_takes_noise_for_a_reply(miso in proptest::collection::vec(any::<u8>(), 0..80)) {
        let mut host = SpiHost::new(Noise(miso));
        let mut buf = [0u8; 16];
        prop_assert!(host.read(0x30, &mut buf).is_err());
        let st = [0u8; 16];
        let req = CyclicRequest { heartbeat: 1, drive_seq: 1, state_seq: 1, state: &st, rsp: (0, &[]), req: (0, 0) };
        prop_assert!(host.cyclic(&req).is_err());
    }

    #[test]
    fn cyclic_parsers_never_panic_and_round_trip(bytes in proptest::collection::vec(any::<u8>(), 0..120)) {
        if let Some(r) = CyclicRequest::parse(&bytes) {
            let mut out = [0u8; 128];
            let n = r.encode(&mut out);
            prop_assert_eq!(&out[..n], &bytes[..]);
        }
        if let Some(r) = CyclicReply::decode(&bytes) {
            prop_assert_eq!(20 + r.command.len() + r.request.len(), bytes.len());
        }
    }
}

/// Issue 16 item 5: a drive on `Host::cycle` serves the parameter mailbox through the CYCLIC
/// exchange's fragments (MBX_REQ in a reply, MBX_RSP in request fragments): one
/// transaction per drive cycle throughout, no block access; the card takes the answer.
#[test]
fn a_cycle_drive_serves_the_mailbox_through_fragments_only() {
    use crate::dpm::host::Answer;
    use crate::dpm::{Mailbox, MailboxRequest, ParamValues};
    let (mut link, mut node) =
        (Link::new(crate::card::MODULES), crate::card::node(DpSlave::new(&crate::card::SLAVE, SLAVE)));
    let bus = Cut { card: Loopback::new(Dpm::new()), left: None };
    let mut host = Host::open(SpiHost::new(bus), Options::DEFAULT).unwrap();
    host.set_irq_mask(crate::dpm::spi::EVENT_BLOCKS & !(1 << 8));
    let mut now = Instant::from_millis(0);
    for i in 0..4 {
        now = now + Duration::from_millis(1);
        card_step(&mut link, &mut node, &mut host, now);
        assert!(host.cycle(now, &state(i)).cyclic);
    }
    assert!(!host.transport().bus().card.irq(), "only CARD / STATUS / DRIVE_CMD news: masked");
    let values = ParamValues::new(crate::profile::param::Format::WORD, 1, &[0x12, 0x34]).unwrap();
    let mut mbx = Mailbox::new(Duration::from_millis(500));
    let read = MailboxRequest::read(1, 100, 0, 1);
    let id = mbx.submit(now, &read, false, &mut host.transport_mut().bus_mut().card.dpm_mut().card()).unwrap();
    assert!(host.transport().bus().card.irq(), "a request asserts IRQ");
    let (t0, _) = host.transport().traffic();
    let (mut cycles, mut served, mut answer) = (0, None, None);
    for i in 0..12 {
        now = now + Duration::from_millis(1);
        card_step(&mut link, &mut node, &mut host, now);
        mbx.poll(now, host.transport().bus().card.dpm());
        if let Some(a) = mbx.take() {
            answer = Some(a);
            break;
        }
        let c = host.cycle(now, &state(10 + i));
        assert!(c.cyclic && c.poll.error.is_none(), "{c:?}");
        cycles += 1;
        let r = host.serve_parameters(&mut |q: &MailboxRequest| {
            assert_eq!((q.pnu, q.kind), (100, read.kind));
            Answer::Now(Ok(values))
        });
        served = served.or(r.unwrap());
    }
    assert_eq!(served, Some(id), "the request came in a fragment");
    assert_eq!(answer, Some((id, Ok(values))), "the card took the fragmented answer");
    // The host counts the answer written once the tail was carried twice.
    for i in 0..2 {
        now = now + Duration::from_millis(1);
        card_step(&mut link, &mut node, &mut host, now);
        host.cycle(now, &state(30 + i));
        cycles += 1;
    }
    assert_eq!(host.stats().responses, 1);
    let (t1, _) = host.transport().traffic();
    assert_eq!(t1 - t0, cycles, "one transaction per cycle: no block access for the mailbox");
    println!("mailbox through CYCLIC fragments: answer after {cycles} drive cycles");
}

/// One mailbox job through the CYCLIC fragments over a lossy pipeline: `faults[i]` is what
/// happens in cycle i (0 nothing, 1 the reply late, 2 the card busy); returns what the host
/// was asked and what the card took.
#[allow(clippy::type_complexity)]
fn lossy_job(
    cyclic_bytes: usize,
    request: crate::dpm::MailboxRequest,
    answer: Result<crate::dpm::ParamValues, crate::profile::param::ParamError>,
    faults: &[u8],
) -> (
    Vec<crate::dpm::MailboxRequest>,
    Option<(u16, Result<crate::dpm::ParamValues, crate::profile::param::ParamError>)>,
    u16,
) {
    use crate::dpm::host::Answer;
    use crate::dpm::{Mailbox, MailboxRequest};
    let (mut link, mut node) =
        (Link::new(crate::card::MODULES), crate::card::node(DpSlave::new(&crate::card::SLAVE, SLAVE)));
    let bus = Cut { card: Loopback::new(Dpm::new()), left: None };
    let opts = Options { cyclic_bytes, ..Options::DEFAULT };
    let mut host = Host::open(SpiHost::new(bus), opts).unwrap();
    let mut now = Instant::from_millis(0);
    for i in 0..3 {
        now = now + Duration::from_millis(1);
        card_step(&mut link, &mut node, &mut host, now);
        host.cycle(now, &state(i));
    }
    let mut mbx = Mailbox::new(Duration::from_millis(10_000));
    let id = mbx.submit(now, &request, false, &mut host.transport_mut().bus_mut().card.dpm_mut().card()).unwrap();
    let mut seen = vec![];
    for (i, &f) in faults.iter().chain(core::iter::repeat_n(&0, 200)).enumerate() {
        now = now + Duration::from_millis(1);
        card_step(&mut link, &mut node, &mut host, now);
        mbx.poll(now, host.transport().bus().card.dpm());
        if let Some(a) = mbx.take() {
            return (seen, Some(a), id);
        }
        match f {
            1 => host.transport_mut().bus_mut().card.set_late(1),
            2 => host.transport_mut().bus_mut().card.set_busy(1),
            _ => {}
        }
        host.cycle(now, &state(i as i16));
        let _ = host.serve_parameters(&mut |q: &MailboxRequest| {
            seen.push(*q);
            Answer::Now(answer)
        });
    }
    (seen, None, id)
}

proptest! {
    /// Issue 16 item 2 / 5: whatever the pipeline loses (late replies, a busy card) and
    /// however small the fragments (the budget), the drive is asked exactly the card's request
    /// and the card takes exactly the drive's answer — never a block with fragments of two
    /// writes, never a stale middle.
    #[test]
    fn mailbox_fragments_survive_a_lossy_pipeline(
        cyclic_bytes in 40usize..=80,
        words in 0usize..=40,
        answer_words in 0usize..=40,
        error in any::<bool>(),
        faults in proptest::collection::vec(prop_oneof![6 => Just(0u8), 1 => Just(1u8), 1 => Just(2u8)], 0..60),
    ) {
        use crate::dpm::{MailboxRequest, ParamValues};
        use crate::profile::param::{ErrorValue, Format, ParamError};
        let bytes: Vec<u8> = (0..2 * words).map(|i| i as u8 ^ 0x5A).collect();
        let request = if words == 0 {
            MailboxRequest::read(1, 0x1234, 3, 5)
        } else {
            MailboxRequest::write(1, 0x1234, 3, ParamValues::new(Format::WORD, words as u8, &bytes).unwrap())
        };
        let out: Vec<u8> = (0..2 * answer_words).map(|i| 0xA5 ^ i as u8).collect();
        let answer = if error {
            Err(ParamError { value: ErrorValue::IMPERMISSIBLE_PARAMETER_NUMBER, additional_info: Some(7) })
        } else {
            Ok(ParamValues::new(Format::WORD, answer_words as u8, &out).unwrap())
        };
        let (seen, taken, id) = lossy_job(cyclic_bytes, request, answer, &faults);
        prop_assert_eq!(seen.len(), 1, "asked once: {:?}", seen);
        let key = |q: &MailboxRequest| (q.id, q.kind, q.axis, q.pnu, q.subindex, q.count, q.values.bytes().to_vec());
        prop_assert_eq!(key(&seen[0]), key(&MailboxRequest { id, ..request }));
        prop_assert_eq!(taken, Some((id, answer)));
    }
}
