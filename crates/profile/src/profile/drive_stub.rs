//! A small drive for the control-profile tests: it reacts to a [`DriveCommand`] one drive
//! cycle at a time (runs, ramps to standstill, coasts, quick-stops, jogs, trips and resets)
//! and reports a [`DriveStatus`]. Speeds are N2.

use super::drive_if::{CommandFlags, DriveCommand, DriveStatus, StatusFlags};

/// Where the stub's control place is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Place {
    /// Always the fieldbus (VACON with the control place parameterised to fieldbus).
    Fieldbus,
    /// The fieldbus while the card requests it (WEG LOC/REM, PROFIdrive b10 at WEG).
    FollowsRequest,
    /// Never the fieldbus.
    Local,
}

/// The drive stub.
#[derive(Debug, Clone)]
pub struct DriveStub {
    /// Actual speed, N2.
    pub speed: i16,
    /// Modulating.
    pub running: bool,
    /// Tripped.
    pub fault: bool,
    /// The fault cause persists (a reset does not clear it).
    pub fault_persists: bool,
    /// Trip when the card reports a fieldbus fault.
    pub trip_on_fieldbus_fault: bool,
    /// Control place.
    pub place: Place,
    /// Speed change per cycle on the normal ramp.
    pub ramp: i16,
    /// Speed change per cycle on the quick-stop ramp.
    pub quick: i16,
    /// The jog speed, N2.
    pub jog: i16,
    target: i16,
    fieldbus: bool,
    resets_seen: u8,
    flux: bool,
    ramp2: bool,
    /// Fault resets the stub executed.
    pub resets: u32,
}

impl Default for DriveStub {
    fn default() -> Self {
        DriveStub {
            speed: 0,
            running: false,
            fault: false,
            fault_persists: false,
            trip_on_fieldbus_fault: true,
            place: Place::Fieldbus,
            ramp: 0x0800,
            quick: 0x1000,
            jog: 0x0800,
            target: 0,
            fieldbus: false,
            resets_seen: 0,
            flux: false,
            ramp2: false,
            resets: 0,
        }
    }
}

fn toward(v: i16, target: i16, step: i16) -> i16 {
    let step = step.max(1) as i32;
    let (v32, t32) = (v as i32, target as i32);
    if (t32 - v32).abs() <= step {
        target
    } else if t32 > v32 {
        (v32 + step) as i16
    } else {
        (v32 - step) as i16
    }
}

impl DriveStub {
    /// Trips the drive (e.g. an overcurrent).
    pub fn trip(&mut self) {
        self.fault = true;
        self.running = false;
        self.speed = 0;
    }

    /// The drive's status.
    pub fn status(&self) -> DriveStatus {
        let mut f = StatusFlags::empty();
        f.set(StatusFlags::READY, !self.fault);
        f.set(StatusFlags::RUNNING, self.running);
        f.set(StatusFlags::REVERSE, self.speed < 0);
        f.set(StatusFlags::FAULT, self.fault);
        f.set(StatusFlags::AT_REFERENCE, self.running && self.speed == self.target);
        f.set(StatusFlags::ZERO_SPEED, self.speed == 0);
        f.set(StatusFlags::FLUX_READY, self.flux);
        f.set(StatusFlags::RAMP_SET_2, self.ramp2);
        let fb = match self.place {
            Place::Fieldbus => true,
            Place::FollowsRequest => self.fieldbus,
            Place::Local => false,
        };
        f.set(StatusFlags::FIELDBUS_CONTROL, fb);
        DriveStatus {
            flags: f,
            speed: self.speed,
            fault_code: if self.fault { 0x10 } else { 0 },
            ..DriveStatus::default()
        }
    }

    /// One drive cycle with the card's command.
    pub fn step(&mut self, cmd: &DriveCommand) {
        let f = cmd.flags;
        self.fieldbus = f.contains(CommandFlags::FIELDBUS_CONTROL);
        self.ramp2 = f.contains(CommandFlags::RAMP_SET_2);
        if cmd.fault_resets != self.resets_seen {
            self.resets_seen = cmd.fault_resets;
            self.resets += 1;
            if !self.fault_persists {
                self.fault = false;
            }
        }
        if f.contains(CommandFlags::FIELDBUS_FAULT) && self.trip_on_fieldbus_fault {
            self.trip();
        }
        if self.fault || f.contains(CommandFlags::COAST) {
            self.running = false;
            self.flux = false;
            self.speed = 0;
            self.target = 0;
            return;
        }
        let dir = |v: i16| if f.contains(CommandFlags::REVERSE) { v.saturating_neg() } else { v };
        if f.contains(CommandFlags::QUICK_STOP) {
            self.target = 0;
            self.speed = toward(self.speed, 0, self.quick);
        } else if f.contains(CommandFlags::RUN) {
            self.running = true;
            self.flux = true;
            self.target = if f.contains(CommandFlags::SETPOINT_ZERO) || f.contains(CommandFlags::RAMP_RESET) {
                0
            } else {
                dir(cmd.speed_setpoint)
            };
            let step = if f.contains(CommandFlags::RAMP_RESET) { self.quick } else { self.ramp };
            if !f.contains(CommandFlags::RAMP_HOLD) {
                self.speed = toward(self.speed, self.target, step);
            }
            return;
        } else if f.contains(CommandFlags::JOG1) {
            self.running = true;
            self.target = dir(self.jog);
            self.speed = toward(self.speed, self.target, self.ramp);
            return;
        } else if f.contains(CommandFlags::PRE_EXCITE) {
            self.running = true;
            self.flux = true;
            self.target = 0;
            self.speed = toward(self.speed, 0, self.ramp);
            return;
        } else {
            self.target = 0;
            self.speed = toward(self.speed, 0, self.ramp);
        }
        if self.speed == 0 {
            self.running = false;
            self.flux = false;
        }
    }
}
