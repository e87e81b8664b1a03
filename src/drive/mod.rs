//! A simulated AC drive's control board behind the DPM — what a drive maker's firmware does
//! with the card, far enough to be alive. The QEMU firmware, the soft slave and the host tests
//! run it; `no_std`, allocation-free, time passed in.
//!
//! [`SimDrive::step`] talks to the card only through the host-side reference implementation
//! ([`crate::dpm::host::Host`], issue 7 item 5) over any [`Transport`]: it reads DRIVE_CMD
//! (the drive-neutral command of [`crate::profile::drive_if`]), runs the drive model
//! ([`model::DriveModel`]: ramps, quick stop, coast, jog, faults, communication-loss
//! reactions, current / torque / power), writes DRIVE_STATE, reports faults and warnings in
//! the DRIVE block (with the GSD's device-related diagnosis block), keeps its heartbeat
//! going, and serves the parameter mailbox from its parameter table ([`params`]).
//!
//! Programmable PZD words are echoed (each input word = the output word of the same
//! position), so a PLC program can check its word mapping. In the Bypass operate mode
//! (OPTE3/E5 §5.1.2, §6.7) the card passes the raw words: the drive reads word 1 as its
//! FBFixedControlWord (OPTE3/E5 §11.1 Table 146: b0 run, b1 reverse, b2 fault reset edge)
//! and word 2 as the setpoint 0..10000 = 0..100 %, and answers FBFixedStatusWord (§11.3
//! Table 149) and the actual speed 0..10000, the other words echoed.

pub mod model;
pub mod params;

use crate::dpm::host::{Host, Transport};
use crate::dpm::layout::operate_mode;
use crate::dpm::{DriveCommandImage, DriveStateImage, PzdWords};
use crate::profile::drive_if::{CommandFlags, DriveCommand, DriveStatus, StatusFlags};
use crate::time::Instant;
use model::{DriveModel, N2_100};
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
}

/// The simulated drive's control board (module docs).
#[derive(Debug, Clone)]
pub struct SimDrive {
    model: DriveModel,
    table: DriveTable,
    serve_parameters: bool,
    image: DriveCommandImage,
    command: DriveCommand,
    status: DriveStatus,
    bypass_cw: u16,
    bypass_resets: u8,
    diag: [u8; 3],
    stats: SimStats,
}

impl SimDrive {
    /// A drive at standstill, ready, with its factory parameter table.
    pub fn new(config: DriveConfig) -> Self {
        SimDrive {
            model: DriveModel::new(config),
            table: sim_drive_table(),
            serve_parameters: true,
            image: DriveCommandImage::EMPTY,
            command: DriveCommand::default(),
            status: DriveStatus::default(),
            bypass_cw: 0,
            bypass_resets: 0,
            diag: [0; 3],
            stats: SimStats::default(),
        }
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
    /// The parameter table, mutable.
    pub fn params_mut(&mut self) -> &mut DriveTable {
        &mut self.table
    }
    /// Whether the drive answers the parameter mailbox (default yes; off: a control board
    /// that does not answer — fault injection).
    pub fn set_serve_parameters(&mut self, on: bool) {
        self.serve_parameters = on;
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
        host.poll(now);
        match host.read_command() {
            Ok((_, img)) => self.image = img,
            Err(_) => self.stats.command_errors = self.stats.command_errors.wrapping_add(1),
        }
        let bypass = self.image.operate_mode == operate_mode::BYPASS;
        self.command = if bypass { self.bypass_command() } else { self.image.command };
        self.status = self.model.step(now, &self.command);
        let extra = if bypass { self.bypass_words() } else { self.image.extra };
        let state = DriveStateImage { status: self.status, inputs_seq: 0, extra };
        if host.write_state(&state).is_err() {
            self.stats.write_errors = self.stats.write_errors.wrapping_add(1);
        }
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
            let _ = host.serve_parameters(&mut crate::dpm::host::Table(&mut self.table));
        }
    }

    /// Bypass: FBFixedControlWord (word 1) and the 0..10000 setpoint (word 2).
    fn bypass_command(&mut self) -> DriveCommand {
        let w = self.image.extra.words();
        let cw = w.first().copied().unwrap_or(0);
        let sp = w.get(1).copied().unwrap_or(0).min(10_000) as i32;
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
}
