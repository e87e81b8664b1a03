//! The PROFIdrive control word STW1, status word ZSW1 and the general state diagram
//! (reference §5.3; OPTE3/E5 manual §6.3.1 Table 14 and §6.3.3–6.3.4), as far as the
//! simulated drive needs them.
//!
//! | state | ZSW1 | left by (STW1, highest priority first) |
//! |---|---|---|
//! | S1 switching on inhibited | b6 | b0 = 0 and b1 = b2 = 1 → S2 (e.g. 0x047E) |
//! | S2 ready for switching on | b0 | b1 = 0 or b2 = 0 → S1; b0 = 1 → S3 |
//! | S3 switched on | b0 b1 | b1 = 0 or b2 = 0 → S1; b0 = 0 → S2; b3 = 1 → S4 |
//! | S4 operation | b0 b1 b2 | b1 = 0 → S1 (coast); b2 = 0 → S5 quick stop; b0 = 0 → S5 ramp stop; b3 = 0 → S3 (pulses off) |
//! | S5 switching off | b0 b1 | b1 = 0 → S1; b2 = 0 → quick stop; b0 = b3 = 1 (ramp stop) → S4; standstill → S2 (ramp) / S1 (quick) |
//! | fault | b3 | b7 rising edge → S1 |
//!
//! STW1 b10 "control by PLC" = 0 means the words are not valid: the control word is not
//! evaluated, and a drive in S4/S5 goes to fault (OPTE3/E5 §6.3.3, bit 10). So a watchdog
//! expiry or a master in Clear (outputs all zero) while the drive runs ends in a fault that
//! the PLC acknowledges with b7 (e.g. 0x04FE, then 0x047E, 0x047F).

bitflags::bitflags! {
    /// STW1, control word 1.
    #[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
    pub struct Stw1: u16 {
        /// b0 ON (1) / OFF1 (0: ramp stop).
        const ON = 1 << 0;
        /// b1 no OFF2 (0: coast stop).
        const NO_COAST_STOP = 1 << 1;
        /// b2 no OFF3 (0: quick stop).
        const NO_QUICK_STOP = 1 << 2;
        /// b3 enable operation (pulses).
        const ENABLE_OPERATION = 1 << 3;
        /// b4 enable the ramp-function generator (0: its output to 0).
        const ENABLE_RAMP = 1 << 4;
        /// b5 unfreeze the ramp-function generator (0: hold).
        const UNFREEZE_RAMP = 1 << 5;
        /// b6 enable setpoint (0: setpoint 0).
        const ENABLE_SETPOINT = 1 << 6;
        /// b7 fault acknowledge (0 → 1 edge).
        const FAULT_ACK = 1 << 7;
        /// b10 control by PLC (the words are valid).
        const CONTROL_BY_PLC = 1 << 10;
        const _ = !0;
    }
}

bitflags::bitflags! {
    /// ZSW1, status word 1.
    #[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
    pub struct Zsw1: u16 {
        /// b0 ready to switch on.
        const READY_TO_SWITCH_ON = 1 << 0;
        /// b1 ready to operate (switched on).
        const READY_TO_OPERATE = 1 << 1;
        /// b2 operation enabled.
        const OPERATION_ENABLED = 1 << 2;
        /// b3 fault present.
        const FAULT = 1 << 3;
        /// b4 coast stop not active.
        const NO_COAST_STOP = 1 << 4;
        /// b5 quick stop not active.
        const NO_QUICK_STOP = 1 << 5;
        /// b6 switching on inhibited.
        const SWITCHING_ON_INHIBITED = 1 << 6;
        /// b7 warning present.
        const WARNING = 1 << 7;
        /// b8 speed error within tolerance (at setpoint).
        const AT_SETPOINT = 1 << 8;
        /// b9 control requested (the drive accepts control through the PZD).
        const CONTROL_REQUESTED = 1 << 9;
        /// b10 f/n comparison value reached or exceeded.
        const SPEED_REACHED = 1 << 10;
    }
}

/// How S5 brings the motor to standstill.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum StopKind {
    /// OFF1: along the normal ramp, then S2.
    Ramp,
    /// OFF3: along the quick-stop ramp, then S1.
    Quick,
}

/// The states of the general state diagram.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum DriveState {
    /// S1.
    SwitchingOnInhibited,
    /// S2.
    ReadyToSwitchOn,
    /// S3.
    SwitchedOn,
    /// S4.
    Operation,
    /// S5.
    SwitchingOff(StopKind),
    /// Fault (acknowledge with a b7 rising edge).
    Fault,
}

impl DriveState {
    /// A readable name ("S4 operation").
    pub const fn name(self) -> &'static str {
        match self {
            DriveState::SwitchingOnInhibited => "S1 switching on inhibited",
            DriveState::ReadyToSwitchOn => "S2 ready for switching on",
            DriveState::SwitchedOn => "S3 switched on",
            DriveState::Operation => "S4 operation",
            DriveState::SwitchingOff(StopKind::Ramp) => "S5 switching off (ramp stop)",
            DriveState::SwitchingOff(StopKind::Quick) => "S5 switching off (quick stop)",
            DriveState::Fault => "fault",
        }
    }

    /// The ZSW1 bits b0, b1, b2, b3 and b6 of the state.
    pub const fn zsw1(self) -> Zsw1 {
        match self {
            DriveState::SwitchingOnInhibited => Zsw1::SWITCHING_ON_INHIBITED,
            DriveState::ReadyToSwitchOn => Zsw1::READY_TO_SWITCH_ON,
            DriveState::SwitchedOn | DriveState::SwitchingOff(_) => {
                Zsw1::READY_TO_SWITCH_ON.union(Zsw1::READY_TO_OPERATE)
            }
            DriveState::Operation => {
                Zsw1::READY_TO_SWITCH_ON.union(Zsw1::READY_TO_OPERATE).union(Zsw1::OPERATION_ENABLED)
            }
            DriveState::Fault => Zsw1::FAULT,
        }
    }

    /// Whether the motor is powered (S4, S5).
    pub const fn is_running(self) -> bool {
        matches!(self, DriveState::Operation | DriveState::SwitchingOff(_))
    }
}

/// What the state machine looks at in one evaluation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Command {
    /// The valid control word (b10 set).
    pub stw1: Stw1,
    /// b7 rose since the last evaluated control word.
    pub fault_ack: bool,
    /// The actual speed is zero.
    pub standstill: bool,
}

/// One transition (or none) of the general state diagram for a valid control word.
pub fn transition(state: DriveState, cmd: Command) -> DriveState {
    use DriveState::*;
    let s = cmd.stw1;
    let off2 = !s.contains(Stw1::NO_COAST_STOP);
    let off3 = !s.contains(Stw1::NO_QUICK_STOP);
    let on = s.contains(Stw1::ON);
    let enable = s.contains(Stw1::ENABLE_OPERATION);
    match state {
        SwitchingOnInhibited if !on && !off2 && !off3 => ReadyToSwitchOn,
        ReadyToSwitchOn | SwitchedOn if off2 || off3 => SwitchingOnInhibited,
        ReadyToSwitchOn if on => SwitchedOn,
        SwitchedOn if !on => ReadyToSwitchOn,
        SwitchedOn if enable => Operation,
        Operation if off2 => SwitchingOnInhibited,
        Operation if off3 => SwitchingOff(StopKind::Quick),
        Operation if !on => SwitchingOff(StopKind::Ramp),
        Operation if !enable => SwitchedOn,
        SwitchingOff(_) if off2 => SwitchingOnInhibited,
        SwitchingOff(StopKind::Ramp) if off3 => SwitchingOff(StopKind::Quick),
        SwitchingOff(StopKind::Ramp) if on && enable => Operation,
        SwitchingOff(StopKind::Ramp) if cmd.standstill => ReadyToSwitchOn,
        SwitchingOff(StopKind::Quick) if cmd.standstill => SwitchingOnInhibited,
        Fault if cmd.fault_ack => SwitchingOnInhibited,
        other => other,
    }
}

/// Follow transitions until the state is stable (0x047F takes S2 through S3 to S4 at once).
/// The fault acknowledge edge counts for the first transition only.
pub fn settle(mut state: DriveState, mut cmd: Command) -> DriveState {
    for _ in 0..6 {
        let next = transition(state, cmd);
        if next == state {
            break;
        }
        state = next;
        cmd.fault_ack = false;
    }
    state
}

#[cfg(test)]
mod tests {
    use super::*;
    use DriveState::*;

    fn cmd(stw1: u16) -> Command {
        Command { stw1: Stw1::from_bits_retain(stw1), fault_ack: false, standstill: true }
    }

    #[test]
    fn manual_sequence_047e_047f() {
        // Reference §5.3: 0x047F from power-up never starts the drive (S1 needs b0 = 0 first).
        assert_eq!(settle(SwitchingOnInhibited, cmd(0x047F)), SwitchingOnInhibited);
        assert_eq!(settle(SwitchingOnInhibited, cmd(0x047E)), ReadyToSwitchOn);
        assert_eq!(settle(ReadyToSwitchOn, cmd(0x047F)), Operation);
        // OPTE3/E5 Table 14: 0x477 disable operation → S3, 0x47D coast → S1, 0x47B quick stop.
        assert_eq!(settle(Operation, cmd(0x0477)), SwitchedOn);
        assert_eq!(settle(Operation, cmd(0x047D)), SwitchingOnInhibited);
        let running = Command { standstill: false, ..cmd(0x047B) };
        assert_eq!(settle(Operation, running), SwitchingOff(StopKind::Quick));
        let running = Command { standstill: false, ..cmd(0x047E) };
        assert_eq!(settle(Operation, running), SwitchingOff(StopKind::Ramp));
        assert_eq!(settle(SwitchingOff(StopKind::Ramp), cmd(0x047E)), ReadyToSwitchOn);
        assert_eq!(settle(SwitchingOff(StopKind::Quick), cmd(0x047E)), ReadyToSwitchOn);
        // Re-enable during the ramp stop (Table 14, transition 14).
        let running = Command { standstill: false, ..cmd(0x047F) };
        assert_eq!(settle(SwitchingOff(StopKind::Ramp), running), Operation);
    }

    #[test]
    fn fault_needs_an_acknowledge_edge() {
        assert_eq!(settle(Fault, cmd(0x04FE)), Fault);
        let ack = Command { fault_ack: true, ..cmd(0x04FE) };
        assert_eq!(settle(Fault, ack), ReadyToSwitchOn);
    }

    #[test]
    fn zsw1_patterns_of_the_manual() {
        // OPTE3/E5 general state diagram: S1 b6; S2 b0; S3 b0,b1; S4 b0,b1,b2; S5 b0,b1.
        assert_eq!(SwitchingOnInhibited.zsw1().bits(), 0x0040);
        assert_eq!(ReadyToSwitchOn.zsw1().bits(), 0x0001);
        assert_eq!(SwitchedOn.zsw1().bits(), 0x0003);
        assert_eq!(Operation.zsw1().bits(), 0x0007);
        assert_eq!(SwitchingOff(StopKind::Ramp).zsw1().bits(), 0x0003);
        assert_eq!(Fault.zsw1().bits(), 0x0008);
    }

    proptest::proptest! {
        #[test]
        fn settle_is_a_fixpoint(stw in proptest::prelude::any::<u16>(), standstill: bool, start in 0usize..7) {
            let states = [SwitchingOnInhibited, ReadyToSwitchOn, SwitchedOn, Operation,
                SwitchingOff(StopKind::Ramp), SwitchingOff(StopKind::Quick), Fault];
            let c = Command { stw1: Stw1::from_bits_retain(stw), fault_ack: false, standstill };
            let s = settle(states[start], c);
            proptest::prop_assert_eq!(transition(s, c), s);
        }
    }
}
