//! The DP-V0 slave (IEC 61158-6-3 / EN 50170 vol. 2; reference §3).
//!
//! [`DpSlave`] implements [`FdlApplication`] for the FDL [`Station`](crate::fdl::station::Station):
//! it runs the state machine Wait_Prm → Wait_Cfg → Data_Exch, evaluates Set_Prm and
//! Chk_Cfg, keeps the diagnosis, the cyclic images, the master lock and the DP watchdog.
//!
//! One room per service: [`prm`] (Set_Prm), [`cfg`](mod@cfg) (Chk_Cfg / Get_Cfg), [`diag`]
//! (Slave_Diag), [`global_control`] (Global_Control), [`slave_add`] (Set_Slave_Add). The
//! state machine and the staging of responses live here.
//!
//! **The product** is a [`SlaveConfig`] value (ident number, modules, User_Prm_Data, supported
//! features, `Max_Diag_Data_Len` — the GSD's values) with its Chk_Cfg rule ([`CfgPolicy`]),
//! passed to [`DpSlave::new`]; `dp` names no product. The buffers are sized for the
//! protocol's maxima ([`MAX_INPUT_LEN`], [`MAX_OUTPUT_LEN`], [`diag::MAX_DIAG_DATA_LEN`],
//! [`prm::MAX_USER_PRM_LEN`]); a product asserts [`SlaveConfig::fits`].
//!
//! **Pre-staged responses.** The Data_Exchange answer (inputs) and the diagnosis answer are
//! complete frames kept in double buffers and rebuilt only when their content changes
//! ([`DpSlave::set_inputs`], a state change). Answering a request only patches the header
//! bytes (destination, FC DL/DH, DSAP) and the checksum incrementally; the frame sent last
//! is never rewritten, so an FCB retry gets it byte for byte.
//!
//! **Services, states and who may use them** (reference §3.1, §3.2, §3.8; `RS` = SD1
//! "no service activated"):
//!
//! | service (DSAP) | allowed | otherwise |
//! |---|---|---|
//! | Data_Exchange (none) | Data_Exch, locking master, output length = configured or 0 | RS (wrong length: RS, outputs zero, → Wait_Prm with Cfg_Fault, counted) |
//! | Set_Slave_Add (55) | Wait_Prm, address not frozen, right ident | RS |
//! | Rd_Inp (56) / Rd_Outp (57) | Data_Exch, any master | RS |
//! | Global_Control (58, SDN) | Data_Exch, locking master, group selected | ignored, counted |
//! | Get_Cfg (59) / Slave_Diag (60) | always, any master; Get_Cfg answers [`DpSlave::real_cfg`] | — |
//! | Set_Prm (61) | unlocked slave or locking master; checked only with Lock_Req = 1, Unlock_Req = 0 ([`prm::LockRequest`]) | SC, content ignored, counted |
//! | Chk_Cfg (62) | Wait_Cfg / Data_Exch, locking master | SC, content ignored, counted |
//!
//! The drive side (DPM `CONFIG`, outside data exchange) can change the station address
//! ([`DpSlave::set_address`], the rules of Set_Slave_Add: frozen by No_Add_Chg) and restrict
//! Chk_Cfg to the module of the telegram it selected ([`DpSlave::require_module`]).
//! | any other SAP | — | RS |

pub mod alarm;
pub mod cfg;
pub mod config;
pub mod diag;
pub mod global_control;
pub mod prm;
pub mod slave_add;

use crate::fdl::station::{FdlApplication, Reply};
use crate::fdl::telegram::{self, DataTelegram, FunctionCode, Header, RequestFunction, ResponseStatus, MAX_FRAME_LEN};
use crate::time::{BitTimes, Duration, Instant};
pub use cfg::{AcceptAll, CfgPolicy, Module};
pub use config::{SlaveConfig, MAX_INPUT_LEN, MAX_OUTPUT_LEN};
use diag::{DiagError, StandardDiag, Status1, Status2};
use global_control::{ControlCommand, GlobalControl};
use prm::{SetPrm, StationStatus};
use slave_add::SetSlaveAdd;

/// DP service access points of a slave (reference §3.1).
pub mod sap {
    /// Set_Slave_Add.
    pub const SET_SLAVE_ADD: u8 = 55;
    /// Rd_Inp.
    pub const RD_INP: u8 = 56;
    /// Rd_Outp.
    pub const RD_OUTP: u8 = 57;
    /// Global_Control.
    pub const GLOBAL_CONTROL: u8 = 58;
    /// Get_Cfg.
    pub const GET_CFG: u8 = 59;
    /// Slave_Diag.
    pub const SLAVE_DIAG: u8 = 60;
    /// Set_Prm.
    pub const SET_PRM: u8 = 61;
    /// Chk_Cfg.
    pub const CHK_CFG: u8 = 62;
}

/// The DP slave states (reference §3.2; SPC3 status codes 00/01/10).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum DpState {
    /// Waiting for a valid Set_Prm (after power on, faults, watchdog expiry, unlock).
    WaitPrm,
    /// Parameterized; waiting for Chk_Cfg.
    WaitCfg,
    /// Cyclic data exchange.
    DataExch,
}

bitflags::bitflags! {
    /// What happened since the last [`DpSlave::take_events`].
    #[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
    pub struct Events: u16 {
        /// The DP state changed.
        const STATE_CHANGED = 1 << 0;
        /// New outputs were applied ([`DpSlave::outputs`]).
        const OUTPUTS_UPDATED = 1 << 1;
        /// Clear mode was entered or left ([`DpSlave::is_clear`]).
        const CLEAR_CHANGED = 1 << 2;
        /// The DP watchdog expired: data exchange was left and the outputs cleared.
        const WATCHDOG_EXPIRED = 1 << 3;
        /// A Set_Prm was accepted (the user parameters may have changed).
        const PRM_ACCEPTED = 1 << 4;
        /// A Set_Prm was refused (Prm_Fault).
        const PRM_FAULT = 1 << 5;
        /// A Chk_Cfg was accepted.
        const CFG_ACCEPTED = 1 << 6;
        /// A Chk_Cfg was refused (Cfg_Fault).
        const CFG_FAULT = 1 << 7;
        /// Set_Slave_Add changed the address: persist it ([`slave_add::AddressStore`]).
        const ADDRESS_CHANGED = 1 << 8;
        /// A Sync command applied the outputs.
        const SYNC = 1 << 9;
        /// A Freeze command sampled the inputs.
        const FREEZE = 1 << 10;
        /// Data exchange was left (any reason).
        const LEFT_DATA_EXCHANGE = 1 << 11;
        /// The locking master read the diagnosis.
        const DIAG_READ = 1 << 12;
    }
}

/// Counters of the DP layer (every refused or ignored request is counted).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct SlaveStats {
    /// Data_Exchange requests answered with data.
    pub data_exchanges: u32,
    /// Slave_Diag requests answered.
    pub diag_reads: u32,
    /// Set_Prm refused (Prm_Fault).
    pub prm_faults: u32,
    /// Chk_Cfg refused (Cfg_Fault).
    pub cfg_faults: u32,
    /// DP watchdog expiries.
    pub watchdog_expiries: u32,
    /// Data_Exchange with a wrong output length.
    pub wrong_output_len: u32,
    /// Requests from a master that does not hold the lock.
    pub not_locking_master: u32,
    /// Requests refused with RS (state, SAP closed, malformed).
    pub rs_answers: u32,
    /// Global_Control ignored (state, master, length, reserved bits, not requested).
    pub gc_ignored: u32,
    /// Chk_Cfg received in Wait_Prm (acknowledged, not evaluated).
    pub cfg_ignored: u32,
    /// Set_Prm with Lock_Req = 0, Unlock_Req = 0: only min_TSDR taken over.
    pub prm_min_tsdr_only: u32,
    /// Set_Prm with Unlock_Req: the slave released.
    pub prm_unlocks: u32,
}

/// Frame buffer ids (see [`FdlApplication::frame`]).
const DX0: u8 = 0;
const DIAG0: u8 = 2;
const MISC: u8 = 4;
const N_BUF: usize = 5;
const MAX_IMAGE: usize = if MAX_INPUT_LEN > MAX_OUTPUT_LEN { MAX_INPUT_LEN } else { MAX_OUTPUT_LEN };

/// Real_Cfg of a configuration without modules (never a product's, [`SlaveConfig::fits`]).
const NO_MODULE: Module = Module { name: "", reference: 0, cfg: &[], inputs: 0, outputs: 0 };

/// The DP slave.
#[derive(Debug, Clone)]
pub struct DpSlave {
    config: &'static SlaveConfig,
    address: u8,
    no_add_chg: bool,
    state: DpState,
    master: Option<u8>,
    prm: Option<SetPrm>,
    min_tsdr: BitTimes,
    module: Option<&'static Module>,
    /// The only module Chk_Cfg may select (the drive's telegram selection), if any.
    required_module: Option<&'static Module>,
    /// The application is ready for parameterisation (issue 16 start-up gate).
    app_ready: bool,
    // Faults and diagnosis flags.
    prm_fault: bool,
    cfg_fault: bool,
    not_supported: bool,
    ext_diag_flag: bool,
    stat_diag: bool,
    ext_diag: heapless::Vec<u8, { diag::MAX_EXT_DIAG_LEN }>,
    /// New diagnosis for the locking master (→ DH in Data_Exchange).
    diag_new: bool,
    /// Diagnostic alarms (DP-V1, [`alarm`]).
    alarms: alarm::Alarms,
    /// The staged diagnosis carries an alarm (delivered when the locking master reads it).
    staged_alarm: bool,
    diag_dirty: bool,
    // Cyclic images.
    app_inputs: [u8; MAX_INPUT_LEN],
    outputs: [u8; MAX_OUTPUT_LEN],
    pending_outputs: [u8; MAX_OUTPUT_LEN],
    has_pending_outputs: bool,
    sync_mode: bool,
    freeze_mode: bool,
    gc_clear: bool,
    fs_clear: bool,
    // DP watchdog.
    wd_time: Option<Duration>,
    wd_deadline: Option<Instant>,
    // Staged frames.
    bufs: [[u8; MAX_FRAME_LEN]; N_BUF],
    lens: [u16; N_BUF],
    /// The buffer that holds the current staged Data_Exchange / diagnosis frame.
    dx_cur: u8,
    diag_cur: u8,
    /// The buffer of the last frame handed to the station (kept intact for retries).
    last_sent: Option<u8>,
    events: Events,
    stats: SlaveStats,
}

impl DpSlave {
    /// A slave of the product `config` at `address` (0..=126), in Wait_Prm, with an unfrozen
    /// address.
    pub fn new(config: &'static SlaveConfig, address: u8) -> Self {
        Self::with_address_lock(config, address, false)
    }

    /// A slave of the product `config` whose address and No_Add_Chg flag come from an
    /// address store.
    ///
    /// Out of line: builds a large value in place (inlined into the start, every store needs its own stack address; footprint, issue 13 item 1).
    #[inline(never)]
    pub fn with_address_lock(config: &'static SlaveConfig, address: u8, no_add_chg: bool) -> Self {
        let mut s = DpSlave {
            config,
            address: address.min(telegram::MAX_STATION_ADDRESS),
            no_add_chg,
            state: DpState::WaitPrm,
            master: None,
            prm: None,
            min_tsdr: BitTimes::MIN_TSDR_DEFAULT,
            module: None,
            required_module: None,
            app_ready: true,
            prm_fault: false,
            cfg_fault: false,
            not_supported: false,
            ext_diag_flag: false,
            stat_diag: false,
            ext_diag: heapless::Vec::new(),
            diag_new: false,
            alarms: alarm::Alarms::new(),
            staged_alarm: false,
            diag_dirty: true,
            app_inputs: [0; MAX_INPUT_LEN],
            outputs: [0; MAX_OUTPUT_LEN],
            pending_outputs: [0; MAX_OUTPUT_LEN],
            has_pending_outputs: false,
            sync_mode: false,
            freeze_mode: false,
            gc_clear: false,
            fs_clear: false,
            wd_time: None,
            wd_deadline: None,
            bufs: [[0; MAX_FRAME_LEN]; N_BUF],
            lens: [0; N_BUF],
            dx_cur: DX0,
            diag_cur: DIAG0,
            last_sent: None,
            events: Events::empty(),
            stats: SlaveStats::default(),
        };
        s.restage_diag();
        s.restage_dx();
        s
    }

    /// The product's configuration the slave checks against.
    pub fn config(&self) -> &'static SlaveConfig {
        self.config
    }
    /// Own station address.
    pub fn address(&self) -> u8 {
        self.address
    }
    /// Whether Set_Slave_Add may no longer change the address.
    pub fn no_add_chg(&self) -> bool {
        self.no_add_chg
    }
    /// DP state.
    pub fn state(&self) -> DpState {
        self.state
    }
    /// The locking master, if any.
    pub fn master_address(&self) -> Option<u8> {
        self.master
    }
    /// min_TSDR from the last Set_Prm (11 bit times by default).
    pub fn min_tsdr(&self) -> BitTimes {
        self.min_tsdr
    }
    /// The module accepted by the last Chk_Cfg.
    pub fn module(&self) -> Option<&'static Module> {
        self.module
    }
    /// The module the drive selected ([`Self::require_module`]), if any.
    pub fn required_module(&self) -> Option<&'static Module> {
        self.required_module
    }

    /// The drive's station address (DPM `CONFIG.STATION_ADDRESS`, 0..=125): refused in data
    /// exchange ([`SlaveAddError::State`](slave_add::SlaveAddError::State)) and, like
    /// Set_Slave_Add (reference §3.9), while No_Add_Chg froze the address
    /// ([`SlaveAddError::Frozen`](slave_add::SlaveAddError::Frozen); the same address is no
    /// change and always accepted). A new address is reported as
    /// [`Events::ADDRESS_CHANGED`], so the platform stores it through its
    /// [`AddressStore`](slave_add::AddressStore) as after a Set_Slave_Add (No_Add_Chg kept as
    /// it is). In Wait_Cfg the parameterization was for the old address: the slave returns to
    /// Wait_Prm (lock released). Returns whether the address changed.
    pub fn set_address(&mut self, address: u8) -> Result<bool, slave_add::SlaveAddError> {
        if address > slave_add::MAX_NEW_ADDRESS {
            return Err(slave_add::SlaveAddError::Address(address));
        }
        if self.state == DpState::DataExch {
            return Err(slave_add::SlaveAddError::State);
        }
        if address == self.address {
            return Ok(false);
        }
        if self.no_add_chg {
            return Err(slave_add::SlaveAddError::Frozen);
        }
        if self.state != DpState::WaitPrm {
            self.leave(DpState::WaitPrm);
        }
        self.address = address;
        self.events |= Events::ADDRESS_CHANGED;
        self.diag_dirty = true;
        self.restage_dx();
        Ok(true)
    }

    /// Restrict Chk_Cfg to `module` (the drive selected its telegram, DPM `CONFIG.TELEGRAM`),
    /// or lift the restriction (`None`, telegram "any"). Any other module, however valid, is
    /// answered with Cfg_Fault ([`cfg::CfgError::NotTheSelectedModule`]) from the next
    /// Chk_Cfg on; the running configuration is not touched.
    pub fn require_module(&mut self, module: Option<&'static Module>) {
        self.required_module = module;
    }
    /// Real_Cfg_Data, what Get_Cfg answers: the configuration in force (reference §3.4,
    /// "Get_Cfg returns Real_Cfg_Data — the active configuration"). In data exchange the
    /// module of the accepted Chk_Cfg; outside it the drive's selected telegram
    /// ([`Self::require_module`]) when there is one — the only module the next Chk_Cfg may
    /// select —, else the module of the last accepted Chk_Cfg, else the GSD's first module
    /// ([`SlaveConfig::modules`]; this card: Standard telegram 1).
    pub fn real_cfg(&self) -> &'static Module {
        match (self.state, self.module, self.required_module) {
            (DpState::DataExch, Some(m), _) => m,
            (_, _, Some(r)) => r,
            (_, Some(m), None) => m,
            (_, None, None) => self.config.modules.first().unwrap_or(&NO_MODULE),
        }
    }

    /// The accepted Set_Prm (user parameters, DPV1 status bytes, watchdog).
    pub fn parameters(&self) -> Option<&SetPrm> {
        self.prm.as_ref()
    }
    /// The DP watchdog time in force, `None` when off.
    pub fn watchdog_time(&self) -> Option<Duration> {
        self.wd_time
    }
    /// Clear mode: Global_Control Clear_Data, or fail-safe zero-length outputs (reference §3.7).
    pub fn is_clear(&self) -> bool {
        self.gc_clear || self.fs_clear
    }
    /// Sync mode active.
    pub fn is_sync(&self) -> bool {
        self.sync_mode
    }
    /// Freeze mode active.
    pub fn is_freeze(&self) -> bool {
        self.freeze_mode
    }
    /// Counters.
    pub fn stats(&self) -> SlaveStats {
        self.stats
    }
    /// Input bytes of the configured module (0 before Chk_Cfg).
    pub fn input_len(&self) -> usize {
        self.module.map_or(0, |m| m.inputs as usize)
    }
    /// Output bytes of the configured module (0 before Chk_Cfg).
    pub fn output_len(&self) -> usize {
        self.module.map_or(0, |m| m.outputs as usize)
    }
    /// The applied output image (master → slave); all zero outside data exchange and after
    /// Clear_Data.
    pub fn outputs(&self) -> &[u8] {
        &self.outputs[..self.output_len()]
    }
    /// The input image the master receives now (frozen inputs in Freeze mode).
    pub fn inputs(&self) -> &[u8] {
        let n = self.input_len();
        if n == 0 {
            return &[];
        }
        let len = self.lens[self.dx_cur as usize] as usize;
        &self.bufs[self.dx_cur as usize][telegram::pdu_range(len, n)]
    }

    /// The staged Data_Exchange answer as it stands (header DA / FC as last patched; the
    /// response path patches them): what `pbcard::fast::CoreLink` publishes for the line.
    pub fn staged_dx_frame(&self) -> &[u8] {
        let id = self.dx_cur as usize;
        &self.bufs[id][..self.lens[id] as usize]
    }

    /// The staged Slave_Diag answer, rebuilt first when the diagnosis changed since it was
    /// staged (the same frame the next Slave_Diag would send): what
    /// `pbcard::fast::CoreLink` publishes for the line.
    pub fn staged_diag_frame(&mut self) -> &[u8] {
        if self.diag_dirty {
            self.restage_diag();
        }
        let id = self.diag_cur as usize;
        &self.bufs[id][..self.lens[id] as usize]
    }

    /// New diagnosis waits for the locking master (Data_Exchange answers DH).
    pub fn has_new_diag(&self) -> bool {
        self.diag_new
    }

    /// Events since the last call.
    pub fn take_events(&mut self) -> Events {
        core::mem::take(&mut self.events)
    }

    /// The application's input image (slave → master). Shorter data is padded with zeros,
    /// longer data cut to the configured length. In Freeze mode the master keeps receiving
    /// the frozen inputs until the next Freeze / Unfreeze.
    pub fn set_inputs(&mut self, data: &[u8]) {
        let n = data.len().min(MAX_INPUT_LEN);
        self.app_inputs[..n].copy_from_slice(&data[..n]);
        self.app_inputs[n..].fill(0);
        if !self.freeze_mode {
            self.restage_dx();
        }
    }

    /// Set the extended diagnosis blocks (after the 6 standard octets) and the Ext_Diag
    /// flag ("a diagnosis entry exists"). A change is announced to the master by answering
    /// Data_Exchange with DH. Malformed blocks are refused and change nothing.
    pub fn set_ext_diag(&mut self, blocks: &[u8], ext_diag: bool) -> Result<(), DiagError> {
        diag::validate_ext_diag(blocks, self.config.max_ext_diag_len())?;
        if self.ext_diag.as_slice() != blocks || self.ext_diag_flag != ext_diag {
            self.ext_diag.clear();
            // Cannot fail: validate_ext_diag bounded the length.
            let _ = self.ext_diag.extend_from_slice(blocks);
            self.ext_diag_flag = ext_diag;
            self.diag_changed();
        }
        Ok(())
    }

    /// Stat_Diag: ask the master to keep reading diagnosis (e.g. while the drive is not
    /// ready after configuration).
    pub fn set_stat_diag(&mut self, on: bool) {
        if self.stat_diag != on {
            self.stat_diag = on;
            self.diag_changed();
        }
    }

    /// The drive's fault code (0 = none, DPM `DRIVE.FAULT_CODE`): a change in data exchange
    /// makes a diagnostic alarm when the master enabled them ([`alarm`]).
    pub fn set_drive_fault(&mut self, code: u16) {
        if self.alarms.set_fault(code, self.state == DpState::DataExch) {
            self.diag_changed();
        }
    }

    /// The diagnostic alarms (outstanding, counters).
    pub fn alarms(&self) -> &alarm::Alarms {
        &self.alarms
    }

    /// Alarm_Ack from the locking master over MSAC_C1 (`5C slot type specifier`): the
    /// outstanding alarm it names is gone; refused with the reason for the DP-V1 error PDU.
    pub fn alarm_ack(&mut self, ack: &alarm::Ack) -> Result<(), alarm::AckError> {
        if self.state != DpState::DataExch {
            return Err(alarm::AckError::State);
        }
        if self.alarms.acknowledge(ack)? {
            self.diag_changed();
        }
        Ok(())
    }

    /// The start-up gate (issue 16): while the application is not ready (the card's drive
    /// has not written a valid configuration yet), a Set_Prm is acknowledged (SC) but not
    /// taken: the slave stays in Wait_Prm and its diagnosis shows Station_Not_Ready
    /// (octet 1 bit 1) with Prm_Req (octet 2 bit 0), no Prm_Fault — the master keeps
    /// parameterising until the card is ready. Default ready.
    pub fn set_ready(&mut self, ready: bool) {
        self.app_ready = ready;
    }

    /// Whether the start-up gate is open ([`Self::set_ready`]).
    pub fn is_ready(&self) -> bool {
        self.app_ready
    }

    /// The standard diagnosis octets as they are now.
    pub fn standard_diag(&self) -> StandardDiag {
        let mut s1 = Status1::empty();
        s1.set(Status1::STATION_NOT_READY, self.state != DpState::DataExch);
        s1.set(Status1::CFG_FAULT, self.cfg_fault);
        s1.set(Status1::EXT_DIAG, self.ext_diag_flag);
        s1.set(Status1::NOT_SUPPORTED, self.not_supported);
        s1.set(Status1::PRM_FAULT, self.prm_fault);
        let mut s2 = Status2::ALWAYS_ONE;
        s2.set(Status2::PRM_REQ, self.state == DpState::WaitPrm);
        s2.set(Status2::STAT_DIAG, self.stat_diag);
        s2.set(Status2::WD_ON, self.wd_time.is_some() && self.state != DpState::WaitPrm);
        s2.set(Status2::FREEZE_MODE, self.freeze_mode);
        s2.set(Status2::SYNC_MODE, self.sync_mode);
        StandardDiag {
            status1: s1,
            status2: s2,
            status3: 0,
            master_add: self.master.unwrap_or(0xFF),
            ident_number: self.config.ident_number,
        }
    }

    /// Run the timers: the DP watchdog (reference §1.6, §3.10).
    pub fn poll(&mut self, now: Instant) {
        if let Some(deadline) = self.wd_deadline {
            if now >= deadline && self.state != DpState::WaitPrm {
                self.stats.watchdog_expiries = self.stats.watchdog_expiries.wrapping_add(1);
                self.events |= Events::WATCHDOG_EXPIRED;
                self.leave(DpState::WaitPrm);
            }
        }
        if self.diag_dirty {
            self.restage_diag();
        }
    }

    // ----- state changes -----

    fn set_state(&mut self, s: DpState) {
        if self.state != s {
            if self.state == DpState::DataExch {
                self.events |= Events::LEFT_DATA_EXCHANGE;
                // Alarms end with data exchange (reference §4.4).
                self.alarms.stop();
            }
            if s == DpState::DataExch {
                self.alarms.start();
            }
            self.state = s;
            self.events |= Events::STATE_CHANGED;
            self.diag_dirty = true;
        }
    }

    /// Leave data exchange / parameterization: outputs cleared (fail-safe), modes reset;
    /// to Wait_Prm also releases the lock and stops the watchdog.
    fn leave(&mut self, to: DpState) {
        let had_outputs = self.outputs[..self.output_len()].iter().any(|&b| b != 0);
        self.outputs.fill(0);
        self.has_pending_outputs = false;
        if had_outputs {
            self.events |= Events::OUTPUTS_UPDATED;
        }
        if self.sync_mode || self.freeze_mode {
            self.sync_mode = false;
            self.freeze_mode = false;
            self.restage_dx();
        }
        if self.is_clear() {
            self.gc_clear = false;
            self.fs_clear = false;
            self.events |= Events::CLEAR_CHANGED;
        }
        if to == DpState::WaitPrm {
            self.master = None;
            self.wd_deadline = None;
        }
        self.set_state(to);
        self.diag_dirty = true;
    }

    fn diag_changed(&mut self) {
        self.diag_dirty = true;
        if self.state == DpState::DataExch {
            self.diag_new = true;
        }
    }

    #[inline(never)]
    fn retrigger(&mut self, now: Instant, sa: u8) {
        if self.master == Some(sa) {
            if let Some(t) = self.wd_time {
                self.wd_deadline = Some(now + t);
            }
        }
    }

    // ----- staging -----

    /// A buffer of the pair starting at `base` that is not the one sent last.
    fn free_of(&self, cur: u8, base: u8) -> u8 {
        if self.last_sent == Some(cur) {
            base + (1 - (cur - base))
        } else {
            cur
        }
    }

    fn restage_dx(&mut self) {
        let n_in = self.input_len();
        let id = self.free_of(self.dx_cur, DX0);
        let hdr = Header {
            da: self.master.unwrap_or(0),
            sa: self.address,
            fc: FunctionCode::response(ResponseStatus::Dl),
            dsap: None,
            ssap: None,
        };
        let buf = &mut self.bufs[id as usize];
        let len = telegram::emit(buf, &hdr, &self.app_inputs[..n_in]).unwrap_or(0);
        self.lens[id as usize] = len as u16;
        self.dx_cur = id;
    }

    fn restage_diag(&mut self) {
        let id = self.free_of(self.diag_cur, DIAG0);
        let std = self.standard_diag().encode();
        let mut pdu = [0u8; diag::MAX_DIAG_DATA_LEN];
        let max = self.config.max_diag_data_len.clamp(6, diag::MAX_DIAG_DATA_LEN);
        pdu[..6].copy_from_slice(&std);
        let dpv1 = self.prm.is_some_and(|p| p.dpv1_status_1.contains(prm::Dpv1Status1::DPV1_ENABLE));
        let alarm = if dpv1 { self.alarms.to_deliver().copied() } else { None };
        self.staged_alarm = alarm.is_some();
        let n = 6 + alarm::device_block(&self.ext_diag, dpv1, alarm.as_ref(), &mut pdu[6..max]);
        let hdr = Header {
            da: 0,
            sa: self.address,
            fc: FunctionCode::response(ResponseStatus::Dl),
            dsap: Some(62),
            ssap: Some(sap::SLAVE_DIAG),
        };
        let len = telegram::emit(&mut self.bufs[id as usize], &hdr, &pdu[..n]).unwrap_or(0);
        self.lens[id as usize] = len as u16;
        self.diag_cur = id;
        self.diag_dirty = false;
    }

    /// Patch destination, FC and (if present) DSAP of a staged frame, keeping the FCS right.
    fn patch(&mut self, id: u8, da: u8, fc: u8, dsap: Option<u8>) -> Reply {
        let len = self.lens[id as usize] as usize;
        let buf = &mut self.bufs[id as usize];
        let at = if buf[0] == telegram::SD2 { 4 } else { 1 };
        let mut fcs = buf[len - 2];
        let da_byte = (buf[at] & 0x80) | da;
        let mut edits = [(at, da_byte), (at + 2, fc), (usize::MAX, 0)];
        if let Some(d) = dsap {
            edits[2] = (at + 3, d & 0x3F);
        }
        for (i, v) in edits {
            if i < len {
                fcs = fcs.wrapping_sub(buf[i]).wrapping_add(v);
                buf[i] = v;
            }
        }
        buf[len - 2] = fcs;
        self.last_sent = Some(id);
        Reply::Frame { id, len: len as u16 }
    }

    fn misc_frame(&mut self, req: &DataTelegram<'_>, pdu: &[u8]) -> Reply {
        let hdr = Header::response_to(req, ResponseStatus::Dl);
        match telegram::emit(&mut self.bufs[MISC as usize], &hdr, pdu) {
            Ok(len) => {
                self.lens[MISC as usize] = len as u16;
                self.last_sent = Some(MISC);
                Reply::Frame { id: MISC, len: len as u16 }
            }
            Err(_) => self.rs(),
        }
    }

    fn rs(&mut self) -> Reply {
        self.stats.rs_answers = self.stats.rs_answers.wrapping_add(1);
        Reply::Status(ResponseStatus::Rs)
    }

    // ----- services -----

    fn data_exchange(&mut self, req: &DataTelegram<'_>) -> Reply {
        if self.state != DpState::DataExch || self.master != Some(req.sa) {
            if self.master.is_some() && self.master != Some(req.sa) {
                self.stats.not_locking_master = self.stats.not_locking_master.wrapping_add(1);
            }
            return self.rs();
        }
        let n_out = self.output_len();
        if req.pdu.is_empty() {
            // Fail-safe Clear: zero-length outputs (reference §3.7).
            if !self.fs_clear {
                self.fs_clear = true;
                self.events |= Events::CLEAR_CHANGED;
            }
            // The image Sync held is discarded with the outputs: never applied after Clear.
            self.has_pending_outputs = false;
            if self.outputs.iter().any(|&b| b != 0) {
                self.outputs.fill(0);
                self.events |= Events::OUTPUTS_UPDATED;
            }
        } else if req.pdu.len() != n_out {
            // Wrong non-zero output length (issue 12 item 4l). Neither the SPC3 nor the VPC3+
            // manual found here states the ASIC's reaction: the VPC3+S user manual §6.2.5
            // "Write_Read_Data / Data_Exchange" only says the received outputs are passed on
            // "after an error-free receipt", and the reference (§3.11, [U]) says "reject (ignore
            // outputs)". Followed here, and made safe for a drive: the outputs are not taken,
            // the request is answered RS (masters react to RS in data exchange by checking the
            // slave again, reference §2.5), and since a master that sends another length than
            // it configured would retrigger the watchdog with stale outputs forever, the slave
            // leaves data exchange: outputs zero, Wait_Prm (Prm_Req), Cfg_Fault in the
            // diagnosis ("configuration does not match") until the next parameterization.
            self.stats.wrong_output_len = self.stats.wrong_output_len.wrapping_add(1);
            self.cfg_fault = true;
            self.leave(DpState::WaitPrm);
            return self.rs();
        } else {
            if self.fs_clear {
                self.fs_clear = false;
                self.events |= Events::CLEAR_CHANGED;
            }
            if self.gc_clear {
                // Clear mode (Global_Control Clear_Data): the outputs stay in the safe state
                // (all zero) whatever the master sends, until a Global_Control without
                // Clear_Data (reference §3.6, §3.7).
            } else if self.sync_mode {
                self.pending_outputs[..n_out].copy_from_slice(req.pdu);
                self.has_pending_outputs = true;
            } else {
                self.outputs[..n_out].copy_from_slice(req.pdu);
                self.events |= Events::OUTPUTS_UPDATED;
            }
        }
        self.stats.data_exchanges = self.stats.data_exchanges.wrapping_add(1);
        let status = if self.diag_new { ResponseStatus::Dh } else { ResponseStatus::Dl };
        if self.input_len() == 0 {
            return if self.diag_new { Reply::Status(status) } else { Reply::ShortAck };
        }
        self.patch(self.dx_cur, req.sa, status as u8, None)
    }

    fn slave_diag(&mut self, req: &DataTelegram<'_>) -> Reply {
        if self.diag_dirty {
            self.restage_diag();
        }
        self.stats.diag_reads = self.stats.diag_reads.wrapping_add(1);
        if self.master == Some(req.sa) && self.diag_new {
            self.diag_new = false;
            self.events |= Events::DIAG_READ;
        }
        let dsap = req.ssap.unwrap_or(62);
        let reply = self.patch(self.diag_cur, req.sa, ResponseStatus::Dl as u8, Some(dsap));
        if self.master == Some(req.sa) && self.staged_alarm {
            // The locking master has the alarm: it waits for its Alarm_Ack; the next waiting
            // alarm (or the status block) goes into the next diagnosis.
            let more = self.alarms.delivered();
            self.diag_dirty = true;
            if more {
                self.diag_new = true;
            }
        }
        reply
    }

    fn set_prm(&mut self, now: Instant, req: &DataTelegram<'_>) -> Reply {
        if let Some(m) = self.master {
            if m != req.sa {
                // Locked by another master: the content is not taken (reference §3.8); the
                // diagnosis' Master_Add tells the other master who owns the slave.
                self.stats.not_locking_master = self.stats.not_locking_master.wrapping_add(1);
                return Reply::ShortAck;
            }
        }
        if !self.app_ready {
            // The start-up gate (`set_ready`): acknowledged, not taken.
            return Reply::ShortAck;
        }
        match prm::LockRequest::of(req.pdu) {
            Some(prm::LockRequest::MinTsdrOnly(t)) => {
                // Lock 0 / Unlock 0: only min_TSDR is taken over; no validation, every other
                // parameter, the state and the outputs unchanged (EN 50170 lock table,
                // reference §3.3).
                if let Some(t) = t {
                    self.min_tsdr = t;
                }
                self.stats.prm_min_tsdr_only = self.stats.prm_min_tsdr_only.wrapping_add(1);
                return Reply::ShortAck;
            }
            Some(prm::LockRequest::Unlock) => {
                // Unlock_Req (Lock 0/1, Unlock 1): released for other masters, whatever the
                // rest of the telegram says (reference §3.3).
                self.stats.prm_unlocks = self.stats.prm_unlocks.wrapping_add(1);
                self.leave(DpState::WaitPrm);
                self.diag_dirty = true;
                return Reply::ShortAck;
            }
            Some(prm::LockRequest::Lock) | None => {}
        }
        match SetPrm::parse(req.pdu, self.config) {
            Err(e) => {
                self.stats.prm_faults = self.stats.prm_faults.wrapping_add(1);
                self.prm_fault = true;
                self.not_supported = e == prm::PrmError::NotSupported;
                self.events |= Events::PRM_FAULT;
                self.prm = None;
                self.wd_time = None;
                self.leave(DpState::WaitPrm);
            }
            Ok(p) => {
                if let Some(t) = p.min_tsdr {
                    self.min_tsdr = t;
                }
                // Lock 1 / Unlock 0 (the other rows of the lock table are handled above).
                {
                    self.prm_fault = false;
                    self.cfg_fault = false;
                    self.not_supported = false;
                    self.master = Some(req.sa);
                    self.wd_time = p.watchdog();
                    self.wd_deadline = self.wd_time.map(|t| now + t);
                    self.prm = Some(p);
                    self.alarms.configure(
                        p.dpv1_status_1.contains(prm::Dpv1Status1::DPV1_ENABLE)
                            && p.dpv1_status_2 & alarm::ENABLE_DIAGNOSTIC_ALARM != 0,
                        p.dpv1_status_3 & 0x07,
                    );
                    self.events |= Events::PRM_ACCEPTED;
                    if self.state == DpState::DataExch {
                        self.leave(DpState::WaitCfg);
                    } else {
                        self.set_state(DpState::WaitCfg);
                    }
                    self.restage_dx();
                }
            }
        }
        self.diag_dirty = true;
        Reply::ShortAck
    }

    fn chk_cfg(&mut self, req: &DataTelegram<'_>) -> Reply {
        // Like Set_Prm, Chk_Cfg is always acknowledged with SC (reference gotcha 6): a master
        // treats anything else as a lost slave. Outside Wait_Cfg / Data_Exch, or from a master
        // that does not hold the lock, the content is not evaluated (counted), and the
        // diagnosis (Prm_Req, Master_Add) tells the master what to do.
        if self.state == DpState::WaitPrm || self.master != Some(req.sa) {
            if self.master.is_some() && self.master != Some(req.sa) {
                self.stats.not_locking_master = self.stats.not_locking_master.wrapping_add(1);
            } else {
                self.stats.cfg_ignored = self.stats.cfg_ignored.wrapping_add(1);
            }
            return Reply::ShortAck;
        }
        // The bytes must be one module, the product's policy must allow it with the Set_Prm
        // in force, and it must be the drive's selection if there is one.
        let user_prm: &[u8] = self.prm.as_ref().map_or(&[], |p| p.user.as_slice());
        let checked = cfg::check(req.pdu, self.config.modules)
            .and_then(|m| self.config.cfg_policy.check_cfg(m, user_prm).map(|()| m))
            .and_then(|m| match self.required_module {
                Some(r) if r.reference != m.reference => Err(cfg::CfgError::NotTheSelectedModule),
                _ => Ok(m),
            });
        match checked {
            Ok(m) => {
                let changed = self.module != Some(m);
                self.cfg_fault = false;
                if changed {
                    self.leave(self.state);
                    self.module = Some(m);
                    self.restage_dx();
                }
                self.events |= Events::CFG_ACCEPTED;
                self.set_state(DpState::DataExch);
            }
            Err(_) => {
                self.stats.cfg_faults = self.stats.cfg_faults.wrapping_add(1);
                self.cfg_fault = true;
                self.events |= Events::CFG_FAULT;
                self.leave(DpState::WaitPrm);
            }
        }
        self.diag_dirty = true;
        Reply::ShortAck
    }

    fn global_control(&mut self, req: &DataTelegram<'_>) {
        let gc = match GlobalControl::parse(req.pdu) {
            Some(gc) if self.state == DpState::DataExch && self.master == Some(req.sa) => gc,
            _ => {
                self.stats.gc_ignored = self.stats.gc_ignored.wrapping_add(1);
                return;
            }
        };
        let group_ident = self.prm.map_or(0, |p| p.group_ident);
        if !gc.selects(group_ident) {
            return;
        }
        if gc.reserved != 0 {
            self.stats.gc_ignored = self.stats.gc_ignored.wrapping_add(1);
        }
        let status = self.prm.map_or(StationStatus::empty(), |p| p.status);
        let cmd = gc.command;
        // Clear_Data: the master is in Clear (reference §3.6, §3.7).
        let clear = cmd.contains(ControlCommand::CLEAR_DATA);
        if clear != self.gc_clear {
            self.gc_clear = clear;
            self.events |= Events::CLEAR_CHANGED;
        }
        if clear {
            // Safety: Clear leaves the outputs zero whatever Sync held; the held image is
            // discarded, never applied later (a Sync in the same command applies nothing).
            self.has_pending_outputs = false;
            if self.outputs.iter().any(|&b| b != 0) {
                self.outputs.fill(0);
                self.events |= Events::OUTPUTS_UPDATED;
            }
        }
        // Sync / Unsync (Unsync wins when both are set).
        if cmd.intersects(ControlCommand::SYNC | ControlCommand::UNSYNC) {
            if !status.contains(StationStatus::SYNC_REQ) {
                self.not_supported = true;
                self.diag_changed();
            } else {
                if self.has_pending_outputs {
                    let n = self.output_len();
                    let pending = self.pending_outputs;
                    self.outputs[..n].copy_from_slice(&pending[..n]);
                    self.has_pending_outputs = false;
                    self.events |= Events::OUTPUTS_UPDATED;
                }
                let sync = !cmd.contains(ControlCommand::UNSYNC);
                if sync {
                    self.events |= Events::SYNC;
                }
                if sync != self.sync_mode {
                    self.sync_mode = sync;
                    self.diag_dirty = true;
                }
            }
        }
        // Freeze / Unfreeze (Unfreeze wins).
        if cmd.intersects(ControlCommand::FREEZE | ControlCommand::UNFREEZE) {
            if !status.contains(StationStatus::FREEZE_REQ) {
                self.not_supported = true;
                self.diag_changed();
            } else {
                let freeze = !cmd.contains(ControlCommand::UNFREEZE);
                let was = self.freeze_mode;
                // Sample the application's inputs now (Freeze) or return to live inputs.
                self.freeze_mode = false;
                self.restage_dx();
                if freeze {
                    self.events |= Events::FREEZE;
                }
                self.freeze_mode = freeze;
                if freeze != was {
                    // Freeze_Mode (diagnosis octet 2 b4) follows at once.
                    self.diag_dirty = true;
                }
            }
        }
    }

    fn set_slave_add(&mut self, req: &DataTelegram<'_>) -> Reply {
        let checked = SetSlaveAdd::parse(req.pdu, self.config.ident_number).and_then(|s| {
            if self.no_add_chg {
                Err(slave_add::SlaveAddError::Frozen)
            } else if self.state != DpState::WaitPrm {
                Err(slave_add::SlaveAddError::State)
            } else {
                Ok(s)
            }
        });
        match checked {
            Ok(s) => {
                self.address = s.address;
                self.no_add_chg = s.no_add_chg;
                self.events |= Events::ADDRESS_CHANGED;
                self.diag_dirty = true;
                self.restage_dx();
                Reply::ShortAck
            }
            Err(_) => self.rs(),
        }
    }
}

impl FdlApplication for DpSlave {
    fn address(&self) -> u8 {
        self.address
    }

    fn on_request(&mut self, now: Instant, req: &DataTelegram<'_>) -> Reply {
        self.retrigger(now, req.sa);
        let srd = matches!(req.fc.function(), RequestFunction::SrdLow | RequestFunction::SrdHigh);
        let reply = match (req.dsap, req.ssap) {
            (None, None) if srd => self.data_exchange(req),
            (Some(sap::GLOBAL_CONTROL), Some(_)) if !srd => {
                self.global_control(req);
                Reply::Silent
            }
            (_, _) if !srd => {
                // SDN to anything but Global_Control: no DP service; never answered.
                self.stats.gc_ignored = self.stats.gc_ignored.wrapping_add(1);
                Reply::Silent
            }
            (Some(dsap), Some(_)) => match dsap {
                sap::SLAVE_DIAG => self.slave_diag(req),
                sap::SET_PRM => self.set_prm(now, req),
                sap::CHK_CFG => self.chk_cfg(req),
                sap::GET_CFG => {
                    let cfg = self.real_cfg().cfg;
                    self.misc_frame(req, cfg)
                }
                sap::RD_INP | sap::RD_OUTP if self.state == DpState::DataExch => {
                    let mut img = [0u8; MAX_IMAGE];
                    let src = if dsap == sap::RD_INP { self.inputs() } else { self.outputs() };
                    let n = src.len();
                    img[..n].copy_from_slice(src);
                    self.misc_frame(req, &img[..n])
                }
                sap::SET_SLAVE_ADD => self.set_slave_add(req),
                _ => self.rs(),
            },
            _ => self.rs(),
        };
        if self.diag_dirty {
            self.restage_diag();
        }
        reply
    }

    fn on_retry(&mut self, now: Instant, req: &DataTelegram<'_>) {
        self.retrigger(now, req.sa);
    }

    fn frame(&self, id: u8, len: u16) -> &[u8] {
        match self.bufs.get(id as usize) {
            Some(b) => &b[..(len as usize).min(b.len())],
            None => &[],
        }
    }
}
