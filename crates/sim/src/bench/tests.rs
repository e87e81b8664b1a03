//! The card and the simulated drive under a scripted master: bytes in, bytes out, the drive's
//! reaction (moved from `pbcard::app` with the bench, issue 13 item 4).

use super::*;
use crate::card;
use crate::dp::{DpSlave, DpState};
use crate::dpm::{CommState, PdFlags, ProcessData, Telegram};
use crate::fdl::telegram::{self, FunctionCode, Header};
use crate::profile::drive_if::CommandFlags;
#[cfg_attr(feature = "bench", allow(unused_imports))] // the trait of a test the bench build leaves out
use crate::profile::drive_if::ControlProfile;
use crate::profile::profidrive::{State as DriveState, StopKind};
use crate::profile::records::CardRecords;
use crate::time::Duration;
use crate::time::{Baudrate, Instant};

const MASTER: u8 = 2;
const SLAVE: u8 = 5;

/// A scripted master: builds SRD requests and feeds them byte by byte.
pub(crate) struct Bench {
    pub(crate) node: Node,
    pub(crate) app: Application,
    pub(crate) now: Instant,
    fcb: bool,
}

impl Bench {
    pub(crate) fn new() -> Self {
        let mut app = Application::new(DriveConfig {
            ramp_time: Duration::from_millis(1000),
            quick_stop_time: Duration::from_millis(100),
            ..DriveConfig::DEFAULT
        });
        app.set_baudrate(Some(Baudrate::B1500k));
        Bench {
            node: crate::card::node(DpSlave::new(&crate::card::SLAVE, SLAVE)),
            app,
            now: Instant::from_millis(0),
            fcb: false,
        }
    }

    /// Send one SRD request; returns the response bytes.
    pub(crate) fn srd(&mut self, dsap: Option<u8>, pdu: &[u8]) -> Vec<u8> {
        self.send(dsap, dsap.map(|_| 62), pdu)
    }

    pub(crate) fn send(&mut self, dsap: Option<u8>, ssap: Option<u8>, pdu: &[u8]) -> Vec<u8> {
        self.send_from(MASTER, dsap, ssap, pdu)
    }

    /// An SRD from master `sa` (on the bench's one FCB); the response bytes.
    pub(crate) fn send_from(&mut self, sa: u8, dsap: Option<u8>, ssap: Option<u8>, pdu: &[u8]) -> Vec<u8> {
        self.fcb = !self.fcb;
        let hdr = Header { da: SLAVE, sa, fc: FunctionCode::request(0xD, self.fcb, true), dsap, ssap };
        let mut buf = [0u8; telegram::MAX_FRAME_LEN];
        let n = telegram::emit(&mut buf, &hdr, pdu).unwrap();
        let mut resp = None;
        for &b in &buf[..n] {
            if let Some(r) = self.node.on_byte(self.now, b) {
                resp = Some(r.to_vec());
            }
        }
        resp.expect("no response")
    }

    /// An SDN Global_Control (SAP 58) with `command` and `group` select, fed byte by byte (no
    /// answer).
    pub(crate) fn gc(&mut self, command: u8, group: u8) {
        let hdr = Header {
            da: SLAVE,
            sa: MASTER,
            fc: FunctionCode::request(0x6, false, false),
            dsap: Some(58),
            ssap: Some(62),
        };
        let mut buf = [0u8; telegram::MAX_FRAME_LEN];
        let n = telegram::emit(&mut buf, &hdr, &[command, group]).unwrap();
        for &x in &buf[..n] {
            assert!(self.node.on_byte(self.now, x).is_none(), "SDN: no answer");
        }
    }

    pub(crate) fn step(&mut self, ms: u64) -> Events {
        self.now = self.now + Duration::from_millis(ms);
        self.app.step(self.now, &mut self.node)
    }

    pub(crate) fn bring_up(&mut self, module: &card::Module) {
        self.bring_up_with(module, card::USER_PRM_DEFAULTS[0]);
    }

    pub(crate) fn bring_up_with(&mut self, module: &card::Module, dpv1_status_1: u8) {
        let mut prm = vec![0x88, 1, 100, 11, (card::IDENT_NUMBER >> 8) as u8, card::IDENT_NUMBER as u8, 0];
        prm.extend_from_slice(&card::USER_PRM_DEFAULTS);
        prm[7] = dpv1_status_1;
        assert_eq!(self.srd(Some(61), &prm), [telegram::SC]);
        self.step(1);
        assert_eq!(self.srd(Some(62), module.cfg), [telegram::SC]);
        self.step(1);
        assert_eq!(self.node.slave().state(), DpState::DataExch);
    }

    /// One MSAC_C1 request, one run of the DP-V1 task over the mailbox-backed parameters,
    /// one poll; returns the DP-V1 response PDU.
    pub(crate) fn c1(&mut self, pdu: &[u8]) -> Vec<u8> {
        assert_eq!(self.send(Some(51), Some(51), pdu), [telegram::SC], "request acknowledged");
        self.acyclic();
        let r = self.send(Some(51), Some(51), &[]);
        assert_eq!(r[0], 0x68, "a response PDU: {r:02X?}");
        r[9..r.len() - 2].to_vec()
    }

    /// The DP-V1 task: process_acyclic over the card's records with the mailbox-backed
    /// parameters.
    pub(crate) fn acyclic(&mut self) {
        let now = self.now;
        self.node.process_acyclic(now, &mut self.app.records(now));
    }

    /// DS_Write `req` to record 47 (checking the write response).
    pub(crate) fn write47(&mut self, req: &[u8]) {
        let n = req.len() as u8;
        assert_eq!(self.c1(&[&[0x5F, 0, 47, n][..], req].concat()), [0x5F, 0, 47, n]);
    }

    /// DS_Read record 47: the parameter response, or the DP-V1 error PDU.
    pub(crate) fn read47(&mut self) -> Vec<u8> {
        let r = self.c1(&[0x5E, 0, 47, 240]);
        if r[0] == 0x5E {
            assert_eq!(r[3] as usize, r.len() - 4);
            r[4..].to_vec()
        } else {
            r
        }
    }

    pub(crate) fn requests(&self) -> u32 {
        self.app.link().mailbox().stats().requests
    }

    /// One Data_Exchange with `outputs`, then a step of `ms`; returns the inputs received.
    pub(crate) fn cycle(&mut self, outputs: &[u8], ms: u64) -> Vec<u8> {
        let r = self.srd(None, outputs);
        self.step(ms);
        r[telegram::pdu_range(r.len(), self.node.slave().input_len())].to_vec()
    }
}

pub(crate) fn words(b: &[u8]) -> Vec<u16> {
    b.chunks(2).map(|w| u16::from_be_bytes([w[0], w[1]])).collect()
}

#[test]
fn split_step_is_the_same_step() {
    let mut a = Bench::new();
    let mut b = Bench::new();
    let mut c = Bench::new();
    for x in [&mut a, &mut b, &mut c] {
        x.bring_up(&card::MODULES[0]);
    }
    for k in 0..40 {
        let q = [0x04, if k < 5 { 0x7E } else { 0x7F }, 0x20, 0x00];
        let ia = a.cycle(&q, 5);
        // The same cycle, the step in three parts.
        let rb = b.srd(None, &q);
        b.now = b.now + Duration::from_millis(5);
        let ev = b.app.step_publish(b.now, &mut b.node);
        b.app.step_drive(b.now);
        b.app.step_collect(b.now, &mut b.node);
        let ib = rb[telegram::pdu_range(rb.len(), b.node.slave().input_len())].to_vec();
        // The firmware's short node locks: a copy of the node, the DPM, drive and profile
        // without it, then the update into the node.
        let rc = c.srd(None, &q);
        c.now = c.now + Duration::from_millis(5);
        let snap = c.app.snapshot(c.now, &mut c.node);
        c.app.publish(&snap);
        c.app.step_drive(c.now);
        let update = c.app.collect(c.now, &snap);
        c.app.apply(&mut c.node, &update);
        let ic = rc[telegram::pdu_range(rc.len(), c.node.slave().input_len())].to_vec();
        assert_eq!(ev, snap.events);
        assert_eq!(ia, ib);
        assert_eq!(ia, ic);
    }
    assert_eq!(a.app.profidrive_state(), Some(DriveState::Operation));
    for x in [&b, &c] {
        assert_eq!(a.app.profidrive_state(), x.app.profidrive_state());
        assert_eq!(a.app.dpm().as_bytes()[..], x.app.dpm().as_bytes()[..]);
        assert_eq!(a.node.slave().inputs(), x.node.slave().inputs());
    }
}

/// An update made for one telegram is not served after the master configured another
/// one between the copy and the update (a Chk_Cfg while the step ran unlocked).
#[test]
fn an_update_for_an_old_telegram_is_dropped() {
    let mut b = Bench::new();
    b.bring_up(&card::MODULES[0]);
    for _ in 0..3 {
        b.cycle(&[0x04, 0x7E, 0x20, 0x00], 5);
    }
    b.now = b.now + Duration::from_millis(5);
    let snap = b.app.snapshot(b.now, &mut b.node);
    b.app.publish(&snap);
    b.app.step_drive(b.now);
    let update = b.app.collect(b.now, &snap);
    assert_eq!(update.telegram(), Telegram::Standard(1));
    assert!(update.inputs().is_some_and(|i| i.len() == 4));
    // Meanwhile: Set_Prm + Chk_Cfg for PPO 1 (the slave leaves data exchange).
    let ppo1 = card::MODULES.iter().find(|m| m.reference == 101).unwrap();
    b.bring_up(ppo1);
    let before = b.node.slave().inputs().to_vec();
    b.app.apply(&mut b.node, &update);
    assert_eq!(b.node.slave().inputs(), &before[..], "the ST1 image is not served to PPO 1");
}

/// The card's profile layer builds the input image; an INPUTS block the host writes
/// (layout 2 style) is not handed to the slave, not even for one cycle.
#[test]
fn the_profile_is_the_only_input_path() {
    let mut b = Bench::new();
    b.bring_up(&card::MODULES[0]);
    for _ in 0..3 {
        b.cycle(&[0x04, 0x7E, 0x20, 0x00], 5);
    }
    let profile = b.node.slave().inputs().to_vec();
    assert_eq!(words(&profile)[0] & 0x0277, 0x0231, "S2 from the profile layer");
    for _ in 0..3 {
        let raw = ProcessData::new(Telegram::Standard(1), PdFlags::empty(), &[0xDE, 0xAD, 0xBE, 0xEF]);
        b.app.dpm_mut().host().write_inputs(&raw);
        b.now = b.now + Duration::from_millis(1);
        let snap = b.app.snapshot(b.now, &mut b.node);
        b.app.publish(&snap);
        let update = b.app.collect(b.now, &snap);
        assert_eq!(update.inputs(), Some(&profile[..]));
        b.app.apply(&mut b.node, &update);
        assert_eq!(b.node.slave().inputs(), &profile[..]);
    }
    assert_eq!(b.app.link().stats().inputs_taken, 0);
}

/// STATUS.CORRUPT_FRAMES: the platform's line errors, plus telegrams the FDL station
/// found invalid (a DMA receiver hands whole telegrams with their checksum unchecked).
#[test]
fn corrupt_frames_come_from_the_line_and_the_station() {
    use crate::phy::line::Receiver;
    let mut b = Bench::new();
    b.bring_up(&card::MODULES[0]);
    b.step(1);
    assert_eq!(b.app.dpm().status().unwrap().corrupt_frames, 0);
    // The line: one segment with a character error, one truncated, one of garbage.
    let mut rx = Receiver::new();
    rx.on_tsyn();
    let hdr = Header { da: SLAVE, sa: MASTER, fc: FunctionCode::request(0xD, true, true), dsap: None, ssap: None };
    let mut buf = [0u8; telegram::MAX_FRAME_LEN];
    let len = telegram::emit(&mut buf, &hdr, &[0x04, 0x7E, 0x20, 0x00]).unwrap();
    let good = buf[..len].to_vec();
    rx.segment(&good, true, |_| {});
    rx.on_tsyn();
    rx.segment(&good[..good.len() - 1], false, |_| {});
    rx.on_tsyn();
    rx.segment(&[0x00, 0x01], false, |_| {});
    rx.on_tsyn();
    // A whole telegram with a bad checksum reaches the node (the receiver cuts by length).
    let mut bad = good.clone();
    let n = bad.len();
    bad[n - 2] ^= 0x01;
    let mut frames = Vec::new();
    rx.segment(&bad, false, |f| frames.push(f.to_vec()));
    assert_eq!(frames.len(), 1);
    assert!(b.node.on_frame(b.now, &frames[0]).is_none(), "no answer to a corrupt telegram");
    assert_eq!(rx.stats().lost_frames(), 3);
    b.app.link_mut().set_line_errors(rx.stats().lost_frames());
    b.step(1);
    assert_eq!(b.app.dpm().status().unwrap().corrupt_frames, 4);
    // Wraps at 16 bits in the block.
    b.app.link_mut().set_line_errors(0xFFFF);
    b.step(1);
    assert_eq!(b.app.dpm().status().unwrap().corrupt_frames, 0);
}

#[test]
fn fail_safe_clears_outputs_and_raises_the_card_fault_event() {
    use crate::dpm::{CardEvent, CardFlags};
    let mut b = Bench::new();
    b.bring_up(&card::MODULES[0]);
    b.cycle(&[0x04, 0x7F, 0x30, 0x00], 5);
    let out = b.app.dpm().outputs().unwrap();
    assert!(out.bytes().iter().any(|&x| x != 0));
    let before = b.app.dpm().card_report().unwrap().events[CardEvent::CardFault as usize];
    b.app.fail_safe();
    let out = b.app.dpm().outputs().unwrap();
    assert!(out.bytes().iter().all(|&x| x == 0), "outputs cleared: {:02X?}", out.bytes());
    assert!(!out.flags.contains(PdFlags::DATA_EXCHANGE));
    let r = b.app.dpm().card_report().unwrap();
    assert_eq!(r.events[CardEvent::CardFault as usize], before.wrapping_add(1));
    assert!(r.flags.contains(CardFlags::CARD_FAULT));
    // After the reset: a fresh image shows the event once more, P0740 is not stuck.
    let mut fresh = Bench::new();
    fresh.app.report_recovered_fault();
    fresh.step(1);
    let r = fresh.app.dpm().card_report().unwrap();
    assert_eq!(r.events[CardEvent::CardFault as usize], 1);
    assert!(!r.flags.contains(CardFlags::CARD_FAULT));
    assert_ne!(fresh.app.dpm().status().unwrap().comm, CommState::InitError);
}

/// The simulated drive reaches the image only through SPI frames (issue 7: the in-process
/// transport uses the same frames as the board).
#[test]
fn the_drive_runs_over_spi_frames() {
    let mut b = Bench::new();
    b.bring_up(&card::MODULES[0]);
    let before = b.app.host().transport().bus().slave().stats();
    b.cycle(&[0x04, 0x7E, 0x20, 0x00], 5);
    let after = b.app.host().transport().bus().slave().stats();
    assert!(after.frames_ok > before.frames_ok, "frames moved in the step");
    assert_eq!(after.refused(), 0);
    assert_eq!(b.app.host().transport().retried(), 0);
    assert!(b.app.simulates_drive());
}

/// Card-only mode: no simulated drive writes the host blocks; the drive's heartbeat never
/// starts, so the master reads zeros until a real drive writes INPUTS.
#[test]
fn card_only_leaves_the_host_blocks_to_the_spi_master() {
    let mut b = Bench::new();
    b.app = Application::card_only();
    b.app.set_baudrate(Some(Baudrate::B1500k));
    assert!(!b.app.simulates_drive());
    // Only `Host::open` (header, the host blocks' counters) used the frames.
    let opened = b.app.host().transport().bus().slave().stats().frames_ok;
    b.bring_up(&card::MODULES[0]);
    let mut i = vec![];
    for _ in 0..5 {
        i = b.cycle(&[0x04, 0x7E, 0x20, 0x00], 5);
    }
    assert_eq!(b.app.host().transport().bus().slave().stats().frames_ok, opened, "no host frames");
    assert_eq!(b.app.dpm().drive_state().unwrap().0, 0, "DRIVE_STATE never written");
    assert_eq!(b.app.dpm().inputs().unwrap().seq, 0, "INPUTS never written");
    assert_eq!(b.app.drive().stats().steps, 0);
    assert_eq!(words(&i)[1], 0);
}

/// Issue 16 item 4: a layout 1 / 2 host's raw INPUTS reach the master until the host
/// writes DRIVE_STATE once; from then on the profile layer's image is the only one.
#[test]
fn raw_inputs_are_served_until_drive_state_is_written() {
    let mut b = Bench::new();
    b.app = Application::card_only();
    b.app.set_baudrate(Some(Baudrate::B1500k));
    b.app.dpm_mut().host().write_config(&crate::dpm::HostConfig::DEFAULT);
    b.step(1);
    b.bring_up(&card::MODULES[0]);
    let raw = ProcessData::new(Telegram::Standard(1), PdFlags::empty(), &[0x12, 0x34, 0x56, 0x78]);
    b.app.dpm_mut().host().write_inputs(&raw);
    b.cycle(&[0x04, 0x7E, 0x20, 0x00], 1);
    let i = b.cycle(&[0x04, 0x7E, 0x20, 0x00], 1);
    assert_eq!(i, [0x12, 0x34, 0x56, 0x78], "the raw INPUTS are served");
    b.app.dpm_mut().host().write_drive_state(&crate::dpm::DriveStateImage::EMPTY);
    b.app.dpm_mut().host().write_inputs(&raw);
    b.cycle(&[0x04, 0x7E, 0x20, 0x00], 1);
    let i = b.cycle(&[0x04, 0x7E, 0x20, 0x00], 1);
    assert_ne!(i, [0x12, 0x34, 0x56, 0x78], "DRIVE_STATE written: INPUTS ignored");
}

#[test]
fn size_stays_small() {
    // DPM image 752 B (layout 4) with the host's state, last status, outputs, drive
    // report, command, drive state and a mailbox answer in the link, two parameter caches
    // (record 47 and PKW, 8 mailbox answers each, ≈ 1.1 KiB each), the profile layer
    // (last cycle, PKW server, fault buffer) and the drive's parameter table, plus the SPI
    // frame transport of the drive's host (the host's MOSI and MISO buffers and the
    // loopback card's two reply buffers of its pipeline, one longest transaction of
    // 1034 B each, ≈ 4.1 KiB): a static in the firmware. The simulated drive's VACON
    // application-ID table (PNU 10001, the PPO PKW) adds ≈ 0.1 KiB, the speed-reference
    // reader (issue 15 item 10) ≈ 40 B; the host's mailbox fragments of the CYCLIC
    // exchange (a request being assembled from fragments, a response on its way, issue 16)
    // ≈ 0.5 KiB; the simulated drive's last DRIVE_STATE (sent again by the first of its two
    // CYCLIC exchanges a cycle) ≈ 60 B. The card's data records (records 47 / 48: the
    // job, the response being built and one response per relation, 240 B each, with the
    // card's values for its PNUs, ≈ 1.3 KiB) moved here from the node. The product's
    // configuration as data (issue 13: the records' slots and PNU 964, the link's GSD
    // modules) ≈ 40 B of references.
    let n = core::mem::size_of::<Application>();
    let records = core::mem::size_of::<CardRecords>();
    assert!(records <= 1408, "CardRecords is {records} bytes");
    assert!(
        n <= 4608 + 4 * crate::dpm::spi::MAX_TRANSACTION + 384 + 256 + 64 + 520 + 64 + 40 + records,
        "Application is {n} bytes"
    );
    // The shipped card: no SPI frame transport, no simulated drive, no host state.
    let c = core::mem::size_of::<Card>();
    assert!(c + 4 * crate::dpm::spi::MAX_TRANSACTION < n, "Card is {c} bytes");
}

/// Issue 13 item 1: the shipped card ([`Card::new`], its own image) is the card of the
/// bench's card-only mode — the same responses and input images, the same blocks of the
/// card's side (STATUS, OUTPUTS, DRIVE_CMD, CARD) for the same drive writes.
#[test]
fn the_card_alone_is_the_card_of_the_bench() {
    use crate::dpm::{DriveStateImage, HostConfig};
    let mut b = Bench::new();
    b.app = Application::card_only();
    b.app.set_baudrate(Some(Baudrate::B1500k));
    let mut card = Card::new();
    card.set_baudrate(Some(Baudrate::B1500k));
    let mut node = crate::card::node(DpSlave::new(&card::SLAVE, SLAVE));
    let mut fcb = false;
    let mut now = Instant::from_millis(0);
    // One request to both nodes, a step of `ms` on both; the responses must agree.
    let mut both = |b: &mut Bench, card: &mut Card, node: &mut Node, dsap: Option<u8>, pdu: &[u8], ms: u64| {
        fcb = !fcb;
        let fc = FunctionCode::request(0xD, fcb, true);
        let hdr = Header { da: SLAVE, sa: MASTER, fc, dsap, ssap: dsap.map(|_| 62) };
        let mut buf = [0u8; telegram::MAX_FRAME_LEN];
        let n = telegram::emit(&mut buf, &hdr, pdu).unwrap();
        let (mut ra, mut rb) = (None, None);
        for &x in &buf[..n] {
            ra = b.node.on_byte(now, x).map(|r| r.to_vec()).or(ra);
            rb = node.on_byte(now, x).map(|r| r.to_vec()).or(rb);
        }
        assert_eq!(ra, rb, "the same response");
        now = now + Duration::from_millis(ms);
        b.now = now;
        let ea = b.app.step(now, &mut b.node);
        let eb = card.step(now, node);
        assert_eq!(ea, eb, "the same events");
        assert_eq!(b.node.slave().inputs(), node.slave().inputs(), "the same input image");
        assert_eq!(b.node.slave().state(), node.slave().state());
        ra.unwrap_or_default()
    };
    // The drive's control board: CONFIG (the start-up gate opens), then its state.
    for dpm in [b.app.dpm_mut(), card.dpm_mut()] {
        dpm.host().write_config(&HostConfig::DEFAULT);
    }
    both(&mut b, &mut card, &mut node, None, &[], 1);
    let mut prm = vec![0x88, 1, 100, 11, (card::IDENT_NUMBER >> 8) as u8, card::IDENT_NUMBER as u8, 0];
    prm.extend_from_slice(&card::USER_PRM_DEFAULTS);
    assert_eq!(both(&mut b, &mut card, &mut node, Some(61), &prm, 1), [telegram::SC]);
    assert_eq!(both(&mut b, &mut card, &mut node, Some(62), card::MODULES[0].cfg, 1), [telegram::SC]);
    assert_eq!(node.slave().state(), DpState::DataExch);
    for k in 0..20u16 {
        if k == 5 {
            for dpm in [b.app.dpm_mut(), card.dpm_mut()] {
                dpm.host().write_drive_state(&DriveStateImage::EMPTY);
            }
        }
        let q = [0x04, if k < 10 { 0x7E } else { 0x7F }, 0x20, k as u8];
        both(&mut b, &mut card, &mut node, None, &q, 2);
    }
    let (x, y) = (b.app.dpm(), card.dpm());
    assert_eq!(x.status(), y.status());
    assert_eq!(x.outputs(), y.outputs());
    assert_eq!(x.drive_command(), y.drive_command());
    assert_eq!(x.card_report(), y.card_report());
    assert_eq!(b.app.profidrive_state(), card.profidrive_state());
    assert_eq!(b.app.link().stats(), card.link().stats());
}

#[test]
fn status_block_follows_the_bring_up() {
    let mut b = Bench::new();
    assert_eq!(b.app.dpm().status().unwrap().comm, CommState::Inactive);
    b.step(1);
    let s = b.app.dpm().status().unwrap();
    assert_eq!((s.comm, s.baud, s.station_address, s.master_address), (CommState::Offline, 6, SLAVE, None));
    b.bring_up(&card::MODULES[0]);
    let s = b.app.dpm().status().unwrap();
    assert_eq!(s.comm, CommState::Online);
    assert_eq!(s.master_address, Some(MASTER));
    assert_eq!(s.telegram, Telegram::Standard(1));
    assert_eq!(s.watchdog_ms, 1000);
    // A Chk_Cfg that matches no module: P0740 "configuration data error".
    assert_eq!(b.srd(Some(62), &[0xF3, 0xF3]), [telegram::SC]);
    b.step(1);
    assert_eq!(b.app.dpm().status().unwrap().comm, CommState::ConfigError);
}

#[test]
fn st1_047e_047f_runs_and_ramps() {
    let mut b = Bench::new();
    b.bring_up(&card::MODULES[0]);
    let sp = 0x2000u16; // 50 %
    let mut q = [0x04, 0x7E, (sp >> 8) as u8, sp as u8];
    for _ in 0..3 {
        b.cycle(&q, 5);
    }
    assert_eq!(b.app.profidrive_state().unwrap(), DriveState::ReadyToSwitchOn);
    let i = b.cycle(&q, 5);
    assert_eq!(words(&i)[0] & 0x0277, 0x0231, "S2: b0, b4, b5, b9 (got {:04X})", words(&i)[0]);
    q[1] = 0x7F;
    let mut last = 0i16;
    let mut rising = 0;
    for _ in 0..150 {
        let i = b.cycle(&q, 5);
        let n = words(&i)[1] as i16;
        assert!(n >= last, "speed must not fall while ramping up");
        rising += (n > last) as u32;
        last = n;
    }
    assert!(rising > 50, "the speed ramps in many steps");
    // 50 % at 1 s per 100 % is reached after 500 ms.
    assert_eq!(last, sp as i16);
    let z = words(&b.cycle(&q, 5))[0];
    assert_eq!(z & 0x0107, 0x0107, "S4 and at setpoint (ZSW1 {z:04X})");
    // 0x047E: ramp stop to standstill, then S2.
    q[1] = 0x7E;
    b.cycle(&q, 5);
    assert_eq!(b.app.profidrive_state().unwrap(), DriveState::SwitchingOff(StopKind::Ramp));
    for _ in 0..120 {
        b.cycle(&q, 5);
    }
    assert_eq!(b.app.profidrive_state().unwrap(), DriveState::ReadyToSwitchOn);
    assert_eq!(b.app.drive().actual_speed(), 0);
}

/// P0799-style I/O update delay from the drive's CONFIG.IO_UPDATE_DELAY (CFW-11 manual):
/// after going online the drive keeps its previous command (none at power-up) for the
/// delay, then the newest outputs apply; the master's inputs stay live meanwhile.
#[test]
fn the_drives_io_update_delay_holds_the_outputs_after_going_online() {
    use crate::dpm::HostConfig;
    let mut b = Bench::new();
    let cfg = HostConfig { io_update_delay: 5, ..HostConfig::DEFAULT }; // 0.5 s
    b.app.host_mut().write_config(&cfg).unwrap();
    b.step(1);
    b.step(1);
    assert_eq!(b.app.link().config().map(|c| c.io_update_delay), Some(5), "taken over outside DX");
    b.bring_up(&card::MODULES[0]);
    let q = [0x04, 0x7E, 0x20, 0x00];
    let mut held = 0;
    for _ in 0..90 {
        let i = b.cycle(&q, 5); // 450 ms
        assert_ne!(words(&i)[0], 0, "the inputs are live during the delay (ZSW1)");
        assert!(!b.app.drive().command().flags.contains(CommandFlags::FIELDBUS_CONTROL), "held");
        held += 1;
    }
    assert_eq!(held, 90);
    for _ in 0..20 {
        b.cycle(&q, 5); // past 500 ms
    }
    assert!(
        b.app.drive().command().flags.contains(CommandFlags::FIELDBUS_CONTROL),
        "the master's STW1 (b10 control by PLC) reaches the drive after the delay"
    );
    assert_eq!(b.app.profidrive_state(), Some(DriveState::ReadyToSwitchOn));
}

#[cfg(not(feature = "bench"))] // the bench-only modules are no GSD telegram
#[test]
fn ppo_types_answer_after_the_pkw() {
    for m in card::MODULES.iter().filter(|m| m.reference > 100) {
        let mut b = Bench::new();
        b.bring_up(m);
        let t = Telegram::of_module(m).unwrap();
        let pkw = t.pkw_words();
        let mut q = vec![0u8; m.outputs as usize];
        for (i, w) in q.chunks_mut(2).enumerate().skip(pkw) {
            w.copy_from_slice(&(0x1100 + i as u16).to_be_bytes());
        }
        q[2 * pkw..2 * pkw + 4].copy_from_slice(&[0x04, 0x7E, 0x40, 0x00]);
        let mut i = vec![];
        for _ in 0..3 {
            i = b.cycle(&q, 5);
        }
        let w = words(&i);
        assert_eq!(w.len(), m.inputs as usize / 2, "{}", m.name);
        assert!(w[..pkw].iter().all(|&x| x == 0), "{}: PKW answered with zeros", m.name);
        if b.app.profidrive_state().is_some() {
            assert_eq!(w[pkw] & 0x0277, 0x0231, "{}: ZSW in S2", m.name);
        } else {
            // WEG manufacturer profile / INVT: the profile's own status word.
            let p = b.app.runtime().profile().unwrap();
            assert_eq!(w[pkw], p.status_word(b.app.drive().status()), "{}: status word", m.name);
        }
        assert_eq!(w[pkw + 1], 0, "{}: HIW at standstill", m.name);
        for (k, &x) in w.iter().enumerate().skip(pkw + 2) {
            assert_eq!(x, 0x1100 + k as u16, "{}: PZD{} echoed", m.name, k - pkw + 1);
        }
    }
}

/// The PKW channel of PPO 1 end to end: the request goes through the PKW server and the
/// DPM mailbox to the drive's table; the response is repeated until the request changes
/// (VACON PKW, OPTE3/E5 §6.6.2: type 1 read word → type 1 value; type 2 write → type 1
/// with value 0, Table 130; the PNU is the drive's application ID).
#[cfg(not(feature = "bench"))]
#[test]
fn ppo1_pkw_reads_and_writes_a_drive_parameter() {
    let m = card::MODULES.iter().find(|m| m.reference == 101).unwrap();
    let mut b = Bench::new();
    b.bring_up(m);
    let mut q = [0u8; 12];
    q[..8].copy_from_slice(&[0x10, 103, 0, 0, 0, 0, 0, 0]); // read ID 103
    q[8..].copy_from_slice(&[0x04, 0x7E, 0, 0]);
    let mut i = vec![];
    for _ in 0..6 {
        i = b.cycle(&q, 2);
    }
    assert_eq!(&words(&i)[..4], &[0x1067, 0, 0, 30], "ID 103 = 30 (3.0 s)");
    // Write ID 103 = 85 (type 2), then the response is held while the request stays.
    q[..8].copy_from_slice(&[0x20, 103, 0, 0, 0, 0, 0, 85]);
    for _ in 0..6 {
        i = b.cycle(&q, 2);
    }
    assert_eq!(&words(&i)[..4], &[0x1067, 0, 0, 0], "Table 130: type 1, value 0");
    assert_eq!(b.app.drive().vacon_ids().get(103, 0), Some(85));
    let requests = b.requests();
    for _ in 0..5 {
        i = b.cycle(&q, 2);
    }
    assert_eq!(&words(&i)[..4], &[0x1067, 0, 0, 0], "held");
    assert_eq!(b.requests(), requests, "executed once");
    // Unknown ID 999: type 7 with fault code 0 (Table 122: illegal parameter).
    q[..8].copy_from_slice(&[0x13, 0xE7, 0, 0, 0, 0, 0, 0]);
    for _ in 0..6 {
        i = b.cycle(&q, 2);
    }
    assert_eq!(&words(&i)[..4], &[0x73E7, 0, 0, 0]);
}

#[test]
fn watchdog_expiry_faults_a_running_drive() {
    let mut b = Bench::new();
    b.bring_up(&card::MODULES[0]);
    for q in [[0x04, 0x7E, 0x20, 0x00], [0x04, 0x7F, 0x20, 0x00]] {
        for _ in 0..3 {
            b.cycle(&q, 5);
        }
    }
    assert_eq!(b.app.profidrive_state().unwrap(), DriveState::Operation);
    let ev = b.step(2000);
    assert!(ev.contains(Events::WATCHDOG_EXPIRED));
    b.step(1);
    assert_eq!(b.app.profidrive_state().unwrap(), DriveState::Fault);
    assert_eq!(b.app.dpm().status().unwrap().comm, CommState::Offline);
    assert_eq!(b.app.dpm().status().unwrap().watchdog_expiries, 1);
}

const STATE_CONFLICT: [u8; 4] = [0xDE, 0x80, 0xB5, 0x00];

#[test]
fn drive_parameter_is_read_through_the_mailbox() {
    let mut b = Bench::new();
    b.bring_up_with(&card::MODULES[0], 0x80);
    // Read P100 (the drive's, default 50): sent through the mailbox, pending meanwhile.
    b.write47(&[1, 1, 1, 1, 0x10, 1, 0, 100, 0, 0]);
    assert!(b.node.has_acyclic_work(), "the job waits for the drive");
    assert_eq!(b.read47(), STATE_CONFLICT);
    assert_eq!(b.requests(), 1);
    // The drive serves the mailbox in the step; the next DP-V1 pass completes the job.
    b.step(1);
    assert_eq!(b.read47(), [1, 1, 1, 1, 0x42, 1, 0, 50]);
    assert!(!b.node.has_acyclic_work());
    // A card PNU (918, station address) with a drive PNU in one request.
    b.write47(&[2, 1, 1, 2, 0x10, 1, 0x03, 0x96, 0, 0, 0x10, 1, 0, 101, 0, 0]);
    assert_eq!(b.read47(), STATE_CONFLICT);
    b.step(1);
    assert_eq!(b.read47(), [2, 1, 1, 2, 0x42, 1, 0, SLAVE, 0x42, 1, 0, 50]);
    // The drive's own errors come back as they are: unknown PNU 0x00.
    b.write47(&[3, 1, 1, 1, 0x10, 1, 0x27, 0x0F, 0, 0]);
    b.step(1);
    assert_eq!(b.read47(), [3, 0x81, 1, 1, 0x44, 1, 0, 0x00]);
}

#[test]
fn a_drive_that_never_answers_gives_error_0x11_after_the_timeout() {
    let mut b = Bench::new();
    b.bring_up_with(&card::MODULES[0], 0x80);
    b.app.set_serve_parameters(false);
    b.write47(&[4, 1, 1, 1, 0x10, 1, 0, 100, 0, 0]);
    for _ in 0..4 {
        b.step(100);
        assert_eq!(b.read47(), STATE_CONFLICT, "still within the mailbox timeout");
    }
    b.step(150);
    assert_eq!(b.read47(), [4, 0x81, 1, 1, 0x44, 2, 0, 0x11, 0xDD, 0x01]);
    assert!(!b.node.has_acyclic_work(), "never a hang");
    // The drive comes back and answers late: ignored; the next job gets its own answer.
    b.app.set_serve_parameters(true);
    b.step(1);
    assert_eq!(b.app.link().mailbox().stats().late_responses, 1);
    b.write47(&[5, 1, 1, 1, 0x10, 1, 0, 101, 0, 0]);
    assert_eq!(b.read47(), STATE_CONFLICT);
    b.step(1);
    assert_eq!(b.read47(), [5, 1, 1, 1, 0x42, 1, 0, 50]);
}

#[test]
fn a_write_reaches_the_drive_once_per_job() {
    let mut b = Bench::new();
    b.bring_up_with(&card::MODULES[0], 0x80);
    // Change P100 = 85 and P101 = 70: two mailbox requests, one after the other.
    b.write47(&[6, 2, 1, 2, 0x10, 1, 0, 100, 0, 0, 0x10, 1, 0, 101, 0, 0, 0x42, 1, 0, 85, 0x42, 1, 0, 70]);
    for _ in 0..3 {
        b.acyclic();
        assert_eq!(b.requests(), 1, "retries do not send the write again");
    }
    b.step(1);
    assert_eq!(b.app.drive_params().get(100, 0), Some(85));
    assert_eq!(b.read47(), STATE_CONFLICT, "P101 is on its way");
    assert_eq!(b.requests(), 2);
    b.acyclic();
    b.step(1);
    assert_eq!(b.read47(), [6, 2, 1, 2]);
    assert_eq!(b.app.drive_params().get(101, 0), Some(70));
    for _ in 0..3 {
        b.acyclic();
        b.step(1);
    }
    assert_eq!(b.requests(), 2, "each write executed once");
    // A new job with the same write sends it again.
    b.write47(&[7, 2, 1, 1, 0x10, 1, 0, 100, 0, 0, 0x42, 1, 0, 85]);
    b.step(1);
    assert_eq!(b.read47(), [7, 2, 1, 1]);
    assert_eq!(b.requests(), 3);
}

/// Set_Prm with DPV1_Status_1..3 `dpv1`, Chk_Cfg of `module`: data exchange.
fn bring_up_dpv1(b: &mut Bench, module: &card::Module, dpv1: [u8; 3]) {
    let mut prm = vec![0x88, 1, 100, 11, (card::IDENT_NUMBER >> 8) as u8, card::IDENT_NUMBER as u8, 0];
    prm.extend_from_slice(&card::USER_PRM_DEFAULTS);
    prm[7..10].copy_from_slice(&dpv1);
    assert_eq!(b.srd(Some(61), &prm), [telegram::SC]);
    b.step(1);
    assert_eq!(b.srd(Some(62), module.cfg), [telegram::SC]);
    b.step(1);
    assert_eq!(b.node.slave().state(), DpState::DataExch);
}

/// Slave_Diag: (Station_Status_1, the extended diagnosis after the 6 octets).
fn diag(b: &mut Bench) -> (u8, Vec<u8>) {
    let r = b.srd(Some(60), &[]);
    // SD2 (68 LE LEr 68 DA SA FC DSAP SSAP …) or SD3 for 8 data bytes (A2 DA SA FC …).
    let start = if r[0] == telegram::SD2 { 9 } else { 6 };
    let d = &r[start..r.len() - 2];
    (d[0], d[6..].to_vec())
}

/// The FC byte of a Data_Exchange answer with `outputs` (DL 0x08 / DH 0x0A), then a step.
fn dx_fc(b: &mut Bench, outputs: &[u8]) -> u8 {
    let r = b.srd(None, outputs);
    b.step(2);
    if r[0] == telegram::SD2 {
        r[6]
    } else {
        r[3]
    }
}

const EXT_DIAG: u8 = 0x08;
const DL: u8 = 0x08;
const DH: u8 = 0x0A;

/// Issue 12 item 2: without DPV1_Enable the vendor block `03 bits value` stays; with it the
/// device-related block is a DP-V1 Status_Message `06 81 00 00 bits value`; Ext_Diag only
/// for a fault, never for a warning alone.
#[test]
fn diagnosis_format_and_ext_diag_only_for_faults() {
    for dpv1 in [false, true] {
        let mut b = Bench::new();
        bring_up_dpv1(&mut b, &card::MODULES[0], [if dpv1 { 0x80 } else { 0 }, 0, 0]);
        let run = [0x04, 0x7E, 0x00, 0x00];
        b.cycle(&run, 2);
        assert_eq!(diag(&mut b), (0, vec![]), "nothing to report");
        b.app.drive_mut().model_mut().set_warning(0x0102);
        b.step(2);
        b.step(2);
        assert_eq!(dx_fc(&mut b, &run), DH, "new diagnosis announced");
        let (s1, ext) = diag(&mut b);
        assert_eq!(s1 & EXT_DIAG, 0, "a warning alone: no Ext_Diag (dpv1 {dpv1})");
        let want: &[u8] = if dpv1 { &[0x06, 0x81, 0x00, 0x00, 0x02, 0x00] } else { &[0x03, 0x02, 0x00] };
        assert_eq!(&ext[..], want, "warning block (dpv1 {dpv1})");
        b.app.drive_mut().inject_fault(0x2310, 0);
        b.step(2);
        b.step(2);
        let (s1, ext) = diag(&mut b);
        assert_eq!(s1 & EXT_DIAG, EXT_DIAG, "a fault: Ext_Diag");
        let want: &[u8] = if dpv1 { &[0x06, 0x81, 0x00, 0x00, 0x03, 0x01] } else { &[0x03, 0x03, 0x01] };
        assert_eq!(&ext[..], want, "fault block (dpv1 {dpv1})");
        assert!(b.node.slave().alarms().outstanding().is_empty(), "alarms not enabled");
    }
}

/// Issue 12 item 3: a diagnostic alarm when the drive faults and when the fault clears,
/// announced by DH, carried in Slave_Diag, acknowledged by Alarm_Ack on SAP 51; a wrong
/// acknowledgement gets the DP-V1 error PDU; leaving data exchange drops the alarms.
#[test]
fn diagnostic_alarms_when_the_drive_faults_and_clears() {
    let mut b = Bench::new();
    bring_up_dpv1(&mut b, &card::MODULES[0], [0x80, 0x20, 0x00]);
    let run = [0x04, 0x7E, 0x00, 0x00];
    for _ in 0..3 {
        assert_eq!(dx_fc(&mut b, &run), DL);
    }
    assert_eq!(b.c1(&[0x5C, 0x00, 0x01, 0x01]), [0xDC, 0x80, 0xB5, 0x00], "no alarm outstanding");
    b.app.drive_mut().inject_fault(0x2310, 0);
    b.step(2);
    b.step(2);
    assert_eq!(dx_fc(&mut b, &run), DH, "the alarm is announced");
    let (s1, ext) = diag(&mut b);
    assert_eq!(s1 & EXT_DIAG, EXT_DIAG);
    assert_eq!(ext, [0x06, 0x01, 0x00, 0x01, 0x23, 0x10], "diagnostic alarm, slot 0, Seq_Nr 0, appears, fault 0x2310");
    // Delivered: the next diagnosis carries the status block.
    assert_eq!(diag(&mut b).1, [0x06, 0x81, 0x00, 0x00, 0x01, 0x01]);
    // Wrong acknowledgements: sequence number, alarm type, slot.
    assert_eq!(b.c1(&[0x5C, 0x00, 0x01, 0x09]), [0xDC, 0x80, 0xB5, 0x00]);
    assert_eq!(b.c1(&[0x5C, 0x00, 0x02, 0x01]), [0xDC, 0x80, 0xB5, 0x00]);
    assert_eq!(b.c1(&[0x5C, 0x01, 0x01, 0x01]), [0xDC, 0x80, 0xB2, 0x00]);
    assert_eq!(b.node.slave().alarms().outstanding().len(), 1);
    assert_eq!(b.c1(&[0x5C, 0x00, 0x01, 0x01]), [0x5C, 0x00, 0x01, 0x01], "acknowledged");
    assert!(b.node.slave().alarms().outstanding().is_empty());
    // The master acknowledges the fault (STW1 bit 7): the fault clears → "disappears".
    dx_fc(&mut b, &[0x04, 0xFE, 0x00, 0x00]);
    let mut fc = DL;
    for _ in 0..10 {
        fc = dx_fc(&mut b, &run);
        if fc == DH {
            break;
        }
    }
    assert_eq!(fc, DH);
    let (s1, ext) = diag(&mut b);
    assert_eq!(s1 & EXT_DIAG, 0, "no fault any more");
    assert_eq!(ext, [0x06, 0x01, 0x00, 0x0A, 0x23, 0x10], "Seq_Nr 1, disappears");
    assert_eq!(diag(&mut b).1, Vec::<u8>::new(), "delivered; nothing else to report");
    // A new fault before the ack: held back (Alarm_Mode 0 = one outstanding), then raised
    // after the ack.
    b.app.drive_mut().inject_fault(0x3210, 0);
    b.step(2);
    b.step(2);
    assert_eq!(b.node.slave().alarms().outstanding().len(), 1, "one per type");
    assert_eq!(b.c1(&[0x5C, 0x00, 0x01, 0x0A]), [0x5C, 0x00, 0x01, 0x0A]);
    assert_eq!(dx_fc(&mut b, &run), DH);
    assert_eq!(diag(&mut b).1, [0x06, 0x01, 0x00, 0x11, 0x32, 0x10], "Seq_Nr 2, appears, 0x3210");
    // Leaving data exchange (a new Set_Prm) drops the unacknowledged alarm; the numbering
    // starts again (the drive's fieldbus fault F-code of the interruption is the next one).
    bring_up_dpv1(&mut b, &card::MODULES[0], [0x80, 0x20, 0x00]);
    assert_eq!(b.node.slave().alarms().stats().dropped, 1);
    let fieldbus = crate::drive::model::FAULT_FIELDBUS;
    assert!(b.node.slave().alarms().outstanding().iter().all(|a| a.seq == 0 && a.fault_code == fieldbus));
}

/// Issue 12 item 3: a Set_Prm asking for alarm types the card does not offer is a
/// Prm_Fault; the diagnostic alarm without DPV1_Enable too.
#[test]
fn set_prm_with_alarms_the_card_does_not_offer_is_a_prm_fault() {
    for dpv1 in [[0x80, 0x40, 0], [0x80, 0x80, 0], [0x80, 0x08, 0], [0x80, 0x04, 0], [0x80, 0x10, 0], [0x00, 0x20, 0]] {
        let mut b = Bench::new();
        let mut prm = vec![0x88, 1, 100, 11, (card::IDENT_NUMBER >> 8) as u8, card::IDENT_NUMBER as u8, 0];
        prm.extend_from_slice(&card::USER_PRM_DEFAULTS);
        prm[7..10].copy_from_slice(&dpv1);
        assert_eq!(b.srd(Some(61), &prm), [telegram::SC]);
        b.step(1);
        assert_eq!(diag(&mut b).0 & 0x40, 0x40, "Prm_Fault for {dpv1:02X?}");
        assert_eq!(b.node.slave().state(), DpState::WaitPrm);
    }
}

/// Issue 12 item 1: I&M0 and I&M1 over MSAC_C1 through the shipped card (Node +
/// Application); I&M1 and I&M3 stored in the card's journal (`store::Journal`, the same
/// one as the station address) and back, byte for byte, after a power cycle.
#[test]
fn identification_and_maintenance_through_the_card() {
    use crate::dpv1::im::ImData;
    use crate::store::sim::SimFlash;
    use crate::store::{Journal, StationAddress, SLOT_SIZE};
    let mut journal = Journal::new(SimFlash::<{ 4 * SLOT_SIZE }>::new());
    journal.save(&StationAddress { address: 61, no_add_chg: false }).unwrap();
    let mut b = Bench::new();
    b.bring_up_with(&card::MODULES[0], 0x80);
    assert_eq!(b.c1(&[0x5F, 0x00, 0xFF, 0x04, 0x08, 0x00, 0xFD, 0xE8]), [0x5F, 0x00, 0xFF, 0x04]);
    let r = b.c1(&[0x5E, 0x00, 0xFF, 0xF0]);
    assert_eq!(&r[..8], &[0x5E, 0x00, 0xFF, 68, 0x08, 0x00, 0xFD, 0xE8]);
    assert_eq!(&r[8 + 12..8 + 19], b"ODC-PB1", "ORDER_ID");
    // SERIAL_NUMBER and HARDWARE_REVISION from the drive (DPM DEVICE, the simulated drive's).
    assert_eq!(&r[8 + 32..8 + 48], b"SIM-DRIVE-000001");
    assert_eq!(&r[8 + 48..8 + 50], &[0, 2]);
    assert_eq!(&r[8 + 56..8 + 58], &[0x3A, 0x00], "PROFILE_ID PROFIdrive");
    // I&M1 TAG_FUNCTION + TAG_LOCATION and I&M3 DESCRIPTOR written by the master.
    let mut im1 = vec![0xA5u8; 10]; // the manufacturer header: not kept
    im1.extend_from_slice(b"Conveyor 3 main drive           ");
    im1.extend_from_slice(b"Hall B, cabinet 12    ");
    let w = [&[0x5F, 0x00, 0xFF, 68, 0x08, 0x00, 0xFD, 0xE9][..], &im1].concat();
    assert_eq!(b.c1(&w), [0x5F, 0x00, 0xFF, 68]);
    let mut im3 = vec![0u8; 10];
    im3.extend_from_slice(&[b'd'; 54]);
    let w = [&[0x5F, 0x00, 0xFF, 68, 0x08, 0x00, 0xFD, 0xEB][..], &im3].concat();
    assert_eq!(b.c1(&w), [0x5F, 0x00, 0xFF, 68]);
    // The platform stores what the card reports as changed (the F411's housekeeping, the
    // soft slave's --state file), once.
    let changed = b.node.im_mut().take_changed().expect("I&M1 and I&M3 changed");
    assert_eq!(b.node.im_mut().take_changed(), None);
    assert_eq!(journal.save(&changed), Ok(true));
    // Power cycle: a new card loads I&M1-4 from the journal, the address is untouched.
    let flash = journal.into_inner();
    let journal = Journal::new(flash);
    assert_eq!(journal.load::<StationAddress>(), Some(StationAddress { address: 61, no_add_chg: false }));
    let mut b = Bench::new();
    assert_eq!(b.node.im().data(), &ImData::DEFAULT);
    if let Some(d) = journal.load::<ImData>() {
        b.node.im_mut().set_data(d);
    }
    assert_eq!(b.node.im_mut().take_changed(), None, "restoring is no change");
    b.bring_up_with(&card::MODULES[0], 0x80);
    assert_eq!(b.c1(&[0x5F, 0x00, 0xFF, 0x04, 0x08, 0x00, 0xFD, 0xE9]), [0x5F, 0x00, 0xFF, 0x04]);
    let r = b.c1(&[0x5E, 0x00, 0xFF, 0xF0]);
    assert_eq!(&r[..8], &[0x5E, 0x00, 0xFF, 68, 0x08, 0x00, 0xFD, 0xE9]);
    assert_eq!(&r[8..18], &[0; 10], "header zeros");
    assert_eq!(&r[18..], &im1[10..], "I&M1 byte for byte");
    assert_eq!(b.c1(&[0x5F, 0x00, 0xFF, 0x04, 0x08, 0x00, 0xFD, 0xEB]), [0x5F, 0x00, 0xFF, 0x04]);
    let r = b.c1(&[0x5E, 0x00, 0xFF, 0xF0]);
    assert_eq!(&r[8 + 10..], &[b'd'; 54]);
}

/// Issue 6 item 5: SYNC / FREEZE / Clear / watchdog on live data through the whole card
/// (DP slave → profile layer → DPM → simulated drive and back), one module of each family
/// (CFW500 §5.1.2 SYNC/FREEZE, §6 A138 / A139 with P0313).
mod process_data_semantics {
    use super::*;
    use crate::dpm::CardEvent;
    use crate::drive::model::{CommLossAction, FAULT_OFFLINE};
    use crate::drive::CommAlarms;

    /// Global_Control commands (reference §3.6).
    const GC_SYNC: u8 = 0x20;
    const GC_UNSYNC: u8 = 0x10;
    const GC_FREEZE: u8 = 0x08;
    const GC_UNFREEZE: u8 = 0x04;
    const GC_CLEAR: u8 = 0x02;

    /// One module per family: ST1, ST20, VACON 138, PPO 5, WEG CFW500 105, CFW-11 103, INVT.
    fn family_modules() -> Vec<&'static card::Module> {
        [1u16, 20, 1138, 105, 2105, 3103, 4001]
            .iter()
            .map(|r| card::MODULES.iter().find(|m| m.reference == *r).expect("module in the GSD"))
            .collect()
    }

    /// The control words of the module's profile: (switch-on sequence, run, stop).
    fn control_words(m: &card::Module) -> (Vec<u16>, u16, u16) {
        match Telegram::of_module(m).unwrap() {
            Telegram::Vendor(crate::dpm::Family::Invt, _) => (vec![], 0x0001, 0x0005),
            // WEG manufacturer profile (P0741 = 1, the drive's factory setting): P0684
            // b0 run, b1 general enable, b2 forward, b4 remote.
            Telegram::Vendor(crate::dpm::Family::WegCfw500 | crate::dpm::Family::WegCfw11, _) => {
                (vec![], 0x0017, 0x0016)
            }
            _ => (vec![0x047E; 3], 0x047F, 0x047E),
        }
    }

    fn image(m: &card::Module, cw: u16, sp: u16) -> Vec<u8> {
        let pkw = Telegram::of_module(m).unwrap().pkw_words();
        let mut q = vec![0u8; m.outputs as usize];
        q[2 * pkw..2 * pkw + 2].copy_from_slice(&cw.to_be_bytes());
        q[2 * pkw + 2..2 * pkw + 4].copy_from_slice(&sp.to_be_bytes());
        q
    }

    /// A setpoint word of `percent` % in the module's profile scale.
    fn setpoint(m: &card::Module, percent: u32) -> u16 {
        let full = match Telegram::of_module(m).unwrap() {
            Telegram::Ppo(_) => 10_000,
            Telegram::Vendor(crate::dpm::Family::Invt, _) => 5000,
            Telegram::Vendor(crate::dpm::Family::WegCfw500 | crate::dpm::Family::WegCfw11, _) => 8192,
            _ => 0x4000,
        };
        (full * percent / 100) as u16
    }

    fn actual(m: &card::Module, inputs: &[u8]) -> u16 {
        let pkw = Telegram::of_module(m).unwrap().pkw_words();
        words(inputs)[pkw + 1]
    }

    impl Bench {
        /// Set_Prm with Sync_Req and Freeze_Req (and the watchdog, 1 s), Chk_Cfg.
        pub(in crate::bench::tests) fn bring_up_sync_freeze(&mut self, m: &card::Module) {
            let mut prm = vec![0xB8, 1, 100, 11, (card::IDENT_NUMBER >> 8) as u8, card::IDENT_NUMBER as u8, 0];
            prm.extend_from_slice(&card::USER_PRM_DEFAULTS);
            assert_eq!(self.srd(Some(61), &prm), [telegram::SC]);
            self.step(1);
            assert_eq!(self.srd(Some(62), m.cfg), [telegram::SC]);
            self.step(1);
            assert_eq!(self.node.slave().state(), DpState::DataExch, "{}", m.name);
        }

        /// Global_Control `command` to group 0 (SDN to SAP 58), then a step.
        fn global_control(&mut self, command: u8) {
            self.gc(command, 0x00);
            self.step(1);
        }

        /// Switch on and run at `percent` % until the drive is there.
        fn run_at(&mut self, m: &card::Module, percent: u32) {
            let (on, run, _) = control_words(m);
            let sp = setpoint(m, percent);
            for cw in on {
                self.cycle(&image(m, cw, sp), 5);
            }
            for _ in 0..150 {
                self.cycle(&image(m, run, sp), 10);
            }
            let want = (0x4000 * percent / 100) as i16;
            let n = self.app.drive().actual_speed();
            assert!((n - want).abs() < 0x40, "{}: running at {percent} % (N2 {n:#06X})", m.name);
        }

        fn card_event(&self, e: CardEvent) -> u8 {
            self.app.dpm().card_report().unwrap().event(e)
        }
    }

    /// SYNC (CFW500 §5.1.2): the outputs received after a SYNC reach the drive only with
    /// the next SYNC (or UNSYNC).
    #[test]
    fn sync_applies_the_outputs_together() {
        for m in family_modules() {
            let mut b = Bench::new();
            b.bring_up_sync_freeze(m);
            b.run_at(m, 25);
            let (_, run, stop) = control_words(m);
            let before = *b.app.drive().command();
            b.global_control(GC_SYNC);
            assert!(b.node.slave().is_sync(), "{}", m.name);
            // New setpoint, then even a stop: stored, not applied.
            for cw in [run, stop] {
                for _ in 0..5 {
                    b.cycle(&image(m, cw, setpoint(m, 50)), 10);
                    assert_eq!(*b.app.drive().command(), before, "{}: held under SYNC", m.name);
                }
            }
            assert!(b.app.drive().actual_speed() > 0x0F00, "{}: still running", m.name);
            // The run command at 50 % is the last one sent: the next SYNC applies it.
            b.cycle(&image(m, run, setpoint(m, 50)), 10);
            b.global_control(GC_SYNC);
            b.step(5);
            let c = b.app.drive().command();
            assert!(c.flags.contains(CommandFlags::RUN), "{}", m.name);
            assert!((c.speed_setpoint - 0x2000).abs() <= 2, "{}: 50 % applied ({:#06X})", m.name, c.speed_setpoint);
            // Stop sent under SYNC, then UNSYNC: applied, and later outputs at once.
            b.cycle(&image(m, stop, setpoint(m, 50)), 10);
            assert!(b.app.drive().command().flags.contains(CommandFlags::RUN), "{}", m.name);
            b.global_control(GC_UNSYNC);
            b.step(5);
            assert!(!b.node.slave().is_sync());
            assert!(!b.app.drive().command().flags.contains(CommandFlags::RUN), "{}: stop applied", m.name);
            b.cycle(&image(m, run, setpoint(m, 10)), 10);
            b.step(5);
            let c = b.app.drive().command();
            assert!((c.speed_setpoint - 0x0666).abs() <= 2, "{}: direct again ({:#06X})", m.name, c.speed_setpoint);
        }
    }

    /// FREEZE (CFW500 §5.1.2): the master's inputs stay frozen while the drive ramps, until
    /// the next FREEZE (a new sample) or UNFREEZE (live again).
    #[test]
    fn freeze_holds_the_inputs_while_the_drive_ramps() {
        for m in family_modules() {
            let mut b = Bench::new();
            b.bring_up_sync_freeze(m);
            b.run_at(m, 10);
            let (_, run, _) = control_words(m);
            let q = image(m, run, setpoint(m, 90));
            b.cycle(&q, 100);
            b.cycle(&q, 10);
            b.global_control(GC_FREEZE);
            assert!(b.node.slave().is_freeze());
            let frozen = b.cycle(&q, 50);
            let speed = b.app.drive().actual_speed();
            for _ in 0..5 {
                assert_eq!(b.cycle(&q, 50), frozen, "{}: inputs frozen", m.name);
            }
            assert!(b.app.drive().actual_speed() > speed + 0x400, "{}: the drive ramps meanwhile", m.name);
            // A new FREEZE takes a new sample, frozen again.
            b.global_control(GC_FREEZE);
            let second = b.cycle(&q, 50);
            assert!(actual(m, &second) > actual(m, &frozen), "{}: a newer sample", m.name);
            assert_eq!(b.cycle(&q, 50), second, "{}", m.name);
            // UNFREEZE: live values, moving on the ramp.
            b.global_control(GC_UNFREEZE);
            b.cycle(&q, 50);
            let a = actual(m, &b.cycle(&q, 50));
            let c = actual(m, &b.cycle(&q, 50));
            assert!(c > a && a > actual(m, &second), "{}: live again ({a} → {c})", m.name);
        }
    }

    /// Clear mode (A138): the drive gets the communication-loss command and the CARD
    /// event; with the drive's action "ramp stop" it stops and shows A138, which goes away
    /// when the master leaves Clear; the outputs then apply again — for the VACON
    /// PROFIdrive profiles only after a b7 acknowledge and a new switch-on (OPTE3/E5 §6.3.3
    /// bit 10: Clear's zero outputs drop b10 in operation → FAULT).
    #[test]
    fn clear_mode_gives_the_drive_its_comm_loss_action() {
        for m in family_modules() {
            let mut b = Bench::new();
            b.app.drive_mut().model_mut().config_mut().comm_loss_action = CommLossAction::RampStop;
            b.bring_up_sync_freeze(m);
            b.run_at(m, 25);
            let (_, run, _) = control_words(m);
            let q = image(m, run, setpoint(m, 25));
            let events = b.card_event(CardEvent::ClearMode);
            b.global_control(GC_CLEAR);
            b.cycle(&q, 5);
            assert_eq!(b.card_event(CardEvent::ClearMode), events.wrapping_add(1), "{}", m.name);
            assert_eq!(b.app.dpm().status().unwrap().comm, CommState::ClearMode);
            assert!(b.app.drive().command().flags.contains(CommandFlags::COMM_LOSS), "{}", m.name);
            assert_eq!(b.app.drive().comm_alarms(), CommAlarms::CLEAR_MODE, "{}", m.name);
            for _ in 0..60 {
                b.cycle(&q, 10);
            }
            assert_eq!(b.app.drive().actual_speed(), 0, "{}: ramp stop (P0313 = 1)", m.name);
            assert_eq!(b.app.drive().status().warning_code, crate::drive::ALARM_CLEAR_MODE);
            // Operate again (Global_Control without Clear_Data): the alarm goes, it runs.
            b.global_control(0x00);
            if b.app.profidrive_state().is_some() {
                // VACON PROFIdrive (OPTE3/E5 §6.3.3 bit 10): Clear's zero outputs dropped
                // STW1 b10 in operation — FAULT; leaving Clear does not restart the motor.
                for _ in 0..20 {
                    b.cycle(&q, 10);
                }
                assert_eq!(b.app.profidrive_state(), Some(DriveState::Fault), "{}", m.name);
                assert_eq!(b.app.drive().actual_speed(), 0, "{}: no restart without acknowledge", m.name);
                // b7 acknowledge, then the switch-on sequence again.
                b.cycle(&image(m, 0x04FE, setpoint(m, 25)), 10);
                for _ in 0..5 {
                    b.cycle(&image(m, 0x047E, setpoint(m, 25)), 10);
                }
                assert_eq!(b.app.profidrive_state(), Some(DriveState::ReadyToSwitchOn), "{}", m.name);
            }
            for _ in 0..60 {
                b.cycle(&q, 10);
            }
            assert!(b.app.drive().comm_alarms().is_empty(), "{}", m.name);
            assert!(!b.app.drive().command().flags.contains(CommandFlags::COMM_LOSS));
            assert_eq!(b.app.drive().status().warning_code, 0);
            assert!(b.app.drive().actual_speed() > 0x0800, "{}: runs again", m.name);
        }
    }

    /// Safety (issue 12 4a): Clear together with Sync (`22 00`) or Unsync (`12 00`), and
    /// zero-length outputs, never apply the outputs Sync held — Rd_Outp and the DPM OUTPUTS
    /// block (what the drive reads) stay zero while Clear lasts, and the held image is
    /// discarded, so it never reaches the drive afterwards.
    #[test]
    fn clear_with_sync_never_applies_the_held_outputs() {
        for m in family_modules() {
            for enter in [0x22u8, 0x12, 0x32, 0x02, 0xFF] {
                let mut b = Bench::new();
                b.bring_up_sync_freeze(m);
                let (_, run, _) = control_words(m);
                let first = image(m, run, setpoint(m, 10));
                b.cycle(&first, 5);
                b.global_control(GC_SYNC);
                let held = image(m, run, setpoint(m, 90));
                b.cycle(&held, 5);
                if enter == 0xFF {
                    // Fail-safe Clear: zero-length outputs.
                    assert!(!b.srd(None, &[]).is_empty());
                    b.step(5);
                } else {
                    b.global_control(enter);
                }
                assert!(b.node.slave().is_clear(), "{} {enter:02X}", m.name);
                let zero = vec![0u8; m.outputs as usize];
                for _ in 0..3 {
                    assert_eq!(b.node.slave().outputs(), &zero[..], "{} {enter:02X}: outputs zero", m.name);
                    let rd = b.srd(Some(57), &[]);
                    assert_eq!(&rd[9..rd.len() - 2], &zero[..], "{} {enter:02X}: Rd_Outp zero", m.name);
                    let dpm = b.app.dpm().outputs().unwrap();
                    assert!(dpm.bytes().iter().all(|&x| x == 0), "{} {enter:02X}: the drive sees zero", m.name);
                    if enter != 0xFF {
                        b.cycle(&held, 5);
                        b.global_control(0x22);
                    }
                }
                // Clear ends and Sync / Unsync follow: the discarded image never comes back.
                b.global_control(0x00);
                b.global_control(GC_UNSYNC);
                let dpm = b.app.dpm().outputs().unwrap();
                assert_ne!(dpm.bytes(), &held[..], "{} {enter:02X}: held outputs reached the drive", m.name);
                assert_ne!(b.node.slave().outputs(), &held[..], "{} {enter:02X}", m.name);
            }
        }
    }

    /// Watchdog expiry (A139): the CARD events, the communication-loss command, and the
    /// drive's factory action "fault" (F239, kept until reset after the master is back).
    #[test]
    fn watchdog_expiry_trips_the_drive_with_its_action() {
        for m in family_modules() {
            let mut b = Bench::new();
            b.bring_up_sync_freeze(m);
            b.run_at(m, 25);
            let (wd, off) = (b.card_event(CardEvent::Watchdog), b.card_event(CardEvent::Offline));
            let ev = b.step(1100);
            assert!(ev.contains(Events::WATCHDOG_EXPIRED), "{}", m.name);
            b.step(1);
            assert_eq!(b.card_event(CardEvent::Watchdog), wd.wrapping_add(1));
            assert_eq!(b.card_event(CardEvent::Offline), off.wrapping_add(1));
            assert!(b.app.drive().command().flags.contains(CommandFlags::COMM_LOSS), "{}", m.name);
            assert_eq!(b.app.drive().comm_alarms(), CommAlarms::OFFLINE, "{}", m.name);
            assert_eq!(b.app.drive().status().fault_code, FAULT_OFFLINE, "{}: F239", m.name);
            assert!(!b.app.drive().model().modulating());
            // The master comes back: the alarm goes, the fault stays.
            b.bring_up_sync_freeze(m);
            let (_, run, _) = control_words(m);
            b.cycle(&image(m, run, setpoint(m, 25)), 10);
            assert!(b.app.drive().comm_alarms().is_empty(), "{}", m.name);
            assert_eq!(b.app.drive().status().fault_code, FAULT_OFFLINE, "{}: until reset", m.name);
        }
    }
}

/// Issue 12 item 4: the conformance defects, bytes in → bytes out through the card.
mod conformance;

/// The outputs' safety under every Clear / Sync / Freeze / watchdog combination.
mod clear_sync;
