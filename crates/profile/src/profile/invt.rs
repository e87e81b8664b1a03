//! The INVT HD2 control profile (INVT PROFIBUS-DP card manual §2.6: Table 2-5 control word,
//! Table 2-6 set frequency, Table 2-7 status word, Table 2-8 running frequency).
//!
//! The control word's low byte is a command code, not a set of bits:
//!
//! | CW b0–b7 | command | [`DriveCommand`] |
//! |---|---|---|
//! | 1 | forward running | RUN |
//! | 2 | reverse running | RUN, REVERSE |
//! | 3 | forward inching (jog) | JOG1 |
//! | 4 | reverse inching | JOG1, REVERSE |
//! | 5 | decelerate to stop | (RUN cleared: ramp stop) |
//! | 6 | coast to stop (emergency stop) | COAST |
//! | 7 | fault reset | `fault_resets` + 1 on entering code 7 |
//! | 8 | inching stopped | ends a jog (ramp stop) |
//! | 9 | pre-excitation | PRE_EXCITE |
//!
//! Our reading: a code is a command that stays in force until another one replaces it (the
//! PLC normally repeats it every cycle); code 0, code 7 and unknown codes (counted) leave the
//! running command as it was. b13 "pre-excitation" adds PRE_EXCITE. b8 (PKW write enable)
//! belongs to the PKW channel; b9–b10 (motor group), b11 (torque/speed switching), b12
//! (power consumption reset) and b14 (DC braking) have no neutral equivalent and are not
//! passed on; b15 (heartbeat) is echoed in the status word's b15 and supervised by the runtime
//! (`profile::runtime`, "INVT heartbeat": a toggling b15 that stands still for 1 s is a
//! communication loss). The INVT words have no
//! "control by PLC" bit: every evaluated word carries [`CommandFlags::FIELDBUS_CONTROL`].
//!
//! **After a fault (our safety choice; the manual is silent):** a drive trip ends the latched
//! running command — the motor does not restart by itself when the fault is reset (code 7, or
//! at the drive). A run / inching code (1–4) sent while the fault is active is not taken, and
//! after the trip the code must be *new*: a control word whose code differs from the previous
//! word's (send 1, trip, send 7 → stays stopped; then 1 → runs). [`Invt::refused_runs`]
//! counts the codes not taken.
//!
//! The main setpoint is the set frequency (P15.02 = 1, Table 2-6: 0–Fmax in 0.01 Hz,
//! unsigned; the direction comes from the command code); the main actual value is the
//! running frequency (P15.13 = 1, Table 2-8: ×100 Hz), reported as a magnitude — the
//! direction is in the status word (1 forward / 2 reverse running). The word mapping
//! P15.02–P15.23 is the drive's (Table 2-6 "settings on the HD2 series inverter side"): the
//! card always scales PZD2 as a set frequency and passes PZD3..PZD12 raw; the drive decides
//! which word is its frequency (P15.02 = 0 "invalid": not PZD2) and fills PZD3..PZD12 of the
//! response (the simulated drive: `pbcard_sim::drive`, "INVT").

use super::drive_if::{CommandFlags, ControlProfile, DriveCommand, DriveStatus, StatusFlags};
use super::profidrive::SpeedScale;

/// The running command the last control word codes left in force.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum RunCommand {
    /// Stopped along the ramp (code 5, code 8 after a jog, power-up).
    Stop,
    /// Coast stop (code 6).
    Coast,
    /// Running (code 1 forward, 2 reverse).
    Run {
        /// Reverse direction.
        reverse: bool,
    },
    /// Inching (code 3 forward, 4 reverse).
    Jog {
        /// Reverse direction.
        reverse: bool,
    },
    /// Pre-excitation (code 9).
    PreExcite,
}

/// INVT status word values of b0–b7 (Table 2-7).
pub mod state {
    /// In forward running.
    pub const FORWARD: u16 = 1;
    /// In reverse running.
    pub const REVERSE: u16 = 2;
    /// Stopped.
    pub const STOPPED: u16 = 3;
    /// Faulty.
    pub const FAULT: u16 = 4;
    /// POFF (power off: DC link undervoltage).
    pub const POFF: u16 = 5;
    /// In pre-excitation.
    pub const PRE_EXCITATION: u16 = 6;
}

/// SW b8: bus voltage established, ready to run.
pub const SW_READY: u16 = 1 << 8;
/// SW b12: overload pre-alarm.
pub const SW_OVERLOAD_PREALARM: u16 = 1 << 12;
/// SW b13–b14 run/stop mode 2: communication-based control.
pub const SW_COMMUNICATION_CONTROL: u16 = 2 << 13;
/// CW / SW b15: heartbeat (reference / feedback).
pub const HEARTBEAT: u16 = 1 << 15;
/// CW b13: enable pre-excitation.
pub const CW_PRE_EXCITATION: u16 = 1 << 13;

/// The INVT control profile.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct Invt {
    scale: SpeedScale,
    run: RunCommand,
    last_code: u8,
    last_cw: u16,
    command: DriveCommand,
    unknown: u32,
    /// The drive tripped since the last accepted run code: a run / inching code needs an
    /// edge (a word whose code differs from the previous word's) to be taken.
    tripped: bool,
    /// Run / inching codes refused because they were not new after a trip.
    refused_runs: u32,
}

impl Invt {
    /// The set-frequency scale for Fmax `fmax` (0.01 Hz) and the drive's N2 reference
    /// `n2_reference` (0.01 Hz): the word is the frequency in 0.01 Hz, 0..Fmax.
    pub const fn scale(fmax: u32, n2_reference: u32) -> SpeedScale {
        SpeedScale { full_scale: fmax, min: 0, max: fmax, n2_reference, limit: fmax }
    }

    /// A stopped profile with the set-frequency scale `scale` ([`Invt::scale`]).
    pub fn new(scale: SpeedScale) -> Self {
        Invt {
            scale,
            run: RunCommand::Stop,
            last_code: 0,
            last_cw: 0,
            command: DriveCommand::default(),
            unknown: 0,
            tripped: false,
            refused_runs: 0,
        }
    }

    /// The set-frequency scale in force.
    pub fn speed_scale(&self) -> &SpeedScale {
        &self.scale
    }

    /// A new set-frequency scale (the drive's Fmax read, `profile::references`).
    pub fn set_scale(&mut self, scale: SpeedScale) {
        self.scale = scale;
    }

    /// The running command in force.
    pub fn run_command(&self) -> RunCommand {
        self.run
    }

    /// Control words with an unknown command code (10–255), counted and ignored.
    pub fn unknown_codes(&self) -> u32 {
        self.unknown
    }

    /// Run / inching codes not taken because they were repeated from before a trip (module
    /// docs, "after a fault").
    pub fn refused_runs(&self) -> u32 {
        self.refused_runs
    }
}

impl ControlProfile for Invt {
    fn command(&mut self, cw: u16, setpoint: u16, drive: &DriveStatus) -> DriveCommand {
        let raw = (cw & 0xFF) as u8;
        let mut resets = self.command.fault_resets;
        let faulted = drive.flags.contains(StatusFlags::FAULT);
        if faulted {
            // A trip ends the latched running command (our safety choice, module docs).
            self.run = RunCommand::Stop;
            self.tripped = true;
        }
        let run_code = matches!(raw, 1..=4);
        let code = if run_code && (faulted || (self.tripped && raw == self.last_code)) {
            // A run code from before the trip (or sent while the fault is active): not new.
            self.refused_runs = self.refused_runs.saturating_add(1);
            0
        } else {
            if run_code {
                self.tripped = false;
            }
            raw
        };
        match code {
            0 => {}
            1 => self.run = RunCommand::Run { reverse: false },
            2 => self.run = RunCommand::Run { reverse: true },
            3 => self.run = RunCommand::Jog { reverse: false },
            4 => self.run = RunCommand::Jog { reverse: true },
            5 => self.run = RunCommand::Stop,
            6 => self.run = RunCommand::Coast,
            7 => {
                if self.last_code != 7 {
                    resets = resets.wrapping_add(1);
                }
            }
            8 => {
                if matches!(self.run, RunCommand::Jog { .. }) {
                    self.run = RunCommand::Stop;
                }
            }
            9 => self.run = RunCommand::PreExcite,
            _ => self.unknown = self.unknown.saturating_add(1),
        }
        self.last_code = raw;
        self.last_cw = cw;
        let mut flags = CommandFlags::FIELDBUS_CONTROL;
        match self.run {
            RunCommand::Stop => {}
            RunCommand::Coast => flags |= CommandFlags::COAST,
            RunCommand::Run { reverse } => {
                flags |= CommandFlags::RUN;
                flags.set(CommandFlags::REVERSE, reverse);
            }
            RunCommand::Jog { reverse } => {
                flags |= CommandFlags::JOG1;
                flags.set(CommandFlags::REVERSE, reverse);
            }
            RunCommand::PreExcite => flags |= CommandFlags::PRE_EXCITE,
        }
        if cw & CW_PRE_EXCITATION != 0 && self.run != RunCommand::Coast {
            flags |= CommandFlags::PRE_EXCITE;
        }
        self.command = DriveCommand {
            flags,
            speed_setpoint: self.scale.to_n2(setpoint as i32),
            fault_resets: resets,
            comm_loss_reaction: 0,
        };
        self.command
    }

    fn comm_lost(&mut self, _drive: &DriveStatus) -> DriveCommand {
        let mut c = self.command;
        c.flags |= CommandFlags::COMM_LOSS;
        c
    }

    fn status_word(&self, drive: &DriveStatus) -> u16 {
        let f = drive.flags;
        let reverse = if drive.speed != 0 { drive.speed < 0 } else { f.contains(StatusFlags::REVERSE) };
        let mut sw = if f.contains(StatusFlags::FAULT) {
            state::FAULT
        } else if f.contains(StatusFlags::RUNNING) {
            if self.command.flags.contains(CommandFlags::PRE_EXCITE)
                && !self.command.flags.intersects(CommandFlags::RUN | CommandFlags::JOG1)
            {
                state::PRE_EXCITATION
            } else if reverse {
                state::REVERSE
            } else {
                state::FORWARD
            }
        } else if f.contains(StatusFlags::UNDERVOLTAGE) {
            state::POFF
        } else {
            state::STOPPED
        };
        if f.contains(StatusFlags::READY) {
            sw |= SW_READY;
        }
        if f.contains(StatusFlags::MOTOR_OVERLOAD) {
            sw |= SW_OVERLOAD_PREALARM;
        }
        if f.contains(StatusFlags::FIELDBUS_CONTROL) {
            sw |= SW_COMMUNICATION_CONTROL;
        }
        sw | (self.last_cw & HEARTBEAT)
    }

    fn actual_value(&self, drive: &DriveStatus) -> u16 {
        self.scale.from_n2(drive.speed.saturating_abs()) as u16
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::profile::profidrive::tests::{check_command, Rig};
    use proptest::prelude::*;

    // Fmax 50.00 Hz, N2 100 % = 50.00 Hz.
    const SCALE: SpeedScale = Invt::scale(5000, 5000);

    #[test]
    fn command_table_2_5() {
        let mut r = Rig::new(Invt::new(SCALE));
        // 1 forward running at 25.00 Hz.
        let (c, sw) = r.run(0x0001, 2500, 10);
        assert_eq!(c.flags, CommandFlags::RUN | CommandFlags::FIELDBUS_CONTROL);
        assert_eq!(c.speed_setpoint, 0x2000);
        assert_eq!(r.d.speed, 0x2000);
        assert_eq!(sw, state::FORWARD | SW_READY | SW_COMMUNICATION_CONTROL);
        assert_eq!(r.actual(), 2500);
        // 0 keeps the command in force.
        let (c, _) = r.cycle(0x0000, 2500);
        assert!(c.flags.contains(CommandFlags::RUN));
        // 2 reverse running.
        let (c, sw) = r.run(0x0002, 2500, 20);
        assert!(c.flags.contains(CommandFlags::RUN | CommandFlags::REVERSE));
        assert_eq!(r.d.speed, -0x2000);
        assert_eq!(sw & 0xFF, state::REVERSE);
        assert_eq!(r.actual(), 2500, "a magnitude; the direction is in the SW");
        // 5 decelerate to stop.
        let (c, _) = r.cycle(0x0005, 2500);
        assert_eq!(c.flags, CommandFlags::FIELDBUS_CONTROL);
        let (_, sw) = r.run(0x0005, 2500, 10);
        assert_eq!(sw & 0xFF, state::STOPPED);
        // 3 forward / 4 reverse inching, 8 inching stopped.
        let (c, _) = r.run(0x0003, 0, 3);
        assert_eq!(c.flags, CommandFlags::JOG1 | CommandFlags::FIELDBUS_CONTROL);
        assert!(r.d.speed > 0);
        let (c, _) = r.cycle(0x0004, 0);
        assert!(c.flags.contains(CommandFlags::JOG1 | CommandFlags::REVERSE));
        let (c, _) = r.cycle(0x0008, 0);
        assert_eq!(c.flags, CommandFlags::FIELDBUS_CONTROL);
        assert_eq!(r.p.run_command(), RunCommand::Stop);
        // 8 does not stop a normal run.
        r.cycle(0x0001, 2500);
        let (c, _) = r.cycle(0x0008, 2500);
        assert!(c.flags.contains(CommandFlags::RUN));
        // 6 coast to stop.
        let (c, sw) = r.cycle(0x0006, 2500);
        assert!(c.flags.contains(CommandFlags::COAST));
        assert_eq!(r.d.speed, 0);
        assert_eq!(sw & 0xFF, state::STOPPED);
        // 9 pre-excitation.
        let (c, sw) = r.cycle(0x0009, 0);
        assert_eq!(c.flags, CommandFlags::PRE_EXCITE | CommandFlags::FIELDBUS_CONTROL);
        assert_eq!(sw & 0xFF, state::PRE_EXCITATION);
        // 7 fault reset: one reset on entering code 7.
        r.d.trip();
        let (_, sw) = r.cycle(0x0005, 0);
        assert_eq!(sw & 0xFF, state::FAULT);
        assert_eq!(sw & SW_READY, 0);
        let n = r.last.fault_resets;
        let (c, _) = r.run(0x0007, 0, 3);
        assert_eq!(c.fault_resets, n.wrapping_add(1));
        assert!(!r.d.fault);
        let (_, sw) = r.cycle(0x0005, 0);
        assert_eq!(sw & 0xFF, state::STOPPED);
        // Unknown codes are counted and change nothing.
        let (c, _) = r.cycle(0x0042, 0);
        assert_eq!(c.flags, CommandFlags::FIELDBUS_CONTROL);
        assert_eq!(r.p.unknown_codes(), 1);
    }

    #[test]
    fn status_word_table_2_7_bits() {
        let mut p = Invt::new(SCALE);
        let _ = p.command(0x8001, 0, &DriveStatus::default());
        let d = DriveStatus {
            flags: StatusFlags::READY | StatusFlags::MOTOR_OVERLOAD | StatusFlags::UNDERVOLTAGE,
            ..DriveStatus::default()
        };
        // POFF, ready, overload pre-alarm, local (keypad), heartbeat echoed.
        assert_eq!(p.status_word(&d), state::POFF | SW_READY | SW_OVERLOAD_PREALARM | HEARTBEAT);
        let _ = p.command(0x0001, 0, &d);
        assert_eq!(p.status_word(&d) & HEARTBEAT, 0);
    }

    #[test]
    fn set_frequency_scale() {
        // Table 2-6: 0–Fmax in 0.01 Hz; the word is unsigned and limited to Fmax.
        assert_eq!(SCALE.to_n2(5000), 0x4000);
        assert_eq!(SCALE.to_n2(1250), 0x1000);
        assert_eq!(SCALE.to_n2(60000), 0x4000);
        let s = Invt::scale(5000, 10000); // N2 100 % = 100.00 Hz
        assert_eq!(s.to_n2(5000), 0x2000);
        assert_eq!(s.from_n2(0x2000), 5000);
        assert_eq!(s.from_n2(0x4000), 5000, "limited to Fmax");
    }

    proptest! {
        #[test]
        fn never_panics(seq in proptest::collection::vec((any::<u16>(), any::<u16>(), any::<u16>(), any::<i16>(), any::<bool>()), 1..60)) {
            let mut p = Invt::new(Invt::scale(5000, 6000));
            let mut seen = false;
            for (cw, sp, f, speed, lost) in seq {
                seen |= !lost;
                let d = DriveStatus { flags: StatusFlags::from_bits_retain(f), speed, ..DriveStatus::default() };
                let c = if lost { p.comm_lost(&d) } else { p.command(cw, sp, &d) };
                check_command(&c)?;
                prop_assert_eq!(c.flags.contains(CommandFlags::FIELDBUS_CONTROL), seen);
                let sw = p.status_word(&d);
                prop_assert!((1..=6).contains(&(sw & 0xFF)));
                prop_assert!(p.actual_value(&d) <= 5000);
            }
        }
    }
}
