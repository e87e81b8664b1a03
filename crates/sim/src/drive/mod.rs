//! A simulated AC drive's control board behind the DPM — what a drive maker's firmware does
//! with the card, far enough to be alive. The QEMU firmware, the soft slave and the host tests
//! run it; `no_std`, allocation-free, time passed in.
//!
//! [`SimDrive::step`] talks to the card only through the host-side reference implementation
//! ([`crate::dpm::host::Host`], issue 7 item 5) over any [`Transport`], on
//! [`Host::cycle`](crate::dpm::host::Host::cycle) (issue 16): two exchanges a drive cycle —
//! the first (CYCLIC over the SPI frames: one transaction in the steady state) brings the
//! newest DRIVE_CMD (the drive-neutral command of [`crate::profile::drive_if`]), the card's
//! heartbeat, events and communication state; the drive model runs
//! ([`model::DriveModel`]: ramps, quick stop, coast, jog, faults, communication-loss
//! reactions, current / torque / power); the second delivers DRIVE_STATE computed from that
//! command before the card's next step (one exchange a cycle would deliver the status of the
//! previous command, a cycle late). It reports faults and warnings in the DRIVE block (with
//! the GSD's device-related diagnosis block), keeps its heartbeat going, and serves the
//! parameter mailbox from its parameter table ([`params`]) — with block accesses
//! (`Options::cyclic_mailbox` off in `bench::Application`: a job within one card step, as the
//! card's parameter tests count; a drive maker's host carries it in the CYCLIC fragments).
//!
//! **Communication errors (WEG CFW500 §4 P0313 and §6, CFW-11 §3 P0313 and §5):** the drive
//! watches the card through [`Host::cycle`]'s poll (the `CARD.EVENTS` counters, the STATUS
//! block's communication state, the card's heartbeat) and raises the manuals' alarms ([`CommAlarms`]):
//!
//! * **A138** "PROFIBUS DP interface in Clear mode" — event 0 (`CardEvent::ClearMode`) or the
//!   STATUS state "Clear"; gone when the master leaves Clear (STATUS "online").
//! * **A139** "PROFIBUS DP interface offline" — event 1 (`Offline`, the card left data
//!   exchange) or 3 (`Watchdog`, the DP watchdog expired); like the manuals, only after an
//!   online → offline transition (not at power-up); gone when the cyclic exchange is back.
//! * **A140** "PROFIBUS DP module access error" — the card's heartbeat stopped
//!   ([`crate::dpm::host::Poll::card_lost`]); gone when it beats again (the WEG drives need a
//!   power cycle for a new attempt; this drive keeps trying).
//!
//! While an alarm is active the drive applies its communication-error action
//! ([`model::CommLossAction`], P0313-style: none, ramp stop, coast, quick stop, fault, keep
//! the last setpoint): the command gets [`CommandFlags::COMM_LOSS`] even before the card's
//! next DRIVE_CMD carries it, and with A140 (the card is gone, its DRIVE_CMD is stale) the
//! drive's own setting decides rather than the card's Set_Prm reaction. With the action
//! "fault" the drive trips with WEG's fault number of the alarm — F238 ([`model::FAULT_CLEAR_MODE`]),
//! F239 ([`model::FAULT_OFFLINE`]), F240 ([`model::FAULT_ACCESS_ERROR`]) — kept until a
//! fault reset (the card's own FIELDBUS_FAULT trips with [`model::FAULT_FIELDBUS`]); otherwise it
//! reports the alarm as its warning code ([`ALARM_CLEAR_MODE`],
//! [`ALARM_OFFLINE`], [`ALARM_ACCESS_ERROR`]), which disappears with the alarm.
//!
//! The drive's own action ("the drive's setting", Set_Prm / CONFIG reaction 0) is the model's
//! [`model::ModelConfig::comm_loss_action`]; writing **VACON ID 733** "response to fieldbus
//! fault" (OPTE3/E5 Table 141, VACON 100 coding, through PNU 10001 or the PPO PKW) sets it:
//! 0 / 1 none (the alarm as warning), 2 alarm + preset frequency, 3 fault with the stop
//! function (ramp), 4 fault with coasting. WEG P0313's options 3 / 4 / 5 come from the card
//! as reactions 5 / 6 / 7 (`DriveCommand::comm_loss_reaction`); only "fault" acts on a
//! drive the fieldbus does not control (CFW500 §4 P0313).
//!
//! **Fault history (VACON PNU 10118 / 10119, OPTE3/E5 Table 108):** every trip enters an
//! 8-bit VACON fault code ([`vacon_fault_code`]) at the head of a 40-entry history; PNU 10119
//! reads it (OctetString, newest first), a write of PNU 10118 clears it. The card's PNU 947
//! fault buffer is the card's own and is not cleared by it.
//!
//! **INVT (INVT §2.6 Tables 2-6 / 2-8, P15.02–P15.23 in [`params`]):** with the INVT frame the
//! drive takes its frequency from the PZD word mapped "1: set frequency" (PZD2: the card's
//! setpoint; PZD3..PZD12: the raw word, 0–Fmax in 0.01 Hz, Fmax [`INVT_FMAX`]); none mapped
//! → no frequency from the bus (0). PZD3..PZD12 of the response follow P15.14–P15.23: 1
//! running frequency, 2 set frequency, 6 torque, 7 power, 8 rotating speed (rpm), 11 fault
//! code; 0 echoes the received word; other values send 0.
//!
//! **Parameters:** the read-only P0680 (status word), P0681 (speed, 13 bits) and P10109
//! (process data in words) follow the drive's state in every step; a P0100 / P0101 (ramp
//! times) written through the card takes effect at once (until one is written, the model's
//! configured ramps apply — the test benches run shorter ramps than P0100's factory 5.0 s).
//!
//! Programmable PZD words are echoed (each input word = the output word of the same
//! position), so a PLC program can check its word mapping. In the Bypass operate mode
//! (OPTE3/E5 §5.1.2, §6.7) the card passes the raw words: the drive reads word 1 as its
//! FBFixedControlWord (OPTE3/E5 §11.1 Table 146: b0 run, b1 reverse, b2 fault reset edge)
//! and word 2 as the setpoint 0..10000 = 0..100 % (a negative word is refused as 0), and answers FBFixedStatusWord (§11.3
//! Table 149) and the actual speed 0..10000, the other words echoed.

pub mod model;
pub mod params;

use crate::dpm::host::{Host, Poll, Transport};
use crate::dpm::layout::operate_mode;
use crate::dpm::{CardEvent, CommState, DriveCommandImage, DriveStateImage, Family, PzdWords, Telegram};
use crate::profile::drive_if::{CommandFlags, DriveCommand, DriveStatus, StatusFlags};
use crate::time::Instant;
use model::{CommLossAction, DriveModel, N2_100};
use params::{sim_drive_table, DriveTable};

pub use model::ModelConfig as DriveConfig;

/// The drive fault codes the GSD's device-related diagnosis names (`Unit_Diag_Area` 16–23):
/// code → value. Other codes report 255 "other fault (see drive)".
pub const DIAG_FAULTS: [(u16, u8); 6] = [
    (0x2310, 1), // overcurrent
    (0x3210, 2), // DC link overvoltage
    (0x3220, 3), // DC link undervoltage
    (0x4310, 4), // motor overtemperature
    (0x4210, 5), // drive overtemperature
    (0x2330, 6), // earth fault
];

/// P0100 / P0101 of `t` (0.1 s).
fn ramp_params(t: &DriveTable) -> (u16, u16) {
    let get = |pnu| t.get(pnu, 0).map_or(0, |v| v.clamp(0, i64::from(u16::MAX)) as u16);
    (get(params::P_ACCELERATION_TIME), get(params::P_DECELERATION_TIME))
}

/// The device-related diagnosis block of the GSD (`gsd/ODCP0F11.gsd`): header 0x03, drive
/// status bits (b0 fault, b1 warning), fault value.
pub fn diag_block(status: &DriveStatus) -> [u8; 3] {
    let mut bits = 0u8;
    if status.flags.contains(StatusFlags::FAULT) {
        bits |= 1;
    }
    if status.flags.contains(StatusFlags::WARNING) {
        bits |= 2;
    }
    let value = match status.fault_code {
        0 => 0,
        c => DIAG_FAULTS.iter().find(|(k, _)| *k == c).map_or(255, |(_, v)| *v),
    };
    [0x03, bits, value]
}

/// Warning code of alarm A138 "PROFIBUS DP interface in Clear mode" (CFW500 §6).
pub const ALARM_CLEAR_MODE: u16 = 138;
/// Warning code of alarm A139 "PROFIBUS DP interface offline" (CFW500 §6).
pub const ALARM_OFFLINE: u16 = 139;
/// Warning code of alarm A140 "PROFIBUS DP module access error" (CFW500 §6).
pub const ALARM_ACCESS_ERROR: u16 = 140;

bitflags::bitflags! {
    /// The drive's communication alarms (module docs; CFW500 §6, CFW-11 §5).
    #[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
    pub struct CommAlarms: u8 {
        /// A138: the master is in Clear (CARD event 0, STATUS "Clear").
        const CLEAR_MODE = 1 << 0;
        /// A139: the card went offline (CARD event 1 "offline" or 3 "watchdog").
        const OFFLINE = 1 << 1;
        /// A140: the card's heartbeat stopped (the drive cannot reach the card).
        const ACCESS_ERROR = 1 << 2;
    }
}

impl CommAlarms {
    /// The warning code of the most severe active alarm (A140 over A139 over A138), 0 for none.
    pub fn warning_code(self) -> u16 {
        if self.contains(CommAlarms::ACCESS_ERROR) {
            ALARM_ACCESS_ERROR
        } else if self.contains(CommAlarms::OFFLINE) {
            ALARM_OFFLINE
        } else if self.contains(CommAlarms::CLEAR_MODE) {
            ALARM_CLEAR_MODE
        } else {
            0
        }
    }
}

/// Counters of the simulated drive.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct SimStats {
    /// Steps run.
    pub steps: u32,
    /// DRIVE_CMD reads that failed (torn on every attempt, transport error).
    pub command_errors: u32,
    /// DRIVE_STATE / DRIVE writes that failed.
    pub write_errors: u32,
    /// Communication alarms raised (A138 / A139 / A140, each counted).
    pub comm_alarms: u32,
}

/// The simulated drive's control board (module docs).
#[derive(Debug, Clone)]
pub struct SimDrive {
    model: DriveModel,
    table: DriveTable,
    vacon_ids: params::VaconIdTable,
    serve_parameters: bool,
    image: DriveCommandImage,
    command: DriveCommand,
    status: DriveStatus,
    bypass_cw: u16,
    bypass_resets: u8,
    /// P0100 / P0101 as last applied to the model (module docs, "parameters").
    ramps_applied: (u16, u16),
    diag: [u8; 3],
    alarms: CommAlarms,
    stats: SimStats,
    /// DPM DEVICE written (once after start).
    device_written: bool,
    /// DRIVE_STATE as sent last (the first exchange of a step sends it again while it fetches
    /// the newest command).
    sent: DriveStateImage,
    /// VACON ID 733 as last applied to the model (module docs, "communication errors").
    id733_applied: i64,
    /// VACON PNU 10119 fault history, 8-bit codes, newest first (module docs, "fault history").
    history: [u8; FAULT_HISTORY_LEN],
    /// The model's trip count when the history was last updated.
    trips_seen: u32,
}

/// Entries of VACON PNU 10119 "read fault history" (OPTE3/E5 Table 108: BYTE\[40\]).
pub const FAULT_HISTORY_LEN: usize = 40;
/// VACON PNU 10118 "clear fault history" (OPTE3/E5 Table 108: writing clears it).
pub const PNU_CLEAR_FAULT_HISTORY: u16 = 10118;
/// VACON PNU 10119 "read fault history" (OPTE3/E5 Table 108).
pub const PNU_READ_FAULT_HISTORY: u16 = 10119;

/// The 8-bit VACON fault code of a drive fault code for PNU 10119 (VACON fault list: F1
/// overcurrent, F2 overvoltage, F3 earth fault, F9 undervoltage, F14 unit overtemperature,
/// F16 motor overtemperature, F53 fieldbus communication); a code up to 255 as it is, any
/// other 255.
pub fn vacon_fault_code(code: u16) -> u8 {
    match code {
        0x2310 => 1,
        0x3210 => 2,
        0x2330 => 3,
        0x3220 => 9,
        0x4210 => 14,
        0x4310 => 16,
        model::FAULT_FIELDBUS | model::FAULT_CLEAR_MODE | model::FAULT_OFFLINE | model::FAULT_ACCESS_ERROR => 53,
        c if c <= 0xFF => c as u8,
        _ => 0xFF,
    }
}

/// What the simulated drive reports in DPM DEVICE (I&M0 SERIAL_NUMBER, HARDWARE_REVISION).
pub const SIM_DEVICE: crate::dpv1::im::DeviceIdent =
    crate::dpv1::im::DeviceIdent { serial_number: *b"SIM-DRIVE-000001", hardware_revision: 2 };

impl SimDrive {
    /// A drive at standstill, ready, with its factory parameter table.
    pub fn new(config: DriveConfig) -> Self {
        SimDrive {
            model: DriveModel::new(config),
            table: sim_drive_table(),
            vacon_ids: params::VACON_ID_TABLE,
            serve_parameters: true,
            image: DriveCommandImage::EMPTY,
            command: DriveCommand::default(),
            status: DriveStatus::default(),
            bypass_cw: 0,
            bypass_resets: 0,
            ramps_applied: ramp_params(&sim_drive_table()),
            diag: [0; 3],
            alarms: CommAlarms::empty(),
            stats: SimStats::default(),
            device_written: false,
            sent: DriveStateImage::EMPTY,
            id733_applied: params::VACON_ID_TABLE.get(params::ID_FIELDBUS_FAULT_RESPONSE, 0).unwrap_or(4),
            history: [0; FAULT_HISTORY_LEN],
            trips_seen: 0,
        }
    }

    /// VACON PNU 10119: the fault history, 8-bit codes, newest first, zeros after the last.
    pub fn fault_history(&self) -> &[u8; FAULT_HISTORY_LEN] {
        &self.history
    }

    /// The drive model.
    pub fn model(&self) -> &DriveModel {
        &self.model
    }
    /// The drive model, mutable (inject a fault, a warning, change its settings).
    pub fn model_mut(&mut self) -> &mut DriveModel {
        &mut self.model
    }
    /// The last DRIVE_CMD read.
    pub fn image(&self) -> &DriveCommandImage {
        &self.image
    }
    /// The command in force (from DRIVE_CMD, or decoded from the raw words in Bypass).
    pub fn command(&self) -> &DriveCommand {
        &self.command
    }
    /// The status written last.
    pub fn status(&self) -> &DriveStatus {
        &self.status
    }
    /// Actual speed (N2).
    pub fn actual_speed(&self) -> i16 {
        self.status.speed
    }
    /// The parameter table.
    pub fn params(&self) -> &DriveTable {
        &self.table
    }
    /// The VACON application parameters (reached through PNU 10001 and the PPO's PKW).
    pub fn vacon_ids(&self) -> &params::VaconIdTable {
        &self.vacon_ids
    }
    /// The VACON application parameters, mutable (the drive's commissioning).
    pub fn vacon_ids_mut(&mut self) -> &mut params::VaconIdTable {
        &mut self.vacon_ids
    }
    /// The parameter table, mutable.
    pub fn params_mut(&mut self) -> &mut DriveTable {
        &mut self.table
    }
    /// Whether the drive answers the parameter mailbox (default yes; off: a control board
    /// that does not answer — fault injection).
    pub fn set_serve_parameters(&mut self, on: bool) {
        self.serve_parameters = on;
    }
    /// The active communication alarms (A138 / A139 / A140, module docs).
    pub fn comm_alarms(&self) -> CommAlarms {
        self.alarms
    }
    /// Counters.
    pub fn stats(&self) -> SimStats {
        self.stats
    }

    /// Trip with `code` (see [`DIAG_FAULTS`]) and MELD_NAMUR bits `namur`.
    pub fn inject_fault(&mut self, code: u16, namur: u16) {
        self.model.inject_fault(code, namur);
    }

    /// One drive cycle at `now` through `host`.
    pub fn step<T: Transport>(&mut self, now: Instant, host: &mut Host<T>) {
        self.stats.steps = self.stats.steps.wrapping_add(1);
        // Two exchanges per drive cycle through `Host::cycle` (issue 16; one CYCLIC
        // transaction each in the steady state): the first fetches the newest command (the card
        // refreshed the armed reply after its step), the second delivers the status computed
        // from it before the card's next step, so the status is not a cycle late (one exchange
        // per cycle would send the status of the previous command: the Anybus-style lag).
        let first = host.cycle(now, &self.sent);
        let poll = first.poll;
        if !self.device_written {
            self.device_written = host.write_device_ident(&SIM_DEVICE).is_ok();
        }
        // A transport without CYCLIC: `cycle` ran the block accesses, STATUS included.
        let comm = if first.cyclic { first.comm } else { host.status().ok().map(|s| s.comm) };
        self.track_alarms(&poll, comm);
        match first.command {
            Some((_, img)) => self.image = img,
            None => self.stats.command_errors = self.stats.command_errors.wrapping_add(1),
        }
        let bypass = self.image.operate_mode == operate_mode::BYPASS;
        let invt = !bypass && matches!(self.image.telegram, Telegram::Vendor(Family::Invt, _));
        self.command = if bypass { self.bypass_command() } else { self.image.command };
        if invt {
            self.command.speed_setpoint = self.invt_setpoint();
        }
        if !self.alarms.is_empty() {
            // The communication error: the drive's P0313-style action, at once.
            self.command.flags |= CommandFlags::COMM_LOSS;
            if self.alarms.contains(CommAlarms::ACCESS_ERROR) {
                // The card is gone: its DRIVE_CMD (and Set_Prm reaction) is stale.
                self.command.comm_loss_reaction = 0;
            }
        }
        self.apply_ramps();
        self.apply_fieldbus_fault_response();
        self.model.set_comm_fault_code(if self.alarms.contains(CommAlarms::ACCESS_ERROR) {
            model::FAULT_ACCESS_ERROR
        } else if self.alarms.contains(CommAlarms::OFFLINE) {
            model::FAULT_OFFLINE
        } else if self.alarms.contains(CommAlarms::CLEAR_MODE) {
            model::FAULT_CLEAR_MODE
        } else {
            model::FAULT_FIELDBUS
        });
        self.status = self.model.step(now, &self.command);
        self.track_history();
        let action = CommLossAction::from_reaction(self.command.comm_loss_reaction)
            .unwrap_or(self.model.config().comm_loss_action);
        if !self.alarms.is_empty() && !action.trips() && self.status.warning_code == 0 {
            self.status.warning_code = self.alarms.warning_code();
            self.status.flags |= StatusFlags::WARNING;
        }
        let extra = if bypass {
            self.bypass_words()
        } else if invt {
            self.invt_words()
        } else {
            self.image.extra
        };
        self.update_parameters(&extra);
        let state = DriveStateImage { status: self.status, inputs_seq: 0, extra };
        let second = host.cycle(now, &state);
        if second.poll.error.is_some() {
            self.stats.write_errors = self.stats.write_errors.wrapping_add(1);
        }
        self.sent = state;
        if host.drive_report().fault_code != self.status.fault_code {
            host.set_fault(self.status.fault_code);
        }
        if host.drive_report().warning_code != self.status.warning_code {
            host.set_warning(self.status.warning_code);
        }
        let diag = diag_block(&self.status);
        if diag != self.diag {
            let blocks: &[u8] = if diag[1] == 0 { &[] } else { &diag };
            if host.set_ext_diag(blocks).is_ok() {
                self.diag = diag;
            }
        }
        if self.serve_parameters {
            // With its own number list (PNU 980, read by the card for its PNUs 980 … 989).
            let mut table = crate::profile::pnu::NumberList(&mut self.table);
            let ids = &mut self.vacon_ids;
            let history = &mut self.history;
            let _ = host.serve_parameters(&mut |req: &crate::dpm::MailboxRequest| {
                crate::dpm::host::Answer::Now(if let Some(answer) = fault_history(req, history) {
                    answer
                } else if req.pnu == params::VACON_DRIVE_PARAMETER {
                    // OPTE3/E5 §6.4.4.7 / §6.6.1: PNU 10001, the application ID as subindex.
                    let mut r = *req;
                    r.pnu = req.subindex;
                    r.subindex = 0;
                    crate::dpm::mailbox::execute(&r, ids)
                } else {
                    crate::dpm::mailbox::execute(req, &mut table)
                })
            });
        }
    }

    /// VACON ID 733 written (PNU 10001 / the PPO PKW): its action becomes the model's own
    /// communication-loss action (until then the model keeps the one it was built with).
    fn apply_fieldbus_fault_response(&mut self) {
        let v = self.vacon_ids.get(params::ID_FIELDBUS_FAULT_RESPONSE, 0).unwrap_or(self.id733_applied);
        if v != self.id733_applied {
            if let Some(a) = CommLossAction::from_vacon_733(v) {
                self.model.config_mut().comm_loss_action = a;
            }
            self.id733_applied = v;
        }
    }

    /// A new trip enters the fault history (PNU 10119), newest first.
    fn track_history(&mut self) {
        let trips = self.model.fault_count();
        if trips != self.trips_seen {
            self.trips_seen = trips;
            if let Some((code, _)) = self.model.fault() {
                self.history.copy_within(..FAULT_HISTORY_LEN - 1, 1);
                self.history[0] = vacon_fault_code(code);
            }
        }
    }

    /// INVT: the set frequency from the PZD word P15.02–P15.12 map to "1: set frequency"
    /// (INVT Table 2-6; the first such word): PZD2 is the card's setpoint (it scaled the word
    /// with Fmax), PZD3..PZD12 are the raw words (0–Fmax in 0.01 Hz, Fmax = 50.00 Hz); none
    /// (P15.02 = 0 "invalid", the manual's factory setting): the bus sets no frequency (0).
    fn invt_setpoint(&self) -> i16 {
        let source =
            (2..=12u16).find(|k| self.table.get(params::P_INVT_RECEIVED + k - 2, 0) == Some(params::INVT_FREQUENCY));
        match source {
            Some(2) => self.image.command.speed_setpoint,
            Some(k) => {
                let w = self.image.extra.words().get(usize::from(k - 3)).copied().unwrap_or(0);
                crate::profile::invt::Invt::scale(INVT_FMAX, INVT_FMAX).to_n2(i32::from(w))
            }
            None => 0,
        }
    }

    /// INVT: the transmitted PZD3..PZD12 per P15.14–P15.23 (INVT Table 2-8): 1 running
    /// frequency, 2 set frequency (0.01 Hz), 6 torque, 7 power (0.1 %), 8 rotating speed (rpm,
    /// P10111 = 100 %), 11 fault code; 0 "invalid" echoes the received word (the simulated
    /// drive's word-mapping check, as for every family); every other value sends 0.
    fn invt_words(&self) -> PzdWords {
        let s = &self.status;
        let hz = |n2: i16| crate::profile::invt::Invt::scale(INVT_FMAX, INVT_FMAX).from_n2(n2.saturating_abs()) as u16;
        let tenth_percent = |n2: i16| (i32::from(n2) * 1000 / N2_100) as i16 as u16;
        let rpm = (i32::from(s.speed) * i32::from(params::reference_speed_rpm(&self.table)) / N2_100) as i16 as u16;
        let received = self.image.extra.words();
        let mut words = [0u16; crate::dpm::layout::EXTRA_WORDS];
        let n = received.len();
        for (k, w) in words.iter_mut().enumerate().take(n) {
            let map = self.table.get(params::P_INVT_TRANSMITTED + 1 + k as u16, 0).unwrap_or(0);
            *w = match map {
                0 => received[k],
                1 => hz(s.speed),
                2 => hz(self.command.speed_setpoint),
                6 => tenth_percent(s.torque),
                7 => tenth_percent(s.power),
                8 => rpm,
                11 => s.fault_code,
                _ => 0,
            };
        }
        PzdWords::new(&words[..n]).unwrap_or(PzdWords::EMPTY)
    }

    /// P0100 / P0101 written (by the master, record 47 / 48 or the PKW): the model ramps with
    /// them from now on. Until then the model keeps its configured ramps.
    fn apply_ramps(&mut self) {
        let now = ramp_params(&self.table);
        if now.0 != self.ramps_applied.0 {
            self.model.config_mut().ramp_time = params::acceleration_time(&self.table);
        }
        if now.1 != self.ramps_applied.1 {
            self.model.set_deceleration_time(params::deceleration_time(&self.table));
        }
        self.ramps_applied = now;
    }

    /// The read-only parameters that show the drive's live state: P0680 status word (WEG
    /// CFW500 Table 4.2, of the command in force), P0681 speed in 13 bits (8192 = the
    /// reference speed P10111), P10109 process data in words (the input words sent).
    fn update_parameters(&mut self, inputs: &PzdWords) {
        use crate::profile::weg::{p0680, WegModel};
        let sw = p0680(WegModel::Cfw500, self.command.flags, &self.status);
        let _ = self.table.set(params::P_STATUS_WORD, 0, i64::from(sw));
        let n13 = WegModel::scale_13bit(1, 1).from_n2(self.status.speed);
        let _ = self.table.set(params::P_SPEED_13BIT, 0, i64::from(n13));
        let w = inputs.words();
        for k in 0..16u16 {
            let v = w.get(usize::from(k)).copied().unwrap_or(0);
            let _ = self.table.set(params::P_PD_IN, k, i64::from(v));
        }
    }

    /// A138 / A139 / A140 from the card's events, communication state and heartbeat
    /// (module docs).
    fn track_alarms(&mut self, poll: &Poll, comm: Option<CommState>) {
        let before = self.alarms;
        let ev = &poll.events;
        if ev.contains(CardEvent::ClearMode) || comm == Some(CommState::ClearMode) {
            self.alarms.insert(CommAlarms::CLEAR_MODE);
        }
        if ev.contains(CardEvent::Offline) || ev.contains(CardEvent::Watchdog) {
            self.alarms.insert(CommAlarms::OFFLINE);
        }
        match comm {
            Some(CommState::Online) => self.alarms.remove(CommAlarms::CLEAR_MODE | CommAlarms::OFFLINE),
            Some(CommState::ClearMode) => self.alarms.remove(CommAlarms::OFFLINE),
            _ => {}
        }
        if poll.card_lost {
            self.alarms.insert(CommAlarms::ACCESS_ERROR);
        }
        if poll.card_returned {
            self.alarms.remove(CommAlarms::ACCESS_ERROR);
        }
        let new = (self.alarms - before).bits().count_ones();
        self.stats.comm_alarms = self.stats.comm_alarms.wrapping_add(new);
    }

    /// Bypass: FBFixedControlWord (word 1) and the 0..10000 setpoint (word 2).
    fn bypass_command(&mut self) -> DriveCommand {
        let w = self.image.extra.words();
        let cw = w.first().copied().unwrap_or(0);
        // 0..10000 = 0.00..100.00 % (OPTE3/E5 §6.7.1), the direction in b1: a negative
        // word (above 0x7FFF) is out of range and taken as 0, never as +100 %.
        let sp = (w.get(1).copied().unwrap_or(0) as i16).clamp(0, 10_000) as i32;
        if cw & 0x0004 != 0 && self.bypass_cw & 0x0004 == 0 {
            self.bypass_resets = self.bypass_resets.wrapping_add(1);
        }
        self.bypass_cw = cw;
        let mut flags = CommandFlags::FIELDBUS_CONTROL;
        flags.set(CommandFlags::RUN, cw & 0x0001 != 0);
        flags.set(CommandFlags::REVERSE, cw & 0x0002 != 0);
        // The card's communication-loss flag stays valid in Bypass.
        flags |= self.image.command.flags & CommandFlags::COMM_LOSS;
        DriveCommand {
            flags,
            speed_setpoint: (sp * N2_100 / 10_000) as i16,
            fault_resets: self.bypass_resets,
            comm_loss_reaction: self.image.command.comm_loss_reaction,
        }
    }

    /// Bypass: FBFixedStatusWord, the actual speed 0..10000, the other words echoed.
    fn bypass_words(&self) -> PzdWords {
        let s = &self.status;
        let f = s.flags;
        let bits = [
            StatusFlags::READY,
            StatusFlags::RUNNING,
            StatusFlags::REVERSE,
            StatusFlags::FAULT,
            StatusFlags::WARNING,
            StatusFlags::AT_REFERENCE,
            StatusFlags::ZERO_SPEED,
            StatusFlags::FLUX_READY,
        ];
        let sw = bits.iter().enumerate().fold(0u16, |a, (i, b)| a | (u16::from(f.contains(*b)) << i));
        let actual = ((s.speed as i32).unsigned_abs() * 10_000 / N2_100 as u32).min(10_000) as u16;
        let mut words = [0u16; crate::dpm::layout::EXTRA_WORDS];
        let n = self.image.extra.words().len();
        words[..n].copy_from_slice(self.image.extra.words());
        if n >= 2 {
            words[0] = sw;
            words[1] = actual;
        }
        PzdWords::new(&words[..n]).unwrap_or(PzdWords::EMPTY)
    }
}

/// INVT Fmax of the simulated drive, 0.01 Hz (50.00 Hz, the card's default scale).
pub const INVT_FMAX: u32 = 5000;

/// PNU 10118 / 10119 (OPTE3/E5 Table 108) against the drive's fault history: a write of
/// 10118 (any value) clears it, a read of 10119 gives the 40 codes as an OctetString (one
/// value per element from the subindex on). `None` for every other request.
fn fault_history(
    req: &crate::dpm::MailboxRequest,
    history: &mut [u8; FAULT_HISTORY_LEN],
) -> Option<Result<crate::dpm::ParamValues, crate::profile::param::ParamError>> {
    use crate::dpm::{ParamValues, RequestKind};
    use crate::profile::param::{ErrorValue, Format};
    Some(match (req.pnu, req.kind) {
        (PNU_CLEAR_FAULT_HISTORY, RequestKind::Write) => {
            *history = [0; FAULT_HISTORY_LEN];
            Ok(ParamValues::NONE)
        }
        (PNU_CLEAR_FAULT_HISTORY, RequestKind::Read) if req.subindex == 0 && req.count <= 1 => {
            ParamValues::new(Format::WORD, 1, &[0, 0]).ok_or(ErrorValue::NOT_EXECUTABLE.into())
        }
        (PNU_READ_FAULT_HISTORY, RequestKind::Read) => {
            let first = usize::from(req.subindex);
            let n = usize::from(req.count.max(1));
            match history.get(first..first + n) {
                Some(v) => ParamValues::new(Format::OCTET_STRING, n as u8, v).ok_or(ErrorValue::NOT_EXECUTABLE.into()),
                None => Err(ErrorValue::INVALID_SUBINDEX.into()),
            }
        }
        (PNU_READ_FAULT_HISTORY, RequestKind::Write) => Err(ErrorValue::VALUE_CANNOT_BE_CHANGED.into()),
        (PNU_CLEAR_FAULT_HISTORY | PNU_READ_FAULT_HISTORY, _) => Err(ErrorValue::NO_DESCRIPTION.into()),
        _ => return None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn diag_block_follows_the_gsd() {
        let mut s = DriveStatus::default();
        assert_eq!(diag_block(&s), [0x03, 0, 0]);
        s.flags = StatusFlags::FAULT;
        s.fault_code = 0x3210;
        assert_eq!(diag_block(&s), [0x03, 1, 2]);
        s.fault_code = 0x1234;
        s.flags |= StatusFlags::WARNING;
        assert_eq!(diag_block(&s), [0x03, 3, 255]);
    }

    use crate::dpm::host::{DpmTransport, Options};
    use crate::dpm::{CardReport, Dpm, Status};
    use crate::time::Duration;
    use model::{FAULT_ACCESS_ERROR, FAULT_OFFLINE};

    /// The card's side of the DPM, scripted: heartbeat, event counters, STATUS, DRIVE_CMD.
    struct Card {
        report: CardReport,
        status: Status,
        command: DriveCommandImage,
        beating: bool,
    }

    impl Card {
        fn new() -> Self {
            let mut command = DriveCommandImage::EMPTY;
            command.command = DriveCommand {
                flags: CommandFlags::RUN | CommandFlags::FIELDBUS_CONTROL,
                speed_setpoint: 0x2000,
                ..DriveCommand::default()
            };
            let status = Status { comm: CommState::Online, ..Status::INACTIVE };
            Card { report: CardReport::default(), status, command, beating: true }
        }
        fn publish(&mut self, dpm: &mut Dpm) {
            if self.beating {
                self.report.heartbeat = self.report.heartbeat.wrapping_add(1).max(1);
            }
            let mut card = dpm.card();
            card.write_status(&self.status);
            card.write_card_report(&self.report);
            card.write_drive_command(&self.command);
        }
        fn raise(&mut self, e: CardEvent) {
            self.report.events[e as usize] = self.report.events[e as usize].wrapping_add(1);
        }
    }

    struct Rig {
        card: Card,
        host: Host<DpmTransport<Dpm>>,
        drive: SimDrive,
        now: Instant,
    }

    impl Rig {
        fn new(action: CommLossAction) -> Self {
            let host = Host::open(DpmTransport::new(Dpm::new()), Options::DEFAULT).unwrap();
            let drive = SimDrive::new(DriveConfig {
                ramp_time: Duration::from_millis(100),
                comm_loss_action: action,
                ..DriveConfig::DEFAULT
            });
            let mut r = Rig { card: Card::new(), host, drive, now: Instant::from_millis(0) };
            r.run(300);
            assert!(r.drive.actual_speed() > 0x1F00, "running at the setpoint");
            assert!(r.drive.comm_alarms().is_empty());
            r
        }
        /// Steps of 10 ms for `ms`.
        fn run(&mut self, ms: u64) {
            for _ in 0..ms / 10 {
                self.now = self.now + Duration::from_millis(10);
                self.card.publish(self.host.transport_mut().dpm_mut());
                self.drive.step(self.now, &mut self.host);
            }
        }
        /// The card goes online again, its command without COMM_LOSS.
        fn back_online(&mut self) {
            self.card.status.comm = CommState::Online;
            self.card.raise(CardEvent::Online);
            self.card.command.command.flags.remove(CommandFlags::COMM_LOSS);
        }
    }

    /// A138: Clear mode gives the drive's P0313-style action at once (before the card's
    /// DRIVE_CMD says so) and the alarm as warning; leaving Clear clears it.
    #[test]
    fn a138_clear_mode_applies_the_drives_action_and_clears() {
        let mut r = Rig::new(CommLossAction::RampStop);
        r.card.raise(CardEvent::ClearMode);
        r.card.status.comm = CommState::ClearMode;
        r.run(10);
        assert_eq!(r.drive.comm_alarms(), CommAlarms::CLEAR_MODE);
        assert!(r.drive.command().flags.contains(CommandFlags::COMM_LOSS));
        assert_eq!(r.drive.status().warning_code, ALARM_CLEAR_MODE);
        assert!(r.drive.status().flags.contains(StatusFlags::WARNING));
        assert_eq!(r.host.drive_report().warning_code, ALARM_CLEAR_MODE, "reported to the card");
        r.card.command.command.flags.insert(CommandFlags::COMM_LOSS);
        r.run(200);
        assert_eq!(r.drive.actual_speed(), 0, "ramp stop");
        assert!(!r.drive.model().modulating());
        // The master leaves Clear: the alarm disappears by itself (an alarm, not a fault).
        r.card.status.comm = CommState::Online;
        r.card.command.command.flags.remove(CommandFlags::COMM_LOSS);
        r.run(10);
        assert!(r.drive.comm_alarms().is_empty());
        assert_eq!(r.drive.status().warning_code, 0);
        r.run(300);
        assert!(r.drive.actual_speed() > 0x1F00, "runs again with the master's command");
        assert_eq!(r.drive.stats().comm_alarms, 1);
    }

    /// A139: the watchdog expiry (event 3) and leaving data exchange (event 1) raise it; the
    /// "fault" action trips (F239-style) and the fault stays after the alarm is gone.
    #[test]
    fn a139_offline_with_the_fault_action_trips_until_reset() {
        for event in [CardEvent::Watchdog, CardEvent::Offline] {
            let mut r = Rig::new(CommLossAction::Fault);
            r.card.raise(event);
            r.card.status.comm = CommState::Offline;
            r.run(10);
            assert_eq!(r.drive.comm_alarms(), CommAlarms::OFFLINE, "{event:?}");
            assert_eq!(r.drive.status().fault_code, FAULT_OFFLINE, "F239");
            assert_eq!(r.drive.status().warning_code, 0, "a fault, not an alarm");
            assert_eq!(r.host.drive_report().fault_code, FAULT_OFFLINE);
            r.back_online();
            r.run(10);
            assert!(r.drive.comm_alarms().is_empty());
            assert_eq!(r.drive.status().fault_code, FAULT_OFFLINE, "kept until a fault reset");
            r.card.command.command.fault_resets = 1;
            r.run(10);
            assert_eq!(r.drive.status().fault_code, 0);
        }
    }

    /// A139 at power-up: offline without a transition from online raises nothing.
    #[test]
    fn a139_not_at_power_up() {
        let host = Host::open(DpmTransport::new(Dpm::new()), Options::DEFAULT).unwrap();
        let mut r =
            Rig { card: Card::new(), host, drive: SimDrive::new(DriveConfig::DEFAULT), now: Instant::from_millis(0) };
        r.card.status.comm = CommState::Offline;
        r.card.command = DriveCommandImage::EMPTY;
        r.run(100);
        assert!(r.drive.comm_alarms().is_empty());
        assert_eq!(r.drive.status().fault_code, 0);
    }

    /// A140: the card's heartbeat stops; the drive's own action applies even though the
    /// card's stale DRIVE_CMD asks for another reaction and has no COMM_LOSS; the alarm goes
    /// when the card beats again.
    #[test]
    fn a140_card_lost_applies_the_drives_own_action() {
        for action in
            [CommLossAction::Coast, CommLossAction::QuickStop, CommLossAction::KeepLast, CommLossAction::Fault]
        {
            let mut r = Rig::new(action);
            r.card.command.command.comm_loss_reaction = 4; // stale "keep last" from Set_Prm
            r.card.beating = false;
            r.run(250);
            assert_eq!(r.drive.comm_alarms(), CommAlarms::ACCESS_ERROR, "{action:?}");
            assert_eq!(r.host.stats().card_losses, 1);
            assert_eq!(r.drive.command().comm_loss_reaction, 0, "the drive's own setting");
            match action {
                CommLossAction::Coast => assert!(!r.drive.model().modulating()),
                CommLossAction::QuickStop => {
                    r.run(600);
                    assert_eq!(r.drive.actual_speed(), 0);
                }
                CommLossAction::KeepLast => assert!(r.drive.actual_speed() > 0x1F00),
                _ => assert_eq!(r.drive.status().fault_code, FAULT_ACCESS_ERROR, "F240"),
            }
            if action != CommLossAction::Fault {
                assert_eq!(r.drive.status().warning_code, ALARM_ACCESS_ERROR);
            }
            r.card.beating = true;
            r.run(20);
            assert!(r.drive.comm_alarms().is_empty(), "{action:?}: the card beats again");
            if action != CommLossAction::Fault {
                assert_eq!(r.drive.status().warning_code, 0);
                r.run(500);
                assert!(r.drive.actual_speed() > 0x1F00, "{action:?}: runs again");
            }
        }
    }

    #[test]
    fn the_most_severe_alarm_is_the_warning() {
        assert_eq!(CommAlarms::all().warning_code(), ALARM_ACCESS_ERROR);
        assert_eq!((CommAlarms::CLEAR_MODE | CommAlarms::OFFLINE).warning_code(), ALARM_OFFLINE);
        assert_eq!(CommAlarms::CLEAR_MODE.warning_code(), ALARM_CLEAR_MODE);
        assert_eq!(CommAlarms::empty().warning_code(), 0);
    }
}
