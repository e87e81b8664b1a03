//! The soft slave over a pseudo-terminal with scripted requests (no master library): refusals
//! are answered and logged with their reason, data exchange works byte for byte, and the binary
//! stops cleanly on SIGINT. Every wait is "until it happened", with deadlines of seconds.

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use pbcard::card;
use pbcard::fdl::telegram::{self, Decoded};
use pbcard::testkit::{ScriptedMaster, SetPrm};
use pbcard::time::Baudrate;
use pbcard_softslave::serial::Port;
use pbcard_softslave::Options;

const SLAVE: u8 = 7;
const MASTER: u8 = 1;

struct Line {
    port: Port,
    master: ScriptedMaster,
}

impl Line {
    /// Send an SRD request and wait for one telegram back.
    fn srd(&mut self, dsap: Option<u8>, pdu: &[u8]) -> Vec<u8> {
        let req = self.master.srd(dsap, pdu);
        self.port.write_all(&req).unwrap();
        let mut rx = Vec::new();
        let end = Instant::now() + Duration::from_secs(20);
        while Instant::now() < end {
            let mut b = [0u8; 256];
            if self.port.wait_readable(Duration::from_millis(10)).unwrap() {
                let k = self.port.read(&mut b).unwrap();
                rx.extend_from_slice(&b[..k]);
                if let Decoded::Frame(_, len) = telegram::decode(&rx) {
                    return rx[..len].to_vec();
                }
            }
        }
        panic!("no answer to {}", pbcard_softslave::hex(&req));
    }
}

/// Set_Prm without the watchdog for `ident`.
fn set_prm(ident: u16) -> Vec<u8> {
    SetPrm::CARD.no_watchdog().ident(ident).pdu().to_vec()
}

fn wait_for(log: &Mutex<Vec<String>>, needle: &str) {
    let end = Instant::now() + Duration::from_secs(20);
    while Instant::now() < end {
        if log.lock().unwrap().iter().any(|l| l.contains(needle)) {
            return;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    panic!("'{needle}' not logged:\n{}", log.lock().unwrap().join("\n"));
}

#[test]
fn refusals_are_logged_with_their_reason_and_data_flows() {
    let port = Port::create_pty(Baudrate::B19200).unwrap();
    let mut opts = Options::new(port.path());
    opts.address = SLAVE;
    opts.pd_every = None;
    let stop = Arc::new(AtomicBool::new(false));
    let log = Arc::new(Mutex::new(Vec::new()));
    let (s, l) = (stop.clone(), log.clone());
    let t = std::thread::spawn(move || {
        pbcard_softslave::run(&opts, &s, &mut |line| l.lock().unwrap().push(line.to_string()))
    });
    wait_for(&log, "waiting for a DP master");
    let mut line = Line { port, master: ScriptedMaster::new(MASTER, SLAVE) };

    assert_eq!(line.srd(Some(61), &set_prm(0x1234)), [telegram::SC]);
    wait_for(&log, "Set_Prm refused (Prm_Fault): ident number 0x1234, this slave is 0x0F11");
    wait_for(&log, "P0740 = 4 (parameterization data error)");

    assert_eq!(line.srd(Some(61), &set_prm(card::IDENT_NUMBER)), [telegram::SC]);
    wait_for(&log, "Set_Prm accepted from master 1: watchdog off");
    assert_eq!(line.srd(Some(62), &[0xF3, 0xF3]), [telegram::SC]);
    wait_for(&log, "Chk_Cfg refused (Cfg_Fault): F3 F3 is no module of the GSD");
    wait_for(&log, "P0740 = 3 (configuration data error)");

    // Standard telegram 1: 0x047E brings the drive to S2; its ZSW1 comes back (a cycle later).
    assert_eq!(line.srd(Some(61), &set_prm(card::IDENT_NUMBER)), [telegram::SC]);
    assert_eq!(line.srd(Some(62), card::MODULES[0].cfg), [telegram::SC]);
    wait_for(&log, "P0740 = 6 (online)");
    let end = Instant::now() + Duration::from_secs(20);
    loop {
        let r = line.srd(None, &[0x04, 0x7E, 0x00, 0x00]);
        let pdu = &r[telegram::pdu_range(r.len(), 4)];
        if u16::from_be_bytes([pdu[0], pdu[1]]) & 0x0277 == 0x0231 {
            break;
        }
        assert!(Instant::now() < end, "ZSW1 never 0x0231:\n{}", log.lock().unwrap().join("\n"));
        std::thread::sleep(Duration::from_millis(5));
    }
    stop.store(true, Ordering::Relaxed);
    let summary = t.join().unwrap().unwrap();
    assert!(summary.data_exchanges >= 1 && summary.responses >= 7, "{summary:?}");
}

#[test]
fn the_binary_stops_cleanly_on_ctrl_c() {
    let mut child = Command::new(env!("CARGO_BIN_EXE_pbcard-softslave"))
        .args(["--device", "pty", "--address", "9"])
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let mut out = BufReader::new(child.stdout.take().unwrap());
    let mut lines = Vec::new();
    loop {
        let mut l = String::new();
        assert!(out.read_line(&mut l).unwrap() > 0, "ended early: {lines:?}");
        let ready = l.contains("waiting for a DP master");
        lines.push(l);
        if ready {
            break;
        }
    }
    // SAFETY: signalling our own child process.
    assert_eq!(unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGINT) }, 0);
    let status = child.wait().unwrap();
    let mut rest = String::new();
    let _ = std::io::Read::read_to_string(&mut out, &mut rest);
    assert!(status.success(), "exit status {status:?}");
    assert!(rest.contains("stopped after"), "{rest}");
    assert!(lines.iter().any(|l| l.contains("created a pseudo-terminal: point the DP master program at /dev/pts/")));
}

#[test]
fn a_bad_station_list_is_one_line_and_exit_status_2_before_the_device_is_opened() {
    let dir = std::env::temp_dir().join(format!("pbcard-softslave-cfg-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let cases: [(&str, &str); 5] = [
        ("[[station]]\naddress = 5\n[[station]]\naddress = 5\n", "station address 5 is given twice"),
        ("[[station]]\naddress = 130\n", "station address 130 is outside 0..=126"),
        ("[[station]]\naddress = 5\nmodule = \"PPO 7\"\n", "unknown module \"PPO 7\""),
        ("[[station]]\naddress = 5\nwatchdog = 1\n", "unknown field `watchdog`"),
        ("[[station]]\naddress = 5\n[station.params]\n100 = 99999\n", "parameter 100 = 99999: refused"),
    ];
    for (i, (text, want)) in cases.iter().enumerate() {
        let path = dir.join(format!("{i}.toml"));
        std::fs::write(&path, text).unwrap();
        // A device that does not exist: opening it would fail with status 1, not 2.
        let out = Command::new(env!("CARGO_BIN_EXE_pbcard-softslave"))
            .args(["--device", "/nonexistent/tty", "--config", path.to_str().unwrap()])
            .output()
            .unwrap();
        let err = String::from_utf8(out.stderr).unwrap();
        assert_eq!(out.status.code(), Some(2), "{text}: {err}");
        assert_eq!(err.lines().count(), 1, "one line: {err}");
        assert!(err.starts_with("pbcard-softslave: configuration: ") && err.contains(want), "{err}");
    }
    let out = Command::new(env!("CARGO_BIN_EXE_pbcard-softslave"))
        .args(["--device", "/nonexistent/tty", "--address", "5,6,5"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn two_stations_on_one_line_answer_each_their_own() {
    let port = Port::create_pty(Baudrate::B19200).unwrap();
    let dir = std::env::temp_dir().join(format!("pbcard-softslave-two-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let cfg = dir.join("two.toml");
    std::fs::write(
        &cfg,
        "[[station]]\naddress = 7\nmodule = 1\n[[station]]\naddress = 8\n[station.params]\n100 = 85\n",
    )
    .unwrap();
    let mut opts = Options::new(port.path());
    opts.config = Some(cfg.to_str().unwrap().into());
    opts.pd_every = None;
    let stop = Arc::new(AtomicBool::new(false));
    let log = Arc::new(Mutex::new(Vec::new()));
    let (s, l) = (stop.clone(), log.clone());
    let t = std::thread::spawn(move || {
        pbcard_softslave::run(&opts, &s, &mut |line| l.lock().unwrap().push(line.to_string()))
    });
    wait_for(&log, "waiting for a DP master");
    wait_for(&log, "stations 7, 8, ident 0x0F11");
    wait_for(&log, "#7 simulated drive");
    wait_for(&log, "#8 simulated drive");
    wait_for(&log, "only Standard telegram 1, PZD-2/2");
    wait_for(&log, "P100 = 85");
    let mut a = Line { port, master: ScriptedMaster::new(MASTER, 7) };
    // #7 refuses PPO 4 (its module is Standard telegram 1), #8 takes it.
    assert_eq!(a.srd(Some(61), &set_prm(card::IDENT_NUMBER)), [telegram::SC]);
    assert_eq!(a.srd(Some(62), &[0xF5]), [telegram::SC]);
    wait_for(&log, "#7 Chk_Cfg refused (Cfg_Fault)");
    let Line { port, .. } = a;
    let mut b = Line { port, master: ScriptedMaster::new(MASTER, 8) };
    assert_eq!(b.srd(Some(61), &set_prm(card::IDENT_NUMBER)), [telegram::SC]);
    assert_eq!(b.srd(Some(62), &[0xF5]), [telegram::SC]);
    wait_for(&log, "#8 Chk_Cfg: PPO 4");
    wait_for(&log, "#8 DP state Data_Exch");
    let r = b.srd(None, &[0; 12]);
    let Decoded::Frame(telegram::Telegram::Data(d), _) = telegram::decode(&r) else { panic!("{r:02x?}") };
    assert_eq!((d.sa, d.pdu.len()), (8, 12), "#8 answers its Data_Exchange");
    stop.store(true, Ordering::Relaxed);
    let summary = t.join().unwrap().unwrap();
    assert_eq!(summary.stations, [(7, 0), (8, 1)]);
    assert!(!log.lock().unwrap().iter().any(|l| l.contains("#7 DP state Data_Exch")));
    let _ = std::fs::remove_dir_all(dir);
}
