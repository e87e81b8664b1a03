//! The blocks of layout versions 2 and 3: identification, the card's and the drive's reports,
//! the configuration from the drive, the parameter mailbox (v2) and the drive-neutral command /
//! status (v3), with their codecs (offsets from [`super::layout`]).

use super::layout::{
    self, card, config, drive, drive_cmd, drive_state, ident, mbx_req, mbx_rsp, EXTRA_WORDS, EXT_DIAG_CAPACITY,
    MBX_CAPACITY, PZD_MAP_WORDS,
};
use super::{get16, put16, Telegram};
use crate::profile::drive_if::{CommandFlags, DriveCommand, DriveStatus, StatusFlags as DriveStatusFlags};
use crate::profile::param::{ErrorValue, Format, ParamError};
use crate::time::{Duration, Instant};

/// `IDENT.CARD_TYPE` of this card (PROFIBUS DP-V1 slave option card).
pub const CARD_TYPE: u16 = 0x0DB1;

const fn parse_u8(s: &str) -> u8 {
    let b = s.as_bytes();
    let mut i = 0;
    let mut v: u32 = 0;
    while i < b.len() {
        v = v * 10 + (b[i] - b'0') as u32;
        i += 1;
    }
    if v > 255 {
        255
    } else {
        v as u8
    }
}

/// The identification block.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Identity {
    /// Card type ([`CARD_TYPE`]).
    pub card_type: u16,
    /// Firmware version: major, minor, patch.
    pub firmware: [u8; 3],
    /// PROFIBUS ident number.
    pub ident_number: u16,
    /// Serial number (0 = not programmed).
    pub serial: u32,
}

impl Identity {
    /// A card of this image (its [`CARD_TYPE`], this crate's version — a product states its
    /// own firmware's with [`with_firmware`](Self::with_firmware)) for the PROFIBUS ident
    /// number `ident_number` (the product's GSD `Ident_Number`; this card: `card::IDENTITY`),
    /// no serial number (the platform sets it).
    pub const fn of_product(ident_number: u16) -> Identity {
        Identity {
            card_type: CARD_TYPE,
            firmware: [
                parse_u8(env!("CARGO_PKG_VERSION_MAJOR")),
                parse_u8(env!("CARGO_PKG_VERSION_MINOR")),
                parse_u8(env!("CARGO_PKG_VERSION_PATCH")),
            ],
            ident_number,
            serial: 0,
        }
    }

    /// The same identity with the firmware version `major.minor.patch` (decimal strings, as
    /// Cargo's `CARGO_PKG_VERSION_*` of the product's crate; each part saturates at 255).
    pub const fn with_firmware(mut self, major: &str, minor: &str, patch: &str) -> Identity {
        self.firmware = [parse_u8(major), parse_u8(minor), parse_u8(patch)];
        self
    }

    pub(super) fn encode(&self, b: &mut [u8]) {
        put16(b, ident::CARD_TYPE, self.card_type);
        b[ident::FW_MAJOR] = self.firmware[0];
        b[ident::FW_MINOR] = self.firmware[1];
        b[ident::FW_PATCH] = self.firmware[2];
        put16(b, ident::IDENT_NUMBER, self.ident_number);
        b[ident::SERIAL..ident::SERIAL + 4].copy_from_slice(&self.serial.to_be_bytes());
    }

    pub(super) fn decode(b: &[u8]) -> Identity {
        Identity {
            card_type: get16(b, ident::CARD_TYPE),
            firmware: [b[ident::FW_MAJOR], b[ident::FW_MINOR], b[ident::FW_PATCH]],
            ident_number: get16(b, ident::IDENT_NUMBER),
            serial: get32(b, ident::SERIAL),
        }
    }
}

bitflags::bitflags! {
    /// `CARD.FLAGS`.
    #[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
    pub struct CardFlags: u8 {
        /// The drive's heartbeat is lost (ZSW1 fault to the master, Stat_Diag, parameter
        /// requests refused).
        const DRIVE_LOST = 1 << 0;
        /// A configuration waits for the cyclic exchange to end.
        const CONFIG_PENDING = 1 << 1;
        /// The card failed (P0740 init error).
        const CARD_FAULT = 1 << 2;
    }
}

/// `CARD.CONFIG_RESULT`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[repr(u8)]
pub enum ConfigResult {
    /// 0: no configuration handled yet.
    None = 0,
    /// 1: taken over.
    Accepted = 1,
    /// 2: valid, waits until no cyclic exchange runs.
    Pending = 2,
    /// 3: refused, invalid content (a field out of range, or a telegram no module of the
    /// card offers); nothing of it applied.
    Refused = 3,
    /// 4: taken over except the station address, which No_Add_Chg (Set_Slave_Add) froze:
    /// the card keeps `STATUS.STATION_ADDRESS`.
    AddressLocked = 4,
}

impl ConfigResult {
    /// The result of a code (unknown codes read as `None`).
    pub const fn from_code(c: u8) -> ConfigResult {
        match c {
            1 => ConfigResult::Accepted,
            2 => ConfigResult::Pending,
            3 => ConfigResult::Refused,
            4 => ConfigResult::AddressLocked,
            _ => ConfigResult::None,
        }
    }
}

/// Card → drive events: index into `CARD.EVENTS`, each a counter the host compares with the
/// value it saw last.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[repr(u8)]
pub enum CardEvent {
    /// The master entered Clear (A138-like).
    ClearMode = 0,
    /// The card left data exchange (A139-like).
    Offline = 1,
    /// The card entered data exchange.
    Online = 2,
    /// The DP watchdog expired (raised with `Offline`: the drive's A139; A140 is the card's
    /// heartbeat lost, seen by the host).
    Watchdog = 3,
    /// A Set_Prm was refused.
    ParameterizationError = 4,
    /// A Chk_Cfg was refused.
    ConfigurationError = 5,
    /// The card failed.
    CardFault = 6,
    /// The drive's heartbeat returned after a loss.
    DriveReturned = 7,
}

impl CardEvent {
    /// Every event, in counter order.
    pub const ALL: [CardEvent; layout::CARD_EVENT_COUNT] = [
        CardEvent::ClearMode,
        CardEvent::Offline,
        CardEvent::Online,
        CardEvent::Watchdog,
        CardEvent::ParameterizationError,
        CardEvent::ConfigurationError,
        CardEvent::CardFault,
        CardEvent::DriveReturned,
    ];
}

/// The card block's content.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct CardReport {
    /// Card heartbeat.
    pub heartbeat: u16,
    /// Flags.
    pub flags: CardFlags,
    /// Result of configuration `config_ack`.
    pub config_result: u8,
    /// The CONFIG sequence counter the result is about.
    pub config_ack: u16,
    /// Event counters, indexed by [`CardEvent`].
    pub events: [u8; layout::CARD_EVENT_COUNT],
    /// Drive heartbeat losses.
    pub drive_losses: u16,
    /// Late / unknown mailbox responses ignored.
    pub late_responses: u16,
    /// Mailbox requests timed out.
    pub mailbox_timeouts: u16,
    /// The card's boot identifier (`CARD.BOOT_ID`: another value on every card start; 0 =
    /// a card that does not show one).
    pub boot_id: u16,
}

impl CardReport {
    /// The counter of `e`.
    pub fn event(&self, e: CardEvent) -> u8 {
        self.events[e as usize]
    }

    /// `config_result` decoded.
    pub fn config_result(&self) -> ConfigResult {
        ConfigResult::from_code(self.config_result)
    }

    pub(super) fn encode(&self, b: &mut [u8]) {
        put16(b, card::HEARTBEAT, self.heartbeat);
        b[card::FLAGS] = self.flags.bits();
        b[card::CONFIG_RESULT] = self.config_result;
        put16(b, card::CONFIG_ACK, self.config_ack);
        b[card::EVENTS..card::EVENTS + layout::CARD_EVENT_COUNT].copy_from_slice(&self.events);
        put16(b, card::DRIVE_LOSSES, self.drive_losses);
        put16(b, card::LATE_RESPONSES, self.late_responses);
        put16(b, card::MAILBOX_TIMEOUTS, self.mailbox_timeouts);
        put16(b, card::BOOT_ID, self.boot_id);
    }

    pub(super) fn decode(b: &[u8]) -> CardReport {
        let mut events = [0u8; layout::CARD_EVENT_COUNT];
        events.copy_from_slice(&b[card::EVENTS..card::EVENTS + layout::CARD_EVENT_COUNT]);
        CardReport {
            heartbeat: get16(b, card::HEARTBEAT),
            flags: CardFlags::from_bits_retain(b[card::FLAGS]),
            config_result: b[card::CONFIG_RESULT],
            config_ack: get16(b, card::CONFIG_ACK),
            events,
            drive_losses: get16(b, card::DRIVE_LOSSES),
            late_responses: get16(b, card::LATE_RESPONSES),
            mailbox_timeouts: get16(b, card::MAILBOX_TIMEOUTS),
            boot_id: get16(b, card::BOOT_ID),
        }
    }
}

/// The drive block's content.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct DriveReport {
    /// Drive heartbeat (0 = not started: the card does not supervise it yet).
    pub heartbeat: u16,
    /// Active fault code (0 = none).
    pub fault_code: u16,
    /// Active warning code (0 = none).
    pub warning_code: u16,
    /// Fault reports.
    pub fault_count: u8,
    /// Warning reports.
    pub warning_count: u8,
    /// The IRQ mask (`DRIVE.IRQ_MASK`): pending-event bits that do not assert the IRQ line.
    pub irq_mask: u16,
    pub(super) ext_diag_len: u8,
    pub(super) ext_diag: [u8; EXT_DIAG_CAPACITY],
}

impl DriveReport {
    /// Nothing reported, heartbeat 0.
    pub const EMPTY: DriveReport = DriveReport {
        heartbeat: 0,
        fault_code: 0,
        warning_code: 0,
        fault_count: 0,
        warning_count: 0,
        irq_mask: 0,
        ext_diag_len: 0,
        ext_diag: [0; EXT_DIAG_CAPACITY],
    };

    /// The extended diagnosis blocks.
    pub fn ext_diag(&self) -> &[u8] {
        &self.ext_diag[..self.ext_diag_len as usize]
    }

    /// Set the extended diagnosis blocks (cut to [`layout::EXT_DIAG_CAPACITY`]).
    pub fn set_ext_diag(&mut self, blocks: &[u8]) {
        let n = blocks.len().min(EXT_DIAG_CAPACITY);
        self.ext_diag = [0; EXT_DIAG_CAPACITY];
        self.ext_diag[..n].copy_from_slice(&blocks[..n]);
        self.ext_diag_len = n as u8;
    }

    pub(super) fn encode(&self, b: &mut [u8]) {
        put16(b, drive::HEARTBEAT, self.heartbeat);
        put16(b, drive::FAULT_CODE, self.fault_code);
        put16(b, drive::WARNING_CODE, self.warning_code);
        b[drive::FAULT_COUNT] = self.fault_count;
        b[drive::WARNING_COUNT] = self.warning_count;
        b[drive::EXT_DIAG_LEN] = self.ext_diag_len;
        b[drive::EXT_DIAG..drive::EXT_DIAG + EXT_DIAG_CAPACITY].copy_from_slice(&self.ext_diag);
        put16(b, drive::IRQ_MASK, self.irq_mask);
    }

    pub(super) fn decode(b: &[u8]) -> DriveReport {
        let mut r = DriveReport {
            heartbeat: get16(b, drive::HEARTBEAT),
            fault_code: get16(b, drive::FAULT_CODE),
            warning_code: get16(b, drive::WARNING_CODE),
            fault_count: b[drive::FAULT_COUNT],
            warning_count: b[drive::WARNING_COUNT],
            irq_mask: get16(b, drive::IRQ_MASK),
            ..DriveReport::default()
        };
        let n = (b[drive::EXT_DIAG_LEN] as usize).min(EXT_DIAG_CAPACITY);
        r.set_ext_diag(&b[drive::EXT_DIAG..drive::EXT_DIAG + n]);
        r
    }
}

/// The configuration block's content.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct HostConfig {
    /// Station address (0..=125; 126 = keep the card's address: the stored one or the
    /// master's Set_Slave_Add).
    pub station_address: u8,
    /// Profile: 0 PROFIdrive, 1 manufacturer.
    pub profile: u8,
    /// Operate mode if the master's Set_Prm leaves it 0: 0 the card's default (PROFIdrive),
    /// 1 PROFIdrive, 2 Bypass, 3 Echo (`layout::operate_mode`); others make CONFIG invalid.
    pub operate_mode: u8,
    /// Communication-loss reaction (DRIVE_CMD coding): 0 the drive's own setting, 1 ramp stop,
    /// 2 coast, 3 quick stop, 4 keep the last setpoint, and WEG P0313's options 3 / 4 / 5
    /// (CFW-11 / CFW500 manuals, P0313): 5 change to local, 6 change to local keeping commands
    /// and reference, 7 fault (even without network control).
    pub comm_loss_reaction: u8,
    /// Telegram selection ([`Telegram::None`] = any module the GSD offers; another one =
    /// Chk_Cfg must select its module, else Cfg_Fault).
    pub telegram: Telegram,
    /// Communication-loss delay in ms.
    pub comm_loss_delay_ms: u16,
    /// PNU of output PZD3..PZD10 (0 = unmapped).
    pub pzd_out_map: [u16; PZD_MAP_WORDS],
    /// PNU of input PZD3..PZD10 (0 = unmapped).
    pub pzd_in_map: [u16; PZD_MAP_WORDS],
    /// I/O update delay after going online in 0.1 s (P0799-style, CFW-11 manual: 0.0 ..
    /// 999.0 s; 0 = none): the card holds the master's outputs back this long.
    pub io_update_delay: u16,
}

impl HostConfig {
    /// Station address 126 (keep the card's), PROFIdrive, no telegram selection, no mapping.
    pub const DEFAULT: HostConfig = HostConfig {
        // 126: the commissioning address (reference §3.9), which here means "keep the card's".
        station_address: crate::fdl::telegram::MAX_STATION_ADDRESS,
        profile: 0,
        operate_mode: 0,
        comm_loss_reaction: 0,
        telegram: Telegram::None,
        comm_loss_delay_ms: 0,
        pzd_out_map: [0; PZD_MAP_WORDS],
        pzd_in_map: [0; PZD_MAP_WORDS],
        io_update_delay: 0,
    };

    /// The largest communication-loss reaction code (7: WEG P0313 option 5, fault).
    pub const MAX_COMM_LOSS_REACTION: u8 = 7;

    /// The largest I/O update delay (999.0 s, in 0.1 s).
    pub const MAX_IO_UPDATE_DELAY: u16 = 9990;

    /// Whether the card can take it over: address 0..=126, profile 0 or 1, reaction 0..=7,
    /// telegram none or a known layout.
    pub fn is_valid(&self) -> bool {
        self.station_address <= crate::fdl::telegram::MAX_STATION_ADDRESS
            && self.profile <= 1
            && self.operate_mode <= crate::dpm::layout::operate_mode::ECHO
            && self.comm_loss_reaction <= Self::MAX_COMM_LOSS_REACTION
            && self.io_update_delay <= Self::MAX_IO_UPDATE_DELAY
            && (self.telegram == Telegram::None || self.telegram.is_known())
    }

    pub(super) fn encode(&self, b: &mut [u8]) {
        b[config::STATION_ADDRESS] = self.station_address;
        b[config::PROFILE] = self.profile;
        b[config::OPERATE_MODE] = self.operate_mode;
        b[config::COMM_LOSS_REACTION] = self.comm_loss_reaction;
        put16(b, config::TELEGRAM, self.telegram.code());
        put16(b, config::COMM_LOSS_DELAY_MS, self.comm_loss_delay_ms);
        put16(b, config::IO_UPDATE_DELAY, self.io_update_delay);
        for i in 0..PZD_MAP_WORDS {
            put16(b, config::PZD_OUT_MAP + 2 * i, self.pzd_out_map[i]);
            put16(b, config::PZD_IN_MAP + 2 * i, self.pzd_in_map[i]);
        }
    }

    pub(super) fn decode(b: &[u8]) -> HostConfig {
        let mut c = HostConfig {
            station_address: b[config::STATION_ADDRESS],
            profile: b[config::PROFILE],
            operate_mode: b[config::OPERATE_MODE],
            comm_loss_reaction: b[config::COMM_LOSS_REACTION],
            telegram: Telegram::from_code(get16(b, config::TELEGRAM)),
            comm_loss_delay_ms: get16(b, config::COMM_LOSS_DELAY_MS),
            io_update_delay: get16(b, config::IO_UPDATE_DELAY),
            ..HostConfig::DEFAULT
        };
        for i in 0..PZD_MAP_WORDS {
            c.pzd_out_map[i] = get16(b, config::PZD_OUT_MAP + 2 * i);
            c.pzd_in_map[i] = get16(b, config::PZD_IN_MAP + 2 * i);
        }
        c
    }
}

/// `MBX_REQ.KIND`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[repr(u8)]
pub enum RequestKind {
    /// 1: read values (attribute 0x10).
    Read = 1,
    /// 2: write values.
    Write = 2,
    /// 3: read a description element (attribute 0x20).
    ReadDescription = 3,
}

impl RequestKind {
    /// The kind of a code.
    pub const fn from_code(c: u8) -> Option<RequestKind> {
        match c {
            1 => Some(RequestKind::Read),
            2 => Some(RequestKind::Write),
            3 => Some(RequestKind::ReadDescription),
            _ => None,
        }
    }
}

/// Parameter values with their format (a write request's or a read response's).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ParamValues {
    /// PROFIdrive format.
    pub format: Format,
    /// Number of values.
    pub count: u8,
    len: u8,
    data: [u8; MBX_CAPACITY],
}

impl ParamValues {
    /// No values (format Zero): a write's positive answer.
    pub const NONE: ParamValues = ParamValues { format: Format::ZERO, count: 0, len: 0, data: [0; MBX_CAPACITY] };

    /// `count` values of `format`; `None` if `bytes` exceed [`layout::MBX_CAPACITY`].
    pub fn new(format: Format, count: u8, bytes: &[u8]) -> Option<ParamValues> {
        if bytes.len() > MBX_CAPACITY {
            return None;
        }
        let mut data = [0; MBX_CAPACITY];
        data[..bytes.len()].copy_from_slice(bytes);
        Some(ParamValues { format, count, len: bytes.len() as u8, data })
    }

    /// The values, big-endian.
    pub fn bytes(&self) -> &[u8] {
        &self.data[..self.len as usize]
    }

    fn from_raw(format: u8, count: u8, len: u8, raw: &[u8]) -> ParamValues {
        let n = (len as usize).min(MBX_CAPACITY);
        let mut data = [0; MBX_CAPACITY];
        data[..n].copy_from_slice(&raw[..n]);
        ParamValues { format: Format(format), count, len: n as u8, data }
    }
}

/// A mailbox request.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MailboxRequest {
    /// Request identifier (set by the card's [`Mailbox`](super::Mailbox); 0 = no request).
    pub id: u16,
    /// What is asked.
    pub kind: RequestKind,
    /// Axis / DO-ID.
    pub axis: u8,
    /// Parameter number.
    pub pnu: u16,
    /// First element / description element.
    pub subindex: u16,
    /// Number of elements (0 counts as 1).
    pub count: u8,
    /// Values to write ([`ParamValues::NONE`] for reads).
    pub values: ParamValues,
}

impl MailboxRequest {
    /// Read `count` elements of `pnu` from `subindex`.
    pub const fn read(axis: u8, pnu: u16, subindex: u16, count: u8) -> Self {
        MailboxRequest { id: 0, kind: RequestKind::Read, axis, pnu, subindex, count, values: ParamValues::NONE }
    }

    /// Write `values` to `pnu` from `subindex`.
    pub const fn write(axis: u8, pnu: u16, subindex: u16, values: ParamValues) -> Self {
        MailboxRequest { id: 0, kind: RequestKind::Write, axis, pnu, subindex, count: values.count, values }
    }

    /// Read description element `element` (0 = all) of `pnu`.
    pub const fn read_description(axis: u8, pnu: u16, element: u16) -> Self {
        MailboxRequest {
            id: 0,
            kind: RequestKind::ReadDescription,
            axis,
            pnu,
            subindex: element,
            count: 1,
            values: ParamValues::NONE,
        }
    }

    pub(super) fn encode(&self, b: &mut [u8]) {
        put16(b, mbx_req::REQ_ID, self.id);
        b[mbx_req::KIND] = self.kind as u8;
        b[mbx_req::AXIS] = self.axis;
        put16(b, mbx_req::PNU, self.pnu);
        put16(b, mbx_req::SUBINDEX, self.subindex);
        b[mbx_req::COUNT] = self.count;
        b[mbx_req::FORMAT] = self.values.format.0;
        b[mbx_req::VALUES_LEN] = self.values.len;
        b[mbx_req::VALUES..mbx_req::VALUES + MBX_CAPACITY].copy_from_slice(&self.values.data);
    }

    /// `None` if no request was written (id 0) or the kind is unknown.
    pub(super) fn decode(b: &[u8]) -> Option<MailboxRequest> {
        let id = get16(b, mbx_req::REQ_ID);
        let kind = RequestKind::from_code(b[mbx_req::KIND])?;
        (id != 0).then(|| MailboxRequest {
            id,
            kind,
            axis: b[mbx_req::AXIS],
            pnu: get16(b, mbx_req::PNU),
            subindex: get16(b, mbx_req::SUBINDEX),
            count: b[mbx_req::COUNT],
            values: ParamValues::from_raw(
                b[mbx_req::FORMAT],
                b[mbx_req::COUNT],
                b[mbx_req::VALUES_LEN],
                &b[mbx_req::VALUES..],
            ),
        })
    }
}

/// A mailbox response: values or a PROFIdrive error.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MailboxResponse {
    /// The request answered.
    pub id: u16,
    /// Values (read) / [`ParamValues::NONE`] (write), or the error.
    pub outcome: Result<ParamValues, ParamError>,
}

impl MailboxResponse {
    pub(super) fn encode(&self, b: &mut [u8]) {
        put16(b, mbx_rsp::REQ_ID, self.id);
        match &self.outcome {
            Ok(v) => {
                b[mbx_rsp::RESULT] = 0;
                b[mbx_rsp::FORMAT] = v.format.0;
                b[mbx_rsp::COUNT] = v.count;
                b[mbx_rsp::VALUES_LEN] = v.len;
                put16(b, mbx_rsp::ERROR, 0);
                put16(b, mbx_rsp::ERROR_INFO, 0);
                b[mbx_rsp::HAS_INFO] = 0;
                b[mbx_rsp::VALUES..mbx_rsp::VALUES + MBX_CAPACITY].copy_from_slice(&v.data);
            }
            Err(e) => {
                b[mbx_rsp::RESULT] = 1;
                b[mbx_rsp::FORMAT] = Format::ERROR.0;
                b[mbx_rsp::COUNT] = 0;
                b[mbx_rsp::VALUES_LEN] = 0;
                put16(b, mbx_rsp::ERROR, e.value.0);
                put16(b, mbx_rsp::ERROR_INFO, e.additional_info.unwrap_or(0));
                b[mbx_rsp::HAS_INFO] = e.additional_info.is_some() as u8;
                b[mbx_rsp::VALUES..mbx_rsp::VALUES + MBX_CAPACITY].fill(0);
            }
        }
    }

    pub(super) fn decode(b: &[u8]) -> MailboxResponse {
        let outcome = if b[mbx_rsp::RESULT] == 0 {
            Ok(ParamValues::from_raw(
                b[mbx_rsp::FORMAT],
                b[mbx_rsp::COUNT],
                b[mbx_rsp::VALUES_LEN],
                &b[mbx_rsp::VALUES..],
            ))
        } else {
            Err(ParamError {
                value: ErrorValue(get16(b, mbx_rsp::ERROR)),
                additional_info: (b[mbx_rsp::HAS_INFO] == 1).then(|| get16(b, mbx_rsp::ERROR_INFO)),
            })
        };
        MailboxResponse { id: get16(b, mbx_rsp::REQ_ID), outcome }
    }
}

/// What a [`HeartbeatMonitor`] concluded from one observation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum Liveness {
    /// Never seen a heartbeat (value 0 so far): not supervised.
    Unknown,
    /// Changed within the timeout.
    Alive,
    /// Unchanged for longer than the timeout.
    Lost,
}

/// Watches a heartbeat counter: alive while it changes at least once per timeout. The card
/// uses it on `DRIVE.HEARTBEAT`; the drive can use it on `CARD.HEARTBEAT`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct HeartbeatMonitor {
    timeout: Duration,
    last: u16,
    since: Option<Instant>,
    lost: bool,
}

impl HeartbeatMonitor {
    /// A monitor with `timeout`; supervision starts with the first non-zero value.
    pub const fn new(timeout: Duration) -> Self {
        HeartbeatMonitor { timeout, last: 0, since: None, lost: false }
    }

    /// Observe the counter at `now`.
    pub fn observe(&mut self, now: Instant, value: u16) -> Liveness {
        match self.since {
            None if value == 0 => return Liveness::Unknown,
            Some(_) if value == self.last => {}
            _ => {
                self.last = value;
                self.since = Some(now);
                self.lost = false;
            }
        }
        let since = self.since.unwrap_or(now);
        if now.saturating_since(since) > self.timeout {
            self.lost = true;
        }
        self.liveness()
    }

    /// The last conclusion.
    pub fn liveness(&self) -> Liveness {
        match (self.since, self.lost) {
            (None, _) => Liveness::Unknown,
            (Some(_), false) => Liveness::Alive,
            (Some(_), true) => Liveness::Lost,
        }
    }
}

fn get32(b: &[u8], at: usize) -> u32 {
    u32::from_be_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

/// Up to [`layout::EXTRA_WORDS`] raw PZD words with their count: the words of a telegram the
/// drive-neutral command / status does not carry (programmable words in the manner of WEG
/// P0742–P0757 / CONFIG.PZD_*_MAP, VACON telegrams' process data words).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct PzdWords {
    count: u8,
    words: [u16; EXTRA_WORDS],
}

impl PzdWords {
    /// No words.
    pub const EMPTY: PzdWords = PzdWords { count: 0, words: [0; EXTRA_WORDS] };

    /// `words`; `None` if there are more than [`layout::EXTRA_WORDS`].
    pub fn new(words: &[u16]) -> Option<PzdWords> {
        if words.len() > EXTRA_WORDS {
            return None;
        }
        let mut w = PzdWords::EMPTY;
        w.words[..words.len()].copy_from_slice(words);
        w.count = words.len() as u8;
        Some(w)
    }

    /// The valid words.
    pub fn words(&self) -> &[u16] {
        &self.words[..self.count as usize]
    }

    /// Word `i` (0 beyond the valid words).
    pub fn word(&self, i: usize) -> u16 {
        self.words().get(i).copied().unwrap_or(0)
    }

    fn encode(&self, b: &mut [u8], count_at: usize, words_at: usize) {
        b[count_at] = self.count;
        for (i, w) in self.words.iter().enumerate() {
            put16(b, words_at + 2 * i, *w);
        }
    }

    fn decode(b: &[u8], count_at: usize, words_at: usize) -> PzdWords {
        let count = b[count_at].min(EXTRA_WORDS as u8);
        let mut w = PzdWords { count, words: [0; EXTRA_WORDS] };
        for i in 0..count as usize {
            w.words[i] = get16(b, words_at + 2 * i);
        }
        w
    }
}

/// The DRIVE_CMD block (layout version 3, card → host): the drive-neutral command of
/// [`crate::profile::drive_if`] (issue 6 item 2, OPTE3/E5 §11.1 model) with the context the
/// drive needs to apply it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DriveCommandImage {
    /// The command: flags, N2 setpoint, fault-reset counter, communication-loss reaction.
    pub command: DriveCommand,
    /// Active operate mode ([`layout::operate_mode`]: 1 PROFIdrive, 2 Bypass, 3 Echo).
    pub operate_mode: u8,
    /// Active telegram.
    pub telegram: Telegram,
    /// The OUTPUTS sequence counter this command was made from (0 = none).
    pub outputs_seq: u16,
    /// Extra raw PZD output words (programmable words).
    pub extra: PzdWords,
}

impl Default for DriveCommandImage {
    fn default() -> Self {
        Self::EMPTY
    }
}

impl DriveCommandImage {
    /// No command (all flags clear: stop), no telegram, no extra words.
    pub const EMPTY: DriveCommandImage = DriveCommandImage {
        command: DriveCommand {
            flags: CommandFlags::empty(),
            speed_setpoint: 0,
            fault_resets: 0,
            comm_loss_reaction: 0,
        },
        operate_mode: layout::operate_mode::UNKNOWN,
        telegram: Telegram::None,
        outputs_seq: 0,
        extra: PzdWords::EMPTY,
    };

    pub(super) fn encode(&self, b: &mut [u8]) {
        let c = &self.command;
        put16(b, drive_cmd::FLAGS, c.flags.bits());
        put16(b, drive_cmd::SPEED_SETPOINT, c.speed_setpoint as u16);
        b[drive_cmd::FAULT_RESETS] = c.fault_resets;
        b[drive_cmd::COMM_LOSS_REACTION] = c.comm_loss_reaction;
        b[drive_cmd::OPERATE_MODE] = self.operate_mode;
        put16(b, drive_cmd::TELEGRAM, self.telegram.code());
        put16(b, drive_cmd::OUTPUTS_SEQ, self.outputs_seq);
        self.extra.encode(b, drive_cmd::EXTRA_COUNT, drive_cmd::EXTRA);
    }

    pub(super) fn decode(b: &[u8]) -> DriveCommandImage {
        DriveCommandImage {
            command: DriveCommand {
                flags: CommandFlags::from_bits_retain(get16(b, drive_cmd::FLAGS)),
                speed_setpoint: get16(b, drive_cmd::SPEED_SETPOINT) as i16,
                fault_resets: b[drive_cmd::FAULT_RESETS],
                comm_loss_reaction: b[drive_cmd::COMM_LOSS_REACTION],
            },
            operate_mode: b[drive_cmd::OPERATE_MODE],
            telegram: Telegram::from_code(get16(b, drive_cmd::TELEGRAM)),
            outputs_seq: get16(b, drive_cmd::OUTPUTS_SEQ),
            extra: PzdWords::decode(b, drive_cmd::EXTRA_COUNT, drive_cmd::EXTRA),
        }
    }
}

/// The DRIVE_STATE block (layout version 3, host → card): the drive-neutral status of
/// [`crate::profile::drive_if`] (OPTE3/E5 §11.3 model) and the extra raw input words.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct DriveStateImage {
    /// The status: flags, N2 speed / current / torque / power, fault, warning, NAMUR bits.
    pub status: DriveStatus,
    /// The INPUTS sequence counter written with this state (0 = none).
    pub inputs_seq: u16,
    /// Extra raw PZD input words (programmable words).
    pub extra: PzdWords,
}

impl DriveStateImage {
    /// Nothing reported: all flags clear, zero values, no extra words.
    pub const EMPTY: DriveStateImage = DriveStateImage {
        status: DriveStatus {
            flags: DriveStatusFlags::empty(),
            speed: 0,
            current: 0,
            torque: 0,
            power: 0,
            fault_code: 0,
            warning_code: 0,
            namur: 0,
        },
        inputs_seq: 0,
        extra: PzdWords::EMPTY,
    };

    pub(super) fn encode(&self, b: &mut [u8]) {
        let s = &self.status;
        put16(b, drive_state::FLAGS, s.flags.bits());
        put16(b, drive_state::SPEED, s.speed as u16);
        put16(b, drive_state::CURRENT, s.current as u16);
        put16(b, drive_state::TORQUE, s.torque as u16);
        put16(b, drive_state::POWER, s.power as u16);
        put16(b, drive_state::FAULT_CODE, s.fault_code);
        put16(b, drive_state::WARNING_CODE, s.warning_code);
        put16(b, drive_state::NAMUR, s.namur);
        put16(b, drive_state::INPUTS_SEQ, self.inputs_seq);
        self.extra.encode(b, drive_state::EXTRA_COUNT, drive_state::EXTRA);
    }

    pub(super) fn decode(b: &[u8]) -> DriveStateImage {
        DriveStateImage {
            status: DriveStatus {
                flags: DriveStatusFlags::from_bits_retain(get16(b, drive_state::FLAGS)),
                speed: get16(b, drive_state::SPEED) as i16,
                current: get16(b, drive_state::CURRENT) as i16,
                torque: get16(b, drive_state::TORQUE) as i16,
                power: get16(b, drive_state::POWER) as i16,
                fault_code: get16(b, drive_state::FAULT_CODE),
                warning_code: get16(b, drive_state::WARNING_CODE),
                namur: get16(b, drive_state::NAMUR),
            },
            inputs_seq: get16(b, drive_state::INPUTS_SEQ),
            extra: PzdWords::decode(b, drive_state::EXTRA_COUNT, drive_state::EXTRA),
        }
    }
}
