//! `--state FILE` (issue 12: I&M1–4 and the station address kept across power loss, here
//! across restarts): a master writes I&M1 over MSAC_C1 and moves the station with
//! Set_Slave_Add; the soft slave is stopped and started again with the same state file; the
//! station answers at its new address and reads I&M1 back byte for byte.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use pbcard::card;
use pbcard::fdl::telegram::{self, Decoded, Telegram};
use pbcard::testkit::{ScriptedMaster, SetPrm};
use pbcard::time::Baudrate;
use pbcard_softslave::serial::Port;
use pbcard_softslave::{Options, Summary};

const MASTER: u8 = 1;

struct Slave {
    stop: Arc<AtomicBool>,
    log: Arc<Mutex<Vec<String>>>,
    thread: Option<JoinHandle<std::io::Result<Summary>>>,
    port: Port,
}

impl Slave {
    fn start(address: u8, state: &str) -> Slave {
        let port = Port::create_pty(Baudrate::B19200).unwrap();
        let mut opts = Options::new(port.path());
        opts.address = address;
        opts.pd_every = None;
        opts.state = Some(state.into());
        let stop = Arc::new(AtomicBool::new(false));
        let log = Arc::new(Mutex::new(Vec::new()));
        let (s, l) = (stop.clone(), log.clone());
        let thread = std::thread::spawn(move || {
            pbcard_softslave::run(&opts, &s, &mut |line| l.lock().unwrap().push(line.to_string()))
        });
        let slave = Slave { stop, log, thread: Some(thread), port };
        slave.wait_for("waiting for a DP master");
        slave
    }

    fn wait_for(&self, needle: &str) {
        let end = Instant::now() + Duration::from_secs(20);
        while Instant::now() < end {
            if self.log.lock().unwrap().iter().any(|l| l.contains(needle)) {
                return;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        panic!("'{needle}' not logged:\n{}", self.log.lock().unwrap().join("\n"));
    }

    /// One request, one telegram back: `None` = the SC short acknowledge, else the PDU.
    fn srd(&mut self, m: &mut ScriptedMaster, dsap: Option<u8>, ssap: Option<u8>, pdu: &[u8]) -> Option<Vec<u8>> {
        let req = m.request(MASTER, dsap, ssap, pdu, true);
        self.port.write_all(&req).unwrap();
        let mut rx = Vec::new();
        let end = Instant::now() + Duration::from_secs(20);
        while Instant::now() < end {
            let mut b = [0u8; 256];
            if self.port.wait_readable(Duration::from_millis(10)).unwrap() {
                let k = self.port.read(&mut b).unwrap();
                rx.extend_from_slice(&b[..k]);
                match telegram::decode(&rx) {
                    Decoded::Frame(Telegram::ShortAck, _) => return None,
                    Decoded::Frame(Telegram::Data(t), _) => return Some(t.pdu.to_vec()),
                    Decoded::Frame(..) | Decoded::Invalid(_) => panic!("not an answer: {rx:02X?}"),
                    Decoded::Incomplete => {}
                }
            }
        }
        panic!("no answer to {req:02X?}:\n{}", self.log.lock().unwrap().join("\n"));
    }

    /// Set_Prm with DPV1_Enable, Chk_Cfg Standard telegram 1: data exchange, MSAC_C1 open.
    fn bring_up(&mut self, m: &mut ScriptedMaster) {
        let prm = SetPrm::CARD.no_watchdog().dpv1_status_1(0x80).pdu();
        assert_eq!(self.srd(m, Some(61), Some(62), &prm), None);
        assert_eq!(self.srd(m, Some(62), Some(62), card::MODULES[0].cfg), None);
        assert!(self.srd(m, None, None, &[0x04, 0x7E, 0x00, 0x00]).is_some(), "data exchange");
    }

    /// An MSAC_C1 request (SAP 51), then polls until the response.
    fn c1(&mut self, m: &mut ScriptedMaster, pdu: &[u8]) -> Vec<u8> {
        assert_eq!(self.srd(m, Some(51), Some(51), pdu), None, "acknowledged");
        let end = Instant::now() + Duration::from_secs(20);
        while Instant::now() < end {
            if let Some(r) = self.srd(m, Some(51), Some(51), &[]) {
                return r;
            }
            std::thread::sleep(Duration::from_millis(5));
        }
        panic!("no C1 response to {pdu:02X?}");
    }

    fn stop(mut self) -> Vec<String> {
        self.stop.store(true, Ordering::Relaxed);
        self.thread.take().unwrap().join().unwrap().unwrap();
        self.log.lock().unwrap().clone()
    }
}

#[test]
fn im1_and_the_station_address_survive_a_restart_with_the_same_state_file() {
    let path = std::env::temp_dir().join(format!("pbcard-softslave-state-{}", std::process::id()));
    let _ = std::fs::remove_file(&path);
    let state = path.to_str().unwrap();

    let mut im1 = vec![0u8; 10];
    im1.extend_from_slice(b"Conveyor 3 main drive           ");
    im1.extend_from_slice(b"Hall B, cabinet 12    ");
    assert_eq!(im1.len(), 64);

    let mut s = Slave::start(7, state);
    s.wait_for("#7 state file");
    s.wait_for("nothing stored yet");
    let mut m = ScriptedMaster::new(MASTER, 7);
    s.bring_up(&mut m);
    let write = [&[0x5F, 0x00, 0xFF, 68, 0x08, 0x00, 0xFD, 0xE9][..], &im1].concat();
    assert_eq!(s.c1(&mut m, &write), [0x5F, 0x00, 0xFF, 68]);
    s.wait_for("I&M1-4 stored in");
    // Set_Slave_Add (SAP 55) is refused in data exchange: back to Wait_Prm first (a Set_Prm
    // for another ident is a Prm_Fault and leaves data exchange).
    let bad = SetPrm::CARD.no_watchdog().ident(0x1234).pdu();
    assert_eq!(s.srd(&mut m, Some(61), Some(62), &bad), None);
    let ident = card::IDENT_NUMBER.to_be_bytes();
    assert_eq!(s.srd(&mut m, Some(55), Some(62), &[9, ident[0], ident[1], 0]), None);
    s.wait_for("station address 9 (No_Add_Chg 0) stored in");
    let log = s.stop();
    assert!(std::fs::metadata(&path).unwrap().len() == 32 * 1024, "{}", log.join("\n"));

    // Restart with the same file (and the old --address): the station is at 9, I&M1 is back.
    let mut s = Slave::start(7, state);
    s.wait_for("restored station address 9 (No_Add_Chg 0), I&M1-4");
    let mut m = ScriptedMaster::new(MASTER, 9);
    s.bring_up(&mut m);
    assert_eq!(s.c1(&mut m, &[0x5F, 0x00, 0xFF, 0x04, 0x08, 0x00, 0xFD, 0xE9]), [0x5F, 0x00, 0xFF, 0x04]);
    let r = s.c1(&mut m, &[0x5E, 0x00, 0xFF, 0xF0]);
    assert_eq!(&r[..8], &[0x5E, 0x00, 0xFF, 68, 0x08, 0x00, 0xFD, 0xE9]);
    assert_eq!(&r[8..], &im1[..], "I&M1 byte for byte (header zeros)");
    // Nothing changed: nothing written.
    let log = s.stop();
    assert!(!log.iter().any(|l| l.contains("stored in")), "{}", log.join("\n"));
    let _ = std::fs::remove_file(&path);
}
