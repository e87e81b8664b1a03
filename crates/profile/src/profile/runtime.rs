//! The card's profile layer at run time (issue 6): the active telegram's cyclic engine
//! ([`super::cyclic`]), the control profile it needs ([`AnyProfile`]), the PKW server of the
//! PPO / INVT telegrams ([`super::pkw`]) and the fault buffer ([`super::faults`]) — between
//! the DP slave's images and the DPM's drive-neutral blocks (DRIVE_CMD / DRIVE_STATE).
//!
//! ```text
//! DpSlave outputs ─▶ Runtime::cycle ─▶ DriveCommandImage (DPM DRIVE_CMD) ─▶ drive
//! DpSlave inputs  ◀─ Runtime::cycle ◀─ DriveStateImage   (DPM DRIVE_STATE) ◀─ drive
//! ```
//!
//! Sans-IO and platform-neutral: `pbcard::app::Card` calls it every housekeeping
//! step; the PKW jobs are served from the DP-V1 task ([`Runtime::service_pkw`]).
//!
//! The operate mode comes from the master (Set_Prm user parameter
//! `pbcard::card::PRM_OPERATE_MODE`, 1..=3 "remote") or, with 0 "local", from the drive's
//! configuration (DPM CONFIG.OPERATE_MODE, OPTE3/E5 §5.1.4); PROFIdrive when neither says.
//!
//! **I/O update delay (CFW-11 P0799 "Atraso Atualização I/O", 0.0…999.0, default 0.0):**
//! after the transition offline → online (the first cycle of data exchange, and every cycle
//! that follows one with the communication lost: the master back after a watchdog expiry or
//! out of Clear), the data the master writes are not taken for [`Runtime::io_update_delay`]:
//! the drive keeps the command it had before going online (after a loss: the
//! communication-loss command; at power-up: none), no PKW request is taken and the output
//! words do not move. The manual delays only the *write* words (the data the drive receives,
//! CFW-11 §3 P0799, Figure 3.1): the master's inputs (status word, actual values) stay live
//! during the delay. The newest output image received meanwhile is applied when the delay
//! ends. The DPM CONFIG block has no field for it: it is a card parameter
//! ([`Runtime::set_io_update_delay`]), default 0 (no delay, as P0799's factory setting), and
//! needs the time ([`Runtime::cycle_at`]; [`Runtime::cycle`] runs without it).
//!
//! **INVT heartbeat (INVT §2.6 Table 2-5 CW b15 "heartbeat reference: 1 enabling heartbeat",
//! Table 2-7 SW b15 "heartbeat feedback"):** the status word echoes b15 (the feedback). The
//! manual does not say how the drive supervises it; our reading: a PLC that *toggles* b15
//! uses the heartbeat, and once the card has seen it change twice (a whole period; a PLC that
//! holds b15 at 1 or 0 never arms it) a b15 standing still for [`INVT_HEARTBEAT_TIMEOUT`]
//! is a communication loss — the drive gets the communication-loss command
//! ([`CommandFlags`](super::drive_if::CommandFlags)`::COMM_LOSS`, its reaction as for a DP
//! watchdog expiry), counted in [`RuntimeStats::heartbeat_losses`], until b15 changes again.
//! The supervision starts afresh with every selection; it needs the time ([`Runtime::cycle_at`]).

use super::cyclic::{Cycle, Cyclic, CyclicError, DriveSide, OperateMode};
use super::drive_if::{ControlProfile, DriveCommand, DriveStatus};
use super::faults::FaultBuffer;
use super::invt::Invt;
use super::param::ParameterAccess;
use super::pkw::{PkwDialect, PkwServer};
use super::pnu::ProcessView;
use super::profidrive::{Profidrive, SpeedScale};
use super::telegram::{DataProfile, Layout, ProfileFamily};
use super::weg::{weg_profidrive, WegManufacturer, WegModel};
use crate::profile::selection::{Family, Telegram};
use crate::time::{Duration, Instant};

/// INVT CW b8 "enable writing" (INVT §2.6 Table 2-5): PKW writes run only with it set.
pub const INVT_ENABLE_WRITING: u16 = 1 << 8;

/// INVT CW b15 "heartbeat reference" / SW b15 "heartbeat feedback" (INVT Table 2-5, 2-7):
/// how long the PLC's heartbeat may stand still once it has toggled (our choice; the manual
/// names no time). See [`Runtime`] "INVT heartbeat".
pub const INVT_HEARTBEAT_TIMEOUT: Duration = Duration::from_millis(1000);

/// The INVT heartbeat supervision's state ([`Runtime`] "INVT heartbeat").
#[derive(Debug, Clone, Copy, Default)]
struct Heartbeat {
    /// CW b15 of the last output image.
    bit: Option<bool>,
    /// Changes of b15 seen (saturating): supervision is armed from the second one on.
    edges: u8,
    /// When b15 changed last.
    last_edge: Option<Instant>,
    /// The heartbeat stands still longer than [`INVT_HEARTBEAT_TIMEOUT`].
    expired: bool,
}

/// The physical references of the speed scales (one unit for all: 0.01 Hz by default).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Scales {
    /// The drive's reference of the neutral N2 scale (0x4000 = this speed; PNU 10111-style).
    pub n2_reference: u32,
    /// Minimum / maximum frequency of the bypass / PPO scale 0..10000 (OPTE3/E5 §6.3.5).
    pub bypass_min: u32,
    /// See [`Self::bypass_min`].
    pub bypass_max: u32,
    /// WEG: 8192 of P0681 / P0685 (P0403 rated frequency).
    pub weg_rated: u32,
    /// WEG: 16384 of the PROFIdrive profile (P0134 maximum speed).
    pub weg_p0134: u32,
    /// INVT: the maximum frequency Fmax of the set-frequency word (0.01 Hz).
    pub invt_fmax: u32,
}

impl Scales {
    /// Everything 50.00 Hz (5000 × 0.01 Hz): N2 0x4000 = bypass 10000 = WEG 8192 = WEG
    /// PROFIdrive 16384 = INVT 5000.
    pub const DEFAULT: Scales = Scales {
        n2_reference: 5000,
        bypass_min: 0,
        bypass_max: 5000,
        weg_rated: 5000,
        weg_p0134: 5000,
        invt_fmax: 5000,
    };
}

impl Default for Scales {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// One of the control profiles, chosen by the telegram (and, for WEG, the drive's P0741).
#[derive(Debug, Clone)]
pub enum AnyProfile {
    /// PROFIdrive 4.1 / 2.0 / WEG PROFIdrive.
    Profidrive(Profidrive),
    /// WEG manufacturer profile.
    Weg(WegManufacturer),
    /// INVT control word.
    Invt(Invt),
}

impl AnyProfile {
    /// The profile `layout` needs with the drive's data profile `data`.
    pub fn for_layout(layout: &Layout, data: DataProfile, s: &Scales) -> AnyProfile {
        let weg_model = match layout.telegram {
            Telegram::Vendor(Family::WegCfw11, _) => WegModel::Cfw11,
            _ => WegModel::Cfw500,
        };
        match layout.profile(data) {
            ProfileFamily::Profidrive41 if layout.is_st20() => AnyProfile::Profidrive(Profidrive::st20()),
            ProfileFamily::Profidrive41 => AnyProfile::Profidrive(Profidrive::st1()),
            ProfileFamily::Profidrive20 => {
                AnyProfile::Profidrive(Profidrive::ppo(SpeedScale::bypass(s.bypass_min, s.bypass_max, s.n2_reference)))
            }
            ProfileFamily::WegManufacturer => {
                AnyProfile::Weg(WegManufacturer::new(weg_model, WegModel::scale_13bit(s.weg_rated, s.n2_reference)))
            }
            ProfileFamily::WegProfidrive => AnyProfile::Profidrive(weg_profidrive(
                weg_model,
                WegModel::scale_profidrive(s.weg_p0134, s.n2_reference),
            )),
            ProfileFamily::Invt => AnyProfile::Invt(Invt::new(Invt::scale(s.invt_fmax, s.n2_reference))),
        }
    }
}

impl AnyProfile {
    /// Take the speed scale of `fresh` (the same profile built with new [`Scales`]), keeping
    /// this profile's state.
    fn take_scale(&mut self, fresh: &AnyProfile) {
        match (self, fresh) {
            (AnyProfile::Profidrive(p), AnyProfile::Profidrive(f)) => p.set_scale(f.config().scale),
            (AnyProfile::Weg(p), AnyProfile::Weg(f)) => p.set_scale(*f.scale()),
            (AnyProfile::Invt(p), AnyProfile::Invt(f)) => p.set_scale(*f.speed_scale()),
            _ => {}
        }
    }
}

impl ControlProfile for AnyProfile {
    fn command(&mut self, cw: u16, setpoint: u16, drive: &DriveStatus) -> DriveCommand {
        match self {
            AnyProfile::Profidrive(p) => p.command(cw, setpoint, drive),
            AnyProfile::Weg(p) => p.command(cw, setpoint, drive),
            AnyProfile::Invt(p) => p.command(cw, setpoint, drive),
        }
    }
    fn comm_lost(&mut self, drive: &DriveStatus) -> DriveCommand {
        match self {
            AnyProfile::Profidrive(p) => p.comm_lost(drive),
            AnyProfile::Weg(p) => p.comm_lost(drive),
            AnyProfile::Invt(p) => p.comm_lost(drive),
        }
    }
    fn clear(&mut self, drive: &DriveStatus) -> DriveCommand {
        match self {
            AnyProfile::Profidrive(p) => p.clear(drive),
            AnyProfile::Weg(p) => p.clear(drive),
            AnyProfile::Invt(p) => p.clear(drive),
        }
    }
    fn status_word(&self, drive: &DriveStatus) -> u16 {
        match self {
            AnyProfile::Profidrive(p) => p.status_word(drive),
            AnyProfile::Weg(p) => p.status_word(drive),
            AnyProfile::Invt(p) => p.status_word(drive),
        }
    }
    fn actual_value(&self, drive: &DriveStatus) -> u16 {
        match self {
            AnyProfile::Profidrive(p) => p.actual_value(drive),
            AnyProfile::Weg(p) => p.actual_value(drive),
            AnyProfile::Invt(p) => p.actual_value(drive),
        }
    }
}

/// What selects the engine: telegram, operate mode, data profile, communication-loss
/// reaction. A change rebuilds the engine and the profile (back to S1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Selection {
    /// The active telegram (from Chk_Cfg).
    pub telegram: Telegram,
    /// The operate mode in force.
    pub mode: OperateMode,
    /// The drive's data profile for the WEG telegrams (P0741).
    pub data: DataProfile,
    /// Set_Prm communication-loss reaction (copied into every command).
    pub comm_loss_reaction: u8,
}

impl Selection {
    /// The mode from the Set_Prm user parameter `remote` (1..=3) or, with 0 "local", the
    /// drive's configured mode `local` (1..=3; else PROFIdrive).
    pub fn mode_of(remote: u8, local: u8) -> OperateMode {
        OperateMode::from_code(remote).or(OperateMode::from_code(local)).unwrap_or(OperateMode::Profidrive)
    }
}

/// The result of a cycle for the platform.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Exchange<'a> {
    /// The input image for the DP slave.
    pub inputs: &'a [u8],
    /// The command for the drive (`None` in Echo, and in Bypass while communicating).
    pub command: Option<DriveCommand>,
    /// The raw words for the drive.
    pub words: &'a [u16],
}

/// Counters.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct RuntimeStats {
    /// Engines built (telegram / mode changes).
    pub selections: u32,
    /// Selections refused ([`CyclicError`]): the card serves the ZSW1 fault image.
    pub refused: u32,
    /// Offline → online transitions that started the I/O update delay (P0799).
    pub delays_started: u32,
    /// Output images held back by the I/O update delay (P0799).
    pub held_outputs: u32,
    /// Lost cycles bridged by the communication-loss delay.
    pub bridged: u32,
    /// INVT heartbeat losses (the PLC's CW b15 stood still, [`INVT_HEARTBEAT_TIMEOUT`]).
    pub heartbeat_losses: u32,
}

/// The I/O update delay's bookkeeping (CFW-11 P0799, module docs).
#[derive(Debug, Clone, Copy)]
struct UpdateDelay {
    /// The card parameter (0 = off).
    delay: Duration,
    /// The previous cycle had the communication (`false` after a selection and while lost).
    online: bool,
    /// The master's outputs are held until this time.
    until: Option<Instant>,
}

/// The card's profile layer (module docs).
#[derive(Debug, Clone)]
pub struct Runtime {
    scales: Scales,
    selection: Option<Selection>,
    engine: Option<Cyclic>,
    profile: Option<AnyProfile>,
    error: Option<CyclicError>,
    pkw: PkwServer,
    faults: FaultBuffer,
    drive_fault: u16,
    last: Option<Cycle>,
    /// The drive's status of the last cycle (PNU 10104 … 10108).
    last_status: DriveStatus,
    delay: UpdateDelay,
    /// The master is in Clear ([`Self::set_clear_mode`]).
    clear: bool,
    /// The communication-loss delay ([`Self::set_comm_loss_delay`]).
    loss_delay: Duration,
    /// Since when the communication is lost (for the delay).
    lost_since: Option<Instant>,
    /// Fault acknowledges of the profiles before this one: a new profile counts from 0, the
    /// drive must see the counter continue (a restart would acknowledge its fault).
    resets_base: u8,
    /// INVT heartbeat supervision.
    heartbeat: Heartbeat,
    stats: RuntimeStats,
}

impl Default for Runtime {
    fn default() -> Self {
        Self::new(Scales::DEFAULT)
    }
}

impl Runtime {
    /// No telegram yet.
    pub fn new(scales: Scales) -> Self {
        Runtime {
            scales,
            selection: None,
            engine: None,
            profile: None,
            error: None,
            pkw: PkwServer::new(PkwDialect::Profidrive2),
            faults: FaultBuffer::new(),
            drive_fault: 0,
            last: None,
            last_status: DriveStatus::default(),
            delay: UpdateDelay { delay: Duration::ZERO, online: false, until: None },
            clear: false,
            loss_delay: Duration::ZERO,
            lost_since: None,
            resets_base: 0,
            heartbeat: Heartbeat::default(),
            stats: RuntimeStats::default(),
        }
    }

    /// The speed references of the profile scales (`profile::references`: read from the
    /// drive after each selection; [`Scales::DEFAULT`] until then). A change applies to the
    /// profile in force at once and keeps its state (no restart of the state machine).
    pub fn set_scales(&mut self, scales: Scales) {
        if scales == self.scales {
            return;
        }
        self.scales = scales;
        if let (Some(p), Some(e), Some(sel)) = (self.profile.as_mut(), self.engine.as_ref(), self.selection) {
            p.take_scale(&AnyProfile::for_layout(e.layout(), sel.data, &scales));
        }
    }

    /// The speed references in force.
    pub fn scales(&self) -> Scales {
        self.scales
    }

    /// The I/O update delay after going online (CFW-11 P0799-style, module docs): the drive's
    /// DPM `CONFIG.IO_UPDATE_DELAY` (0.1 s units), set by `app::Card` on every cycle;
    /// default 0 = the master's outputs are taken at once. Takes effect at the next
    /// offline → online transition.
    pub fn set_io_update_delay(&mut self, delay: Duration) {
        self.delay.delay = delay;
    }
    /// See [`Self::set_io_update_delay`].
    pub fn io_update_delay(&self) -> Duration {
        self.delay.delay
    }
    /// The drive's communication-loss delay (DPM `CONFIG.COMM_LOSS_DELAY_MS`, set by
    /// `app::Card` on every cycle; 0 = none): a loss (watchdog, master gone, Clear)
    /// shorter than this is bridged — the drive keeps the profile's command of the last output
    /// image, without [`CommandFlags`](super::drive_if::CommandFlags)`::COMM_LOSS`, and the
    /// I/O update delay does not restart; once it lasts longer, the loss command follows.
    /// Needs the time ([`Self::cycle_at`]); counted in [`RuntimeStats::bridged`].
    pub fn set_comm_loss_delay(&mut self, delay: Duration) {
        self.loss_delay = delay;
    }

    /// Whether the master is in Clear (its outputs are zero, reference §3.6): a lost cycle
    /// then runs the profile's [`ControlProfile::clear`] (VACON PROFIdrive: b10 = 0 in
    /// operation → FAULT, OPTE3/E5 §6.3.3) instead of [`ControlProfile::comm_lost`].
    /// `app::Card` sets it from the DP slave's Clear state on every cycle.
    pub fn set_clear_mode(&mut self, clear: bool) {
        self.clear = clear;
    }

    /// Whether the I/O update delay holds the master's outputs back at `now`.
    pub fn io_update_held(&self, now: Instant) -> bool {
        self.delay.until.is_some_and(|t| now < t)
    }

    /// Select telegram / mode / data profile / reaction; a change rebuilds the engine. A
    /// selection the engine refuses (ST20 with a local Bypass / Echo) leaves no engine
    /// ([`Self::error`]).
    pub fn select(&mut self, sel: Selection) {
        if self.selection == Some(sel) {
            return;
        }
        self.selection = Some(sel);
        self.stats.selections = self.stats.selections.wrapping_add(1);
        if let Some(c) = self.last.take().and_then(|c| c.command) {
            self.resets_base = c.fault_resets;
        }
        self.delay.online = false;
        self.delay.until = None;
        self.heartbeat = Heartbeat::default();
        // The PPO types are VACON's (OPTE3/E5 §6.5.4, §6.6): their PKW speaks VACON's coding
        // (application IDs, request types 1 / 2, fault codes of Table 122); INVT its own.
        let dialect = match sel.telegram {
            Telegram::Vendor(Family::Invt, _) => PkwDialect::Invt,
            Telegram::Ppo(_) => PkwDialect::Vacon,
            _ => PkwDialect::Profidrive2,
        };
        self.pkw = PkwServer::new(dialect);
        match (Cyclic::new(sel.telegram, sel.mode, sel.comm_loss_reaction), Layout::of(sel.telegram)) {
            (Ok(e), Some(l)) => {
                self.profile = Some(AnyProfile::for_layout(&l, sel.data, &self.scales));
                self.engine = Some(e);
                self.error = None;
            }
            (r, _) => {
                self.engine = None;
                self.profile = None;
                self.error = r.err().filter(|_| sel.telegram != Telegram::None);
                if self.error.is_some() {
                    self.stats.refused = self.stats.refused.wrapping_add(1);
                }
            }
        }
    }

    /// The selection in force.
    pub fn selection(&self) -> Option<Selection> {
        self.selection
    }
    /// Why the selection has no engine.
    pub fn error(&self) -> Option<CyclicError> {
        self.error
    }
    /// The control profile in force.
    pub fn profile(&self) -> Option<&AnyProfile> {
        self.profile.as_ref()
    }
    /// The cyclic engine in force.
    pub fn engine(&self) -> Option<&Cyclic> {
        self.engine.as_ref()
    }
    /// The fault buffer (PNU 944 / 947).
    pub fn faults(&self) -> &FaultBuffer {
        &self.faults
    }
    /// The PKW server.
    pub fn pkw(&self) -> &PkwServer {
        &self.pkw
    }
    /// Counters.
    pub fn stats(&self) -> RuntimeStats {
        self.stats
    }

    /// One cycle: `outputs` = a new output image from Data_Exchange (else the last one is
    /// evaluated again), `lost` = the communication is lost (watchdog, Clear, master gone),
    /// `drive` = the drive's latest status and raw words. `None` without an engine. Without
    /// the time, no I/O update delay applies ([`Self::cycle_at`]).
    pub fn cycle(
        &mut self,
        outputs: Option<&[u8]>,
        lost: bool,
        drive: &DriveStatus,
        words: &[u16],
    ) -> Option<Exchange<'_>> {
        self.run(None, outputs, lost, drive, words)
    }

    /// [`Self::cycle`] at `now`, with the I/O update delay after going online (P0799-style,
    /// module docs): while it runs, the master's outputs are kept back (the newest one is
    /// applied when it ends), the drive keeps the command it had before going online, the
    /// master's inputs stay live.
    pub fn cycle_at(
        &mut self,
        now: Instant,
        outputs: Option<&[u8]>,
        lost: bool,
        drive: &DriveStatus,
        words: &[u16],
    ) -> Option<Exchange<'_>> {
        self.run(Some(now), outputs, lost, drive, words)
    }

    fn run(
        &mut self,
        now: Option<Instant>,
        outputs: Option<&[u8]>,
        lost: bool,
        drive: &DriveStatus,
        words: &[u16],
    ) -> Option<Exchange<'_>> {
        self.track_faults(drive);
        let lost = self.heartbeat_lost(now, outputs) || lost;
        let grace = match (lost, now) {
            (true, Some(n)) if self.loss_delay > Duration::ZERO => {
                let since = *self.lost_since.get_or_insert(n);
                n < since + self.loss_delay
            }
            _ => false,
        };
        if !lost {
            self.lost_since = None;
        }
        if grace {
            self.stats.bridged = self.stats.bridged.wrapping_add(1);
        }
        let lost = lost && !grace;
        let (engine, profile) = (self.engine.as_mut()?, self.profile.as_mut()?);
        let side = DriveSide { status: drive, words, pkw_response: self.pkw.response() };
        let d = &mut self.delay;
        if lost {
            d.online = false;
            d.until = None;
        } else if !d.online {
            d.online = true;
            if let Some(now) = now.filter(|_| d.delay > Duration::ZERO) {
                d.until = Some(now + d.delay);
                self.stats.delays_started = self.stats.delays_started.wrapping_add(1);
            }
        }
        let (held, resumed) = match (d.until, now) {
            (Some(t), Some(now)) if now < t => (true, false),
            (Some(_), _) => {
                d.until = None;
                (false, true)
            }
            _ => (false, false),
        };
        let continued = held && self.last.is_some();
        let mut cycle = if held {
            if outputs.is_some() {
                self.stats.held_outputs = self.stats.held_outputs.wrapping_add(1);
            }
            // The drive keeps the command it had before going online; the inputs are live.
            engine.hold(profile, outputs, side, self.last.as_ref())
        } else if lost && self.clear {
            engine.clear(profile, side)
        } else if lost {
            engine.comm_lost(profile, side)
        } else if let Some(out) = outputs {
            match engine.exchange(profile, out, side) {
                Some(c) => c,
                None => engine.step(profile, side),
            }
        } else if resumed {
            // The delay is over: the newest image held back is taken now.
            engine.resume(profile, side)
        } else {
            engine.step(profile, side)
        };
        if let Some(req) = cycle.pkw_request {
            // INVT CW b8 "enable writing (mainly through PKW1 to PKW4)", INVT Table 2-5.
            let enabled = self.pkw.dialect() != PkwDialect::Invt || cycle.control_word & INVT_ENABLE_WRITING != 0;
            self.pkw.on_request_enabled(req, enabled);
        }
        if let Some(c) = cycle.command.as_mut().filter(|_| !continued) {
            c.fault_resets = c.fault_resets.wrapping_add(self.resets_base);
        }
        self.last_status = *drive;
        let c = self.last.insert(cycle);
        Some(Exchange { inputs: c.inputs(), command: c.command, words: c.drive_words() })
    }

    /// What the card's PNUs show of the profile layer ([`ProcessView`]): the selection's data
    /// profile and PNU 10100 … 10108 of the last cycle — the output image's control word and
    /// main setpoint, the input image's status word and main actual value (after the PKW),
    /// the drive's current, active current, power, the actual value again (no filter) and
    /// MELD_NAMUR.
    pub fn process_view(&self) -> ProcessView {
        let data = self.selection.map_or(DataProfile::Factory, |s| s.data);
        let Some(c) = self.last.as_ref() else {
            return ProcessView { data, ..ProcessView::EMPTY };
        };
        let pkw = self.engine.as_ref().map_or(0, |e| e.layout().pkw);
        let input = |k: usize| {
            let i = c.inputs();
            i.get(2 * (pkw + k)..2 * (pkw + k) + 2).map_or(0, |b| u16::from_be_bytes([b[0], b[1]]))
        };
        let s = &self.last_status;
        ProcessView {
            data,
            words: [
                c.control_word,
                c.setpoint_word,
                input(0),
                input(1),
                s.current as u16,
                s.torque as u16,
                s.power as u16,
                input(1),
                s.namur,
            ],
        }
    }

    /// The INVT heartbeat supervision ([`Runtime`] "INVT heartbeat"): whether the PLC's CW b15
    /// stood still too long. Needs the time; only for the INVT frame.
    fn heartbeat_lost(&mut self, now: Option<Instant>, outputs: Option<&[u8]>) -> bool {
        let Some(now) = now.filter(|_| self.pkw.dialect() == PkwDialect::Invt) else { return false };
        let h = &mut self.heartbeat;
        if let Some(&[hi, lo]) = outputs.and_then(|o| o.get(8..10)) {
            let bit = u16::from_be_bytes([hi, lo]) & super::invt::HEARTBEAT != 0;
            if h.bit.is_some_and(|b| b != bit) {
                h.edges = h.edges.saturating_add(1);
                h.last_edge = Some(now);
            }
            h.bit = Some(bit);
        }
        let expired = h.edges >= 2 && h.last_edge.is_some_and(|t| now >= t + INVT_HEARTBEAT_TIMEOUT);
        if expired && !h.expired {
            self.stats.heartbeat_losses = self.stats.heartbeat_losses.wrapping_add(1);
        }
        h.expired = expired;
        expired
    }

    /// Whether a PKW job waits for [`Self::service_pkw`].
    pub fn has_pkw_work(&self) -> bool {
        self.pkw.is_busy()
    }

    /// Serve the PKW job against `table` (from the DP-V1 task, not the interrupt).
    pub fn service_pkw(&mut self, table: &mut impl ParameterAccess) {
        if self.pkw.is_busy() {
            self.pkw.service(table);
        }
    }

    /// Feed the fault buffer: a new drive fault code opens / extends the active situation,
    /// the fault going away (acknowledged in the drive) closes it.
    fn track_faults(&mut self, drive: &DriveStatus) {
        let code = drive.fault_code;
        if code == self.drive_fault {
            return;
        }
        if code == 0 {
            self.faults.acknowledge();
        } else {
            self.faults.report(code);
        }
        self.drive_fault = code;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::profile::drive_if::{CommandFlags, StatusFlags};

    fn ready() -> DriveStatus {
        DriveStatus {
            flags: StatusFlags::READY | StatusFlags::FIELDBUS_CONTROL | StatusFlags::ZERO_SPEED,
            ..DriveStatus::default()
        }
    }

    fn sel(telegram: Telegram, mode: OperateMode) -> Selection {
        Selection { telegram, mode, data: DataProfile::Factory, comm_loss_reaction: 2 }
    }

    #[test]
    fn st1_runs_through_the_profidrive_profile() {
        let mut r = Runtime::default();
        r.select(sel(Telegram::Standard(1), OperateMode::Profidrive));
        let d = ready();
        let e = r.cycle(Some(&[0x04, 0x7E, 0x20, 0x00]), false, &d, &[]).unwrap();
        assert_eq!(e.inputs.len(), 4);
        let cmd = e.command.unwrap();
        assert!(!cmd.flags.contains(CommandFlags::RUN));
        assert_eq!(cmd.comm_loss_reaction, 2);
        let e = r.cycle(Some(&[0x04, 0x7F, 0x20, 0x00]), false, &d, &[]).unwrap();
        let cmd = e.command.unwrap();
        assert!(cmd.flags.contains(CommandFlags::RUN));
        assert_eq!(cmd.speed_setpoint, 0x2000);
        assert_eq!(u16::from_be_bytes([e.inputs[0], e.inputs[1]]) & 0x0007, 0x0007, "S4");
    }

    #[test]
    fn echo_and_bypass() {
        let mut r = Runtime::default();
        r.select(sel(Telegram::Ppo(4), OperateMode::Echo));
        let out: Vec<u8> = (1..=12).collect();
        let e = r.cycle(Some(&out), false, &ready(), &[]).unwrap();
        assert_eq!(e.inputs, &out[..]);
        assert_eq!(e.command, None);
        r.select(sel(Telegram::Ppo(4), OperateMode::Bypass));
        let e = r.cycle(Some(&out), false, &ready(), &[0xAAAA, 0xBBBB]).unwrap();
        assert_eq!(&e.inputs[..4], &[0xAA, 0xAA, 0xBB, 0xBB]);
        assert_eq!(e.words.len(), 6);
        assert_eq!(e.words[0], 0x0102);
    }

    #[test]
    fn st20_with_local_echo_is_refused() {
        let mut r = Runtime::default();
        r.select(sel(Telegram::Standard(20), OperateMode::Echo));
        assert_eq!(r.error(), Some(CyclicError::ModeNotAllowed));
        assert!(r.cycle(Some(&[0; 4]), false, &ready(), &[]).is_none());
        assert_eq!(r.stats().refused, 1);
        assert_eq!(Selection::mode_of(0, 3), OperateMode::Echo);
        assert_eq!(Selection::mode_of(2, 3), OperateMode::Bypass);
        assert_eq!(Selection::mode_of(0, 0), OperateMode::Profidrive);
    }

    #[test]
    fn the_fault_buffer_follows_the_drive() {
        let mut r = Runtime::default();
        r.select(sel(Telegram::Standard(1), OperateMode::Profidrive));
        let mut d = ready();
        d.fault_code = 0x2310;
        r.cycle(None, false, &d, &[]);
        r.cycle(None, false, &d, &[]);
        assert_eq!(r.faults().active()[..2], [0x2310, 0]);
        d.fault_code = 0;
        r.cycle(None, false, &d, &[]);
        assert_eq!(r.faults().situation(1).unwrap()[..2], [0x2310, 0]);
        assert_eq!(r.faults().counter(), 2);
    }

    fn at(ms: u64) -> Instant {
        Instant::from_millis(ms)
    }

    /// CFW-11 P0799: after going online the master's outputs wait for the delay; the drive
    /// keeps the pre-online command (at power-up: none), the master's inputs are live, the
    /// newest image held back is applied when the delay ends.
    #[test]
    fn io_update_delay_holds_the_outputs_after_going_online() {
        let mut r = Runtime::default();
        assert_eq!(r.io_update_delay(), Duration::ZERO, "default 0 like P0799's factory setting");
        r.set_io_update_delay(Duration::from_millis(500));
        r.select(sel(Telegram::Standard(1), OperateMode::Profidrive));
        let mut d = ready();
        d.speed = 0x1000;
        let e = r.cycle_at(at(0), Some(&[0x04, 0x7E, 0x20, 0x00]), false, &d, &[]).unwrap();
        assert_eq!(e.command, Some(DriveCommand::default()), "power-up: no command before online");
        assert_eq!(&e.inputs[2..4], &[0x10, 0x00], "the actual value is live during the delay");
        assert!(r.io_update_held(at(499)));
        let e = r.cycle_at(at(499), Some(&[0x04, 0x7F, 0x30, 0x00]), false, &d, &[]).unwrap();
        assert!(!e.command.unwrap().flags.contains(CommandFlags::RUN), "still held at 499 ms");
        assert_eq!(r.stats().held_outputs, 2);
        // The delay is over: the newest held image is taken without a new Data_Exchange.
        let e = r.cycle_at(at(500), None, false, &d, &[]).unwrap();
        let cmd = e.command.unwrap();
        assert!(!r.io_update_held(at(500)));
        assert_eq!(cmd.speed_setpoint, 0x3000, "the newest held setpoint");
        assert!(cmd.flags.contains(CommandFlags::FIELDBUS_CONTROL));
        // Run the state machine to S4.
        for t in [510, 520, 530] {
            r.cycle_at(at(t), Some(&[0x04, 0x7E, 0x30, 0x00]), false, &d, &[]);
        }
        let e = r.cycle_at(at(540), Some(&[0x04, 0x7F, 0x30, 0x00]), false, &d, &[]).unwrap();
        assert!(e.command.unwrap().flags.contains(CommandFlags::RUN));
        // Communication lost, then back: the comm-loss command stays for the delay.
        let lost = r.cycle_at(at(600), None, true, &d, &[]).unwrap().command.unwrap();
        assert!(lost.flags.contains(CommandFlags::COMM_LOSS));
        let e = r.cycle_at(at(700), Some(&[0x04, 0x7F, 0x10, 0x00]), false, &d, &[]).unwrap();
        assert_eq!(e.command, Some(lost), "the pre-online (communication-loss) command is kept");
        let e = r.cycle_at(at(1199), Some(&[0x04, 0x7F, 0x10, 0x00]), false, &d, &[]).unwrap();
        assert_eq!(e.command, Some(lost));
        let e = r.cycle_at(at(1200), Some(&[0x04, 0x7F, 0x10, 0x00]), false, &d, &[]).unwrap();
        let cmd = e.command.unwrap();
        assert!(!cmd.flags.contains(CommandFlags::COMM_LOSS));
        assert_eq!(cmd.speed_setpoint, 0x1000);
        assert_eq!(r.stats().delays_started, 2);
    }

    #[test]
    fn without_a_delay_the_outputs_are_taken_at_once() {
        let mut r = Runtime::default();
        r.select(sel(Telegram::Standard(1), OperateMode::Profidrive));
        let e = r.cycle_at(at(0), Some(&[0x04, 0x7E, 0x20, 0x00]), false, &ready(), &[]).unwrap();
        assert!(e.command.unwrap().flags.contains(CommandFlags::FIELDBUS_CONTROL));
        assert_eq!(e.command.unwrap().speed_setpoint, 0x2000);
        assert_eq!(r.stats().delays_started, 0);
        // `cycle` without the time never delays.
        r.set_io_update_delay(Duration::from_millis(100));
        r.cycle(None, true, &ready(), &[]);
        let e = r.cycle(Some(&[0x04, 0x7E, 0x10, 0x00]), false, &ready(), &[]).unwrap();
        assert_eq!(e.command.unwrap().speed_setpoint, 0x1000);
    }

    /// The PKW channel is part of the write words: no request is taken during the delay.
    #[test]
    fn io_update_delay_holds_the_pkw_request_and_the_raw_words() {
        let mut r = Runtime::default();
        r.set_io_update_delay(Duration::from_millis(100));
        r.select(sel(Telegram::Ppo(2), OperateMode::Profidrive));
        let mut out = [0u8; 20];
        out[..2].copy_from_slice(&[0x10, 100]);
        out[8..10].copy_from_slice(&[0x04, 0x7E]);
        out[12..14].copy_from_slice(&[0x12, 0x34]);
        let e = r.cycle_at(at(0), Some(&out), false, &ready(), &[]).unwrap();
        assert!(e.words.iter().all(|&w| w == 0), "the drive keeps the pre-online words");
        assert!(!r.has_pkw_work());
        let e = r.cycle_at(at(100), None, false, &ready(), &[]).unwrap();
        assert_eq!(e.words[0], 0x1234);
        assert!(r.has_pkw_work(), "the held PKW request is taken when the delay ends");
    }

    /// A new telegram (a new profile counting its acknowledges from 0) does not acknowledge
    /// the drive's fault: the counter the drive sees continues.
    #[test]
    fn a_new_selection_continues_the_fault_acknowledge_counter() {
        let mut r = Runtime::default();
        r.select(sel(Telegram::Standard(1), OperateMode::Profidrive));
        let d = ready();
        r.cycle(Some(&[0x04, 0x7E, 0, 0]), false, &d, &[]);
        let e = r.cycle(Some(&[0x04, 0xFE, 0, 0]), false, &d, &[]).unwrap();
        assert_eq!(e.command.unwrap().fault_resets, 1);
        r.select(sel(Telegram::Vendor(Family::Invt, 1), OperateMode::Profidrive));
        let e = r.cycle(Some(&[0; 32]), false, &d, &[]).unwrap();
        assert_eq!(e.command.unwrap().fault_resets, 1, "no acknowledge by the change");
        let mut q = [0u8; 32];
        q[9] = 7; // INVT command 7: fault reset
        let e = r.cycle(Some(&q), false, &d, &[]).unwrap();
        assert_eq!(e.command.unwrap().fault_resets, 2);
    }
}
