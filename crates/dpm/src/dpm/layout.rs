//! The DPM memory map, layout version 4: every offset the card and the host use, in one place.
//! [`FIELDS`] lists every byte of the image (reserved bytes included) and is what
//! `docs/DPM.md` is generated from ([`write_markdown`]); a test fails when the two differ.
//!
//! All multi-byte fields are **big-endian** (as the PROFIBUS wire and the PZD words), so the
//! process data bytes are the telegram's bytes unchanged. Offsets of a field inside a block
//! are relative to the block's start. Reserved bytes are written as 0 and must be ignored.
//!
//! ```text
//! 0x00  HEADER   16 B  card, once   magic "PBDM", layout version, image size
//! 0x10  STATUS   32 B  card → host  communication state (P0740), baud (P0963), addresses,
//!                                   active telegram, DP state, flags, watchdog, counters
//! 0x30  OUTPUTS  72 B  card → host  process data master → drive (STW1, NSOLL_A … / PKW + PZD)
//! 0x78  INPUTS   72 B  host → card  process data drive → master (ZSW1, NIST_A … / PKW + PZD)
//! 0xC0  IDENT    16 B  card, once   card type, firmware version, ident number, serial   (v2)
//! 0xD0  CARD     32 B  card → host  card heartbeat, configuration acknowledge, event
//!                                   counters, drive-lost state                          (v2)
//! 0xF0  DRIVE    48 B  host → card  drive heartbeat, fault / warning reports, ext. diag.  (v2)
//! 0x120 CONFIG   48 B  host → card  station address, telegram, profile, operate mode,
//!                                   PZD mapping, communication-loss reaction and delay  (v2)
//! 0x150 MBX_REQ 144 B  card → host  parameter mailbox request                           (v2)
//! 0x1E0 MBX_RSP 144 B  host → card  parameter mailbox response                          (v2)
//! 0x270 DRIVE_CMD 48 B card → host  drive-neutral command                               (v3)
//! 0x2A0 DRIVE_STATE 56 B host → card drive-neutral status                              (v3)
//! 0x2D8 DEVICE   24 B  host → card  the drive's serial number and hardware revision (I&M0) (v4)
//! 0x2F0 end (IMAGE_SIZE = 752)
//! ```
//!
//! Version 1 ended at 0xC0; version 2 only appended blocks and the header's capability word
//! (a version-1 host that checks `IMAGE_SIZE >= 0xC0` keeps working).
//!
//! Every block except HEADER and IDENT is a *sequenced block*: the first word (`SEQ_HEAD`) and the last
//! word (`SEQ_TAIL`) hold the same sequence counter once a write is complete (see
//! [`super`] for the protocol). Later layout versions append blocks; the offsets below do not
//! move.

/// `HEADER.MAGIC` value: ASCII "PBDM".
pub const MAGIC: [u8; 4] = *b"PBDM";
/// `HEADER.LAYOUT_VERSION` value of this map.
pub const LAYOUT_VERSION: u16 = 4;

/// Bits of `HEADER.CAPABILITIES`: which optional blocks this card serves. The host reads the
/// header (magic, version, size, capabilities) before anything else.
pub mod cap {
    /// IDENT is filled in.
    pub const IDENT: u32 = 1 << 0;
    /// CARD: card heartbeat and event counters.
    pub const CARD_EVENTS: u32 = 1 << 1;
    /// DRIVE: the card supervises the drive heartbeat and takes fault / warning / ext. diag.
    pub const DRIVE_REPORTS: u32 = 1 << 2;
    /// CONFIG is taken over (outside data exchange) and acknowledged in CARD.
    pub const CONFIG: u32 = 1 << 3;
    /// MBX_REQ / MBX_RSP: the parameter mailbox.
    pub const MAILBOX: u32 = 1 << 4;
    /// DRIVE_CMD: the card writes the drive-neutral command (layout version 3).
    pub const DRIVE_CMD: u32 = 1 << 5;
    /// DRIVE_STATE: the card takes the drive-neutral status (layout version 3).
    pub const DRIVE_STATE: u32 = 1 << 6;
    /// DEVICE: the card takes the drive's serial number and hardware revision for I&M0
    /// (layout version 4).
    pub const DEVICE: u32 = 1 << 7;
    /// Everything this card implements.
    pub const ALL: u32 = IDENT | CARD_EVENTS | DRIVE_REPORTS | CONFIG | MAILBOX | DRIVE_CMD | DRIVE_STATE | DEVICE;
}

/// Header: written once by the card when the image is created.
pub mod header {
    /// Block start.
    pub const START: usize = 0x00;
    /// Block length.
    pub const LEN: usize = 16;
    /// 4 bytes, [`super::MAGIC`].
    pub const MAGIC: usize = 0x00;
    /// u16, [`super::LAYOUT_VERSION`].
    pub const LAYOUT_VERSION: usize = 0x04;
    /// u16, [`super::IMAGE_SIZE`].
    pub const IMAGE_SIZE: usize = 0x06;
    /// u32, [`super::cap`] bits (layout version 2).
    pub const CAPABILITIES: usize = 0x08;
}

/// Status block (card → host).
pub mod status {
    /// Block start.
    pub const START: usize = 0x10;
    /// Block length.
    pub const LEN: usize = 32;
    /// u16 sequence counter, written last by the card.
    pub const SEQ_HEAD: usize = 0x00;
    /// u8 communication state in the P0740 coding ([`crate::dpm::CommState`]).
    pub const COMM_STATE: usize = 0x02;
    /// u8 detected baud rate in the P0963 coding (5 = not detected).
    pub const BAUD: usize = 0x03;
    /// u8 own station address (0..=126).
    pub const STATION_ADDRESS: usize = 0x04;
    /// u8 address of the master holding the lock, 0xFF = none.
    pub const MASTER_ADDRESS: usize = 0x05;
    /// u16 active telegram ([`crate::dpm::Telegram`] code; 0 = not configured).
    pub const TELEGRAM: usize = 0x06;
    /// u8 DP state: 0 Wait_Prm, 1 Wait_Cfg, 2 Data_Exch.
    pub const DP_STATE: usize = 0x08;
    /// u8 flags ([`crate::dpm::StatusFlags`]).
    pub const FLAGS: usize = 0x09;
    /// u16 DP watchdog time in ms (0 = off; saturates at 65535).
    pub const WATCHDOG_MS: usize = 0x0A;
    /// u32 Data_Exchange requests answered (wraps).
    pub const DATA_EXCHANGES: usize = 0x0C;
    /// u16 Set_Prm refused (wraps).
    pub const PRM_FAULTS: usize = 0x10;
    /// u16 Chk_Cfg refused (wraps).
    pub const CFG_FAULTS: usize = 0x12;
    /// u16 DP watchdog expiries (wraps).
    pub const WATCHDOG_EXPIRIES: usize = 0x14;
    /// u16 corrupt telegrams seen by the framer (wraps).
    pub const CORRUPT_FRAMES: usize = 0x16;
    /// u16 sequence counter, written first by the card.
    pub const SEQ_TAIL: usize = LEN - 2;
}

/// Bytes of process data a process-data block holds (32 words; the largest module today has
/// 28 bytes, `card::MAX_INPUT_LEN` / `MAX_OUTPUT_LEN`).
pub const PD_CAPACITY: usize = 64;

/// Field offsets shared by the two process-data blocks ([`outputs`], [`inputs`]).
pub mod pd {
    /// u16 sequence counter: the head.
    pub const SEQ_HEAD: usize = 0x00;
    /// u16 telegram the data is laid out for ([`crate::dpm::Telegram`] code).
    pub const TELEGRAM: usize = 0x02;
    /// u8 valid bytes in `DATA` (at most [`super::PD_CAPACITY`]; larger values read as that).
    pub const LEN: usize = 0x04;
    /// u8 flags ([`crate::dpm::PdFlags`]).
    pub const FLAGS: usize = 0x05;
    /// The process data, as on the wire (big-endian words).
    pub const DATA: usize = 0x06;
    /// u16 sequence counter: the tail.
    pub const SEQ_TAIL: usize = DATA + super::PD_CAPACITY;
    /// Block length.
    pub const LEN_BLOCK: usize = SEQ_TAIL + 2;
}

/// Outputs block (card → host): what the master sent, as the drive must apply it.
pub mod outputs {
    /// Block start.
    pub const START: usize = 0x30;
    /// Block length.
    pub const LEN: usize = super::pd::LEN_BLOCK;
}

/// Inputs block (host → card): what the drive answers, served to the master.
pub mod inputs {
    /// Block start.
    pub const START: usize = super::outputs::START + super::outputs::LEN;
    /// Block length.
    pub const LEN: usize = super::pd::LEN_BLOCK;
}

/// Identification (card → host), written once when the image is created.
pub mod ident {
    /// Block start.
    pub const START: usize = super::inputs::START + super::inputs::LEN;
    /// Block length.
    pub const LEN: usize = 16;
    /// u16 card type ([`crate::dpm::CARD_TYPE`]).
    pub const CARD_TYPE: usize = 0x00;
    /// u8 firmware major version.
    pub const FW_MAJOR: usize = 0x02;
    /// u8 firmware minor version.
    pub const FW_MINOR: usize = 0x03;
    /// u8 firmware patch version.
    pub const FW_PATCH: usize = 0x04;
    /// u16 PROFIBUS ident number (the GSD's).
    pub const IDENT_NUMBER: usize = 0x06;
    /// u32 serial number (0 = not programmed).
    pub const SERIAL: usize = 0x08;
}

/// Number of card → drive event counters in CARD ([`crate::dpm::CardEvent`]).
pub const CARD_EVENT_COUNT: usize = 8;

/// Card block (card → host): heartbeat, configuration acknowledge, events.
pub mod card {
    /// Block start.
    pub const START: usize = super::ident::START + super::ident::LEN;
    /// Block length.
    pub const LEN: usize = 32;
    /// u16 sequence counter, written last by the card.
    pub const SEQ_HEAD: usize = 0x00;
    /// u16 card heartbeat: incremented on every card cycle (wraps, skips 0).
    pub const HEARTBEAT: usize = 0x02;
    /// u8 card state flags ([`crate::dpm::CardFlags`]).
    pub const FLAGS: usize = 0x04;
    /// u8 result of the configuration named by `CONFIG_ACK` ([`crate::dpm::ConfigResult`]).
    pub const CONFIG_RESULT: usize = 0x05;
    /// u16 the CONFIG sequence counter `CONFIG_RESULT` is about (0 = none yet).
    pub const CONFIG_ACK: usize = 0x06;
    /// u8 × 8 event counters, one per [`crate::dpm::CardEvent`] (wrap); a change = new event.
    pub const EVENTS: usize = 0x08;
    /// u16 drive heartbeat losses detected (wraps).
    pub const DRIVE_LOSSES: usize = 0x10;
    /// u16 late or unknown mailbox responses ignored (wraps).
    pub const LATE_RESPONSES: usize = 0x12;
    /// u16 mailbox requests timed out (wraps).
    pub const MAILBOX_TIMEOUTS: usize = 0x14;
    // --- issue 16 (restart rules) ---
    /// u16 boot identifier: another value on every card start (panic and watchdog resets
    /// included), never 0; a change tells the host to re-open and rewrite CONFIG.
    pub const BOOT_ID: usize = 0x16;
    // --- end issue 16 ---
    /// u16 sequence counter, written first by the card.
    pub const SEQ_TAIL: usize = LEN - 2;
}

/// Bytes of extended diagnosis the drive can hand over in DRIVE.
pub const EXT_DIAG_CAPACITY: usize = 32;

/// Drive block (host → card): drive heartbeat, fault and warning reports, ext. diagnosis.
pub mod drive {
    /// Block start.
    pub const START: usize = super::card::START + super::card::LEN;
    /// Block length.
    pub const LEN: usize = 48;
    /// u16 sequence counter: the head.
    pub const SEQ_HEAD: usize = 0x00;
    /// u16 drive heartbeat: changed on every drive cycle (0 = drive not started).
    pub const HEARTBEAT: usize = 0x02;
    /// u16 active fault code (0 = none).
    pub const FAULT_CODE: usize = 0x04;
    /// u16 active warning code (0 = none).
    pub const WARNING_CODE: usize = 0x06;
    /// u8 fault reports (wraps): incremented for each new fault.
    pub const FAULT_COUNT: usize = 0x08;
    /// u8 warning reports (wraps): incremented for each new warning.
    pub const WARNING_COUNT: usize = 0x09;
    /// u8 valid bytes in `EXT_DIAG` (larger values read as the capacity).
    pub const EXT_DIAG_LEN: usize = 0x0A;
    /// Extended diagnosis blocks as DP sends them (device / identifier / channel related).
    pub const EXT_DIAG: usize = 0x0C;
    /// u16 the host's IRQ mask (issue 16 item 4, `docs/SPI.md` "Events and the IRQ line"):
    /// bits of the pending-events bitmap that do not assert IRQ (set = masked; 0 = every
    /// event asserts it).
    pub const IRQ_MASK: usize = EXT_DIAG + super::EXT_DIAG_CAPACITY;
    /// u16 sequence counter: the tail.
    pub const SEQ_TAIL: usize = LEN - 2;
}

/// Words of programmable PZD mapping each way (PZD3..PZD10).
pub const PZD_MAP_WORDS: usize = 8;

/// Configuration block (host → card), taken over only while no cyclic exchange runs.
pub mod config {
    /// Block start.
    pub const START: usize = super::drive::START + super::drive::LEN;
    /// Block length.
    pub const LEN: usize = 48;
    /// u16 sequence counter: the head.
    pub const SEQ_HEAD: usize = 0x00;
    /// u8 station address (0..=125; 126 = keep the card's address).
    pub const STATION_ADDRESS: usize = 0x02;
    /// u8 profile ([`crate::dpm::HostConfig::profile`]: 0 PROFIdrive, 1 manufacturer).
    pub const PROFILE: usize = 0x03;
    /// u8 operate mode (drive-defined, e.g. speed / position).
    pub const OPERATE_MODE: usize = 0x04;
    /// u8 communication-loss reaction the drive applies (0 its own setting, 1 ramp stop,
    /// 2 coast, 3 quick stop, 4 keep the last setpoint; the coding of DRIVE_CMD and of the
    /// GSD user parameter).
    pub const COMM_LOSS_REACTION: usize = 0x05;
    /// u16 telegram selection ([`crate::dpm::Telegram`] code, 0 = any module; else Chk_Cfg
    /// must select this telegram's module).
    pub const TELEGRAM: usize = 0x06;
    /// u16 communication-loss delay in ms.
    pub const COMM_LOSS_DELAY_MS: usize = 0x08;
    /// u16 × 8: drive PNU mapped to output PZD3..PZD10 (0 = unmapped).
    pub const PZD_OUT_MAP: usize = 0x0A;
    /// u16 × 8: drive PNU mapped to input PZD3..PZD10 (0 = unmapped).
    pub const PZD_IN_MAP: usize = PZD_OUT_MAP + 2 * super::PZD_MAP_WORDS;
    /// u16 I/O update delay in 0.1 s (P0799-style, CFW-11 manual; 0 = none, at most 9990):
    /// after going online the drive keeps its previous command this long before the master's
    /// outputs apply.
    pub const IO_UPDATE_DELAY: usize = PZD_IN_MAP + 2 * super::PZD_MAP_WORDS;
    /// u16 sequence counter: the tail.
    pub const SEQ_TAIL: usize = LEN - 2;
}

/// Bytes of parameter values a mailbox request or response carries.
pub const MBX_CAPACITY: usize = 128;

/// Mailbox request (card → host).
pub mod mbx_req {
    /// Block start.
    pub const START: usize = super::config::START + super::config::LEN;
    /// u16 sequence counter, written last by the card.
    pub const SEQ_HEAD: usize = 0x00;
    /// u16 request identifier (1..=65535, skips 0; 0 = no request yet).
    pub const REQ_ID: usize = 0x02;
    /// u8 kind ([`crate::dpm::RequestKind`]: 1 read, 2 write, 3 read description).
    pub const KIND: usize = 0x04;
    /// u8 axis / DO-ID.
    pub const AXIS: usize = 0x05;
    /// u16 parameter number.
    pub const PNU: usize = 0x06;
    /// u16 subindex (first element / description element).
    pub const SUBINDEX: usize = 0x08;
    /// u8 number of elements.
    pub const COUNT: usize = 0x0A;
    /// u8 PROFIdrive format of `VALUES` (write only).
    pub const FORMAT: usize = 0x0B;
    /// u8 valid bytes in `VALUES` (write only).
    pub const VALUES_LEN: usize = 0x0C;
    /// Values to write, big-endian, `COUNT × size of FORMAT` bytes.
    pub const VALUES: usize = 0x0E;
    /// u16 sequence counter, written first by the card.
    pub const SEQ_TAIL: usize = VALUES + super::MBX_CAPACITY;
    /// Block length.
    pub const LEN: usize = SEQ_TAIL + 2;
}

/// Mailbox response (host → card).
pub mod mbx_rsp {
    /// Block start.
    pub const START: usize = super::mbx_req::START + super::mbx_req::LEN;
    /// u16 sequence counter: the head.
    pub const SEQ_HEAD: usize = 0x00;
    /// u16 the request identifier answered (a response naming another is ignored).
    pub const REQ_ID: usize = 0x02;
    /// u8 0 = values / write done, 1 = error (`ERROR`, `ERROR_INFO`).
    pub const RESULT: usize = 0x04;
    /// u8 PROFIdrive format of `VALUES`.
    pub const FORMAT: usize = 0x05;
    /// u8 number of values.
    pub const COUNT: usize = 0x06;
    /// u8 valid bytes in `VALUES`.
    pub const VALUES_LEN: usize = 0x07;
    /// u16 PROFIdrive error value (RESULT = 1).
    pub const ERROR: usize = 0x08;
    /// u16 additional information (RESULT = 1 and `HAS_INFO` = 1).
    pub const ERROR_INFO: usize = 0x0A;
    /// u8 1 = `ERROR_INFO` is valid.
    pub const HAS_INFO: usize = 0x0C;
    /// Values read, big-endian.
    pub const VALUES: usize = 0x0E;
    /// u16 sequence counter: the tail.
    pub const SEQ_TAIL: usize = VALUES + super::MBX_CAPACITY;
    /// Block length.
    pub const LEN: usize = SEQ_TAIL + 2;
}

/// Raw PZD words DRIVE_CMD and DRIVE_STATE carry beside the drive-neutral values (the
/// programmable words, P0742–P0757 style, and vendor telegrams' extra words).
pub const EXTRA_WORDS: usize = 16;

/// `DRIVE_CMD.OPERATE_MODE` codes: the OPTE3/E5 panel parameter's coding (OPTE3/E5 §5.1
/// Table 9, P5.x.3.2 "Operate mode").
pub mod operate_mode {
    /// 0: not known yet (no module configured).
    pub const UNKNOWN: u8 = 0;
    /// 1: PROFIdrive (the card's profile drives the command).
    pub const PROFIDRIVE: u8 = 1;
    /// 2: Bypass (the PLC's words pass to the drive unchanged, manufacturer control word).
    pub const BYPASS: u8 = 2;
    /// 3: Echo (the card returns the outputs as inputs; the drive is not commanded).
    pub const ECHO: u8 = 3;
}

/// Drive command block (card → host), layout version 3: the drive-neutral command of
/// `crate::profile::drive_if` (issue 6 item 2) plus the raw words the profile does not interpret.
pub mod drive_cmd {
    /// Block start.
    pub const START: usize = super::mbx_rsp::START + super::mbx_rsp::LEN;
    /// Block length.
    pub const LEN: usize = 48;
    /// u16 sequence counter, written last by the card.
    pub const SEQ_HEAD: usize = 0x00;
    /// u16 `CommandFlags` (`crate::profile::drive_if`).
    pub const FLAGS: usize = 0x02;
    /// i16 speed setpoint, N2 (0x4000 = 100 % of the reference speed).
    pub const SPEED_SETPOINT: usize = 0x04;
    /// u8 fault acknowledges requested so far (wraps).
    pub const FAULT_RESETS: usize = 0x06;
    /// u8 communication-loss reaction while `COMM_LOSS` is set (0 drive's own … 7 fault,
    /// [`crate::dpm::HostConfig::comm_loss_reaction`] coding).
    pub const COMM_LOSS_REACTION: usize = 0x07;
    /// u8 active operate mode ([`super::operate_mode`]).
    pub const OPERATE_MODE: usize = 0x08;
    /// u8 valid words in `EXTRA` (larger values read as [`super::EXTRA_WORDS`]).
    pub const EXTRA_COUNT: usize = 0x09;
    /// u16 active telegram (`crate::dpm::Telegram` code).
    pub const TELEGRAM: usize = 0x0A;
    /// u16 the OUTPUTS sequence counter this command was made from (0 = none).
    pub const OUTPUTS_SEQ: usize = 0x0C;
    /// u16 × 16 extra raw PZD output words.
    pub const EXTRA: usize = 0x0E;
    /// u16 sequence counter, written first by the card.
    pub const SEQ_TAIL: usize = LEN - 2;
}

/// Drive state block (host → card), layout version 3: the drive-neutral status of
/// `crate::profile::drive_if` plus raw words.
pub mod drive_state {
    /// Block start.
    pub const START: usize = super::drive_cmd::START + super::drive_cmd::LEN;
    /// Block length.
    pub const LEN: usize = 56;
    /// u16 sequence counter: the head.
    pub const SEQ_HEAD: usize = 0x00;
    /// u16 `StatusFlags` (`crate::profile::drive_if`).
    pub const FLAGS: usize = 0x02;
    /// i16 actual speed, N2.
    pub const SPEED: usize = 0x04;
    /// i16 output current, N2 (0x4000 = rated current).
    pub const CURRENT: usize = 0x06;
    /// i16 torque, N2 (0x4000 = rated torque).
    pub const TORQUE: usize = 0x08;
    /// i16 active power, N2 (0x4000 = rated power).
    pub const POWER: usize = 0x0A;
    /// u16 active fault code (0 = none).
    pub const FAULT_CODE: usize = 0x0C;
    /// u16 active warning code (0 = none).
    pub const WARNING_CODE: usize = 0x0E;
    /// u16 MELD_NAMUR bits.
    pub const NAMUR: usize = 0x10;
    /// u16 the INPUTS sequence counter written with this state (0 = none).
    pub const INPUTS_SEQ: usize = 0x12;
    /// u8 valid words in `EXTRA` (larger values read as [`super::EXTRA_WORDS`]).
    pub const EXTRA_COUNT: usize = 0x14;
    /// u16 × 16 extra raw PZD input words.
    pub const EXTRA: usize = 0x16;
    /// u16 sequence counter: the tail.
    pub const SEQ_TAIL: usize = LEN - 2;
}

/// Device block (host → card), layout version 4: what the drive tells the card about the device
/// it sits in, for I&M0 (`crate::dpv1::im`, reference §4.7). Written once by the drive after
/// start (and again if it changes); the card reads it whenever the counter changes.
pub mod device {
    /// Block start.
    pub const START: usize = super::drive_state::START + super::drive_state::LEN;
    /// Block length.
    pub const LEN: usize = 24;
    /// u16 sequence counter: the head.
    pub const SEQ_HEAD: usize = 0x00;
    /// u8 × 16 I&M0 SERIAL_NUMBER of the drive, visible string (ASCII 0x20..0x7E), blank-padded.
    pub const SERIAL_NUMBER: usize = 0x02;
    /// u16 I&M0 HARDWARE_REVISION of the drive (0 = not known: the card's own).
    pub const HARDWARE_REVISION: usize = 0x12;
    /// u16 sequence counter: the tail.
    pub const SEQ_TAIL: usize = LEN - 2;
}

/// Size of the whole image.
pub const IMAGE_SIZE: usize = device::START + device::LEN;

/// The image size of each layout version (index = version; newer versions only append).
pub const IMAGE_SIZE_OF_VERSION: [usize; 5] =
    [0, inputs::START + inputs::LEN, drive_cmd::START, drive_state::START + drive_state::LEN, IMAGE_SIZE];

const _: () = {
    assert!(header::START + header::LEN == status::START);
    assert!(status::START + status::LEN == outputs::START);
    assert!(outputs::START == 0x30 && inputs::START == 0x78 && ident::START == 0xC0);
    assert!(drive_cmd::START == 0x270 && drive_state::START == 0x2A0);
    assert!(device::START == 0x2D8 && IMAGE_SIZE == 0x2F0 && IMAGE_SIZE <= u16::MAX as usize);
    assert!(device::HARDWARE_REVISION + 2 <= device::SEQ_TAIL);
    assert!(IMAGE_SIZE_OF_VERSION[LAYOUT_VERSION as usize] == IMAGE_SIZE);
    assert!(drive_cmd::EXTRA + 2 * EXTRA_WORDS == drive_cmd::SEQ_TAIL);
    assert!(drive_state::EXTRA + 2 * EXTRA_WORDS == drive_state::SEQ_TAIL);
    assert!(EXTRA_WORDS <= u8::MAX as usize);
    assert!(card::BOOT_ID + 2 <= card::SEQ_TAIL);
    assert!(drive::EXT_DIAG + EXT_DIAG_CAPACITY <= drive::SEQ_TAIL);
    assert!(drive::IRQ_MASK + 2 == drive::SEQ_TAIL);
    assert!(config::PZD_IN_MAP + 2 * PZD_MAP_WORDS <= config::IO_UPDATE_DELAY);
    assert!(config::IO_UPDATE_DELAY + 2 <= config::SEQ_TAIL);
    assert!(MBX_CAPACITY <= u8::MAX as usize);
    assert!(status::CORRUPT_FRAMES + 2 <= status::SEQ_TAIL);
    assert!(PD_CAPACITY <= u8::MAX as usize);
};

/// A block's place and writer: [`BLOCKS`] without the names and texts, for the card's walks
/// over the map at run time (the SPI transport's write check, events and hand-over). Only
/// the host tools and the C header need the texts; a walk over [`BLOCKS`] would link all of
/// them into the firmware (footprint, issue 13 item 1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Span {
    /// Absolute offset.
    pub start: usize,
    /// Length in bytes.
    pub len: usize,
    /// Who writes it.
    pub writer: Writer,
    /// Whether it is a sequenced block (`SEQ_HEAD` / `SEQ_TAIL`).
    pub sequenced: bool,
}

/// [`BLOCKS`] as [`Span`]s, same order (index i = `BLOCKS[i]`).
pub const SPANS: [Span; BLOCKS.len()] = {
    let mut s = [Span { start: 0, len: 0, writer: Writer::Card, sequenced: false }; BLOCKS.len()];
    let mut i = 0;
    while i < BLOCKS.len() {
        let b = &BLOCKS[i];
        s[i] = Span { start: b.start, len: b.len, writer: b.writer, sequenced: b.sequenced };
        i += 1;
    }
    s
};

/// Who writes a field.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Writer {
    /// The card.
    Card,
    /// The host (the drive's control board).
    Host,
}

impl Writer {
    /// "card" / "host".
    pub const fn name(self) -> &'static str {
        match self {
            Writer::Card => "card",
            Writer::Host => "host",
        }
    }
}

/// One block of the map.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Block {
    /// Name as used in [`FIELDS`] (`NAME.FIELD`).
    pub name: &'static str,
    /// Absolute offset.
    pub start: usize,
    /// Length in bytes.
    pub len: usize,
    /// Who writes it.
    pub writer: Writer,
    /// Whether it is a sequenced block (`SEQ_HEAD` / `SEQ_TAIL`).
    pub sequenced: bool,
    /// Layout version that introduced it.
    pub since: u16,
    /// What it holds.
    pub text: &'static str,
}

/// Every block, in address order.
pub const BLOCKS: &[Block] = &[
    Block {
        name: "HEADER",
        start: header::START,
        len: header::LEN,
        writer: Writer::Card,
        sequenced: false,
        since: 1,
        text: "Magic, layout version, image size, capabilities. Written once when the image is created.",
    },
    Block {
        name: "STATUS",
        start: status::START,
        len: status::LEN,
        writer: Writer::Card,
        sequenced: true,
        since: 1,
        text: "Communication state, baud rate, addresses, telegram, DP state, counters. Written when it changes.",
    },
    Block {
        name: "OUTPUTS",
        start: outputs::START,
        len: outputs::LEN,
        writer: Writer::Card,
        sequenced: true,
        since: 1,
        text: "Process data master → drive. Written on every Data_Exchange and when its meaning changes.",
    },
    Block {
        name: "INPUTS",
        start: inputs::START,
        len: inputs::LEN,
        writer: Writer::Host,
        sequenced: true,
        since: 1,
        text: "Process data drive → master (layout 1 / 2 hosts). The card serves an image written for the active telegram until the host first writes DRIVE_STATE; from then on the inputs are built from DRIVE_STATE and INPUTS is ignored.",
    },
    Block {
        name: "IDENT",
        start: ident::START,
        len: ident::LEN,
        writer: Writer::Card,
        sequenced: false,
        since: 2,
        text: "Identification. Written once when the image is created, with the header.",
    },
    Block {
        name: "CARD",
        start: card::START,
        len: card::LEN,
        writer: Writer::Card,
        sequenced: true,
        since: 2,
        text: "Card heartbeat, configuration acknowledge, card → drive event counters. Written on every card cycle.",
    },
    Block {
        name: "DRIVE",
        start: drive::START,
        len: drive::LEN,
        writer: Writer::Host,
        sequenced: true,
        since: 2,
        text: "Drive heartbeat, fault / warning reports, extended diagnosis. Written on every drive cycle.",
    },
    Block {
        name: "CONFIG",
        start: config::START,
        len: config::LEN,
        writer: Writer::Host,
        sequenced: true,
        since: 2,
        text: "Configuration from the drive. Taken over only while no cyclic exchange runs; acknowledged in CARD.",
    },
    Block {
        name: "MBX_REQ",
        start: mbx_req::START,
        len: mbx_req::LEN,
        writer: Writer::Card,
        sequenced: true,
        since: 2,
        text: "Parameter mailbox request. A new REQ_ID is a new request.",
    },
    Block {
        name: "MBX_RSP",
        start: mbx_rsp::START,
        len: mbx_rsp::LEN,
        writer: Writer::Host,
        sequenced: true,
        since: 2,
        text: "Parameter mailbox response. Taken only when REQ_ID names the outstanding request.",
    },
    Block {
        name: "DRIVE_CMD",
        start: drive_cmd::START,
        len: drive_cmd::LEN,
        writer: Writer::Card,
        sequenced: true,
        since: 3,
        text: "Drive-neutral command (run / stop kinds, setpoint, fault resets, …), operate mode, telegram, extra PZD output words. Written after OUTPUTS in the same card cycle.",
    },
    Block {
        name: "DRIVE_STATE",
        start: drive_state::START,
        len: drive_state::LEN,
        writer: Writer::Host,
        sequenced: true,
        since: 3,
        text: "Drive-neutral status (state bits, speed, current, torque, power, fault, warning, NAMUR), extra PZD input words. Written after INPUTS every drive cycle.",
    },
    Block {
        name: "DEVICE",
        start: device::START,
        len: device::LEN,
        writer: Writer::Host,
        sequenced: true,
        since: 4,
        text: "The drive's serial number and hardware revision, which the card reports in I&M0 (DP-V1 slot 0 index 255). Written once after the drive starts.",
    },
];

/// One field of the map.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Field {
    /// `BLOCK.FIELD`.
    pub name: &'static str,
    /// Absolute offset.
    pub offset: usize,
    /// Size in bytes.
    pub size: usize,
    /// Type: `u8`, `u16`, `i16`, `u32`, `u8[n]`, `u16[n]` or `reserved`.
    pub ty: &'static str,
    /// Who writes it.
    pub writer: Writer,
    /// When the value is valid, and what it means.
    pub valid: &'static str,
}

impl Field {
    /// Byte order: big-endian for multi-byte integers, none for bytes.
    pub fn byte_order(&self) -> &'static str {
        if self.ty.starts_with("u16") || self.ty.starts_with("i16") || self.ty.starts_with("u32") {
            "big-endian"
        } else {
            "-"
        }
    }
}

const C: Writer = Writer::Card;
const H: Writer = Writer::Host;

macro_rules! f {
    ($name:literal, $block:ident :: $field:ident, $size:expr, $ty:literal, $w:expr, $valid:expr) => {
        Field { name: $name, offset: $block::START + $block::$field, size: $size, ty: $ty, writer: $w, valid: $valid }
    };
    ($name:literal, @ $off:expr, $size:expr, $ty:literal, $w:expr, $valid:expr) => {
        Field { name: $name, offset: $off, size: $size, ty: $ty, writer: $w, valid: $valid }
    };
}

const SEQ_VALID: &str = "sequence counter, 0 = never written; head = tail: the block is consistent";
const PD: usize = PD_CAPACITY;

/// Every byte of the image, in address order (reserved bytes included). `docs/DPM.md` is
/// generated from this table and the tests check it covers the image exactly.
pub const FIELDS: &[Field] = &[
    f!("HEADER.MAGIC", header::MAGIC, 4, "u8[4]", C, "always: ASCII \"PBDM\""),
    f!("HEADER.LAYOUT_VERSION", header::LAYOUT_VERSION, 2, "u16", C, "always: 4 (read first, with the magic; 1, 2 and 3 are prefixes of 4)"),
    f!("HEADER.IMAGE_SIZE", header::IMAGE_SIZE, 2, "u16", C, "always: bytes in the image (752; version 1: 192, version 2: 624, version 3: 728)"),
    f!("HEADER.CAPABILITIES", header::CAPABILITIES, 4, "u32", C, "always (version >= 2): bit 0 IDENT, 1 CARD events, 2 DRIVE reports, 3 CONFIG, 4 MAILBOX, 5 DRIVE_CMD, 6 DRIVE_STATE, 7 DEVICE"),
    f!("HEADER.reserved", @ header::START + 0x0C, 4, "reserved", C, "0"),
    f!("STATUS.SEQ_HEAD", status::SEQ_HEAD, 2, "u16", C, SEQ_VALID),
    f!("STATUS.COMM_STATE", status::COMM_STATE, 1, "u8", C, "consistent block: P0740 coding 0 inactive, 1 init error, 2 offline, 3 cfg error, 4 prm error, 5 clear, 6 online"),
    f!("STATUS.BAUD", status::BAUD, 1, "u8", C, "consistent block: P0963 coding, 5 = not detected"),
    f!("STATUS.STATION_ADDRESS", status::STATION_ADDRESS, 1, "u8", C, "consistent block: own address 0..=126"),
    f!("STATUS.MASTER_ADDRESS", status::MASTER_ADDRESS, 1, "u8", C, "consistent block: master holding the lock, 0xFF = none"),
    f!("STATUS.TELEGRAM", status::TELEGRAM, 2, "u16", C, "consistent block: 0 none, n = standard telegram n (< 0x4000), 0x4000|family<<8|n = vendor telegram n (family 1 VACON, 2 CFW500, 3 CFW-11, 4 INVT), 0x8000|n = PPO n"),
    f!("STATUS.DP_STATE", status::DP_STATE, 1, "u8", C, "consistent block: 0 Wait_Prm, 1 Wait_Cfg, 2 Data_Exch"),
    f!("STATUS.FLAGS", status::FLAGS, 1, "u8", C, "consistent block: bit 0 clear, 1 sync, 2 freeze, 3 watchdog on, 4 address locked"),
    f!("STATUS.WATCHDOG_MS", status::WATCHDOG_MS, 2, "u16", C, "consistent block: DP watchdog ms, 0 = off"),
    f!("STATUS.DATA_EXCHANGES", status::DATA_EXCHANGES, 4, "u32", C, "consistent block: Data_Exchange count (wraps)"),
    f!("STATUS.PRM_FAULTS", status::PRM_FAULTS, 2, "u16", C, "consistent block: Set_Prm refused (wraps)"),
    f!("STATUS.CFG_FAULTS", status::CFG_FAULTS, 2, "u16", C, "consistent block: Chk_Cfg refused (wraps)"),
    f!("STATUS.WATCHDOG_EXPIRIES", status::WATCHDOG_EXPIRIES, 2, "u16", C, "consistent block: DP watchdog expiries (wraps)"),
    f!("STATUS.CORRUPT_FRAMES", status::CORRUPT_FRAMES, 2, "u16", C, "consistent block: corrupt telegrams (wraps)"),
    f!("STATUS.reserved", @ status::START + status::CORRUPT_FRAMES + 2, status::SEQ_TAIL - status::CORRUPT_FRAMES - 2, "reserved", C, "0"),
    f!("STATUS.SEQ_TAIL", status::SEQ_TAIL, 2, "u16", C, SEQ_VALID),
    f!("OUTPUTS.SEQ_HEAD", @ outputs::START + pd::SEQ_HEAD, 2, "u16", C, SEQ_VALID),
    f!("OUTPUTS.TELEGRAM", @ outputs::START + pd::TELEGRAM, 2, "u16", C, "consistent block: layout of DATA (STATUS.TELEGRAM coding)"),
    f!("OUTPUTS.LEN", @ outputs::START + pd::LEN, 1, "u8", C, "consistent block: valid bytes of DATA (<= 64)"),
    f!("OUTPUTS.FLAGS", @ outputs::START + pd::FLAGS, 1, "u8", C, "consistent block: bit 0 data exchange, bit 1 clear (data all zero)"),
    f!("OUTPUTS.DATA", @ outputs::START + pd::DATA, PD, "u8[64]", C, "consistent block, first LEN bytes: the master's outputs as on the wire (big-endian words)"),
    f!("OUTPUTS.SEQ_TAIL", @ outputs::START + pd::SEQ_TAIL, 2, "u16", C, SEQ_VALID),
    f!("INPUTS.SEQ_HEAD", @ inputs::START + pd::SEQ_HEAD, 2, "u16", H, SEQ_VALID),
    f!("INPUTS.TELEGRAM", @ inputs::START + pd::TELEGRAM, 2, "u16", H, "consistent block: layout of DATA; taken only if it is the active telegram"),
    f!("INPUTS.LEN", @ inputs::START + pd::LEN, 1, "u8", H, "consistent block: valid bytes of DATA (<= 64)"),
    f!("INPUTS.FLAGS", @ inputs::START + pd::FLAGS, 1, "u8", H, "consistent block: 0 (reserved flags)"),
    f!("INPUTS.DATA", @ inputs::START + pd::DATA, PD, "u8[64]", H, "consistent block, first LEN bytes: the drive's inputs as on the wire"),
    f!("INPUTS.SEQ_TAIL", @ inputs::START + pd::SEQ_TAIL, 2, "u16", H, SEQ_VALID),
    f!("IDENT.CARD_TYPE", ident::CARD_TYPE, 2, "u16", C, "once the magic is valid: card type (0x0DB1 = this PROFIBUS DP-V1 card)"),
    f!("IDENT.FW_MAJOR", ident::FW_MAJOR, 1, "u8", C, "once the magic is valid: firmware major version"),
    f!("IDENT.FW_MINOR", ident::FW_MINOR, 1, "u8", C, "once the magic is valid: firmware minor version"),
    f!("IDENT.FW_PATCH", ident::FW_PATCH, 1, "u8", C, "once the magic is valid: firmware patch version"),
    f!("IDENT.reserved", @ ident::START + 0x05, 1, "reserved", C, "0"),
    f!("IDENT.IDENT_NUMBER", ident::IDENT_NUMBER, 2, "u16", C, "once the magic is valid: PROFIBUS ident number"),
    f!("IDENT.SERIAL", ident::SERIAL, 4, "u32", C, "once the magic is valid: serial number, 0 = not programmed"),
    f!("IDENT.reserved", @ ident::START + 0x0C, 4, "reserved", C, "0"),
    f!("CARD.SEQ_HEAD", card::SEQ_HEAD, 2, "u16", C, SEQ_VALID),
    f!("CARD.HEARTBEAT", card::HEARTBEAT, 2, "u16", C, "consistent block: changes every card cycle; unchanged for the drive's timeout = card lost"),
    f!("CARD.FLAGS", card::FLAGS, 1, "u8", C, "consistent block: bit 0 drive heartbeat lost, bit 1 configuration pending, bit 2 card fault"),
    f!("CARD.CONFIG_RESULT", card::CONFIG_RESULT, 1, "u8", C, "consistent block, CONFIG_ACK != 0: 1 taken over, 2 pending (cyclic exchange runs), 3 refused (invalid, or a telegram without a module; nothing applied), 4 taken over but STATION_ADDRESS kept (No_Add_Chg froze it)"),
    f!("CARD.CONFIG_ACK", card::CONFIG_ACK, 2, "u16", C, "consistent block: the CONFIG.SEQ_HEAD the result is about, 0 = none"),
    f!("CARD.EVENTS", card::EVENTS, 8, "u8[8]", C, "consistent block: counters, a change = event: 0 clear mode, 1 offline, 2 online, 3 watchdog, 4 prm error, 5 cfg error, 6 card fault, 7 drive heartbeat returned"),
    f!("CARD.DRIVE_LOSSES", card::DRIVE_LOSSES, 2, "u16", C, "consistent block: drive heartbeat losses (wraps)"),
    f!("CARD.LATE_RESPONSES", card::LATE_RESPONSES, 2, "u16", C, "consistent block: mailbox responses ignored, late or unknown REQ_ID (wraps)"),
    f!("CARD.MAILBOX_TIMEOUTS", card::MAILBOX_TIMEOUTS, 2, "u16", C, "consistent block: mailbox requests timed out (wraps)"),
    // --- issue 16 (restart rules) ---
    f!("CARD.BOOT_ID", card::BOOT_ID, 2, "u16", C, "consistent block, layout 3 cards since issue 16 (0 = an older card): changes on every card start (panic / watchdog resets included), never 0; a new value = the card restarted: the host re-opens, rewrites CONFIG and resynchronises the event counters"),
    f!("CARD.reserved", @ card::START + card::BOOT_ID + 2, card::SEQ_TAIL - card::BOOT_ID - 2, "reserved", C, "0"),
    // --- end issue 16 ---
    f!("CARD.SEQ_TAIL", card::SEQ_TAIL, 2, "u16", C, SEQ_VALID),
    f!("DRIVE.SEQ_HEAD", drive::SEQ_HEAD, 2, "u16", H, SEQ_VALID),
    f!("DRIVE.HEARTBEAT", drive::HEARTBEAT, 2, "u16", H, "consistent block: changes every drive cycle; unchanged for the card's timeout = drive lost"),
    f!("DRIVE.FAULT_CODE", drive::FAULT_CODE, 2, "u16", H, "consistent block: active fault, 0 = none"),
    f!("DRIVE.WARNING_CODE", drive::WARNING_CODE, 2, "u16", H, "consistent block: active warning, 0 = none"),
    f!("DRIVE.FAULT_COUNT", drive::FAULT_COUNT, 1, "u8", H, "consistent block: fault reports (wraps), a change = new fault"),
    f!("DRIVE.WARNING_COUNT", drive::WARNING_COUNT, 1, "u8", H, "consistent block: warning reports (wraps), a change = new warning"),
    f!("DRIVE.EXT_DIAG_LEN", drive::EXT_DIAG_LEN, 1, "u8", H, "consistent block: valid bytes of EXT_DIAG (<= 32)"),
    f!("DRIVE.reserved", @ drive::START + 0x0B, 1, "reserved", H, "0"),
    f!("DRIVE.EXT_DIAG", drive::EXT_DIAG, EXT_DIAG_CAPACITY, "u8[32]", H, "consistent block, first EXT_DIAG_LEN bytes: DP extended diagnosis blocks (refused if malformed)"),
    f!("DRIVE.IRQ_MASK", drive::IRQ_MASK, 2, "u16", H, "consistent block (SPI transport): bits of the pending-events bitmap that do not assert the IRQ line (bit set = masked; 0 = every event asserts it, as before this field); the bitmap itself and the block events are not masked"),
    f!("DRIVE.SEQ_TAIL", drive::SEQ_TAIL, 2, "u16", H, SEQ_VALID),
    f!("CONFIG.SEQ_HEAD", config::SEQ_HEAD, 2, "u16", H, SEQ_VALID),
    f!("CONFIG.STATION_ADDRESS", config::STATION_ADDRESS, 1, "u8", H, "consistent block, SEQ != 0: station address 0..=125, set outside data exchange like Set_Slave_Add (reported as a changed address and stored; refused with result 4 while No_Add_Chg froze it); 126 = keep the card's address"),
    f!("CONFIG.PROFILE", config::PROFILE, 1, "u8", H, "consistent block, SEQ != 0: 0 PROFIdrive, 1 manufacturer"),
    f!("CONFIG.OPERATE_MODE", config::OPERATE_MODE, 1, "u8", H, "consistent block, SEQ != 0: operate mode when the master's Set_Prm user parameter leaves it 0 (DRIVE_CMD.OPERATE_MODE coding): 0 the card's default (PROFIdrive), 1 PROFIdrive, 2 Bypass, 3 Echo; other values: CONFIG refused"),
    f!("CONFIG.COMM_LOSS_REACTION", config::COMM_LOSS_REACTION, 1, "u8", H, "consistent block, SEQ != 0: the drive's communication-loss reaction (P0313-style), used when the master's Set_Prm reaction is 0; DRIVE_CMD coding: 0 its own setting, 1 ramp stop, 2 coast, 3 quick stop, 4 keep last setpoint, 5 change to local, 6 change to local keeping commands and reference, 7 fault (WEG P0313 options 3 / 4 / 5); others make CONFIG invalid"),
    f!("CONFIG.TELEGRAM", config::TELEGRAM, 2, "u16", H, "consistent block, SEQ != 0: telegram selection (STATUS.TELEGRAM coding): 0 = any module; else Chk_Cfg with another module is a Cfg_Fault and PNU 922 shows this telegram"),
    f!("CONFIG.COMM_LOSS_DELAY_MS", config::COMM_LOSS_DELAY_MS, 2, "u16", H, "consistent block, SEQ != 0: communication-loss delay in ms (P0314-style; 0 = none): a loss shorter than this is bridged — DRIVE_CMD keeps the last command without bit 12 (COMM_LOSS) — a longer one sets bit 12 with the reaction"),
    f!("CONFIG.PZD_OUT_MAP", config::PZD_OUT_MAP, 16, "u16[8]", H, "reserved in this firmware (accepted, not used; write 0): PNU of output PZD3..PZD10 — the extra words reach the drive raw in DRIVE_CMD.EXTRA"),
    f!("CONFIG.PZD_IN_MAP", config::PZD_IN_MAP, 16, "u16[8]", H, "reserved in this firmware (accepted, not used; write 0): PNU of input PZD3..PZD10 — the drive sends the extra words raw in DRIVE_STATE.EXTRA"),
    f!("CONFIG.IO_UPDATE_DELAY", config::IO_UPDATE_DELAY, 2, "u16", H, "consistent block, SEQ != 0: I/O update delay in 0.1 s (P0799-style, 0..=9990; 0 = none; a v3 host that leaves it 0 has none): after going online (and after Clear) the drive keeps its previous command this long, then the newest outputs apply"),
    f!("CONFIG.reserved", @ config::START + config::IO_UPDATE_DELAY + 2, config::SEQ_TAIL - config::IO_UPDATE_DELAY - 2, "reserved", H, "0"),
    f!("CONFIG.SEQ_TAIL", config::SEQ_TAIL, 2, "u16", H, SEQ_VALID),
    f!("MBX_REQ.SEQ_HEAD", mbx_req::SEQ_HEAD, 2, "u16", C, SEQ_VALID),
    f!("MBX_REQ.REQ_ID", mbx_req::REQ_ID, 2, "u16", C, "consistent block: request identifier, a new value = a new request, 0 = none"),
    f!("MBX_REQ.KIND", mbx_req::KIND, 1, "u8", C, "consistent block, REQ_ID != 0: 1 read value, 2 write value, 3 read description"),
    f!("MBX_REQ.AXIS", mbx_req::AXIS, 1, "u8", C, "consistent block, REQ_ID != 0: axis / DO-ID"),
    f!("MBX_REQ.PNU", mbx_req::PNU, 2, "u16", C, "consistent block, REQ_ID != 0: parameter number"),
    f!("MBX_REQ.SUBINDEX", mbx_req::SUBINDEX, 2, "u16", C, "consistent block, REQ_ID != 0: first element / description element"),
    f!("MBX_REQ.COUNT", mbx_req::COUNT, 1, "u8", C, "consistent block, REQ_ID != 0: number of elements (0 counts as 1)"),
    f!("MBX_REQ.FORMAT", mbx_req::FORMAT, 1, "u8", C, "consistent block, KIND = 2: PROFIdrive format of VALUES"),
    f!("MBX_REQ.VALUES_LEN", mbx_req::VALUES_LEN, 1, "u8", C, "consistent block, KIND = 2: valid bytes of VALUES (<= 128)"),
    f!("MBX_REQ.reserved", @ mbx_req::START + 0x0D, 1, "reserved", C, "0"),
    f!("MBX_REQ.VALUES", mbx_req::VALUES, MBX_CAPACITY, "u8[128]", C, "consistent block, KIND = 2, first VALUES_LEN bytes: the values, big-endian"),
    f!("MBX_REQ.SEQ_TAIL", mbx_req::SEQ_TAIL, 2, "u16", C, SEQ_VALID),
    f!("MBX_RSP.SEQ_HEAD", mbx_rsp::SEQ_HEAD, 2, "u16", H, SEQ_VALID),
    f!("MBX_RSP.REQ_ID", mbx_rsp::REQ_ID, 2, "u16", H, "consistent block: the MBX_REQ.REQ_ID answered"),
    f!("MBX_RSP.RESULT", mbx_rsp::RESULT, 1, "u8", H, "consistent block: 0 values (read) / done (write), 1 error"),
    f!("MBX_RSP.FORMAT", mbx_rsp::FORMAT, 1, "u8", H, "consistent block, RESULT = 0: PROFIdrive format of VALUES"),
    f!("MBX_RSP.COUNT", mbx_rsp::COUNT, 1, "u8", H, "consistent block, RESULT = 0: number of values"),
    f!("MBX_RSP.VALUES_LEN", mbx_rsp::VALUES_LEN, 1, "u8", H, "consistent block, RESULT = 0: valid bytes of VALUES (<= 128)"),
    f!("MBX_RSP.ERROR", mbx_rsp::ERROR, 2, "u16", H, "consistent block, RESULT = 1: PROFIdrive error value"),
    f!("MBX_RSP.ERROR_INFO", mbx_rsp::ERROR_INFO, 2, "u16", H, "consistent block, RESULT = 1, HAS_INFO = 1: additional information"),
    f!("MBX_RSP.HAS_INFO", mbx_rsp::HAS_INFO, 1, "u8", H, "consistent block, RESULT = 1: 1 = ERROR_INFO valid"),
    f!("MBX_RSP.reserved", @ mbx_rsp::START + 0x0D, 1, "reserved", H, "0"),
    f!("MBX_RSP.VALUES", mbx_rsp::VALUES, MBX_CAPACITY, "u8[128]", H, "consistent block, RESULT = 0, first VALUES_LEN bytes: the values, big-endian"),
    f!("MBX_RSP.SEQ_TAIL", mbx_rsp::SEQ_TAIL, 2, "u16", H, SEQ_VALID),
    f!("DRIVE_CMD.SEQ_HEAD", drive_cmd::SEQ_HEAD, 2, "u16", C, SEQ_VALID),
    f!("DRIVE_CMD.FLAGS", drive_cmd::FLAGS, 2, "u16", C, "consistent block, SEQ != 0: command bits: 0 run, 1 reverse, 2 coast, 3 quick stop, 4 ramp hold, 5 setpoint zero, 6 ramp reset, 7 fieldbus control, 8 jog 1, 9 jog 2, 10 ramp set 2, 11 pre-excite, 12 communication lost, 13 fieldbus fault"),
    f!("DRIVE_CMD.SPEED_SETPOINT", drive_cmd::SPEED_SETPOINT, 2, "i16", C, "consistent block, SEQ != 0: speed setpoint N2, 0x4000 = 100 % of the reference speed, negative = reverse"),
    f!("DRIVE_CMD.FAULT_RESETS", drive_cmd::FAULT_RESETS, 1, "u8", C, "consistent block, SEQ != 0: fault acknowledges so far (wraps), a change = acknowledge"),
    f!("DRIVE_CMD.COMM_LOSS_REACTION", drive_cmd::COMM_LOSS_REACTION, 1, "u8", C, "consistent block, FLAGS bit 12: 0 drive's own setting, 1 ramp stop, 2 coast, 3 quick stop, 4 keep last setpoint, 5 change to local, 6 change to local keeping commands and reference, 7 fault (WEG P0313 options 3 / 4 / 5)"),
    f!("DRIVE_CMD.OPERATE_MODE", drive_cmd::OPERATE_MODE, 1, "u8", C, "consistent block, SEQ != 0: 0 unknown, 1 PROFIdrive, 2 Bypass, 3 Echo (OPTE3/E5 Table 9)"),
    f!("DRIVE_CMD.EXTRA_COUNT", drive_cmd::EXTRA_COUNT, 1, "u8", C, "consistent block, SEQ != 0: valid words of EXTRA (<= 16)"),
    f!("DRIVE_CMD.TELEGRAM", drive_cmd::TELEGRAM, 2, "u16", C, "consistent block, SEQ != 0: active telegram (STATUS.TELEGRAM coding)"),
    f!("DRIVE_CMD.OUTPUTS_SEQ", drive_cmd::OUTPUTS_SEQ, 2, "u16", C, "consistent block, SEQ != 0: OUTPUTS.SEQ_HEAD this command was made from, 0 = none (pair check)"),
    f!("DRIVE_CMD.EXTRA", drive_cmd::EXTRA, 32, "u16[16]", C, "consistent block, first EXTRA_COUNT words: raw PZD output words (programmable words)"),
    f!("DRIVE_CMD.SEQ_TAIL", drive_cmd::SEQ_TAIL, 2, "u16", C, SEQ_VALID),
    f!("DRIVE_STATE.SEQ_HEAD", drive_state::SEQ_HEAD, 2, "u16", H, SEQ_VALID),
    f!("DRIVE_STATE.FLAGS", drive_state::FLAGS, 2, "u16", H, "consistent block, SEQ != 0: status bits: 0 ready, 1 running, 2 reverse, 3 fault, 4 warning, 5 at reference, 6 zero speed, 7 flux ready, 8 fieldbus control, 9 speed reached, 10 limit, 11 motor overload, 12 jogging, 13 undervoltage, 14 ramp set 2"),
    f!("DRIVE_STATE.SPEED", drive_state::SPEED, 2, "i16", H, "consistent block, SEQ != 0: actual speed N2, 0x4000 = 100 % of the reference speed"),
    f!("DRIVE_STATE.CURRENT", drive_state::CURRENT, 2, "i16", H, "consistent block, SEQ != 0: output current N2, 0x4000 = rated current"),
    f!("DRIVE_STATE.TORQUE", drive_state::TORQUE, 2, "i16", H, "consistent block, SEQ != 0: torque N2, 0x4000 = rated torque"),
    f!("DRIVE_STATE.POWER", drive_state::POWER, 2, "i16", H, "consistent block, SEQ != 0: active power N2, 0x4000 = rated power"),
    f!("DRIVE_STATE.FAULT_CODE", drive_state::FAULT_CODE, 2, "u16", H, "consistent block, SEQ != 0: active fault, 0 = none"),
    f!("DRIVE_STATE.WARNING_CODE", drive_state::WARNING_CODE, 2, "u16", H, "consistent block, SEQ != 0: active warning, 0 = none"),
    f!("DRIVE_STATE.NAMUR", drive_state::NAMUR, 2, "u16", H, "consistent block, SEQ != 0: MELD_NAMUR bits of the active fault"),
    f!("DRIVE_STATE.INPUTS_SEQ", drive_state::INPUTS_SEQ, 2, "u16", H, "consistent block, SEQ != 0: INPUTS.SEQ_HEAD written with this state, 0 = none (pair check)"),
    f!("DRIVE_STATE.EXTRA_COUNT", drive_state::EXTRA_COUNT, 1, "u8", H, "consistent block, SEQ != 0: valid words of EXTRA (<= 16)"),
    f!("DRIVE_STATE.reserved", @ drive_state::START + drive_state::EXTRA_COUNT + 1, 1, "reserved", H, "0"),
    f!("DRIVE_STATE.EXTRA", drive_state::EXTRA, 32, "u16[16]", H, "consistent block, first EXTRA_COUNT words: raw PZD input words (programmable words)"),
    f!("DRIVE_STATE.SEQ_TAIL", drive_state::SEQ_TAIL, 2, "u16", H, SEQ_VALID),
    f!("DEVICE.SEQ_HEAD", device::SEQ_HEAD, 2, "u16", H, SEQ_VALID),
    f!("DEVICE.SERIAL_NUMBER", device::SERIAL_NUMBER, 16, "u8[16]", H, "consistent block, SEQ != 0: I&M0 SERIAL_NUMBER of the drive, visible string blank-padded (other bytes read as blanks); SEQ = 0: blanks"),
    f!("DEVICE.HARDWARE_REVISION", device::HARDWARE_REVISION, 2, "u16", H, "consistent block, SEQ != 0: I&M0 HARDWARE_REVISION of the drive; 0 or SEQ = 0: the card's own (card::IM_HARDWARE_REVISION)"),
    f!("DEVICE.reserved", @ device::START + device::HARDWARE_REVISION + 2, device::SEQ_TAIL - device::HARDWARE_REVISION - 2, "reserved", H, "0"),
    f!("DEVICE.SEQ_TAIL", device::SEQ_TAIL, 2, "u16", H, SEQ_VALID),
];

/// Write the map as Markdown (the content of `docs/DPM.md`).
pub fn write_markdown(out: &mut impl core::fmt::Write) -> core::fmt::Result {
    writeln!(out, "# DPM memory map, layout version {LAYOUT_VERSION}")?;
    writeln!(out)?;
    writeln!(out, "<!-- Generated from crates/dpm/src/dpm/layout.rs (FIELDS, BLOCKS). Do not edit: run")?;
    writeln!(
        out,
        "     DPM_DOC_WRITE=1 cargo test -p pbcard-dpm --lib --target x86_64-unknown-linux-gnu dpm::tests_v2::doc_is_current -->"
    )?;
    writeln!(out)?;
    writeln!(out, "Image size {IMAGE_SIZE} bytes (0x{IMAGE_SIZE:X}). All multi-byte integers are big-endian. Offsets are absolute.")?;
    writeln!(
        out,
        "Reserved bytes are written as 0 and must be ignored. The host reads the header first: magic \"PBDM\","
    )?;
    writeln!(out, "`LAYOUT_VERSION` (a newer version only appends blocks), `IMAGE_SIZE` and `CAPABILITIES`.")?;
    writeln!(out)?;
    writeln!(out, "**Sequenced blocks.** `SEQ_HEAD` (first word) and `SEQ_TAIL` (last word) hold the same counter")?;
    writeln!(
        out,
        "(1..=65535, then 1; 0 = never written) once a write is complete. The host reads and writes a block"
    )?;
    writeln!(out, "in one ascending pass (head, payload, tail); the card writes tail, payload, head and reads tail,")?;
    writeln!(out, "payload, head. Counters that differ mean the read was torn: read again. A field of a sequenced")?;
    writeln!(out, "block is valid only in a read whose counters are equal (\"consistent block\").")?;
    writeln!(out)?;
    writeln!(
        out,
        "**Mailbox.** The card writes MBX_REQ with a new `REQ_ID`; the host answers in MBX_RSP with the same"
    )?;
    writeln!(
        out,
        "`REQ_ID`. The card ignores a response naming another id (late answer). Without an answer within its"
    )?;
    writeln!(
        out,
        "timeout the card answers the request itself with PROFIdrive error 0x11 and additional info 0xDD01;"
    )?;
    writeln!(out, "while the drive heartbeat is lost, with 0x11 / 0xDD02.")?;
    writeln!(out)?;
    writeln!(out, "**Command and state (v3).** The card writes OUTPUTS, then DRIVE_CMD with `OUTPUTS_SEQ` = the")?;
    writeln!(out, "OUTPUTS counter it was made from; the host accepts a DRIVE_CMD / OUTPUTS pair as one bus cycle")?;
    writeln!(out, "when `DRIVE_CMD.OUTPUTS_SEQ` equals `OUTPUTS.SEQ_HEAD` (or is 0), else reads both again. The")?;
    writeln!(out, "host writes INPUTS, then DRIVE_STATE with `INPUTS_SEQ` = the INPUTS counter it just wrote. The")?;
    writeln!(out, "card serves INPUTS to the master only until DRIVE_STATE is first written (a layout 1 / 2 host);")?;
    writeln!(out, "afterwards the card's profile layer builds the inputs from DRIVE_STATE and ignores INPUTS.")?;
    writeln!(out)?;
    writeln!(
        out,
        "**Heartbeats.** The host writes DRIVE every drive cycle with a changed `HEARTBEAT`; the card writes"
    )?;
    writeln!(out, "CARD every card cycle with a changed `HEARTBEAT`. Each side counts the other lost when the value")?;
    writeln!(out, "stays unchanged for longer than its timeout (the drive: the A140 situation). `dpm-host/` is the")?;
    writeln!(out, "host-side reference implementation of all of this.")?;
    writeln!(out)?;
    writeln!(out, "## Blocks")?;
    writeln!(out)?;
    writeln!(out, "| Block | Offset | Size | Writer | Sequenced | Since | Content |")?;
    writeln!(out, "|---|---|---|---|---|---|---|")?;
    for b in BLOCKS {
        let seq = if b.sequenced { "yes" } else { "no" };
        writeln!(
            out,
            "| {} | 0x{:03X} | {} | {} | {} | v{} | {} |",
            b.name,
            b.start,
            b.len,
            b.writer.name(),
            seq,
            b.since,
            b.text
        )?;
    }
    writeln!(out)?;
    writeln!(out, "## Fields")?;
    writeln!(out)?;
    writeln!(out, "| Field | Offset | Size | Type | Byte order | Writer | Valid / meaning |")?;
    writeln!(out, "|---|---|---|---|---|---|---|")?;
    for f in FIELDS {
        writeln!(
            out,
            "| {} | 0x{:03X} | {} | {} | {} | {} | {} |",
            f.name,
            f.offset,
            f.size,
            f.ty,
            f.byte_order(),
            f.writer.name(),
            f.valid
        )?;
    }
    Ok(())
}
