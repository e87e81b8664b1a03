//! A simulated AC drive behind the DPM: what the drive's control board would do with the
//! process data, far enough to be alive. The QEMU firmware, the soft slave and the host tests
//! run it; `no_std`, allocation-free, time passed in.
//!
//! [`SimDrive::step`] reads OUTPUTS through the host side of the [`Dpm`](crate::dpm::Dpm)
//! (drive-neutral: the raw PZD words and the telegram that lays them out), runs the
//! PROFIdrive general state diagram ([`profidrive`]) and a ramp-function generator, and
//! writes INPUTS:
//!
//! | telegram | master → drive | drive → master |
//! |---|---|---|
//! | Standard Telegram 1 | STW1, NSOLL_A | ZSW1, NIST_A |
//! | PPO 1/2/5 | PKW (4 words), STW, HSW, PZD3.. | PKW = 0 (the PKW channel is a later issue), ZSW, HIW, PZD3.. echoed |
//! | PPO 3/4/6 | STW, HSW, PZD3.. | ZSW, HIW, PZD3.. echoed |
//!
//! Speeds are N2 values: 0x4000 = 100 % of the reference speed, negative = reverse. The ramp
//! takes [`DriveConfig::ramp_time`] from 0 to 100 % (and back for OFF1), the quick stop
//! [`DriveConfig::quick_stop_time`]. The words after ZSW/HIW of the PPO types are echoed so a
//! PLC program can check its word mapping (as the OPTE3/E5 Echo operate mode does).
//!
//! ZSW1: b0/b1/b2/b3/b6 from the state, b4/b5 mirror STW1 b1/b2, b7 the simulated warning,
//! b8 |NIST − target| ≤ [`DriveConfig::setpoint_tolerance`] in S4, b9 always (the drive wants
//! PLC control), b10 |NIST| ≥ [`DriveConfig::compare_speed`].

pub mod model;
pub mod params;
pub mod profidrive;

use crate::dpm::{HostSide, PdFlags, ProcessData, Telegram};
use crate::time::{Duration, Instant};
use profidrive::{Command, DriveState, StopKind, Stw1, Zsw1};

/// 100 % speed in the N2 coding.
pub const SPEED_100: i32 = 0x4000;

/// Micro-units per speed count (the ramp integrates in these, so no step is lost to rounding).
const MICRO: i64 = 1_000_000;

/// Settings of the simulated drive.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DriveConfig {
    /// Ramp-function generator: time from 0 to 100 % (also 100 % → 0 for OFF1). Zero = jump.
    pub ramp_time: Duration,
    /// Quick stop (OFF3, STW1 b4 = 0): time from 100 % to 0. Zero = jump.
    pub quick_stop_time: Duration,
    /// ZSW1 b8 "at setpoint": largest |actual − target| in N2 counts (default 1 % = 0x00A4).
    pub setpoint_tolerance: u16,
    /// ZSW1 b10 "f/n reached": the comparison speed in N2 counts (default 100 % = 0x4000).
    pub compare_speed: u16,
}

impl DriveConfig {
    /// 2 s ramp, 0.5 s quick stop, 1 % tolerance, comparison speed 100 %.
    pub const DEFAULT: DriveConfig = DriveConfig {
        ramp_time: Duration::from_millis(2000),
        quick_stop_time: Duration::from_millis(500),
        setpoint_tolerance: 0x00A4,
        compare_speed: 0x4000,
    };
}

impl Default for DriveConfig {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Why the simulated drive is in fault.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum FaultCause {
    /// STW1 b10 "control by PLC" dropped while the motor was powered (watchdog, Clear, PLC).
    ControlLost,
    /// [`SimDrive::inject_fault`].
    Injected,
}

/// The simulated drive.
#[derive(Debug, Clone)]
pub struct SimDrive {
    config: DriveConfig,
    state: DriveState,
    fault: Option<FaultCause>,
    warning: bool,
    /// Actual speed in N2 counts × [`MICRO`].
    speed: i64,
    /// The last control word with b10 set (the one in force).
    stw1: Stw1,
    /// The setpoint in force (N2).
    setpoint: i16,
    outputs: ProcessData,
    last_step: Option<Instant>,
    /// OUTPUTS sequence answered last, and the image written then.
    answered_seq: u16,
    last_inputs: Option<ProcessData>,
    torn_reads: u32,
}

impl SimDrive {
    /// A drive at standstill in S1, no telegram.
    pub fn new(config: DriveConfig) -> Self {
        SimDrive {
            config,
            state: DriveState::SwitchingOnInhibited,
            fault: None,
            warning: false,
            speed: 0,
            stw1: Stw1::empty(),
            setpoint: 0,
            outputs: ProcessData::new(Telegram::None, PdFlags::empty(), &[]),
            last_step: None,
            answered_seq: 0,
            last_inputs: None,
            torn_reads: 0,
        }
    }

    /// Settings.
    pub fn config(&self) -> &DriveConfig {
        &self.config
    }
    /// State of the general state diagram.
    pub fn state(&self) -> DriveState {
        self.state
    }
    /// Why it is in fault.
    pub fn fault(&self) -> Option<FaultCause> {
        self.fault
    }
    /// Actual speed NIST_A (N2).
    pub fn actual_speed(&self) -> i16 {
        (self.speed / MICRO).clamp(i16::MIN as i64, i16::MAX as i64) as i16
    }
    /// The setpoint in force NSOLL_A (N2).
    pub fn setpoint(&self) -> i16 {
        self.setpoint
    }
    /// The raw control word the master sends now (b10 may be 0).
    pub fn control_word(&self) -> u16 {
        self.outputs.word(self.outputs.telegram.pkw_words())
    }
    /// The telegram the drive answers.
    pub fn telegram(&self) -> Telegram {
        self.outputs.telegram
    }
    /// OUTPUTS reads that saw a write in progress.
    pub fn torn_reads(&self) -> u32 {
        self.torn_reads
    }

    /// ZSW1 as it is now.
    pub fn status_word(&self) -> u16 {
        let mut z = self.state.zsw1() | Zsw1::CONTROL_REQUESTED;
        z.set(Zsw1::NO_COAST_STOP, self.stw1.contains(Stw1::NO_COAST_STOP));
        z.set(Zsw1::NO_QUICK_STOP, self.stw1.contains(Stw1::NO_QUICK_STOP));
        z.set(Zsw1::WARNING, self.warning);
        let n = self.actual_speed() as i32;
        let at = (n - self.target() as i32).unsigned_abs() <= self.config.setpoint_tolerance as u32;
        z.set(Zsw1::AT_SETPOINT, self.state == DriveState::Operation && at);
        z.set(Zsw1::SPEED_REACHED, n.unsigned_abs() >= self.config.compare_speed as u32);
        z.bits()
    }

    /// Put the drive in fault (coast to standstill).
    pub fn inject_fault(&mut self) {
        self.enter_fault(FaultCause::Injected);
    }

    /// Set or clear the simulated warning (ZSW1 b7).
    pub fn set_warning(&mut self, on: bool) {
        self.warning = on;
    }

    /// One step at `now`: read OUTPUTS, run the state machine and the ramp, write INPUTS when
    /// the master sent new outputs or the answer changed.
    pub fn step(&mut self, now: Instant, dpm: &mut HostSide<'_>) {
        let dt = self.last_step.map_or(Duration::ZERO, |t| now - t);
        self.last_step = Some(now);
        match dpm.read_outputs() {
            Ok(pd) => self.outputs = pd,
            Err(_) => self.torn_reads = self.torn_reads.wrapping_add(1),
        }
        self.control();
        self.ramp(dt);
        // S5 ends at standstill.
        self.state = profidrive::settle(self.state, self.command(false));
        self.answer(dpm);
    }

    /// The speed the ramp heads for.
    fn target(&self) -> i16 {
        match self.state {
            DriveState::Operation
                if self.stw1.contains(Stw1::ENABLE_RAMP) && self.stw1.contains(Stw1::ENABLE_SETPOINT) =>
            {
                self.setpoint
            }
            _ => 0,
        }
    }

    fn command(&self, fault_ack: bool) -> Command {
        Command { stw1: self.stw1, fault_ack, standstill: self.speed == 0 }
    }

    fn enter_fault(&mut self, cause: FaultCause) {
        self.state = DriveState::Fault;
        self.fault = Some(cause);
        self.speed = 0;
    }

    /// Evaluate the control word and the setpoint.
    fn control(&mut self) {
        let pkw = self.outputs.telegram.pkw_words();
        let stw1 = Stw1::from_bits_retain(self.outputs.word(pkw));
        if !stw1.contains(Stw1::CONTROL_BY_PLC) {
            // The words are not valid: keep the last ones; a powered motor faults.
            if self.state.is_running() {
                self.enter_fault(FaultCause::ControlLost);
            }
            return;
        }
        let ack = stw1.contains(Stw1::FAULT_ACK) && !self.stw1.contains(Stw1::FAULT_ACK);
        self.stw1 = stw1;
        self.setpoint = self.outputs.word(pkw + 1) as i16;
        let before = self.state;
        self.state = profidrive::settle(self.state, self.command(ack));
        if before == DriveState::Fault && self.state != DriveState::Fault {
            self.fault = None;
        }
        if !self.state.is_running() {
            // Pulses off: coast (S1, S2, S3 and fault have no speed).
            self.speed = 0;
        }
    }

    /// Move the actual speed toward the target along the ramp in force.
    fn ramp(&mut self, dt: Duration) {
        if !self.state.is_running() {
            return;
        }
        let quick = self.state == DriveState::SwitchingOff(StopKind::Quick)
            || (self.state == DriveState::Operation && !self.stw1.contains(Stw1::ENABLE_RAMP));
        if self.state == DriveState::Operation && !quick && !self.stw1.contains(Stw1::UNFREEZE_RAMP) {
            return; // STW1 b5 = 0: hold the ramp-function generator.
        }
        let time = if quick { self.config.quick_stop_time } else { self.config.ramp_time };
        let target = self.target() as i64 * MICRO;
        let dt_us = dt.as_micros().min(10_000_000) as i64;
        let step = match time.as_micros() {
            0 => i64::MAX,
            t => (SPEED_100 as i64 * MICRO).saturating_mul(dt_us) / t as i64,
        };
        self.speed = if self.speed < target {
            self.speed.saturating_add(step).min(target)
        } else {
            self.speed.saturating_sub(step).max(target)
        };
    }

    /// Write INPUTS for the telegram of the outputs.
    fn answer(&mut self, dpm: &mut HostSide<'_>) {
        let t = self.outputs.telegram;
        if !t.is_known() {
            return;
        }
        let (pkw, pzd) = (t.pkw_words(), t.pzd_words());
        let mut bytes = [0u8; crate::dpm::layout::PD_CAPACITY];
        let put = |bytes: &mut [u8], i: usize, w: u16| bytes[2 * i..2 * i + 2].copy_from_slice(&w.to_be_bytes());
        put(&mut bytes, pkw, self.status_word());
        put(&mut bytes, pkw + 1, self.actual_speed() as u16);
        for i in pkw + 2..pkw + pzd {
            put(&mut bytes, i, self.outputs.word(i));
        }
        let pd = ProcessData::new(t, PdFlags::empty(), &bytes[..2 * (pkw + pzd)]);
        if self.outputs.seq != self.answered_seq || self.last_inputs.as_ref() != Some(&pd) {
            dpm.write_inputs(&pd);
            self.answered_seq = self.outputs.seq;
            self.last_inputs = Some(pd);
        }
    }
}

#[cfg(test)]
mod tests;
