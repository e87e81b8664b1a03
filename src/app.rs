//! The card as it ships ([`Card`]): one call per main-loop turn.
//!
//! ```text
//! Card:        Node::poll ─▶ Link::publish (STATUS, OUTPUTS, CARD)
//!              ─▶ (the drive's control board writes DRIVE_STATE, DRIVE, CONFIG, MBX_RSP through the SPI transport)
//!              ─▶ Link::collect (DRIVE, CONFIG, mailbox) ─▶ profile::runtime (DRIVE_STATE ─▶ input image; outputs ─▶ DRIVE_CMD)
//! ```
//!
//! [`Card`] is everything the card does without a simulated drive: the node-side DPM link
//! ([`Link`]), the card's profile layer ([`crate::profile::runtime::Runtime`]: the telegram,
//! the control profile (PROFIdrive 4.1 / 2.0, WEG, INVT), the operate mode (PROFIdrive /
//! Bypass / Echo), the PKW channel and the fault buffer), the speed-reference reader, the
//! fail-safe path and the card's DPM image. The drive sees only the drive-neutral DRIVE_CMD
//! and answers DRIVE_STATE (issue 6 item 2). The board firmware of a real card runs
//! [`Card::new`]: the drive's control board is the SPI master and its frames reach the image
//! through [`Card::dpm_mut`] (`dpm::spi::SpiSlave`).
//!
//! The simulation is not in this crate (issue 13 items 1 and 4): the bench
//! `pbcard_sim::bench::Application` (the crate `pbcard-sim`, `crates/sim`) wraps a [`Card`]
//! whose image is [`DriveHost`] — the host side's reference implementation over the SPI frames
//! to an in-process card — and runs the simulated drive `pbcard_sim::drive::SimDrive` on it
//! between [`Card::step_publish`] and [`Card::step_collect`]. The card-only F411 build does not
//! compile it (`pbcard-bsp` names `pbcard-sim` only for QEMU and `sim-drive`), and
//! `scripts/footprint.sh` checks the ELF.
//!
//! PROFIdrive parameters not owned by the card go to the drive through the DPM parameter
//! mailbox: [`Card::parameters`] is the table behind the card's data records
//! ([`Card::records`], which the DP-V1 task passes to [`Node::process_acyclic`]); the PKW channel
//! of the PPO / INVT telegrams uses the same mailbox with its own answer cache.

use crate::card;
use crate::dp::{DpState, Events};
use crate::dpm::host::Host;
use crate::dpm::layout::operate_mode;
use crate::dpm::spi::{Loopback, SpiHost};
use crate::dpm::{
    Dpm, DriveCommandImage, Link, MailboxParams, NodeSnapshot, NodeUpdate, ParamCache, PzdWords, Telegram,
};
use crate::node::Node;
use crate::profile::cyclic::OperateMode;
use crate::profile::drive_if::CommandFlags;
use crate::profile::profidrive::State;
use crate::profile::records::{CardRecords, WithTable};
use crate::profile::references::References;
use crate::profile::runtime::{AnyProfile, Runtime, Scales, Selection};
use crate::profile::telegram::DataProfile;
use crate::time::{Baudrate, Duration, Instant};

/// Whether the master gets the drive's raw INPUTS (issue 16 item 4): a host of layout 1 / 2
/// writes INPUTS (the telegram's input words) and no DRIVE_STATE; its INPUTS are served until
/// it writes DRIVE_STATE once (`DRIVE_STATE.SEQ_HEAD` ≠ 0). From then on the profile layer
/// builds the input image from DRIVE_STATE and INPUTS is ignored (docs/DPM.md, INPUTS).
fn raw_inputs(dpm: &Dpm) -> bool {
    let img = dpm.as_bytes();
    let head = |at: usize| u16::from_be_bytes([img[at], img[at + 1]]);
    head(crate::dpm::layout::drive_state::START) == 0 && head(crate::dpm::layout::inputs::START) != 0
}

/// Where the card's DPM image lives: in the card itself ([`Dpm`], the board), or behind the
/// simulated drive's host interface ([`DriveHost`], the bench's in-process SPI card).
pub trait CardImage {
    /// The DPM image.
    fn dpm(&self) -> &Dpm;
    /// The DPM image, writable.
    fn dpm_mut(&mut self) -> &mut Dpm;
}

impl CardImage for Dpm {
    fn dpm(&self) -> &Dpm {
        self
    }
    fn dpm_mut(&mut self) -> &mut Dpm {
        self
    }
}

/// The drive's side of the DPM as the bench sees it: the host reference implementation over
/// the SPI frames of [`crate::dpm::spi`], the card an in-process [`Loopback`] that owns the
/// card's DPM image.
pub type DriveHost = Host<SpiHost<Loopback>>;

impl CardImage for DriveHost {
    fn dpm(&self) -> &Dpm {
        self.transport().dpm()
    }
    fn dpm_mut(&mut self) -> &mut Dpm {
        self.transport_mut().dpm_mut()
    }
}

/// The card (ARCHITECTURE §2): the DPM image `I` (its own [`Dpm`] on the board) with the
/// card-side link, the profile layer, the speed-reference reader and the parameter caches of
/// record 47 and the PKW channel. No drive: the drive's control board writes the host blocks
/// through the transport the platform feeds into [`dpm_mut`](Self::dpm_mut).
#[derive(Debug, Clone)]
pub struct Card<I = Dpm> {
    image: I,
    link: Link,
    params: ParamCache,
    pkw_params: ParamCache,
    /// The speed references read from the drive after each selection (issue 15 item 10;
    /// through the record-47 answer cache `params`, so neither takes the other's answers).
    refs: References,
    runtime: Runtime,
    /// The card's DP-V1 data records behind I&M (PROFIdrive record 47, WEG record 48), with the
    /// fault buffer and process view [`apply`](Self::apply) hands them.
    records: CardRecords,
    /// Events of [`Self::step_publish`] for [`Self::step_collect`].
    events: Events,
}

impl Card {
    /// The card as it ships: a fresh image (P0740 "inactive" until the first step), the
    /// profile layer without a telegram, no parameterisation before the drive has written a
    /// valid CONFIG (issue 16, [`Link::set_startup_gate`]). The host blocks (INPUTS, DRIVE,
    /// CONFIG, MBX_RSP, DRIVE_STATE) are written only by the drive's control board.
    ///
    /// Out of line: builds a large value in place (inlined into the start, every store needs its own stack address; footprint, issue 13 item 1).
    #[inline(never)]
    pub fn new() -> Self {
        let mut card = Self::with_image(Dpm::with_identity(&crate::card::IDENTITY));
        card.link.set_startup_gate(true);
        card
    }
}

impl Default for Card {
    fn default() -> Self {
        Self::new()
    }
}

impl<I: CardImage> Card<I> {
    /// The card over `image` (a fresh one), without the startup gate: the bench's card, whose
    /// simulated drive writes CONFIG in its first cycle.
    pub fn with_image(image: I) -> Self {
        Card {
            image,
            link: Link::new(crate::card::MODULES),
            params: ParamCache::new(),
            pkw_params: ParamCache::new(),
            refs: References::new(),
            runtime: Runtime::new(Scales::DEFAULT),
            records: CardRecords::new(&crate::card::RECORDS),
            events: Events::empty(),
        }
    }

    /// The card's DP-V1 data records (PROFIdrive record 47, WEG record 48: the card's own PNUs in
    /// front of [`parameters`](Self::parameters) at `now`), for [`Node::process_acyclic`].
    pub fn records(&mut self, now: Instant) -> WithTable<'_, MailboxParams<'_>> {
        let table = MailboxParams::new(now, &mut self.link, self.image.dpm_mut(), &mut self.params);
        self.records.with(table)
    }

    /// The card's data records' state (records 47 / 48, fault buffer, process view).
    pub fn card_records(&self) -> &CardRecords {
        &self.records
    }

    /// The drive's parameters (behind the card's own PNUs) through the DPM parameter mailbox
    /// at `now`, for the card's data records ([`records`](Self::records)): never waits; a value not there yet makes the
    /// job pending, a drive that does not answer makes it fail with 0x11 after the mailbox
    /// timeout.
    pub fn parameters(&mut self, now: Instant) -> MailboxParams<'_> {
        MailboxParams::new(now, &mut self.link, self.image.dpm_mut(), &mut self.params)
    }

    /// The rate the platform listens at (`None` while searching); shown as P0963.
    pub fn set_baudrate(&mut self, rate: Option<Baudrate>) {
        self.link.set_baudrate(rate);
    }

    /// One step of the card alone: the node's timers, [`Link::publish`] (STATUS, OUTPUTS,
    /// CARD), then [`Link::collect`] and the profile layer (DRIVE_STATE → the next input image,
    /// the outputs → DRIVE_CMD) and a waiting PKW job. Returns the node's events (for logs and
    /// LEDs). The drive's control board writes the host blocks between two steps, through the
    /// transport the platform feeds into [`dpm_mut`](Self::dpm_mut).
    pub fn step(&mut self, now: Instant, node: &mut Node) -> Events {
        let events = self.step_publish(now, node);
        self.step_collect(now, node);
        events
    }

    /// The first part of [`step`](Self::step), the part that needs the node: its timers and
    /// [`Link::publish`] (status, outputs, events into the DPM). The same as
    /// [`snapshot`](Self::snapshot) + [`publish`](Self::publish).
    pub fn step_publish(&mut self, now: Instant, node: &mut Node) -> Events {
        let snap = self.snapshot(now, node);
        self.publish(&snap);
        snap.events
    }

    /// The last part of [`step`](Self::step) (after the drive's part, on a bench), with the node: [`Link::collect`] (drive
    /// supervision, configuration takeover, mailbox), the profile layer (DRIVE_STATE → the
    /// next input image, the outputs → DRIVE_CMD) and a waiting PKW job. The same as
    /// [`collect`](Self::collect) on a fresh copy of the node + [`apply`](Self::apply).
    pub fn step_collect(&mut self, now: Instant, node: &mut Node) {
        let snap = self.link.snapshot(node, Events::empty());
        let update = self.collect(now, &snap);
        self.apply(node, &update);
    }

    /// The node's part of a step for a firmware that keeps the node's lock short (call it
    /// with the lock held; it only copies): the node's timers ([`Node::poll`]), the link's
    /// reaction to a new telegram, and a [`NodeSnapshot`] of what [`publish`](Self::publish)
    /// and [`collect`](Self::collect) need. The firmware's step is `snapshot` (locked) →
    /// `publish` → (on a bench: `pbcard_sim::bench::Application::step_drive`) → `collect` → [`apply`](Self::apply)
    /// (locked); [`step`](Self::step) does the same with the node at hand.
    pub fn snapshot(&mut self, now: Instant, node: &mut Node) -> NodeSnapshot {
        let events = node.poll(now);
        self.link.take_snapshot(node, events)
    }

    /// Without the node: STATUS, OUTPUTS and CARD into the DPM from `snap`
    /// ([`Link::publish_snapshot`]); its events are kept for the profile layer.
    pub fn publish(&mut self, snap: &NodeSnapshot) {
        self.link.publish_snapshot(snap, self.image.dpm_mut());
        self.events |= snap.events;
    }

    /// Without the node: [`Link::collect_host`] (drive supervision, configuration takeover,
    /// mailbox; no raw INPUTS: the profile layer builds the input image), the profile cycle
    /// on `snap` (DRIVE_STATE → the next input image, the outputs → DRIVE_CMD) and a waiting
    /// PKW job. Returns what the node must learn, for [`apply`](Self::apply).
    pub fn collect(&mut self, now: Instant, snap: &NodeSnapshot) -> NodeUpdate {
        let dpm = self.image.dpm();
        let raw = raw_inputs(dpm);
        let mut update = self.link.collect_host(now, snap.dp_state(), dpm, raw);
        let events = core::mem::replace(&mut self.events, Events::empty());
        self.run_profile(now, snap, events, &mut update, raw);
        self.service_pkw(now);
        self.service_references(now);
        update
    }

    /// Read the speed references of a new selection from the drive through the mailbox
    /// (`profile::references`). They share the record-47 answer cache: one request at a time
    /// for both, and an answer is never taken by the other (a record-47 job starting meanwhile
    /// empties the cache; the reads are then asked again). After a waiting PKW job (its own
    /// cache).
    fn service_references(&mut self, now: Instant) {
        // The record-47 cache takes its answer even while a PKW job waits: the answer is
        // claimed for it (`Link::take_parameter_answer`), and the PKW job's request can be
        // sent only once it is taken.
        if !self.refs.is_busy() && !self.params.waiting() {
            return;
        }
        let dpm = self.image.dpm_mut();
        let mut table = MailboxParams::new(now, &mut self.link, dpm, &mut self.params);
        if self.refs.is_busy() && !self.runtime.has_pkw_work() {
            if let Some(scales) = self.refs.service(now, &mut table, self.runtime.scales()) {
                self.runtime.set_scales(scales);
            }
        }
    }

    /// The speed-reference reader (`profile::references`).
    pub fn references(&self) -> &References {
        &self.refs
    }

    /// The node's last part (call it with the lock held; it only copies): the drive's
    /// diagnosis and the new input image ([`Link::apply`]), and the profile layer's fault
    /// buffer for PNU 944 / 947 and the process view for the card's data records
    /// ([`CardRecords::set_fault_buffer`], [`CardRecords::set_process_view`]).
    pub fn apply(&mut self, node: &mut Node, update: &NodeUpdate) {
        self.link.apply(node, update);
        let faults = self.runtime.faults();
        self.records.set_fault_buffer(faults.counter(), faults.numbers());
        self.records.set_process_view(self.runtime.process_view());
    }

    /// The panic / hard-fault path (ARCHITECTURE §2 "supervision"): the DPM OUTPUTS block to
    /// the safe state (all zero, neither DATA_EXCHANGE nor CLEAR flagged, no telegram), the
    /// command to the drive a coast stop with the communication lost, the card fault flag set
    /// and the `CARD.EVENTS` "card fault" counter (index 6) raised, so the drive sees the
    /// failure in the image the transport moves next. Bounded, no allocation, no node needed:
    /// callable from a panic handler on a possibly corrupt state.
    pub fn fail_safe(&mut self) {
        self.link.set_init_error(true);
        let mut safe = DriveCommandImage::EMPTY;
        safe.command.flags = CommandFlags::COAST | CommandFlags::COMM_LOSS;
        // OUTPUTS and DRIVE_CMD of one card cycle: the host's pairing check takes it.
        self.link.publish_safe_state(&safe, self.image.dpm_mut());
    }

    /// After a reset that followed [`fail_safe`](Self::fail_safe) (the board keeps a flag in
    /// RAM that survives the reset): raise the "card fault" event once more in the fresh
    /// image, without keeping P0740 at "initialization error".
    pub fn report_recovered_fault(&mut self) {
        self.link.set_init_error(true);
        self.link.set_init_error(false);
    }

    /// The profile layer: select the engine for the active telegram, run one cycle with the
    /// drive's latest state, stage the input image in `update`, write DRIVE_CMD.
    fn run_profile(&mut self, now: Instant, snap: &NodeSnapshot, events: Events, update: &mut NodeUpdate, raw: bool) {
        let telegram = snap.telegram();
        let in_dx = snap.dp_state() == DpState::DataExch;
        if telegram != Telegram::None && in_dx {
            let user = snap.user_prm();
            let config = self.link.config();
            let local = config.map_or(0, |c| c.operate_mode);
            let data = DataProfile::of_config(config.map(|c| c.profile));
            let delay = config.map_or(0, |c| c.io_update_delay);
            self.runtime.set_io_update_delay(Duration::from_millis(100 * u64::from(delay)));
            let loss_delay = config.map_or(0, |c| c.comm_loss_delay_ms);
            self.runtime.set_comm_loss_delay(Duration::from_millis(u64::from(loss_delay)));
            // The master's reaction (Set_Prm) first; its 0 "the drive's own setting" takes the
            // drive's CONFIG.COMM_LOSS_REACTION (P0313-style), so a drive that leaves the
            // reaction to the card gets the one it configured.
            let reaction = match user.get(card::PRM_COMM_LOSS_REACTION.offset).copied().unwrap_or(0) {
                0 => config.map_or(0, |c| c.comm_loss_reaction),
                r => r,
            };
            let selections = self.runtime.stats().selections;
            self.runtime.select(Selection {
                telegram,
                mode: Selection::mode_of(user.get(card::PRM_OPERATE_MODE.offset).copied().unwrap_or(0), local),
                data,
                comm_loss_reaction: reaction,
            });
            if self.runtime.stats().selections != selections {
                // A new selection: its speed references come from the drive (issue 15 item 10).
                self.runtime.set_scales(Scales::DEFAULT);
                self.refs.start(telegram, data);
            }
        }
        let Some(sel) = self.runtime.selection() else { return };
        // Watchdog expired / master gone (left data exchange) or master in Clear.
        let lost = !in_dx || snap.is_clear();
        self.runtime.set_clear_mode(in_dx && snap.is_clear());
        let state = *self.link.read_drive_state(self.image.dpm());
        let outputs = (events.contains(Events::OUTPUTS_UPDATED) && !lost).then(|| snap.outputs());
        let drive_lost = self.link.drive_lost();
        let Some(x) = self.runtime.cycle_at(now, outputs, lost, &state.status, state.extra.words()) else { return };
        let img = DriveCommandImage {
            command: x.command.unwrap_or_default(),
            operate_mode: match sel.mode {
                OperateMode::Profidrive => operate_mode::PROFIDRIVE,
                OperateMode::Bypass => operate_mode::BYPASS,
                OperateMode::Echo => operate_mode::ECHO,
            },
            telegram: sel.telegram,
            outputs_seq: 0,
            extra: PzdWords::new(x.words).unwrap_or(PzdWords::EMPTY),
        };
        if in_dx && !drive_lost && !raw && sel.telegram == telegram && telegram == update.telegram() {
            update.set_inputs(x.inputs);
        }
        self.link.publish_command(&img, self.image.dpm_mut());
    }

    /// Serve a waiting PKW job through the mailbox (its own answer cache, so a record-47 job
    /// and a PKW job never discard each other's answers).
    pub fn service_pkw(&mut self, now: Instant) {
        if self.runtime.has_pkw_work() {
            let dpm = self.image.dpm_mut();
            let mut table = MailboxParams::new(now, &mut self.link, dpm, &mut self.pkw_params);
            self.runtime.service_pkw(&mut table);
        }
    }

    /// The DPM image.
    pub fn dpm(&self) -> &Dpm {
        self.image.dpm()
    }
    /// The DPM image, writable: for a transport that moves the host's bytes into it
    /// (`dpm::spi::SpiSlave` on the board).
    pub fn dpm_mut(&mut self) -> &mut Dpm {
        self.image.dpm_mut()
    }
    /// The card-side link (counters, init-error flag).
    pub fn link_mut(&mut self) -> &mut Link {
        &mut self.link
    }
    /// The card-side link.
    pub fn link(&self) -> &Link {
        &self.link
    }
    /// The card's profile layer.
    pub fn runtime(&self) -> &Runtime {
        &self.runtime
    }
    /// The PROFIdrive state of the active profile (`None` without one, or for the WEG
    /// manufacturer / INVT profiles, which have no state machine).
    pub fn profidrive_state(&self) -> Option<State> {
        match self.runtime.profile()? {
            AnyProfile::Profidrive(p) => Some(p.state()),
            _ => None,
        }
    }
    /// Where the image lives ([`DriveHost`] on the bench).
    pub fn image(&self) -> &I {
        &self.image
    }
    /// Where the image lives, writable.
    pub fn image_mut(&mut self) -> &mut I {
        &mut self.image
    }
}

/// The shipped card in a main loop ([`crate::fast::tick`]): [`Card::step`] and [`Card::records`].
impl<I: CardImage> crate::fast::CardApp for Card<I> {
    type Records<'a>
        = WithTable<'a, MailboxParams<'a>>
    where
        I: 'a;
    fn step(&mut self, now: Instant, node: &mut Node) -> Events {
        Card::step(self, now, node)
    }
    fn records(&mut self, now: Instant) -> Self::Records<'_> {
        Card::records(self, now)
    }
}
