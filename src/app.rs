//! The card with a simulated drive behind its DPM, as the QEMU firmware, the soft slave and
//! the host tests run it: one call per main-loop turn.
//!
//! ```text
//! Node::poll ─▶ Link::publish ─▶ DPM (STATUS, OUTPUTS) ─▶ SimDrive::step ─▶ DPM (INPUTS) ─▶ Link::collect ─▶ DpSlave::set_inputs
//! ```
//!
//! The board firmware of a real card does the same without the drive: [`Link::publish`],
//! the transport to the drive's control board, [`Link::collect`].

use crate::dp::Events;
use crate::dpm::{Dpm, Link};
use crate::drive::{DriveConfig, SimDrive};
use crate::node::Node;
use crate::time::{Baudrate, Instant};

/// DPM image + card-side link + simulated drive.
#[derive(Debug, Clone)]
pub struct Application {
    dpm: Dpm,
    link: Link,
    drive: SimDrive,
}

impl Application {
    /// A fresh image (P0740 "inactive" until the first step) and a drive in S1.
    pub fn new(drive: DriveConfig) -> Self {
        Application { dpm: Dpm::new(), link: Link::new(), drive: SimDrive::new(drive) }
    }

    /// The rate the platform listens at (`None` while searching); shown as P0963.
    pub fn set_baudrate(&mut self, rate: Option<Baudrate>) {
        self.link.set_baudrate(rate);
    }

    /// Run the node's timers, move the master's outputs through the DPM to the drive, run
    /// the drive, and stage its answer for the next Data_Exchange. Returns the node's
    /// events (for logs and LEDs). Call it often (every few ms, and after each received
    /// telegram if the platform can): the answer to Data_Exchange *n* carries the drive's
    /// reaction to the outputs of an earlier cycle.
    pub fn step(&mut self, now: Instant, node: &mut Node) -> Events {
        let events = node.poll(now);
        self.link.publish(node, events, &mut self.dpm);
        self.drive.step(now, &mut self.dpm.host());
        self.link.collect(now, node, &self.dpm);
        events
    }

    /// The DPM image.
    pub fn dpm(&self) -> &Dpm {
        &self.dpm
    }
    /// The card-side link (counters, init-error flag).
    pub fn link_mut(&mut self) -> &mut Link {
        &mut self.link
    }
    /// The card-side link.
    pub fn link(&self) -> &Link {
        &self.link
    }
    /// The simulated drive.
    pub fn drive(&self) -> &SimDrive {
        &self.drive
    }
    /// The simulated drive, mutable (inject a fault, a warning).
    pub fn drive_mut(&mut self) -> &mut SimDrive {
        &mut self.drive
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::card;
    use crate::dp::{DpSlave, DpState};
    use crate::dpm::{CommState, Telegram};
    use crate::drive::profidrive::DriveState;
    use crate::fdl::telegram::{self, FunctionCode, Header};
    use crate::time::Duration;

    const MASTER: u8 = 2;
    const SLAVE: u8 = 5;

    /// A scripted master: builds SRD requests and feeds them byte by byte.
    struct Bench {
        node: Node,
        app: Application,
        now: Instant,
        fcb: bool,
    }

    impl Bench {
        fn new() -> Self {
            let mut app = Application::new(DriveConfig {
                ramp_time: Duration::from_millis(1000),
                quick_stop_time: Duration::from_millis(100),
                ..DriveConfig::DEFAULT
            });
            app.set_baudrate(Some(Baudrate::B1500k));
            Bench { node: Node::new(DpSlave::new(SLAVE)), app, now: Instant::from_millis(0), fcb: false }
        }

        /// Send one SRD request; returns the response bytes.
        fn srd(&mut self, dsap: Option<u8>, pdu: &[u8]) -> Vec<u8> {
            self.fcb = !self.fcb;
            let hdr = Header {
                da: SLAVE,
                sa: MASTER,
                fc: FunctionCode::request(0xD, self.fcb, true),
                dsap,
                ssap: dsap.map(|_| 62),
            };
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

        fn step(&mut self, ms: u64) -> Events {
            self.now = self.now + Duration::from_millis(ms);
            self.app.step(self.now, &mut self.node)
        }

        fn bring_up(&mut self, module: &card::Module) {
            let mut prm = vec![0x88, 1, 100, 11, (card::IDENT_NUMBER >> 8) as u8, card::IDENT_NUMBER as u8, 0];
            prm.extend_from_slice(&card::USER_PRM_DEFAULTS);
            assert_eq!(self.srd(Some(61), &prm), [telegram::SC]);
            self.step(1);
            assert_eq!(self.srd(Some(62), module.cfg), [telegram::SC]);
            self.step(1);
            assert_eq!(self.node.slave().state(), DpState::DataExch);
        }

        /// One Data_Exchange with `outputs`, then a step of `ms`; returns the inputs received.
        fn cycle(&mut self, outputs: &[u8], ms: u64) -> Vec<u8> {
            let r = self.srd(None, outputs);
            self.step(ms);
            r[telegram::pdu_range(r.len(), self.node.slave().input_len())].to_vec()
        }
    }

    fn words(b: &[u8]) -> Vec<u16> {
        b.chunks(2).map(|w| u16::from_be_bytes([w[0], w[1]])).collect()
    }

    #[test]
    fn size_stays_small() {
        // DPM image 624 B (layout 2), last status, outputs, drive report and a mailbox answer
        // in the link, last outputs and inputs in the drive: a static in the firmware.
        let n = core::mem::size_of::<Application>();
        assert!(n <= 1536, "Application is {n} bytes");
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
        assert_eq!(b.app.drive().state(), DriveState::ReadyToSwitchOn);
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
        assert_eq!(b.app.drive().state(), DriveState::SwitchingOff(crate::drive::profidrive::StopKind::Ramp));
        for _ in 0..120 {
            b.cycle(&q, 5);
        }
        assert_eq!(b.app.drive().state(), DriveState::ReadyToSwitchOn);
        assert_eq!(b.app.drive().actual_speed(), 0);
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
            for (i, w) in q.chunks_mut(2).enumerate() {
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
            assert_eq!(w[pkw] & 0x0277, 0x0231, "{}: ZSW in S2", m.name);
            assert_eq!(w[pkw + 1], 0, "{}: HIW at standstill", m.name);
            for (k, &x) in w.iter().enumerate().skip(pkw + 2) {
                assert_eq!(x, 0x1100 + k as u16, "{}: PZD{} echoed", m.name, k - pkw + 1);
            }
        }
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
        assert_eq!(b.app.drive().state(), DriveState::Operation);
        let ev = b.step(2000);
        assert!(ev.contains(Events::WATCHDOG_EXPIRED));
        b.step(1);
        assert_eq!(b.app.drive().state(), DriveState::Fault);
        assert_eq!(b.app.dpm().status().unwrap().comm, CommState::Offline);
        assert_eq!(b.app.dpm().status().unwrap().watchdog_expiries, 1);
    }
}
