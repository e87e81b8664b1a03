//! The host-side reference implementation of the DPM interface (issue 7 item 5): the
//! [`Host`] is what the drive's control board runs against the card's DPM. `no_std`, no
//! allocation, time handed in: port it by implementing [`Transport`] for the board's link to
//! the card (the SPI frames of [`crate::dpm::spi`], a dual-port RAM) and calling [`Host`] from the
//! drive's cycle. The simulated drive of the QEMU build, the soft slave and the host tests
//! (`pbcard_sim::bench::Application`) runs through it. The `dpm-host` crate re-exports it with `std`
//! extras (a shared in-process image).
//!
//! * [`Host::open`] — check magic, layout version, image size, capabilities.
//! * [`Host::identity`], [`Host::status`], [`Host::card_report`] — what the card is and does.
//! * [`Host::write_config`], [`Host::config_outcome`] — configuration, taken over by the card
//!   only while no cyclic exchange runs (`CARD.CONFIG_RESULT`).
//! * [`Host::read_process_data`], [`Host::write_process_data`] — DRIVE_CMD + OUTPUTS of one
//!   card cycle in, INPUTS + DRIVE_STATE out (torn reads repeated, never returned).
//! * [`Host::serve_parameters`], [`Host::respond`] — the parameter mailbox.
//! * [`Host::set_fault`], [`Host::set_warning`], [`Host::set_ext_diag`], [`Host::poll`] — the
//!   DRIVE block with the drive's heartbeat, the card's heartbeat watched (lost = A140).

pub mod transport;

use crate::dpm::codec::{self, BlockCodec, BlockError, Header};
use crate::dpm::layout::{self, cap, CARD_EVENT_COUNT, EXT_DIAG_CAPACITY};
use crate::dpm::spi::cyclic;
use crate::dpm::{
    mailbox, CardEvent, CardReport, CommState, ConfigResult, DriveCommandImage, DriveReport, DriveStateImage,
    HeartbeatMonitor, HostConfig, Identity, Liveness, MailboxRequest, MailboxResponse, ParamValues, ProcessData,
    Status, Torn,
};
use crate::profile::param::{ParamError, ParameterAccess};
use crate::time::{Duration, Instant};
pub use transport::{CyclicReceipt, DpmTransport, MemoryTransport, Transport, TransportError};

/// The longest block (the reader's buffer).
const MAX_BLOCK: usize = {
    let mut i = 0;
    let mut m = 0;
    while i < layout::BLOCKS.len() {
        if layout::BLOCKS[i].len > m {
            m = layout::BLOCKS[i].len;
        }
        i += 1;
    }
    m
};

const fn next_seq(s: u16) -> u16 {
    if s == u16::MAX {
        1
    } else {
        s + 1
    }
}

/// How the [`Host`] works.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Options {
    /// How long `CARD.HEARTBEAT` may stay unchanged before the card counts as lost (the A140
    /// situation). Default 200 ms, the card's default for the drive's heartbeat.
    pub card_timeout: Duration,
    /// Reads of a block (or of a DRIVE_CMD / OUTPUTS pair) before giving up on a torn one.
    /// Default 8; at least 1.
    pub read_attempts: u8,
    /// Capability bits ([`layout::cap`]) the drive cannot work without; [`Host::open`] refuses a
    /// card lacking one. Default none.
    pub required: u32,
    /// Bytes one CYCLIC transaction may clock (`docs/SPI.md` "One drive cycle"): the mailbox
    /// fragments are sized to what the telegram leaves of it, each way (at least
    /// [`cyclic::MIN_FRAGMENT`], at most [`cyclic::MAX_FRAGMENT`] bytes). Default 64 (issue 16:
    /// ≤ 64 bytes per drive cycle for ST1 and PPO 5).
    pub cyclic_bytes: usize,
    /// The parameter mailbox rides in the CYCLIC exchange's fragments (default). Off: a
    /// [`Host::cycle`] drive fetches MBX_REQ and writes MBX_RSP with block accesses (a
    /// request answered within one drive cycle, at the cost of extra transactions in the
    /// cycles that carry one: the simulated drive, whose tests count card steps per job).
    pub cyclic_mailbox: bool,
}

impl Default for Options {
    fn default() -> Self {
        Options::DEFAULT
    }
}

impl Options {
    /// 200 ms card timeout, 8 read attempts, nothing required, 64-byte CYCLIC transactions,
    /// the mailbox in them.
    pub const DEFAULT: Options = Options {
        card_timeout: Duration::from_millis(200),
        read_attempts: 8,
        required: 0,
        cyclic_bytes: 64,
        cyclic_mailbox: true,
    };
}

/// Why [`Host::open`] refused the image.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OpenError {
    /// The header could not be read.
    Transport(TransportError),
    /// `HEADER.MAGIC` is not "PBDM" (no card, or not initialised yet: try again).
    BadMagic([u8; 4]),
    /// `HEADER.LAYOUT_VERSION` 0 (not a layout).
    BadVersion(u16),
    /// `HEADER.IMAGE_SIZE` is smaller than the layout version promises.
    BadImageSize {
        /// The layout version read.
        version: u16,
        /// The size read.
        size: u16,
    },
    /// The card lacks capabilities [`Options::required`] names (the missing bits).
    MissingCapabilities(u32),
}

impl From<TransportError> for OpenError {
    fn from(e: TransportError) -> Self {
        OpenError::Transport(e)
    }
}

/// Why a [`Host`] call gave no data.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Error {
    /// The transport failed.
    Transport(TransportError),
    /// Every attempt saw the block being written; nothing was returned (read again later).
    Torn(Torn),
    /// The card does not serve this (capability bit(s) missing, or an older layout version).
    NotSupported(u32),
    /// DRIVE_CMD and OUTPUTS stayed from different card cycles for every attempt (the
    /// command's `outputs_seq`, the outputs' counter).
    Unpaired {
        /// `DRIVE_CMD.OUTPUTS_SEQ` as read last.
        command_for: u16,
        /// `OUTPUTS.SEQ_HEAD` as read last.
        outputs: u16,
    },
    /// [`Host::respond`] to a request that is no longer the card's current one (the card timed
    /// it out and asked something else): the answer is not written, so it can never be taken
    /// for the new request.
    StaleResponse {
        /// The request answered.
        id: u16,
        /// The card's current request (0 = none).
        current: u16,
    },
    /// More bytes than the block holds (extended diagnosis).
    TooLong,
}

impl From<TransportError> for Error {
    fn from(e: TransportError) -> Self {
        Error::Transport(e)
    }
}

impl core::fmt::Display for Error {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Error::Transport(e) => write!(f, "transport: {e}"),
            Error::Torn(t) => write!(f, "block torn on every attempt (head {}, tail {})", t.head, t.tail),
            Error::NotSupported(c) => write!(f, "not served by this card (capabilities {c:#x})"),
            Error::Unpaired { command_for, outputs } => {
                write!(f, "command for outputs {command_for}, outputs {outputs}: never one cycle")
            }
            Error::StaleResponse { id, current } => write!(f, "request {id} is no longer current ({current})"),
            Error::TooLong => f.write_str("too long for the block"),
        }
    }
}

impl core::error::Error for Error {}

impl core::error::Error for OpenError {}

impl core::fmt::Display for OpenError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            OpenError::Transport(e) => write!(f, "transport: {e}"),
            OpenError::BadMagic(m) => write!(f, "bad magic {m:02X?}"),
            OpenError::BadVersion(v) => write!(f, "bad layout version {v}"),
            OpenError::BadImageSize { version, size } => write!(f, "image size {size} too small for version {version}"),
            OpenError::MissingCapabilities(c) => write!(f, "missing capabilities {c:#x}"),
        }
    }
}

/// Where the configuration the host wrote last stands (`CARD.CONFIG_ACK` / `CONFIG_RESULT`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ConfigOutcome {
    /// This host has written no configuration.
    NotWritten,
    /// The card has not looked at it yet.
    Waiting,
    /// Valid; the card waits until no cyclic exchange runs.
    Pending,
    /// Taken over.
    Accepted,
    /// Refused as invalid (nothing applied).
    Refused,
    /// Taken over, except the station address: No_Add_Chg froze it (the card keeps its own).
    AddressLocked,
}

/// New card → drive events since the previous [`Host::poll`]: how often each
/// [`CardEvent`] happened (from the wrapping counters in `CARD.EVENTS`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct CardEvents {
    counts: [u8; CARD_EVENT_COUNT],
}

impl CardEvents {
    /// How often `e` happened.
    pub fn count(&self, e: CardEvent) -> u8 {
        self.counts[e as usize]
    }

    /// Whether `e` happened.
    pub fn contains(&self, e: CardEvent) -> bool {
        self.count(e) > 0
    }

    /// Whether nothing happened.
    pub fn is_empty(&self) -> bool {
        self.counts.iter().all(|&c| c == 0)
    }

    /// The events that happened.
    pub fn iter(&self) -> impl Iterator<Item = CardEvent> + '_ {
        CardEvent::ALL.into_iter().filter(|&e| self.contains(e))
    }
}

/// What one [`Host::poll`] saw.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Poll {
    /// The card's heartbeat: `Lost` = the card stopped (the manuals' A140 situation; the drive
    /// applies its communication-error action, P0313-style).
    pub card: Liveness,
    /// The card was alive (or never seen) and is lost since this poll.
    pub card_lost: bool,
    /// The card was lost and beats again since this poll.
    pub card_returned: bool,
    /// Card → drive events since the last poll (none on the first read after [`Host::open`]).
    pub events: CardEvents,
    /// `CARD.BOOT_ID` changed: the card restarted. This poll has re-opened the interface
    /// (header checked again), rewritten the last CONFIG, taken the event counters as they
    /// are now (no events reported for the restart's counter reset) and forgotten the
    /// mailbox state; the card's start-up gate opens once it takes the CONFIG over.
    pub card_restarted: bool,
    /// The CARD block as read now (`None`: not served, torn on every attempt, or the transport
    /// failed — see `error`).
    pub report: Option<CardReport>,
    /// The first failure of this poll (the DRIVE write or the CARD read), if any.
    pub error: Option<Error>,
}

/// What one [`Host::cycle`] exchanged.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Cycle {
    /// The card's heartbeat, events and restart, as [`Host::poll`] reports them (`report`
    /// is `None` in a CYCLIC exchange, which carries the CARD fields the drive needs only).
    pub poll: Poll,
    /// The drive-neutral command with its DRIVE_CMD counter (`None`: none consistent this
    /// cycle: keep the last one, the card heartbeat decides when it is too old).
    pub command: Option<(u16, DriveCommandImage)>,
    /// `STATUS.COMM_STATE` (P0740 coding) as the card sent it.
    pub comm: Option<CommState>,
    /// The cycle ran as one CYCLIC exchange (else as block accesses).
    pub cyclic: bool,
}

/// Index of MBX_REQ in `layout::BLOCKS` (its bit in the events bitmap).
const MBX_REQ_BLOCK: usize = 8;
const _: () = assert!(layout::BLOCKS[MBX_REQ_BLOCK].start == layout::mbx_req::START);

/// The drive's answer to a parameter request ([`ParameterServer`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Answer {
    /// The values read / write done, or the PROFIdrive error.
    Now(Result<ParamValues, ParamError>),
    /// The drive answers later with [`Host::respond`] (it must, within the card's mailbox
    /// timeout, or the card answers the master with 0x11 / 0xDD01 itself).
    Later,
}

/// The drive's parameter table as the mailbox sees it: one call per new request.
pub trait ParameterServer {
    /// Answer `req` (read, write or read description of `req.pnu`).
    fn request(&mut self, req: &MailboxRequest) -> Answer;
}

impl<F: FnMut(&MailboxRequest) -> Answer> ParameterServer for F {
    fn request(&mut self, req: &MailboxRequest) -> Answer {
        self(req)
    }
}

/// A synchronous parameter table ([`ParameterAccess`], the same trait the card's own
/// parameters implement) as a [`ParameterServer`]: answered at once by
/// [`crate::dpm::mailbox::execute`] (format and count checks, PROFIdrive error values).
#[derive(Debug)]
pub struct Table<'a, P>(pub &'a mut P);

impl<P: ParameterAccess> ParameterServer for Table<'_, P> {
    fn request(&mut self, req: &MailboxRequest) -> Answer {
        Answer::Now(mailbox::execute(req, self.0))
    }
}

/// The process data of one card cycle: the drive-neutral command and the master's raw outputs
/// it was made from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ProcessImage {
    /// DRIVE_CMD's sequence counter (0 = the card has not written a command yet).
    pub command_seq: u16,
    /// The command.
    pub command: DriveCommandImage,
    /// The outputs (`seq` = OUTPUTS' counter).
    pub outputs: ProcessData,
}

/// MBX_RSP written through the CYCLIC exchange (issue 16 item 5): the block as encoded, its
/// body (head, fields, values: `block[..len]`) streamed in ascending fragments sized to the
/// cycle's spare bytes, one per cycle, then the tail. A fragment counts as applied once the
/// reply **to the request that carried it** came back OK ([`CyclicReceipt::previous`] says
/// which request a reply answers); after a failed exchange the unconfirmed part is sent again.
/// The tail, which makes the block consistent for the card, goes only once the whole body is
/// confirmed, so the card never takes a block with a stale middle.
#[derive(Debug, Clone)]
struct RspFragments {
    block: [u8; layout::mbx_rsp::LEN],
    /// Bytes of the body (head, fields, values).
    len: usize,
    /// Every body byte below this is confirmed applied.
    confirmed: usize,
    /// The next body byte to send.
    next: usize,
}

impl RspFragments {
    const TAIL: usize = layout::mbx_rsp::SEQ_TAIL;

    /// The fragment of this cycle, at most `room` bytes (≥ 2): the next body bytes, or the
    /// tail once the body is confirmed.
    fn fragment(&mut self, room: usize) -> (u8, &[u8]) {
        if self.confirmed >= self.len {
            return (Self::TAIL as u8, &self.block[Self::TAIL..]);
        }
        if self.next >= self.len {
            self.next = self.confirmed;
        }
        let at = self.next;
        let n = room.min(self.len - at);
        self.next += n;
        (at as u8, &self.block[at..at + n])
    }
}

/// MBX_REQ read through the CYCLIC exchange (issue 16 item 5): the fragments the replies
/// carried, in ascending order from offset 0 (which carries `SEQ_HEAD`, and counts as the
/// host's read of the block for the events). Each fragment is a copy of a consistent block
/// (the card sends none while it writes the block); a request that took more than one fragment
/// is taken only when a last 2-byte fragment at `SEQ_TAIL` equals the head: the counter only
/// grows, so every fragment between came from the same request.
#[derive(Debug, Clone)]
struct ReqFragments {
    block: [u8; layout::mbx_req::LEN],
    /// Bytes `block[..have]` received.
    have: usize,
    /// Fragments they came in.
    fragments: u8,
}

impl ReqFragments {
    /// Bytes of the request from offset 0 (through its values), as far as known.
    fn need(&self) -> usize {
        use layout::mbx_req;
        if self.have > mbx_req::VALUES_LEN {
            mbx_req::VALUES + usize::from(self.block[mbx_req::VALUES_LEN]).min(layout::MBX_CAPACITY)
        } else {
            mbx_req::VALUES
        }
    }

    /// The fragment to ask next, at most `room` bytes (≥ 2).
    fn wanted(&self, room: usize) -> (u8, u8) {
        let need = self.need();
        if self.have < need {
            (self.have as u8, room.min(need - self.have) as u8)
        } else {
            (layout::mbx_req::SEQ_TAIL as u8, 2)
        }
    }
}

/// The mailbox fragments one CYCLIC request carried: MBX_REQ asked (offset, bytes), MBX_RSP
/// sent (offset, bytes).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
struct Carried {
    req: (u8, u8),
    rsp: (u8, u8),
}

/// Counters of the [`Host`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct HostStats {
    /// Block reads that saw a write in progress and were repeated.
    pub torn_retries: u32,
    /// Reads that stayed torn for every attempt ([`Error::Torn`]).
    pub torn_failures: u32,
    /// DRIVE_CMD / OUTPUTS pairs from two card cycles, read again.
    pub unpaired_retries: u32,
    /// Transport failures.
    pub transport_errors: u32,
    /// Parameter requests taken from MBX_REQ.
    pub requests: u32,
    /// Responses written to MBX_RSP.
    pub responses: u32,
    /// Responses not written because their request was no longer current.
    pub stale_responses: u32,
    /// Card heartbeat losses.
    pub card_losses: u32,
    /// Card restarts seen (`CARD.BOOT_ID` changed).
    pub card_restarts: u32,
}

/// The host side of the DPM interface over a [`Transport`]: open and check the image, read
/// the card's identity, status and events, write configuration and see its acknowledge,
/// exchange process data through the sequenced blocks, serve the parameter mailbox, report
/// faults / warnings / extended diagnosis, and keep both heartbeats.
///
/// Time is handed in ([`Instant`]); nothing blocks. A typical drive cycle:
///
/// ```text
/// host.poll(now)                      // DRIVE (heartbeat, reports) out, CARD in: events, card lost?
/// host.read_process_data()            // DRIVE_CMD + OUTPUTS of one card cycle
/// … the drive applies the command …
/// host.write_process_data(&inputs, &state)   // INPUTS, then DRIVE_STATE
/// host.serve_parameters(&mut table)   // a new mailbox request, if any
/// ```
#[derive(Debug, Clone)]
pub struct Host<T> {
    transport: T,
    header: Header,
    opts: Options,
    seq_inputs: u16,
    seq_drive: u16,
    seq_config: u16,
    seq_rsp: u16,
    seq_state: u16,
    seq_device: u16,
    heartbeat: u16,
    report: DriveReport,
    card_monitor: HeartbeatMonitor,
    card_heartbeat: u16,
    card_lost: bool,
    events_seen: Option<[u8; CARD_EVENT_COUNT]>,
    config_written: Option<u16>,
    /// The configuration written last (rewritten after a card restart).
    last_config: Option<HostConfig>,
    /// `CARD.BOOT_ID` as last read (0 = not known yet / a card without one).
    boot_id: u16,
    /// The DRIVE report as last written whole (a CYCLIC cycle writes only the heartbeat).
    report_written: Option<DriveReport>,
    /// From the last CYCLIC reply: whether MBX_REQ changed (`None`: unknown, look).
    mailbox_hint: Option<bool>,
    /// A whole MBX_REQ assembled from CYCLIC replies' fragments (its counter and request),
    /// for [`Self::fetch_request`].
    fragment: Option<(u16, Option<MailboxRequest>)>,
    /// MBX_REQ being assembled from fragments.
    req_in: Option<ReqFragments>,
    /// A response on its way through the CYCLIC exchange's MBX_RSP fragments.
    rsp_out: Option<RspFragments>,
    /// The fragments the last CYCLIC request carried (its reply may come with the next).
    carried: Carried,
    /// DRIVE_CMD bytes of the last CYCLIC reply (the reply's length without its fragment).
    command_len: usize,
    request_seen: u16,
    /// `MBX_REQ.SEQ_HEAD` of the last consistent read of MBX_REQ (0 = none yet).
    request_block_seq: u16,
    request_open: Option<u16>,
    stats: HostStats,
}

impl<T: Transport> Host<T> {
    /// Open the interface: read the header, check the magic, the layout version (any version;
    /// newer cards only append) and its image size, and the capabilities `opts.required`;
    /// then take over the sequence counters of the blocks the host writes, so a restarted host
    /// continues them (the card only takes a block whose counter changed).
    pub fn open(mut transport: T, opts: Options) -> Result<Self, OpenError> {
        let mut buf = [0u8; layout::header::LEN];
        transport.read(codec::HEADER.start() as u16, &mut buf)?;
        let header = match codec::HEADER.decode(&buf) {
            Ok((_, h)) => h,
            Err(_) => return Err(OpenError::BadMagic([0; 4])),
        };
        if header.magic != layout::MAGIC {
            return Err(OpenError::BadMagic(header.magic));
        }
        if header.layout_version == 0 {
            return Err(OpenError::BadVersion(0));
        }
        let known = (header.layout_version as usize).min(layout::LAYOUT_VERSION as usize);
        if (header.image_size as usize) < layout::IMAGE_SIZE_OF_VERSION[known] {
            return Err(OpenError::BadImageSize { version: header.layout_version, size: header.image_size });
        }
        let missing = opts.required & !header.capabilities;
        if missing != 0 {
            return Err(OpenError::MissingCapabilities(missing));
        }
        let mut host = Host {
            transport,
            header,
            opts,
            seq_inputs: 0,
            seq_drive: 0,
            seq_config: 0,
            seq_rsp: 0,
            seq_state: 0,
            seq_device: 0,
            heartbeat: 0,
            report: DriveReport::EMPTY,
            card_monitor: HeartbeatMonitor::new(opts.card_timeout),
            card_heartbeat: 0,
            card_lost: false,
            events_seen: None,
            config_written: None,
            last_config: None,
            boot_id: 0,
            report_written: None,
            mailbox_hint: None,
            fragment: None,
            req_in: None,
            rsp_out: None,
            carried: Carried::default(),
            command_len: layout::drive_cmd::SEQ_TAIL - layout::drive_cmd::FLAGS,
            request_seen: 0,
            request_block_seq: 0,
            request_open: None,
            stats: HostStats::default(),
        };
        host.seq_inputs = host.read_u16(codec::INPUTS.start())?;
        if host.has(cap::DRIVE_REPORTS) {
            host.seq_drive = host.read_u16(codec::DRIVE.start())?;
            host.heartbeat = host.read_u16(codec::DRIVE.start() + layout::drive::HEARTBEAT)?;
        }
        if host.has(cap::CONFIG) {
            host.seq_config = host.read_u16(codec::CONFIG.start())?;
        }
        if host.has(cap::MAILBOX) {
            host.seq_rsp = host.read_u16(codec::MBX_RSP.start())?;
            host.request_seen = host.read_u16(codec::MBX_RSP.start() + layout::mbx_rsp::REQ_ID)?;
        }
        if host.has(cap::DRIVE_STATE) {
            host.seq_state = host.read_u16(codec::DRIVE_STATE.start())?;
        }
        if host.has(cap::DEVICE) {
            host.seq_device = host.read_u16(codec::DEVICE.start())?;
        }
        Ok(host)
    }

    /// The header read by [`Self::open`].
    pub fn header(&self) -> &Header {
        &self.header
    }

    /// Whether the card serves every bit of `capabilities` ([`layout::cap`]).
    pub fn has(&self, capabilities: u32) -> bool {
        self.header.capabilities & capabilities == capabilities && self.header.layout_version >= 2
    }

    /// Counters.
    pub fn stats(&self) -> HostStats {
        self.stats
    }

    /// The transport.
    pub fn transport(&self) -> &T {
        &self.transport
    }

    /// The transport, writable (an in-process test works on the card side through it).
    pub fn transport_mut(&mut self) -> &mut T {
        &mut self.transport
    }

    /// Close: give the transport back.
    pub fn into_transport(self) -> T {
        self.transport
    }

    // -----------------------------------------------------------------------------------
    // Identity, status, card report

    /// The identification block (card type, firmware, ident number, serial).
    pub fn identity(&mut self) -> Result<Identity, Error> {
        self.require(cap::IDENT)?;
        self.read(&codec::IDENT).map(|(_, v)| v)
    }

    /// The status block (P0740 state, P0963 baud, addresses, telegram, DP state, counters).
    pub fn status(&mut self) -> Result<Status, Error> {
        self.read(&codec::STATUS).map(|(_, v)| v)
    }

    /// The card block as it is now (heartbeat, configuration acknowledge, event counters); the
    /// events and the card's liveness are followed by [`Self::poll`].
    pub fn card_report(&mut self) -> Result<CardReport, Error> {
        self.require(cap::CARD_EVENTS)?;
        self.read(&codec::CARD).map(|(_, v)| v)
    }

    // -----------------------------------------------------------------------------------
    // Configuration

    /// Write the configuration (station address, telegram, profile, operate mode, PZD
    /// mapping, communication-loss reaction and delay); returns its sequence counter. The card
    /// takes it over only while no cyclic exchange runs ([`Self::config_outcome`]).
    pub fn write_config(&mut self, cfg: &HostConfig) -> Result<u16, Error> {
        self.require(cap::CONFIG)?;
        let mut seq = self.seq_config;
        let r = self.write(&codec::CONFIG, cfg, &mut seq);
        self.seq_config = seq;
        self.config_written = Some(seq);
        self.last_config = Some(*cfg);
        r
    }

    /// `CARD.BOOT_ID` as last read by [`Self::poll`] (0: not known yet, or a card without one).
    pub fn boot_id(&self) -> u16 {
        self.boot_id
    }

    /// The card restarted (its BOOT_ID changed): check the header again, rewrite the last
    /// CONFIG, forget the mailbox state (the card's request ids start again). The event
    /// counters are taken by the caller.
    fn card_restart(&mut self) -> Result<(), Error> {
        self.stats.card_restarts = self.stats.card_restarts.wrapping_add(1);
        let mut buf = [0u8; layout::header::LEN];
        if let Err(e) = self.transport.read(codec::HEADER.start() as u16, &mut buf) {
            return Err(self.transport_error(e));
        }
        match codec::HEADER.decode(&buf) {
            Ok((_, h)) if h.magic == layout::MAGIC && h.layout_version != 0 => self.header = h,
            _ => return Err(Error::Transport(TransportError::Corrupt)),
        }
        self.request_seen = 0;
        self.request_block_seq = 0;
        self.request_open = None;
        self.req_in = None;
        self.rsp_out = None;
        self.fragment = None;
        if let Some(cfg) = self.last_config {
            self.write_config(&cfg)?;
        }
        Ok(())
    }

    /// Where the configuration written last stands, from `CARD.CONFIG_ACK` / `CONFIG_RESULT`.
    pub fn config_outcome(&mut self) -> Result<ConfigOutcome, Error> {
        let Some(seq) = self.config_written else { return Ok(ConfigOutcome::NotWritten) };
        let r = self.card_report()?;
        Ok(Self::outcome(seq, &r))
    }

    fn outcome(seq: u16, r: &CardReport) -> ConfigOutcome {
        if r.config_ack != seq {
            return ConfigOutcome::Waiting;
        }
        match r.config_result() {
            ConfigResult::Accepted => ConfigOutcome::Accepted,
            ConfigResult::Pending => ConfigOutcome::Pending,
            ConfigResult::Refused => ConfigOutcome::Refused,
            ConfigResult::AddressLocked => ConfigOutcome::AddressLocked,
            ConfigResult::None => ConfigOutcome::Waiting,
        }
    }

    // -----------------------------------------------------------------------------------
    // Process data

    /// The master's outputs (raw telegram words) as the card wrote them last.
    pub fn read_outputs(&mut self) -> Result<ProcessData, Error> {
        self.read(&codec::OUTPUTS).map(|(_, v)| v)
    }

    /// The drive-neutral command as the card wrote it last, with its sequence counter.
    pub fn read_command(&mut self) -> Result<(u16, DriveCommandImage), Error> {
        self.require(cap::DRIVE_CMD)?;
        self.read(&codec::DRIVE_CMD)
    }

    /// DRIVE_CMD and OUTPUTS of one card cycle: both blocks consistent, and the command made
    /// from exactly these outputs (`DRIVE_CMD.OUTPUTS_SEQ` = `OUTPUTS.SEQ_HEAD`, or 0 = not
    /// tied to outputs). A pair from two cycles is read again; nothing torn or unpaired is
    /// ever returned.
    pub fn read_process_data(&mut self) -> Result<ProcessImage, Error> {
        self.require(cap::DRIVE_CMD)?;
        let mut last = (0, 0);
        for _ in 0..self.opts.read_attempts.max(1) {
            let (_, outputs) = self.read(&codec::OUTPUTS)?;
            let (command_seq, command) = self.read(&codec::DRIVE_CMD)?;
            if command.outputs_seq == 0 || command.outputs_seq == outputs.seq {
                return Ok(ProcessImage { command_seq, command, outputs });
            }
            last = (command.outputs_seq, outputs.seq);
            self.stats.unpaired_retries = self.stats.unpaired_retries.wrapping_add(1);
        }
        Err(Error::Unpaired { command_for: last.0, outputs: last.1 })
    }

    /// Write the drive's inputs (raw telegram words for `inputs.telegram`; the card serves
    /// them only for the active telegram); returns INPUTS' new counter.
    pub fn write_inputs(&mut self, inputs: &ProcessData) -> Result<u16, Error> {
        let mut seq = self.seq_inputs;
        let r = self.write(&codec::INPUTS, inputs, &mut seq);
        self.seq_inputs = seq;
        r
    }

    /// Write the drive-neutral status alone (its `inputs_seq` as given); returns DRIVE_STATE's
    /// new counter.
    pub fn write_state(&mut self, state: &DriveStateImage) -> Result<u16, Error> {
        self.require(cap::DRIVE_STATE)?;
        let mut seq = self.seq_state;
        let r = self.write(&codec::DRIVE_STATE, state, &mut seq);
        self.seq_state = seq;
        r
    }

    /// Write DEVICE (layout 4): the drive's serial number and hardware revision, which the
    /// card reports in I&M0 (DP-V1 slot 0 / index 255). Once after start is enough.
    pub fn write_device_ident(&mut self, ident: &crate::dpv1::im::DeviceIdent) -> Result<u16, Error> {
        self.require(cap::DEVICE)?;
        let mut seq = self.seq_device;
        let r = self.write(&codec::DEVICE, ident, &mut seq);
        self.seq_device = seq;
        r
    }

    /// Write INPUTS, then DRIVE_STATE naming it (`inputs_seq`), so the card can tell the two
    /// belong to one drive cycle. Returns the two counters.
    pub fn write_process_data(&mut self, inputs: &ProcessData, state: &DriveStateImage) -> Result<(u16, u16), Error> {
        self.require(cap::DRIVE_STATE)?;
        let i = self.write_inputs(inputs)?;
        let s = self.write_state(&DriveStateImage { inputs_seq: i, ..*state })?;
        Ok((i, s))
    }

    // -----------------------------------------------------------------------------------
    // Faults, warnings, extended diagnosis (DRIVE), heartbeats

    /// Report the active fault (0 = none); a new non-zero code counts as a new fault report
    /// (`DRIVE.FAULT_COUNT`). Written with the next [`Self::poll`].
    pub fn set_fault(&mut self, code: u16) {
        if code != 0 && code != self.report.fault_code {
            self.report.fault_count = self.report.fault_count.wrapping_add(1);
        }
        self.report.fault_code = code;
    }

    /// Report the active warning (0 = none), like [`Self::set_fault`].
    pub fn set_warning(&mut self, code: u16) {
        if code != 0 && code != self.report.warning_code {
            self.report.warning_count = self.report.warning_count.wrapping_add(1);
        }
        self.report.warning_code = code;
    }

    /// Hand over extended diagnosis blocks as DP sends them (device / identifier / channel
    /// related; empty = none); the card refuses malformed ones (it counts them). Written with
    /// the next [`Self::poll`].
    pub fn set_ext_diag(&mut self, blocks: &[u8]) -> Result<(), Error> {
        if blocks.len() > EXT_DIAG_CAPACITY {
            return Err(Error::TooLong);
        }
        self.report.set_ext_diag(blocks);
        Ok(())
    }

    /// Set the IRQ mask (`DRIVE.IRQ_MASK`, `docs/SPI.md` "Events and the IRQ line"): bits of
    /// the pending-events bitmap that do not assert the card's IRQ line (0 = none masked).
    /// Written with the next [`Self::poll`] / [`Self::cycle`].
    pub fn set_irq_mask(&mut self, mask: u16) {
        self.report.irq_mask = mask;
    }

    /// What the next [`Self::poll`] writes to DRIVE (heartbeat excepted).
    pub fn drive_report(&self) -> &DriveReport {
        &self.report
    }

    /// The card's heartbeat as last judged.
    pub fn card_liveness(&self) -> Liveness {
        self.card_monitor.liveness()
    }

    /// The drive cycle's supervision step: write DRIVE (a new heartbeat, the fault / warning
    /// reports, the extended diagnosis), read CARD, judge the card's heartbeat (a CARD that
    /// cannot be read counts as unchanged, so a dead link is a lost card too) and report the
    /// card → drive events since the last poll. Call it every drive cycle, well within the
    /// card's drive timeout.
    pub fn poll(&mut self, now: Instant) -> Poll {
        let mut error = None;
        if self.has(cap::DRIVE_REPORTS) {
            self.heartbeat = next_seq(self.heartbeat);
            error = self.write_drive().err();
        }
        let report = if self.has(cap::CARD_EVENTS) {
            match self.read(&codec::CARD) {
                Ok((_, r)) => Some(r),
                Err(e) => {
                    error = error.or(Some(e));
                    None
                }
            }
        } else {
            None
        };
        let seen = report.map(|r| (r.heartbeat, r.events, r.boot_id));
        self.observe_card(now, seen, report, error)
    }

    /// Write DRIVE whole: the report with the heartbeat as it is now, the next counter (the
    /// block path of [`Self::poll`] and a changed report in [`Self::cycle`]).
    fn write_drive(&mut self) -> Result<u16, Error> {
        let mut report = self.report;
        report.heartbeat = self.heartbeat;
        let mut seq = self.seq_drive;
        let r = self.write(&codec::DRIVE, &report, &mut seq);
        self.seq_drive = seq;
        if r.is_ok() {
            self.report_written = Some(self.report);
        }
        r
    }

    /// The card part of a poll or a cycle: the heartbeat judged (`card` = heartbeat, event
    /// counters and boot id as read now; `None`: not read, counts as unchanged), a new
    /// BOOT_ID handled ([`Poll::card_restarted`]), the events since the last read.
    fn observe_card(
        &mut self,
        now: Instant,
        card: Option<(u16, [u8; CARD_EVENT_COUNT], u16)>,
        report: Option<CardReport>,
        mut error: Option<Error>,
    ) -> Poll {
        let mut events = CardEvents::default();
        let mut card_restarted = false;
        if let Some((heartbeat, counters, boot_id)) = card {
            self.card_heartbeat = heartbeat;
            if boot_id != 0 && self.boot_id != 0 && boot_id != self.boot_id {
                card_restarted = true;
                // The restarted card's counters start again: resynchronise.
                self.events_seen = None;
                if let Err(e) = self.card_restart() {
                    error = error.or(Some(e));
                }
            }
            self.boot_id = boot_id;
            if let Some(seen) = self.events_seen {
                for (i, c) in events.counts.iter_mut().enumerate() {
                    *c = counters[i].wrapping_sub(seen[i]);
                }
            }
            self.events_seen = Some(counters);
        }
        let before = self.card_monitor.liveness();
        let card = self.card_monitor.observe(now, self.card_heartbeat);
        let card_lost = card == Liveness::Lost && before != Liveness::Lost;
        let card_returned = card == Liveness::Alive && self.card_lost;
        if card_lost {
            self.card_lost = true;
            // A card that comes back may have restarted its counters: read MBX_REQ whole.
            self.request_block_seq = 0;
            self.stats.card_losses = self.stats.card_losses.wrapping_add(1);
        }
        if card_returned {
            self.card_lost = false;
        }
        Poll { card, card_lost, card_returned, events, card_restarted, report, error }
    }

    /// One drive cycle in one exchange (issue 16 item 2): the drive's heartbeat and `state`
    /// (DRIVE_STATE, sized to its extra words) out; the card's heartbeat, flags, events,
    /// boot id, communication state and the newest drive-neutral command (DRIVE_CMD, sized
    /// to the telegram) in. Over the SPI frames this is the CYCLIC exchange: one transaction
    /// per cycle in the steady state, two at most (`docs/SPI.md`); a changed fault / warning
    /// report or extended diagnosis adds one DRIVE write. The mailbox rides along: when the
    /// reply's events say MBX_REQ changed, the next requests ask its fragments, which
    /// [`Self::fetch_request`] / [`Self::serve_parameters`] take without a block access, and
    /// an answer from [`Self::respond`] goes to MBX_RSP in request fragments, each sized to
    /// what the telegram leaves of [`Options::cyclic_bytes`] (a request or answer longer than
    /// one fragment takes several cycles, never a block access). A transport without CYCLIC
    /// (a dual-port RAM) does the same with block accesses ([`Self::poll`],
    /// [`Self::status`], [`Self::read_command`], [`Self::write_state`]).
    pub fn cycle(&mut self, now: Instant, state: &DriveStateImage) -> Cycle {
        let needed = cap::CARD_EVENTS | cap::DRIVE_REPORTS | cap::DRIVE_CMD | cap::DRIVE_STATE;
        if self.has(needed) {
            if let Some(c) = self.cycle_cyclic(now, state) {
                return c;
            }
        }
        let poll = self.poll(now);
        let comm = self.status().ok().map(|s| s.comm);
        let command = self.read_command().ok();
        let mut poll = poll;
        if let Err(e) = self.write_state(state) {
            poll.error = poll.error.or(Some(e));
        }
        self.mailbox_hint = None;
        self.fragment = None;
        self.req_in = None;
        Cycle { poll, command, comm, cyclic: false }
    }

    /// [`Self::cycle`] over a transport with CYCLIC (`None`: it has none).
    fn cycle_cyclic(&mut self, now: Instant, state: &DriveStateImage) -> Option<Cycle> {
        use crate::dpm::spi::{CRC_LEN, REPLY_HEADER, REQUEST_HEADER};
        let mut error = None;
        let mut drive_seq = next_seq(self.seq_drive);
        self.heartbeat = next_seq(self.heartbeat);
        if self.report_written != Some(self.report) {
            // The report changed: DRIVE whole this cycle (with the new heartbeat).
            error = self.write_drive().err();
            drive_seq = 0;
        }
        let state_seq = next_seq(self.seq_state);
        let mut blk = [0u8; layout::drive_state::LEN];
        if codec::DRIVE_STATE.encode(state, state_seq, &mut blk).is_err() {
            return None;
        }
        let words = usize::from(blk[layout::drive_state::EXTRA_COUNT]);
        let n = if words == 0 && state.inputs_seq == 0 {
            cyclic::STATE_BASE
        } else {
            layout::drive_state::EXTRA - layout::drive_state::FLAGS + 2 * words
        };
        // The mailbox fragments get what the telegram leaves of the transaction, each way.
        let room =
            |used: usize| self.opts.cyclic_bytes.saturating_sub(used).clamp(cyclic::MIN_FRAGMENT, cyclic::MAX_FRAGMENT);
        let rsp_room = room(REQUEST_HEADER + cyclic::REQUEST_FIXED + n + CRC_LEN);
        let req_room = room(REPLY_HEADER + cyclic::REPLY_FIXED + self.command_len + CRC_LEN);
        let req_asked = match &self.req_in {
            Some(a) => a.wanted(req_room),
            // MBX_REQ changed (or not known yet): its first fragment comes with the reply.
            None if self.has(cap::MAILBOX) && self.opts.cyclic_mailbox && self.mailbox_hint != Some(false) => {
                (0, req_room as u8)
            }
            None => (0, 0),
        };
        let flags = layout::drive_state::FLAGS;
        let rsp = self.rsp_out.as_mut().map_or((0, &[][..]), |r| r.fragment(rsp_room));
        let sent = Carried { req: req_asked, rsp: (rsp.0, rsp.1.len() as u8) };
        let req = cyclic::CyclicRequest {
            heartbeat: self.heartbeat,
            drive_seq,
            state_seq,
            state: &blk[flags..flags + n],
            rsp,
            req: req_asked,
        };
        let mut out = [0u8; cyclic::MAX_REPLY_DATA];
        let r = self.transport.cyclic(&req, &mut out)?;
        // The counters advance even if the exchange failed (the card may have applied it).
        if drive_seq != 0 {
            self.seq_drive = drive_seq;
        }
        self.seq_state = state_seq;
        let before = core::mem::replace(&mut self.carried, sent);
        let (reply, answered) = match r {
            Ok(k) => (cyclic::CyclicReply::decode(&out[..k.len]), if k.previous { before } else { sent }),
            Err(e) => {
                error = error.or(Some(self.transport_error(e)));
                (None, sent)
            }
        };
        let Some(reply) = reply else {
            // Whatever was not confirmed goes again.
            if let Some(r) = self.rsp_out.as_mut() {
                r.next = r.confirmed;
            }
            self.mailbox_hint = None;
            let poll = self.observe_card(now, None, None, error.or(Some(Error::Transport(TransportError::Corrupt))));
            return Some(Cycle { poll, command: None, comm: None, cyclic: true });
        };
        self.command_len = reply.command.len();
        let changed = reply.events & (1u16 << MBX_REQ_BLOCK) != 0;
        self.mailbox_hint = Some(changed);
        self.rsp_confirmed(answered.rsp);
        self.req_fragment(answered.req, reply.request, changed);
        let command = if reply.command_seq != 0 {
            let mut b = [0u8; layout::drive_cmd::LEN];
            let c = reply.command;
            b[..2].copy_from_slice(&reply.command_seq.to_be_bytes());
            b[layout::drive_cmd::FLAGS..layout::drive_cmd::FLAGS + c.len()].copy_from_slice(c);
            b[layout::drive_cmd::SEQ_TAIL..].copy_from_slice(&reply.command_seq.to_be_bytes());
            codec::DRIVE_CMD.decode(&b).ok()
        } else {
            None
        };
        let comm = CommState::from_code(reply.comm_state);
        let seen = Some((reply.card_heartbeat, reply.card_events, reply.boot_id));
        let poll = self.observe_card(now, seen, None, error);
        Some(Cycle { poll, command, comm, cyclic: true })
    }

    // -----------------------------------------------------------------------------------
    // Parameter mailbox

    /// The reply to a request that carried the MBX_RSP fragment `(off, len)` came back OK: the
    /// fragment is applied. The confirmed tail completes the response.
    fn rsp_confirmed(&mut self, (off, len): (u8, u8)) {
        let Some(r) = self.rsp_out.as_mut() else { return };
        let (off, len) = (usize::from(off), usize::from(len));
        if len == 0 {
            return;
        }
        if off == RspFragments::TAIL && r.confirmed >= r.len {
            self.rsp_out = None;
            self.stats.responses = self.stats.responses.wrapping_add(1);
        } else if off <= r.confirmed && off + len <= r.len {
            r.confirmed = r.confirmed.max(off + len);
        }
    }

    /// A reply's MBX_REQ fragment `f` for the asked `(off, len)` (`changed`: the reply's
    /// events say MBX_REQ changed since the host read its head). A fragment at offset 0
    /// starts a request; the next ones extend it; a one-fragment request is whole, a longer
    /// one once the tail fragment names its head.
    fn req_fragment(&mut self, (off, len): (u8, u8), f: &[u8], changed: bool) {
        use layout::mbx_req;
        let (off, len) = (usize::from(off), usize::from(len));
        if len == 0 || f.len() != len {
            // Not asked, or the card was writing the block: ask again. A new request
            // replaced the one being assembled: start again from offset 0.
            if changed && self.req_in.as_ref().is_some_and(|a| a.have > 0) {
                self.req_in = None;
            }
            return;
        }
        if off == 0 {
            let mut a = ReqFragments { block: [0; mbx_req::LEN], have: len, fragments: 1 };
            a.block[..len].copy_from_slice(f);
            self.req_in = Some(a);
        } else if changed {
            // The head read with offset 0 is no longer the block's.
            self.req_in = None;
            return;
        } else if let Some(a) = self.req_in.as_mut() {
            if off == mbx_req::SEQ_TAIL && len == 2 && a.have >= a.need() {
                if f != &a.block[..2] {
                    // Fragments of two requests: read it again from offset 0.
                    self.req_in = None;
                    self.mailbox_hint = None;
                    return;
                }
                a.fragments = 1;
            } else if off == a.have && off + len <= mbx_req::SEQ_TAIL {
                a.block[off..off + len].copy_from_slice(f);
                a.have += len;
                a.fragments = a.fragments.saturating_add(1);
            }
        }
        let Some(a) = self.req_in.as_ref() else { return };
        if a.have < mbx_req::VALUES || a.have < a.need() || a.fragments != 1 {
            return;
        }
        let mut b = a.block;
        b.copy_within(mbx_req::SEQ_HEAD..mbx_req::SEQ_HEAD + 2, mbx_req::SEQ_TAIL);
        self.req_in = None;
        match codec::MBX_REQ.decode(&b) {
            Ok(r) => self.fragment = Some(r),
            // Not a request this host understands: the block tells (a block read).
            Err(_) => self.mailbox_hint = None,
        }
    }

    /// A new request in MBX_REQ, once (`None`: none, or already taken). The answer goes back
    /// with [`Self::respond`]. After a [`Self::cycle`] over the CYCLIC exchange the request
    /// comes in a mailbox fragment of the exchange (issue 16 item 5): no block access; the
    /// request may take several fragments (several cycles).
    pub fn fetch_request(&mut self) -> Result<Option<MailboxRequest>, Error> {
        self.require(cap::MAILBOX)?;
        match self.fragment.take() {
            Some((seq, req)) => {
                self.request_block_seq = seq;
                return Ok(self.take_request(req));
            }
            // The last CYCLIC reply said MBX_REQ is unchanged since the host read it, or
            // changed: its fragments come with the next replies.
            None if self.mailbox_hint.is_some() && self.opts.cyclic_mailbox => return Ok(None),
            None => {}
        }
        // The card starts every write of MBX_REQ with a new SEQ_HEAD: while it is the value
        // of the last consistent read, the block holds what was read then (no new request),
        // and two bytes answer instead of the whole block (the drive polls every cycle).
        if self.request_block_seq != 0 {
            match self.read_u16(codec::MBX_REQ.start()) {
                Ok(head) if head == self.request_block_seq => return Ok(None),
                Ok(_) => {}
                Err(e) => return Err(self.transport_error(e)),
            }
        }
        let (seq, req) = self.read(&codec::MBX_REQ)?;
        self.request_block_seq = seq;
        Ok(self.take_request(req))
    }

    /// `req` (MBX_REQ as read) if it is a new request.
    fn take_request(&mut self, req: Option<MailboxRequest>) -> Option<MailboxRequest> {
        match req {
            Some(r) if r.id != self.request_seen => {
                self.request_seen = r.id;
                self.request_open = Some(r.id);
                self.stats.requests = self.stats.requests.wrapping_add(1);
                Some(r)
            }
            _ => None,
        }
    }

    /// The request taken and not answered yet.
    pub fn open_request(&self) -> Option<u16> {
        self.request_open
    }

    /// Answer request `id`: written only while it is still the card's current request (else
    /// [`Error::StaleResponse`], and the new request is there to be fetched), so a late answer
    /// can never overwrite the answer to a newer request; the card, for its part, takes a
    /// response only when its `REQ_ID` names the outstanding request.
    pub fn respond(&mut self, id: u16, outcome: Result<ParamValues, ParamError>) -> Result<(), Error> {
        self.require(cap::MAILBOX)?;
        // Over the CYCLIC exchange the last reply says whether MBX_REQ changed since the
        // request was taken; else (or when it did) the block tells.
        let current = if self.mailbox_hint == Some(false)
            && self.opts.cyclic_mailbox
            && self.fragment.is_none()
            && self.req_in.is_none()
            && self.request_seen == id
        {
            id
        } else {
            let (_, req) = self.read(&codec::MBX_REQ)?;
            req.map_or(0, |r| r.id)
        };
        if current != id {
            self.stats.stale_responses = self.stats.stale_responses.wrapping_add(1);
            if self.request_open == Some(id) {
                self.request_open = None;
            }
            return Err(Error::StaleResponse { id, current });
        }
        let rsp = MailboxResponse { id, outcome };
        if self.mailbox_hint.is_some() && self.opts.cyclic_mailbox {
            // CYCLIC: through MBX_RSP fragments.
            let mut block = [0u8; layout::mbx_rsp::LEN];
            let seq = next_seq(self.seq_rsp);
            let values = outcome.map_or(0, |v| v.bytes().len());
            let len = layout::mbx_rsp::VALUES + values;
            if codec::MBX_RSP.encode(&rsp, seq, &mut block).is_ok() {
                self.seq_rsp = seq;
                self.rsp_out = Some(RspFragments { block, len, confirmed: 0, next: 0 });
                self.request_open = None;
                return Ok(());
            }
        }
        self.rsp_out = None;
        let mut seq = self.seq_rsp;
        let r = self.write(&codec::MBX_RSP, &rsp, &mut seq);
        self.seq_rsp = seq;
        r?;
        self.request_open = None;
        self.stats.responses = self.stats.responses.wrapping_add(1);
        Ok(())
    }

    /// Fetch a new request and hand it to `server`; an immediate answer is written at once.
    /// Returns the id of the request taken (`None`: nothing new).
    pub fn serve_parameters(&mut self, server: &mut impl ParameterServer) -> Result<Option<u16>, Error> {
        let Some(req) = self.fetch_request()? else { return Ok(None) };
        if let Answer::Now(outcome) = server.request(&req) {
            self.respond(req.id, outcome)?;
        }
        Ok(Some(req.id))
    }

    // -----------------------------------------------------------------------------------
    // Block access

    fn require(&self, capabilities: u32) -> Result<(), Error> {
        if self.has(capabilities) {
            Ok(())
        } else {
            Err(Error::NotSupported(capabilities & !self.header.capabilities))
        }
    }

    fn transport_error(&mut self, e: TransportError) -> Error {
        self.stats.transport_errors = self.stats.transport_errors.wrapping_add(1);
        Error::Transport(e)
    }

    fn read_u16(&mut self, at: usize) -> Result<u16, TransportError> {
        let mut b = [0u8; 2];
        self.transport.read(at as u16, &mut b)?;
        Ok(u16::from_be_bytes(b))
    }

    /// Read a block in one ascending pass; a torn read is repeated up to
    /// `read_attempts` times and never returned.
    fn read<V>(&mut self, c: &BlockCodec<V>) -> Result<(u16, V), Error> {
        let mut buf = [0u8; MAX_BLOCK];
        let b = &mut buf[..c.len()];
        let mut torn = Torn { head: 0, tail: 0 };
        for _ in 0..self.opts.read_attempts.max(1) {
            if let Err(e) = self.transport.read(c.start() as u16, b) {
                return Err(self.transport_error(e));
            }
            match c.decode(b) {
                Ok(v) => return Ok(v),
                Err(BlockError::Torn(t)) => {
                    torn = t;
                    self.stats.torn_retries = self.stats.torn_retries.wrapping_add(1);
                }
                // `b` has the block's length by construction.
                Err(BlockError::Length { .. }) => return Err(Error::Transport(TransportError::OutOfRange)),
            }
        }
        self.stats.torn_failures = self.stats.torn_failures.wrapping_add(1);
        Err(Error::Torn(torn))
    }

    /// Write a block in one ascending pass with the next counter after `*seq` (advanced even
    /// if the transport fails: a half-written block is never completed under the same number).
    fn write<V>(&mut self, c: &BlockCodec<V>, value: &V, seq: &mut u16) -> Result<u16, Error> {
        let mut buf = [0u8; MAX_BLOCK];
        let b = &mut buf[..c.len()];
        *seq = next_seq(*seq);
        if c.encode(value, *seq, b).is_err() {
            return Err(Error::Transport(TransportError::OutOfRange));
        }
        match self.transport.write(c.start() as u16, b) {
            Ok(()) => Ok(*seq),
            Err(e) => Err(self.transport_error(e)),
        }
    }
}
