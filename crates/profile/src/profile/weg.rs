//! WEG's control profiles (CFW500 manual §4 P0680 / P0681 / P0684 / P0685 / P0741 / P0967 /
//! P0968 and §5.1; CFW-11 manual §3, the same parameters).
//!
//! P0741 selects the profile of the first two I/O words:
//!
//! * 1 = manufacturer ([`WegManufacturer`]): control word P0684, speed reference P0685,
//!   status word P0680, motor speed P0681, the speeds in the signed 13-bit scale
//!   (8192 = P0403 rated frequency at the CFW500, the synchronous speed at the CFW-11).
//! * 0 = PROFIdrive ([`weg_profidrive`]): control word P0967, status word P0968 — the
//!   PROFIdrive state machine of [`super::profidrive`] with WEG's bit set (no freeze bit,
//!   b8 jog 1; status b0–b7, b9, and at the CFW-11 b10) and 16384 = P0134 maximum speed.
//!
//! The conversions between those scales and the neutral N2 scale are
//! [`super::profidrive::SpeedScale`]s ([`WegModel::scale_13bit`], [`WegModel::scale_profidrive`]).

use super::drive_if::{CommandFlags, ControlProfile, DriveCommand, DriveStatus, StatusFlags};
use super::profidrive::{Profidrive, ProfidriveConfig, SpeedScale};

/// The WEG drive the card sits in (the status words differ in a few bits).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum WegModel {
    /// CFW500 (CFW500-CPRO): P0680 b0 STO and b1 run command exist; P0968 b10 is reserved.
    Cfw500,
    /// CFW-11 (PROFIBUSDP-01): P0680 b0–b3 reserved; P0968 b10 "frequency reached".
    Cfw11,
}

impl WegModel {
    /// The 13-bit scale of P0681 / P0685: 8192 = `rated` (P0403 rated frequency at the
    /// CFW500, the synchronous speed at the CFW-11), in the unit of `n2_reference` (the
    /// drive's reference of the neutral scale).
    pub const fn scale_13bit(rated: u32, n2_reference: u32) -> SpeedScale {
        SpeedScale::linear(8192, rated, n2_reference)
    }

    /// The PROFIdrive scale: 16384 = `p0134` maximum speed (CFW500 P0741 "Speed for
    /// PROFIdrive profile", CFW-11 §3).
    pub const fn scale_profidrive(p0134: u32, n2_reference: u32) -> SpeedScale {
        SpeedScale::linear(0x4000, p0134, n2_reference)
    }

    /// The P0968 bits the model reports (CFW500 Table 4.8: b0–b7, b9; CFW-11 Table 3.9:
    /// also b10).
    pub const fn p0968_mask(self) -> u16 {
        match self {
            WegModel::Cfw500 => 0x02FF,
            WegModel::Cfw11 => 0x06FF,
        }
    }
}

/// WEG's PROFIdrive profile (P0741 = 0): P0967 control word (CFW500 Table 4.7), P0968 status
/// word (Table 4.8 / 3.9), speeds with 16384 = P0134. Where WEG's P0967 differs from VACON's
/// STW1 (OPTE3/E5 Table 26) the card follows WEG:
///
/// * b4 = 0 "disables the drive via deceleration ramp" (a ramp stop, not a ramp-function
///   generator reset);
/// * b5 reserved (no setpoint freeze); b8 JOG 1;
/// * b7 "1: if in a fault condition, it executes the fault reset" — on the level, once per
///   fault, not on an edge;
/// * b10 "0: the drive goes to the LOCAL situation, 1: REMOTE" — b10 = 0 only takes the
///   fieldbus control away ([`CommandFlags::FIELDBUS_CONTROL`] cleared); it never freezes
///   the data or faults (VACON's §6.3.3 reading), and Clear mode is only the
///   communication-loss command (A138 with P0313).
pub fn weg_profidrive(model: WegModel, scale: SpeedScale) -> Profidrive {
    Profidrive::new(ProfidriveConfig {
        st20: false,
        ramp_enable_bit: true,
        freeze_bit: false,
        setpoint_enable_bit: true,
        jog_bit: true,
        b10_is_local_remote: true,
        b4_is_ramp_stop: true,
        ack_on_level: true,
        clear_faults: false,
        zsw1_mask: model.p0968_mask(),
        scale,
    })
}

bitflags::bitflags! {
    /// P0684, the WEG control word (CFW500 Table 4.3, CFW-11 Tabela 3.3).
    #[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
    pub struct P0684: u16 {
        /// b0 run (1) / stop with the deceleration ramp (0).
        const RUN = 1 << 0;
        /// b1 general enable (0: disable, the motor coasts).
        const GENERAL_ENABLE = 1 << 1;
        /// b2 speed direction: 1 = as the reference's sign, 0 = opposite.
        const DIRECTION = 1 << 2;
        /// b3 JOG.
        const JOG = 1 << 3;
        /// b4 LOC/REM: 1 = remote.
        const REMOTE = 1 << 4;
        /// b5 second ramp (P0102/P0103).
        const SECOND_RAMP = 1 << 5;
        /// b6 quick stop.
        const QUICK_STOP = 1 << 6;
        /// b7 fault reset.
        const FAULT_RESET = 1 << 7;
        const _ = !0;
    }
}

bitflags::bitflags! {
    /// P0680, the WEG status word (CFW500 Table 4.2, CFW-11 Tabela 3.2).
    #[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
    pub struct P0680: u16 {
        /// b0 STO (CFW500 only): safe torque off. Not in the neutral status: always 0.
        const STO = 1 << 0;
        /// b1 run command active (CFW500 only).
        const RUN_COMMAND = 1 << 1;
        /// b4 quick stop active (executing).
        const QUICK_STOP = 1 << 4;
        /// b5 second ramp.
        const SECOND_RAMP = 1 << 5;
        /// b6 configuration mode. Not in the neutral status: always 0.
        const CONFIGURATION = 1 << 6;
        /// b7 alarm.
        const ALARM = 1 << 7;
        /// b8 motor running (ramp enabled).
        const RUNNING = 1 << 8;
        /// b9 general enable active.
        const GENERAL_ENABLE = 1 << 9;
        /// b10 direction: 1 = forward.
        const FORWARD = 1 << 10;
        /// b11 JOG active.
        const JOG = 1 << 11;
        /// b12 LOC/REM: 1 = remote.
        const REMOTE = 1 << 12;
        /// b13 undervoltage.
        const UNDERVOLTAGE = 1 << 13;
        /// b14 PID automatic. Not in the neutral status: always 0.
        const PID_AUTOMATIC = 1 << 14;
        /// b15 fault.
        const FAULT = 1 << 15;
    }
}

/// P0680, the WEG status word (CFW500 Table 4.2, CFW-11 Tabela 3.2), of the drive's status
/// and the command in force (`c`: the run command, quick stop, general enable, remote) — the
/// manufacturer profile's status word, and the simulated drive's parameter P0680.
pub fn p0680(model: WegModel, c: CommandFlags, drive: &DriveStatus) -> u16 {
    let f = drive.flags;
    let mut s = P0680::empty();
    if model == WegModel::Cfw500 {
        s.set(P0680::RUN_COMMAND, c.intersects(CommandFlags::RUN | CommandFlags::JOG1));
    }
    s.set(P0680::QUICK_STOP, c.contains(CommandFlags::QUICK_STOP) && f.contains(StatusFlags::RUNNING));
    s.set(P0680::SECOND_RAMP, f.contains(StatusFlags::RAMP_SET_2));
    s.set(P0680::ALARM, f.contains(StatusFlags::WARNING));
    s.set(P0680::RUNNING, f.contains(StatusFlags::RUNNING));
    s.set(
        P0680::GENERAL_ENABLE,
        !c.contains(CommandFlags::COAST)
            && f.intersects(StatusFlags::READY | StatusFlags::RUNNING)
            && !f.contains(StatusFlags::FAULT),
    );
    let forward = if drive.speed != 0 { drive.speed > 0 } else { !f.contains(StatusFlags::REVERSE) };
    s.set(P0680::FORWARD, forward);
    s.set(P0680::JOG, f.contains(StatusFlags::JOGGING));
    // b12 LOC/REM: remote while the drive's control place is the fieldbus and P0684 b4 asks
    // for remote.
    s.set(P0680::REMOTE, f.contains(StatusFlags::FIELDBUS_CONTROL) && c.contains(CommandFlags::FIELDBUS_CONTROL));
    s.set(P0680::UNDERVOLTAGE, f.contains(StatusFlags::UNDERVOLTAGE));
    s.set(P0680::FAULT, f.contains(StatusFlags::FAULT));
    s.bits()
}

/// WEG's manufacturer profile (P0741 = 1): P0684 → [`DriveCommand`], [`DriveStatus`] →
/// P0680, P0685 / P0681 in the 13-bit scale.
///
/// No state machine: every control word is a complete command. P0684 b7 "if in a fault
/// condition, executes the reset" is taken on its 0 → 1 edge (one reset per edge, so a held
/// bit cannot reset a fault that appears later; [`DriveCommand::fault_resets`] is a counter).
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct WegManufacturer {
    model: WegModel,
    scale: SpeedScale,
    last_cw: u16,
    command: DriveCommand,
}

impl WegManufacturer {
    /// The profile for `model` with the 13-bit scale `scale` ([`WegModel::scale_13bit`]).
    pub fn new(model: WegModel, scale: SpeedScale) -> Self {
        WegManufacturer { model, scale, last_cw: 0, command: DriveCommand::default() }
    }

    /// The speed scale.
    pub fn scale(&self) -> &SpeedScale {
        &self.scale
    }

    /// A new speed scale (the drive's references read, `profile::references`).
    pub fn set_scale(&mut self, scale: SpeedScale) {
        self.scale = scale;
    }
}

impl ControlProfile for WegManufacturer {
    fn command(&mut self, cw: u16, setpoint: u16, _drive: &DriveStatus) -> DriveCommand {
        let w = P0684::from_bits_retain(cw);
        let mut flags = CommandFlags::empty();
        flags.set(CommandFlags::RUN, w.contains(P0684::RUN) && w.contains(P0684::GENERAL_ENABLE));
        flags.set(CommandFlags::COAST, !w.contains(P0684::GENERAL_ENABLE));
        // P0685: b2 = 0 runs opposite to the reference's sign.
        flags.set(CommandFlags::REVERSE, !w.contains(P0684::DIRECTION));
        flags.set(CommandFlags::JOG1, w.contains(P0684::JOG) && w.contains(P0684::GENERAL_ENABLE));
        flags.set(CommandFlags::FIELDBUS_CONTROL, w.contains(P0684::REMOTE));
        flags.set(CommandFlags::RAMP_SET_2, w.contains(P0684::SECOND_RAMP));
        if w.contains(P0684::QUICK_STOP) && w.contains(P0684::GENERAL_ENABLE) {
            // Quick stop overrides run (the neutral priority: COAST > QUICK_STOP > RUN).
            flags.insert(CommandFlags::QUICK_STOP);
            flags.remove(CommandFlags::RUN | CommandFlags::JOG1);
        }
        let mut resets = self.command.fault_resets;
        if w.contains(P0684::FAULT_RESET) && self.last_cw & P0684::FAULT_RESET.bits() == 0 {
            resets = resets.wrapping_add(1);
        }
        self.last_cw = cw;
        self.command = DriveCommand {
            flags,
            speed_setpoint: self.scale.to_n2(setpoint as i16 as i32),
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
        p0680(self.model, self.command.flags, drive)
    }

    fn actual_value(&self, drive: &DriveStatus) -> u16 {
        self.scale.word_from_n2(drive.speed)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::profile::drive_stub::Place;
    use crate::profile::profidrive::tests::{check_command, Rig};
    use crate::profile::profidrive::State;
    use proptest::prelude::*;

    // Units: 0.1 Hz. Rated frequency P0403 = 60.0 Hz; the drive's N2 reference 60.0 Hz.
    const SCALE: SpeedScale = WegModel::scale_13bit(600, 600);

    #[test]
    fn p0685_example_30hz_is_4096() {
        // CFW500 P0685: "60 Hz rated frequency ... 30 Hz → 13 bit reference = 4096".
        assert_eq!(SCALE.from_physical(300), 4096);
        assert_eq!(SCALE.from_physical(600), 8192);
        assert_eq!(SCALE.from_physical(-300), -4096);
        // CFW-11 P0685: 1800 rpm synchronous speed, 900 rpm → 4096.
        assert_eq!(WegModel::scale_13bit(1800, 1800).from_physical(900), 4096);
    }

    #[test]
    fn p0681_example_2048_is_15hz() {
        // CFW500 P0681: 2048 at 60 Hz rated → 15 Hz.
        assert_eq!(SCALE.to_physical(2048), 150);
        // CFW-11 P0681: 2048 at 1800 rpm synchronous → 450 rpm.
        assert_eq!(WegModel::scale_13bit(1800, 1800).to_physical(2048), 450);
        // Saturation at 32767 / −32768 ("maximum of 4 times").
        // N2 0x7FFF is 200 % of the N2 reference: 2 × 8192 when that is the rated frequency.
        assert_eq!(SCALE.word_from_n2(i16::MAX), 16384);
        assert_eq!(WegModel::scale_13bit(600, 3000).word_from_n2(i16::MAX), 0x7FFF);
        assert_eq!(WegModel::scale_13bit(600, 3000).word_from_n2(i16::MIN), 0x8000);
    }

    #[test]
    fn profidrive_16384_is_p0134() {
        // CFW500: P0134 = 30 Hz, 2048 read → 3.75 Hz (units 0.01 Hz).
        let s = WegModel::scale_profidrive(3000, 6000);
        assert_eq!(s.to_physical(16384), 3000);
        assert_eq!(s.to_physical(2048), 375);
        // CFW-11: P0134 = 1800 rpm, 2048 → 225 rpm.
        assert_eq!(WegModel::scale_profidrive(1800, 1800).to_physical(2048), 225);
        // To the neutral scale: N2 100 % = 60 Hz, so P0134 = 30 Hz is N2 50 %.
        assert_eq!(s.to_n2(16384), 0x2000);
        assert_eq!(s.from_n2(0x2000), 16384);
        assert_eq!(s.from_n2(-0x1000), -8192);
    }

    #[test]
    fn thirteen_bit_to_n2() {
        // 8192 = 60 Hz = N2 reference 60 Hz → 0x4000; with a 120 Hz reference → 0x2000.
        assert_eq!(SCALE.to_n2(8192), 0x4000);
        assert_eq!(SCALE.to_n2(4096), 0x2000);
        assert_eq!(SCALE.to_n2(-4096), -0x2000);
        assert_eq!(SCALE.to_n2(32767), i16::MAX, "saturates");
        let s = WegModel::scale_13bit(600, 1200);
        assert_eq!(s.to_n2(8192), 0x2000);
        assert_eq!(s.from_n2(0x2000), 8192);
    }

    #[test]
    fn p0684_command_table() {
        let mut p = WegManufacturer::new(WegModel::Cfw500, SCALE);
        let d = DriveStatus::default();
        // 0x0000: general disable → coast.
        let c = p.command(0x0000, 0, &d);
        assert_eq!(c.flags, CommandFlags::COAST | CommandFlags::REVERSE);
        // b0 run, b1 enable, b2 direction as reference, b4 remote: 0x0017.
        let c = p.command(0x0017, 4096, &d);
        assert_eq!(c.flags, CommandFlags::RUN | CommandFlags::FIELDBUS_CONTROL);
        assert_eq!(c.speed_setpoint, 0x2000);
        // b0 = 0: ramp stop.
        let c = p.command(0x0016, 4096, &d);
        assert_eq!(c.flags, CommandFlags::FIELDBUS_CONTROL);
        // b1 = 0: coast, whatever b0 says.
        let c = p.command(0x0015, 4096, &d);
        assert_eq!(c.flags, CommandFlags::COAST | CommandFlags::FIELDBUS_CONTROL);
        // Direction table of P0685: b2 = 1 and > 0 forward; b2 = 1 and < 0 reverse;
        // b2 = 0 and > 0 reverse; b2 = 0 and < 0 forward (REVERSE applies on the sign).
        for (cw, sp, forward) in
            [(0x0017u16, 4096i16, true), (0x0017, -4096, false), (0x0013, 4096, false), (0x0013, -4096, true)]
        {
            let c = p.command(cw, sp as u16, &d);
            let reverse = c.flags.contains(CommandFlags::REVERSE);
            let effective = if reverse { -c.speed_setpoint } else { c.speed_setpoint };
            assert_eq!(effective > 0, forward, "cw {:#06x} sp {}", cw, sp);
        }
        // b3 JOG, b5 second ramp, b6 quick stop.
        let c = p.command(0x001E, 0, &d);
        assert!(c.flags.contains(CommandFlags::JOG1));
        let c = p.command(0x0037, 0, &d);
        assert!(c.flags.contains(CommandFlags::RAMP_SET_2 | CommandFlags::RUN));
        let c = p.command(0x0057, 0, &d);
        assert!(c.flags.contains(CommandFlags::QUICK_STOP));
        assert!(!c.flags.contains(CommandFlags::RUN));
        // b7 fault reset: one reset per 0 → 1 edge.
        let n = c.fault_resets;
        assert_eq!(p.command(0x0090, 0, &d).fault_resets, n.wrapping_add(1));
        assert_eq!(p.command(0x0090, 0, &d).fault_resets, n.wrapping_add(1));
        assert_eq!(p.command(0x0010, 0, &d).fault_resets, n.wrapping_add(1));
        assert_eq!(p.command(0x0090, 0, &d).fault_resets, n.wrapping_add(2));
        // Communication lost: the last command with COMM_LOSS.
        let c = p.comm_lost(&d);
        assert!(c.flags.contains(CommandFlags::COMM_LOSS | CommandFlags::FIELDBUS_CONTROL));
    }

    #[test]
    fn p0680_status_from_the_drive() {
        let mut r = Rig::new(WegManufacturer::new(WegModel::Cfw500, SCALE));
        r.d.place = Place::FollowsRequest;
        // Stopped, local, enabled: b9 general enable, b10 forward.
        let (_, s) = r.cycle(0x0006, 0);
        assert_eq!(s, 0x0600);
        // Remote run forward at 30 Hz: b1 run command, b8 running, b9, b10, b12 remote.
        let (_, s) = r.run(0x0017, 4096, 10);
        assert_eq!(r.d.speed, 0x2000);
        assert_eq!(s, 0x0002 | 0x0100 | 0x0200 | 0x0400 | 0x1000);
        assert_eq!(r.actual(), 4096);
        // Reverse (b2 = 0): b10 = 0, negative P0681.
        let (_, s) = r.run(0x0013, 4096, 20);
        assert_eq!(s & 0x0400, 0);
        assert_eq!(r.actual(), (-4096i16) as u16);
        // Quick stop executing: b4.
        let (_, s) = r.cycle(0x0053, 4096);
        assert_eq!(s & 0x0010, 0x0010);
        // Fault: b15; general enable gone.
        r.d.trip();
        let (_, s) = r.cycle(0x0013, 4096);
        assert_eq!(s & 0x8200, 0x8000);
        // Fault reset edge: the drive resets.
        r.cycle(0x0093, 4096);
        assert!(!r.d.fault);
        // CFW-11: b0–b3 reserved.
        let mut r11 = Rig::new(WegManufacturer::new(WegModel::Cfw11, SCALE));
        let (_, s) = r11.run(0x0017, 4096, 10);
        assert_eq!(s & 0x000F, 0);
    }

    #[test]
    fn weg_profidrive_p0967_p0968() {
        let scale = WegModel::scale_profidrive(600, 600);
        let mut r = Rig::new(weg_profidrive(WegModel::Cfw500, scale));
        r.d.place = Place::FollowsRequest;
        r.cycle(0x0000, 0);
        r.cycle(0x047E, 0);
        // The drive goes remote on b10 (P0967 "Control By PLC"), then S4.
        let (c, _) = r.run(0x047F, 0x2000, 10);
        assert_eq!(r.p.state(), State::Operation);
        assert_eq!(c.speed_setpoint, 0x2000);
        let (_, z) = r.run(0x047F, 0x2000, 10);
        // P0968 (CFW500): b0–b2, b4, b5, b9 (b8, b10–b15 reserved).
        assert_eq!(z, 0x0237);
        // b5 is reserved at WEG: no freeze.
        let (c, _) = r.cycle(0x045F, 0x1000);
        assert!(!c.flags.contains(CommandFlags::RAMP_HOLD));
        assert_eq!(c.speed_setpoint, 0x1000);
        // b8 JOG 1.
        let (c, _) = r.cycle(0x057F, 0x1000);
        assert!(c.flags.contains(CommandFlags::JOG1));
        // b6 = 0 "resets the speed reference".
        let (c, _) = r.cycle(0x043F, 0x1000);
        assert_eq!(c.speed_setpoint, 0);
        // CFW-11 reports b10 frequency reached.
        assert_eq!(WegModel::Cfw11.p0968_mask() & 0x0400, 0x0400);
    }

    proptest! {
        #[test]
        fn manufacturer_never_panics(seq in proptest::collection::vec((any::<u16>(), any::<u16>(), any::<u16>(), any::<i16>(), any::<bool>()), 1..60)) {
            let mut p = WegManufacturer::new(WegModel::Cfw500, WegModel::scale_13bit(600, 500));
            for (cw, sp, f, speed, lost) in seq {
                let d = DriveStatus { flags: StatusFlags::from_bits_retain(f), speed, ..DriveStatus::default() };
                let c = if lost { p.comm_lost(&d) } else { p.command(cw, sp, &d) };
                check_command(&c)?;
                let s = p.status_word(&d);
                prop_assert_eq!(s & 0x4041, 0, "STO, configuration, PID bits are not modelled");
                prop_assert_eq!(s & 0x8000 != 0, f & StatusFlags::FAULT.bits() != 0);
                let _ = p.actual_value(&d);
            }
        }
    }
}
