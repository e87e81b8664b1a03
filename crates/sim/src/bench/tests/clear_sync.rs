//! Safety of the outputs under every combination of Global_Control commands, fail-safe Clear,
//! Data_Exchange of any length, a second master and the DP watchdog — bytes in through the
//! shipped card (`Node` + `Application`), judged at the DPM OUTPUTS block, i.e. what the
//! drive reads (brief: "outputs to the drive are either the newest valid ones or zero —
//! never stale"; reference §3.6 Global_Control, §3.7 Clear / fail-safe).
//!
//! A model of EN 50170's output rules says what the drive must see after every request:
//! - Clear_Data (Global_Control b1) or a zero-length Data_Exchange (fail-safe Clear): zero,
//!   and an image Sync held is discarded;
//! - Sync (b5): the outputs received since apply at the next Sync or Unsync (b4; Unsync wins
//!   when both are set), until then the drive keeps the image of the previous Sync;
//! - Freeze / Unfreeze (b3 / b2) touch no output; reserved bits change nothing else;
//! - a Global_Control to another group, a Data_Exchange from another master: no change;
//! - a Data_Exchange of another length than configured: RS, data exchange left, zero;
//! - the watchdog expiring (no request for longer than its time): zero.

use super::*;
use proptest::prelude::*;

const OTHER_MASTER: u8 = 3;

/// One thing a master (or time) does.
#[derive(Clone, Debug)]
enum Op {
    /// Data_Exchange with an image made from the seed.
    Dx(u8),
    /// Data_Exchange with zero-length outputs (fail-safe Clear).
    DxEmpty,
    /// Data_Exchange one byte longer than configured.
    DxWrongLength(u8),
    /// Data_Exchange from a master that did not parameterise the slave.
    DxOtherMaster(u8),
    /// Global_Control command octet to group 0 (all slaves).
    Gc(u8),
    /// Global_Control to group 8, which this slave (Group_Ident 0) is not in.
    GcOtherGroup(u8),
    /// The application's cycle: time passes (short of the watchdog).
    Step(u8),
    /// No request for 1.5 s: the 1 s watchdog expires; then the master parameterises again.
    WatchdogExpires,
}

fn op() -> impl Strategy<Value = Op> {
    prop_oneof![
        4 => any::<u8>().prop_map(Op::Dx),
        1 => Just(Op::DxEmpty),
        1 => any::<u8>().prop_map(Op::DxWrongLength),
        1 => any::<u8>().prop_map(Op::DxOtherMaster),
        // Mostly the defined bits (Clear 02, Unfreeze 04, Freeze 08, Unsync 10, Sync 20) in
        // every combination, sometimes any octet (reserved bits 01, 40, 80).
        4 => (0u8..64).prop_map(|c| Op::Gc(c & 0x3E)),
        1 => any::<u8>().prop_map(Op::Gc),
        1 => (0u8..64).prop_map(|c| Op::GcOtherGroup(c & 0x3E)),
        2 => (1u8..=20).prop_map(Op::Step),
        1 => Just(Op::WatchdogExpires),
    ]
}

/// What the drive must see: the model's state.
#[derive(Debug)]
struct Model {
    /// The outputs in force (what the DPM OUTPUTS block must carry).
    applied: Vec<u8>,
    /// Outputs received in Sync mode, applied at the next Sync / Unsync.
    pending: Option<Vec<u8>>,
    sync: bool,
    gc_clear: bool,
}

impl Model {
    fn new(n: usize) -> Self {
        Model { applied: vec![0; n], pending: None, sync: false, gc_clear: false }
    }

    fn zero(&mut self) {
        self.applied.iter_mut().for_each(|b| *b = 0);
        self.pending = None;
    }

    fn dx(&mut self, image: &[u8]) {
        if self.gc_clear {
            // Clear mode: whatever the master sends, the outputs stay zero.
        } else if self.sync {
            self.pending = Some(image.to_vec());
        } else {
            self.applied = image.to_vec();
        }
    }

    fn gc(&mut self, cmd: u8) {
        self.gc_clear = cmd & 0x02 != 0;
        if self.gc_clear {
            self.zero();
        }
        if cmd & 0x30 != 0 {
            if let Some(p) = self.pending.take() {
                self.applied = p;
            }
            self.sync = cmd & 0x10 == 0;
        }
    }
}

fn image_of(seed: u8, n: usize) -> Vec<u8> {
    (0..n).map(|i| seed.wrapping_mul(31).wrapping_add((i as u8).wrapping_mul(7)).wrapping_add(1)).collect()
}

impl Bench {
    /// A Data_Exchange from `sa`; the response bytes.
    fn dx_from(&mut self, sa: u8, outputs: &[u8]) -> Vec<u8> {
        self.send_from(sa, None, None, outputs)
    }

    /// The outputs the drive reads (DPM OUTPUTS), the configured length.
    fn drive_outputs(&self, n: usize) -> Vec<u8> {
        let pd = self.app.dpm().outputs().expect("OUTPUTS never torn between steps");
        let mut v = pd.bytes().to_vec();
        v.resize(n, 0);
        v
    }
}

/// The modules of every control profile family with Sync support (the GSD's ST1, ST20,
/// PPO 1 … 5, the vendor telegrams; in the bench build also Bench 32/32). The bench build's
/// 244-byte module is left out: the DPM carries only its first `PD_CAPACITY` bytes
/// (`card::BENCH_244`), so the drive never sees the whole image the model compares.
fn modules() -> Vec<&'static card::Module> {
    card::MODULES
        .iter()
        .filter(|m| m.outputs >= 4 && usize::from(m.outputs) <= crate::dpm::layout::PD_CAPACITY)
        .collect()
}

fn run(module: usize, ops: &[Op]) -> Result<(), TestCaseError> {
    let mods = modules();
    let m = mods[module % mods.len()];
    let n = m.outputs as usize;
    let mut b = Bench::new();
    b.bring_up_sync_freeze(m);
    let mut model = Model::new(n);
    // Images sent since the last Clear / fail-safe / leave: the only ones the drive may see.
    let mut fresh: Vec<Vec<u8>> = Vec::new();
    for (k, op) in ops.iter().enumerate() {
        match *op {
            Op::Dx(seed) => {
                let img = image_of(seed, n);
                let r = b.dx_from(MASTER, &img);
                prop_assert!(matches!(r[0], 0x68 | 0xA2 | telegram::SC), "{k}: {op:?} answered {r:02X?}");
                model.dx(&img);
                if !model.gc_clear {
                    fresh.push(img);
                }
            }
            Op::DxEmpty => {
                b.dx_from(MASTER, &[]);
                model.zero();
                fresh.clear();
            }
            Op::DxWrongLength(seed) => {
                let r = b.dx_from(MASTER, &image_of(seed, n + 1));
                prop_assert_eq!(r.len(), 6, "{}: RS (SD1)", k);
                prop_assert_eq!(b.node.slave().state(), DpState::WaitPrm);
                model = Model::new(n);
                fresh.clear();
                b.step(1);
                prop_assert_eq!(b.drive_outputs(n), model.applied.clone(), "{}: zero after leaving", k);
                b.bring_up_sync_freeze(m);
            }
            Op::DxOtherMaster(seed) => {
                let r = b.dx_from(OTHER_MASTER, &image_of(seed, n));
                prop_assert_eq!(r.len(), 6, "{}: RS to another master", k);
            }
            Op::Gc(cmd) => {
                b.gc(cmd, 0);
                model.gc(cmd);
                if cmd & 0x02 != 0 {
                    fresh.clear();
                }
            }
            Op::GcOtherGroup(cmd) => b.gc(cmd, 0x08),
            Op::Step(ms) => {
                b.step(u64::from(ms));
            }
            Op::WatchdogExpires => {
                b.step(1500);
                prop_assert_ne!(b.node.slave().state(), DpState::DataExch, "{}: the watchdog expired", k);
                model = Model::new(n);
                fresh.clear();
                b.step(1);
                prop_assert_eq!(b.drive_outputs(n), model.applied.clone(), "{}: zero after the watchdog", k);
                b.bring_up_sync_freeze(m);
            }
        }
        b.step(1);
        let seen = b.drive_outputs(n);
        prop_assert_eq!(&seen, &model.applied, "{}: after {:?} ({}), model {:?}", k, op, m.name, model);
        prop_assert!(
            seen.iter().all(|&x| x == 0) || fresh.contains(&seen),
            "{k}: stale outputs reached the drive after {op:?}"
        );
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 96, ..ProptestConfig::default() })]

    /// Every combination of Clear / Sync / Unsync / Freeze / Unfreeze (and reserved bits),
    /// fail-safe Clear, wrong lengths, a second master, other groups and the watchdog: the
    /// drive sees exactly the model's outputs, which are zero or an image sent since the last
    /// Clear — never a stale one.
    #[test]
    fn the_drive_sees_the_newest_valid_outputs_or_zero(module in 0usize..64, ops in proptest::collection::vec(op(), 1..40)) {
        run(module, &ops)?;
    }
}

/// The hand-picked sequences a test lab starts with, per module: Clear with Sync held,
/// Sync–Clear–Unsync, fail-safe Clear under Sync, Clear + Sync + Freeze in one command.
#[test]
fn the_classic_clear_sync_sequences() {
    use Op::*;
    let sequences: &[&[Op]] = &[
        &[Dx(1), Gc(0x20), Dx(2), Gc(0x22), Gc(0x00), Gc(0x10)],
        &[Dx(1), Gc(0x20), Dx(2), Gc(0x12), Dx(3), Gc(0x00), Dx(4)],
        &[Dx(1), Gc(0x20), Dx(2), DxEmpty, Gc(0x20), Dx(3), Gc(0x10)],
        &[Dx(1), Gc(0x2A), Dx(2), Gc(0x28), Dx(3), Gc(0x14)],
        &[Gc(0x20), Dx(1), Gc(0x20), Dx(2), WatchdogExpires, Dx(3), Gc(0x10)],
        &[Dx(1), Gc(0x20), Dx(2), DxWrongLength(3), Dx(4)],
        &[Dx(1), Gc(0x22), Dx(2), DxOtherMaster(3), Gc(0x20), Dx(4), Gc(0x20)],
    ];
    for module in 0..modules().len() {
        for s in sequences {
            if let Err(e) = run(module, s) {
                panic!("module {module}, {s:?}: {e}");
            }
        }
    }
}
