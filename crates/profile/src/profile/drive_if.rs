//! The drive-neutral command / status interface between the card's profile layer and the
//! drive's control board (issue 6 item 2, ARCHITECTURE §5).
//!
//! The card owns the fieldbus profile (PROFIdrive 4.1 for the standard telegrams, PROFIdrive 2.0
//! for the PPO types, the WEG manufacturer profile, the INVT control word): it interprets the
//! PLC's control word and setpoint and tells the drive, in one form that does not depend on
//! the telegram, what to do. The drive answers in one form too; the profile builds the status
//! word and actual values the PLC expects from it. The model is the drive-internal fieldbus
//! control / status word of a VACON drive behind an OPTE3/E5 board (OPTE3/E5 appendix §11.1
//! Table 146 FBFixedControlWord, §11.3 Table 149 FBFixedStatusWord), extended with what the
//! WEG (CFW500 §5.1, P0684 / P0680) and INVT (§2.6 control word commands 1–9) profiles need.
//!
//! Scaling: every speed, current, torque and power is an N2 value, 0x4000 = 100 % of the
//! drive's reference (speed: PNU 10111-style reference speed, OPTE3/E5 §6.3.7; current:
//! PNU 10116 rated current; torque: rated torque; power: rated power), negative = reverse.
//! A profile with another scale (WEG's 13-bit 8192 = rated frequency, VACON bypass's
//! 0..10000 = 0.00..100.00 %) converts at the profile layer, never in the drive.
//!
//! Both structures are plain values: the DPM carries them in sequenced blocks (see
//! `pbcard::dpm`), so the drive always sees one consistent command and the card one
//! consistent status.

bitflags::bitflags! {
    /// What the card asks of the drive (OPTE3/E5 §11.1 Table 146 model).
    ///
    /// Priority when several stop requests are set: [`Self::COAST`] over [`Self::QUICK_STOP`]
    /// over "[`Self::RUN`] cleared" (ramp stop) — the PROFIdrive order (OPTE3/E5 §6.3.1
    /// Table 14: OFF2 before OFF3 before OFF1).
    #[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
    pub struct CommandFlags: u16 {
        /// b0 Run request: modulate and follow the setpoint. Cleared = stop along the normal
        /// deceleration ramp (OFF1), then pulses off at standstill.
        const RUN = 1 << 0;
        /// b1 Requested direction reverse (the setpoint's sign is applied on top: a negative
        /// setpoint with REVERSE runs forward). Used by profiles with a direction bit (WEG
        /// P0684 b2, INVT "reverse run", VACON bypass b1).
        const REVERSE = 1 << 1;
        /// b2 Coast stop (OFF2 / run disable): pulses off now, the motor coasts.
        const COAST = 1 << 2;
        /// b3 Quick stop (OFF3): decelerate along the quick-stop ramp, pulses off at
        /// standstill.
        const QUICK_STOP = 1 << 3;
        /// b4 Hold the ramp-function generator output. No profile sets it today: PROFIdrive
        /// STW1 b5 = 0 freezes the setpoint only (OPTE3/E5 Table 26), which the profile does
        /// itself by holding [`DriveCommand::speed_setpoint`].
        const RAMP_HOLD = 1 << 4;
        /// b5 Setpoint to zero (PROFIdrive STW1 b6 = 0): decelerate along the normal ramp to
        /// zero speed while still running.
        const SETPOINT_ZERO = 1 << 5;
        /// b6 Reset the ramp-function generator (PROFIdrive STW1 b4 = 0): the speed goes to
        /// zero as fast as possible (quick-stop ramp) while still running.
        const RAMP_RESET = 1 << 6;
        /// b7 The fieldbus has control: the PLC's words are valid (PROFIdrive STW1 b10, WEG
        /// P0684 b4 LOC/REM = REM from the network). Cleared while the drive runs from the
        /// fieldbus = the communication-error situation; see [`Self::COMM_LOSS`].
        const FIELDBUS_CONTROL = 1 << 7;
        /// b8 Jog with jog reference 1 (INVT 3/4, WEG P0684 b3, VACON b10).
        const JOG1 = 1 << 8;
        /// b9 Jog with jog reference 2 (VACON b11).
        const JOG2 = 1 << 9;
        /// b10 Second ramp set / parameter set 2 (WEG P0684 b5 "2nd ramp", ST20 STW1 b15).
        const RAMP_SET_2 = 1 << 10;
        /// b11 Pre-excitation: magnetise the motor without turning it (INVT command 9).
        const PRE_EXCITE = 1 << 11;
        /// b12 Communication lost (DP watchdog expired, master in Clear, master gone, or
        /// control by PLC dropped while running): apply the drive's communication-error action
        /// (P0313-style; the card's `pbcard::card::PRM_COMM_LOSS_REACTION` may override it
        /// through [`DriveCommand::comm_loss_reaction`]).
        const COMM_LOSS = 1 << 12;
        /// b13 The card's profile layer is in fault (e.g. PROFIdrive: control by PLC dropped
        /// in operation): the drive should trip with a fieldbus fault.
        const FIELDBUS_FAULT = 1 << 13;
    }
}

bitflags::bitflags! {
    /// What the drive reports (OPTE3/E5 §11.3 Table 149 model).
    #[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
    pub struct StatusFlags: u16 {
        /// b0 Ready: no fault, power section ready, the drive would start on RUN.
        const READY = 1 << 0;
        /// b1 Running: the power section modulates (the motor is powered).
        const RUNNING = 1 << 1;
        /// b2 The motor turns in reverse.
        const REVERSE = 1 << 2;
        /// b3 A fault is active (tripped).
        const FAULT = 1 << 3;
        /// b4 A warning (alarm) is active.
        const WARNING = 1 << 4;
        /// b5 Running at the reference speed (within the drive's tolerance).
        const AT_REFERENCE = 1 << 5;
        /// b6 Zero speed (standstill).
        const ZERO_SPEED = 1 << 6;
        /// b7 Motor magnetised (flux ready).
        const FLUX_READY = 1 << 7;
        /// b8 The drive's control place is the fieldbus (it wants control by the PLC:
        /// PROFIdrive ZSW1 b9, WEG P0680 b12 LOC/REM).
        const FIELDBUS_CONTROL = 1 << 8;
        /// b9 The comparison speed is reached or exceeded (PROFIdrive ZSW1 b10).
        const SPEED_REACHED = 1 << 9;
        /// b10 Current or torque limit reached (ST20 ZSW1 b11 inverted).
        const LIMIT_REACHED = 1 << 10;
        /// b11 Motor overload (ST20 ZSW1 b13 inverted).
        const MOTOR_OVERLOAD = 1 << 11;
        /// b12 Jogging.
        const JOGGING = 1 << 12;
        /// b13 Undervoltage of the DC link (WEG P0680 b13).
        const UNDERVOLTAGE = 1 << 13;
        /// b14 The drive's control comes from the fieldbus ramp set 2 (WEG P0680 b5).
        const RAMP_SET_2 = 1 << 14;
    }
}

/// The command the card writes for the drive (one consistent value per bus cycle).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub struct DriveCommand {
    /// Run / stop kinds / direction / ramp and control-place bits.
    pub flags: CommandFlags,
    /// Speed setpoint, N2 (0x4000 = 100 % of the reference speed, negative = reverse).
    pub speed_setpoint: i16,
    /// Fault acknowledges requested so far (wrapping counter): +1 on each acknowledge edge of
    /// the profile (PROFIdrive STW1 b7 0 → 1, WEG P0684 b7, INVT command 7). A counter, not a
    /// level, so a sampled image never loses or repeats an edge.
    pub fault_resets: u8,
    /// Requested communication-loss reaction while [`CommandFlags::COMM_LOSS`] is set:
    /// 0 = the drive's own setting, 1 = ramp stop, 2 = coast, 3 = quick stop, 4 = keep the
    /// last setpoint, and WEG P0313's options 3 / 4 / 5 (CFW500 Table 4.1): 5 = change to
    /// local, 6 = change to local keeping commands and reference, 7 = fault, also when the
    /// drive is not controlled via the network (the card's Set_Prm user parameter
    /// `PRM_COMM_LOSS_REACTION`; the DPM CONFIG.COMM_LOSS_REACTION carries 0..4 only).
    pub comm_loss_reaction: u8,
}

/// The status the drive writes for the card (one consistent value per drive cycle).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub struct DriveStatus {
    /// Ready / running / fault / warning / speed bits.
    pub flags: StatusFlags,
    /// Actual speed, N2 (0x4000 = 100 % of the reference speed, negative = reverse).
    pub speed: i16,
    /// Output current, N2 (0x4000 = 100 % of the rated current, PNU 10116).
    pub current: i16,
    /// Active current / torque, N2 (0x4000 = 100 % of the rated torque).
    pub torque: i16,
    /// Active power, N2 (0x4000 = 100 % of the rated power).
    pub power: i16,
    /// Active fault code (drive-specific, 0 = none).
    pub fault_code: u16,
    /// Active warning code (drive-specific, 0 = none).
    pub warning_code: u16,
    /// MELD_NAMUR bits of the active fault (OPTE3/E5 §6.3.2.2 Table 21; CFW-11 P0763).
    pub namur: u16,
}

impl DriveStatus {
    /// Whether the motor is at standstill (not modulating, or modulating at zero speed).
    pub fn standstill(&self) -> bool {
        !self.flags.contains(StatusFlags::RUNNING) || self.flags.contains(StatusFlags::ZERO_SPEED)
    }
}

/// A control profile: how one family of telegrams turns the PLC's control word and main
/// setpoint into a [`DriveCommand`], and the drive's [`DriveStatus`] into the status word and
/// main actual value the PLC reads (PROFIdrive 4.1 for ST1 / ST20 / vendor telegrams,
/// PROFIdrive 2.0 for the PPO types — OPTE3/E5 §5.1 note; the WEG manufacturer profile,
/// CFW500 §5.1; the INVT control word, INVT §2.6).
///
/// The cyclic engine calls [`Self::command`] for every new output image and on every
/// housekeeping step with the last one (so transitions that wait for the drive — standstill,
/// fault cleared — happen without new bus traffic), and [`Self::comm_lost`] while the
/// communication is lost (watchdog expired, master in Clear, master gone).
pub trait ControlProfile {
    /// The command for the control word `cw` and main setpoint `setpoint` (raw 16-bit words
    /// as on the wire, in the profile's own scale), given the drive's latest status.
    fn command(&mut self, cw: u16, setpoint: u16, drive: &DriveStatus) -> DriveCommand;
    /// The command while the communication is lost (the profile keeps its state; the drive
    /// applies its communication-error action, [`CommandFlags::COMM_LOSS`]).
    fn comm_lost(&mut self, drive: &DriveStatus) -> DriveCommand;
    /// The command while the master is in Clear (its outputs are zero, reference §3.6): by
    /// default [`Self::comm_lost`]; a profile whose zero control word has a meaning of its own
    /// reacts to it too (VACON PROFIdrive: b10 = 0 in operation → FAULT, OPTE3/E5 §6.3.3).
    fn clear(&mut self, drive: &DriveStatus) -> DriveCommand {
        self.comm_lost(drive)
    }
    /// The status word for the PLC.
    fn status_word(&self, drive: &DriveStatus) -> u16;
    /// The main actual value (speed) for the PLC, in the profile's scale, as a raw word.
    fn actual_value(&self, drive: &DriveStatus) -> u16;
}
