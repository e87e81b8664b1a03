//! I&M1–I&M4 (tag function / location, installation date, descriptor, signature; reference
//! §4.7, [`crate::dpv1::im`]) in flash, with the discipline of the address journal
//! ([`super::JournalStore`]): an append-only journal in two sectors behind the same [`Flash`]
//! trait, the newest valid record wins, the sector with the newest record is never erased, no
//! slot is programmed twice between erases, and every torn write or partial erase is detected
//! by a Berger check (number of 0 bits, which a 0 → 1 corruption can only lower in the data and
//! only raise in the stored count) on top of a CRC-16. A power cut at any moment of a save
//! leaves the previous or the new I&M1–4, never garbage, never nothing once a save completed.
//!
//! Record layout ([`IM_RECORD_SIZE`] = 256 bytes, one [`Flash::program`] call):
//!
//! | bytes | content |
//! |---|---|
//! | 0..4 | sequence number, u32 little-endian, first record = 1 |
//! | 4 | magic `0x1A` |
//! | 5..221 | I&M1, I&M2, I&M3, I&M4: 54 content bytes each ([`ImData::encode`]) |
//! | 221..223 | CRC-16/CCITT-FALSE over bytes 0..221, big-endian |
//! | 223..225 | Berger check: number of 0 bits in bytes 0..223, u16 big-endian |
//! | 225..256 | reserved, left 0xFF |
//!
//! The board gives the I&M journal two sectors of its own (a 16 KiB sector holds 64 records);
//! I&M1–4 are written rarely (commissioning), so a sector switch is rare.

use super::{crc16, Flash, StoreError};
use crate::dpv1::im::ImData;

/// Bytes per I&M journal record.
pub const IM_RECORD_SIZE: usize = 256;
const MAGIC: u8 = 0x1A;
const DATA: usize = 5;
const CRC: usize = DATA + ImData::LEN;
const BERGER: usize = CRC + 2;
const END: usize = BERGER + 2;

fn zero_bits(data: &[u8]) -> u16 {
    data.iter().map(|b| b.count_zeros() as u16).sum()
}

/// One I&M journal entry.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ImRecord {
    /// Sequence number: the newest record has the highest.
    pub seq: u32,
    /// I&M1–4.
    pub data: ImData,
}

/// What a record slot holds.
// A slot is decoded one at a time on the stack and there is no heap (no_std): the size of
// `Valid` is the point, not a waste.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ImSlot {
    /// Erased (all 0xFF).
    Empty,
    /// A complete, checked record.
    Valid(ImRecord),
    /// Anything else: skipped, never reused.
    Invalid,
}

impl ImRecord {
    /// The bytes as programmed.
    pub fn encode(&self) -> [u8; IM_RECORD_SIZE] {
        let mut b = [0xFF; IM_RECORD_SIZE];
        b[0..4].copy_from_slice(&self.seq.to_le_bytes());
        b[4] = MAGIC;
        b[DATA..CRC].copy_from_slice(&self.data.encode());
        let crc = crc16(&b[..CRC]);
        b[CRC..BERGER].copy_from_slice(&crc.to_be_bytes());
        let z = zero_bits(&b[..BERGER]);
        b[BERGER..END].copy_from_slice(&z.to_be_bytes());
        b
    }

    /// Classify the bytes of one slot.
    pub fn decode(b: &[u8; IM_RECORD_SIZE]) -> ImSlot {
        if b.iter().all(|&x| x == 0xFF) {
            return ImSlot::Empty;
        }
        let ok = u16::from_be_bytes([b[BERGER], b[BERGER + 1]]) == zero_bits(&b[..BERGER])
            && u16::from_be_bytes([b[CRC], b[CRC + 1]]) == crc16(&b[..CRC])
            && b[4] == MAGIC
            && b[END..].iter().all(|&x| x == 0xFF);
        if !ok {
            return ImSlot::Invalid;
        }
        let mut d = [0u8; ImData::LEN];
        d.copy_from_slice(&b[DATA..CRC]);
        ImSlot::Valid(ImRecord { seq: u32::from_le_bytes([b[0], b[1], b[2], b[3]]), data: ImData::decode(&d) })
    }
}

/// The power-loss-safe I&M1–4 journal (see the module documentation).
#[derive(Debug)]
pub struct ImJournal<F: Flash> {
    flash: F,
}

impl<F: Flash> ImJournal<F> {
    /// Record slots per sector.
    pub const SLOTS: u32 = F::SECTOR_SIZE / IM_RECORD_SIZE as u32;

    /// A journal over `flash` (no flash access yet).
    pub fn new(flash: F) -> Self {
        ImJournal { flash }
    }

    /// The flash device.
    pub fn flash(&self) -> &F {
        &self.flash
    }

    /// Give the flash device back.
    pub fn into_inner(self) -> F {
        self.flash
    }

    fn read_slot(&self, sector: u8, slot: u32) -> [u8; IM_RECORD_SIZE] {
        let mut b = [0u8; IM_RECORD_SIZE];
        self.flash.read(sector, slot * IM_RECORD_SIZE as u32, &mut b);
        b
    }

    /// The newest valid record and its sector; per sector the first free slot after the last
    /// used one (`None` = full).
    fn scan(&self) -> (Option<(u8, ImRecord)>, [Option<u32>; 2]) {
        let mut newest: Option<(u8, ImRecord)> = None;
        let mut free = [Some(0); 2];
        for sector in 0..2u8 {
            for slot in 0..Self::SLOTS {
                match ImRecord::decode(&self.read_slot(sector, slot)) {
                    ImSlot::Empty => continue,
                    ImSlot::Valid(r) => {
                        if newest.is_none_or(|(_, n)| r.seq > n.seq) {
                            newest = Some((sector, r));
                        }
                    }
                    ImSlot::Invalid => {}
                }
                free[sector as usize] = if slot + 1 < Self::SLOTS { Some(slot + 1) } else { None };
            }
        }
        (newest, free)
    }

    /// The newest valid record, `None` on a blank or erased journal.
    pub fn latest(&self) -> Option<ImRecord> {
        self.scan().0.map(|(_, r)| r)
    }

    /// The stored I&M1–4 (`None`: never written — the card ships [`ImData::DEFAULT`]).
    pub fn load(&self) -> Option<ImData> {
        self.latest().map(|r| r.data)
    }

    /// Append `data` as the newest record (nothing is written when it already is). Returns
    /// the record written.
    pub fn save(&mut self, data: &ImData) -> Result<Option<ImRecord>, StoreError<F::Error>> {
        if Self::SLOTS == 0 {
            return Err(StoreError::Exhausted);
        }
        let (newest, free) = self.scan();
        let seq = match newest {
            Some((_, r)) if r.data == *data => return Ok(None),
            Some((_, r)) => r.seq.checked_add(1).ok_or(StoreError::Exhausted)?,
            None => 1,
        };
        let rec = ImRecord { seq, data: *data };
        let active = newest.map_or(0, |(s, _)| s);
        let (sector, slot) = match free[active as usize] {
            Some(slot) => (active, slot),
            None => {
                let other = 1 - active;
                self.flash.erase(other).map_err(StoreError::Flash)?;
                (other, 0)
            }
        };
        let bytes = rec.encode();
        self.flash.program(sector, slot * IM_RECORD_SIZE as u32, &bytes).map_err(StoreError::Flash)?;
        if self.read_slot(sector, slot) != bytes {
            return Err(StoreError::Verify);
        }
        Ok(Some(rec))
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::{PowerCut, SimFlash};
    use super::*;
    use crate::dpv1::im::CONTENT_LEN;

    fn data(k: u8) -> ImData {
        let mut d = ImData::DEFAULT;
        for (i, r) in d.records.iter_mut().enumerate() {
            r.iter_mut()
                .enumerate()
                .for_each(|(j, b)| *b = k.wrapping_mul(31).wrapping_add((i * CONTENT_LEN + j) as u8));
        }
        d
    }

    #[test]
    fn layout_and_round_trip() {
        let r = ImRecord { seq: 7, data: data(3) };
        let b = r.encode();
        assert_eq!(&b[..5], &[7, 0, 0, 0, 0x1A]);
        assert_eq!(&b[5..5 + 54], &r.data.records[0]);
        assert!(b[225..].iter().all(|&x| x == 0xFF));
        assert_eq!(ImRecord::decode(&b), ImSlot::Valid(r));
        assert_eq!(ImRecord::decode(&[0xFF; IM_RECORD_SIZE]), ImSlot::Empty);
        assert_eq!(ImRecord::decode(&[0; IM_RECORD_SIZE]), ImSlot::Invalid);
        let mut bad = b;
        bad[100] ^= 0x10;
        assert_eq!(ImRecord::decode(&bad), ImSlot::Invalid);
    }

    #[test]
    fn blank_then_saves_with_sector_switches() {
        let mut j = ImJournal::new(SimFlash::<768>::new()); // 3 slots per sector
        assert_eq!(j.load(), None);
        for k in 0..10 {
            j.save(&data(k)).unwrap();
            assert_eq!(j.load(), Some(data(k)));
        }
        assert_eq!(j.save(&data(9)).unwrap(), None, "unchanged: nothing written");
        assert_eq!(j.latest().unwrap().seq, 10);
        assert!(j.flash().erases >= 3);
    }

    /// A power cut after every single byte-program or byte-erase step of a sequence of saves
    /// with sector switches: the journal loads the old or the new I&M1–4, never garbage, never
    /// nothing once a save completed, and works on after the reboot.
    #[test]
    fn power_cut_at_every_step() {
        const SAVES: usize = 7;
        let total = {
            let mut j = ImJournal::new(SimFlash::<512>::new()); // 2 slots per sector
            for k in 0..SAVES {
                j.save(&data(k as u8)).unwrap();
            }
            j.flash().steps
        };
        let mut cuts = 0;
        for k in 0..=total {
            for seed in [0x1234_5678_9ABC_DEF1u64, 0xFFFF_FFFF_FFFF_FFFF] {
                let mut flash = SimFlash::<512>::new();
                flash.cut_after(k, seed);
                let mut j = ImJournal::new(flash);
                let mut committed = None;
                let mut cut_at = None;
                for i in 0..SAVES {
                    match j.save(&data(i as u8)) {
                        Ok(_) => committed = Some(data(i as u8)),
                        Err(StoreError::Flash(PowerCut)) => {
                            cut_at = Some(i);
                            break;
                        }
                        Err(e) => panic!("{e:?}"),
                    }
                }
                let mut flash = j.into_inner();
                flash.power_on();
                let mut j = ImJournal::new(flash);
                let loaded = j.load();
                match cut_at {
                    None => assert_eq!(loaded, committed),
                    Some(i) => {
                        cuts += 1;
                        assert!(
                            loaded == committed || loaded == Some(data(i as u8)),
                            "cut after {k} steps in save {i}: {loaded:?}"
                        );
                        if committed.is_some() {
                            assert!(loaded.is_some());
                        }
                        for n in i..SAVES {
                            j.save(&data(n as u8)).unwrap();
                            assert_eq!(j.load(), Some(data(n as u8)));
                        }
                    }
                }
            }
        }
        assert_eq!(cuts, 2 * total);
    }

    proptest::proptest! {
        /// Unidirectional damage (0 → 1) to a record is always detected.
        #[test]
        fn berger_check_detects_unidirectional_errors(seq in proptest::num::u32::ANY, k in proptest::num::u8::ANY,
                                                     at in 0usize..225, mask in 1u8..=255) {
            let r = ImRecord { seq, data: data(k) };
            let mut b = r.encode();
            b[at] |= mask;
            let damaged = b != r.encode();
            match ImRecord::decode(&b) {
                ImSlot::Valid(v) => { proptest::prop_assert!(!damaged); proptest::prop_assert_eq!(v, r); }
                ImSlot::Empty | ImSlot::Invalid => proptest::prop_assert!(damaged),
            }
        }
    }
}
