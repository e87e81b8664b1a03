//! Replays of the OPTE3/E5 control-word sequences (§6.3.1 Table 14, §6.3.8 Tables 32–35,
//! §6.5.1 Table 115) against the drive stub, with the status word checked at every step.

use super::*;
use crate::profile::drive_stub::{DriveStub, Place};
use proptest::prelude::*;

/// A profile wired to a drive stub: one bus cycle = the profile's command, one drive cycle,
/// the status word of the new drive status.
pub(crate) struct Rig<P: ControlProfile> {
    pub p: P,
    pub d: DriveStub,
    pub last: DriveCommand,
}

impl<P: ControlProfile> Rig<P> {
    pub fn new(p: P) -> Self {
        Rig { p, d: DriveStub::default(), last: DriveCommand::default() }
    }

    /// One cycle; returns the command and the status word.
    pub fn cycle(&mut self, cw: u16, sp: u16) -> (DriveCommand, u16) {
        let st = self.d.status();
        let c = self.p.command(cw, sp, &st);
        self.d.step(&c);
        self.last = c;
        (c, self.p.status_word(&self.d.status()))
    }

    /// `n` cycles with the same words (housekeeping); returns the last.
    pub fn run(&mut self, cw: u16, sp: u16, n: usize) -> (DriveCommand, u16) {
        let mut r = self.cycle(cw, sp);
        for _ in 1..n {
            r = self.cycle(cw, sp);
        }
        r
    }

    pub fn actual(&self) -> u16 {
        self.p.actual_value(&self.d.status())
    }
}

// ZSW1 values with the stub (control place fieldbus → b9, READY → b13, RUNNING → b12):
const B9: u16 = 0x0200;
const B12: u16 = 0x1000;
const B13: u16 = 0x2000;
const NO_OFF2_OFF3: u16 = 0x0030;

fn started() -> Rig<Profidrive> {
    let mut r = Rig::new(Profidrive::st1());
    r.cycle(0x0000, 0);
    r.cycle(0x047E, 0x2000);
    r.run(0x047F, 0x2000, 4);
    assert_eq!(r.p.state(), State::Operation);
    assert_eq!(r.d.speed, 0x2000);
    r
}

#[test]
fn start_sequence_table_32() {
    let mut r = Rig::new(Profidrive::st1());
    // 0000h power-up default: S1, nothing valid (b4/b5 show the OFF2/OFF3 of an all-zero word).
    let (c, z) = r.cycle(0x0000, 0);
    assert_eq!(r.p.state(), State::SwitchingOnInhibited);
    assert_eq!(z, 0x0040 | B9 | B13);
    assert!(c.flags.contains(CommandFlags::COAST));
    assert!(!c.flags.contains(CommandFlags::FIELDBUS_CONTROL));
    // Reference §5.3: 0x047F straight from S1 never starts (S1 needs b0 = 0 first).
    let (_, z) = r.cycle(0x047F, 0x2000);
    assert_eq!(r.p.state(), State::SwitchingOnInhibited);
    assert_eq!(z, 0x0040 | NO_OFF2_OFF3 | B9 | B13);
    // 047Eh: S1 → S2 (#1, the drive is READY).
    let (c, z) = r.cycle(0x047E, 0x2000);
    assert_eq!(r.p.state(), State::ReadyToSwitchOn);
    assert_eq!(z, 0x2231);
    assert_eq!(c.flags, CommandFlags::COAST | CommandFlags::FIELDBUS_CONTROL);
    // 047Fh: S2 → S3 → S4 (#3, #6) in one evaluation; the drive starts.
    let (c, z) = r.cycle(0x047F, 0x2000);
    assert_eq!(r.p.state(), State::Operation);
    assert_eq!(c.flags, CommandFlags::RUN | CommandFlags::FIELDBUS_CONTROL);
    assert_eq!(c.speed_setpoint, 0x2000);
    assert_eq!(z, 0x0007 | NO_OFF2_OFF3 | B9 | B12 | B13);
    // Running at the setpoint: b8.
    let (_, z) = r.run(0x047F, 0x2000, 3);
    assert_eq!(z, 0x3337);
    assert_eq!(r.actual(), 0x2000);
}

#[test]
fn s3_to_s4_waits_for_the_fieldbus_control_place() {
    // Table 14 #6 "requires that Drive is in fieldbus control (ZSW1 bit 9)".
    let mut r = Rig::new(Profidrive::st1());
    r.d.place = Place::Local;
    r.cycle(0x047E, 0);
    let (c, z) = r.run(0x047F, 0, 3);
    assert_eq!(r.p.state(), State::SwitchedOn);
    assert_eq!(z & 0x0247, 0x0003);
    assert!(!c.flags.contains(CommandFlags::RUN));
    // The control place changes to the fieldbus (keypad): the next housekeeping step enters S4.
    r.d.place = Place::Fieldbus;
    r.cycle(0x047F, 0);
    assert_eq!(r.p.state(), State::Operation);
}

#[test]
fn s1_to_s2_waits_for_ready() {
    // Table 14 #1 "requires that Drive is READY (ZSW1 status word bit 13)".
    let mut r = Rig::new(Profidrive::st1());
    r.d.fault = true;
    r.d.fault_persists = true;
    let mut st = r.d.status();
    st.flags.remove(StatusFlags::FAULT);
    let _ = r.p.command(0x047E, 0, &st);
    assert_eq!(r.p.state(), State::SwitchingOnInhibited);
    st.flags.insert(StatusFlags::READY);
    let _ = r.p.command(0x047E, 0, &st);
    assert_eq!(r.p.state(), State::ReadyToSwitchOn);
}

#[test]
fn ramp_stop_and_cancel_table_33() {
    let mut r = started();
    // 047Eh: S5 ramp stop, the drive decelerates along the normal ramp.
    let (c, z) = r.cycle(0x047E, 0x2000);
    assert_eq!(r.p.state(), State::SwitchingOff(StopKind::Ramp));
    assert_eq!(c.flags, CommandFlags::FIELDBUS_CONTROL);
    assert_eq!(z, 0x0003 | NO_OFF2_OFF3 | B9 | B12 | B13);
    assert_eq!(r.d.speed, 0x1800);
    // 047Fh before standstill: cancel (#14), back to S4.
    let (c, z) = r.cycle(0x047F, 0x2000);
    assert_eq!(r.p.state(), State::Operation);
    assert!(c.flags.contains(CommandFlags::RUN));
    assert_eq!(z & 0x0007, 0x0007);
    // 047Eh again, then standstill → S2 (#13), pulses off.
    r.run(0x047E, 0x2000, 4);
    assert_eq!(r.d.speed, 0);
    assert!(!r.d.running);
    let (c, z) = r.cycle(0x047E, 0x2000);
    assert_eq!(r.p.state(), State::ReadyToSwitchOn);
    assert!(c.flags.contains(CommandFlags::COAST));
    assert_eq!(z, 0x2231);
}

#[test]
fn coast_stop_table_34() {
    let mut r = started();
    let (c, z) = r.cycle(0x047D, 0x2000);
    assert_eq!(r.p.state(), State::SwitchingOnInhibited);
    assert!(c.flags.contains(CommandFlags::COAST));
    assert!(!c.flags.contains(CommandFlags::RUN));
    assert_eq!(r.d.speed, 0);
    // S1, b4 = 0 (coast stop active), b5 = 1.
    assert_eq!(z, 0x0040 | 0x0020 | B9 | B13);
    // Restart: 047E, 047F.
    r.cycle(0x047E, 0x2000);
    r.cycle(0x047F, 0x2000);
    assert_eq!(r.p.state(), State::Operation);
}

#[test]
fn quick_stop_table_35() {
    let mut r = started();
    let (c, z) = r.cycle(0x047B, 0x2000);
    assert_eq!(r.p.state(), State::SwitchingOff(StopKind::Quick));
    assert_eq!(c.flags, CommandFlags::QUICK_STOP | CommandFlags::FIELDBUS_CONTROL);
    // b0, b1; b4 = 1, b5 = 0 (quick stop active); still running.
    assert_eq!(z, 0x0003 | 0x0010 | B9 | B12 | B13);
    // A re-enable does not cancel a quick stop.
    r.cycle(0x047F, 0x2000);
    assert_eq!(r.p.state(), State::SwitchingOff(StopKind::Quick));
    assert_eq!(r.d.speed, 0);
    // Standstill → S1 (#15).
    let (c, z) = r.cycle(0x047B, 0x2000);
    assert_eq!(r.p.state(), State::SwitchingOnInhibited);
    assert!(c.flags.contains(CommandFlags::COAST));
    assert_eq!(z, 0x0040 | 0x0010 | B9 | B13);
}

#[test]
fn quick_stop_overrides_a_ramp_stop() {
    let mut r = started();
    r.cycle(0x047E, 0x2000);
    assert_eq!(r.p.state(), State::SwitchingOff(StopKind::Ramp));
    r.cycle(0x047A, 0x2000);
    assert_eq!(r.p.state(), State::SwitchingOff(StopKind::Quick));
}

#[test]
fn disable_operation_0477() {
    let mut r = started();
    // §6.3.3 bit 3: "When it is set to 0 during operation, the drive performs a coast stop."
    let (c, z) = r.cycle(0x0477, 0x2000);
    assert_eq!(r.p.state(), State::SwitchedOn);
    assert!(c.flags.contains(CommandFlags::COAST));
    assert_eq!(r.d.speed, 0);
    assert_eq!(z, 0x0003 | NO_OFF2_OFF3 | B9 | B13);
    // Re-enable: S3 → S4.
    r.cycle(0x047F, 0x2000);
    assert_eq!(r.p.state(), State::Operation);
    // b3 = 0 during a ramp stop: pulses off, S2 (#13).
    r.cycle(0x047E, 0x2000);
    let (c, _) = r.cycle(0x0476, 0x2000);
    assert_eq!(r.p.state(), State::ReadyToSwitchOn);
    assert!(c.flags.contains(CommandFlags::COAST));
}

#[test]
fn fault_acknowledge_edge() {
    let mut r = started();
    r.d.trip();
    let (c, z) = r.cycle(0x047F, 0x2000);
    assert_eq!(r.p.state(), State::Fault);
    assert!(c.flags.contains(CommandFlags::COAST));
    assert_eq!(z, 0x0008 | NO_OFF2_OFF3 | B9);
    let resets = c.fault_resets;
    // No edge, no acknowledge: 047E keeps the fault.
    r.run(0x047E, 0x2000, 3);
    assert_eq!(r.p.state(), State::Fault);
    // 04FEh: the b7 edge; the drive resets in the same cycle ...
    let (c, _) = r.cycle(0x04FE, 0x2000);
    assert_eq!(c.fault_resets, resets.wrapping_add(1));
    assert!(!r.d.fault);
    // ... and the profile leaves the fault state on the next evaluation: S1 → S2.
    let (c, z) = r.cycle(0x047E, 0x2000);
    assert_eq!(c.fault_resets, resets.wrapping_add(1));
    assert_eq!(r.p.state(), State::ReadyToSwitchOn);
    assert_eq!(z, 0x2231);
    // 047Fh: running again.
    r.cycle(0x047F, 0x2000);
    assert_eq!(r.p.state(), State::Operation);
    // A held b7 is no new edge.
    let (c, _) = r.run(0x04FF, 0x2000, 2);
    assert_eq!(c.fault_resets, resets.wrapping_add(2));
    let (c, _) = r.run(0x04FF, 0x2000, 3);
    assert_eq!(c.fault_resets, resets.wrapping_add(2));
}

#[test]
fn a_persisting_drive_fault_keeps_the_fault_state() {
    let mut r = started();
    r.d.trip();
    r.d.fault_persists = true;
    r.cycle(0x047E, 0);
    r.cycle(0x04FE, 0);
    r.run(0x047E, 0, 3);
    assert_eq!(r.p.state(), State::Fault);
    // The cause goes away: the armed acknowledge completes without a new edge.
    r.d.fault = false;
    r.cycle(0x047E, 0);
    assert_eq!(r.p.state(), State::ReadyToSwitchOn);
}

#[test]
fn control_by_plc_lost_in_operation_freezes_and_faults() {
    let mut r = started();
    r.d.trip_on_fieldbus_fault = false;
    let before = r.last;
    // §6.3.3 bit 10: b10 drops in operation; new setpoint words are ignored.
    let (c, z) = r.cycle(0x007F, 0x1000);
    assert_eq!(r.p.state(), State::Fault);
    assert!(r.p.fieldbus_fault());
    assert_eq!(c.flags, before.flags | CommandFlags::FIELDBUS_FAULT);
    assert_eq!(c.speed_setpoint, 0x2000);
    assert_eq!(z & 0x004F, 0x0008);
    // A master in Clear sends zeros: still the frozen command.
    let (c, _) = r.run(0x0000, 0, 3);
    assert_eq!(c.flags, before.flags | CommandFlags::FIELDBUS_FAULT);
    assert_eq!(r.d.speed, 0x2000, "the drive reacts as parameterised (here: not at all)");
    // b10 back without an acknowledge: still the fault.
    let (c, _) = r.cycle(0x047F, 0x2000);
    assert!(c.flags.contains(CommandFlags::FIELDBUS_FAULT));
    assert_eq!(r.p.state(), State::Fault);
    // 04FEh / 047Eh / 047Fh.
    let (c, _) = r.cycle(0x04FE, 0x2000);
    assert!(!c.flags.contains(CommandFlags::FIELDBUS_FAULT));
    assert!(!r.p.fieldbus_fault());
    r.cycle(0x047E, 0x2000);
    assert_eq!(r.p.state(), State::ReadyToSwitchOn);
    r.cycle(0x047F, 0x2000);
    assert_eq!(r.p.state(), State::Operation);
}

#[test]
fn control_by_plc_lost_drive_trips_on_the_fieldbus_fault() {
    let mut r = started();
    r.cycle(0x0000, 0);
    assert!(r.d.fault);
    assert_eq!(r.d.speed, 0);
    r.cycle(0x04FE, 0x2000);
    r.cycle(0x047E, 0x2000);
    assert_eq!(r.p.state(), State::ReadyToSwitchOn);
    r.run(0x047F, 0x2000, 10);
    assert_eq!(r.d.speed, 0x2000);
}

#[test]
fn control_by_plc_lost_during_a_ramp_stop() {
    let mut r = started();
    r.cycle(0x047E, 0);
    assert_eq!(r.p.state(), State::SwitchingOff(StopKind::Ramp));
    let (c, _) = r.cycle(0x007E, 0);
    assert_eq!(r.p.state(), State::Fault);
    assert!(c.flags.contains(CommandFlags::FIELDBUS_FAULT));
}

#[test]
fn without_control_by_plc_a_stopped_drive_cannot_be_started() {
    let mut r = Rig::new(Profidrive::st1());
    let (c, _) = r.run(0x007E, 0x2000, 2);
    assert_eq!(r.p.state(), State::SwitchingOnInhibited);
    assert!(!c.flags.contains(CommandFlags::FIELDBUS_CONTROL));
    let (c, _) = r.run(0x007F, 0x2000, 3);
    assert_eq!(r.p.state(), State::SwitchingOnInhibited);
    assert!(!c.flags.contains(CommandFlags::RUN));
    // From S2 as well; and no fault: the drive was not operating.
    r.cycle(0x047E, 0);
    let (c, _) = r.run(0x007F, 0x2000, 3);
    assert_eq!(r.p.state(), State::ReadyToSwitchOn);
    assert!(!c.flags.contains(CommandFlags::RUN));
    assert!(!r.p.fieldbus_fault());
    assert_eq!(r.p.ignored_words(), 8);
}

#[test]
fn ramp_generator_freeze_and_setpoint_enable() {
    let mut r = started();
    // b4 = 0: reset the ramp-function generator.
    let (c, _) = r.run(0x046F, 0x2000, 3);
    assert!(c.flags.contains(CommandFlags::RAMP_RESET | CommandFlags::RUN));
    assert_eq!(r.d.speed, 0);
    r.run(0x047F, 0x2000, 10);
    // b5 = 0: freeze the setpoint (Table 26); the setpoint word is not taken over, the
    // ramp-function generator is not held.
    let (c, _) = r.cycle(0x045F, 0x3000);
    assert!(!c.flags.contains(CommandFlags::RAMP_HOLD));
    assert_eq!(c.speed_setpoint, 0x2000);
    assert_eq!(r.d.speed, 0x2000);
    let (c, _) = r.cycle(0x047F, 0x3000);
    assert_eq!(c.speed_setpoint, 0x3000);
    // b6 = 0: setpoint 0, the drive decelerates while running.
    let (c, z) = r.cycle(0x043F, 0x3000);
    assert!(c.flags.contains(CommandFlags::SETPOINT_ZERO | CommandFlags::RUN));
    assert_eq!(c.speed_setpoint, 0);
    assert_eq!(z & 0x0007, 0x0007);
}

#[test]
fn st20_modifications_tables_18_19() {
    let mut r = Rig::new(Profidrive::st20());
    r.cycle(0x047E, 0x2000);
    // b11 setpoint inversion, b15 parameter set 2.
    let (c, _) = r.cycle(0x8C7F, 0x2000);
    assert_eq!(c.speed_setpoint, -0x2000);
    assert!(c.flags.contains(CommandFlags::RAMP_SET_2 | CommandFlags::RUN));
    let (_, z) = r.run(0x8C7F, 0x2000, 3);
    assert_eq!(r.d.speed, -0x2000);
    // ZSW1: b0–b2, b4, b5, b8, b9, b11 no limit, b12 reserved, b13 no overload, b14 = 0
    // (reverse), b15 parameter set 2 active.
    assert_eq!(z, 0x0007 | NO_OFF2_OFF3 | 0x0100 | B9 | 0x0800 | 0x2000 | 0x8000);
    assert_eq!(r.actual(), (-0x2000i16) as u16);
    let (_, z) = r.run(0x047F, 0x2000, 6);
    assert_eq!(z & 0xC000, 0x4000);
    // The ST1 profile does not know these bits.
    let mut r1 = started();
    let (c, _) = r1.cycle(0x8C7F, 0x2000);
    assert_eq!(c.speed_setpoint, 0x2000);
    assert!(!c.flags.contains(CommandFlags::RAMP_SET_2));
}

#[test]
fn setpoint_and_actual_are_n2_at_vacon() {
    // §6.3.5 Table 28, §6.3.6 Table 30: 0xC000 = −100 %, 0x4000 = +100 %.
    let mut r = Rig::new(Profidrive::st1());
    r.cycle(0x047E, 0);
    let (c, _) = r.cycle(0x047F, 0xC000);
    assert_eq!(c.speed_setpoint, -0x4000);
    r.run(0x047F, 0xC000, 10);
    assert_eq!(r.actual(), 0xC000);
    for v in [i16::MIN, -1, 0, 1, 0x4000, i16::MAX] {
        assert_eq!(SpeedScale::N2.to_n2(v as i32), v);
        assert_eq!(SpeedScale::N2.from_n2(v) as i16, v);
    }
}

#[test]
fn comm_lost_keeps_the_state_and_flags_the_loss() {
    let mut r = started();
    let st = r.d.status();
    let c = r.p.comm_lost(&st);
    assert_eq!(c.flags, r.last.flags | CommandFlags::COMM_LOSS);
    assert_eq!(r.p.state(), State::Operation);
    // The drive trips on its communication-error action: the profile shows the fault.
    r.d.trip();
    let c = r.p.comm_lost(&r.d.status());
    assert_eq!(r.p.state(), State::Fault);
    assert!(c.flags.contains(CommandFlags::COAST | CommandFlags::COMM_LOSS));
    // Communication back: acknowledge and restart.
    r.cycle(0x04FE, 0);
    r.cycle(0x047E, 0);
    assert_eq!(r.p.state(), State::ReadyToSwitchOn);
    let c = r.p.command(0x047E, 0, &r.d.status());
    assert!(!c.flags.contains(CommandFlags::COMM_LOSS));
}

#[test]
fn ppo_commands_table_115() {
    // PROFIdrive 2.0, bypass scale: 0..10000 = 0..50.00 Hz, N2 100 % = 50.00 Hz.
    let scale = SpeedScale::bypass(0, 5000, 5000);
    let mut r = Rig::new(Profidrive::ppo(scale));
    r.cycle(0x0000, 0);
    r.cycle(0x047E, 0);
    // RUN 047Fh.
    let (c, _) = r.cycle(0x047F, 5000);
    assert!(c.flags.contains(CommandFlags::RUN));
    assert_eq!(c.speed_setpoint, 0x2000);
    let (_, z) = r.run(0x047F, 5000, 10);
    assert_eq!(r.actual(), 5000);
    // Table 117: b0–b2, b4, b5, b8, b9, b12, b13; b10 is "not used".
    assert_eq!(z, 0x0007 | NO_OFF2_OFF3 | 0x0100 | B9 | B12 | B13);
    // STOP 1 047Eh: stop by ramp.
    let (c, _) = r.cycle(0x047E, 5000);
    assert_eq!(c.flags, CommandFlags::FIELDBUS_CONTROL);
    r.run(0x047E, 5000, 10);
    assert_eq!(r.p.state(), State::ReadyToSwitchOn);
    // STOP 2 047Dh: stop by coast.
    r.run(0x047F, 5000, 10);
    let (c, _) = r.cycle(0x047D, 5000);
    assert!(c.flags.contains(CommandFlags::COAST));
    assert_eq!(r.d.speed, 0);
    // STOP 3 047Bh: "stop by ramp" along the quick ramp (§6.3.1 note: a normal ramp stop
    // where the application has no quick stop).
    r.cycle(0x047E, 5000);
    r.run(0x047F, 5000, 10);
    let (c, _) = r.cycle(0x047B, 5000);
    assert!(c.flags.contains(CommandFlags::QUICK_STOP));
    // RUN DISABLE 0477h: stop by coast.
    r.run(0x047B, 5000, 2);
    r.cycle(0x047E, 5000);
    r.run(0x047F, 5000, 10);
    let (c, _) = r.cycle(0x0477, 5000);
    assert!(c.flags.contains(CommandFlags::COAST));
    // FAULT RESET: bit 7 = 0, then 1.
    r.d.trip();
    r.cycle(0x047F, 5000);
    assert_eq!(r.p.state(), State::Fault);
    let n = r.last.fault_resets;
    let (c, _) = r.cycle(0x04FF, 5000);
    assert_eq!(c.fault_resets, n.wrapping_add(1));
    // b4–b6 are "no action" in PROFIdrive 2.0: 0x040F runs like 0x047F.
    r.cycle(0x047E, 5000);
    let (c, _) = r.cycle(0x040F, 5000);
    assert_eq!(r.p.state(), State::Operation);
    assert_eq!(c.flags, CommandFlags::RUN | CommandFlags::FIELDBUS_CONTROL);
    assert_eq!(c.speed_setpoint, 0x2000);
}

#[test]
fn ppo_scale_reading() {
    // Our reading of §6.3.5 for PPO: magnitude in the bypass scale (0 = minimum frequency,
    // 10000 = maximum frequency), and — the PD 2.0 control word has no direction bit (Table
    // 114 b1 is STOP 2) — the sign of the word is the direction, as in §6.3.5's first sentence.
    let s = SpeedScale::bypass(1000, 5000, 5000); // 10.00..50.00 Hz, N2 100 % = 50.00 Hz
    assert_eq!(s.to_n2(0), 3277); // 10 Hz = 0x4000 · 10 / 50 = 3276.8
    assert_eq!(s.to_n2(10_000), 0x4000);
    assert_eq!(s.to_n2(-10_000), -0x4000);
    assert_eq!(s.to_n2(20_000), 0x4000, "clamped to 100 %");
    assert_eq!(s.to_n2(5_000), 9830); // 30 Hz = 9830.4
    assert_eq!(s.from_n2(0x4000), 10_000);
    assert_eq!(s.from_n2(-0x4000), -10_000);
    assert_eq!(s.from_n2(0x7FFF), 10_000, "limited to 10000");
    assert_eq!(s.from_n2(100), 0, "below the minimum frequency");
    assert_eq!(s.to_physical(5_000), 3000);
    assert_eq!(s.from_physical(3000), 5_000);
}

#[test]
fn speed_scale_never_divides_by_zero() {
    let z = SpeedScale { full_scale: 0, min: 0, max: 0, n2_reference: 0, limit: 0 };
    assert_eq!(z.to_n2(1234), 0);
    assert_eq!(z.from_n2(1234), 0);
    assert_eq!(z.to_physical(1234), 0);
    assert_eq!(z.from_physical(1234), 0);
}

const INTERESTING: [u16; 14] =
    [0x0000, 0x047E, 0x047F, 0x047D, 0x047B, 0x0477, 0x04FE, 0x04FF, 0x007F, 0x046F, 0x045F, 0x043F, 0x8C7F, 0x0476];

/// One step of a random scenario.
#[derive(Debug, Clone)]
enum Ev {
    /// A control word (an index into INTERESTING, or a random word) and a setpoint.
    Word(u16, u16),
    /// The communication is lost.
    CommLost,
    /// The drive trips.
    Trip,
    /// An arbitrary drive status instead of the stub's.
    Arbitrary(u16, i16),
}

fn ev() -> impl Strategy<Value = Ev> {
    prop_oneof![
        6 => (0usize..INTERESTING.len(), any::<u16>()).prop_map(|(i, s)| Ev::Word(INTERESTING[i], s)),
        2 => (any::<u16>(), any::<u16>()).prop_map(|(c, s)| Ev::Word(c, s)),
        1 => Just(Ev::CommLost),
        1 => Just(Ev::Trip),
        1 => (any::<u16>(), any::<i16>()).prop_map(|(f, s)| Ev::Arbitrary(f, s)),
    ]
}

/// The invariants of one command / status word pair.
pub(crate) fn check_command(c: &DriveCommand) -> Result<(), TestCaseError> {
    let f = c.flags;
    if f.contains(CommandFlags::COAST) {
        prop_assert!(!f.contains(CommandFlags::RUN), "COAST with RUN: {:?}", c);
    }
    if f.contains(CommandFlags::QUICK_STOP) {
        prop_assert!(!f.contains(CommandFlags::RUN), "QUICK_STOP with RUN: {:?}", c);
    }
    Ok(())
}

fn check(p: &Profidrive, c: &DriveCommand, z: u16, valid: bool) -> Result<(), TestCaseError> {
    check_command(c)?;
    let state_bits = z & ZSW1_STATE_BITS;
    prop_assert!(
        [0x0040, 0x0001, 0x0003, 0x0007, 0x0008].contains(&state_bits),
        "illegal ZSW1 state bits {:#06x}",
        state_bits
    );
    prop_assert_eq!(state_bits, p.state().zsw1().bits());
    let f = c.flags;
    if f.contains(CommandFlags::RUN) {
        prop_assert!(p.state() == State::Operation || p.fieldbus_fault());
    }
    if p.fieldbus_fault() {
        prop_assert_eq!(p.state(), State::Fault);
        prop_assert!(f.contains(CommandFlags::FIELDBUS_FAULT));
    } else {
        prop_assert!(!f.contains(CommandFlags::FIELDBUS_FAULT));
        prop_assert_eq!(f.contains(CommandFlags::FIELDBUS_CONTROL), valid);
    }
    Ok(())
}

proptest! {
    #[test]
    fn settle_is_a_fixpoint(stw: u16, flags: u16, speed: i16, start in 0usize..7) {
        let states = [State::SwitchingOnInhibited, State::ReadyToSwitchOn, State::SwitchedOn,
            State::Operation, State::SwitchingOff(StopKind::Ramp),
            State::SwitchingOff(StopKind::Quick), State::Fault];
        let d = DriveStatus { flags: StatusFlags::from_bits_retain(flags), speed, ..DriveStatus::default() };
        let s = settle(states[start], Stw1::from_bits_retain(stw), &d);
        prop_assert_eq!(transition(s, Stw1::from_bits_retain(stw), &d), s);
    }

    #[test]
    fn any_sequence_keeps_the_invariants(events in proptest::collection::vec(ev(), 1..80), st20: bool) {
        let p = if st20 { Profidrive::st20() } else { Profidrive::st1() };
        let mut r = Rig::new(p);
        let mut valid = false;
        for e in events {
            let (c, z) = match e {
                Ev::Word(cw, sp) => {
                    valid = cw & 0x0400 != 0;
                    r.cycle(cw, sp)
                }
                Ev::CommLost => {
                    let c = r.p.comm_lost(&r.d.status());
                    prop_assert!(c.flags.contains(CommandFlags::COMM_LOSS));
                    r.d.step(&c);
                    let mut c2 = c;
                    c2.flags.remove(CommandFlags::COMM_LOSS);
                    (c2, r.p.status_word(&r.d.status()))
                }
                Ev::Trip => {
                    r.d.trip();
                    continue;
                }
                Ev::Arbitrary(f, speed) => {
                    let d = DriveStatus { flags: StatusFlags::from_bits_retain(f), speed, ..DriveStatus::default() };
                    let c = r.p.command(0x047F, speed as u16, &d);
                    valid = true;
                    let _ = r.p.actual_value(&d);
                    (c, r.p.status_word(&d))
                }
            };
            check(&r.p, &c, z, valid)?;
        }
    }
}

/// Issue 15 item 13: the drive losing READY (ZSW1 b13) without a fault takes S2..S4 back to
/// S1 (Figure 11: "ready" is a condition of S2 and above); with a fault it is the fault state.
#[test]
fn losing_ready_without_a_fault_falls_back_to_s1() {
    let ready = DriveStatus { flags: StatusFlags::READY | StatusFlags::FIELDBUS_CONTROL, ..DriveStatus::default() };
    let not_ready = DriveStatus { flags: StatusFlags::FIELDBUS_CONTROL, ..DriveStatus::default() };
    for (words, state) in [
        (&[0x047E][..], State::ReadyToSwitchOn),
        (&[0x047E, 0x0477][..], State::SwitchedOn),
        (&[0x047E, 0x047F][..], State::Operation),
    ] {
        let mut p = Profidrive::st1();
        for &w in words {
            p.command(w, 0, &ready);
        }
        assert_eq!(p.state(), state);
        let c = p.command(*words.last().unwrap(), 0, &not_ready);
        assert_eq!(p.state(), State::SwitchingOnInhibited, "from {state:?}");
        assert!(c.flags.contains(CommandFlags::COAST));
    }
}

/// `div_round`: halves away from zero in every sign combination, 0 for a zero divisor.
#[test]
fn div_round_halves_away_from_zero() {
    for (num, den, q) in
        [(5, 2, 3), (-5, 2, -3), (5, -2, -3), (-5, -2, 3), (4, 3, 1), (-4, 3, -1), (7, 0, 0), (0, -3, 0)]
    {
        assert_eq!(div_round(num, den), q, "{num} / {den}");
    }
    let big = (u32::MAX as i128) * (u32::MAX as i128) * 3;
    assert_eq!(div_round(big, -(u32::MAX as i128)), -3 * (u32::MAX as i128));
}
