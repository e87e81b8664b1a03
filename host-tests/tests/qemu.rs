//! End to end: the real firmware (the RTIC application with the QEMU board module, built by
//! `scripts/qemu.sh build`) boots in `qemu-system-arm -M netduinoplus2`; profirust's DP master
//! on the host talks to its USART1 through a Unix socket ([`host_tests::serial::StreamPhy`]),
//! brings it to data exchange and runs the firmware's simulated drive (`pbcard_sim::bench::Application`
//! behind the DPM) like a PLC program: 0x047E → ready, 0x047F with a setpoint → the speed
//! ramps up and holds, 0x047E → it ramps down to standstill. Every input image is checked
//! ([`DriveSession`]: state bits, PKW, PZD echo in order); the ramps must be monotonic and
//! reach their end points. A scripted DP-V1 master reads the card's PNUs through MSAC_C1 and
//! MSAC_C2, which the firmware's middle-priority task answers.
//!
//! Nothing depends on the machine's speed: wall-clock master with a 160 ms slot time and 15
//! retries, DP watchdog 10 s, a ready probe before the master starts, every phase a
//! wait-until with a deadline of a minute, the ramps judged by direction and end points, not
//! by cycle counts or times (see `host_tests::qemu`).
//!
//! Without the ELF (or without QEMU) the tests are skipped with a note, unless
//! `PBCARD_QEMU_REQUIRED=1` (set by `scripts/test.sh`, so CI cannot skip them).
//!
//! Run: `bash scripts/qemu.sh test`

mod families;

use std::time::{Duration, Instant};

use host_tests::qemu::{
    self, monotonic, Build, DriveSession, LiveMaster, MasterSetup, Qemu, QemuOptions, Sample, SLAVE, ZSW1_S2,
    ZSW1_S3_S5, ZSW1_S4, ZSW1_STATE_MASK,
};
use host_tests::serial::StreamPhy;
use pbcard::card;
use pbcard::fdl::telegram::{self, Decoded, FunctionCode, Header, Telegram};
use pbcard::time::Baudrate;
use profirust::dp::PeripheralEvent;

/// Deadline of each phase (reached in about a second on an idle machine).
const PHASE: Duration = Duration::from_secs(60);

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

/// Boot the firmware, connect to its USART1 and wait until the slave answers: the line, the
/// running QEMU and the time to the first answer (`None`: QEMU not available, test skipped).
fn boot_and_connect() -> Option<(Qemu, StreamPhy<std::os::unix::net::UnixStream>, Duration)> {
    let q = boot()?;
    let mut phy = match q.connect() {
        Ok(p) => p,
        Err(e) => fail(q, &[], format!("connect to USART1: {e}")),
    };
    match qemu::wait_for_answer(&mut phy, SLAVE, Duration::from_secs(20)) {
        Ok(t) => Some((q, phy, t)),
        Err(e) => fail(q, &[], e),
    }
}

fn fail(q: Qemu, master_events: &[(u64, PeripheralEvent)], what: String) -> ! {
    let log = q.stop();
    panic!("{what}\nmaster events (ms, event): {master_events:?}\n--- firmware log ---\n{}", log.join("\n"));
}

/// The drive through one run: ready, ramp up to `setpoint`, `hold` cycles there, ramp down.
fn run_the_drive<S: std::io::Read + std::io::Write>(
    s: &mut DriveSession<S>,
    setpoint: i16,
    hold: usize,
) -> Result<String, String> {
    let masked = |x: &Sample| x.zsw1 & ZSW1_STATE_MASK;
    // 0x047E: S1 → S2 "ready to switch on" at standstill (a few cycles of lag first).
    s.run(0x047E, setpoint, PHASE, |x| masked(x) == ZSW1_S2)?;
    s.hold(0x047E, setpoint, 20, PHASE, "S2 at standstill", |x| masked(x) == ZSW1_S2 && x.nist == 0)?;

    // 0x047F: S4 "operation enabled"; NIST_A ramps up to the setpoint and ZSW1 b8 comes.
    let up = s.run(0x047F, setpoint, PHASE, |x| masked(x) == ZSW1_S4 && x.zsw1 & 0x0100 != 0 && x.nist == setpoint)?;
    let steps_up = monotonic(&up, 0, setpoint)?;
    let first_s4 = up.iter().position(|x| masked(x) == ZSW1_S4).ok_or("no S4")?;
    if let Some(x) = up[first_s4..].iter().find(|x| masked(x) != ZSW1_S4) {
        return Err(format!("left S4 while ramping up: {x:04X?}"));
    }
    if up[..first_s4].iter().any(|x| masked(x) != ZSW1_S2 || x.nist != 0) {
        return Err(format!("before S4 the drive must stay in S2 at standstill: {:04X?}", &up[..first_s4]));
    }
    if steps_up < 3 {
        return Err(format!("NIST_A jumped instead of ramping ({steps_up} values between): {up:04X?}"));
    }
    s.hold(0x047F, setpoint, hold, PHASE, "S4 at the setpoint", |x| {
        masked(x) == ZSW1_S4 && x.zsw1 & 0x0100 != 0 && x.nist == setpoint
    })?;

    // 0x047E: S5 ramp stop; NIST_A ramps down to 0, then S2.
    let down = s.run(0x047E, setpoint, PHASE, |x| masked(x) == ZSW1_S2 && x.nist == 0)?;
    let steps_down = monotonic(&down, setpoint, 0)?;
    let s5 = down.iter().filter(|x| masked(x) == ZSW1_S3_S5 && x.nist != 0).count();
    if steps_down < 3 || s5 < 3 {
        return Err(format!("no ramp down through S5 ({steps_down} values between, {s5} cycles in S5): {down:04X?}"));
    }
    if let Some(x) = down.iter().find(|x| ![ZSW1_S4, ZSW1_S3_S5, ZSW1_S2].contains(&masked(x))) {
        return Err(format!("ramp stop through an unexpected state: {x:04X?}"));
    }
    s.hold(0x047E, setpoint, 20, PHASE, "S2 at standstill", |x| masked(x) == ZSW1_S2 && x.nist == 0)?;
    Ok(format!(
        "ramp up {} cycles ({steps_up} speeds between), {hold} cycles at {setpoint:+}, ramp down {} cycles \
         ({steps_down} between)",
        up.len(),
        down.len()
    ))
}

/// Bring-up, then the drive run with `module` (STW1 at the word after the PKW).
fn drive_end_to_end(module: &card::Module, setpoint: i16, hold: usize) {
    let Some((q, phy, ready)) = boot_and_connect() else { return };
    let mut m = LiveMaster::new(phy, SLAVE, module, &MasterSetup::default());
    if let Err(e) = m.bring_up(PHASE) {
        let ev = m.events.clone();
        fail(q, &ev, e);
    }
    let t_up = m.ms();
    let mut s = DriveSession::new(m, module);
    let t0 = Instant::now();
    let report = run_the_drive(&mut s, setpoint, hold);
    let secs = t0.elapsed().as_secs_f64();
    let mut q = q;
    let report = report.and_then(|r| q.check_running().map(|()| r));
    let report = match report {
        Ok(r) => r,
        Err(e) => {
            let ev = s.master.events.clone();
            fail(q, &ev, e);
        }
    };
    let ev = &s.master.events;
    let first = ev.iter().map(|e| e.1).take(3).collect::<Vec<_>>();
    if first != [PeripheralEvent::Online, PeripheralEvent::Configured, PeripheralEvent::DataExchanged]
        || ev.iter().any(|e| e.1 == PeripheralEvent::Offline)
    {
        let ev = ev.clone();
        fail(q, &ev, "unexpected master events".into());
    }
    let stats = s.master.phy.stats();
    let fw = q.stop();
    // With defmt-print installed the log is decoded: the firmware saw the same run.
    if fw.iter().any(|l| l.contains("pbcard: station")) {
        for line in [
            "DP state DataExch, master 2",
            "P0740 = 6",
            "drive: S1 switching on inhibited -> S2 ready for switching on",
            "drive: S2 ready for switching on -> S4 operation",
            "drive: S4 operation -> S5 switching off (ramp stop)",
            "drive: S5 switching off (ramp stop) -> S2 ready for switching on",
        ] {
            assert!(fw.iter().any(|l| l.contains(line)), "firmware log without '{line}': {fw:#?}");
        }
    }
    assert!(!fw.iter().any(|l| l.contains("panic") || l.contains("HardFault")), "firmware log: {fw:#?}");
    println!(
        "{}: slave ready after {} ms, data exchange after {t_up} ms; {} cycles checked in {secs:.1} s \
         ({:.2} ms/cycle): {report}; {}; {} telegrams / {} bytes out, {} bytes in, {} stale bytes dropped",
        module.name,
        ready.as_millis(),
        s.cycles,
        secs * 1000.0 / s.cycles as f64,
        if qemu::DriveImage::new(module).len() > 8 {
            format!("PZD3… echoed at most {} cycles late", s.max_echo_lag)
        } else {
            "no echo words".into()
        },
        stats.tx_telegrams,
        stats.tx_bytes,
        stats.rx_bytes,
        stats.rx_dropped
    );
}

#[test]
fn standard_telegram_1_drive_runs_ramps_to_50_percent_and_back() {
    drive_end_to_end(&card::MODULES[0], 0x2000, 500);
}

#[test]
fn ppo5_zsw_hiw_after_the_pkw_pzd_echoed_drive_runs() {
    let ppo5 = card::MODULES.iter().find(|m| m.reference == 105).expect("PPO 5 in card::MODULES");
    assert_eq!(qemu::DriveImage::new(ppo5).pzd1(), 4, "PPO 5: ZSW/HIW after the four PKW words");
    drive_end_to_end(ppo5, -0x1000, 300);
}

/// One module's run with the family PLC on a master already in data exchange: run up to
/// the setpoint (echo back), stop to standstill.
fn run_family<S: std::io::Read + std::io::Write>(
    m: &mut LiveMaster<S>,
    plc: &mut families::FamilyDrive,
) -> Result<String, String> {
    use families::Phase;
    let t0 = Instant::now();
    for phase in [Phase::Run, Phase::Stop] {
        plc.start(phase);
        let deadline = Instant::now() + PHASE;
        loop {
            if Instant::now() > deadline {
                return Err(format!(
                    "{}: {phase:?} not done within {PHASE:?}; actuals {:?}",
                    plc.module.name, plc.actuals
                ));
            }
            match m.poll() {
                Some(PeripheralEvent::DataExchanged) => {
                    let i = m.peripheral().pi_i().to_vec();
                    let (q, done) = plc.next(&i, phase)?;
                    m.peripheral().pi_q_mut().copy_from_slice(&q);
                    if done {
                        break;
                    }
                }
                Some(PeripheralEvent::Offline) => {
                    return Err(format!("{}: the master lost the slave", plc.module.name))
                }
                _ => {}
            }
        }
        if phase == Phase::Run {
            plc.check_ramp()?;
        }
    }
    Ok(format!(
        "{}: {} cycles in {:.1} s, {} fault acknowledges, ramp through {} values",
        plc.module.name,
        plc.cycles,
        t0.elapsed().as_secs_f64(),
        plc.resets,
        plc.actuals.len()
    ))
}

/// Issue 6 "the QEMU build runs any of these telegrams": one boot, re-parameterised module
/// after module (Set_Prm / Chk_Cfg again from a new master on the same line) — ST20, VACON
/// 138, CFW500 105, CFW-11 103, INVT, then ST1 again — each run up to its setpoint with the
/// programmable words echoed and stopped, through its own control profile. Leaving data
/// exchange for the new Set_Prm trips the running card's drive (A139 with its factory action
/// "fault"): each family acknowledges it with its own reset.
#[test]
fn every_family_runs_the_drive_on_one_boot() {
    let Some((q, mut phy, _)) = boot_and_connect() else { return };
    let mut reports = Vec::new();
    let mut q = q;
    for reference in [20u16, 1138, 2105, 3103, 4001, 1] {
        let mut plc = families::FamilyDrive::new(reference, 25);
        let mut m = LiveMaster::new(phy, SLAVE, plc.module, &MasterSetup::default());
        if let Err(e) = m.bring_up(PHASE) {
            let ev = m.events.clone();
            fail(q, &ev, format!("{}: {e}", plc.module.name));
        }
        match run_family(&mut m, &mut plc).and_then(|r| q.check_running().map(|()| r)) {
            Ok(r) => reports.push(r),
            Err(e) => {
                let ev = m.events.clone();
                fail(q, &ev, e);
            }
        }
        phy = m.phy;
    }
    let fw = q.stop();
    assert!(!fw.iter().any(|l| l.contains("panic") || l.contains("HardFault")), "firmware log: {fw:#?}");
    for r in reports {
        println!("{r}");
    }
}

// ----- DP-V1 through the firmware's middle-priority task -----

/// A scripted master on the socket: SRD requests with its own FCB per source address.
struct Dpv1Master<S: std::io::Read + std::io::Write> {
    phy: StreamPhy<S>,
    fcb: [bool; 128],
}

impl<S: std::io::Read + std::io::Write> Dpv1Master<S> {
    /// One SRD (FCB toggled); the response PDU, or `Err` with the SD1/SC kind.
    fn srd(&mut self, sa: u8, dsap: u8, ssap: u8, pdu: &[u8]) -> Result<Vec<u8>, String> {
        self.fcb[sa as usize] = !self.fcb[sa as usize];
        let h = Header {
            da: SLAVE,
            sa,
            fc: FunctionCode::request(0x0D, self.fcb[sa as usize], true),
            dsap: Some(dsap),
            ssap: Some(ssap),
        };
        let req = qemu::frame(&h, pdu);
        let resp = match self.phy.request(&req, Duration::from_secs(10)) {
            Ok(Some(r)) => r,
            Ok(None) => return Err(format!("no answer to {}", host_tests::hex(&req))),
            Err(e) => return Err(format!("socket: {e}")),
        };
        match telegram::decode(&resp) {
            Decoded::Frame(Telegram::ShortAck, _) => Err("SC".into()),
            Decoded::Frame(Telegram::Data(t), _) if t.pdu.is_empty() && t.dsap.is_none() => {
                Err(format!("SD1 FC {:02X}", t.fc.0))
            }
            Decoded::Frame(Telegram::Data(t), _) => Ok(t.pdu.to_vec()),
            other => Err(format!("invalid answer {other:?}")),
        }
    }

    /// Request (acknowledged with SC), then poll with empty PDUs until the response: "not
    /// ready" (SC) until the firmware's DP-V1 task has worked on it.
    fn transact(&mut self, sa: u8, dsap: u8, ssap: u8, pdu: &[u8]) -> Result<Vec<u8>, String> {
        match self.srd(sa, dsap, ssap, pdu) {
            Err(e) if e == "SC" => {}
            other => return Err(format!("request {}: {other:?} instead of SC", host_tests::hex(pdu))),
        }
        let deadline = Instant::now() + PHASE;
        loop {
            match self.srd(sa, dsap, ssap, &[]) {
                Ok(p) => return Ok(p),
                Err(e) if e == "SC" && Instant::now() < deadline => std::thread::sleep(Duration::from_millis(2)),
                Err(e) => return Err(format!("poll after {}: {e}", host_tests::hex(pdu))),
            }
        }
    }

    /// DS_Read of record 47 until the parameter response is there: PROFIdrive answers
    /// `DE 80 B5 00` (state conflict, "response not yet available") while the drive behind
    /// the DPM mailbox is still working on the request; a PROFIdrive master repeats the read
    /// (reference §5.1, VACON OPTE3/E5 Table 45/46).
    fn read47(&mut self, sa: u8, dsap: u8, ssap: u8) -> Result<Vec<u8>, String> {
        let deadline = Instant::now() + PHASE;
        loop {
            let r = self.transact(sa, dsap, ssap, &[0x5E, 0, 47, 240])?;
            if r != [0xDE, 0x80, 0xB5, 0x00] || Instant::now() >= deadline {
                return Ok(r);
            }
            std::thread::sleep(Duration::from_millis(5));
        }
    }

    /// Read PNUs 918 (station address) and 963 (baud rate) through record 47 on `dsap`;
    /// returns the two values.
    fn read_918_963(&mut self, sa: u8, dsap: u8, ssap: u8, reference: u8) -> Result<(u16, u16), String> {
        let req = [0x5F, 0, 47, 16, reference, 0x01, 1, 2, 0x10, 1, 0x03, 0x96, 0, 0, 0x10, 1, 0x03, 0xC3, 0, 0];
        let w = self.transact(sa, dsap, ssap, &req)?;
        if w != [0x5F, 0, 47, 16] {
            return Err(format!("DS_Write response {}", host_tests::hex(&w)));
        }
        let r = self.read47(sa, dsap, ssap)?;
        match r.as_slice() {
            [0x5E, 0, 47, 12, rf, 0x01, 1, 2, 0x42, 1, a, b, 0x42, 1, c, d] if *rf == reference => {
                Ok((u16::from_be_bytes([*a, *b]), u16::from_be_bytes([*c, *d])))
            }
            _ => Err(format!("DS_Read response {}", host_tests::hex(&r))),
        }
    }
}

#[test]
fn dpv1_card_and_drive_parameters_through_msac_c1_and_c2() {
    let Some((q, phy, _)) = boot_and_connect() else { return };
    let mut m = Dpv1Master { phy, fcb: [false; 128] };
    let baud = u16::from(Baudrate::B1500k.p0963_code());
    let run = |m: &mut Dpv1Master<_>| -> Result<(), String> {
        // MSAC_C2 (class-2 master #10), independent of the cyclic state: Initiate on the
        // resource manager (SAP 49), then on the connection SAP it names; Send_Timeout 60 s.
        let initiate = [0x57, 0, 0, 0, 0x17, 0x70, 0x01, 0x00, 0, 0, 0, 0, 0, 2, 0, 2, 0, 0, 0, 0];
        let rm = m.srd(10, 49, 50, &initiate)?;
        let sap = match rm.as_slice() {
            [0x56, sap, _, _] => *sap,
            _ => return Err(format!("RM answer {}", host_tests::hex(&rm))),
        };
        let res = m.transact(10, sap, 50, &initiate)?;
        if res.first() != Some(&0x57) {
            return Err(format!("Initiate.res {}", host_tests::hex(&res)));
        }
        let c2 = m.read_918_963(10, sap, 50, 0x21)?;
        if c2 != (u16::from(SLAVE), baud) {
            return Err(format!("MSAC_C2: PNU 918/963 = {c2:?}, expected ({SLAVE}, {baud})"));
        }
        // MSAC_C1 (class-1 master #2): Set_Prm with DPV1_Enable, Chk_Cfg, then SAP 51.
        let id = card::IDENT_NUMBER.to_be_bytes();
        let mut prm = vec![0x88, 100, 100, 11, id[0], id[1], 0, 0x80, 0, 0];
        prm.extend_from_slice(&card::USER_PRM_DEFAULTS[3..]);
        prm.truncate(7 + card::USER_PRM_LEN);
        for (dsap, pdu) in [(61, prm.as_slice()), (62, card::MODULES[0].cfg)] {
            match m.srd(qemu::MASTER, dsap, 62, pdu) {
                Err(e) if e == "SC" => {}
                other => return Err(format!("SAP {dsap}: {other:?}")),
            }
        }
        let c1 = m.read_918_963(qemu::MASTER, 51, 51, 0x22)?;
        if c1 != (u16::from(SLAVE), baud) {
            return Err(format!("MSAC_C1: PNU 918/963 = {c1:?}, expected ({SLAVE}, {baud})"));
        }
        // A drive parameter end to end through the DPM parameter mailbox: change P100
        // (acceleration time, 0.1 s) to 123 over MSAC_C1, read it back over MSAC_C2; a value
        // above its limit (9999) is refused by the drive with error 0x02.
        let change = [0x5F, 0, 47, 14, 0x23, 0x02, 1, 1, 0x10, 1, 0, 100, 0, 0, 0x42, 1, 0, 123];
        let w = m.transact(qemu::MASTER, 51, 51, &change)?;
        if w != [0x5F, 0, 47, 14] {
            return Err(format!("P100 change: DS_Write response {}", host_tests::hex(&w)));
        }
        let r = m.read47(qemu::MASTER, 51, 51)?;
        if r != [0x5E, 0, 47, 4, 0x23, 0x02, 1, 1] {
            return Err(format!("P100 change: response {}", host_tests::hex(&r)));
        }
        let read = [0x5F, 0, 47, 10, 0x24, 0x01, 1, 1, 0x10, 1, 0, 100, 0, 0];
        m.transact(10, sap, 50, &read)?;
        let r = m.read47(10, sap, 50)?;
        if r != [0x5E, 0, 47, 8, 0x24, 0x01, 1, 1, 0x42, 1, 0, 123] {
            return Err(format!("P100 read over MSAC_C2: {}", host_tests::hex(&r)));
        }
        let too_big = [0x5F, 0, 47, 14, 0x25, 0x02, 1, 1, 0x10, 1, 0, 100, 0, 0, 0x42, 1, 0x27, 0x10];
        m.transact(qemu::MASTER, 51, 51, &too_big)?;
        let r = m.read47(qemu::MASTER, 51, 51)?;
        if r != [0x5E, 0, 47, 8, 0x25, 0x82, 1, 1, 0x44, 1, 0, 0x02] {
            return Err(format!("P100 = 10000: response {}", host_tests::hex(&r)));
        }
        // I&M0 (slot 0, index 255, call header 08 00 FD E8) over MSAC_C2 and MSAC_C1, with the
        // simulated drive's serial number and hardware revision from the DPM DEVICE block;
        // I&M1 written over MSAC_C1 is read back over MSAC_C2 (issue 12 item 1).
        for (sa, dsap, ssap) in [(10, sap, 50), (qemu::MASTER, 51, 51)] {
            let w = m.transact(sa, dsap, ssap, &[0x5F, 0, 0xFF, 4, 0x08, 0x00, 0xFD, 0xE8])?;
            if w != [0x5F, 0, 0xFF, 4] {
                return Err(format!("I&M0 call on SAP {dsap}: {}", host_tests::hex(&w)));
            }
            let r = m.transact(sa, dsap, ssap, &[0x5E, 0, 0xFF, 0xF0])?;
            let ok = r.len() == 72
                && r[..8] == [0x5E, 0, 0xFF, 68, 0x08, 0x00, 0xFD, 0xE8]
                && &r[8 + 12..8 + 19] == b"ODC-PB1"
                && &r[8 + 32..8 + 48] == pbcard_sim::drive::SIM_DEVICE.serial_number.as_slice()
                && r[8 + 48..8 + 50] == [0, 2]
                && r[8 + 56..8 + 58] == [0x3A, 0x00];
            if !ok {
                return Err(format!("I&M0 on SAP {dsap}: {}", host_tests::hex(&r)));
            }
        }
        let mut im1 = vec![0x5F, 0, 0xFF, 68, 0x08, 0x00, 0xFD, 0xE9];
        im1.extend_from_slice(&[0; 10]);
        im1.extend_from_slice(&[b'Q'; 54]);
        let w = m.transact(qemu::MASTER, 51, 51, &im1)?;
        if w != [0x5F, 0, 0xFF, 68] {
            return Err(format!("I&M1 write: {}", host_tests::hex(&w)));
        }
        m.transact(10, sap, 50, &[0x5F, 0, 0xFF, 4, 0x08, 0x00, 0xFD, 0xE9])?;
        let r = m.transact(10, sap, 50, &[0x5E, 0, 0xFF, 0xF0])?;
        if r.len() != 72 || r[18..] != [b'Q'; 54] {
            return Err(format!("I&M1 over MSAC_C2: {}", host_tests::hex(&r)));
        }
        Ok(())
    };
    if let Err(e) = run(&mut m) {
        fail(q, &[], e);
    }
    let fw = q.stop();
    assert!(!fw.iter().any(|l| l.contains("panic") || l.contains("HardFault")), "firmware log: {fw:#?}");
}

/// Issue 12 item 4e (station part) on the firmware: requests from SA 127, from the card's own
/// address, or with FC bit 7 set are never answered; the same requests from a master are.
#[test]
fn impossible_sources_and_reserved_fc_are_never_answered() {
    let Some((q, mut phy, _)) = boot_and_connect() else { return };
    let sd1 =
        |sa: u8, fc: u8| qemu::frame(&Header { da: SLAVE, sa, fc: FunctionCode(fc), dsap: None, ssap: None }, &[]);
    let diag = |sa: u8, fc: u8| {
        qemu::frame(&Header { da: SLAVE, sa, fc: FunctionCode(fc), dsap: Some(60), ssap: Some(62) }, &[])
    };
    let never = [sd1(127, 0x49), sd1(SLAVE, 0x49), sd1(2, 0xC9), diag(127, 0x6D), diag(SLAVE, 0x6D), diag(2, 0xED)];
    for f in &never {
        match phy.request(f, Duration::from_millis(500)) {
            Ok(None) => {}
            Ok(Some(a)) => fail(q, &[], format!("{} answered with {}", host_tests::hex(f), host_tests::hex(&a))),
            Err(e) => fail(q, &[], format!("USART1 socket: {e}")),
        }
    }
    match phy.request(&diag(2, 0x6D), Duration::from_secs(5)) {
        Ok(Some(a)) if matches!(telegram::decode(&a), Decoded::Frame(Telegram::Data(_), _)) => {}
        other => fail(q, &[], format!("Slave_Diag from master 2: {other:?}")),
    }
    q.stop();
}

/// Issue 12 item 4e (line part) on the firmware: a request followed without an idle line by
/// more bytes (`FDL_Status 00 11 22` in one write) is not answered — the answer waits for the
/// quiet window of `bsp::qemu` and is dropped when a character comes first —; the same request
/// alone is answered before and after.
#[test]
fn a_request_followed_without_a_gap_is_not_answered() {
    let Some((q, mut phy, _)) = boot_and_connect() else { return };
    let status = qemu::frame(&Header { da: SLAVE, sa: 2, fc: FunctionCode(0x49), dsap: None, ssap: None }, &[]);
    let answered = |r: &std::io::Result<Option<Vec<u8>>>| matches!(r, Ok(Some(a)) if matches!(telegram::decode(a), Decoded::Frame(Telegram::Data(_), _)));
    let r = phy.request(&status, Duration::from_secs(5));
    if !answered(&r) {
        fail(q, &[], format!("clean FDL_Status: {r:?}"));
    }
    std::thread::sleep(Duration::from_millis(50));
    let _ = phy.take_received();
    let mut run_on = status.clone();
    run_on.extend_from_slice(&[0x00, 0x11, 0x22]);
    for _ in 0..3 {
        match phy.request(&run_on, Duration::from_millis(500)) {
            Ok(None) => {}
            Ok(Some(a)) => fail(q, &[], format!("{} answered with {}", host_tests::hex(&run_on), host_tests::hex(&a))),
            Err(e) => fail(q, &[], format!("USART1 socket: {e}")),
        }
    }
    for _ in 0..3 {
        let r = phy.request(&status, Duration::from_secs(5));
        if !answered(&r) {
            fail(q, &[], format!("clean FDL_Status after the run-on ones: {r:?}"));
        }
    }
    q.stop();
}
