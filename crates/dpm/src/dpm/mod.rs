//! The dual-port memory (DPM) image: what the card and the drive's control board share
//! (ARCHITECTURE §5). Layout version 3 — process data both ways, a status block, and (appended
//! to version 1) identification, heartbeats and events both ways, configuration from the
//! drive and the parameter mailbox, and (appended in version 3) the drive-neutral command and
//! status ([`layout`] is the one source of truth for every offset; `docs/DPM.md` is generated
//! from it; [`codec`] gives the block codecs on raw bytes to a host behind a transport).
//!
//! [`Dpm`] is a plain byte array. The card side ([`CardSide`], via [`Dpm::card`]) writes the
//! status and the master's outputs and reads the drive's inputs; the host side
//! ([`HostSide`], via [`Dpm::host`]) is what the drive's control board does with the same
//! bytes (the simulated drive in `pbcard_sim::drive` uses it; a transport such as SPI moves
//! [`Dpm::as_bytes`] ranges). [`Link`] moves data between a [`Node`](crate::node::Node)
//! and the image.
//!
//! ## Tear-free exchange (sequenced blocks)
//!
//! Each block that changes at run time (STATUS, OUTPUTS, INPUTS) starts with `SEQ_HEAD` and ends
//! with `SEQ_TAIL`, two copies of one 16-bit sequence counter (1, 2, … 65535, 1, …; 0 = never
//! written). One rule fixes the order, because a transport moves the host's accesses in
//! ascending address order:
//!
//! * **The host reads and writes a block in one ascending pass.** It writes `SEQ_HEAD = n`,
//!   the payload, `SEQ_TAIL = n`; it reads `SEQ_HEAD`, the payload, `SEQ_TAIL`.
//! * **The card goes the other way round.** It writes `SEQ_TAIL = n` first, then the payload,
//!   then `SEQ_HEAD = n`; it reads `SEQ_TAIL` first, then the payload, then `SEQ_HEAD`.
//!
//! A reader whose two counter reads differ saw a write in progress ([`Torn`]) and tries again
//! later; equal counters mean the payload it read belongs to write *n* entirely (the counter
//! the writer writes first is the one the reader reads last). A changed counter also tells
//! the reader that the block is new. `tests_v2::every_interleaving_reads_whole_or_torn`
//! enumerates every interleaving of one or two writes with one read, both directions, block
//! sizes 5..=8, and checks that a read is either torn or one whole image; the same enumeration
//! catches a wrong order (`the_enumeration_catches_a_wrong_order`).
//!
//! ## Layout version 2
//!
//! IDENT (card type, firmware, ident number, serial), CARD (card heartbeat, configuration
//! acknowledge, card → drive event counters), DRIVE (drive heartbeat, fault / warning reports,
//! extended diagnosis), CONFIG (taken over only outside data exchange) and the parameter
//! mailbox ([`mailbox`]: request id, timeout, late answers ignored; [`params`]: the drive's
//! parameters through it as a table). [`Link`] supervises the
//! drive's heartbeat; [`HeartbeatMonitor`] is what the drive uses on the card's.
//!
//! ## Layout version 3
//!
//! DRIVE_CMD (card → host): the drive-neutral [`DriveCommand`](crate::profile::drive_if::DriveCommand)
//! of the profile layer with the operate mode, the active telegram, the OUTPUTS counter it was
//! made from and up to 16 raw PZD output words ([`DriveCommandImage`]); DRIVE_STATE (host →
//! card): the drive-neutral [`DriveStatus`](crate::profile::drive_if::DriveStatus) and up to 16 raw
//! PZD input words ([`DriveStateImage`]). Capability bits [`layout::cap::DRIVE_CMD`] and
//! [`layout::cap::DRIVE_STATE`].
//!
//! ## Codings shown to the drive
//!
//! * Communication state: [`CommState`], the CFW500 manual's P0740 values.
//! * Baud rate: P0963 ([`Baudrate::p0963_code`], [`BAUD_NOT_DETECTED`] = 5).
//! * Active telegram: [`Telegram`] — PROFIdrive standard telegram number (P922), PPO type, or
//!   a manufacturer's telegram tagged with its [`Family`].

mod blocks;
pub mod c_header;
pub mod codec;
pub mod host;
pub mod layout;
mod link;
pub mod mailbox;
pub mod params;
pub mod spi;

pub use blocks::{
    CardEvent, CardFlags, CardReport, ConfigResult, DriveCommandImage, DriveReport, DriveStateImage, HeartbeatMonitor,
    HostConfig, Identity, Liveness, MailboxRequest, MailboxResponse, ParamValues, PzdWords, RequestKind, CARD_TYPE,
};
pub use link::{Link, LinkStats, NodeSnapshot, NodeUpdate, USER_PRM_CAPACITY, ZSW1_FAULT};
pub use mailbox::{Mailbox, MailboxBusy, MailboxServer, MailboxStats};
pub use params::{MailboxParams, ParamCache};

use crate::dp::diag::Status1;
use crate::dp::{DpSlave, DpState};
use crate::time::Baudrate;
use layout::{pd, status, PD_CAPACITY};

/// Size of the image in bytes.
pub const IMAGE_SIZE: usize = layout::IMAGE_SIZE;

/// P0963 value "not detected" (CFW500 manual, P0963).
pub const BAUD_NOT_DETECTED: u8 = 5;

/// The P0963 code of a detected rate, or [`BAUD_NOT_DETECTED`].
pub const fn p0963(rate: Option<Baudrate>) -> u8 {
    match rate {
        Some(r) => r.p0963_code(),
        None => BAUD_NOT_DETECTED,
    }
}

/// The rate a P0963 code names (`None` for "not detected", "reserved" and unknown codes).
pub fn baudrate_from_p0963(code: u8) -> Option<Baudrate> {
    Baudrate::ALL.into_iter().find(|r| r.p0963_code() == code)
}

/// A reader saw a block while it was being written: its two sequence counters differ. Read
/// again later.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct Torn {
    /// `SEQ_HEAD` as read.
    pub head: u16,
    /// `SEQ_TAIL` as read.
    pub tail: u16,
}

/// PROFIBUS communication state in the coding of the CFW500 manual's P0740 (Table 4.5).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[repr(u8)]
pub enum CommState {
    /// 0: the PROFIBUS interface is not running (image created, stack not started).
    Inactive = 0,
    /// 1: the interface failed to initialise (set by the platform).
    InitError = 1,
    /// 2: running and configured, but no cyclic exchange with a master.
    Offline = 2,
    /// 3: the last Chk_Cfg matched no module (Cfg_Fault).
    ConfigError = 3,
    /// 4: the last Set_Prm was refused (Prm_Fault).
    ParameterError = 4,
    /// 5: in data exchange, the master is in Clear (Global_Control Clear_Data or fail-safe).
    ClearMode = 5,
    /// 6: cyclic data exchange with the master.
    Online = 6,
}

impl CommState {
    /// Every value, in code order.
    pub const ALL: [CommState; 7] = [
        CommState::Inactive,
        CommState::InitError,
        CommState::Offline,
        CommState::ConfigError,
        CommState::ParameterError,
        CommState::ClearMode,
        CommState::Online,
    ];

    /// The state a running slave is in.
    pub fn of(slave: &DpSlave) -> CommState {
        let s1 = slave.standard_diag().status1;
        match slave.state() {
            DpState::DataExch if slave.is_clear() => CommState::ClearMode,
            DpState::DataExch => CommState::Online,
            _ if s1.contains(Status1::PRM_FAULT) => CommState::ParameterError,
            _ if s1.contains(Status1::CFG_FAULT) => CommState::ConfigError,
            _ => CommState::Offline,
        }
    }

    /// The P0740 code.
    pub const fn code(self) -> u8 {
        self as u8
    }

    /// The state of a P0740 code.
    pub fn from_code(code: u8) -> Option<CommState> {
        CommState::ALL.get(code as usize).copied()
    }

    /// The manual's text.
    pub const fn text(self) -> &'static str {
        match self {
            CommState::Inactive => "inactive",
            CommState::InitError => "interface initialization error",
            CommState::Offline => "offline",
            CommState::ConfigError => "configuration data error",
            CommState::ParameterError => "parameterization data error",
            CommState::ClearMode => "clear mode",
            CommState::Online => "online",
        }
    }
}

/// The process-data layout and its manufacturer family are profile concepts
/// ([`crate::profile::selection`]); the DPM carries their codes ([`Telegram::code`]).
pub use crate::profile::selection::{Family, Telegram};

bitflags::bitflags! {
    /// `STATUS.FLAGS`.
    #[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
    pub struct StatusFlags: u8 {
        /// The master is in Clear (Clear_Data or fail-safe zero-length outputs).
        const CLEAR = 1 << 0;
        /// Sync mode.
        const SYNC = 1 << 1;
        /// Freeze mode.
        const FREEZE = 1 << 2;
        /// The DP watchdog is on.
        const WATCHDOG_ON = 1 << 3;
        /// The address may no longer be changed by Set_Slave_Add (No_Add_Chg).
        const ADDRESS_LOCKED = 1 << 4;
    }
}

bitflags::bitflags! {
    /// `OUTPUTS.FLAGS` / `INPUTS.FLAGS`.
    #[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
    pub struct PdFlags: u8 {
        /// OUTPUTS: the card is in data exchange, the data is the master's. Outside data
        /// exchange the data is all zero.
        const DATA_EXCHANGE = 1 << 0;
        /// OUTPUTS: the master is in Clear; the data is all zero.
        const CLEAR = 1 << 1;
    }
}

/// The status block's content.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Status {
    /// Communication state (P0740).
    pub comm: CommState,
    /// Detected baud rate, P0963 coding ([`p0963`]).
    pub baud: u8,
    /// Own station address.
    pub station_address: u8,
    /// The master holding the lock.
    pub master_address: Option<u8>,
    /// Active telegram.
    pub telegram: Telegram,
    /// DP state.
    pub dp_state: DpState,
    /// Flags.
    pub flags: StatusFlags,
    /// DP watchdog in ms (0 = off).
    pub watchdog_ms: u16,
    /// Data_Exchange requests answered.
    pub data_exchanges: u32,
    /// Set_Prm refused.
    pub prm_faults: u16,
    /// Chk_Cfg refused.
    pub cfg_faults: u16,
    /// DP watchdog expiries.
    pub watchdog_expiries: u16,
    /// Corrupt telegrams.
    pub corrupt_frames: u16,
}

impl Status {
    /// The status of an image nobody has started: P0740 "inactive", baud not detected.
    pub const INACTIVE: Status = Status {
        comm: CommState::Inactive,
        baud: BAUD_NOT_DETECTED,
        station_address: 0,
        master_address: None,
        telegram: Telegram::None,
        dp_state: DpState::WaitPrm,
        flags: StatusFlags::empty(),
        watchdog_ms: 0,
        data_exchanges: 0,
        prm_faults: 0,
        cfg_faults: 0,
        watchdog_expiries: 0,
        corrupt_frames: 0,
    };

    fn encode(&self, b: &mut [u8]) {
        b[status::COMM_STATE] = self.comm.code();
        b[status::BAUD] = self.baud;
        b[status::STATION_ADDRESS] = self.station_address;
        b[status::MASTER_ADDRESS] = self.master_address.unwrap_or(0xFF);
        put16(b, status::TELEGRAM, self.telegram.code());
        b[status::DP_STATE] = match self.dp_state {
            DpState::WaitPrm => 0,
            DpState::WaitCfg => 1,
            DpState::DataExch => 2,
        };
        b[status::FLAGS] = self.flags.bits();
        put16(b, status::WATCHDOG_MS, self.watchdog_ms);
        b[status::DATA_EXCHANGES..status::DATA_EXCHANGES + 4].copy_from_slice(&self.data_exchanges.to_be_bytes());
        put16(b, status::PRM_FAULTS, self.prm_faults);
        put16(b, status::CFG_FAULTS, self.cfg_faults);
        put16(b, status::WATCHDOG_EXPIRIES, self.watchdog_expiries);
        put16(b, status::CORRUPT_FRAMES, self.corrupt_frames);
    }

    fn decode(b: &[u8]) -> Status {
        let mut dx = [0u8; 4];
        dx.copy_from_slice(&b[status::DATA_EXCHANGES..status::DATA_EXCHANGES + 4]);
        Status {
            // An unknown code (a newer card) reads as "init error": something is wrong.
            comm: CommState::from_code(b[status::COMM_STATE]).unwrap_or(CommState::InitError),
            baud: b[status::BAUD],
            station_address: b[status::STATION_ADDRESS],
            master_address: match b[status::MASTER_ADDRESS] {
                0xFF => None,
                a => Some(a),
            },
            telegram: Telegram::from_code(get16(b, status::TELEGRAM)),
            dp_state: match b[status::DP_STATE] {
                1 => DpState::WaitCfg,
                2 => DpState::DataExch,
                _ => DpState::WaitPrm,
            },
            flags: StatusFlags::from_bits_retain(b[status::FLAGS]),
            watchdog_ms: get16(b, status::WATCHDOG_MS),
            data_exchanges: u32::from_be_bytes(dx),
            prm_faults: get16(b, status::PRM_FAULTS),
            cfg_faults: get16(b, status::CFG_FAULTS),
            watchdog_expiries: get16(b, status::WATCHDOG_EXPIRIES),
            corrupt_frames: get16(b, status::CORRUPT_FRAMES),
        }
    }
}

/// One process-data image as a block holds it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ProcessData {
    /// The block's sequence counter (0 = never written).
    pub seq: u16,
    /// The layout of [`Self::bytes`].
    pub telegram: Telegram,
    /// Flags.
    pub flags: PdFlags,
    len: u8,
    data: [u8; PD_CAPACITY],
}

impl ProcessData {
    /// Process data for `telegram` (longer data is cut to [`layout::PD_CAPACITY`]); `seq` is
    /// set when written.
    pub fn new(telegram: Telegram, flags: PdFlags, bytes: &[u8]) -> Self {
        let n = bytes.len().min(PD_CAPACITY);
        let mut data = [0u8; PD_CAPACITY];
        data[..n].copy_from_slice(&bytes[..n]);
        ProcessData { seq: 0, telegram, flags, len: n as u8, data }
    }

    /// The valid bytes.
    pub fn bytes(&self) -> &[u8] {
        &self.data[..self.len as usize]
    }

    /// Word `i` (big-endian; 0 beyond the valid bytes).
    pub fn word(&self, i: usize) -> u16 {
        match self.bytes().get(2 * i..2 * i + 2) {
            Some(w) => u16::from_be_bytes([w[0], w[1]]),
            None => 0,
        }
    }

    fn encode(&self, b: &mut [u8]) {
        put16(b, pd::TELEGRAM, self.telegram.code());
        b[pd::LEN] = self.len;
        b[pd::FLAGS] = self.flags.bits();
        b[pd::DATA..pd::DATA + PD_CAPACITY].copy_from_slice(&self.data);
    }

    fn decode(b: &[u8]) -> ProcessData {
        let len = b[pd::LEN].min(PD_CAPACITY as u8);
        let mut data = [0u8; PD_CAPACITY];
        data[..len as usize].copy_from_slice(&b[pd::DATA..pd::DATA + len as usize]);
        ProcessData {
            seq: get16(b, pd::SEQ_HEAD),
            telegram: Telegram::from_code(get16(b, pd::TELEGRAM)),
            flags: PdFlags::from_bits_retain(b[pd::FLAGS]),
            len,
            data,
        }
    }
}

/// The DPM image.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Dpm {
    image: [u8; IMAGE_SIZE],
}

impl Default for Dpm {
    fn default() -> Self {
        Self::new()
    }
}

impl Dpm {
    /// A fresh image: header written, status [`Status::INACTIVE`], no process data (every
    /// sequence counter 0), IDENT of this firmware without an ident number (0:
    /// [`with_identity`](Self::with_identity) gives the product's; the card: `card::IDENTITY`).
    pub fn new() -> Self {
        let mut image = [0u8; IMAGE_SIZE];
        image[layout::header::MAGIC..layout::header::MAGIC + 4].copy_from_slice(&layout::MAGIC);
        put16(&mut image, layout::header::LAYOUT_VERSION, layout::LAYOUT_VERSION);
        put16(&mut image, layout::header::IMAGE_SIZE, IMAGE_SIZE as u16);
        image[layout::header::CAPABILITIES..layout::header::CAPABILITIES + 4]
            .copy_from_slice(&layout::cap::ALL.to_be_bytes());
        Status::INACTIVE.encode(&mut image[status::START..status::START + status::LEN]);
        Identity::of_product(0).encode(&mut image[layout::ident::START..layout::ident::START + layout::ident::LEN]);
        Dpm { image }
    }

    /// A fresh image with `identity` in IDENT (the platform knows the serial number).
    pub fn with_identity(identity: &Identity) -> Self {
        let mut dpm = Self::new();
        identity.encode(&mut dpm.image[layout::ident::START..layout::ident::START + layout::ident::LEN]);
        dpm
    }

    /// `HEADER.LAYOUT_VERSION`.
    pub fn layout_version(&self) -> u16 {
        get16(&self.image, layout::header::LAYOUT_VERSION)
    }

    /// `HEADER.CAPABILITIES`.
    pub fn capabilities(&self) -> u32 {
        let c = layout::header::CAPABILITIES;
        u32::from_be_bytes([self.image[c], self.image[c + 1], self.image[c + 2], self.image[c + 3]])
    }

    /// The identification block.
    pub fn identity(&self) -> Identity {
        Identity::decode(&self.image[layout::ident::START..layout::ident::START + layout::ident::LEN])
    }

    /// The card block as the host reads it.
    pub fn card_report(&self) -> Result<CardReport, Torn> {
        read_card_report(&self.image)
    }

    /// The drive block as the card reads it.
    pub fn drive_report(&self) -> Result<DriveReport, Torn> {
        read_drive_report(&self.image)
    }

    /// The configuration block as the card reads it, with its sequence counter (0 = never
    /// written).
    pub fn config(&self) -> Result<(u16, HostConfig), Torn> {
        read_config(&self.image)
    }

    /// The mailbox request as the host reads it (`None`: no request yet).
    pub fn request(&self) -> Result<Option<MailboxRequest>, Torn> {
        read_request(&self.image)
    }

    /// The mailbox response as the card reads it, with its sequence counter.
    pub fn response(&self) -> Result<(u16, MailboxResponse), Torn> {
        read_response(&self.image)
    }

    /// DRIVE_CMD as the host reads it, with its sequence counter (0 = never written).
    pub fn drive_command(&self) -> Result<(u16, DriveCommandImage), Torn> {
        read_drive_command(&self.image)
    }

    /// DRIVE_STATE as the card reads it, with its sequence counter (0 = never written).
    pub fn drive_state(&self) -> Result<(u16, DriveStateImage), Torn> {
        read_drive_state(&self.image)
    }

    /// DEVICE (layout 4): the drive's serial number and hardware revision for I&M0, with the
    /// block's counter (0 = never written), as the card reads it.
    pub fn device_ident(&self) -> Result<(u16, crate::dpv1::im::DeviceIdent), Torn> {
        let (s, n) = (layout::device::START, layout::device::LEN);
        card_read(&self.image, s, n).map(|b| (get16(&b, 0), codec::DEVICE_DECODE(&b[..n])))
    }

    /// The raw image (for a transport, a dump, a test).
    pub fn as_bytes(&self) -> &[u8; IMAGE_SIZE] {
        &self.image
    }

    /// The raw image, writable (a transport writing the host's bytes).
    pub fn as_bytes_mut(&mut self) -> &mut [u8; IMAGE_SIZE] {
        &mut self.image
    }

    /// The card's view.
    pub fn card(&mut self) -> CardSide<'_> {
        CardSide { image: &mut self.image }
    }

    /// The host's (drive control board's) view.
    pub fn host(&mut self) -> HostSide<'_> {
        HostSide { image: &mut self.image }
    }

    /// Read the status as the host does (no write access needed).
    pub fn status(&self) -> Result<Status, Torn> {
        read_status(&self.image)
    }

    /// Read the outputs as the host does.
    pub fn outputs(&self) -> Result<ProcessData, Torn> {
        read_outputs(&self.image)
    }

    /// Read the inputs as the card does.
    pub fn inputs(&self) -> Result<ProcessData, Torn> {
        read_inputs(&self.image)
    }
}

/// The card's access to the image: writes STATUS, OUTPUTS, CARD, MBX_REQ and DRIVE_CMD;
/// reads INPUTS, DRIVE, CONFIG, MBX_RSP and DRIVE_STATE.
#[derive(Debug)]
pub struct CardSide<'a> {
    image: &'a mut [u8; IMAGE_SIZE],
}

impl CardSide<'_> {
    /// Write the status block; returns its new sequence counter.
    pub fn write_status(&mut self, s: &Status) -> u16 {
        card_write(self.image, status::START, status::LEN, |b| s.encode(b))
    }

    /// Write the outputs block (the master's process data); returns its new sequence counter.
    ///
    /// Out of line: several tasks call it (footprint, issue 13 item 1).
    #[inline(never)]
    pub fn write_outputs(&mut self, pd: &ProcessData) -> u16 {
        card_write(self.image, layout::outputs::START, pd::LEN_BLOCK, |b| pd.encode(b))
    }

    /// Read the inputs block (the drive's process data).
    pub fn read_inputs(&self) -> Result<ProcessData, Torn> {
        read_inputs(self.image)
    }

    /// Write the card block; returns its new sequence counter.
    ///
    /// Out of line: several tasks call it (footprint, issue 13 item 1).
    #[inline(never)]
    pub fn write_card_report(&mut self, r: &CardReport) -> u16 {
        card_write(self.image, layout::card::START, layout::card::LEN, |b| r.encode(b))
    }

    /// Write the mailbox request (use [`Mailbox::submit`], which assigns the request id).
    pub fn write_request(&mut self, r: &MailboxRequest) -> u16 {
        card_write(self.image, layout::mbx_req::START, layout::mbx_req::LEN, |b| r.encode(b))
    }

    /// Read the drive block.
    pub fn read_drive_report(&self) -> Result<DriveReport, Torn> {
        read_drive_report(self.image)
    }

    /// Read the configuration block with its sequence counter (0 = never written).
    pub fn read_config(&self) -> Result<(u16, HostConfig), Torn> {
        read_config(self.image)
    }

    /// Read the mailbox response with its sequence counter (0 = never written).
    pub fn read_response(&self) -> Result<(u16, MailboxResponse), Torn> {
        read_response(self.image)
    }

    /// Write DRIVE_CMD (after OUTPUTS in the same card cycle, `outputs_seq` = the OUTPUTS
    /// counter the command was made from); returns its new sequence counter.
    pub fn write_drive_command(&mut self, c: &DriveCommandImage) -> u16 {
        card_write(self.image, layout::drive_cmd::START, layout::drive_cmd::LEN, |b| c.encode(b))
    }

    /// Read DRIVE_STATE with its sequence counter (0 = never written).
    pub fn read_drive_state(&self) -> Result<(u16, DriveStateImage), Torn> {
        read_drive_state(self.image)
    }
}

/// The host's (drive control board's) access: reads STATUS, OUTPUTS, IDENT, CARD, MBX_REQ and
/// DRIVE_CMD; writes INPUTS, DRIVE, CONFIG, MBX_RSP and DRIVE_STATE.
#[derive(Debug)]
pub struct HostSide<'a> {
    image: &'a mut [u8; IMAGE_SIZE],
}

impl HostSide<'_> {
    /// Read the status block.
    pub fn read_status(&self) -> Result<Status, Torn> {
        read_status(self.image)
    }

    /// Read the outputs block (the master's process data).
    pub fn read_outputs(&self) -> Result<ProcessData, Torn> {
        read_outputs(self.image)
    }

    /// Write the inputs block (the drive's process data); returns its new sequence counter.
    pub fn write_inputs(&mut self, pd: &ProcessData) -> u16 {
        host_write(self.image, layout::inputs::START, pd::LEN_BLOCK, |b| pd.encode(b))
    }

    /// The identification block.
    pub fn read_identity(&self) -> Identity {
        Identity::decode(&self.image[layout::ident::START..layout::ident::START + layout::ident::LEN])
    }

    /// Read the card block.
    pub fn read_card_report(&self) -> Result<CardReport, Torn> {
        read_card_report(self.image)
    }

    /// Write the drive block; returns its new sequence counter.
    pub fn write_drive_report(&mut self, r: &DriveReport) -> u16 {
        host_write(self.image, layout::drive::START, layout::drive::LEN, |b| r.encode(b))
    }

    /// Write the configuration block; returns its sequence counter (the card acknowledges
    /// it in `CARD.CONFIG_ACK`).
    pub fn write_config(&mut self, c: &HostConfig) -> u16 {
        host_write(self.image, layout::config::START, layout::config::LEN, |b| c.encode(b))
    }

    /// Read the mailbox request (`None`: no request yet).
    pub fn read_request(&self) -> Result<Option<MailboxRequest>, Torn> {
        read_request(self.image)
    }

    /// Write the mailbox response (see [`MailboxServer`]).
    pub fn write_response(&mut self, r: &MailboxResponse) -> u16 {
        host_write(self.image, layout::mbx_rsp::START, layout::mbx_rsp::LEN, |b| r.encode(b))
    }

    /// Read DRIVE_CMD with its sequence counter (0 = never written).
    pub fn read_drive_command(&self) -> Result<(u16, DriveCommandImage), Torn> {
        read_drive_command(self.image)
    }

    /// Write DEVICE (layout 4): the drive's serial number and hardware revision for I&M0.
    pub fn write_device_ident(&mut self, d: &crate::dpv1::im::DeviceIdent) -> u16 {
        host_write(self.image, layout::device::START, layout::device::LEN, |b| codec::DEVICE_ENCODE(d, b))
    }

    /// Write DRIVE_STATE (after INPUTS, `inputs_seq` = the INPUTS counter just written);
    /// returns its new sequence counter.
    pub fn write_drive_state(&mut self, s: &DriveStateImage) -> u16 {
        host_write(self.image, layout::drive_state::START, layout::drive_state::LEN, |b| s.encode(b))
    }
}

/// Largest block (for the readers' local copies).
const MAX_BLOCK: usize = layout::mbx_req::LEN;

const _: () = {
    let mut i = 0;
    while i < layout::BLOCKS.len() {
        assert!(layout::BLOCKS[i].len <= MAX_BLOCK);
        i += 1;
    }
};

const fn next_seq(s: u16) -> u16 {
    if s == u16::MAX {
        1
    } else {
        s + 1
    }
}

fn get16(b: &[u8], at: usize) -> u16 {
    u16::from_be_bytes([b[at], b[at + 1]])
}

fn put16(b: &mut [u8], at: usize, v: u16) {
    b[at..at + 2].copy_from_slice(&v.to_be_bytes());
}

/// The card writes a block: tail first, payload (`fill` gets the whole block; it must leave
/// the two counters alone), head last.
fn card_write(image: &mut [u8; IMAGE_SIZE], start: usize, len: usize, fill: impl FnOnce(&mut [u8])) -> u16 {
    let block = &mut image[start..start + len];
    let seq = next_seq(get16(block, 0));
    put16(block, len - 2, seq);
    fill(block);
    put16(block, 0, seq);
    seq
}

/// The host writes a block in one ascending pass: head, payload (`fill` gets the whole
/// block; it must leave the counters alone), tail.
fn host_write(image: &mut [u8; IMAGE_SIZE], start: usize, len: usize, fill: impl FnOnce(&mut [u8])) -> u16 {
    let block = &mut image[start..start + len];
    let seq = next_seq(get16(block, 0));
    put16(block, 0, seq);
    fill(block);
    put16(block, len - 2, seq);
    seq
}

fn read_card_report(image: &[u8; IMAGE_SIZE]) -> Result<CardReport, Torn> {
    let (s, n) = (layout::card::START, layout::card::LEN);
    host_read(image, s, n).map(|b| CardReport::decode(&b[..n]))
}

fn read_request(image: &[u8; IMAGE_SIZE]) -> Result<Option<MailboxRequest>, Torn> {
    let (s, n) = (layout::mbx_req::START, layout::mbx_req::LEN);
    host_read(image, s, n).map(|b| MailboxRequest::decode(&b[..n]))
}

fn read_drive_command(image: &[u8; IMAGE_SIZE]) -> Result<(u16, DriveCommandImage), Torn> {
    let (s, n) = (layout::drive_cmd::START, layout::drive_cmd::LEN);
    host_read(image, s, n).map(|b| (get16(&b, 0), DriveCommandImage::decode(&b[..n])))
}

fn read_drive_state(image: &[u8; IMAGE_SIZE]) -> Result<(u16, DriveStateImage), Torn> {
    let (s, n) = (layout::drive_state::START, layout::drive_state::LEN);
    card_read(image, s, n).map(|b| (get16(&b, 0), DriveStateImage::decode(&b[..n])))
}

fn read_drive_report(image: &[u8; IMAGE_SIZE]) -> Result<DriveReport, Torn> {
    let (s, n) = (layout::drive::START, layout::drive::LEN);
    card_read(image, s, n).map(|b| DriveReport::decode(&b[..n]))
}

fn read_config(image: &[u8; IMAGE_SIZE]) -> Result<(u16, HostConfig), Torn> {
    let (s, n) = (layout::config::START, layout::config::LEN);
    card_read(image, s, n).map(|b| (get16(&b, 0), HostConfig::decode(&b[..n])))
}

fn read_response(image: &[u8; IMAGE_SIZE]) -> Result<(u16, MailboxResponse), Torn> {
    let (s, n) = (layout::mbx_rsp::START, layout::mbx_rsp::LEN);
    card_read(image, s, n).map(|b| (get16(&b, 0), MailboxResponse::decode(&b[..n])))
}

/// STATUS as the host reads it.
fn read_status(image: &[u8; IMAGE_SIZE]) -> Result<Status, Torn> {
    host_read(image, status::START, status::LEN).map(|b| Status::decode(&b[..status::LEN]))
}

/// OUTPUTS as the host reads it.
fn read_outputs(image: &[u8; IMAGE_SIZE]) -> Result<ProcessData, Torn> {
    host_read(image, layout::outputs::START, pd::LEN_BLOCK).map(|b| ProcessData::decode(&b[..pd::LEN_BLOCK]))
}

/// INPUTS as the card reads it.
fn read_inputs(image: &[u8; IMAGE_SIZE]) -> Result<ProcessData, Torn> {
    card_read(image, layout::inputs::START, pd::LEN_BLOCK).map(|b| ProcessData::decode(&b[..pd::LEN_BLOCK]))
}

/// The card reads a block: tail first, payload, head last.
fn card_read(image: &[u8; IMAGE_SIZE], start: usize, len: usize) -> Result<[u8; MAX_BLOCK], Torn> {
    let block = &image[start..start + len];
    let tail = get16(block, len - 2);
    let mut copy = [0u8; MAX_BLOCK];
    copy[2..len - 2].copy_from_slice(&block[2..len - 2]);
    let head = get16(block, 0);
    put16(&mut copy, 0, head);
    put16(&mut copy, len - 2, tail);
    if head == tail {
        Ok(copy)
    } else {
        Err(Torn { head, tail })
    }
}

/// The host reads a block in one ascending pass.
fn host_read(image: &[u8; IMAGE_SIZE], start: usize, len: usize) -> Result<[u8; MAX_BLOCK], Torn> {
    let mut copy = [0u8; MAX_BLOCK];
    copy[..len].copy_from_slice(&image[start..start + len]);
    let (head, tail) = (get16(&copy, 0), get16(&copy, len - 2));
    if head == tail {
        Ok(copy)
    } else {
        Err(Torn { head, tail })
    }
}

#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_v2;
