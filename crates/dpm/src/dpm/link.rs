//! The card's side of the DPM exchange: node → image (status, outputs, card report, mailbox
//! requests) and image → node (inputs, drive report, configuration, mailbox responses), with
//! the supervision of the drive's heartbeat.

use super::layout::PD_CAPACITY;
use super::{
    CardEvent, CardFlags, CardReport, CommState, ConfigResult, Dpm, DriveCommandImage, DriveReport, DriveStateImage,
    HeartbeatMonitor, HostConfig, Liveness, Mailbox, MailboxBusy, MailboxRequest, ParamValues, PdFlags, ProcessData,
    Status, StatusFlags, Telegram,
};
use crate::dp::{DpState, Events, Module};
use crate::node::Node;
use crate::profile::param::ParamError;
use crate::time::{Baudrate, Duration, Instant};

/// The User_Prm_Data octets (counted from DPV1_Status_1) a [`NodeSnapshot`] carries for the
/// card's profile layer: the product's user parameters (this card: `card::USER_PRM_LEN`, 5,
/// asserted to fit). Longer User_Prm_Data is cut.
pub const USER_PRM_CAPACITY: usize = 16;

/// ZSW1 bit 3 "fault present": what the master reads in place of the drive's status word
/// while the drive's heartbeat is lost (every other word 0).
pub const ZSW1_FAULT: u16 = 1 << 3;

/// Counters of the [`Link`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct LinkStats {
    /// INPUTS reads that saw a write in progress (retried next time).
    pub torn_reads: u32,
    /// INPUTS written for another telegram than the active one (not served to the master).
    pub stale_telegram: u32,
    /// INPUTS images handed to the DP slave.
    pub inputs_taken: u32,
    /// OUTPUTS writes.
    pub outputs_written: u32,
    /// STATUS writes.
    pub status_written: u32,
    /// DRIVE or CONFIG reads that saw a write in progress.
    pub torn_host_blocks: u32,
    /// Extended diagnosis from the drive refused as malformed.
    pub bad_ext_diag: u32,
    /// Configurations taken over.
    pub configs_taken: u32,
    /// DRIVE_CMD writes.
    pub commands_written: u32,
}

/// Moves data between a [`Node`] and a [`Dpm`], on the card's side.
///
/// Call [`Link::publish`] after [`Node::poll`] (it writes STATUS when it changed and OUTPUTS
/// whenever a Data_Exchange delivered outputs or their meaning changed), let the host work on
/// the image, then [`Link::collect`] (it hands a new INPUTS image written for the active
/// telegram to the DP slave; the master receives it with its next Data_Exchange).
///
/// Supervision: once `DRIVE.HEARTBEAT` is non-zero, the card expects it to change within
/// [`Link::set_drive_timeout`]. When it does not, the master reads ZSW1 with only
/// [`ZSW1_FAULT`] set, Stat_Diag is on, `CARD.FLAGS` shows the loss and parameter requests are
/// answered with [`super::mailbox::DRIVE_LOST_ERROR`]; when it changes again, the
/// `DriveReturned` event is raised and the drive's inputs are served again. A host that
/// never writes DRIVE (layout version 1) is not supervised.
///
/// Configuration: a new CONFIG (a new sequence counter) is checked, then taken over when the
/// slave is not in data exchange (else `CONFIG_RESULT` = pending until it leaves it). Taking
/// it over applies the station address ([`crate::dp::DpSlave::set_address`]: a new address is
/// reported as `Events::ADDRESS_CHANGED` for the address store; frozen by No_Add_Chg →
/// `CONFIG_RESULT` 4, the rest taken) and the telegram selection
/// ([`crate::dp::DpSlave::require_module`]: Chk_Cfg with another module → Cfg_Fault); the
/// platform gets the whole block once ([`Link::take_config`]) for the profile settings.
#[derive(Debug, Clone)]
pub struct Link {
    baud: Option<Baudrate>,
    init_error: bool,
    telegram: Telegram,
    last_status: Option<Status>,
    last_outputs: Option<ProcessData>,
    outputs_seq: u16,
    last_command: Option<DriveCommandImage>,
    drive_state: DriveStateImage,
    inputs_seq: u16,
    stats: LinkStats,
    report: CardReport,
    drive_monitor: HeartbeatMonitor,
    drive: DriveReport,
    drive_lost: bool,
    config_done: u16,
    config: Option<HostConfig>,
    config_new: bool,
    mailbox: Mailbox,
    /// The parameter request a [`super::ParamCache`] waits for (0 = none): its answer is kept
    /// for that cache, whichever cache looks first ([`Link::take_parameter_answer`]).
    param_claim: u16,
    /// When the answer waiting in the mailbox arrived (a claim not taken within the mailbox
    /// timeout is given up, so a claimant that never comes back cannot block the mailbox).
    param_answered_at: Option<Instant>,
    line_errors: u32,
    /// DEVICE.SEQ last taken.
    device_seq: u16,
    /// Issue 16: no parameterisation before the drive's first valid CONFIG.
    startup_gate: bool,
    /// The product's GSD modules (`dp::SlaveConfig::modules`): CONFIG.TELEGRAM selects one.
    modules: &'static [Module],
}

impl Link {
    /// A link with no baud rate detected yet, for a product with the GSD `modules` (the
    /// node's `dp::SlaveConfig::modules`; this card: `card::MODULES`), one of which the drive's
    /// CONFIG.TELEGRAM may select.
    pub const fn new(modules: &'static [Module]) -> Self {
        Link {
            modules,
            baud: None,
            init_error: false,
            telegram: Telegram::None,
            last_status: None,
            last_outputs: None,
            outputs_seq: 0,
            last_command: None,
            drive_state: DriveStateImage::EMPTY,
            device_seq: 0,
            inputs_seq: 0,
            stats: LinkStats {
                torn_reads: 0,
                stale_telegram: 0,
                inputs_taken: 0,
                outputs_written: 0,
                status_written: 0,
                torn_host_blocks: 0,
                bad_ext_diag: 0,
                configs_taken: 0,
                commands_written: 0,
            },
            report: CardReport {
                heartbeat: 0,
                flags: CardFlags::empty(),
                config_result: 0,
                config_ack: 0,
                events: [0; super::layout::CARD_EVENT_COUNT],
                drive_losses: 0,
                late_responses: 0,
                mailbox_timeouts: 0,
                boot_id: 1,
            },
            drive_monitor: HeartbeatMonitor::new(Self::DEFAULT_DRIVE_TIMEOUT),
            drive: DriveReport::EMPTY,
            drive_lost: false,
            config_done: 0,
            config: None,
            config_new: false,
            mailbox: Mailbox::new(Mailbox::DEFAULT_TIMEOUT),
            param_claim: 0,
            param_answered_at: None,
            line_errors: 0,
            startup_gate: false,
        }
    }

    /// `CARD.BOOT_ID`: the platform's boot identifier (another value on every card start,
    /// panic and watchdog resets included; 0 is shown as 1). The host re-opens the interface
    /// and rewrites CONFIG when it changes.
    pub fn set_boot_id(&mut self, id: u16) {
        self.report.boot_id = id.max(1);
    }

    /// The start-up gate (issue 16; on for a card with a drive, off for a card without one,
    /// whose simulated drive writes no CONFIG): until the drive has written a CONFIG the card
    /// takes over (result 1 or 4), the slave acknowledges Set_Prm without taking it and shows
    /// Station_Not_Ready + Prm_Req in its diagnosis ([`crate::dp::DpSlave::set_ready`]), as
    /// an Anybus module keeps the network off until its host has finished the setup. Applied
    /// to the node by [`Link::apply`].
    pub fn set_startup_gate(&mut self, on: bool) {
        self.startup_gate = on;
    }

    /// Whether the start-up gate holds the slave back now (on, and no CONFIG taken over yet).
    pub fn gated(&self) -> bool {
        self.startup_gate && self.config.is_none()
    }

    /// The safe state after a card fault (`pbcard::app::Card::fail_safe`): empty
    /// OUTPUTS (no data exchange), then DRIVE_CMD `cmd` tied to exactly these OUTPUTS, so the
    /// host's pairing check takes the fail-safe command.
    pub fn publish_safe_state(&mut self, cmd: &DriveCommandImage, dpm: &mut Dpm) {
        let pd = ProcessData::new(Telegram::None, PdFlags::empty(), &[]);
        let mut card = dpm.card();
        self.outputs_seq = card.write_outputs(&pd);
        card.write_card_report(&self.report);
        self.last_outputs = Some(pd);
        self.publish_command(cmd, dpm);
    }

    /// How long the drive's heartbeat may stay unchanged.
    pub const DEFAULT_DRIVE_TIMEOUT: Duration = Duration::from_millis(200);

    /// Set how long the drive's heartbeat may stay unchanged before the drive counts as lost.
    pub fn set_drive_timeout(&mut self, timeout: Duration) {
        self.drive_monitor = HeartbeatMonitor::new(timeout);
    }

    /// Set the parameter mailbox's timeout (drops an outstanding request).
    pub fn set_mailbox_timeout(&mut self, timeout: Duration) {
        self.mailbox = Mailbox::new(timeout);
    }

    /// Whether the drive's heartbeat is lost.
    pub fn drive_lost(&self) -> bool {
        self.drive_lost
    }

    /// The drive's last consistent report (fault, warning, extended diagnosis).
    pub fn drive_report(&self) -> &DriveReport {
        &self.drive
    }

    /// What the card last wrote (or will write next) to CARD.
    pub fn card_report(&self) -> &CardReport {
        &self.report
    }

    /// The configuration taken over last.
    pub fn config(&self) -> Option<&HostConfig> {
        self.config.as_ref()
    }

    /// A newly taken-over configuration, once (the platform applies it).
    pub fn take_config(&mut self) -> Option<HostConfig> {
        if core::mem::take(&mut self.config_new) {
            self.config
        } else {
            None
        }
    }

    /// Ask the drive for a parameter through the mailbox; returns the request id. The answer
    /// comes from [`Link::take_parameter_response`] after a later [`Link::collect`] — the
    /// drive's values or error, or a timeout / drive-lost error; never a hang.
    pub fn submit_parameter(&mut self, now: Instant, req: &MailboxRequest, dpm: &mut Dpm) -> Result<u16, MailboxBusy> {
        self.mailbox.submit(now, req, self.drive_lost, &mut dpm.card())
    }

    /// Look for the answer to the outstanding parameter request, or time it out (also done by
    /// [`Link::collect`]).
    pub fn poll_parameter(&mut self, now: Instant, dpm: &Dpm) {
        self.mailbox.poll(now, dpm);
        match (self.mailbox.answered(), self.param_answered_at) {
            (None, _) => self.param_answered_at = None,
            (Some(_), None) => self.param_answered_at = Some(now),
            (Some(id), Some(at)) => {
                if id == self.param_claim && now.saturating_since(at) >= Mailbox::DEFAULT_TIMEOUT {
                    self.param_claim = 0;
                }
            }
        }
    }

    /// The answer to the last parameter request, once.
    pub fn take_parameter_response(&mut self) -> Option<(u16, Result<ParamValues, ParamError>)> {
        self.mailbox.take()
    }

    /// Claim the answer to request `id` (0: give up the claim of a request whose answer is
    /// no longer wanted): [`Self::take_parameter_answer`] keeps it for the claimant.
    pub fn claim_parameter(&mut self, id: u16) {
        self.param_claim = id;
    }

    /// The answer to request `mine` (the caller's claim), once. An answer claimed by another
    /// caller stays for it (the record-47 and the PKW caches share the mailbox: neither takes
    /// the other's answer); an unclaimed one (its job ended) is dropped, so the mailbox is
    /// free again.
    pub fn take_parameter_answer(&mut self, mine: Option<u16>) -> Option<(u16, Result<ParamValues, ParamError>)> {
        let id = self.mailbox.answered()?;
        if Some(id) == mine {
            if self.param_claim == id {
                self.param_claim = 0;
            }
            return self.mailbox.take();
        }
        if id != self.param_claim {
            self.mailbox.take();
        }
        None
    }

    /// The parameter mailbox (counters, busy).
    pub fn mailbox(&self) -> &Mailbox {
        &self.mailbox
    }

    fn raise(&mut self, e: CardEvent) {
        let c = &mut self.report.events[e as usize];
        *c = c.wrapping_add(1);
    }

    /// The rate the platform listens at (`None` while the autobaud search runs); shown as
    /// P0963 in the status block.
    pub fn set_baudrate(&mut self, rate: Option<Baudrate>) {
        self.baud = rate;
    }

    /// The platform could not start the PROFIBUS interface: the status block shows P0740
    /// "initialization error" until cleared.
    pub fn set_init_error(&mut self, failed: bool) {
        if failed && !self.init_error {
            self.raise(CardEvent::CardFault);
        }
        self.init_error = failed;
        self.report.flags.set(CardFlags::CARD_FAULT, failed);
    }

    /// Counters.
    pub fn stats(&self) -> LinkStats {
        self.stats
    }

    /// The status block's content for `node` as it is now.
    pub fn status_of(&self, node: &Node) -> Status {
        let slave = node.slave();
        let st = slave.stats();
        let mut flags = StatusFlags::empty();
        flags.set(StatusFlags::CLEAR, slave.is_clear());
        flags.set(StatusFlags::SYNC, slave.is_sync());
        flags.set(StatusFlags::FREEZE, slave.is_freeze());
        flags.set(StatusFlags::WATCHDOG_ON, slave.watchdog_time().is_some() && slave.state() != DpState::WaitPrm);
        flags.set(StatusFlags::ADDRESS_LOCKED, slave.no_add_chg());
        Status {
            comm: if self.init_error { CommState::InitError } else { CommState::of(slave) },
            baud: super::p0963(self.baud),
            station_address: slave.address(),
            master_address: slave.master_address(),
            telegram: active_telegram(node),
            dp_state: slave.state(),
            flags,
            watchdog_ms: slave.watchdog_time().map_or(0, |t| t.as_millis().min(u16::MAX as u64) as u16),
            data_exchanges: st.data_exchanges,
            prm_faults: st.prm_faults as u16,
            cfg_faults: st.cfg_faults as u16,
            watchdog_expiries: st.watchdog_expiries as u16,
            corrupt_frames: self.corrupt_frames(node) as u16,
        }
    }

    /// The platform's receiver counts of telegrams lost to the line (cumulative, wrapping):
    /// character errors, telegrams cut off or no telegram at all where one should start, as a
    /// receiver that delimits telegrams itself counts them (the F411's DMA receiver,
    /// `pbcard_link::phy::line::RxStats::lost_frames`; the QEMU board's own framer). Shown in
    /// `STATUS.CORRUPT_FRAMES` (DPM layout, docs/DPM.md) with the node's own framer count and
    /// the telegrams the FDL station found invalid (checksum, delimiters).
    pub fn set_line_errors(&mut self, count: u32) {
        self.line_errors = count;
    }

    /// `STATUS.CORRUPT_FRAMES` before the cut to 16 bits: the node's framer (per-byte
    /// receivers), the FDL station's invalid telegrams (a receiver that hands whole telegrams
    /// to [`Node::on_frame`] leaves the checksum to it) and the platform's line errors
    /// ([`Link::set_line_errors`]).
    pub fn corrupt_frames(&self, node: &Node) -> u32 {
        node.framer().stats().corrupt.wrapping_add(node.station().stats().invalid).wrapping_add(self.line_errors)
    }

    /// Write STATUS (when changed), OUTPUTS (on new outputs or a changed meaning) and CARD
    /// (every call: the card's heartbeat; `events` raise the card → drive events). A change
    /// of the active telegram also clears the input image until the host answers for the new
    /// one. The same as [`Link::take_snapshot`] (the part that needs the node) followed by
    /// [`Link::publish_snapshot`] (the DPM writes).
    pub fn publish(&mut self, node: &mut Node, events: Events, dpm: &mut Dpm) {
        let snap = self.take_snapshot(node, events);
        self.publish_snapshot(&snap, dpm);
    }

    /// The part of [`Link::publish`] that needs the node, for a platform that holds the
    /// node's lock only while copying: a change of the active telegram clears the input image
    /// (or serves the fault image while the drive is lost), then the node is copied into a
    /// [`NodeSnapshot`] with `events`.
    pub fn take_snapshot(&mut self, node: &mut Node, events: Events) -> NodeSnapshot {
        let telegram = active_telegram(node);
        if telegram != self.telegram {
            self.telegram = telegram;
            self.inputs_seq = 0;
            node.slave_mut().set_inputs(&[]);
            if self.drive_lost {
                set_fault_image(node, telegram, self.config.map(|c| c.profile));
            }
        }
        self.snapshot(node, events)
    }

    /// A copy of what the link and the card's profile layer need of `node` (no change to
    /// the link or the node).
    pub fn snapshot(&self, node: &Node, events: Events) -> NodeSnapshot {
        let slave = node.slave();
        let out = slave.outputs();
        let n = out.len().min(PD_CAPACITY);
        let mut outputs = [0u8; PD_CAPACITY];
        outputs[..n].copy_from_slice(&out[..n]);
        // The user parameters of the last accepted Set_Prm, else the product's defaults.
        let user = slave.parameters().map_or(slave.config().user_prm_defaults, |p| p.user.as_slice());
        let u = user.len().min(USER_PRM_CAPACITY);
        let mut user_prm = [0u8; USER_PRM_CAPACITY];
        user_prm[..u].copy_from_slice(&user[..u]);
        NodeSnapshot {
            events,
            status: self.status_of(node),
            outputs,
            outputs_len: n as u8,
            user_prm,
            user_prm_len: u as u8,
        }
    }

    /// The part of [`Link::publish`] without the node: STATUS, OUTPUTS and CARD from a
    /// [`NodeSnapshot`] taken by [`Link::take_snapshot`].
    pub fn publish_snapshot(&mut self, snap: &NodeSnapshot, dpm: &mut Dpm) {
        self.raise_events(snap);
        self.report.heartbeat = super::next_seq(self.report.heartbeat);
        let m = self.mailbox.stats();
        self.report.late_responses = m.late_responses as u16;
        self.report.mailbox_timeouts = m.timeouts as u16;
        let mut card = dpm.card();
        card.write_card_report(&self.report);
        if self.last_status != Some(snap.status) {
            card.write_status(&snap.status);
            self.last_status = Some(snap.status);
            self.stats.status_written = self.stats.status_written.wrapping_add(1);
        }

        let mut flags = PdFlags::empty();
        flags.set(PdFlags::DATA_EXCHANGE, snap.dp_state() == DpState::DataExch);
        flags.set(PdFlags::CLEAR, snap.is_clear());
        let pd = ProcessData::new(self.telegram, flags, snap.outputs());
        if snap.events.contains(Events::OUTPUTS_UPDATED) || self.last_outputs.as_ref() != Some(&pd) {
            self.outputs_seq = card.write_outputs(&pd);
            self.last_outputs = Some(pd);
            self.stats.outputs_written = self.stats.outputs_written.wrapping_add(1);
        }
    }

    /// Supervise the drive's heartbeat, take its report, a new configuration, a mailbox
    /// response, and a new INPUTS image written for the active telegram. The same as
    /// [`Link::collect_host`] (with the raw INPUTS path) followed by [`Link::apply`].
    pub fn collect(&mut self, now: Instant, node: &mut Node, dpm: &Dpm) {
        let update = self.collect_host(now, node.slave().state(), dpm, true);
        self.apply(node, &update);
    }

    /// The part of [`Link::collect`] without the node, `dp_state` being the slave's state
    /// when it was last copied: the drive's report and heartbeat, a new configuration (taken
    /// over outside data exchange), the mailbox, and with `raw_inputs` a new INPUTS image
    /// written for the active telegram. What the node must learn from it is returned, for
    /// [`Link::apply`]. A card that builds the input image itself (the profile layer,
    /// DRIVE_STATE) passes `raw_inputs = false`: then its image is the only input path.
    pub fn collect_host(&mut self, now: Instant, dp_state: DpState, dpm: &Dpm, raw_inputs: bool) -> NodeUpdate {
        let mut update = NodeUpdate::new(self.telegram);
        self.supervise(now, dpm, &mut update);
        self.take_over_config(dp_state, dpm, &mut update);
        self.poll_parameter(now, dpm);
        match dpm.device_ident() {
            Ok((seq, d)) if seq != 0 && seq != self.device_seq => {
                self.device_seq = seq;
                update.device = Some(device_ident(d));
            }
            Ok(_) => {}
            Err(_) => self.stats.torn_host_blocks = self.stats.torn_host_blocks.wrapping_add(1),
        }
        if self.drive_lost || !raw_inputs {
            return update;
        }
        match dpm.inputs() {
            Err(_) => self.stats.torn_reads = self.stats.torn_reads.wrapping_add(1),
            Ok(pd) if pd.seq != self.inputs_seq => {
                self.inputs_seq = pd.seq;
                if pd.telegram == self.telegram && self.telegram != Telegram::None {
                    update.set_inputs(pd.bytes());
                    self.stats.inputs_taken = self.stats.inputs_taken.wrapping_add(1);
                } else {
                    self.stats.stale_telegram = self.stats.stale_telegram.wrapping_add(1);
                }
            }
            Ok(_) => {}
        }
        update
    }

    /// Hand a [`NodeUpdate`] to the node: the drive's extended diagnosis, Stat_Diag while the
    /// drive is lost, and the input image (the fault image while the drive is lost). Images
    /// made for another telegram than the node's active one now (a Chk_Cfg came between) are
    /// dropped: the next [`Link::take_snapshot`] clears the inputs for the new one.
    pub fn apply(&mut self, node: &mut Node, update: &NodeUpdate) {
        if let Some(t) = &update.config {
            self.apply_config(node, t);
        }
        if node.slave().is_ready() == self.gated() {
            node.slave_mut().set_ready(!self.gated());
        }
        if update.ext_diag {
            // Ext_Diag (Station_Status_1 b3) only for a fault: a PLC raises OB82 and shows the
            // slave faulty on it; a warning is carried in the block without it (issue 12).
            let ext = self.drive.ext_diag();
            let fault = self.drive.fault_code;
            if node.slave_mut().set_ext_diag(ext, fault != 0).is_err() {
                self.stats.bad_ext_diag = self.stats.bad_ext_diag.wrapping_add(1);
            }
            // A fault appearing or clearing: a diagnostic alarm when the master enabled them.
            node.slave_mut().set_drive_fault(fault);
        }
        if let Some(on) = update.stat_diag {
            node.slave_mut().set_stat_diag(on);
        }
        if let Some(d) = update.device {
            node.im_mut().set_ident(d);
        }
        if active_telegram(node) != update.telegram {
            return;
        }
        if update.fault_image {
            set_fault_image(node, update.telegram, self.config.map(|c| c.profile));
        } else if let Some(inputs) = update.inputs() {
            node.slave_mut().set_inputs(inputs);
        }
    }

    /// Write DRIVE_CMD (layout 3) when it changed: the drive-neutral command of the card's
    /// profile layer, tied to the OUTPUTS image written last (`outputs_seq`, so the host
    /// never pairs a command with outputs of another cycle).
    pub fn publish_command(&mut self, img: &DriveCommandImage, dpm: &mut Dpm) {
        let img = DriveCommandImage { outputs_seq: self.outputs_seq, ..*img };
        if self.last_command.as_ref() != Some(&img) {
            dpm.card().write_drive_command(&img);
            self.last_command = Some(img);
            self.stats.commands_written = self.stats.commands_written.wrapping_add(1);
        }
    }

    /// The drive's latest consistent DRIVE_STATE (layout 3); a torn read keeps the previous
    /// one (counted). All zero until the host writes it.
    pub fn read_drive_state(&mut self, dpm: &Dpm) -> &DriveStateImage {
        match dpm.drive_state() {
            Ok((seq, img)) if seq != 0 => self.drive_state = img,
            Ok(_) => {}
            Err(_) => self.stats.torn_host_blocks = self.stats.torn_host_blocks.wrapping_add(1),
        }
        &self.drive_state
    }

    fn raise_events(&mut self, snap: &NodeSnapshot) {
        let events = snap.events;
        if events.contains(Events::CLEAR_CHANGED) && snap.is_clear() {
            self.raise(CardEvent::ClearMode);
        }
        if events.contains(Events::LEFT_DATA_EXCHANGE) {
            self.raise(CardEvent::Offline);
        }
        if events.contains(Events::STATE_CHANGED) && snap.dp_state() == DpState::DataExch {
            self.raise(CardEvent::Online);
        }
        if events.contains(Events::WATCHDOG_EXPIRED) {
            self.raise(CardEvent::Watchdog);
        }
        if events.contains(Events::PRM_FAULT) {
            self.raise(CardEvent::ParameterizationError);
        }
        if events.contains(Events::CFG_FAULT) {
            self.raise(CardEvent::ConfigurationError);
        }
    }

    fn supervise(&mut self, now: Instant, dpm: &Dpm, update: &mut NodeUpdate) {
        match dpm.drive_report() {
            Ok(r) => {
                if r != self.drive {
                    if r.ext_diag() != self.drive.ext_diag() || r.fault_code != self.drive.fault_code {
                        update.ext_diag = true;
                    }
                    self.drive = r;
                }
            }
            Err(_) => self.stats.torn_host_blocks = self.stats.torn_host_blocks.wrapping_add(1),
        }
        let live = self.drive_monitor.observe(now, self.drive.heartbeat);
        match (live, self.drive_lost) {
            (Liveness::Lost, false) => {
                self.drive_lost = true;
                self.report.drive_losses = self.report.drive_losses.wrapping_add(1);
                self.report.flags.insert(CardFlags::DRIVE_LOST);
                self.mailbox.abort();
                update.stat_diag = Some(true);
                update.fault_image = true;
            }
            (Liveness::Alive, true) => {
                self.drive_lost = false;
                self.report.flags.remove(CardFlags::DRIVE_LOST);
                self.raise(CardEvent::DriveReturned);
                update.stat_diag = Some(false);
                // Serve the drive's next image (even if its INPUTS counter did not move).
                self.inputs_seq = 0;
            }
            _ => {}
        }
    }

    /// A new CONFIG (DPM sequence counter moved): refused when invalid or naming a telegram
    /// the card has no module for, kept pending in data exchange; otherwise handed to
    /// [`Link::apply`] (through `update`), which applies the station address and the telegram
    /// restriction to the node and acknowledges.
    fn take_over_config(&mut self, dp_state: DpState, dpm: &Dpm, update: &mut NodeUpdate) {
        let (seq, cfg) = match dpm.config() {
            Ok(c) => c,
            Err(_) => {
                self.stats.torn_host_blocks = self.stats.torn_host_blocks.wrapping_add(1);
                return;
            }
        };
        if seq == 0 || seq == self.config_done {
            return;
        }
        // The module of the selected telegram (none: any module).
        let module = match cfg.telegram {
            Telegram::None => None,
            t => self.modules.iter().find(|m| Telegram::of_module(m) == Some(t)),
        };
        if !cfg.is_valid() || (cfg.telegram != Telegram::None && module.is_none()) {
            self.acknowledge_config(seq, ConfigResult::Refused);
        } else if dp_state == DpState::DataExch {
            self.acknowledge_config(seq, ConfigResult::Pending);
        } else {
            update.config = Some(ConfigTakeover { seq, config: cfg, module });
        }
    }

    /// The node part of a configuration takeover (under the node's lock): the station address
    /// (126: keep the card's) and the Chk_Cfg restriction to the selected telegram's module.
    /// A slave that entered data exchange since the snapshot keeps the configuration pending.
    fn apply_config(&mut self, node: &mut Node, t: &ConfigTakeover) {
        if node.slave().state() == DpState::DataExch {
            self.acknowledge_config(t.seq, ConfigResult::Pending);
            return;
        }
        let slave = node.slave_mut();
        let address = match t.config.station_address {
            a if a <= crate::dp::slave_add::MAX_NEW_ADDRESS => slave.set_address(a),
            _ => Ok(false),
        };
        slave.require_module(t.module);
        self.config = Some(t.config);
        self.config_new = true;
        self.stats.configs_taken = self.stats.configs_taken.wrapping_add(1);
        let result = match address {
            Err(crate::dp::slave_add::SlaveAddError::Frozen) => ConfigResult::AddressLocked,
            _ => ConfigResult::Accepted,
        };
        self.acknowledge_config(t.seq, result);
    }

    /// CARD.CONFIG_ACK / CONFIG_RESULT for the configuration `seq`; every result but Pending
    /// ends its processing.
    fn acknowledge_config(&mut self, seq: u16, result: ConfigResult) {
        if result != ConfigResult::Pending {
            self.config_done = seq;
        }
        self.report.config_ack = seq;
        self.report.config_result = result as u8;
        self.report.flags.set(CardFlags::CONFIG_PENDING, result == ConfigResult::Pending);
    }
}

/// A configuration taken over by [`Link::collect_host`], applied to the node by
/// [`Link::apply`].
#[derive(Debug, Clone, Copy)]
struct ConfigTakeover {
    seq: u16,
    config: HostConfig,
    module: Option<&'static Module>,
}

/// Serve the profile's fault status word (after the PKW; [`ZSW1_FAULT`] for PROFIdrive, WEG
/// P0680 b15, INVT state 4: `profile::telegram::ProfileFamily::fault_status_word`), every
/// other word 0. `profile` is the drive's CONFIG.PROFILE (WEG P0741; `None` without CONFIG).
fn set_fault_image(node: &mut Node, telegram: Telegram, profile: Option<u8>) {
    use crate::profile::telegram::{DataProfile, Layout};
    let word =
        Layout::of(telegram).map_or(ZSW1_FAULT, |l| l.profile(DataProfile::of_config(profile)).fault_status_word());
    let (pkw, pzd) = (telegram.pkw_words(), telegram.pzd_words());
    if pzd == 0 {
        return;
    }
    let mut bytes = [0u8; super::layout::PD_CAPACITY];
    bytes[2 * pkw..2 * pkw + 2].copy_from_slice(&word.to_be_bytes());
    node.slave_mut().set_inputs(&bytes[..2 * (pkw + pzd)]);
}

/// The telegram of the module the last Chk_Cfg selected.
fn active_telegram(node: &Node) -> Telegram {
    node.slave().module().and_then(Telegram::of_module).unwrap_or(Telegram::None)
}

/// What the [`Link`] and the card's profile layer need of the [`Node`], copied while the
/// node is locked ([`Link::take_snapshot`]); the DPM is written from the copy, outside the
/// lock (issue 5: the node's lock is what delays the response decision).
#[derive(Debug, Clone)]
pub struct NodeSnapshot {
    /// The node's events since the last snapshot ([`Node::poll`]).
    pub events: Events,
    /// The status block's content (DP state, active telegram, Clear, counters).
    pub status: Status,
    outputs: [u8; PD_CAPACITY],
    outputs_len: u8,
    user_prm: [u8; USER_PRM_CAPACITY],
    user_prm_len: u8,
}

impl NodeSnapshot {
    /// The active telegram (the module of the last Chk_Cfg).
    pub fn telegram(&self) -> Telegram {
        self.status.telegram
    }
    /// The DP state.
    pub fn dp_state(&self) -> DpState {
        self.status.dp_state
    }
    /// The master is in Clear (outputs all zero).
    pub fn is_clear(&self) -> bool {
        self.status.flags.contains(StatusFlags::CLEAR)
    }
    /// The master's outputs (Data_Exchange; at most the DPM's `PD_CAPACITY`).
    pub fn outputs(&self) -> &[u8] {
        &self.outputs[..usize::from(self.outputs_len)]
    }
    /// The User_Prm_Data octets (from DPV1_Status_1 on) of the last accepted Set_Prm, the
    /// product's defaults before one (`dp::SlaveConfig::user_prm_defaults`), at most
    /// [`USER_PRM_CAPACITY`]: the card reads its user parameters (operate mode,
    /// communication-loss reaction) from them.
    pub fn user_prm(&self) -> &[u8] {
        &self.user_prm[..usize::from(self.user_prm_len)]
    }
}

/// What the node must learn from one [`Link::collect_host`] (and the card's profile layer):
/// applied while the node is locked by [`Link::apply`].
#[derive(Debug, Clone)]
pub struct NodeUpdate {
    telegram: Telegram,
    ext_diag: bool,
    stat_diag: Option<bool>,
    fault_image: bool,
    inputs: [u8; PD_CAPACITY],
    inputs_len: Option<u8>,
    config: Option<ConfigTakeover>,
    /// The drive's DEVICE block (serial number, hardware revision for I&M0), when it changed.
    device: Option<crate::dpv1::im::DeviceIdent>,
}

impl NodeUpdate {
    /// Nothing to change, for images of `telegram`.
    pub const fn new(telegram: Telegram) -> Self {
        NodeUpdate {
            telegram,
            ext_diag: false,
            stat_diag: None,
            fault_image: false,
            inputs: [0; PD_CAPACITY],
            inputs_len: None,
            config: None,
            device: None,
        }
    }

    /// The telegram the images are for.
    pub fn telegram(&self) -> Telegram {
        self.telegram
    }

    /// A new input image for the DP slave (cut to the DPM's process-data capacity,
    /// `layout::PD_CAPACITY`; [`crate::dp::DpSlave::set_inputs`] then cuts it to the
    /// configured module's length).
    pub fn set_inputs(&mut self, bytes: &[u8]) {
        let n = bytes.len().min(PD_CAPACITY);
        self.inputs[..n].copy_from_slice(&bytes[..n]);
        self.inputs_len = Some(n as u8);
    }

    /// The new input image, if any.
    pub fn inputs(&self) -> Option<&[u8]> {
        self.inputs_len.map(|n| &self.inputs[..usize::from(n)])
    }
}

/// The drive's DEVICE block as I&M0 reports it: a serial number byte outside the visible
/// string range reads as a blank (a hardware revision 0 reads as the device's own,
/// [`crate::dpv1::im::Im::set_ident`]).
fn device_ident(d: crate::dpv1::im::DeviceIdent) -> crate::dpv1::im::DeviceIdent {
    let mut out = d;
    for b in out.serial_number.iter_mut() {
        if !(0x20..=0x7E).contains(b) {
            *b = b' ';
        }
    }
    out
}
