//! A simulated AC drive behind the drive-neutral interface ([`crate::profile::drive_if`]):
//! what a drive's control board does with the card's [`DriveCommand`], far enough to be a
//! believable machine for every telegram (issue 6 item 7).
//!
//! * **Run / stop:** RUN modulates and ramps to the setpoint along [`ModelConfig::ramp_time`]
//!   (0 → 100 %); RUN cleared ramps to standstill, then the pulses go off; QUICK_STOP ramps
//!   along [`ModelConfig::quick_stop_time`]; COAST switches the pulses off at once (the motor
//!   coasts: the model lets the speed fall with [`ModelConfig::coast_time`]).
//! * **Ramp-function generator:** RAMP_HOLD holds it, RAMP_RESET drives its output to zero on
//!   the quick-stop ramp, SETPOINT_ZERO takes zero as the setpoint (normal ramp).
//! * **Jog / pre-excitation:** JOG1 / JOG2 run at [`ModelConfig::jog_speed`] (JOG2 reverse of
//!   it); PRE_EXCITE magnetises without turning (FLUX_READY).
//! * **Faults:** [`DriveModel::inject_fault`] trips (coast, FAULT, the code and MELD_NAMUR
//!   bits); a new [`DriveCommand::fault_resets`] count acknowledges it. FIELDBUS_FAULT from the
//!   card trips with [`FAULT_FIELDBUS`].
//! * **Local / remote:** a command without FIELDBUS_CONTROL (WEG P0967 b10 = 0 or P0684 b4 =
//!   0 "local", PROFIdrive b10 = 0) does not run the drive: the local control place has no
//!   run command in the simulation, so the drive ramps to a stop.
//! * **Communication loss:** while COMM_LOSS is set the drive applies the reaction asked in
//!   [`DriveCommand::comm_loss_reaction`], or its own [`ModelConfig::comm_loss_action`] when it
//!   is 0 (P0313-style: none, ramp stop, coast, quick stop, fault, keep the last setpoint;
//!   WEG P0313's "change to local" / "change to local keeping commands and reference";
//!   VACON ID 733's "alarm + preset frequency" / "fault: stop function"). Only "fault"
//!   acts on a drive that the fieldbus does not control (CFW500 §4 P0313).
//! * **Actual values:** current = magnetising share while modulating + a load share that
//!   grows with speed² + an acceleration share; torque and power follow; all N2.
//!
//! `no_std`, allocation-free, time passed in.

use crate::profile::drive_if::{CommandFlags, DriveCommand, DriveStatus, StatusFlags};
use crate::time::{Duration, Instant};

/// 100 % in the N2 coding.
pub const N2_100: i32 = 0x4000;
/// Micro-units per speed count (the ramp integrates in these, so no step is lost to rounding).
const MICRO: i64 = 1_000_000;

/// Fault code of a fieldbus fault (the card's profile reported FIELDBUS_FAULT or the
/// communication-loss action "fault"; WEG F238 / F239 / F240 with P0313 = 5, CFW500 §6).
pub const FAULT_FIELDBUS: u16 = 0x7510;
/// Fault F238 "PROFIBUS DP interface in Clear mode" (CFW500 §6): the communication-loss action
/// "fault" with alarm A138 active.
pub const FAULT_CLEAR_MODE: u16 = 238;
/// Fault F239 "PROFIBUS DP interface offline" (CFW500 §6): the action "fault" with A139.
pub const FAULT_OFFLINE: u16 = 239;
/// Fault F240 "PROFIBUS DP module access error" (CFW500 §6): the action "fault" with A140.
pub const FAULT_ACCESS_ERROR: u16 = 240;
/// MELD_NAMUR b7 "error communication bus" (OPTE3/E5 Table 21).
pub const NAMUR_BUS: u16 = 1 << 7;
/// MELD_NAMUR b15 "miscellaneous faults" (the only bit OPTE3/E5 sets, §6.3.2.2 note).
pub const NAMUR_MISC: u16 = 1 << 15;

/// The drive's own reaction to a communication loss (P0313-style).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum CommLossAction {
    /// Keep going with the last command.
    None,
    /// Ramp to standstill (OFF1).
    RampStop,
    /// Pulses off (OFF2).
    Coast,
    /// Quick stop (OFF3).
    QuickStop,
    /// Trip (the drive's communication fault code, [`DriveModel::set_comm_fault_code`]:
    /// F238 / F239 / F240 with the alarm, else [`FAULT_FIELDBUS`]).
    Fault,
    /// Keep running with the last setpoint.
    KeepLast,
    /// WEG P0313 = 3 "change to local" (CFW500 Table 4.1): the fieldbus command is dropped,
    /// the local control place commands (the simulation's has no run command: a ramp stop);
    /// the status shows the local place (no FIELDBUS_CONTROL).
    Local,
    /// WEG P0313 = 4 "change to local keeping commands and reference": local, with the
    /// enable and the speed reference received via the network kept.
    LocalKeep,
    /// VACON ID 733 = 2 "alarm + preset frequency" (OPTE3/E5 Table 141, VACON 100 family):
    /// run on at the preset frequency — the model's [`ModelConfig::jog_speed`].
    PresetFrequency,
    /// VACON ID 733 = 3 "fault: stop function": trip (the fault is shown at once) and stop
    /// along the deceleration ramp, pulses off at standstill (VACON's default stop function
    /// "ramping"); [`Self::Fault`] is ID 733 = 4 "fault: coast".
    FaultStop,
}

impl CommLossAction {
    /// The action for a [`DriveCommand::comm_loss_reaction`] code (1..=7: ramp stop, coast,
    /// quick stop, keep the last setpoint, and WEG P0313's options 3 / 4 / 5 — change to local,
    /// change to local keeping commands and reference, fault); 0 or an unknown code: `None`
    /// (the drive's own setting applies).
    pub const fn from_reaction(code: u8) -> Option<CommLossAction> {
        match code {
            1 => Some(CommLossAction::RampStop),
            2 => Some(CommLossAction::Coast),
            3 => Some(CommLossAction::QuickStop),
            4 => Some(CommLossAction::KeepLast),
            5 => Some(CommLossAction::Local),
            6 => Some(CommLossAction::LocalKeep),
            7 => Some(CommLossAction::Fault),
            _ => None,
        }
    }

    /// The action of VACON ID 733 "response to fieldbus fault" in the VACON 100 family's coding
    /// (OPTE3/E5 Table 141: 0 no action, 1 alarm, 2 alarm + preset frequency, 3 fault: stop
    /// function, 4 fault: coast); `None` for another value. 0 and 1 both keep the drive going
    /// (the simulated drive reports the communication alarm as its warning for both).
    pub const fn from_vacon_733(value: i64) -> Option<CommLossAction> {
        match value {
            0 | 1 => Some(CommLossAction::None),
            2 => Some(CommLossAction::PresetFrequency),
            3 => Some(CommLossAction::FaultStop),
            4 => Some(CommLossAction::Fault),
            _ => None,
        }
    }

    /// Whether the action trips the drive.
    pub const fn trips(self) -> bool {
        matches!(self, CommLossAction::Fault | CommLossAction::FaultStop)
    }
}

/// Settings of the simulated drive.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ModelConfig {
    /// Normal ramp: time from 0 to 100 % (and back). Zero = jump.
    pub ramp_time: Duration,
    /// Quick-stop ramp: time from 100 % to 0. Zero = jump.
    pub quick_stop_time: Duration,
    /// Coasting motor: time from 100 % to 0 without torque.
    pub coast_time: Duration,
    /// "At reference": largest |actual − setpoint| in N2 counts.
    pub setpoint_tolerance: u16,
    /// "Speed reached" comparison value in N2 counts.
    pub compare_speed: u16,
    /// Jog speed (N2).
    pub jog_speed: i16,
    /// The control place is the fieldbus (StatusFlags::FIELDBUS_CONTROL, ZSW1 b9).
    pub fieldbus_control_place: bool,
    /// The drive's own communication-loss reaction.
    pub comm_loss_action: CommLossAction,
}

impl ModelConfig {
    /// 2 s ramp, 0.5 s quick stop, 4 s coast, 1 % tolerance, comparison 100 %, jog 10 %,
    /// fieldbus control place, fault on communication loss.
    pub const DEFAULT: ModelConfig = ModelConfig {
        ramp_time: Duration::from_millis(2000),
        quick_stop_time: Duration::from_millis(500),
        coast_time: Duration::from_millis(4000),
        setpoint_tolerance: 0x00A4,
        compare_speed: 0x4000,
        jog_speed: 0x0666,
        fieldbus_control_place: true,
        comm_loss_action: CommLossAction::Fault,
    };
}

impl Default for ModelConfig {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// The simulated drive (see the module docs).
#[derive(Debug, Clone)]
pub struct DriveModel {
    config: ModelConfig,
    /// Actual speed in N2 counts × [`MICRO`].
    speed: i64,
    /// The power section modulates.
    modulating: bool,
    /// Ramp target in force (N2).
    target: i16,
    fault: Option<(u16, u16)>,
    warning: u16,
    resets_seen: Option<u8>,
    last_step: Option<Instant>,
    /// The last command taken (kept while the communication is lost with "keep last").
    last: DriveCommand,
    accelerating: bool,
    faults: u32,
    /// The fault code of the communication-loss action "fault" ([`Self::set_comm_fault_code`]).
    comm_fault_code: u16,
    /// Deceleration ramp (0 → 100 % time) when it differs from [`ModelConfig::ramp_time`]
    /// (WEG P0101 written, [`Self::set_deceleration_time`]).
    decel_time: Option<Duration>,
    /// The communication-loss action in force changed the control place to local (WEG
    /// P0313 = 3 / 4): the status shows no FIELDBUS_CONTROL.
    local: bool,
    /// The active fault came from "fault: stop function" (VACON ID 733 = 3): the motor ramps
    /// to standstill before the pulses go off.
    fault_ramp: bool,
}

impl DriveModel {
    /// A drive at standstill, ready, no fault.
    pub fn new(config: ModelConfig) -> Self {
        DriveModel {
            config,
            speed: 0,
            modulating: false,
            target: 0,
            fault: None,
            warning: 0,
            resets_seen: None,
            last_step: None,
            last: DriveCommand::default(),
            accelerating: false,
            faults: 0,
            comm_fault_code: FAULT_FIELDBUS,
            decel_time: None,
            local: false,
            fault_ramp: false,
        }
    }

    /// The fault code the communication-loss action "fault" trips with (the drive sets it from
    /// its active alarm: [`FAULT_CLEAR_MODE`], [`FAULT_OFFLINE`], [`FAULT_ACCESS_ERROR`];
    /// default [`FAULT_FIELDBUS`]). The card's FIELDBUS_FAULT always trips with
    /// [`FAULT_FIELDBUS`].
    pub fn set_comm_fault_code(&mut self, code: u16) {
        self.comm_fault_code = code;
    }

    /// The normal deceleration ramp (time from 100 % to 0; P0101-style); until set, the
    /// acceleration ramp [`ModelConfig::ramp_time`] serves both ways.
    pub fn set_deceleration_time(&mut self, t: Duration) {
        self.decel_time = Some(t);
    }

    /// Settings.
    pub fn config(&self) -> &ModelConfig {
        &self.config
    }
    /// Settings, mutable.
    pub fn config_mut(&mut self) -> &mut ModelConfig {
        &mut self.config
    }
    /// Actual speed (N2).
    pub fn speed(&self) -> i16 {
        (self.speed / MICRO).clamp(i16::MIN as i64, i16::MAX as i64) as i16
    }
    /// Whether the power section modulates.
    pub fn modulating(&self) -> bool {
        self.modulating
    }
    /// Active fault code and MELD_NAMUR bits.
    pub fn fault(&self) -> Option<(u16, u16)> {
        self.fault
    }
    /// Faults tripped so far.
    pub fn fault_count(&self) -> u32 {
        self.faults
    }

    /// Trip with `code` (MELD_NAMUR bits `namur`): pulses off, the motor coasts.
    pub fn inject_fault(&mut self, code: u16, namur: u16) {
        if self.fault.is_none() {
            self.faults = self.faults.wrapping_add(1);
        }
        self.fault = Some((code, namur));
        self.modulating = false;
    }

    /// Set (code ≠ 0) or clear the active warning.
    pub fn set_warning(&mut self, code: u16) {
        self.warning = code;
    }

    /// One step at `now` with the card's command; returns the drive's status.
    pub fn step(&mut self, now: Instant, cmd: &DriveCommand) -> DriveStatus {
        let dt = self.last_step.map_or(Duration::ZERO, |t| now - t);
        self.last_step = Some(now);
        // Fault acknowledge: a new count (the first command seen only sets the reference).
        if self.resets_seen.is_some_and(|r| r != cmd.fault_resets) && self.fault.is_some() {
            self.fault = None;
            self.fault_ramp = false;
        }
        self.resets_seen = Some(cmd.fault_resets);
        let cmd = self.effective(cmd);
        let f = cmd.flags;
        if f.contains(CommandFlags::FIELDBUS_FAULT) && self.fault.is_none() {
            // A drive already tripped keeps its first fault (F238 / F239 / F240 of the loss).
            self.inject_fault(FAULT_FIELDBUS, NAMUR_BUS);
        }
        let (target, rate) = self.decide(&cmd);
        self.ramp(dt, target, rate);
        self.status(&cmd)
    }

    /// The command in force: the card's, or the communication-loss reaction's.
    fn effective(&mut self, cmd: &DriveCommand) -> DriveCommand {
        // LOCAL (WEG P0967 b10 = 0 / P0684 b4 = 0): the fieldbus does not command the drive;
        // its local control place has no run command here (a ramp stop). The fault
        // acknowledges still count (they are the card's, not a run command).
        fn local(mut c: DriveCommand) -> DriveCommand {
            c.flags.remove(CommandFlags::RUN | CommandFlags::JOG1 | CommandFlags::JOG2 | CommandFlags::PRE_EXCITE);
            c.flags.remove(CommandFlags::FIELDBUS_CONTROL);
            c
        }
        if !cmd.flags.contains(CommandFlags::COMM_LOSS) {
            self.last = *cmd;
            self.local = false;
            if !cmd.flags.contains(CommandFlags::FIELDBUS_CONTROL) {
                return local(*cmd);
            }
            return *cmd;
        }
        let action = CommLossAction::from_reaction(cmd.comm_loss_reaction).unwrap_or(self.config.comm_loss_action);
        let mut c = self.last;
        c.fault_resets = cmd.fault_resets;
        if !c.flags.contains(CommandFlags::FIELDBUS_CONTROL) && !action.trips() {
            // WEG P0313 (CFW500 §4): the actions apply to a drive controlled via the network,
            // "with exception of option 'Causes a Fault', which blocks the equipment even if it
            // is not controlled by network".
            return local(c);
        }
        match action {
            CommLossAction::None | CommLossAction::KeepLast => {}
            CommLossAction::RampStop => c.flags.remove(CommandFlags::RUN),
            CommLossAction::Coast => c.flags.insert(CommandFlags::COAST),
            CommLossAction::QuickStop => c.flags.insert(CommandFlags::QUICK_STOP),
            CommLossAction::Local => {
                self.local = true;
                c = local(c);
            }
            CommLossAction::LocalKeep => self.local = true,
            CommLossAction::PresetFrequency => {
                c.speed_setpoint = self.config.jog_speed;
                c.flags.remove(CommandFlags::REVERSE | CommandFlags::SETPOINT_ZERO | CommandFlags::RAMP_HOLD);
            }
            CommLossAction::Fault | CommLossAction::FaultStop => {
                c.flags.remove(CommandFlags::FIELDBUS_FAULT);
                if self.fault.is_none() {
                    let modulating = self.modulating;
                    self.inject_fault(self.comm_fault_code, NAMUR_BUS);
                    if action == CommLossAction::FaultStop {
                        self.fault_ramp = true;
                        self.modulating = modulating;
                    }
                }
            }
        }
        c
    }

    /// Pulses on/off and the ramp target and time for this step.
    fn decide(&mut self, cmd: &DriveCommand) -> (i16, Duration) {
        let f = cmd.flags;
        let normal = self.config.ramp_time;
        let quick = self.config.quick_stop_time;
        if self.fault.is_some() && self.fault_ramp && self.modulating && !f.contains(CommandFlags::COAST) {
            // "Fault: stop function" (VACON ID 733 = 3): tripped, ramping to standstill.
            self.stop_at_standstill();
            return (0, self.decel_time.unwrap_or(normal));
        }
        if self.fault.is_some() || f.contains(CommandFlags::COAST) {
            self.modulating = false;
            return (0, self.config.coast_time);
        }
        let jog = f.intersects(CommandFlags::JOG1 | CommandFlags::JOG2);
        let run = f.contains(CommandFlags::RUN) || jog;
        if f.contains(CommandFlags::QUICK_STOP) {
            self.stop_at_standstill();
            return (0, quick);
        }
        if !run {
            if self.modulating {
                self.stop_at_standstill();
                return (0, self.decel_time.unwrap_or(normal));
            }
            return (0, self.config.coast_time);
        }
        self.modulating = true;
        if f.contains(CommandFlags::RAMP_RESET) {
            return (0, quick);
        }
        if f.contains(CommandFlags::RAMP_HOLD) {
            return (self.speed(), normal);
        }
        let mut sp = if f.contains(CommandFlags::JOG1) {
            self.config.jog_speed
        } else if f.contains(CommandFlags::JOG2) {
            self.config.jog_speed.saturating_neg()
        } else if f.contains(CommandFlags::SETPOINT_ZERO) {
            0
        } else {
            cmd.speed_setpoint
        };
        if f.contains(CommandFlags::REVERSE) {
            sp = sp.saturating_neg();
        }
        (sp, normal)
    }

    /// A stop ramp ends with the pulses off once the motor stands.
    fn stop_at_standstill(&mut self) {
        if self.speed == 0 {
            self.modulating = false;
        }
    }

    fn ramp(&mut self, dt: Duration, target: i16, time: Duration) {
        self.target = target;
        let target = target as i64 * MICRO;
        let dt_us = dt.as_micros().min(10_000_000) as i64;
        let step = match time.as_micros() {
            0 => i64::MAX,
            t => (N2_100 as i64 * MICRO).saturating_mul(dt_us) / t as i64,
        };
        let before = self.speed;
        self.speed = if self.speed < target {
            self.speed.saturating_add(step).min(target)
        } else {
            self.speed.saturating_sub(step).max(target)
        };
        self.accelerating = self.modulating && self.speed.unsigned_abs() > before.unsigned_abs();
    }

    fn status(&self, cmd: &DriveCommand) -> DriveStatus {
        let n = self.speed() as i32;
        let mut fl = StatusFlags::empty();
        fl.set(StatusFlags::READY, self.fault.is_none());
        fl.set(StatusFlags::RUNNING, self.modulating);
        fl.set(StatusFlags::REVERSE, n < 0);
        fl.set(StatusFlags::FAULT, self.fault.is_some());
        fl.set(StatusFlags::WARNING, self.warning != 0);
        let at = (n - self.target as i32).unsigned_abs() <= self.config.setpoint_tolerance as u32;
        fl.set(StatusFlags::AT_REFERENCE, self.modulating && at);
        fl.set(StatusFlags::ZERO_SPEED, n == 0);
        let excite = cmd.flags.contains(CommandFlags::PRE_EXCITE) && self.fault.is_none();
        fl.set(StatusFlags::FLUX_READY, self.modulating || excite);
        fl.set(StatusFlags::FIELDBUS_CONTROL, self.config.fieldbus_control_place && !self.local);
        fl.set(StatusFlags::SPEED_REACHED, n.unsigned_abs() >= self.config.compare_speed as u32);
        fl.set(StatusFlags::JOGGING, self.modulating && cmd.flags.intersects(CommandFlags::JOG1 | CommandFlags::JOG2));
        fl.set(StatusFlags::RAMP_SET_2, cmd.flags.contains(CommandFlags::RAMP_SET_2));
        // Load torque ∝ n² (a fan / pump), 60 % at 100 % speed, +40 % while accelerating;
        // current = 30 % magnetising + the torque share; power = torque × speed.
        let (torque, current) = if self.modulating || excite {
            let load = 0x4000i64 * 6 / 10 * (n as i64 * n as i64) / (N2_100 as i64 * N2_100 as i64);
            let acc = if self.accelerating { 0x4000 * 4 / 10 } else { 0 };
            let t = (load + acc).min(i16::MAX as i64);
            let t = if n < 0 { -t } else { t };
            let i = (0x4000 * 3 / 10 + t.abs() * 7 / 10).min(i16::MAX as i64);
            (t, i)
        } else {
            (0, 0)
        };
        let power = (torque * n as i64 / N2_100 as i64).clamp(i16::MIN as i64, i16::MAX as i64);
        let (fault_code, namur) = self.fault.unwrap_or((0, 0));
        DriveStatus {
            flags: fl,
            speed: self.speed(),
            current: current as i16,
            torque: torque as i16,
            power: power as i16,
            fault_code,
            warning_code: self.warning,
            namur,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Rig {
        m: DriveModel,
        now: Instant,
        cmd: DriveCommand,
        st: DriveStatus,
    }

    impl Rig {
        fn new() -> Self {
            let cfg = ModelConfig {
                ramp_time: Duration::from_millis(1000),
                quick_stop_time: Duration::from_millis(100),
                coast_time: Duration::from_millis(2000),
                ..ModelConfig::DEFAULT
            };
            Rig {
                m: DriveModel::new(cfg),
                now: Instant::from_millis(0),
                cmd: DriveCommand::default(),
                st: DriveStatus::default(),
            }
        }
        fn run(&mut self, ms: u64) -> DriveStatus {
            for _ in 0..ms.max(1) {
                self.now = self.now + Duration::from_millis(1);
                self.st = self.m.step(self.now, &self.cmd);
            }
            self.st
        }
        fn set(&mut self, flags: CommandFlags, sp: i16) {
            self.cmd.flags = flags | CommandFlags::FIELDBUS_CONTROL;
            self.cmd.speed_setpoint = sp;
        }
    }

    #[test]
    fn ramps_up_and_stops_along_the_ramp() {
        let mut r = Rig::new();
        let s = r.run(1);
        assert!(s.flags.contains(StatusFlags::READY) && !s.flags.contains(StatusFlags::RUNNING));
        r.set(CommandFlags::RUN, 0x4000);
        let s = r.run(250);
        assert_eq!(s.speed, 0x1000, "250 ms of a 1 s ramp");
        assert!(s.current > 4915 && s.torque > 0, "accelerating: current and torque");
        let s = r.run(750);
        assert_eq!(s.speed, 0x4000);
        assert!(s.flags.contains(StatusFlags::AT_REFERENCE | StatusFlags::SPEED_REACHED | StatusFlags::RUNNING));
        assert!(s.power > 0);
        r.set(CommandFlags::empty(), 0x4000);
        let s = r.run(500);
        assert_eq!(s.speed, 0x2000);
        assert!(s.flags.contains(StatusFlags::RUNNING));
        let s = r.run(501);
        assert_eq!(s.speed, 0);
        assert!(!s.flags.contains(StatusFlags::RUNNING) && s.flags.contains(StatusFlags::ZERO_SPEED));
        assert_eq!((s.current, s.torque, s.power), (0, 0, 0));
    }

    #[test]
    fn quick_stop_coast_and_reverse() {
        let mut r = Rig::new();
        r.set(CommandFlags::RUN | CommandFlags::REVERSE, 0x2000);
        let s = r.run(600);
        assert_eq!(s.speed, -0x2000);
        assert!(s.flags.contains(StatusFlags::REVERSE) && s.torque < 0 && s.power > 0);
        r.set(CommandFlags::RUN | CommandFlags::QUICK_STOP, 0x2000);
        let s = r.run(60);
        assert_eq!(s.speed, 0, "50 % in half the 100 ms quick-stop time");
        assert!(!s.flags.contains(StatusFlags::RUNNING));
        r.set(CommandFlags::RUN, 0x4000);
        r.run(1000);
        r.set(CommandFlags::RUN | CommandFlags::COAST, 0x4000);
        let s = r.run(1);
        assert!(!s.flags.contains(StatusFlags::RUNNING), "coast: pulses off at once");
        let s = r.run(999);
        assert_eq!(s.speed, 0x2000, "the motor coasts down over 2 s");
    }

    #[test]
    fn ramp_hold_reset_and_setpoint_zero() {
        let mut r = Rig::new();
        r.run(1);
        r.set(CommandFlags::RUN, 0x4000);
        r.run(500);
        r.set(CommandFlags::RUN | CommandFlags::RAMP_HOLD, 0x4000);
        assert_eq!(r.run(300).speed, 0x2000);
        r.set(CommandFlags::RUN | CommandFlags::SETPOINT_ZERO, 0x4000);
        assert_eq!(r.run(250).speed, 0x1000);
        r.set(CommandFlags::RUN | CommandFlags::RAMP_RESET, 0x4000);
        let s = r.run(30);
        assert_eq!(s.speed, 0);
        assert!(s.flags.contains(StatusFlags::RUNNING), "ramp reset keeps the pulses on");
    }

    #[test]
    fn faults_trip_and_are_acknowledged_by_a_new_count() {
        let mut r = Rig::new();
        r.set(CommandFlags::RUN, 0x4000);
        r.run(1000);
        r.m.inject_fault(0x2310, NAMUR_MISC);
        let s = r.run(1);
        assert!(s.flags.contains(StatusFlags::FAULT) && !s.flags.contains(StatusFlags::READY | StatusFlags::RUNNING));
        assert_eq!((s.fault_code, s.namur), (0x2310, NAMUR_MISC));
        assert!(r.run(5).flags.contains(StatusFlags::FAULT), "the same count does not acknowledge");
        r.cmd.fault_resets = r.cmd.fault_resets.wrapping_add(1);
        r.set(CommandFlags::empty(), 0);
        let s = r.run(1);
        assert!(!s.flags.contains(StatusFlags::FAULT) && s.flags.contains(StatusFlags::READY));
        assert_eq!(r.m.fault_count(), 1);
    }

    #[test]
    fn communication_loss_reactions() {
        for (code, own, running_after, faulted) in [
            (0, CommLossAction::Fault, false, true),
            (0, CommLossAction::None, true, false),
            (1, CommLossAction::Fault, false, false),
            (2, CommLossAction::Fault, false, false),
            (3, CommLossAction::Fault, false, false),
            (4, CommLossAction::Fault, true, false),
        ] {
            let mut r = Rig::new();
            r.m.config_mut().comm_loss_action = own;
            r.set(CommandFlags::RUN, 0x2000);
            r.run(600);
            // The card sends a zero command with COMM_LOSS: the last one stays in force.
            r.cmd = DriveCommand {
                flags: CommandFlags::COMM_LOSS,
                comm_loss_reaction: code,
                fault_resets: r.cmd.fault_resets,
                ..DriveCommand::default()
            };
            let s = r.run(3000);
            assert_eq!(s.flags.contains(StatusFlags::RUNNING), running_after, "reaction {code} / {own:?}");
            assert_eq!(s.flags.contains(StatusFlags::FAULT), faulted, "reaction {code} / {own:?}");
            if running_after {
                assert_eq!(s.speed, 0x2000);
            }
            if faulted {
                assert_eq!((s.fault_code, s.namur), (FAULT_FIELDBUS, NAMUR_BUS));
            }
        }
    }

    #[test]
    fn jog_and_pre_excitation() {
        let mut r = Rig::new();
        r.set(CommandFlags::JOG1, 0);
        let s = r.run(1000);
        assert_eq!(s.speed, 0x0666);
        assert!(s.flags.contains(StatusFlags::JOGGING));
        r.set(CommandFlags::empty(), 0);
        r.run(1000);
        r.set(CommandFlags::PRE_EXCITE, 0);
        let s = r.run(10);
        assert!(s.flags.contains(StatusFlags::FLUX_READY) && s.speed == 0 && s.current > 0);
    }

    proptest::proptest! {
        #[test]
        fn any_command_sequence_is_safe(cmds in proptest::collection::vec((proptest::prelude::any::<u16>(), proptest::prelude::any::<i16>(), 0u8..3, 0u8..6, 1u64..200), 1..40)) {
            let mut r = Rig::new();
            for (flags, sp, resets, reaction, ms) in cmds {
                r.cmd = DriveCommand { flags: CommandFlags::from_bits_retain(flags), speed_setpoint: sp, fault_resets: resets, comm_loss_reaction: reaction };
                let s = r.run(ms);
                proptest::prop_assert!(!(s.flags.contains(StatusFlags::FAULT) && s.flags.contains(StatusFlags::RUNNING)));
                proptest::prop_assert_eq!(s.flags.contains(StatusFlags::ZERO_SPEED), s.speed == 0);
                if !s.flags.contains(StatusFlags::RUNNING) && !s.flags.contains(StatusFlags::FLUX_READY) {
                    proptest::prop_assert_eq!((s.current, s.torque, s.power), (0, 0, 0));
                }
            }
        }
    }
}
