//! The station address and No_Add_Chg flag in flash, safe against power loss at any moment
//! (reference §3.9: Set_Slave_Add must survive a power cut).
//!
//! [`JournalStore`] keeps an append-only journal of [`Record`]s in two flash sectors behind
//! the tiny [`Flash`] trait (NOR semantics: erase sets every byte to 0xFF, programming can
//! only clear bits). The board maps the trait's sectors 0 and 1 to two real sectors (on the
//! STM32F411, e.g. sectors 2 and 3, 16 KiB each = 1024 records each).
//!
//! * **Save** appends a record with the next sequence number to the first empty slot of the
//!   sector holding the newest record. When that sector is full, the *other* sector is erased
//!   and the record goes to its first slot; the full sector keeps the previous record until
//!   the next switch erases it. No slot is ever programmed twice between erases, and the
//!   sector holding the newest valid record is never erased.
//! * **Load** scans both sectors and returns the valid record with the highest sequence
//!   number.
//!
//! **Why a torn write can never be mistaken for a record.** Flash failures from power loss
//! are *unidirectional* relative to the record that was meant to be there: an interrupted
//! program leaves some bits still 1 that should have become 0, and an interrupted erase turns
//! some 0 bits into 1. Besides a CRC-16, each record carries a Berger check — the number of
//! 0 bits in its first eight bytes. Turning 0s into 1s lowers that number in the data but can
//! only raise the stored count, so *every* such corruption is detected, deterministically
//! (the CRC catches random bit rot on top). So the journal always yields either the previous
//! or the new pair, and never `None` once a save has completed.
//!
//! Record layout ([`RECORD_SIZE`] = 16 bytes, programmed with one [`Flash::program`] call):
//!
//! | bytes | content |
//! |---|---|
//! | 0..4 | sequence number, u32 little-endian, first record = 1 |
//! | 4 | station address, 0..=126 |
//! | 5 | flags: `0xA4` \| No_Add_Chg (bit 0) |
//! | 6..8 | CRC-16/CCITT-FALSE over bytes 0..6, big-endian |
//! | 8 | Berger check: number of 0 bits in bytes 0..8 |
//! | 9..16 | reserved, left 0xFF |

use crate::card;
use crate::dp::slave_add::AddressStore;

/// A flash device with two erasable sectors (NOR semantics).
pub trait Flash {
    /// Bytes per sector (the journal uses `SECTOR_SIZE / RECORD_SIZE` slots per sector).
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

/// Bytes per journal record.
pub const RECORD_SIZE: usize = 16;

/// Bits 7..1 of the flags byte of every record.
const FLAGS_MAGIC: u8 = 0xA4;

/// CRC-16/CCITT-FALSE (polynomial 0x1021, initial value 0xFFFF, no reflection, no final
/// XOR; check value of `"123456789"` = 0x29B1), bitwise: records are 6 bytes, speed is
/// irrelevant.
pub fn crc16(data: &[u8]) -> u16 {
    let mut crc: u16 = 0xFFFF;
    for &b in data {
        crc ^= (b as u16) << 8;
        for _ in 0..8 {
            crc = if crc & 0x8000 != 0 { (crc << 1) ^ 0x1021 } else { crc << 1 };
        }
    }
    crc
}

fn zero_bits(data: &[u8]) -> u8 {
    data.iter().map(|b| b.count_zeros() as u8).sum()
}

/// One journal entry.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct Record {
    /// Sequence number: the newest record has the highest.
    pub seq: u32,
    /// Station address (0..=126).
    pub address: u8,
    /// No_Add_Chg: the address is frozen.
    pub no_add_chg: bool,
}

/// What a record slot holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum Slot {
    /// Erased (all 0xFF): free for the next record.
    Empty,
    /// A complete, checked record.
    Valid(Record),
    /// Anything else (torn write, partial erase, corruption): skipped, never reused.
    Invalid,
}

impl Record {
    /// The bytes of the record as programmed.
    pub fn encode(&self) -> [u8; RECORD_SIZE] {
        let mut b = [0xFF; RECORD_SIZE];
        b[0..4].copy_from_slice(&self.seq.to_le_bytes());
        b[4] = self.address;
        b[5] = FLAGS_MAGIC | self.no_add_chg as u8;
        let crc = crc16(&b[0..6]);
        b[6..8].copy_from_slice(&crc.to_be_bytes());
        b[8] = zero_bits(&b[0..8]);
        b
    }

    /// Classify the bytes of one slot.
    pub fn decode(b: &[u8; RECORD_SIZE]) -> Slot {
        if b.iter().all(|&x| x == 0xFF) {
            return Slot::Empty;
        }
        let ok = b[8] == zero_bits(&b[0..8])
            && u16::from_be_bytes([b[6], b[7]]) == crc16(&b[0..6])
            && b[5] & 0xFE == FLAGS_MAGIC
            && b[4] <= card::MAX_STATION_ADDRESS
            && b[9..].iter().all(|&x| x == 0xFF);
        if !ok {
            return Slot::Invalid;
        }
        Slot::Valid(Record {
            seq: u32::from_le_bytes([b[0], b[1], b[2], b[3]]),
            address: b[4],
            no_add_chg: b[5] & 1 != 0,
        })
    }
}

/// Why a save failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum StoreError<E> {
    /// The flash reported an error (the journal is still consistent: the old pair loads).
    Flash(E),
    /// Address above 126.
    Address(u8),
    /// Read-back after programming differed (worn or faulty flash).
    Verify,
    /// The sequence number is exhausted (2³² − 1 saves) or a sector holds no record.
    Exhausted,
}

/// The result of scanning both sectors.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Scan {
    /// The newest valid record and its sector.
    newest: Option<(u8, Record)>,
    /// Per sector: the first empty slot after the last non-empty one, `None` = full.
    free: [Option<u32>; 2],
}

/// The power-loss-safe station address journal (see the module documentation).
#[derive(Debug)]
pub struct JournalStore<F: Flash> {
    flash: F,
}

impl<F: Flash> JournalStore<F> {
    /// Record slots per sector.
    pub const SLOTS: u32 = F::SECTOR_SIZE / RECORD_SIZE as u32;

    /// A store over `flash` (no flash access yet).
    pub fn new(flash: F) -> Self {
        JournalStore { flash }
    }

    /// The flash device.
    pub fn flash(&self) -> &F {
        &self.flash
    }

    /// Give the flash device back.
    pub fn into_inner(self) -> F {
        self.flash
    }

    fn read_slot(&self, sector: u8, slot: u32) -> [u8; RECORD_SIZE] {
        let mut b = [0u8; RECORD_SIZE];
        self.flash.read(sector, slot * RECORD_SIZE as u32, &mut b);
        b
    }

    fn scan(&self) -> Scan {
        let mut newest: Option<(u8, Record)> = None;
        let mut free = [Some(0); 2];
        for sector in 0..2u8 {
            for slot in 0..Self::SLOTS {
                match Record::decode(&self.read_slot(sector, slot)) {
                    Slot::Empty => continue,
                    Slot::Valid(r) => {
                        if newest.is_none_or(|(_, n)| r.seq > n.seq) {
                            newest = Some((sector, r));
                        }
                    }
                    Slot::Invalid => {}
                }
                free[sector as usize] = if slot + 1 < Self::SLOTS { Some(slot + 1) } else { None };
            }
        }
        Scan { newest, free }
    }

    /// The newest valid record, `None` if there is none (blank or erased flash).
    pub fn latest(&self) -> Option<Record> {
        self.scan().newest.map(|(_, r)| r)
    }

    /// Append `address` / `no_add_chg` as the newest record (nothing is written when they are
    /// already the newest). Returns the record written.
    pub fn save_record(&mut self, address: u8, no_add_chg: bool) -> Result<Option<Record>, StoreError<F::Error>> {
        if address > card::MAX_STATION_ADDRESS {
            return Err(StoreError::Address(address));
        }
        if Self::SLOTS == 0 {
            return Err(StoreError::Exhausted);
        }
        let scan = self.scan();
        let seq = match scan.newest {
            Some((_, r)) if r.address == address && r.no_add_chg == no_add_chg => return Ok(None),
            Some((_, r)) => r.seq.checked_add(1).ok_or(StoreError::Exhausted)?,
            None => 1,
        };
        let rec = Record { seq, address, no_add_chg };
        let active = scan.newest.map_or(0, |(s, _)| s);
        let (sector, slot) = match scan.free[active as usize] {
            Some(slot) => (active, slot),
            None => {
                let other = 1 - active;
                self.flash.erase(other).map_err(StoreError::Flash)?;
                (other, 0)
            }
        };
        let bytes = rec.encode();
        self.flash.program(sector, slot * RECORD_SIZE as u32, &bytes).map_err(StoreError::Flash)?;
        if self.read_slot(sector, slot) != bytes {
            return Err(StoreError::Verify);
        }
        Ok(Some(rec))
    }

    /// Erase both sectors (factory reset: the next load is `None`). The sector without the
    /// newest record goes first, so a power cut in between still loads the newest pair.
    pub fn erase_all(&mut self) -> Result<(), StoreError<F::Error>> {
        let active = self.scan().newest.map_or(0, |(s, _)| s);
        self.flash.erase(1 - active).map_err(StoreError::Flash)?;
        self.flash.erase(active).map_err(StoreError::Flash)
    }
}

impl<F: Flash> AddressStore for JournalStore<F> {
    type Error = StoreError<F::Error>;

    fn load(&mut self) -> Option<(u8, bool)> {
        self.latest().map(|r| (r.address, r.no_add_chg))
    }

    fn save(&mut self, address: u8, no_add_chg: bool) -> Result<(), Self::Error> {
        self.save_record(address, no_add_chg).map(|_| ())
    }
}

pub mod im;

pub use im::ImJournal;

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use std::vec::Vec;

    /// Simulated NOR flash: two sectors of `N` bytes, erase = 0xFF, program clears bits and
    /// may only touch erased bytes, and an optional power cut after a number of byte steps
    /// (each programmed byte and each erased byte is one step). The step that is cut is done
    /// partially: a program clears only some of the bits it should, an erase leaves every
    /// byte not yet erased with some bits set. After the cut every operation fails.
    #[derive(Clone)]
    pub(crate) struct SimFlash<const N: usize> {
        pub(crate) mem: [[u8; N]; 2],
        budget: Option<u64>,
        pub(crate) steps: u64,
        seed: u64,
        pub(crate) erases: u32,
    }

    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub(crate) struct PowerCut;

    impl<const N: usize> SimFlash<N> {
        pub(crate) fn new() -> Self {
            SimFlash { mem: [[0xFF; N]; 2], budget: None, steps: 0, seed: 1, erases: 0 }
        }
        fn rand(&mut self) -> u8 {
            self.seed ^= self.seed << 13;
            self.seed ^= self.seed >> 7;
            self.seed ^= self.seed << 17;
            (self.seed >> 24) as u8
        }
        /// Take one step; `false` = the power fails during this step.
        fn step(&mut self) -> Result<bool, PowerCut> {
            match self.budget {
                Some(0) => Err(PowerCut),
                Some(ref mut b) => {
                    *b -= 1;
                    self.steps += 1;
                    Ok(*b != 0)
                }
                None => {
                    self.steps += 1;
                    Ok(true)
                }
            }
        }
        pub(crate) fn cut_after(&mut self, steps: u64, seed: u64) {
            self.budget = Some(steps + 1);
            self.seed = seed | 1;
        }
        pub(crate) fn power_on(&mut self) {
            self.budget = None;
        }
    }

    impl<const N: usize> Flash for SimFlash<N> {
        const SECTOR_SIZE: u32 = N as u32;
        type Error = PowerCut;

        fn erase(&mut self, sector: u8) -> Result<(), PowerCut> {
            self.erases += 1;
            for i in 0..N {
                if !self.step()? {
                    // Cut mid-erase: bytes from i on are only partly erased.
                    for j in i..N {
                        let m = self.rand() & self.rand();
                        self.mem[sector as usize][j] |= m;
                    }
                    self.budget = Some(0);
                    return Err(PowerCut);
                }
                self.mem[sector as usize][i] = 0xFF;
            }
            Ok(())
        }

        fn program(&mut self, sector: u8, offset: u32, data: &[u8]) -> Result<(), PowerCut> {
            for (i, &d) in data.iter().enumerate() {
                let a = offset as usize + i;
                let old = self.mem[sector as usize][a];
                assert!(old == 0xFF || d == 0xFF, "programming a non-erased byte at {sector}:{a}");
                if !self.step()? {
                    let m = self.rand();
                    self.mem[sector as usize][a] &= d | m;
                    self.budget = Some(0);
                    return Err(PowerCut);
                }
                self.mem[sector as usize][a] &= d;
            }
            Ok(())
        }

        fn read(&self, sector: u8, offset: u32, buf: &mut [u8]) {
            let o = offset as usize;
            buf.copy_from_slice(&self.mem[sector as usize][o..o + buf.len()]);
        }
    }

    #[test]
    fn crc_check_value() {
        assert_eq!(crc16(b"123456789"), 0x29B1);
    }

    #[test]
    fn record_round_trip_and_layout() {
        let r = Record { seq: 0x0102_0304, address: 126, no_add_chg: true };
        let b = r.encode();
        assert_eq!(&b[0..6], &[0x04, 0x03, 0x02, 0x01, 126, 0xA5]);
        assert_eq!(&b[9..], &[0xFF; 7]);
        assert_eq!(Record::decode(&b), Slot::Valid(r));
        assert_eq!(Record::decode(&[0xFF; RECORD_SIZE]), Slot::Empty);
        assert_eq!(Record::decode(&[0x00; RECORD_SIZE]), Slot::Invalid);
        let mut bad = Record { seq: 1, address: 127, no_add_chg: false }.encode();
        assert_eq!(Record::decode(&bad), Slot::Invalid);
        bad[4] = 3;
        assert_eq!(Record::decode(&bad), Slot::Invalid); // CRC
    }

    #[test]
    fn blank_store_loads_none_then_saves() {
        let mut s = JournalStore::new(SimFlash::<64>::new());
        assert_eq!(s.load(), None);
        s.save(7, false).unwrap();
        assert_eq!(s.load(), Some((7, false)));
        s.save(7, false).unwrap(); // unchanged: nothing written
        assert_eq!(s.flash().steps, 16);
        assert_eq!(s.save(127, false), Err(StoreError::Address(127)));
        s.save(9, true).unwrap();
        assert_eq!(s.load(), Some((9, true)));
        assert_eq!(s.latest().unwrap().seq, 2);
        s.erase_all().unwrap();
        assert_eq!(s.load(), None);
    }

    #[test]
    fn sector_switch_keeps_newest() {
        let mut s = JournalStore::new(SimFlash::<64>::new());
        for i in 0..20u8 {
            s.save(i, i % 3 == 0).unwrap();
            assert_eq!(s.load(), Some((i, i % 3 == 0)));
            assert_eq!(s.latest().unwrap().seq, i as u32 + 1);
        }
        // 4 slots per sector: records 1..4 in 0, 5..8 in 1, … → 4 switches.
        assert_eq!(s.flash().erases, 4);
    }

    /// The sequence of saves of the exhaustive test: many sector switches, flag changes,
    /// a repeated pair (no write).
    const SAVES: [(u8, bool); 15] = [
        (3, false),
        (126, false),
        (0, false),
        (125, true),
        (125, true),
        (4, false),
        (4, true),
        (255 / 2 - 1, false),
        (17, false),
        (18, false),
        (19, true),
        (20, false),
        (1, false),
        (2, true),
        (99, false),
    ];

    /// Run `SAVES` on a blank flash with a power cut after `k` steps; then power on and
    /// check the journal, finish the remaining saves and check again.
    fn run_with_cut<const N: usize>(k: u64, seed: u64) -> bool {
        let mut flash = SimFlash::<N>::new();
        flash.cut_after(k, seed);
        let mut s = JournalStore::new(flash);
        let mut committed: Option<(u8, bool)> = None;
        let mut cut_at = None;
        for (i, &(a, f)) in SAVES.iter().enumerate() {
            match s.save(a, f) {
                Ok(()) => committed = Some((a, f)),
                Err(StoreError::Flash(PowerCut)) => {
                    cut_at = Some(i);
                    break;
                }
                Err(e) => panic!("{e:?}"),
            }
        }
        let mut flash = s.into_inner();
        flash.power_on();
        let mut s = JournalStore::new(flash);
        let loaded = s.load();
        match cut_at {
            None => assert_eq!(loaded, committed),
            Some(i) => {
                let new = Some(SAVES[i]);
                assert!(
                    loaded == committed || loaded == new,
                    "cut after {k} steps (seed {seed}) in save {i}: loaded {loaded:?}, expected {committed:?} or {new:?}"
                );
                if committed.is_some() {
                    assert!(loaded.is_some());
                }
                // After the reboot the journal works on: redo the interrupted save and the rest.
                for &(a, f) in &SAVES[i..] {
                    s.save(a, f).unwrap();
                    assert_eq!(s.load(), Some((a, f)));
                }
            }
        }
        cut_at.is_some()
    }

    fn total_steps<const N: usize>() -> u64 {
        let mut s = JournalStore::new(SimFlash::<N>::new());
        for &(a, f) in &SAVES {
            s.save(a, f).unwrap();
        }
        s.flash().steps
    }

    /// Power cut after every single byte-program or byte-erase step of a long sequence of
    /// saves with sector switches (several partial-bit patterns per step): the journal loads
    /// the old or the new pair, never garbage, never None once something was saved.
    #[test]
    fn power_cut_at_every_step() {
        fn all<const N: usize>() {
            let total = total_steps::<N>();
            let mut cuts = 0;
            for k in 0..=total {
                for seed in
                    [0x1234_5678_9ABC_DEF1u64, 0x0F0F_0F0F_1111_2222, 0xFFFF_FFFF_FFFF_FFFF, 0x8000_0000_0000_0001]
                {
                    if run_with_cut::<N>(k, seed) {
                        cuts += 1;
                    }
                }
            }
            assert_eq!(cuts, 4 * total, "every step was cut once per seed");
        }
        all::<48>(); // 3 slots per sector: a switch every third save
        all::<64>();
        all::<112>();
    }

    proptest::proptest! {
        /// Power cuts after random steps during random saves, several reboots in a row.
        #[test]
        fn repeated_power_cuts(ops in proptest::collection::vec((0u8..=126, proptest::bool::ANY, 0u64..60, proptest::num::u64::ANY), 1..40)) {
            let mut flash = SimFlash::<48>::new();
            let mut committed: Option<(u8, bool)> = None;
            for (a, f, cut, seed) in ops {
                flash.cut_after(cut, seed);
                let mut s = JournalStore::new(flash);
                let r = s.save(a, f);
                flash = s.into_inner();
                flash.power_on();
                let mut s = JournalStore::new(flash);
                let loaded = s.load();
                match r {
                    Ok(()) => proptest::prop_assert_eq!(loaded, Some((a, f))),
                    Err(StoreError::Flash(PowerCut)) => {
                        proptest::prop_assert!(loaded == committed || loaded == Some((a, f)), "{:?}", loaded);
                    }
                    Err(e) => proptest::prop_assert!(false, "{:?}", e),
                }
                if committed.is_some() {
                    proptest::prop_assert!(loaded.is_some());
                }
                committed = loaded;
                flash = s.into_inner();
            }
        }

        /// Unidirectional damage (0 → 1: torn program or partial erase) to a record is always
        /// detected; arbitrary bytes never decode to an out-of-range record.
        #[test]
        fn berger_check_detects_unidirectional_errors(seq in proptest::num::u32::ANY, addr in 0u8..=126, flag in proptest::bool::ANY,
                                                     mask in proptest::collection::vec(proptest::num::u8::ANY, 9)) {
            let r = Record { seq, address: addr, no_add_chg: flag };
            let mut b = r.encode();
            for (x, m) in b.iter_mut().zip(&mask) {
                *x |= m;
            }
            let damaged = b != r.encode();
            match Record::decode(&b) {
                Slot::Valid(v) => { proptest::prop_assert!(!damaged); proptest::prop_assert_eq!(v, r); }
                Slot::Empty | Slot::Invalid => proptest::prop_assert!(damaged),
            }
        }

        #[test]
        fn decode_arbitrary_bytes(b in proptest::array::uniform16(proptest::num::u8::ANY)) {
            if let Slot::Valid(r) = Record::decode(&b) {
                proptest::prop_assert!(r.address <= 126);
                proptest::prop_assert_eq!(r.encode(), b);
            }
        }
    }

    #[test]
    fn invalid_slots_are_skipped_not_reused() {
        let mut flash = SimFlash::<64>::new();
        flash.mem[0][0] = 0x12; // garbage in slot 0
        flash.mem[0][20] = 0x00; // garbage in slot 1
        let mut s = JournalStore::new(flash);
        assert_eq!(s.load(), None);
        s.save(5, false).unwrap();
        assert_eq!(s.load(), Some((5, false)));
        s.save(6, false).unwrap(); // slot 3: the sector is now full
        s.save(7, false).unwrap(); // → sector 1
        assert_eq!(s.flash().erases, 1);
        assert_eq!(s.load(), Some((7, false)));
        let v: Vec<Slot> = (0..4).map(|i| Record::decode(&s.read_slot(1, i))).collect();
        assert_eq!(v[1], Slot::Empty);
    }
}
