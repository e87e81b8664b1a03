//! The card's side of the DPM exchange: node → image (status, outputs, card report, mailbox
//! requests) and image → node (inputs, drive report, configuration, mailbox responses), with
//! the supervision of the drive's heartbeat.

use super::{
    CardEvent, CardFlags, CardReport, CardSide, CommState, ConfigResult, Dpm, DriveCommandImage, DriveReport,
    DriveStateImage, HeartbeatMonitor, HostConfig, Liveness, Mailbox, MailboxBusy, MailboxRequest, ParamValues,
    PdFlags, ProcessData, Status, StatusFlags, Telegram,
};
use crate::dp::{DpState, Events};
use crate::node::Node;
use crate::profile::param::ParamError;
use crate::time::{Baudrate, Duration, Instant};

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
}

impl Default for Link {
    fn default() -> Self {
        Self::new()
    }
}

impl Link {
    /// A link with no baud rate detected yet.
    pub const fn new() -> Self {
        Link {
            baud: None,
            init_error: false,
            telegram: Telegram::None,
            last_status: None,
            last_outputs: None,
            outputs_seq: 0,
            last_command: None,
            drive_state: DriveStateImage::EMPTY,
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
            },
            drive_monitor: HeartbeatMonitor::new(Self::DEFAULT_DRIVE_TIMEOUT),
            drive: DriveReport::EMPTY,
            drive_lost: false,
            config_done: 0,
            config: None,
            config_new: false,
            mailbox: Mailbox::new(Mailbox::DEFAULT_TIMEOUT),
        }
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
    }

    /// The answer to the last parameter request, once.
    pub fn take_parameter_response(&mut self) -> Option<(u16, Result<ParamValues, ParamError>)> {
        self.mailbox.take()
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
            corrupt_frames: node.framer().stats().corrupt as u16,
        }
    }

    /// Write STATUS (when changed), OUTPUTS (on new outputs or a changed meaning) and CARD
    /// (every call: the card's heartbeat; `events` raise the card → drive events). A change
    /// of the active telegram also clears the input image until the host answers for the new
    /// one.
    pub fn publish(&mut self, node: &mut Node, events: Events, dpm: &mut Dpm) {
        let telegram = active_telegram(node);
        if telegram != self.telegram {
            self.telegram = telegram;
            self.inputs_seq = 0;
            node.slave_mut().set_inputs(&[]);
            if self.drive_lost {
                set_fault_image(node, telegram);
            }
        }
        self.raise_events(node, events);
        self.report.heartbeat = super::next_seq(self.report.heartbeat);
        let m = self.mailbox.stats();
        self.report.late_responses = m.late_responses as u16;
        self.report.mailbox_timeouts = m.timeouts as u16;
        let mut card = dpm.card();
        card.write_card_report(&self.report);
        self.write_status(node, &mut card);

        let slave = node.slave();
        let mut flags = PdFlags::empty();
        flags.set(PdFlags::DATA_EXCHANGE, slave.state() == DpState::DataExch);
        flags.set(PdFlags::CLEAR, slave.is_clear());
        let pd = ProcessData::new(telegram, flags, slave.outputs());
        if events.contains(Events::OUTPUTS_UPDATED) || self.last_outputs.as_ref() != Some(&pd) {
            self.outputs_seq = card.write_outputs(&pd);
            self.last_outputs = Some(pd);
            self.stats.outputs_written = self.stats.outputs_written.wrapping_add(1);
        }
    }

    /// Supervise the drive's heartbeat, take its report, a new configuration, a mailbox
    /// response, and a new INPUTS image written for the active telegram.
    pub fn collect(&mut self, now: Instant, node: &mut Node, dpm: &Dpm) {
        self.supervise(now, node, dpm);
        self.take_over_config(node, dpm);
        self.mailbox.poll(now, dpm);
        if self.drive_lost {
            return;
        }
        match dpm.inputs() {
            Err(_) => self.stats.torn_reads = self.stats.torn_reads.wrapping_add(1),
            Ok(pd) if pd.seq != self.inputs_seq => {
                self.inputs_seq = pd.seq;
                if pd.telegram == self.telegram && self.telegram != Telegram::None {
                    node.slave_mut().set_inputs(pd.bytes());
                    self.stats.inputs_taken = self.stats.inputs_taken.wrapping_add(1);
                } else {
                    self.stats.stale_telegram = self.stats.stale_telegram.wrapping_add(1);
                }
            }
            Ok(_) => {}
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

    fn raise_events(&mut self, node: &Node, events: Events) {
        let slave = node.slave();
        if events.contains(Events::CLEAR_CHANGED) && slave.is_clear() {
            self.raise(CardEvent::ClearMode);
        }
        if events.contains(Events::LEFT_DATA_EXCHANGE) {
            self.raise(CardEvent::Offline);
        }
        if events.contains(Events::STATE_CHANGED) && slave.state() == DpState::DataExch {
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

    fn supervise(&mut self, now: Instant, node: &mut Node, dpm: &Dpm) {
        match dpm.drive_report() {
            Ok(r) => {
                if r != self.drive {
                    if r.ext_diag() != self.drive.ext_diag() {
                        let ext = r.ext_diag();
                        if node.slave_mut().set_ext_diag(ext, !ext.is_empty()).is_err() {
                            self.stats.bad_ext_diag = self.stats.bad_ext_diag.wrapping_add(1);
                        }
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
                node.slave_mut().set_stat_diag(true);
                set_fault_image(node, self.telegram);
            }
            (Liveness::Alive, true) => {
                self.drive_lost = false;
                self.report.flags.remove(CardFlags::DRIVE_LOST);
                self.raise(CardEvent::DriveReturned);
                node.slave_mut().set_stat_diag(false);
                // Serve the drive's next image (even if its INPUTS counter did not move).
                self.inputs_seq = 0;
            }
            _ => {}
        }
    }

    fn take_over_config(&mut self, node: &mut Node, dpm: &Dpm) {
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
            t => crate::card::MODULES.iter().find(|m| Telegram::of_module(m) == Some(t)),
        };
        let result = if !cfg.is_valid() || (cfg.telegram != Telegram::None && module.is_none()) {
            ConfigResult::Refused
        } else if node.slave().state() == DpState::DataExch {
            ConfigResult::Pending
        } else {
            let slave = node.slave_mut();
            // 126: keep the card's address.
            let address = match cfg.station_address {
                a if a <= crate::dp::slave_add::MAX_NEW_ADDRESS => slave.set_address(a),
                _ => Ok(false),
            };
            slave.require_module(module);
            self.config = Some(cfg);
            self.config_new = true;
            self.stats.configs_taken = self.stats.configs_taken.wrapping_add(1);
            match address {
                Err(crate::dp::slave_add::SlaveAddError::Frozen) => ConfigResult::AddressLocked,
                _ => ConfigResult::Accepted,
            }
        };
        if result != ConfigResult::Pending {
            self.config_done = seq;
        }
        self.report.config_ack = seq;
        self.report.config_result = result as u8;
        self.report.flags.set(CardFlags::CONFIG_PENDING, result == ConfigResult::Pending);
    }

    fn write_status(&mut self, node: &Node, card: &mut CardSide<'_>) {
        let s = self.status_of(node);
        if self.last_status != Some(s) {
            card.write_status(&s);
            self.last_status = Some(s);
            self.stats.status_written = self.stats.status_written.wrapping_add(1);
        }
    }
}

/// Serve ZSW1 = [`ZSW1_FAULT`] (after the PKW), every other word 0.
fn set_fault_image(node: &mut Node, telegram: Telegram) {
    let (pkw, pzd) = (telegram.pkw_words(), telegram.pzd_words());
    if pzd == 0 {
        return;
    }
    let mut bytes = [0u8; super::layout::PD_CAPACITY];
    bytes[2 * pkw..2 * pkw + 2].copy_from_slice(&ZSW1_FAULT.to_be_bytes());
    node.slave_mut().set_inputs(&bytes[..2 * (pkw + pzd)]);
}

/// The telegram of the module the last Chk_Cfg selected.
fn active_telegram(node: &Node) -> Telegram {
    node.slave().module().and_then(Telegram::of_module).unwrap_or(Telegram::None)
}
