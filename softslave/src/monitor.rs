//! The readable log: bring-up steps, state changes, process data.

use std::fmt::Write as _;

use pbcard::card;
use pbcard::dp::prm::{PrmError, SetPrm, StationStatus};
use pbcard::dp::{sap, DpState, Events};
use pbcard::dpm::{CommState, ProcessData, Telegram};
use pbcard::fdl::telegram::{self, Decoded, RequestFunction, Telegram as Frame};
use pbcard::node::Node;
use pbcard::profile::profidrive::State;
use pbcard_sim::bench::Application;

/// Hex dump `10 02 08 49 53 16`.
pub fn hex(bytes: &[u8]) -> String {
    let mut s = String::with_capacity(bytes.len() * 3);
    for (i, b) in bytes.iter().enumerate() {
        if i > 0 {
            s.push(' ');
        }
        let _ = write!(s, "{b:02X}");
    }
    s
}

/// An N2 speed as a percentage ("+50.0 %").
pub fn percent(n2: u16) -> String {
    let v = n2 as i16 as i32;
    format!("{:+.1} %", v as f64 * 100.0 / 16384.0)
}

fn dp_state(s: DpState) -> &'static str {
    match s {
        DpState::WaitPrm => "Wait_Prm",
        DpState::WaitCfg => "Wait_Cfg",
        DpState::DataExch => "Data_Exch",
    }
}

fn prm_error(e: PrmError) -> String {
    match e {
        PrmError::Ident(i) => format!("ident number 0x{i:04X}, this slave is 0x{:04X}", card::IDENT_NUMBER),
        PrmError::Length(n) => {
            format!("{n} bytes, expected 7 to {} (7 + Max_User_Prm_Data_Len)", 7 + card::USER_PRM_LEN)
        }
        PrmError::ReservedStationStatus(s) => format!("reserved Station_Status bits set (0x{s:02X})"),
        PrmError::WatchdogFactor => "WD_On with a watchdog factor of 0".into(),
        PrmError::NotSupported => "Sync/Freeze requested but not supported".into(),
        PrmError::Dpv1Status { byte, value } => {
            format!("DPV1_Status_{byte} = 0x{value:02X} asks for something this slave does not do (DP-V1, alarms)")
        }
        PrmError::UserPrm { offset, value } => {
            format!("user parameter at offset {offset} = {value} is outside its GSD range")
        }
        other => format!("{other:?}"),
    }
}

/// What the log remembers between calls.
#[derive(Debug)]
pub struct Monitor {
    verbose: bool,
    address: u8,
    last_set_prm: Vec<u8>,
    last_chk_cfg: Vec<u8>,
    diag_logged_in: Option<DpState>,
    seen_masters: Vec<u8>,
    comm: CommState,
    drive: String,
    dx_at_last_pd: u32,
    sync: bool,
    freeze: bool,
}

impl Monitor {
    /// A monitor for a slave at `address`.
    pub fn new(verbose: bool, address: u8) -> Self {
        Monitor {
            verbose,
            address,
            last_set_prm: Vec::new(),
            last_chk_cfg: Vec::new(),
            diag_logged_in: None,
            seen_masters: Vec::new(),
            comm: CommState::Inactive,
            drive: String::new(),
            dx_at_last_pd: 0,
            sync: false,
            freeze: false,
        }
    }

    /// A complete telegram on the line (request, or our own echo on some adapters).
    pub fn on_frame(&mut self, frame: &[u8], node: &Node, log: &mut dyn FnMut(String)) {
        let Decoded::Frame(Frame::Data(t), _) = telegram::decode(frame) else { return };
        // Several stations see every telegram: each logs its own (and broadcasts).
        if self.verbose && (t.da == node.slave().address() || t.da == telegram::BROADCAST) {
            log(format!("rx {}", hex(frame)));
        }
        if !t.fc.is_request() || t.da != node.slave().address() {
            return;
        }
        if !self.seen_masters.contains(&t.sa) {
            self.seen_masters.push(t.sa);
            let what = match (t.fc.function(), t.dsap) {
                (RequestFunction::FdlStatus, _) => "FDL_Status".to_string(),
                (_, Some(sap::SLAVE_DIAG)) => "Slave_Diag".to_string(),
                (_, Some(s)) => format!("SAP {s}"),
                (_, None) => "Data_Exchange".to_string(),
            };
            log(format!("first request from master {}: {what}", t.sa));
        }
        match t.dsap {
            Some(sap::SET_PRM) => self.last_set_prm = t.pdu.to_vec(),
            Some(sap::CHK_CFG) => self.last_chk_cfg = t.pdu.to_vec(),
            Some(sap::SLAVE_DIAG) => {
                let st = node.slave().state();
                if self.diag_logged_in != Some(st) {
                    self.diag_logged_in = Some(st);
                    let d = node.slave().standard_diag();
                    log(format!("Slave_Diag read by master {} in {}: {}", t.sa, dp_state(st), hex(&d.encode())));
                }
            }
            _ => {}
        }
    }

    /// Our response went out.
    pub fn on_response(&mut self, bytes: &[u8], late_us: Option<u64>, log: &mut dyn FnMut(String)) {
        if self.verbose {
            match late_us {
                Some(us) => log(format!("tx {} ({us} µs after min_TSDR)", hex(bytes))),
                None => log(format!("tx {}", hex(bytes))),
            }
        }
    }

    /// After each application step.
    pub fn on_step(&mut self, events: Events, node: &Node, app: &Application, log: &mut dyn FnMut(String)) {
        let slave = node.slave();
        if events.contains(Events::PRM_ACCEPTED) {
            if let Some(p) = slave.parameters() {
                log(describe_prm(p, slave.master_address()));
            }
        }
        if events.contains(Events::PRM_FAULT) {
            let why = match SetPrm::parse(&self.last_set_prm, &card::SLAVE) {
                Err(e) => prm_error(e),
                Ok(_) => "refused".into(),
            };
            log(format!("Set_Prm refused (Prm_Fault): {why}"));
        }
        if events.contains(Events::CFG_ACCEPTED) {
            if let Some(m) = slave.module() {
                log(format!("Chk_Cfg: {} ({}): {} bytes out, {} bytes in", m.name, hex(m.cfg), m.outputs, m.inputs));
            }
        }
        if events.contains(Events::CFG_FAULT) {
            let names: Vec<String> = card::MODULES.iter().map(|m| format!("{} = {}", m.name, hex(m.cfg))).collect();
            log(format!(
                "Chk_Cfg refused (Cfg_Fault): {} is no module of the GSD (modules: {})",
                hex(&self.last_chk_cfg),
                names.join("; ")
            ));
        }
        if events.contains(Events::WATCHDOG_EXPIRED) {
            let ms = slave.watchdog_time().map_or(0, |t| t.as_millis());
            log(format!(
                "watchdog expired: no request from the master for {ms} ms; outputs cleared, waiting for Set_Prm"
            ));
        }
        if events.contains(Events::STATE_CHANGED) {
            let st = slave.state();
            let mut line = format!("DP state {}", dp_state(st));
            if st == DpState::DataExch {
                let _ = write!(line, ": data exchange with master {}", slave.master_address().unwrap_or(0xFF));
            }
            log(line);
        }
        if events.contains(Events::CLEAR_CHANGED) {
            log(if slave.is_clear() {
                "master in Clear: outputs zero".into()
            } else {
                "master left Clear: outputs valid".to_string()
            });
        }
        if slave.is_sync() != self.sync || slave.is_freeze() != self.freeze {
            self.sync = slave.is_sync();
            self.freeze = slave.is_freeze();
            log(format!(
                "Global_Control: sync {}, freeze {}",
                if self.sync { "on" } else { "off" },
                if self.freeze { "on" } else { "off" }
            ));
        }
        if events.contains(Events::ADDRESS_CHANGED) {
            self.address = slave.address();
            log(format!(
                "Set_Slave_Add: station address is now {} (kept across restarts with --state FILE, else start with --address {} next time)",
                self.address, self.address
            ));
        }
        if let Ok(s) = app.dpm().status() {
            if s.comm != self.comm {
                self.comm = s.comm;
                log(format!("P0740 = {} ({})", s.comm.code(), s.comm.text()));
            }
        }
        // The card's PROFIdrive state of the drive (S1 before a profile is selected).
        let d = app.profidrive_state().unwrap_or(State::SwitchingOnInhibited).name().to_string();
        if d != self.drive {
            let (stw, zsw) = match app.dpm().outputs() {
                Ok(out) => {
                    let pkw = out.telegram.pkw_words();
                    let inputs = node.slave().inputs();
                    let z = inputs.get(2 * pkw..2 * pkw + 2).map_or(0, |w| u16::from_be_bytes([w[0], w[1]]));
                    (out.word(pkw), z)
                }
                Err(_) => (0, 0),
            };
            log(format!(
                "drive: {} → {d} (STW1 {stw:04X}, ZSW1 {zsw:04X}, {})",
                if self.drive.is_empty() { State::SwitchingOnInhibited.name() } else { &self.drive },
                drive_summary(app)
            ));
            self.drive = d;
        }
    }

    /// The periodic process-data line (`secs` since the last one).
    pub fn process_data(&mut self, secs: f64, node: &Node, app: &Application, log: &mut dyn FnMut(String)) {
        let dx = node.slave().stats().data_exchanges;
        let rate = (dx.wrapping_sub(self.dx_at_last_pd)) as f64 / secs.max(1e-3);
        self.dx_at_last_pd = dx;
        if node.slave().state() != DpState::DataExch {
            return;
        }
        let Ok(out) = app.dpm().outputs() else { return };
        let inp = ProcessData::new(out.telegram, pbcard::dpm::PdFlags::empty(), node.slave().inputs());
        log(format!(
            "PD out {} | in {} | drive {} | {rate:.0} Data_Exchange/s",
            words(&out, true),
            words(&inp, false),
            drive_summary(app)
        ));
    }
}

/// The drive's own state from DRIVE_STATE: "drive running, speed +8192" / "drive fault 2310".
fn drive_summary(app: &Application) -> String {
    let st = app.drive().status();
    let f = st.flags;
    if f.contains(pbcard::profile::drive_if::StatusFlags::FAULT) {
        format!("drive fault {:04X}{}", st.fault_code, {
            use pbcard_sim::drive::model::{FAULT_ACCESS_ERROR, FAULT_CLEAR_MODE, FAULT_FIELDBUS, FAULT_OFFLINE};
            let fieldbus = [FAULT_FIELDBUS, FAULT_CLEAR_MODE, FAULT_OFFLINE, FAULT_ACCESS_ERROR];
            if fieldbus.contains(&st.fault_code) {
                " (fieldbus: communication lost)"
            } else {
                ""
            }
        })
    } else if f.contains(pbcard::profile::drive_if::StatusFlags::RUNNING) {
        format!("drive running, speed {:+}", st.speed)
    } else {
        "drive stopped".to_string()
    }
}

/// "STW1 047F NSOLL_A 2000 (+50.0 %)" / PPO: "PKW 0000 … STW 047F HSW 2000 (+50.0 %) PZD3 …".
fn words(pd: &ProcessData, out: bool) -> String {
    let t = pd.telegram;
    let pkw = t.pkw_words();
    let (w1, w2) = match (t, out) {
        (Telegram::Standard(_), true) => ("STW1", "NSOLL_A"),
        (Telegram::Standard(_), false) => ("ZSW1", "NIST_A"),
        (_, true) => ("STW", "HSW"),
        (_, false) => ("ZSW", "HIW"),
    };
    let mut s = String::new();
    if pkw > 0 {
        let k: Vec<String> = (0..pkw).map(|i| format!("{:04X}", pd.word(i))).collect();
        let _ = write!(s, "PKW {} ", k.join(" "));
    }
    let _ = write!(s, "{w1} {:04X} {w2} {:04X} ({})", pd.word(pkw), pd.word(pkw + 1), percent(pd.word(pkw + 1)));
    for i in 2..t.pzd_words() {
        let _ = write!(s, " PZD{} {:04X}", i + 1, pd.word(pkw + i));
    }
    s
}

fn describe_prm(p: &SetPrm, master: Option<u8>) -> String {
    let wd = match p.watchdog() {
        Some(t) => format!("watchdog {} ms", t.as_millis()),
        None => "watchdog off".into(),
    };
    let min_tsdr = p.min_tsdr.map_or("kept".to_string(), |b| format!("{} bit", b.0));
    let user: Vec<String> = card::USER_PRMS.iter().map(|u| format!("{} {}", u.name, p.user[u.offset])).collect();
    format!(
        "Set_Prm accepted from master {}: {wd}, min_TSDR {min_tsdr}, group 0x{:02X}, sync {}, freeze {}, {}",
        master.unwrap_or(0xFF),
        p.group_ident,
        if p.status.contains(StationStatus::SYNC_REQ) { "requested" } else { "off" },
        if p.status.contains(StationStatus::FREEZE_REQ) { "requested" } else { "off" },
        user.join(", ")
    )
}
