//! The journal under power cuts: a cut after every single byte step of long save sequences,
//! for each record type alone and for the two interleaved in one journal, with compactions.

use super::sim::{PowerCut, SimFlash};
use super::*;
use crate::dpv1::im::{ImData, CONTENT_LEN};
use std::vec::Vec;

/// Three slots per sector: a compaction every few saves.
const S3: usize = 3 * SLOT_SIZE;
/// Two slots per sector: the smallest journal for two kinds (every compaction fills it).
const S2: usize = 2 * SLOT_SIZE;

fn addr(address: u8, no_add_chg: bool) -> StationAddress {
    StationAddress { address, no_add_chg }
}

/// I&M1–4 number `k` (every byte depends on `k` and its place).
pub(crate) fn im(k: u8) -> ImData {
    let mut d = ImData::DEFAULT;
    for (i, r) in d.records.iter_mut().enumerate() {
        r.iter_mut().enumerate().for_each(|(j, b)| *b = k.wrapping_mul(31).wrapping_add((i * CONTENT_LEN + j) as u8));
    }
    d
}

/// One save of a sequence.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Op {
    Addr(StationAddress),
    Im(u8),
}

/// What the journal holds of each kind.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
struct State {
    addr: Option<StationAddress>,
    im: Option<ImData>,
}

impl State {
    fn of<F: Flash>(j: &Journal<F>) -> State {
        State { addr: j.load::<StationAddress>(), im: j.load::<ImData>() }
    }
    fn after(mut self, op: Op) -> State {
        match op {
            Op::Addr(a) => self.addr = Some(a),
            Op::Im(k) => self.im = Some(im(k)),
        }
        self
    }
}

fn apply<F: Flash>(j: &mut Journal<F>, op: Op) -> Result<bool, StoreError<F::Error>> {
    match op {
        Op::Addr(a) => j.save(&a),
        Op::Im(k) => j.save(&im(k)),
    }
}

/// Run `ops` on a blank flash with a power cut after `k` steps; then power on and check that
/// every kind holds its committed value, or — only the kind being saved — the new one, and
/// nothing is lost once saved; then go on with the rest, checking after each: with the
/// interrupted save redone first (`redo`), or dropped (the next save, often of the other
/// kind, then completes an interrupted compaction). Returns whether the cut fell inside the
/// sequence.
fn run_with_cut<const N: usize>(ops: &[Op], k: u64, seed: u64, redo: bool) -> bool {
    let mut flash = SimFlash::<N>::new();
    flash.cut_after(k, seed);
    let mut j = Journal::new(flash);
    let mut committed = State::default();
    let mut cut_at = None;
    for (i, &op) in ops.iter().enumerate() {
        match apply(&mut j, op) {
            Ok(_) => committed = committed.after(op),
            Err(StoreError::Flash(PowerCut)) => {
                cut_at = Some(i);
                break;
            }
            Err(e) => panic!("{e:?} in save {i} ({op:?})"),
        }
    }
    let mut flash = j.into_inner();
    flash.power_on();
    let mut j = Journal::new(flash);
    let loaded = State::of(&j);
    match cut_at {
        None => assert_eq!(loaded, committed),
        Some(i) => {
            let new = committed.after(ops[i]);
            let ok_addr = loaded.addr == committed.addr || loaded.addr == new.addr;
            let ok_im = loaded.im == committed.im || loaded.im == new.im;
            assert!(
                ok_addr && ok_im,
                "cut after {k} steps (seed {seed:#x}) in save {i} ({:?}): loaded {loaded:?}, committed {committed:?}",
                ops[i]
            );
            for &op in &ops[if redo { i } else { i + 1 }..] {
                let want = State::of(&j).after(op);
                apply(&mut j, op).unwrap_or_else(|e| panic!("after the cut at {k}: {e:?} in {op:?}"));
                assert_eq!(State::of(&j), want, "after the cut at {k} (seed {seed:#x}), {op:?}");
            }
        }
    }
    cut_at.is_some()
}

fn total_steps<const N: usize>(ops: &[Op]) -> u64 {
    let mut j = Journal::new(SimFlash::<N>::new());
    for &op in ops {
        apply(&mut j, op).unwrap();
    }
    j.flash().steps
}

/// A power cut after every single step of `ops`, with several partial-bit patterns per step.
fn cut_everywhere<const N: usize>(ops: &[Op], seeds: &[u64]) {
    let total = total_steps::<N>(ops);
    let mut cuts = 0;
    for k in 0..=total {
        for &seed in seeds {
            if run_with_cut::<N>(ops, k, seed, true) {
                cuts += 1;
            }
            if seed == seeds[0] {
                run_with_cut::<N>(ops, k, seed, false);
            }
        }
    }
    assert_eq!(cuts, seeds.len() as u64 * total, "every step was cut once per seed");
}

/// Partial-bit patterns of the cut step; 0 = a clean cut.
const SEEDS: [u64; 2] = [0x1234_5678_9ABC_DEF1, 0];

#[test]
fn crc_check_value() {
    assert_eq!(crc16(b"123456789"), 0x29B1);
}

#[test]
fn slot_layout_and_round_trip() {
    let b = encode_slot(0x0102_0304, StationAddress::KIND, &[126, 1]);
    assert_eq!(&b[0..8], &[0x04, 0x03, 0x02, 0x01, 0x01, 2, 126, 1]);
    assert!(b[8..252].iter().all(|&x| x == 0xFF), "padding stays erased");
    assert_eq!(&b[252..254], &crc16(&b[..8]).to_be_bytes());
    assert_eq!(u16::from_be_bytes([b[254], b[255]]), zero_bits(&b[..254]));
    assert_eq!(decode_slot(&b), Slot::Valid(SlotHeader { seq: 0x0102_0304, kind: 1, len: 2 }));
    assert_eq!(decode_slot(&[0xFF; SLOT_SIZE]), Slot::Empty);
    assert_eq!(decode_slot(&[0x00; SLOT_SIZE]), Slot::Invalid);
    let mut bad = b;
    bad[6] = 3; // payload changed, counts fixed up: the CRC catches it
    let z = zero_bits(&bad[..254]);
    bad[254..].copy_from_slice(&z.to_be_bytes());
    assert_eq!(decode_slot(&bad), Slot::Invalid);
    assert_eq!(StationAddress::decode(&[127, 0]), None);
    assert_eq!(StationAddress::decode(&[5, 2]), None);
    assert_eq!(StationAddress::decode(&[5, 1]), Some(addr(5, true)));
    let d = im(9);
    let mut p = [0u8; ImData::LEN];
    Record::encode(&d, &mut p);
    assert_eq!(<ImData as Record>::decode(&p), Some(d));
}

#[test]
fn blank_journal_loads_nothing_then_saves() {
    let mut j = Journal::new(SimFlash::<S3>::new());
    assert_eq!(AddressStore::load(&mut j), None);
    assert_eq!(j.load::<ImData>(), None);
    AddressStore::save(&mut j, 7, false).unwrap();
    assert_eq!(AddressStore::load(&mut j), Some((7, false)));
    assert_eq!(j.flash().steps, 8 + 4, "an address record programs 12 bytes");
    assert_eq!(j.save(&addr(7, false)), Ok(false), "unchanged: nothing written");
    assert_eq!(j.flash().steps, 12);
    assert_eq!(AddressStore::save(&mut j, 127, false), Err(StoreError::Address(127)));
    assert_eq!(j.save(&im(1)), Ok(true));
    assert_eq!(j.load::<ImData>(), Some(im(1)));
    assert_eq!(j.load::<StationAddress>(), Some(addr(7, false)), "the other kind is untouched");
    j.save(&addr(9, true)).unwrap();
    assert_eq!(j.latest::<StationAddress>(), Some((3, addr(9, true))));
    j.erase_all().unwrap();
    assert_eq!(State::of(&j), State::default());
}

/// A full sector is compacted: the other kind's newest record is carried over, nothing is
/// lost, and the sector holding the newest records is never erased.
#[test]
fn compaction_carries_the_other_kind() {
    let mut j = Journal::new(SimFlash::<S3>::new());
    j.save(&im(1)).unwrap();
    for a in 0..20u8 {
        j.save(&addr(a, a % 3 == 0)).unwrap();
        assert_eq!(State::of(&j), State { addr: Some(addr(a, a % 3 == 0)), im: Some(im(1)) });
    }
    // Each compaction: 1 copy of I&M + the new address → 1 more address fits per sector.
    assert!(j.flash().erases >= 9, "{}", j.flash().erases);
    for k in 2..6 {
        j.save(&im(k)).unwrap();
        assert_eq!(State::of(&j), State { addr: Some(addr(19, false)), im: Some(im(k)) });
    }
    let mut j2 = Journal::new(SimFlash::<S2>::new());
    for k in 0..6 {
        j2.save(&addr(k, false)).unwrap();
        j2.save(&im(k)).unwrap();
        assert_eq!(State::of(&j2), State { addr: Some(addr(k, false)), im: Some(im(k)) });
    }
}

#[test]
fn a_sector_too_small_for_every_kind_is_refused() {
    let mut j = Journal::new(SimFlash::<SLOT_SIZE>::new());
    j.save(&addr(3, false)).unwrap();
    assert_eq!(j.save(&im(1)), Err(StoreError::Exhausted));
    assert_eq!(State::of(&j), State { addr: Some(addr(3, false)), im: None });
}

/// The address alone (the old journal's sequence): many compactions, flag changes, a
/// repeated pair (no write).
const ADDRESS_SAVES: [Op; 15] = [
    Op::Addr(StationAddress { address: 3, no_add_chg: false }),
    Op::Addr(StationAddress { address: 126, no_add_chg: false }),
    Op::Addr(StationAddress { address: 0, no_add_chg: false }),
    Op::Addr(StationAddress { address: 125, no_add_chg: true }),
    Op::Addr(StationAddress { address: 125, no_add_chg: true }),
    Op::Addr(StationAddress { address: 4, no_add_chg: false }),
    Op::Addr(StationAddress { address: 4, no_add_chg: true }),
    Op::Addr(StationAddress { address: 126, no_add_chg: false }),
    Op::Addr(StationAddress { address: 17, no_add_chg: false }),
    Op::Addr(StationAddress { address: 18, no_add_chg: false }),
    Op::Addr(StationAddress { address: 19, no_add_chg: true }),
    Op::Addr(StationAddress { address: 20, no_add_chg: false }),
    Op::Addr(StationAddress { address: 1, no_add_chg: false }),
    Op::Addr(StationAddress { address: 2, no_add_chg: true }),
    Op::Addr(StationAddress { address: 99, no_add_chg: false }),
];

/// Power cut after every single byte-program or byte-erase step of address saves: the
/// journal loads the old or the new pair, never garbage, never nothing once saved.
#[test]
fn power_cut_at_every_step_address_only() {
    cut_everywhere::<S3>(&ADDRESS_SAVES, &[0x1234_5678_9ABC_DEF1, 0x0F0F_0F0F_1111_2222, 0]);
    cut_everywhere::<S2>(&ADDRESS_SAVES[..8], &SEEDS);
}

/// The same for I&M1–4 alone.
#[test]
fn power_cut_at_every_step_im_only() {
    let ops: Vec<Op> = [1, 2, 3, 3, 4, 5, 6].into_iter().map(Op::Im).collect();
    cut_everywhere::<S3>(&ops, &SEEDS);
    cut_everywhere::<S2>(&ops[..5], &SEEDS);
}

/// Both kinds in one journal: address written, then I&M, a cut during the I&M write → the
/// address is still good (and the other way round), through compactions and cuts during
/// compactions (erase, copy of the other kind, the new record).
#[test]
fn power_cut_at_every_step_interleaved() {
    let ops = [
        Op::Addr(addr(5, false)),
        Op::Im(1),
        Op::Addr(addr(6, false)),
        Op::Im(2),
        Op::Im(2),
        Op::Addr(addr(6, false)),
        Op::Addr(addr(7, true)),
        Op::Im(3),
        Op::Addr(addr(126, false)),
        Op::Addr(addr(8, false)),
        Op::Im(4),
        Op::Addr(addr(9, false)),
    ];
    cut_everywhere::<S3>(&ops, &SEEDS);
    cut_everywhere::<S2>(&ops[..8], &SEEDS);
    // I&M first on a blank journal, then the address.
    cut_everywhere::<S3>(&[Op::Im(7), Op::Addr(addr(10, false)), Op::Im(8), Op::Addr(addr(11, false))], &SEEDS);
    // Runs of one kind after a cut compaction for the other: the compaction must be completed
    // by the first of them, before the sector fills.
    let runs = [
        Op::Addr(addr(1, false)),
        Op::Im(1),
        Op::Addr(addr(2, false)),
        Op::Addr(addr(3, false)),
        Op::Im(2),
        Op::Addr(addr(4, false)),
        Op::Addr(addr(5, false)),
        Op::Addr(addr(6, false)),
        Op::Im(3),
        Op::Im(4),
        Op::Addr(addr(7, false)),
        Op::Addr(addr(8, false)),
        Op::Addr(addr(9, false)),
    ];
    cut_everywhere::<{ 4 * SLOT_SIZE }>(&runs, &SEEDS);
}

/// Run `ops` with a cut after `k` steps (none when the sequence needs fewer), power on, and
/// check every kind against `committed` (updated): its value, or the new one of the save that
/// was cut. Returns the journal after the reboot and the index of the cut save.
fn cut_run<const N: usize>(
    flash: SimFlash<N>,
    ops: &[Op],
    k: u64,
    seed: u64,
    committed: &mut State,
) -> (Journal<SimFlash<N>>, Option<usize>) {
    let mut flash = flash;
    flash.cut_after(k, seed);
    let mut j = Journal::new(flash);
    let mut cut_at = None;
    for (i, &op) in ops.iter().enumerate() {
        match apply(&mut j, op) {
            Ok(_) => *committed = committed.after(op),
            Err(StoreError::Flash(PowerCut)) => {
                cut_at = Some(i);
                break;
            }
            Err(e) => panic!("{e:?} in save {i} ({op:?})"),
        }
    }
    let mut flash = j.into_inner();
    flash.power_on();
    let j = Journal::new(flash);
    let loaded = State::of(&j);
    let new = cut_at.map_or(*committed, |i| committed.after(ops[i]));
    assert!(loaded.addr == committed.addr || loaded.addr == new.addr, "{loaded:?} {committed:?} {new:?}");
    assert!(loaded.im == committed.im || loaded.im == new.im, "{loaded:?} {committed:?} {new:?}");
    *committed = loaded;
    (j, cut_at)
}

/// Two cuts in a row: a compaction cut after it copied the other kind (the new record not
/// written), a save of the other kind that completes it, then a cut at every step of the
/// next saves (which fill the sector and compact again). Each kind still loads its last value
/// or the one being saved: the first save after the cut must have carried the record the cut
/// compaction left behind.
#[test]
fn a_cut_compaction_then_a_cut_while_it_is_completed() {
    let prefix = [Op::Addr(addr(1, false)), Op::Im(1), Op::Addr(addr(2, false))];
    let rest = [Op::Addr(addr(3, false)), Op::Addr(addr(4, false)), Op::Addr(addr(5, false)), Op::Im(3)];
    let mut j = Journal::new(SimFlash::<S3>::new());
    for &op in &prefix {
        apply(&mut j, op).unwrap();
    }
    // Im(2) compacts: erase (S3 steps), copy the address (12 steps), I&M (226 steps).
    let committed = State::of(&j);
    for (k1, seed) in [(S3 as u64 + 12, 0), (S3 as u64 + 12, 7), (S3 as u64 + 12 + 100, 0)] {
        let mut c = committed;
        let (j1, cut) = cut_run(j.flash().clone(), &[Op::Im(2)], k1, seed, &mut c);
        assert_eq!(cut, Some(0));
        assert_eq!(c, committed, "the cut save did not take");
        let total = {
            let mut j = Journal::new(j1.flash().clone());
            let s0 = j.flash().steps;
            for &op in &rest {
                apply(&mut j, op).unwrap();
            }
            j.flash().steps - s0
        };
        for k2 in 0..=total {
            let mut c2 = c;
            let (mut j2, cut) = cut_run(j1.flash().clone(), &rest, k2, k2 ^ 0x5555, &mut c2);
            for &op in &rest[cut.unwrap_or(rest.len())..] {
                let want = State::of(&j2).after(op);
                apply(&mut j2, op).unwrap();
                assert_eq!(State::of(&j2), want, "k1 {k1} k2 {k2} {op:?}");
            }
        }
    }
}

proptest::proptest! {
    /// Power cuts after random steps during random saves of both kinds, several reboots in a
    /// row (also cuts while an earlier cut compaction is being completed or restarted).
    #[test]
    fn repeated_power_cuts(ops in proptest::collection::vec((proptest::bool::ANY, 0u8..=126, proptest::bool::ANY, 0u64..1200, proptest::num::u64::ANY), 1..40)) {
        let mut flash = SimFlash::<S3>::new();
        let mut committed = State::default();
        for (is_im, a, f, cut, seed) in ops {
            let op = if is_im { Op::Im(a) } else { Op::Addr(addr(a, f)) };
            flash.cut_after(cut, seed);
            let mut j = Journal::new(flash);
            let r = apply(&mut j, op);
            flash = j.into_inner();
            flash.power_on();
            let j = Journal::new(flash);
            let loaded = State::of(&j);
            let new = committed.after(op);
            match r {
                Ok(_) => proptest::prop_assert_eq!(loaded, new),
                Err(StoreError::Flash(PowerCut)) => {
                    proptest::prop_assert!(loaded.addr == committed.addr || loaded.addr == new.addr, "{:?}", loaded);
                    proptest::prop_assert!(loaded.im == committed.im || loaded.im == new.im, "{:?}", loaded);
                }
                Err(e) => proptest::prop_assert!(false, "{:?}", e),
            }
            committed = loaded;
            flash = j.into_inner();
        }
    }

    /// Unidirectional damage (0 → 1: torn program or partial erase) to a slot is always
    /// detected.
    #[test]
    fn berger_check_detects_unidirectional_errors(seq in proptest::num::u32::ANY, k in proptest::num::u8::ANY, is_im in proptest::bool::ANY,
                                                 damage in proptest::collection::vec((0usize..SLOT_SIZE, 1u8..=255), 1..6)) {
        let b0 = if is_im {
            let mut p = [0u8; ImData::LEN];
            Record::encode(&im(k), &mut p);
            encode_slot(seq, ImData::KIND, &p)
        } else {
            encode_slot(seq, StationAddress::KIND, &[k % 127, k & 1])
        };
        let mut b = b0;
        for (at, m) in damage {
            b[at] |= m;
        }
        let damaged = b != b0;
        match decode_slot(&b) {
            Slot::Valid(_) => proptest::prop_assert!(!damaged),
            Slot::Empty | Slot::Invalid => proptest::prop_assert!(damaged),
        }
    }

    /// Arbitrary bytes: never a panic; a valid slot re-encodes to the same bytes.
    #[test]
    fn decode_arbitrary_bytes(v in proptest::collection::vec(proptest::num::u8::ANY, SLOT_SIZE)) {
        let mut b = [0u8; SLOT_SIZE];
        b.copy_from_slice(&v);
        if let Slot::Valid(h) = decode_slot(&b) {
            let len = h.len as usize;
            proptest::prop_assert_eq!(encode_slot(h.seq, h.kind, &b[HEADER_LEN..HEADER_LEN + len]), b);
        }
    }
}

#[test]
fn invalid_slots_are_skipped_not_reused() {
    let mut flash = SimFlash::<S3>::new();
    flash.mem[0][0] = 0x12; // garbage in slot 0
    flash.mem[0][SLOT_SIZE + 20] = 0x00; // garbage in slot 1
    let mut j = Journal::new(flash);
    assert_eq!(State::of(&j), State::default());
    j.save(&addr(5, false)).unwrap(); // slot 2: the sector is now full
    assert_eq!(j.load::<StationAddress>(), Some(addr(5, false)));
    j.save(&im(1)).unwrap(); // → sector 1: address copied, then I&M
    assert_eq!(j.flash().erases, 1);
    assert_eq!(State::of(&j), State { addr: Some(addr(5, false)), im: Some(im(1)) });
    let v: Vec<Slot> = (0..3).map(|i| decode_slot(&j.read_slot(1, i))).collect();
    assert!(matches!(v[0], Slot::Valid(SlotHeader { kind: 1, .. })));
    assert!(matches!(v[1], Slot::Valid(SlotHeader { kind: 2, .. })));
    assert_eq!(v[2], Slot::Empty);
}
