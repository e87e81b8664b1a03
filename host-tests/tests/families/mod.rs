//! A PLC program for any GSD module (shared by `qemu.rs` and `softslave.rs`): runs the card's
//! simulated drive through the control profile of the module's family — PROFIdrive 4.1 (ST1,
//! ST20, VACON 100/101/138/139), PROFIdrive 2.0 (PPO), the WEG manufacturer profile (CFW500 /
//! CFW-11 telegrams with the drive's factory P0741 = 1) and the INVT control word — and checks
//! the live values both ways:
//!
//! * a fault (the re-parameterisation of a running card leaves data exchange: A139 with the
//!   drive's factory action "fault") is acknowledged with the profile's reset edge;
//! * the main actual value ramps through intermediate values to the setpoint and back to 0;
//! * the programmable input words echo the programmable output words (the simulated drive
//!   echoes them) with a tag that changes with the phase;
//! * ST20: IAIST_GLATT (output current) is live while the motor turns.

use pbcard::card;
use pbcard::dpm::{Family, Telegram};
use pbcard::profile::telegram::{Layout, Word};

/// The control profile a module runs with the drive's factory settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// PROFIdrive STW1 / ZSW1 (4.1 and 2.0).
    Profidrive,
    /// WEG P0684 / P0680.
    Weg,
    /// INVT command / status codes.
    Invt,
}

/// What the PLC asks of the drive.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    /// Run at the setpoint until the actual value is there and the echo came back.
    Run,
    /// Stop until standstill.
    Stop,
}

/// One module's PLC program (module docs).
#[derive(Debug, Clone)]
pub struct FamilyDrive {
    /// The module.
    pub module: &'static card::Module,
    /// Its profile.
    pub kind: Kind,
    layout: Layout,
    setpoint: u16,
    toggle: bool,
    tag: u16,
    /// Main actual values seen while running up.
    pub actuals: Vec<u16>,
    /// Fault acknowledges sent.
    pub resets: u32,
    /// Cycles seen.
    pub cycles: u32,
    /// Largest IAIST_GLATT seen (ST20).
    pub max_current: u16,
}

fn word(b: &[u8], i: usize) -> u16 {
    u16::from_be_bytes([b[2 * i], b[2 * i + 1]])
}

impl FamilyDrive {
    /// The module with GSD reference `reference`, at `percent` % of the reference speed.
    pub fn new(reference: u16, percent: u32) -> Self {
        let module = card::MODULES.iter().find(|m| m.reference == reference).expect("module in the GSD");
        let t = Telegram::of_module(module).expect("a known telegram");
        let layout = Layout::of(t).expect("a layout");
        let (kind, full) = match t {
            Telegram::Ppo(_) => (Kind::Profidrive, 10_000),
            Telegram::Vendor(Family::Invt, _) => (Kind::Invt, 5000),
            Telegram::Vendor(Family::WegCfw500 | Family::WegCfw11, _) => (Kind::Weg, 8192),
            _ => (Kind::Profidrive, 0x4000),
        };
        FamilyDrive {
            module,
            kind,
            layout,
            setpoint: (full * percent / 100) as u16,
            toggle: false,
            tag: reference,
            actuals: Vec::new(),
            resets: 0,
            cycles: 0,
            max_current: 0,
        }
    }

    fn faulted(&self, sw: u16) -> bool {
        match self.kind {
            Kind::Profidrive => sw & 0x0008 != 0,
            Kind::Weg => sw & 0x8000 != 0,
            Kind::Invt => sw & 0x00FF == 4,
        }
    }

    /// The control word for status word `sw` in `phase` (a fault is acknowledged first).
    fn control_word(&mut self, sw: u16, phase: Phase) -> u16 {
        self.toggle = !self.toggle;
        if self.faulted(sw) {
            if self.toggle {
                self.resets += 1;
            }
            return match (self.kind, self.toggle) {
                (Kind::Profidrive, true) => 0x04FE,
                (Kind::Profidrive, false) => 0x047E,
                (Kind::Weg, true) => 0x0096,
                (Kind::Weg, false) => 0x0016,
                (Kind::Invt, true) => 0x0007,
                (Kind::Invt, false) => 0x0005,
            };
        }
        match (self.kind, phase) {
            // S1 → S2 with 0x047E first, then 0x047F.
            (Kind::Profidrive, Phase::Run) if sw & 0x0001 == 0 => 0x047E,
            (Kind::Profidrive, Phase::Run) => 0x047F,
            (Kind::Profidrive, Phase::Stop) => 0x047E,
            // P0684: b0 run, b1 general enable, b2 forward, b4 remote.
            (Kind::Weg, Phase::Run) => 0x0017,
            (Kind::Weg, Phase::Stop) => 0x0016,
            (Kind::Invt, Phase::Run) => 0x0001,
            (Kind::Invt, Phase::Stop) => 0x0005,
        }
    }

    /// A new phase: a new tag for the programmable words.
    pub fn start(&mut self, phase: Phase) {
        self.tag = self.tag.wrapping_mul(31).wrapping_add(if phase == Phase::Run { 0x1357 } else { 0x2468 });
    }

    /// The output image after the input image `inputs` (the last one received) in `phase`,
    /// and whether the phase is done (`Err` on a failed check).
    pub fn next(&mut self, inputs: &[u8], phase: Phase) -> Result<(Vec<u8>, bool), String> {
        let l = self.layout;
        if inputs.len() != l.input_bytes() {
            return Err(format!(
                "{}: {} input bytes, the module has {}",
                self.module.name,
                inputs.len(),
                l.input_bytes()
            ));
        }
        self.cycles += 1;
        let p = l.pkw;
        let (sw, actual) = (word(inputs, p), word(inputs, p + 1));
        let cw = self.control_word(sw, phase);
        let mut w = vec![0u16; p + l.pzd_out];
        w[p] = cw;
        w[p + 1] = self.setpoint;
        for (k, x) in w.iter_mut().enumerate().skip(p + 2) {
            *x = self.tag ^ (0x0101 * k as u16);
        }
        let mut echo = true;
        for i in p + 2..p + l.pzd_in {
            match l.input_word(i) {
                Some(Word::Programmable(_)) => echo &= word(inputs, i) == w.get(i).copied().unwrap_or(0),
                Some(Word::OutputCurrent) => self.max_current = self.max_current.max(word(inputs, i)),
                _ => {}
            }
        }
        if inputs[..2 * p].iter().any(|&b| b != 0) {
            return Err(format!("{}: PKW not zero without a request", self.module.name));
        }
        let faulted = self.faulted(sw);
        let done = match phase {
            Phase::Run => {
                if !faulted && self.actuals.last() != Some(&actual) {
                    self.actuals.push(actual);
                }
                !faulted && actual.abs_diff(self.setpoint) <= 3 && echo
            }
            Phase::Stop => !faulted && actual == 0 && echo,
        };
        Ok((w.iter().flat_map(|x| x.to_be_bytes()).collect(), done))
    }

    /// After a run phase: the actual value ramped (monotonic, intermediate values).
    pub fn check_ramp(&self) -> Result<usize, String> {
        let a = &self.actuals;
        let between = a.iter().filter(|&&x| x > 0 && x.abs_diff(self.setpoint) > 3).count();
        if a.windows(2).any(|w| w[1] < w[0]) {
            return Err(format!("{}: the actual value fell while running up: {a:?}", self.module.name));
        }
        if between < 3 {
            return Err(format!("{}: the actual value jumped instead of ramping: {a:?}", self.module.name));
        }
        if self.layout.is_st20() && self.max_current == 0 {
            return Err(format!("{}: IAIST_GLATT never moved while the motor turned", self.module.name));
        }
        Ok(between)
    }
}
