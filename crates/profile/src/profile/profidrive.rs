//! The PROFIdrive control profiles: PROFIdrive 4.1 (Standard Telegrams 1 and 20, VACON
//! telegrams 100 / 101 / 138 / 139, WEG's P0741 = PROFIdrive) and PROFIdrive 2.0 (the PPO
//! types), as [`ControlProfile`]s on the drive-neutral interface of [`super::drive_if`].
//!
//! Sources: VACON OPTE3/E5 manual §6.3.1 (Figure 11 general state diagram, Table 14
//! transitions), §6.3.2.2 (Tables 18/19 ST20 modifications), §6.3.3 (Table 26 STW1), §6.3.4
//! (Table 27 ZSW1), §6.3.5–6.3.7 (setpoint / actual value, 0x4000 = 100 % of PNU 10111),
//! §6.3.8 (Tables 32–35 command sequences), §6.5 (PROFIdrive 2.0: Tables 114/115 control word,
//! Table 117 status word), §6.3.5 / §6.7.1 (bypass scale 0..10000 = 0.00..100.00 %); WEG CFW500
//! §4 P0967 / P0968 and CFW-11 §3 (the same words, with bits the WEG drives do not use).
//!
//! # The general state diagram (OPTE3/E5 §6.3.1 Table 14)
//!
//! | state | ZSW1 b0 b1 b2 b3 b6 | left by (highest priority first) | drive command |
//! |---|---|---|---|
//! | S1 switching on inhibited | b6 | #1 b0 = 0, b1 = b2 = 1 and the drive READY (ZSW1 b13) → S2 (0x047E) | pulses off (COAST) |
//! | S2 ready for switching on | b0 | #2 b1 = 0 or b2 = 0 → S1; #3 b0 = 1 → S3 | pulses off |
//! | S3 switched on | b0 b1 | #4 b1 = 0 or b2 = 0 → S1; #5 b0 = 0 → S2; #6 b3 = 1 and the drive's control place is the fieldbus (ZSW1 b9) → S4 | pulses off |
//! | S4 operation | b0 b1 b2 | #7 b1 = 0 → S1 (coast); #8 b2 = 0 → S5 quick; #9 b0 = 0 → S5 ramp; #10 b3 = 0 → S3 (pulses off: the motor coasts, §6.3.3 bit 3) | RUN |
//! | S5 switching off (ramp) | b0 b1 | #11 b1 = 0 → S1; #12 b2 = 0 → S5 quick; #14 b0 = b3 = 1 → S4; #13 standstill or b3 = 0 → S2 | ramp stop (RUN cleared) |
//! | S5 switching off (quick) | b0 b1 | #11 b1 = 0 → S1; #15 standstill or b3 = 0 → S1 | QUICK_STOP |
//! | fault | b3 | a b7 0 → 1 edge, then the drive's fault cleared → S1 | pulses off |
//!
//! A drive fault ([`StatusFlags::FAULT`]) puts every state into the fault state; it is taken
//! before the control word's acknowledge, so a b7 edge in the cycle the drive trips is not
//! lost. The drive losing READY without a fault takes S2, S3 and S4 back to S1. Transitions
//! chain within one evaluation (0x047F takes S2 through S3 to S4), and the cyclic engine calls
//! [`ControlProfile::command`] on every housekeeping step with the last image, so transitions
//! that wait for the drive (standstill, fault cleared, READY, fieldbus control place) happen
//! without new bus traffic.
//!
//! # Control by PLC (STW1 b10, OPTE3/E5 §6.3.3 bit 10)
//!
//! With b10 = 0 the control word is not evaluated: a stopped drive cannot be started (the state
//! stays, the command loses [`CommandFlags::FIELDBUS_CONTROL`]). If b10 drops while the drive is
//! operating (S4 or S5) the profile freezes the process data — the drive keeps receiving the
//! last valid [`DriveCommand`] — and goes to the fault state with
//! [`CommandFlags::FIELDBUS_FAULT`] set; the drive reacts as it is parameterised. A b7 edge in
//! a valid word acknowledges it. The frozen command keeps `FIELDBUS_CONTROL` set on purpose: the
//! drive must not fall back to another control place while the fieldbus fault is pending.
//! Clear mode counts as b10 = 0 (its outputs are zero; [`ControlProfile::clear`]): leaving
//! Clear needs the acknowledge and a new switch-on. WEG's P0967 reads b10 as LOCAL / REMOTE
//! only ([`ProfidriveConfig::b10_is_local_remote`], `super::weg::weg_profidrive`).
//!
//! # Setpoint freeze (STW1 b5, OPTE3/E5 Table 26)
//!
//! b5 = 0 holds the setpoint (the setpoint word is not taken over); the ramp-function
//! generator runs on to it — no [`CommandFlags::RAMP_HOLD`].
//!
//! # Fault acknowledge (STW1 b7)
//!
//! Every 0 → 1 edge of b7 (WEG: b7 = 1 in the fault state, once per fault,
//! [`ProfidriveConfig::ack_on_level`]) in a valid control word adds one to [`DriveCommand::fault_resets`]
//! (also outside the fault state: the drive resets warnings and infos too, OPTE3/E5 §11.1
//! Table 146 b2). An edge in the fault state also arms the exit: the profile leaves the fault
//! state for S1 once the drive reports its fault cleared.

use super::drive_if::{CommandFlags, ControlProfile, DriveCommand, DriveStatus, StatusFlags};

bitflags::bitflags! {
    /// STW1, PROFIdrive control word 1 (OPTE3/E5 §6.3.3 Table 26, ST20 Table 18; WEG P0967;
    /// PROFIdrive 2.0 Table 114 uses the same positions for b0–b7 and b10).
    #[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
    pub struct Stw1: u16 {
        /// b0 ON (1) / OFF1 (0: ramp stop).
        const ON = 1 << 0;
        /// b1 no coast stop (0: OFF2, coast stop).
        const NO_COAST_STOP = 1 << 1;
        /// b2 no quick stop (0: OFF3, quick stop).
        const NO_QUICK_STOP = 1 << 2;
        /// b3 enable operation (0: disable operation, pulses off).
        const ENABLE_OPERATION = 1 << 3;
        /// b4 enable the ramp-function generator (0: reset it, the speed goes to zero fast).
        const ENABLE_RAMP = 1 << 4;
        /// b5 unfreeze (0: freeze the setpoint; the ramp-function generator runs on — OPTE3/E5
        /// Table 26 "freeze setpoint").
        const UNFREEZE_RAMP = 1 << 5;
        /// b6 enable the setpoint (0: setpoint 0).
        const ENABLE_SETPOINT = 1 << 6;
        /// b7 fault acknowledge (0 → 1 edge).
        const FAULT_ACK = 1 << 7;
        /// b8 jog 1 on (WEG P0967 only; "not used" at VACON).
        const JOG1 = 1 << 8;
        /// b10 control by PLC (the words are valid).
        const CONTROL_BY_PLC = 1 << 10;
        /// b11 setpoint inversion (ST20 Table 18 only).
        const SETPOINT_INVERSION = 1 << 11;
        /// b15 parameter set 2 (ST20 Table 18 only).
        const PARAMETER_SET_2 = 1 << 15;
        const _ = !0;
    }
}

bitflags::bitflags! {
    /// ZSW1, PROFIdrive status word 1 (OPTE3/E5 §6.3.4 Table 27, ST20 Table 19; WEG P0968;
    /// PROFIdrive 2.0 Table 117). b11–b15 mean different things in ST1 and ST20; both names
    /// are given.
    #[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
    pub struct Zsw1: u16 {
        /// b0 ready to switch on.
        const READY_TO_SWITCH_ON = 1 << 0;
        /// b1 ready to operate (switched on).
        const READY_TO_OPERATE = 1 << 1;
        /// b2 operation enabled (the drive follows the setpoint).
        const OPERATION_ENABLED = 1 << 2;
        /// b3 fault present.
        const FAULT = 1 << 3;
        /// b4 coast stop not activated.
        const NO_COAST_STOP = 1 << 4;
        /// b5 quick stop not activated.
        const NO_QUICK_STOP = 1 << 5;
        /// b6 switching on inhibited.
        const SWITCHING_ON_INHIBITED = 1 << 6;
        /// b7 warning present.
        const WARNING = 1 << 7;
        /// b8 speed error within the tolerance range (running at setpoint).
        const AT_SETPOINT = 1 << 8;
        /// b9 control by PLC requested (the drive's control place is the fieldbus).
        const CONTROL_REQUESTED = 1 << 9;
        /// b10 f or n reached or exceeded.
        const SPEED_REACHED = 1 << 10;
        /// b11 (ST20) current or torque limit not reached.
        const NO_LIMIT_REACHED = 1 << 11;
        /// b12 (ST1) the drive is running.
        const RUNNING = 1 << 12;
        /// b13 (ST1) the drive is ready for operation.
        const DRIVE_READY = 1 << 13;
        /// b13 (ST20) motor overload not activated.
        const NO_MOTOR_OVERLOAD = 1 << 13;
        /// b14 (ST20) positive speed direction.
        const POSITIVE_DIRECTION = 1 << 14;
        /// b15 (ST20) parameter set 2 active.
        const PARAMETER_SET_2 = 1 << 15;
    }
}

/// The ZSW1 state bits (b0, b1, b2, b3, b6).
pub const ZSW1_STATE_BITS: u16 = 0x004F;

/// How S5 brings the motor to standstill.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum StopKind {
    /// OFF1: along the normal ramp, then S2 (Table 14 #9, #13).
    Ramp,
    /// OFF3: along the quick-stop ramp, then S1 (Table 14 #8, #12, #15).
    Quick,
}

/// The states of the general state diagram (OPTE3/E5 §6.3.1 Figure 11).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum State {
    /// S1 switching on inhibited.
    SwitchingOnInhibited,
    /// S2 ready for switching on.
    ReadyToSwitchOn,
    /// S3 switched on.
    SwitchedOn,
    /// S4 operation.
    Operation,
    /// S5 switching off.
    SwitchingOff(StopKind),
    /// Fault (acknowledge with a STW1 b7 rising edge).
    Fault,
}

impl State {
    /// A readable name ("S4 operation").
    pub const fn name(self) -> &'static str {
        match self {
            State::SwitchingOnInhibited => "S1 switching on inhibited",
            State::ReadyToSwitchOn => "S2 ready for switching on",
            State::SwitchedOn => "S3 switched on",
            State::Operation => "S4 operation",
            State::SwitchingOff(StopKind::Ramp) => "S5 switching off (ramp stop)",
            State::SwitchingOff(StopKind::Quick) => "S5 switching off (quick stop)",
            State::Fault => "fault",
        }
    }

    /// The ZSW1 state bits b0, b1, b2, b3 and b6 (Figure 11).
    pub const fn zsw1(self) -> Zsw1 {
        match self {
            State::SwitchingOnInhibited => Zsw1::SWITCHING_ON_INHIBITED,
            State::ReadyToSwitchOn => Zsw1::READY_TO_SWITCH_ON,
            State::SwitchedOn | State::SwitchingOff(_) => Zsw1::READY_TO_SWITCH_ON.union(Zsw1::READY_TO_OPERATE),
            State::Operation => Zsw1::READY_TO_SWITCH_ON.union(Zsw1::READY_TO_OPERATE).union(Zsw1::OPERATION_ENABLED),
            State::Fault => Zsw1::FAULT,
        }
    }

    /// Whether the drive is operating (S4, S5): the states in which losing control by PLC is
    /// a fieldbus fault (§6.3.3 bit 10).
    pub const fn is_operating(self) -> bool {
        matches!(self, State::Operation | State::SwitchingOff(_))
    }
}

/// One transition (or none) of the general state diagram for a valid control word (Table 14,
/// highest priority first). The fault state is left elsewhere (it needs the acknowledge).
pub fn transition(state: State, stw: Stw1, drive: &DriveStatus) -> State {
    use State::*;
    let off2 = !stw.contains(Stw1::NO_COAST_STOP);
    let off3 = !stw.contains(Stw1::NO_QUICK_STOP);
    let on = stw.contains(Stw1::ON);
    let enable = stw.contains(Stw1::ENABLE_OPERATION);
    let ready = drive.flags.contains(StatusFlags::READY);
    let fieldbus = drive.flags.contains(StatusFlags::FIELDBUS_CONTROL);
    let fault = drive.flags.contains(StatusFlags::FAULT);
    match state {
        // The drive is no longer ready (ZSW1 b13 drops) without a fault: S2..S4 fall back
        // to S1 (Figure 11: S2 and above need "ready"; a fault is the fault state instead).
        ReadyToSwitchOn | SwitchedOn | Operation if !ready && !fault => SwitchingOnInhibited,
        // #1: requires that the drive is READY (ZSW1 b13).
        SwitchingOnInhibited if !on && !off2 && !off3 && ready => ReadyToSwitchOn,
        // #2, #4.
        ReadyToSwitchOn | SwitchedOn if off2 || off3 => SwitchingOnInhibited,
        // #3.
        ReadyToSwitchOn if on => SwitchedOn,
        // #5.
        SwitchedOn if !on => ReadyToSwitchOn,
        // #6: requires that the drive is in fieldbus control (ZSW1 b9).
        SwitchedOn if enable && fieldbus => Operation,
        // #7, #8, #9, #10.
        Operation if off2 => SwitchingOnInhibited,
        Operation if off3 => SwitchingOff(StopKind::Quick),
        Operation if !on => SwitchingOff(StopKind::Ramp),
        Operation if !enable => SwitchedOn,
        // #11, #12.
        SwitchingOff(_) if off2 => SwitchingOnInhibited,
        SwitchingOff(StopKind::Ramp) if off3 => SwitchingOff(StopKind::Quick),
        // #14 re-enable (cancel the ramp stop, Table 33).
        SwitchingOff(StopKind::Ramp) if on && enable => Operation,
        // #13, #15.
        SwitchingOff(StopKind::Ramp) if !enable || drive.standstill() => ReadyToSwitchOn,
        SwitchingOff(StopKind::Quick) if !enable || drive.standstill() => SwitchingOnInhibited,
        other => other,
    }
}

/// Follows [`transition`] until the state is stable (0x047F takes S2 through S3 to S4 at
/// once). The diagram has no cycle without a changing input, so six steps always suffice.
pub fn settle(mut state: State, stw: Stw1, drive: &DriveStatus) -> State {
    for _ in 0..6 {
        let next = transition(state, stw, drive);
        if next == state {
            break;
        }
        state = next;
    }
    state
}

/// The conversion between a profile's speed word and the neutral N2 scale of
/// [`super::drive_if`] (0x4000 = 100 % of the drive's reference speed).
///
/// A profile word `raw` means the physical speed `min + (max − min) · |raw| / full_scale`
/// with the sign of `raw` (any unit: rpm, 0.1 Hz, 0.01 Hz — the same for all four speeds):
///
/// * PROFIdrive 4.1 at VACON: [`SpeedScale::N2`] (0x4000 = PNU 10111, OPTE3/E5 §6.3.7).
/// * WEG PROFIdrive: 16384 = P0134 maximum speed (CFW500 §4 P0741, CFW-11 §3).
/// * WEG manufacturer: 8192 = P0403 rated frequency (CFW500 P0681/P0685) or the synchronous
///   speed (CFW-11).
/// * VACON bypass and PPO: 0..10000 = minimum..maximum frequency (OPTE3/E5 §6.3.5, §6.7.1).
/// * INVT: the set frequency in 0.01 Hz (INVT §2.6 Table 2-6): `full_scale = max`.
///
/// All arithmetic is exact (i128) with rounding to the nearest value; a zero divisor gives 0;
/// results saturate — nothing panics.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct SpeedScale {
    /// The profile value that means `max`.
    pub full_scale: u32,
    /// The physical speed of the profile value 0 (the bypass scale's minimum frequency;
    /// 0 elsewhere).
    pub min: u32,
    /// The physical speed of `full_scale`.
    pub max: u32,
    /// The physical speed of N2 0x4000 (the drive's reference for the neutral scale).
    pub n2_reference: u32,
    /// The largest magnitude the profile word carries (10000 for the bypass scale; 32768 for
    /// a full signed word: the result then saturates at 32767 / −32768).
    pub limit: u32,
}

/// Division rounding to the nearest value (halves away from zero); 0 for a zero divisor.
/// Out of line: an `i128` division, called from every scaling (footprint, issue 13 item 1).
#[inline(never)]
fn div_round(num: i128, den: i128) -> i128 {
    if den == 0 {
        return 0;
    }
    // One division of the magnitudes (the 128-bit division is expanded inline: one copy).
    let (n, d) = (num.unsigned_abs(), den.unsigned_abs());
    let q = ((n + d / 2) / d) as i128;
    if (num < 0) != (den < 0) {
        -q
    } else {
        q
    }
}

/// Saturates to the i16 range.
pub(crate) fn saturate_i16(v: i128) -> i16 {
    v.clamp(i16::MIN as i128, i16::MAX as i128) as i16
}

impl SpeedScale {
    /// The identity: the profile word is N2 already (PROFIdrive 4.1 at VACON, OPTE3/E5 §6.3.7).
    pub const N2: SpeedScale = SpeedScale { full_scale: 0x4000, min: 0, max: 1, n2_reference: 1, limit: 0x8000 };

    /// A signed-word scale without offset: `full_scale` means `max`, N2 0x4000 means
    /// `n2_reference` (WEG P0681/P0685: `full_scale` 8192; WEG PROFIdrive: 16384).
    pub const fn linear(full_scale: u32, max: u32, n2_reference: u32) -> SpeedScale {
        SpeedScale { full_scale, min: 0, max, n2_reference, limit: 0x8000 }
    }

    /// The bypass / PPO scale 0..10000 = `min`..`max` (OPTE3/E5 §6.3.5 Table 29, §6.7.1).
    pub const fn bypass(min: u32, max: u32, n2_reference: u32) -> SpeedScale {
        SpeedScale { full_scale: 10_000, min, max, n2_reference, limit: 10_000 }
    }

    fn clamp_raw(&self, raw: i32) -> i128 {
        let limit = self.limit as i128;
        (raw as i128).clamp(-limit, limit)
    }

    /// The physical speed of a profile value (rounded; e.g. WEG P0681 2048 → 15 Hz at a rated
    /// frequency of 60 Hz).
    pub fn to_physical(&self, raw: i32) -> i64 {
        let raw = self.clamp_raw(raw);
        let fs = self.full_scale as i128;
        if fs == 0 {
            return 0;
        }
        let span = self.max as i128 - self.min as i128;
        let mag = div_round(self.min as i128 * fs + span * raw.abs(), fs);
        (if raw < 0 { -mag } else { mag }) as i64
    }

    /// The profile value of a physical speed (rounded, limited; e.g. WEG P0685: 30 Hz → 4096
    /// at a rated frequency of 60 Hz). Speeds below `min` give 0.
    pub fn from_physical(&self, phys: i64) -> i32 {
        let p = phys as i128;
        let span = self.max as i128 - self.min as i128;
        let over = p.abs() - self.min as i128;
        if span <= 0 || over <= 0 {
            return 0;
        }
        let mag = div_round(over * self.full_scale as i128, span).min(self.limit as i128);
        (if p < 0 { -mag } else { mag }) as i32
    }

    /// The N2 value of a profile value (saturating).
    #[inline(never)]
    pub fn to_n2(&self, raw: i32) -> i16 {
        let raw = self.clamp_raw(raw);
        let fs = self.full_scale as i128;
        let span = self.max as i128 - self.min as i128;
        let num = (self.min as i128 * fs + span * raw.abs()) * 0x4000;
        let mag = div_round(num, fs * self.n2_reference as i128);
        saturate_i16(if raw < 0 { -mag } else { mag })
    }

    /// The profile value of an N2 value (rounded, limited to `limit`; speeds below `min`
    /// give 0).
    #[inline(never)]
    pub fn from_n2(&self, n2: i16) -> i32 {
        let n2 = n2 as i128;
        let span = self.max as i128 - self.min as i128;
        let over = n2.abs() * self.n2_reference as i128 - self.min as i128 * 0x4000;
        if span <= 0 || over <= 0 {
            return 0;
        }
        let mag = div_round(over * self.full_scale as i128, span * 0x4000).min(self.limit as i128);
        (if n2 < 0 { -mag } else { mag }) as i32
    }

    /// The profile word for an N2 actual value, as a raw word (two's complement).
    #[inline(never)]
    pub fn word_from_n2(&self, n2: i16) -> u16 {
        saturate_i16(self.from_n2(n2) as i128) as u16
    }
}

/// Which PROFIdrive flavour a [`Profidrive`] implements: which control word bits it evaluates,
/// which status word bits it reports, and its speed scale.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ProfidriveConfig {
    /// ST20 modifications (OPTE3/E5 Tables 18/19): STW1 b11 setpoint inversion, b15 parameter
    /// set 2; ZSW1 b11 limit not reached, b12 reserved, b13 no motor overload, b14 positive
    /// direction, b15 parameter set 2 active.
    pub st20: bool,
    /// STW1 b4 (ramp-function generator enable) is evaluated.
    pub ramp_enable_bit: bool,
    /// STW1 b5 (freeze) is evaluated (reserved at WEG, P0967).
    pub freeze_bit: bool,
    /// STW1 b6 (setpoint enable) is evaluated.
    pub setpoint_enable_bit: bool,
    /// STW1 b8 is jog 1 (WEG P0967).
    pub jog_bit: bool,
    /// STW1 b10 = 0 means "the drive goes to LOCAL" (WEG P0967 Table 4.7 "Control By PLC:
    /// 0: The drive goes to the LOCAL situation"): the command loses
    /// [`CommandFlags::FIELDBUS_CONTROL`] and nothing else happens — no frozen data, no fault.
    /// `false` (VACON, OPTE3/E5 §6.3.3 bit 10): b10 dropping in operation freezes the process
    /// data and goes to FAULT.
    pub b10_is_local_remote: bool,
    /// STW1 b4 = 0 is "disable the drive via the deceleration ramp" (WEG P0967 Table 4.7 bit
    /// 4): RUN is cleared (a ramp stop, the state stays S4). `false` (VACON Table 26): b4 = 0
    /// resets the ramp-function generator ([`CommandFlags::RAMP_RESET`], quick-stop ramp to 0
    /// while running).
    pub b4_is_ramp_stop: bool,
    /// STW1 b7 acts on its level (WEG P0967 bit 7 "1: If in a fault condition, it executes
    /// the fault reset"): in the fault state a word with b7 = 1 acknowledges, once per fault.
    /// `false` (VACON Table 26, PROFIdrive): a 0 → 1 edge acknowledges.
    pub ack_on_level: bool,
    /// Clear mode (the master's outputs are zero, reference §3.6) counts as STW1 b10 dropping
    /// (OPTE3/E5 §6.3.3 bit 10: in operation → FAULT, acknowledge with b7 once the master
    /// operates again). `false` (WEG: b10 = 0 is only LOCAL): Clear is the communication-loss
    /// command alone.
    pub clear_faults: bool,
    /// The ZSW1 bits the product reports (the others are sent as 0).
    pub zsw1_mask: u16,
    /// The speed scale of the setpoint and the actual value.
    pub scale: SpeedScale,
}

impl ProfidriveConfig {
    /// PROFIdrive 4.1, Standard Telegram 1 and the VACON telegrams 100 / 101 / 138 / 139
    /// (OPTE3/E5 §6.3.3 Table 26, §6.3.4 Table 27: ZSW1 b0–b10, b12, b13), N2 scale.
    pub const ST1: ProfidriveConfig = ProfidriveConfig {
        st20: false,
        ramp_enable_bit: true,
        freeze_bit: true,
        setpoint_enable_bit: true,
        jog_bit: false,
        b10_is_local_remote: false,
        b4_is_ramp_stop: false,
        ack_on_level: false,
        clear_faults: true,
        zsw1_mask: 0x37FF,
        scale: SpeedScale::N2,
    };

    /// PROFIdrive 4.1, Standard Telegram 20 (OPTE3/E5 §6.3.2.2 Tables 18/19; b12 is reserved
    /// in Table 19), N2 scale.
    pub const ST20: ProfidriveConfig = ProfidriveConfig { st20: true, zsw1_mask: 0xEFFF, ..ProfidriveConfig::ST1 };

    /// PROFIdrive 2.0 for the PPO types (OPTE3/E5 §6.5): STW1 b0–b3, b7 and b10 (Table 114;
    /// b4–b6 are "no action / START" and not evaluated, b11–b15 are the NX fieldbus DINs,
    /// which the neutral interface does not carry), ZSW1 b0–b9, b12, b13 (Table 117), the
    /// bypass scale (§6.3.5: "When using PPO types 1-6, the value is identical to that of
    /// the operate mode Bypass").
    pub const fn ppo(scale: SpeedScale) -> ProfidriveConfig {
        ProfidriveConfig {
            st20: false,
            ramp_enable_bit: false,
            freeze_bit: false,
            setpoint_enable_bit: false,
            jog_bit: false,
            b10_is_local_remote: false,
            b4_is_ramp_stop: false,
            ack_on_level: false,
            clear_faults: true,
            zsw1_mask: 0x33FF,
            scale,
        }
    }
}

/// A PROFIdrive control profile (4.1 or 2.0, see [`ProfidriveConfig`]): the general state
/// diagram, the control word evaluation and the status word (module docs).
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct Profidrive {
    config: ProfidriveConfig,
    state: State,
    /// The last raw control word (b7 edge detection).
    last_cw: u16,
    /// The last valid (b10 = 1) control word.
    last_valid: Stw1,
    /// Whether the last control word was valid.
    valid: bool,
    /// The held speed setpoint, N2 (follows the PLC unless frozen by b5 = 0).
    setpoint: i16,
    /// The last command (without COMM_LOSS).
    command: DriveCommand,
    /// The frozen command of a pending fieldbus fault (b10 dropped in operation).
    frozen: Option<DriveCommand>,
    /// An acknowledge edge was seen in the fault state.
    ack_pending: bool,
    fault_resets: u8,
    /// Control words with b10 = 0 that were not evaluated.
    ignored: u32,
}

impl Profidrive {
    /// A profile in S1 after power-up (Table 14 #0).
    pub fn new(config: ProfidriveConfig) -> Self {
        let mut p = Profidrive {
            config,
            state: State::SwitchingOnInhibited,
            last_cw: 0,
            last_valid: Stw1::empty(),
            valid: false,
            setpoint: 0,
            command: DriveCommand::default(),
            frozen: None,
            ack_pending: false,
            fault_resets: 0,
            ignored: 0,
        };
        p.command = p.build();
        p
    }

    /// PROFIdrive 4.1 for ST1 and the VACON telegrams 100 / 101 / 138 / 139.
    pub fn st1() -> Self {
        Self::new(ProfidriveConfig::ST1)
    }

    /// PROFIdrive 4.1 for ST20.
    pub fn st20() -> Self {
        Self::new(ProfidriveConfig::ST20)
    }

    /// PROFIdrive 2.0 for the PPO types, with the bypass scale.
    pub fn ppo(scale: SpeedScale) -> Self {
        Self::new(ProfidriveConfig::ppo(scale))
    }

    /// A new speed scale (the drive's references read, `profile::references`); the state
    /// machine keeps its state.
    pub fn set_scale(&mut self, scale: SpeedScale) {
        self.config.scale = scale;
    }

    /// The configuration.
    pub fn config(&self) -> &ProfidriveConfig {
        &self.config
    }

    /// The state of the general state diagram.
    pub fn state(&self) -> State {
        self.state
    }

    /// Whether a fieldbus fault (b10 dropped in operation) is pending: the process data are
    /// frozen.
    pub fn fieldbus_fault(&self) -> bool {
        self.frozen.is_some()
    }

    /// Control words with b10 = 0 that were not evaluated (STYLE: every ignored event is
    /// counted).
    pub fn ignored_words(&self) -> u32 {
        self.ignored
    }

    /// §6.3.3 bit 10 dropped in operation: the last command is kept (frozen), state FAULT.
    fn freeze_and_fault(&mut self) {
        self.frozen = Some(self.command);
        self.state = State::Fault;
        self.ack_pending = false;
    }

    fn enter_fault_if_drive_faulted(&mut self, drive: &DriveStatus) {
        if drive.flags.contains(StatusFlags::FAULT) && self.state != State::Fault {
            self.state = State::Fault;
            self.ack_pending = false;
        }
    }

    /// The setpoint of a valid control word in N2 (ST20 inversion applied).
    fn convert_setpoint(&self, stw: Stw1, setpoint: u16) -> i16 {
        let n2 = self.config.scale.to_n2(setpoint as i16 as i32);
        if self.config.st20 && stw.contains(Stw1::SETPOINT_INVERSION) {
            n2.saturating_neg()
        } else {
            n2
        }
    }

    /// The command of the current state.
    #[inline(never)]
    fn build(&self) -> DriveCommand {
        if let Some(frozen) = self.frozen {
            let mut c = frozen;
            c.flags |= CommandFlags::FIELDBUS_FAULT;
            c.fault_resets = self.fault_resets;
            return c;
        }
        let cfg = &self.config;
        let stw = self.last_valid;
        let mut flags = CommandFlags::empty();
        if self.valid {
            flags |= CommandFlags::FIELDBUS_CONTROL;
        }
        let mut speed_setpoint = self.setpoint;
        match self.state {
            State::Operation => {
                flags |= CommandFlags::RUN;
                if cfg.ramp_enable_bit && !stw.contains(Stw1::ENABLE_RAMP) {
                    if cfg.b4_is_ramp_stop {
                        // WEG P0967 b4 = 0: disable via the deceleration ramp.
                        flags.remove(CommandFlags::RUN);
                    } else {
                        flags |= CommandFlags::RAMP_RESET;
                    }
                }
                // b5 = 0 freezes the setpoint only (OPTE3/E5 Table 26 "freeze setpoint"): the
                // held setpoint is in `self.setpoint`, the ramp-function generator runs on.
                if cfg.jog_bit && stw.contains(Stw1::JOG1) {
                    flags |= CommandFlags::JOG1;
                }
            }
            State::SwitchingOff(StopKind::Ramp) => {}
            State::SwitchingOff(StopKind::Quick) => flags |= CommandFlags::QUICK_STOP,
            State::SwitchingOnInhibited | State::ReadyToSwitchOn | State::SwitchedOn | State::Fault => {
                flags |= CommandFlags::COAST
            }
        }
        if cfg.setpoint_enable_bit && !stw.contains(Stw1::ENABLE_SETPOINT) {
            flags |= CommandFlags::SETPOINT_ZERO;
            speed_setpoint = 0;
        }
        if cfg.st20 && stw.contains(Stw1::PARAMETER_SET_2) {
            flags |= CommandFlags::RAMP_SET_2;
        }
        DriveCommand { flags, speed_setpoint, fault_resets: self.fault_resets, comm_loss_reaction: 0 }
    }
}

impl ControlProfile for Profidrive {
    fn command(&mut self, cw: u16, setpoint: u16, drive: &DriveStatus) -> DriveCommand {
        let stw = Stw1::from_bits_retain(cw);
        let edge = stw.contains(Stw1::FAULT_ACK) && self.last_cw & Stw1::FAULT_ACK.bits() == 0;
        self.last_cw = cw;
        self.valid = stw.contains(Stw1::CONTROL_BY_PLC);
        // A drive trip is taken first, so an acknowledge in the word of the cycle the drive
        // trips is not spent before the state becomes FAULT (issue 15 item 13).
        self.enter_fault_if_drive_faulted(drive);
        if self.valid {
            self.last_valid = stw;
            let ack = if self.config.ack_on_level {
                // WEG P0967 b7 "1: if in a fault condition, executes the reset": once per fault.
                stw.contains(Stw1::FAULT_ACK) && self.state == State::Fault && !self.ack_pending
            } else {
                edge
            };
            if ack {
                self.fault_resets = self.fault_resets.wrapping_add(1);
                if self.state == State::Fault {
                    self.ack_pending = true;
                    self.frozen = None;
                }
            }
            let frozen = self.config.freeze_bit && !stw.contains(Stw1::UNFREEZE_RAMP);
            if !frozen {
                self.setpoint = self.convert_setpoint(stw, setpoint);
            }
        } else {
            self.ignored = self.ignored.saturating_add(1);
            if !self.config.b10_is_local_remote && self.state.is_operating() {
                // §6.3.3 bit 10: freeze the process data, state FAULT.
                self.freeze_and_fault();
            }
        }
        if self.state == State::Fault
            && self.ack_pending
            && self.frozen.is_none()
            && !drive.flags.contains(StatusFlags::FAULT)
        {
            self.state = State::SwitchingOnInhibited;
            self.ack_pending = false;
        }
        if self.valid && self.state != State::Fault {
            self.state = settle(self.state, stw, drive);
        }
        self.command = self.build();
        self.command
    }

    fn comm_lost(&mut self, drive: &DriveStatus) -> DriveCommand {
        let before = self.state;
        self.enter_fault_if_drive_faulted(drive);
        if self.state != before {
            self.command = self.build();
        }
        let mut c = self.command;
        c.flags |= CommandFlags::COMM_LOSS;
        c
    }

    /// Clear mode: the master's outputs are zero, so STW1 b10 is 0 (OPTE3/E5 §6.3.3 bit 10):
    /// in operation the process data freeze and the state becomes FAULT — leaving Clear does
    /// not restart the motor, a b7 acknowledge is needed ([`ProfidriveConfig::clear_faults`]).
    /// The drive also gets the communication-loss command (A138).
    fn clear(&mut self, drive: &DriveStatus) -> DriveCommand {
        if self.config.clear_faults {
            // The zero word: the next b7 = 1 is an edge.
            self.last_cw = 0;
            self.valid = false;
            if self.state.is_operating() {
                self.freeze_and_fault();
                self.command = self.build();
            }
        }
        self.comm_lost(drive)
    }

    fn status_word(&self, drive: &DriveStatus) -> u16 {
        let f = drive.flags;
        let mut z = self.state.zsw1();
        z.set(Zsw1::NO_COAST_STOP, self.last_valid.contains(Stw1::NO_COAST_STOP));
        z.set(
            Zsw1::NO_QUICK_STOP,
            self.last_valid.contains(Stw1::NO_QUICK_STOP) && self.state != State::SwitchingOff(StopKind::Quick),
        );
        z.set(Zsw1::WARNING, f.contains(StatusFlags::WARNING));
        // b8 "the drive is operating and the actual speed matches the setpoint" (§6.3.4): S4 only.
        let operating = self.state == State::Operation;
        z.set(
            Zsw1::AT_SETPOINT,
            operating && f.contains(StatusFlags::AT_REFERENCE) && f.contains(StatusFlags::RUNNING),
        );
        z.set(Zsw1::CONTROL_REQUESTED, f.contains(StatusFlags::FIELDBUS_CONTROL));
        z.set(Zsw1::SPEED_REACHED, f.contains(StatusFlags::SPEED_REACHED));
        if self.config.st20 {
            let positive = if drive.speed != 0 { drive.speed > 0 } else { !f.contains(StatusFlags::REVERSE) };
            z.set(Zsw1::NO_LIMIT_REACHED, !f.contains(StatusFlags::LIMIT_REACHED));
            z.set(Zsw1::NO_MOTOR_OVERLOAD, !f.contains(StatusFlags::MOTOR_OVERLOAD));
            z.set(Zsw1::POSITIVE_DIRECTION, positive);
            z.set(Zsw1::PARAMETER_SET_2, f.contains(StatusFlags::RAMP_SET_2));
        } else {
            z.set(Zsw1::RUNNING, f.contains(StatusFlags::RUNNING));
            z.set(Zsw1::DRIVE_READY, f.contains(StatusFlags::READY));
        }
        z.bits() & self.config.zsw1_mask
    }

    fn actual_value(&self, drive: &DriveStatus) -> u16 {
        self.config.scale.word_from_n2(drive.speed)
    }
}

#[cfg(test)]
pub(crate) mod tests;
