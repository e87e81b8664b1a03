//! The DPM memory map, layout version 1: every offset the card and the host use, in one place.
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
//! 0xC0  end (IMAGE_SIZE = 192)
//! ```
//!
//! STATUS, OUTPUTS and INPUTS are *sequenced blocks*: the first word (`SEQ_HEAD`) and the last
//! word (`SEQ_TAIL`) hold the same sequence counter once a write is complete (see
//! [`super`] for the protocol). Later layout versions (parameter mailbox, events,
//! configuration, heartbeat) append blocks after `0xC0`; the offsets below do not move.

/// `HEADER.MAGIC` value: ASCII "PBDM".
pub const MAGIC: [u8; 4] = *b"PBDM";
/// `HEADER.LAYOUT_VERSION` value of this map.
pub const LAYOUT_VERSION: u16 = 1;

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

/// Size of the whole image.
pub const IMAGE_SIZE: usize = inputs::START + inputs::LEN;

const _: () = {
    assert!(header::START + header::LEN == status::START);
    assert!(status::START + status::LEN == outputs::START);
    assert!(outputs::START == 0x30 && inputs::START == 0x78 && IMAGE_SIZE == 0xC0);
    assert!(status::CORRUPT_FRAMES + 2 <= status::SEQ_TAIL);
    assert!(PD_CAPACITY >= crate::card::MAX_INPUT_LEN && PD_CAPACITY >= crate::card::MAX_OUTPUT_LEN);
    assert!(PD_CAPACITY <= u8::MAX as usize);
};
