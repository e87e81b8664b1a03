//! The simulated drive's parameter set: a [`Table`] over [`DRIVE_PARAMS`], the table behind
//! record 47 / 48 for every PNU the card does not own itself.
//!
//! | PNU | name | type | range | default | unit | access | source |
//! |---|---|---|---|---|---|---|---|
//! | 3 | INVT P00.03 maximum output frequency Fmax | U16 | 1..60000 | 5000 | 0.01 Hz | rw | INVT Table 2-6 "0–Fmax" (`profile::references`) |
//! | 100 | acceleration time | U16 | 0..9999 | 50 | 0.1 s | rw | WEG P0100 (CFW-11 §4.2.5 Exemplo 2: 8.5 s is sent as 85; CFW500 P0750: 5.0 s as 50) |
//! | 101 | deceleration time | U16 | 0..9999 | 50 | 0.1 s | rw | WEG P0101 (CFW500 P0680 bit 5: the first ramp is P0100/P0101) |
//! | 133 | minimum speed | U16 | 0..18000 | 90 | rpm | rw | WEG P0133 |
//! | 134 | maximum speed | U16 | 0..18000 | 1800 | rpm | rw | WEG P0134 (CFW-11 §3: 0x4000 = P0134 in the PROFIdrive profile; the manual's example 1800 rpm) |
//! | 403 | rated frequency | U16 | 1..400 | 50 | Hz | rw | WEG P0403 (CFW500 P0681: 8192 = P0403; `profile::references`) |
//! | 514 | INVT P02.02 motor rated frequency | U16 | 1..60000 | 5000 | 0.01 Hz | rw | INVT motor parameters (P02.02; N2 0x4000, `profile::references`) |
//! | 680 | status word | U16 | 0..FFFFh | 0 | bits | ro | WEG P0680 (CFW500 Table 4.2: "Range 0000h to FFFFh … Properties: RO") |
//! | 681 | motor speed in 13 bits | I16 | −32768..32767 | 0 | 8192 = synchronous speed | ro | WEG P0681 (CFW500, CFW-11: 2000h = rated / synchronous speed, 1800 rpm for 4 poles at 60 Hz) |
//! | 684 | control word | U16 | 0..FFFFh | 0 | bits | rw | WEG P0684 (CFW500 Table 4.3) |
//! | 685 | speed reference | I16 | −32768..32767 | 0 | 8192 = synchronous speed | rw | WEG P0685 |
//! | 3842..3852 | INVT P15.02–P15.12 received PZD2..PZD12 | U16 | 0..18 | P15.02 = 1, others 0 | – | rw | INVT Table 2-6 (0 invalid, 1 set frequency, …) |
//! | 3853..3863 | INVT P15.13–P15.23 transmitted PZD2..PZD12 | U16 | 0..24 (P15.13: 1) | P15.13 = 1, others 0 | – | rw | INVT Table 2-8 (0 invalid, 1 running frequency, …) |
//! | 9900 | dummy writeable single parameter | U16 | full | 0 | – | rw | VACON OPTE3/E5 §6.4.5 Table 108 (test parameter) |
//! | 9901 | dummy writeable array parameter | U16\[8\] | full | 0 | – | rw | VACON Table 108 (test array parameter) |
//! | 10109 | process data in words | U16\[16\] | full | 0 | – | ro | VACON Table 108 ("Process Data In word UINT\[16\]", §6.9) |
//! | 10111 | speed physical reference value | U16 | 1..18000 | 1800 | rpm | ro | VACON Table 108 / §6.3.7: the rpm worth 0x4000 = 100.00 % |
//!
//! The WEG ranges of P0100/P0101 (0.0–999.9 s) and P0133/P0134 (0–18000 rpm) are those of the
//! CFW-11 programming manual, which is not among the seeds; the communication manuals only give
//! the units. P0681 and P0685 are ratios (variable index 24) normalised at bit 13 to the
//! reference speed P10111 (VACON §6.4.3.15–6.4.3.16), which the simulated drive takes as the
//! synchronous speed; P10111 is read-only for the master as on the VACON board (it follows the
//! motor's nominal speed), the drive sets it with [`Table::set`].
//!
//! **INVT P15.02–P15.23** are numbered as the INVT PKW addresses them, group × 256 + code
//! (P15.02 = 0x0F02; our reading of the function-code numbering — the manual's PKW example
//! only shows address 0x0010). The manual's factory setting of P15.02 is 0 "invalid" (the
//! bus sets no frequency); the simulated drive is delivered commissioned for the fieldbus,
//! P15.02 = 1 "set frequency" and P15.13 = 1 "running frequency", as a PLC program for this
//! card expects. PZD2 of the response is built by the card (the running frequency,
//! [`crate::profile::invt`]), so P15.13 accepts only 1. What the simulated drive does with
//! the others: see [`crate::drive`] "INVT".
//!
//! The drive updates the read-only values (status word, speed, process data) with
//! [`Table::set`] and reads its ramp from [`acceleration_time`] / [`deceleration_time`].

use crate::profile::table::{slots, ParamDef, Table, Type, CONV_BASE, CONV_PER_MINUTE, VAR_RATIO, VAR_SPEED, VAR_TIME};
use crate::time::Duration;

/// INVT P00.03 maximum output frequency Fmax, 0.01 Hz (group × 256 + code).
pub const P_INVT_FMAX: u16 = 0x0003;
/// WEG P0403 rated frequency, Hz.
pub const P_RATED_FREQUENCY: u16 = 403;
/// INVT P02.02 motor rated frequency, 0.01 Hz.
pub const P_INVT_RATED_FREQUENCY: u16 = 0x0202;
/// P0100 acceleration time, 0.1 s.
pub const P_ACCELERATION_TIME: u16 = 100;
/// P0101 deceleration time, 0.1 s.
pub const P_DECELERATION_TIME: u16 = 101;
/// P0133 minimum speed, rpm.
pub const P_MIN_SPEED: u16 = 133;
/// P0134 maximum speed, rpm.
pub const P_MAX_SPEED: u16 = 134;
/// P0680 status word (read-only).
pub const P_STATUS_WORD: u16 = 680;
/// P0681 motor speed, 13 bits (read-only).
pub const P_SPEED_13BIT: u16 = 681;
/// P0684 control word.
pub const P_CONTROL_WORD: u16 = 684;
/// P0685 speed reference, 13 bits.
pub const P_SPEED_REFERENCE: u16 = 685;
/// INVT P15.02 (received PZD2), numbered group × 256 + code: P15.(k) for PZD k is
/// [`P_INVT_RECEIVED`] + k − 2, k = 2..=12.
pub const P_INVT_RECEIVED: u16 = 0x0F02;
/// INVT P15.13 (transmitted PZD2): P15.(11 + k) for PZD k is [`P_INVT_TRANSMITTED`] + k − 2.
pub const P_INVT_TRANSMITTED: u16 = 0x0F0D;
/// INVT Table 2-6 / 2-8 value 1: set frequency (received) / running frequency (transmitted).
pub const INVT_FREQUENCY: i64 = 1;
/// PNU 9900: VACON's dummy writeable single parameter.
pub const P_DUMMY: u16 = 9900;
/// PNU 9901: VACON's dummy writeable array parameter, 8 elements.
pub const P_DUMMY_ARRAY: u16 = 9901;
/// PNU 10109: process data in words, 16 elements (read-only).
pub const P_PD_IN: u16 = 10109;
/// PNU 10111: speed physical reference value, rpm (0x4000 = 100.00 %).
pub const P_REFERENCE_SPEED: u16 = 10111;

/// 2000h: the 13-bit speed scale's 100 % (WEG P0681 / P0685).
pub const SPEED_13BIT_100: i64 = 0x2000;

/// Percent per count of a 13-bit speed (8192 = 100 %), exact in f32.
const PERCENT_PER_13BIT: f32 = 100.0 / 8192.0;

/// The simulated drive's parameters, ascending by PNU.
pub const DRIVE_PARAMS: &[ParamDef] = &[
    ParamDef::new(P_INVT_FMAX, "P00.03 Fmax", Type::U16).limits(1, 60000).with_default(5000),
    ParamDef::new(P_ACCELERATION_TIME, "Accel. Time", Type::U16)
        .limits(0, 9999)
        .with_default(50)
        .scaled(0.1, VAR_TIME, CONV_BASE),
    ParamDef::new(P_DECELERATION_TIME, "Decel. Time", Type::U16)
        .limits(0, 9999)
        .with_default(50)
        .scaled(0.1, VAR_TIME, CONV_BASE),
    ParamDef::new(P_MIN_SPEED, "Minimum Speed", Type::U16).limits(0, 18000).with_default(90).scaled(
        1.0,
        VAR_SPEED,
        CONV_PER_MINUTE,
    ),
    ParamDef::new(P_MAX_SPEED, "Maximum Speed", Type::U16).limits(0, 18000).with_default(1800).scaled(
        1.0,
        VAR_SPEED,
        CONV_PER_MINUTE,
    ),
    ParamDef::new(P_RATED_FREQUENCY, "Rated Frequency", Type::U16).limits(1, 400).with_default(50),
    ParamDef::new(P_INVT_RATED_FREQUENCY, "P02.02 Rated Frq", Type::U16).limits(1, 60000).with_default(5000),
    ParamDef::new(P_STATUS_WORD, "Status Word", Type::U16).read_only(),
    ParamDef::new(P_SPEED_13BIT, "Speed 13 bits", Type::I16)
        .read_only()
        .scaled(PERCENT_PER_13BIT, VAR_RATIO, CONV_BASE)
        .normalised(P_REFERENCE_SPEED, 13),
    ParamDef::new(P_CONTROL_WORD, "Control Word", Type::U16),
    ParamDef::new(P_SPEED_REFERENCE, "Speed Reference", Type::I16)
        .scaled(PERCENT_PER_13BIT, VAR_RATIO, CONV_BASE)
        .normalised(P_REFERENCE_SPEED, 13),
    ParamDef::new(P_INVT_RECEIVED, "P15.02 Rx PZD2", Type::U16).limits(0, 18).with_default(INVT_FREQUENCY),
    ParamDef::new(P_INVT_RECEIVED + 1, "P15.03 Rx PZD3", Type::U16).limits(0, 18),
    ParamDef::new(P_INVT_RECEIVED + 2, "P15.04 Rx PZD4", Type::U16).limits(0, 18),
    ParamDef::new(P_INVT_RECEIVED + 3, "P15.05 Rx PZD5", Type::U16).limits(0, 18),
    ParamDef::new(P_INVT_RECEIVED + 4, "P15.06 Rx PZD6", Type::U16).limits(0, 18),
    ParamDef::new(P_INVT_RECEIVED + 5, "P15.07 Rx PZD7", Type::U16).limits(0, 18),
    ParamDef::new(P_INVT_RECEIVED + 6, "P15.08 Rx PZD8", Type::U16).limits(0, 18),
    ParamDef::new(P_INVT_RECEIVED + 7, "P15.09 Rx PZD9", Type::U16).limits(0, 18),
    ParamDef::new(P_INVT_RECEIVED + 8, "P15.10 Rx PZD10", Type::U16).limits(0, 18),
    ParamDef::new(P_INVT_RECEIVED + 9, "P15.11 Rx PZD11", Type::U16).limits(0, 18),
    ParamDef::new(P_INVT_RECEIVED + 10, "P15.12 Rx PZD12", Type::U16).limits(0, 18),
    ParamDef::new(P_INVT_TRANSMITTED, "P15.13 Tx PZD2", Type::U16).limits(1, 1).with_default(INVT_FREQUENCY),
    ParamDef::new(P_INVT_TRANSMITTED + 1, "P15.14 Tx PZD3", Type::U16).limits(0, 24),
    ParamDef::new(P_INVT_TRANSMITTED + 2, "P15.15 Tx PZD4", Type::U16).limits(0, 24),
    ParamDef::new(P_INVT_TRANSMITTED + 3, "P15.16 Tx PZD5", Type::U16).limits(0, 24),
    ParamDef::new(P_INVT_TRANSMITTED + 4, "P15.17 Tx PZD6", Type::U16).limits(0, 24),
    ParamDef::new(P_INVT_TRANSMITTED + 5, "P15.18 Tx PZD7", Type::U16).limits(0, 24),
    ParamDef::new(P_INVT_TRANSMITTED + 6, "P15.19 Tx PZD8", Type::U16).limits(0, 24),
    ParamDef::new(P_INVT_TRANSMITTED + 7, "P15.20 Tx PZD9", Type::U16).limits(0, 24),
    ParamDef::new(P_INVT_TRANSMITTED + 8, "P15.21 Tx PZD10", Type::U16).limits(0, 24),
    ParamDef::new(P_INVT_TRANSMITTED + 9, "P15.22 Tx PZD11", Type::U16).limits(0, 24),
    ParamDef::new(P_INVT_TRANSMITTED + 10, "P15.23 Tx PZD12", Type::U16).limits(0, 24),
    ParamDef::new(P_DUMMY, "Dummy Single", Type::U16),
    ParamDef::new(P_DUMMY_ARRAY, "Dummy Array", Type::U16).array(8),
    ParamDef::new(P_PD_IN, "PD In Words", Type::U16).array(16).read_only(),
    ParamDef::new(P_REFERENCE_SPEED, "Reference Speed", Type::U16)
        .limits(1, 18000)
        .with_default(1800)
        .read_only()
        .scaled(1.0, VAR_SPEED, CONV_PER_MINUTE),
];

/// PNU 10001 "parameter in drive" (OPTE3/E5 Table 108, §6.4.4.7): the VACON application ID
/// as subindex; the PPO types' PKW addresses the same IDs (§6.6.1).
pub use crate::profile::pkw::VACON_DRIVE_PARAMETER;

/// VACON ID 101 minimum frequency, 0.01 Hz.
pub const ID_MIN_FREQUENCY: u16 = 101;
/// VACON ID 102 maximum frequency, 0.01 Hz (OPTE3/E5 §6.6.3.1: 50.00 Hz read as 5000).
pub const ID_MAX_FREQUENCY: u16 = 102;
/// VACON ID 103 acceleration time 1, 0.1 s (OPTE3/E5 §6.4.4.7 example: 3.0 s as 30).
pub const ID_ACCELERATION_TIME: u16 = 103;
/// VACON ID 104 deceleration time 1, 0.1 s.
pub const ID_DECELERATION_TIME: u16 = 104;
/// VACON ID 111 motor nominal frequency, 0.01 Hz: the frequency of the nominal speed P10111,
/// N2 0x4000 (`profile::references`).
pub const ID_MOTOR_NOMINAL_FREQUENCY: u16 = 111;
/// VACON ID 125 control place (OPTE3/E5 §6.6.3.2 writes 2): 1 I/O terminal, 2 keypad,
/// 3 fieldbus.
pub const ID_CONTROL_PLACE: u16 = 125;
/// VACON ID 733 "response to fieldbus fault" (OPTE3/E5 Table 141, VACON 100 family coding:
/// 0 no action, 1 alarm, 2 alarm + preset frequency, 3 fault: stop function, 4 fault:
/// coast). The simulated drive's factory value is 4, the action its model is built with
/// (VACON 100's factory default is 3); a value written through the card becomes the drive's
/// own communication-loss action ([`crate::drive`] "communication errors").
pub const ID_FIELDBUS_FAULT_RESPONSE: u16 = 733;

/// The simulated drive's VACON application parameters (the IDs the manual's examples use),
/// a table of their own: VACON's IDs overlap WEG's P numbers (ID 101 is a frequency, P0101 a
/// ramp time), so PNU 10001 / the PPO PKW never reach the WEG-numbered table.
pub const VACON_IDS: &[ParamDef] = &[
    ParamDef::new(ID_MIN_FREQUENCY, "Min Frequency", Type::U16).limits(0, 32000).with_default(0),
    ParamDef::new(ID_MAX_FREQUENCY, "Max Frequency", Type::U16).limits(0, 32000).with_default(5000),
    ParamDef::new(ID_ACCELERATION_TIME, "Accel Time 1", Type::U16).limits(1, 30000).with_default(30),
    ParamDef::new(ID_DECELERATION_TIME, "Decel Time 1", Type::U16).limits(1, 30000).with_default(30),
    ParamDef::new(ID_MOTOR_NOMINAL_FREQUENCY, "Motor Nom Freq", Type::U16).limits(1, 32000).with_default(5000),
    ParamDef::new(ID_CONTROL_PLACE, "Control Place", Type::U16).limits(1, 3).with_default(3),
    ParamDef::new(ID_FIELDBUS_FAULT_RESPONSE, "FB Fault Resp", Type::U16).limits(0, 4).with_default(4),
];

/// The VACON application parameter table.
pub type VaconIdTable = Table<VACON_ID_SLOTS>;

/// Value slots of [`VACON_IDS`].
pub const VACON_ID_SLOTS: usize = slots(VACON_IDS);

/// [`VACON_IDS`] at their factory settings.
pub const VACON_ID_TABLE: VaconIdTable = Table::new(VACON_IDS);

/// Value slots of [`DRIVE_PARAMS`].
pub const DRIVE_SLOTS: usize = slots(DRIVE_PARAMS);

/// The simulated drive's parameter table.
pub type DriveTable = Table<DRIVE_SLOTS>;

/// The table at its factory settings (checked at compile time).
pub const SIM_DRIVE_TABLE: DriveTable = Table::new(DRIVE_PARAMS);

/// The simulated drive's table at its factory settings.
pub const fn sim_drive_table() -> DriveTable {
    SIM_DRIVE_TABLE
}

/// A time in 0.1 s from the table.
fn tenths(t: &DriveTable, pnu: u16) -> Duration {
    Duration::from_millis(t.get(pnu, 0).map_or(0, |v| v.max(0) as u64 * 100))
}

/// P0100: the ramp time from 0 to the maximum speed.
pub fn acceleration_time(t: &DriveTable) -> Duration {
    tenths(t, P_ACCELERATION_TIME)
}

/// P0101: the ramp time from the maximum speed to 0.
pub fn deceleration_time(t: &DriveTable) -> Duration {
    tenths(t, P_DECELERATION_TIME)
}

/// PNU 10111: the rpm that 0x4000 (100.00 %) stands for.
pub fn reference_speed_rpm(t: &DriveTable) -> u16 {
    t.get(P_REFERENCE_SPEED, 0).map_or(0, |v| v as u16)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::profile::param::{ParamAddress, ParameterAccess, ValueWriter};
    use crate::profile::table::FormatStyle;

    #[test]
    fn factory_settings() {
        let t = sim_drive_table();
        assert_eq!(DRIVE_SLOTS, 13 + 22 + 8 + 16, "13 single values, P15.02–P15.23, 9901 [8], 10109 [16]");
        assert_eq!(acceleration_time(&t), Duration::from_millis(5000));
        assert_eq!(deceleration_time(&t), Duration::from_millis(5000));
        assert_eq!(reference_speed_rpm(&t), 1800);
        assert_eq!((t.get(P_MIN_SPEED, 0), t.get(P_MAX_SPEED, 0)), (Some(90), Some(1800)));
        assert!(t.defs().iter().all(|d| d.name.len() <= 16));
        // Every PNU is outside the card's own (918..=980).
        assert!(t.defs().iter().all(|d| !(918..=980).contains(&d.pnu)));
    }

    #[test]
    fn the_drive_sets_what_the_master_only_reads() {
        let mut t = sim_drive_table().with_formats(FormatStyle::Untyped);
        t.set(P_STATUS_WORD, 0, 0x0302).unwrap();
        t.set(P_SPEED_13BIT, 0, -SPEED_13BIT_100).unwrap();
        t.set(P_ACCELERATION_TIME, 0, 85).unwrap();
        assert_eq!(acceleration_time(&t), Duration::from_millis(8500));
        let mut buf = [0u8; 8];
        let mut w = ValueWriter::new(&mut buf);
        let a = ParamAddress {
            attribute: crate::profile::param::Attribute::Value,
            elements: 1,
            pnu: P_SPEED_13BIT,
            subindex: 0,
        };
        t.read_value(1, &a, &mut w).unwrap();
        assert_eq!(w.bytes(), [0xE0, 0x00]);
        // The 13-bit percent factor is exact.
        assert_eq!(PERCENT_PER_13BIT * 8192.0, 100.0);
    }
}
