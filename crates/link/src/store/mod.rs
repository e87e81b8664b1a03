//! What the card keeps across power loss — the station address with No_Add_Chg (reference
//! §3.9: Set_Slave_Add must survive a power cut) and I&M1–I&M4 (reference §4.7, issue 12) —
//! in **one** journal, safe against power loss at any moment.
//!
//! [`Journal`] is an append-only log of typed records in two flash sectors behind the tiny
//! [`Flash`] trait (NOR semantics: erase sets every byte to 0xFF, programming can only clear
//! bits). A record type implements [`Record`] (a kind byte, a fixed payload length, encode and
//! decode); the card has two: [`StationAddress`] and [`ImData`](crate::dpv1::im::ImData)
//! (`store/im.rs`). The board maps the trait's sectors 0 and 1 to two real sectors (STM32F411:
//! sectors 1 and 2, 16 KiB each = 64 slots each, `crates/bsp/src/flash.rs`).
//!
//! * **Save** appends a record of one kind with the next sequence number (one counter for all
//!   kinds) to the first empty slot of the *active* sector, the one holding the newest record.
//!   Nothing is written when the newest record of that kind already holds the same payload.
//! * **Compaction.** When the active sector has no room, the *other* sector is erased, the
//!   newest record of every other kind is copied into it (new sequence numbers, same payload),
//!   then the new record is written there. The full sector is not touched, so until the copies
//!   are complete it still holds every kind's newest record.
//! * **Completing an interrupted compaction.** A power cut after the first copy leaves the
//!   active sector with some kinds only: the newest records of the others are still in the full
//!   sector. The next save copies them over first (before its own record), so no sector that
//!   holds a kind's newest record is ever erased.
//! * **Load** of a kind: the valid record of that kind with the highest sequence number in
//!   either sector.
//!
//! **Why a torn write can never be mistaken for a record.** Flash failures from power loss are
//! *unidirectional*: an interrupted program leaves some bits still 1 that should have become 0,
//! and an interrupted erase turns some 0 bits into 1. Besides a CRC-16, every slot carries a
//! Berger check — the number of 0 bits in all its other bytes. Turning 0s into 1s lowers that
//! number in the data but can only raise the stored count, so *every* such corruption is
//! detected, deterministically (the CRC catches random bit rot on top). So each kind always
//! loads its previous or its new value — never garbage, never nothing once a save of that
//! kind completed — and a save of one kind never disturbs another kind, whatever the moment of
//! the cut (the tests cut after every single byte step, `tests::power_cut_at_every_step_*`).
//!
//! Slot layout ([`SLOT_SIZE`] = 256 bytes; programmed in two [`Flash::program`] calls, header
//! and payload first, the check bytes last; the padding stays erased):
//!
//! | bytes | content |
//! |---|---|
//! | 0..4 | sequence number, u32 little-endian, first record = 1 |
//! | 4 | kind ([`Record::KIND`]; 0x00 and 0xFF are never kinds) |
//! | 5 | payload length ([`Record::LEN`], at most [`MAX_PAYLOAD`] = 246) |
//! | 6..6+len | payload ([`Record::encode`]) |
//! | 6+len..252 | padding, 0xFF |
//! | 252..254 | CRC-16/CCITT-FALSE (the `crc` crate's `CRC_16_IBM_3740`) over bytes 0..6+len, big-endian |
//! | 254..256 | Berger check: number of 0 bits in bytes 0..254, u16 big-endian |
//!
//! The slot format replaced the address-only journal of 16-byte records (session 4): a card
//! updated from that firmware finds no record it knows and starts at its default address once
//! (README, "Flash store").

use crate::dp::slave_add::AddressStore;
use crate::fdl::telegram::MAX_STATION_ADDRESS;

pub mod im;

/// A flash device with two erasable sectors (NOR semantics) — the board contract of the
/// store (issue 13 item 3; README "Hardware"): the F411's sectors 1 and 2
/// (`crates/bsp/src/flash.rs` `JournalFlash`), the soft slave's state file (`softslave/src/state.rs`
/// `FileFlash`); QEMU has no store (RAM only).
///
/// The one method of the contract that **blocks**: an erase or program returns when the
/// operation is complete (F411: up to ≈ 0.5 s for a 16 KiB erase, every instruction fetch from
/// flash stalled meanwhile; the file: written through and synced). So the journal runs at the
/// lowest priority only (the firmware's housekeeping task, after silencing the line; the
/// soft slave's loop between two steps), never from the line or the protocol core. An
/// operation cut by a power loss may leave any mix of old and new bits (only 1 → 0 for a
/// program, only 0 → 1 for an erase): the journal's slot checks rely on that, nothing more.
pub trait Flash {
    /// Bytes per sector (the journal uses `SECTOR_SIZE / SLOT_SIZE` slots per sector).
    const SECTOR_SIZE: u32;
    /// Why an erase or program failed.
    type Error;
    /// Set every byte of `sector` (0 or 1) to 0xFF.
    fn erase(&mut self, sector: u8) -> Result<(), Self::Error>;
    /// Program `data` at `offset` in `sector` (only clears bits; the journal only programs
    /// erased bytes).
    fn program(&mut self, sector: u8, offset: u32, data: &[u8]) -> Result<(), Self::Error>;
    /// Read `buf.len()` bytes at `offset` in `sector` (memory-mapped on the STM32: cannot fail).
    fn read(&self, sector: u8, offset: u32, buf: &mut [u8]);
}

/// One record type of the [`Journal`]: a kind byte of its own and a payload of fixed length.
pub trait Record: Sized {
    /// The kind byte in the slot header; unique per record type, never 0x00 or 0xFF.
    const KIND: u8;
    /// Payload bytes, at most [`MAX_PAYLOAD`].
    const LEN: usize;
    /// Write the payload into `out` (`out.len() == Self::LEN`).
    fn encode(&self, out: &mut [u8]);
    /// The value of a payload (`bytes.len() == Self::LEN`); `None` = not a value of this type
    /// (the journal then reports the kind as not stored).
    fn decode(bytes: &[u8]) -> Option<Self>;
}

/// Bytes per journal slot.
pub const SLOT_SIZE: usize = 256;
/// Bytes of the slot header (sequence number, kind, length).
pub const HEADER_LEN: usize = 6;
const CRC_AT: usize = SLOT_SIZE - 4;
const BERGER_AT: usize = SLOT_SIZE - 2;
/// The largest payload of a record.
pub const MAX_PAYLOAD: usize = CRC_AT - HEADER_LEN;
/// Kinds the journal keeps apart (a slot of a further kind is ignored and not carried over).
pub const MAX_KINDS: usize = 4;

/// CRC-16/CCITT-FALSE (polynomial 0x1021, initial value 0xFFFF, no reflection, no final XOR;
/// check value of `"123456789"` = 0x29B1), the `crc` crate's byte-wise table (512 bytes).
static CRC: crc::Crc<u16, crc::Table<1>> = crc::Crc::<u16, crc::Table<1>>::new(&crc::CRC_16_IBM_3740);

/// The CRC-16 of a slot (CRC-16/CCITT-FALSE, the `crc` crate's `CRC_16_IBM_3740`).
#[inline(never)]
pub fn crc16(data: &[u8]) -> u16 {
    CRC.checksum(data)
}

fn zero_bits(data: &[u8]) -> u16 {
    data.iter().map(|b| b.count_zeros() as u16).sum()
}

/// The header of a valid slot.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct SlotHeader {
    /// Sequence number: the newest record has the highest.
    pub seq: u32,
    /// [`Record::KIND`].
    pub kind: u8,
    /// Payload length.
    pub len: u8,
}

/// What a slot holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum Slot {
    /// Erased (all 0xFF): free for a record.
    Empty,
    /// A complete, checked record.
    Valid(SlotHeader),
    /// Anything else (torn write, partial erase, corruption): skipped, never reused.
    Invalid,
}

/// The bytes of a slot holding `payload` (at most [`MAX_PAYLOAD`] bytes; longer is cut).
pub fn encode_slot(seq: u32, kind: u8, payload: &[u8]) -> [u8; SLOT_SIZE] {
    let len = payload.len().min(MAX_PAYLOAD);
    let mut b = [0xFF; SLOT_SIZE];
    b[0..4].copy_from_slice(&seq.to_le_bytes());
    b[4] = kind;
    b[5] = len as u8;
    b[HEADER_LEN..HEADER_LEN + len].copy_from_slice(&payload[..len]);
    let crc = crc16(&b[..HEADER_LEN + len]);
    b[CRC_AT..BERGER_AT].copy_from_slice(&crc.to_be_bytes());
    let z = zero_bits(&b[..BERGER_AT]);
    b[BERGER_AT..].copy_from_slice(&z.to_be_bytes());
    b
}

/// Classify the bytes of one slot.
pub fn decode_slot(b: &[u8; SLOT_SIZE]) -> Slot {
    if b.iter().all(|&x| x == 0xFF) {
        return Slot::Empty;
    }
    let len = b[5] as usize;
    let ok = u16::from_be_bytes([b[BERGER_AT], b[BERGER_AT + 1]]) == zero_bits(&b[..BERGER_AT])
        && len <= MAX_PAYLOAD
        && b[4] != 0x00
        && b[4] != 0xFF
        && b[HEADER_LEN + len..CRC_AT].iter().all(|&x| x == 0xFF)
        && u16::from_be_bytes([b[CRC_AT], b[CRC_AT + 1]]) == crc16(&b[..HEADER_LEN + len]);
    if !ok {
        return Slot::Invalid;
    }
    Slot::Valid(SlotHeader { seq: u32::from_le_bytes([b[0], b[1], b[2], b[3]]), kind: b[4], len: b[5] })
}

/// Why a save failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum StoreError<E> {
    /// The flash reported an error (the journal is still consistent: the old value loads).
    Flash(E),
    /// Address above 126.
    Address(u8),
    /// Read-back after programming differed (worn or faulty flash).
    Verify,
    /// The sequence number is exhausted (2³² − 1 saves), or a sector has too few slots for
    /// one record of every kind.
    Exhausted,
}

/// Where a valid slot is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Loc {
    sector: u8,
    slot: u32,
    seq: u32,
}

/// The result of scanning both sectors.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Scan {
    /// Per kind: its newest valid slot.
    kinds: [Option<(u8, Loc)>; MAX_KINDS],
    /// The newest valid slot of any kind (its sector is the active one).
    newest: Option<Loc>,
    /// Per sector: the first empty slot after the last non-empty one, `None` = full.
    free: [Option<u32>; 2],
}

impl Scan {
    #[inline(never)]
    fn find(&self, kind: u8) -> Option<Loc> {
        self.kinds.iter().flatten().find(|(k, _)| *k == kind).map(|&(_, l)| l)
    }
    fn active(&self) -> u8 {
        self.newest.map_or(0, |l| l.sector)
    }
}

/// The power-loss-safe journal of the card's records (see the module documentation).
#[derive(Debug)]
pub struct Journal<F: Flash> {
    flash: F,
}

impl<F: Flash> Journal<F> {
    /// Record slots per sector.
    pub const SLOTS: u32 = F::SECTOR_SIZE / SLOT_SIZE as u32;

    /// A journal over `flash` (no flash access yet).
    pub fn new(flash: F) -> Self {
        Journal { flash }
    }

    /// The flash device.
    pub fn flash(&self) -> &F {
        &self.flash
    }

    /// Give the flash device back.
    pub fn into_inner(self) -> F {
        self.flash
    }

    #[inline(never)]
    fn read_slot(&self, sector: u8, slot: u32) -> [u8; SLOT_SIZE] {
        let mut b = [0u8; SLOT_SIZE];
        self.flash.read(sector, slot * SLOT_SIZE as u32, &mut b);
        b
    }

    fn scan(&self) -> Scan {
        let mut s = Scan { kinds: [None; MAX_KINDS], newest: None, free: [Some(0); 2] };
        for sector in 0..2u8 {
            for slot in 0..Self::SLOTS {
                match decode_slot(&self.read_slot(sector, slot)) {
                    Slot::Empty => continue,
                    Slot::Valid(h) => {
                        let loc = Loc { sector, slot, seq: h.seq };
                        if s.newest.is_none_or(|n| h.seq > n.seq) {
                            s.newest = Some(loc);
                        }
                        if let Some(e) = s.kinds.iter_mut().flatten().find(|(k, _)| *k == h.kind) {
                            if h.seq > e.1.seq {
                                e.1 = loc;
                            }
                        } else if let Some(e) = s.kinds.iter_mut().find(|e| e.is_none()) {
                            *e = Some((h.kind, loc));
                        }
                    }
                    Slot::Invalid => {}
                }
                s.free[sector as usize] = if slot + 1 < Self::SLOTS { Some(slot + 1) } else { None };
            }
        }
        s
    }

    /// The newest record of type `R` and its sequence number; `None` when none is stored
    /// (blank or erased flash, or its newest payload is no value of `R`).
    pub fn latest<R: Record>(&self) -> Option<(u32, R)> {
        let loc = self.scan().find(R::KIND)?;
        let b = self.read_slot(loc.sector, loc.slot);
        if b[5] as usize != R::LEN {
            return None;
        }
        R::decode(&b[HEADER_LEN..HEADER_LEN + R::LEN]).map(|r| (loc.seq, r))
    }

    /// The stored value of type `R` ([`Self::latest`] without the sequence number).
    pub fn load<R: Record>(&self) -> Option<R> {
        self.latest().map(|(_, r)| r)
    }

    /// Program `payload` of `kind` as record `seq` into an empty slot, check bytes last, and
    /// read it back.
    fn write_slot(
        &mut self,
        sector: u8,
        slot: u32,
        seq: u32,
        kind: u8,
        payload: &[u8],
    ) -> Result<(), StoreError<F::Error>> {
        let bytes = encode_slot(seq, kind, payload);
        let at = slot * SLOT_SIZE as u32;
        let body = HEADER_LEN + payload.len();
        self.flash.program(sector, at, &bytes[..body]).map_err(StoreError::Flash)?;
        self.flash.program(sector, at + CRC_AT as u32, &bytes[CRC_AT..]).map_err(StoreError::Flash)?;
        if self.read_slot(sector, slot) != bytes {
            return Err(StoreError::Verify);
        }
        Ok(())
    }

    /// Copy the record at `from` as record `seq` into an empty slot.
    fn copy_slot(&mut self, from: Loc, sector: u8, slot: u32, seq: u32) -> Result<(), StoreError<F::Error>> {
        let b = self.read_slot(from.sector, from.slot);
        let len = (b[5] as usize).min(MAX_PAYLOAD);
        let mut payload = [0u8; MAX_PAYLOAD];
        payload[..len].copy_from_slice(&b[HEADER_LEN..HEADER_LEN + len]);
        self.write_slot(sector, slot, seq, b[4], &payload[..len])
    }

    /// Store `record` as the newest of its kind (nothing is written when it already is).
    /// Returns whether a record was written. On a power cut the kind keeps its previous
    /// value or gets the new one; every other kind keeps its value.
    pub fn save<R: Record>(&mut self, record: &R) -> Result<bool, StoreError<F::Error>> {
        const { assert!(R::LEN <= MAX_PAYLOAD && R::KIND != 0 && R::KIND != 0xFF) };
        let mut buf = [0xFF; MAX_PAYLOAD];
        record.encode(&mut buf[..R::LEN]);
        self.save_payload(R::KIND, &buf[..R::LEN])
    }

    /// [`Self::save`] of an encoded record: one copy of the compaction logic for every
    /// record type (footprint, issue 13 item 1).
    #[inline(never)]
    fn save_payload(&mut self, kind: u8, payload: &[u8]) -> Result<bool, StoreError<F::Error>> {
        let mut scan = self.scan();
        if let Some(loc) = scan.find(kind) {
            let b = self.read_slot(loc.sector, loc.slot);
            if b[5] as usize == payload.len() && &b[HEADER_LEN..HEADER_LEN + payload.len()] == payload {
                return Ok(false);
            }
        }
        let (sector, slot, carry) = loop {
            let active = scan.active();
            let room = scan.free[active as usize].map_or(0, |f| Self::SLOTS - f) as usize;
            let first_free = scan.free[active as usize].unwrap_or(0);
            // Kinds whose newest record is outside the active sector: a compaction into the
            // active sector was cut. The active sector then holds only copies of what the
            // other sector holds (a record of its own is written only after every copy).
            let outside = scan.kinds.iter().flatten().filter(|(_, l)| l.sector != active);
            let mut carry = [None; MAX_KINDS];
            let mut n = 0;
            for &(_, l) in outside.clone().filter(|(k, _)| *k != kind) {
                carry[n] = Some(l);
                n += 1;
            }
            if outside.clone().next().is_none() {
                if room >= 1 {
                    break (active, first_free, carry);
                }
                // Compaction: every other kind's newest into the erased other sector.
                for &(_, l) in scan.kinds.iter().flatten().filter(|(k, _)| *k != kind) {
                    carry[n] = Some(l);
                    n += 1;
                }
                if n + 1 > Self::SLOTS as usize {
                    return Err(StoreError::Exhausted);
                }
                let other = 1 - active;
                self.flash.erase(other).map_err(StoreError::Flash)?;
                break (other, 0, carry);
            }
            if room > n {
                // Complete the interrupted compaction, then the record.
                break (active, first_free, carry);
            }
            // No room to complete it: the active sector holds only copies; erase it and
            // compact again from the other sector, which still holds every kind's newest.
            self.flash.erase(active).map_err(StoreError::Flash)?;
            scan = self.scan();
            if scan.kinds.iter().flatten().any(|(_, l)| l.sector == active) {
                return Err(StoreError::Verify);
            }
        };
        let mut seq = scan.newest.map_or(0, |l| l.seq);
        let mut slot = slot;
        for from in carry.into_iter().flatten() {
            seq = seq.checked_add(1).ok_or(StoreError::Exhausted)?;
            self.copy_slot(from, sector, slot, seq)?;
            slot += 1;
        }
        seq = seq.checked_add(1).ok_or(StoreError::Exhausted)?;
        self.write_slot(sector, slot, seq, kind, payload)?;
        Ok(true)
    }

    /// Erase both sectors (factory reset: nothing loads afterwards). The sector without the
    /// newest record goes first, so a power cut in between still loads the active sector's
    /// records.
    pub fn erase_all(&mut self) -> Result<(), StoreError<F::Error>> {
        let active = self.scan().active();
        self.flash.erase(1 - active).map_err(StoreError::Flash)?;
        self.flash.erase(active).map_err(StoreError::Flash)
    }
}

/// The station address and No_Add_Chg flag (Set_Slave_Add, reference §3.9) as a journal
/// record: kind 0x01, payload `address, no_add_chg` (2 bytes).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct StationAddress {
    /// Station address (0..=126).
    pub address: u8,
    /// No_Add_Chg: the address is frozen.
    pub no_add_chg: bool,
}

impl Record for StationAddress {
    const KIND: u8 = 0x01;
    const LEN: usize = 2;
    fn encode(&self, out: &mut [u8]) {
        out.copy_from_slice(&[self.address, self.no_add_chg as u8]);
    }
    fn decode(b: &[u8]) -> Option<Self> {
        (b.len() == 2 && b[0] <= MAX_STATION_ADDRESS && b[1] <= 1)
            .then(|| StationAddress { address: b[0], no_add_chg: b[1] == 1 })
    }
}

impl<F: Flash> AddressStore for Journal<F> {
    type Error = StoreError<F::Error>;

    fn load(&mut self) -> Option<(u8, bool)> {
        Journal::load::<StationAddress>(self).map(|r| (r.address, r.no_add_chg))
    }

    fn save(&mut self, address: u8, no_add_chg: bool) -> Result<(), Self::Error> {
        if address > MAX_STATION_ADDRESS {
            return Err(StoreError::Address(address));
        }
        Journal::save(self, &StationAddress { address, no_add_chg }).map(|_| ())
    }
}

#[cfg(any(test, feature = "test-support"))]
pub mod sim;
#[cfg(test)]
mod tests;
