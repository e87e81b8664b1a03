//! The fast path's tests with this card's configuration (moved with `crates/link`, issue 13
//! item 4: they run `card::SLAVE`, the scripted master and the card's records, which are above
//! the line side): the split against the core alone, chunking, the lock table, Global_Control.

use crate::card;
use crate::dp::diag::Status1;
use crate::dp::DpSlave;
use crate::dp::DpState;
use crate::fast::check::{self, Mode};
use crate::fast::*;
use crate::fdl::telegram::{self, Decoded, FunctionCode, Header, ResponseStatus, Telegram};
use crate::node::Node;
use crate::phy::stream::TelegramSink;
use crate::testkit::{ScriptedMaster, SetPrm};
use crate::time::Instant;
use proptest::prelude::*;

fn hex(s: &str) -> std::vec::Vec<u8> {
    (0..s.len()).step_by(2).map(|i| u8::from_str_radix(&s[i..i + 2], 16).unwrap()).collect()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]
    /// Any sequence (two masters, retries, foreign traffic, mangled sources, the lock
    /// table, short Set_Prm, Data_Exchange of any length, Global_Control): the split
    /// answers as the core alone, byte for byte ([`Mode::Sync`]), and differs only by
    /// the Station_Not_Ready diagnosis in the not-ready window ([`Mode::Lag`]).
    #[test]
    fn split_answers_equal_the_core(data in proptest::collection::vec(any::<u8>(), 0..600), lag in any::<bool>()) {
        let mode = if lag { Mode::Lag } else { Mode::Sync };
        let r = check::run(&data, mode, 400);
        prop_assert!(r.is_ok(), "{:02x?}", r);
    }
}

/// A verdict as owned bytes (`None`: silent; the core's answer after a core run).
fn owned(v: Verdict<'_>) -> (u8, std::vec::Vec<u8>) {
    match v {
        Verdict::Silent => (0, std::vec::Vec::new()),
        Verdict::Answer(a) => (1, a.to_vec()),
        Verdict::Core => (2, std::vec::Vec::new()),
    }
}

/// One of the telegrams of the chunking property (`op` chooses, `x` varies it).
fn chunk_telegram(m: &mut ScriptedMaster, op: u8, x: u8, tail: &[u8]) -> std::vec::Vec<u8> {
    let module = &card::MODULES[usize::from(x) % card::MODULES.len()];
    let out = std::vec![x; module.outputs as usize];
    let mut f: std::vec::Vec<u8> = match op % 16 {
        0 | 1 => m.srd(Some(61), &SetPrm::CARD.dpv1_status_1(x & 0x80).pdu()).to_vec(),
        2 => m.srd(Some(62), module.cfg).to_vec(),
        3..=5 => m.srd(None, &out).to_vec(),
        6 => m.srd(Some(60), &[]).to_vec(),
        7 => m.srd(Some(59), &[]).to_vec(),
        8 => m.srd(Some(if x & 1 == 0 { 56 } else { 57 }), &[]).to_vec(),
        9 => m.request(2, Some(51), Some(51), &[0x5E, 0, 255, 64], true).to_vec(),
        10 => m.request(2, Some(51), Some(51), &[], true).to_vec(),
        11 => crate::testkit::frame(
            &Header { da: 8, sa: 2, fc: FunctionCode::request(9, false, false), dsap: None, ssap: None },
            &[],
        )
        .to_vec(),
        // Another station's Data_Exchange, a token, SC.
        12 => ScriptedMaster::new(2, 9 + x % 3).srd(None, &out).to_vec(),
        13 => [&[0xDCu8, 8, 2][..], &[0xE5]][usize::from(x & 1)].to_vec(),
        // A retry of the last Data_Exchange (FCB not toggled).
        14 => m.request(2, None, None, &out, false).to_vec(),
        _ => m.srd(None, &out[..usize::from(x) % (out.len() + 1)]).to_vec(),
    };
    // Mangled: a byte changed, cut short, bytes appended, raw bytes.
    match x >> 5 {
        1 if !f.is_empty() => {
            let i = usize::from(tail.first().copied().unwrap_or(0)) % f.len();
            f[i] ^= tail.get(1).copied().unwrap_or(1) | 1;
        }
        2 => f.truncate(usize::from(tail.first().copied().unwrap_or(0)) % (f.len() + 1)),
        3 => f.extend_from_slice(&tail[..tail.len().min(3)]),
        4 if x & 3 == 0 => f = tail.to_vec(),
        _ => {}
    }
    f
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 500, ..ProptestConfig::default() })]
    /// Any chunking of any telegram sequence — random piece sizes down to single bytes, the
    /// whole telegram at once — through the [`TelegramSink`] and [`FastPath::finish`]
    /// gives exactly [`FastPath::on_frame`]'s verdicts, counters and queued telegrams: two
    /// splits side by side, the cores run (or left behind) at the same points, every core
    /// step and answer compared.
    #[test]
    fn any_chunking_equals_on_frame(
        ops in proptest::collection::vec((any::<u8>(), any::<u8>(), proptest::collection::vec(any::<u8>(), 0..6), any::<bool>()), 1..60),
        cuts in proptest::collection::vec(0u8..=255, 1..12),
    ) {
        let mut na = crate::card::node(DpSlave::new(&card::SLAVE, 8));
        let mut nb = crate::card::node(DpSlave::new(&card::SLAVE, 8));
        let mut sa = Shared::new();
        let mut sb = Shared::new();
        let (mut fa, mut ca) = sa.split(&mut na);
        let (mut fb, mut cb) = sb.split(&mut nb);
        let mut ma = ScriptedMaster::new(2, 8);
        let mut mb = ScriptedMaster::new(2, 8);
        let mut k = 0usize;
        let mut t = 0u64;
        for (op, x, tail, run) in ops {
            t += 200;
            let now = Instant::from_micros(t);
            let f = chunk_telegram(&mut ma, op, x, &tail);
            prop_assert_eq!(&f, &chunk_telegram(&mut mb, op, x, &tail));
            let va = owned(fa.on_frame(now, &f));
            fb.begin();
            let mut rest = &f[..];
            while !rest.is_empty() {
                let n = match cuts[k % cuts.len()] {
                    c @ 0..=200 => usize::from(c % 20) + 1,
                    c => usize::from(c),
                };
                k += 1;
                let (piece, r) = rest.split_at(n.min(rest.len()));
                fb.bytes(piece);
                rest = r;
            }
            let vb = owned(fb.finish(now));
            prop_assert_eq!(&va, &vb, "{:02x?}", f);
            prop_assert_eq!(fa.stats(), fb.stats());
            if va.0 == 2 || run || fa.queue_free() < 2 {
                loop {
                    let (a, b) = (ca.step(&mut na), cb.step(&mut nb));
                    prop_assert_eq!(a, b);
                    let Some(a) = a else { break };
                    let n = a.answer_len.unwrap_or(0);
                    prop_assert_eq!(ca.answer(n), cb.answer(n));
                }
                prop_assert_eq!(fa.take_deferred().map(|d| d.to_vec()), fb.take_deferred().map(|d| d.to_vec()));
            }
        }
        prop_assert_eq!(na.slave().outputs(), nb.slave().outputs());
        prop_assert_eq!(na.slave().state(), nb.slave().state());
    }

    /// The check against the core alone with the split's line fed in pieces.
    #[test]
    fn split_in_pieces_answers_equal_the_core(
        data in proptest::collection::vec(any::<u8>(), 0..600),
        lag in any::<bool>(),
        cuts in proptest::collection::vec(any::<u8>(), 1..8),
    ) {
        let mode = if lag { Mode::Lag } else { Mode::Sync };
        let r = check::run_in_pieces(&data, mode, 400, &cuts);
        prop_assert!(r.is_ok(), "{:02x?}", r);
    }
}

/// A telegram that is begun but aborted leaves nothing: the next one is decided alone,
/// and bytes without a `begin` are ignored.
#[test]
fn abort_forgets_the_telegram() {
    let mut node = crate::card::node(DpSlave::new(&card::SLAVE, 8));
    let mut shared = Shared::new();
    let (mut fast, core) = shared.split(&mut node);
    let mut m = ScriptedMaster::new(2, 8);
    let f = m.srd(Some(61), &SetPrm::CARD.pdu());
    fast.begin();
    fast.bytes(&f[..7]);
    fast.abort();
    fast.bytes(&f[7..]);
    assert_eq!(fast.finish(Instant::from_micros(1)), Verdict::Silent);
    assert_eq!(fast.stats().others, 1);
    assert!(!core.pending());
    let f = m.srd(Some(61), &SetPrm::CARD.pdu());
    fast.begin();
    fast.bytes(&f[..3]);
    fast.begin();
    fast.bytes(&f);
    assert_eq!(fast.finish(Instant::from_micros(2)), Verdict::Answer(&[telegram::SC]));
    assert!(core.pending());
}

/// The generator reaches data exchange, the window, the core's DP-V1 answers and retries.
#[test]
fn the_generator_gets_somewhere() {
    let mut x = 0x2545_f491_4f6c_dd1du64;
    let mut rng = move || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        x as u8
    };
    let mut sum = check::Coverage::default();
    for i in 0..400 {
        let data: std::vec::Vec<u8> = (0..600).map(|_| rng()).collect();
        let mode = if i % 2 == 0 { Mode::Sync } else { Mode::Lag };
        let c = match check::run(&data, mode, 400) {
            Ok(c) => c,
            Err(e) => {
                check::TRACE.with(|t| t.set(true));
                let _ = check::run(&data, mode, 400);
                panic!("{e:02x?}");
            }
        };
        sum.data_exchanges += c.data_exchanges;
        sum.not_ready_diags += c.not_ready_diags;
        sum.deferred += c.deferred;
        sum.retries += c.retries;
        sum.dpv1_line += c.dpv1_line;
        sum.dpv1_responses += c.dpv1_responses;
        sum.held_repolls += c.held_repolls;
    }
    std::eprintln!("coverage {sum:?}");
    assert!(sum.data_exchanges > 0 && sum.not_ready_diags > 0 && sum.retries > 0, "{sum:?}");
    assert!(sum.dpv1_line > 0 && sum.dpv1_responses > 0 && sum.held_repolls > 0, "{sum:?}");
}

/// The previous build's fuzz crash (Station_Status_1 = 0x10 from the split, 0x00 from the
/// core): the input through this harness in both modes.
#[test]
fn regression_previous_crash_input() {
    let data = hex("003f34653434dcc9c9c90403feffffffd3000302004397000207ffffffff07fffb00ede6");
    for mode in [Mode::Sync, Mode::Lag] {
        assert_eq!(check::run(&data, mode, 400).map(|_| ()), Ok(()));
    }
}

/// FC and PDU of an answer.
fn parts(f: &[u8]) -> (u8, std::vec::Vec<u8>) {
    match telegram::decode(f) {
        Decoded::Frame(Telegram::Data(t), _) => (t.fc.0, t.pdu.to_vec()),
        other => panic!("{other:?}"),
    }
}

struct Pair {
    alone: Node,
    split: Node,
}

fn answer(
    fast: &mut FastPath<'_>,
    core: &mut CoreLink<'_>,
    node: &mut Node,
    now: Instant,
    f: &[u8],
) -> Option<std::vec::Vec<u8>> {
    let r = match fast.on_frame(now, f) {
        Verdict::Silent => None,
        Verdict::Answer(a) => Some(a.to_vec()),
        Verdict::Core => {
            core.run(node);
            fast.take_deferred().filter(|a| !a.is_empty()).map(|a| a.to_vec())
        }
    };
    core.run(node);
    r
}

/// One-shot diagnosis bits read through the line: Global_Control Sync on a slave that was
/// not parameterised for Sync sets Not_Supported and new diagnosis (DH); the locking
/// master's Slave_Diag (answered by the line) consumes DH in the core too; the next
/// Data_Exchange answers DL, the next diagnosis equals the core alone's.
#[test]
fn one_shot_diagnosis_through_the_line() {
    let mut p = Pair {
        alone: crate::card::node(DpSlave::new(&crate::card::SLAVE, 8)),
        split: crate::card::node(DpSlave::new(&crate::card::SLAVE, 8)),
    };
    let mut shared = Shared::new();
    let (mut fast, mut core) = shared.split(&mut p.split);
    let mut m = ScriptedMaster::new(2, 8);
    let mut t = 0u64;
    let mut both = |f: &[u8], p: &mut Pair, fast: &mut FastPath<'_>, core: &mut CoreLink<'_>| {
        t += 100;
        let now = Instant::from_micros(t);
        let a = p.alone.on_frame(now, f).map(|a| a.to_vec());
        let s = answer(fast, core, &mut p.split, now, f);
        assert_eq!(a, s, "request {f:02x?}");
        s
    };
    let prm = SetPrm::CARD.pdu();
    both(&m.srd(Some(61), &prm), &mut p, &mut fast, &mut core);
    both(&m.srd(Some(62), card::MODULES[0].cfg), &mut p, &mut fast, &mut core);
    let gc = crate::testkit::frame(
        &Header { da: 8, sa: 2, fc: FunctionCode::request(6, false, false), dsap: Some(58), ssap: Some(62) },
        &[0x20, 0],
    );
    both(&gc, &mut p, &mut fast, &mut core);
    let dx = both(&m.srd(None, &[1, 2, 3, 4]), &mut p, &mut fast, &mut core).unwrap();
    assert_eq!(parts(&dx).0, ResponseStatus::Dh as u8, "DH after Not_Supported");
    let diag = both(&m.srd(Some(60), &[]), &mut p, &mut fast, &mut core).unwrap();
    assert_ne!(parts(&diag).1[0] & Status1::NOT_SUPPORTED.bits(), 0);
    let dx = both(&m.srd(None, &[1, 2, 3, 4]), &mut p, &mut fast, &mut core).unwrap();
    assert_eq!(parts(&dx).0, ResponseStatus::Dl as u8, "DH consumed by the diagnosis read");
    both(&m.srd(Some(60), &[]), &mut p, &mut fast, &mut core);
}

/// The not-ready window: after Set_Prm / Chk_Cfg, before the core judged them, the line
/// answers Slave_Diag with Station_Not_Ready set, Data_Exchange with RS; after the core
/// ran, the ready diagnosis.
#[test]
fn not_ready_window() {
    let mut node = crate::card::node(DpSlave::new(&crate::card::SLAVE, 8));
    let mut shared = Shared::new();
    let (mut fast, mut core) = shared.split(&mut node);
    let mut m = ScriptedMaster::new(2, 8);
    let now = Instant::from_micros(100);
    assert_eq!(fast.on_frame(now, &m.srd(Some(61), &SetPrm::CARD.pdu())), Verdict::Answer(&[telegram::SC]));
    assert_eq!(fast.on_frame(now, &m.srd(Some(62), card::MODULES[0].cfg)), Verdict::Answer(&[telegram::SC]));
    assert!(fast.in_window());
    let Verdict::Answer(d) = fast.on_frame(now, &m.srd(Some(60), &[])) else { panic!() };
    assert_ne!(parts(d).1[0] & Status1::STATION_NOT_READY.bits(), 0);
    let Verdict::Answer(rs) = fast.on_frame(now, &m.srd(None, &[0; 4])) else { panic!() };
    assert_eq!(parts(rs).0, ResponseStatus::Rs as u8);
    core.run(&mut node);
    assert!(!fast.in_window());
    assert_eq!(node.slave().state(), DpState::DataExch);
    let Verdict::Answer(d) = fast.on_frame(now, &m.srd(Some(60), &[])) else { panic!() };
    assert_eq!(parts(d).1[0] & Status1::STATION_NOT_READY.bits(), 0);
    let Verdict::Answer(dx) = fast.on_frame(now, &m.srd(None, &[9, 8, 7, 6])) else { panic!() };
    assert_eq!(parts(dx).0, ResponseStatus::Dl as u8);
    core.run(&mut node);
    assert_eq!(node.slave().outputs(), &[9, 8, 7, 6]);
}

/// min_TSDR travels in the staging: the node's value after the core judged a Set_Prm.
#[test]
fn min_tsdr_is_staged() {
    let mut node = crate::card::node(DpSlave::new(&card::SLAVE, 8));
    let mut shared = Shared::new();
    let (mut fast, mut core) = shared.split(&mut node);
    assert_eq!(fast.min_tsdr(), node.min_tsdr());
    let mut m = ScriptedMaster::new(2, 8);
    let now = Instant::from_micros(100);
    let prm = SetPrm::CARD.min_tsdr(200);
    assert_eq!(fast.on_frame(now, &m.srd(Some(61), &prm.pdu())), Verdict::Answer(&[telegram::SC]));
    core.run(&mut node);
    assert_eq!(node.min_tsdr(), crate::time::BitTimes(200));
    assert_eq!(fast.min_tsdr(), crate::time::BitTimes(200));
}

/// Sequence numbers wrap: 2^31 telegrams after the last Chk_Cfg the not-ready window
/// does not reopen (it did, answering Data_Exchange RS once per 2^31 telegrams).
#[test]
fn the_not_ready_window_survives_the_sequence_wrap() {
    let mut node = crate::card::node(DpSlave::new(&card::SLAVE, 8));
    let mut shared = Shared::new();
    let (mut fast, mut core) = shared.split(&mut node);
    let mut m = ScriptedMaster::new(2, 8);
    let now = Instant::from_micros(100);
    assert_eq!(fast.on_frame(now, &m.srd(Some(61), &SetPrm::CARD.pdu())), Verdict::Answer(&[telegram::SC]));
    assert_eq!(fast.on_frame(now, &m.srd(Some(62), card::MODULES[0].cfg)), Verdict::Answer(&[telegram::SC]));
    core.run(&mut node);
    let Verdict::Answer(dx) = fast.on_frame(now, &m.srd(None, &[1, 2, 3, 4])) else { panic!() };
    assert_eq!(parts(dx).0, ResponseStatus::Dl as u8);
    core.run(&mut node);
    // As if 2^31 - 8 telegrams had passed since the Chk_Cfg.
    fast.test_advance_seq(0x7FFF_FFF8);
    for k in 0..32u8 {
        let Verdict::Answer(dx) = fast.on_frame(now, &m.srd(None, &[k, 2, 3, 4])) else { panic!() };
        assert_eq!(parts(dx).0, ResponseStatus::Dl as u8, "Data_Exchange {k} after the wrap");
        assert!(!fast.in_window(), "{k}");
        core.run(&mut node);
        assert_eq!(node.slave().outputs(), &[k, 2, 3, 4]);
    }
}

/// DP-V1 from the staging: the line answers SC to a request and to a poll whose response
/// the core finished but has not published yet; the core keeps that response (the poll was
/// held) and the next poll gets it from the line, once; the RM answers before the core ran.
#[test]
fn dpv1_held_poll_keeps_the_response() {
    use crate::dpv1::c2;
    let mut node = crate::card::node(DpSlave::new(&crate::card::SLAVE, 8));
    let mut shared = Shared::new();
    let (mut fast, mut core) = shared.split(&mut node);
    let mut m = ScriptedMaster::new(2, 8);
    let now = Instant::from_micros(100);
    let prm = SetPrm::CARD.dpv1_status_1(0x80).pdu();
    assert_eq!(fast.on_frame(now, &m.srd(Some(61), &prm)), Verdict::Answer(&[telegram::SC]));
    assert_eq!(fast.on_frame(now, &m.srd(Some(62), card::MODULES[0].cfg)), Verdict::Answer(&[telegram::SC]));
    core.run(&mut node);
    let c1 = |m: &mut ScriptedMaster, pdu: &[u8]| m.request(2, Some(51), Some(51), pdu, true);
    // I&M0 read.
    assert_eq!(fast.on_frame(now, &c1(&mut m, &[0x5E, 0, 255, 64])), Verdict::Answer(&[telegram::SC]));
    core.run(&mut node);
    let mut params = crate::testkit::FakeDrive::new();
    node.process_acyclic(now, &mut crate::profile::records::CardRecords::new(&crate::card::RECORDS).with(&mut params));
    assert!(node.c1().ready_frame().is_some());
    // Not published yet: the line says "not ready", the core holds the response.
    assert_eq!(fast.on_frame(now, &c1(&mut m, &[])), Verdict::Answer(&[telegram::SC]));
    core.run(&mut node);
    let want = node.c1().ready_frame().expect("held, not spent").to_vec();
    core.publish(&mut node);
    let Verdict::Answer(a) = fast.on_frame(now, &c1(&mut m, &[])) else { panic!() };
    assert_eq!(a, &want[..]);
    core.run(&mut node);
    assert!(node.c1().ready_frame().is_none());
    assert_eq!(fast.on_frame(now, &c1(&mut m, &[])), Verdict::Answer(&[telegram::SC]));
    core.run(&mut node);
    // MSAC_C2: the RM names SAP 48 with the core not run.
    let mut init = [0u8; 64];
    let n = initiate_pdu(&mut init);
    let mut c2f = |sap: u8, pdu: &[u8]| m.request(3, Some(sap), Some(40), pdu, true);
    let Verdict::Answer(rm) = fast.on_frame(now, &c2f(c2::RM_SAP, &init[..n])) else { panic!() };
    assert_eq!(parts(rm).1, [0x56, 48, 0, c2::DEFAULT_MIN_SEND_TIMEOUT as u8]);
    assert_eq!(fast.on_frame(now, &c2f(48, &init[..n])), Verdict::Answer(&[telegram::SC]));
    // In flight: "not ready" although the core alone would have the Initiate.res.
    assert_eq!(fast.on_frame(now, &c2f(48, &[])), Verdict::Answer(&[telegram::SC]));
    core.run(&mut node);
    let Verdict::Answer(res) = fast.on_frame(now, &c2f(48, &[])) else { panic!() };
    assert_eq!(parts(res).1[0], 0x57, "Initiate.res");
    core.run(&mut node);
    assert_eq!(fast.stats().deferred, 0);
}

/// An MSAC_C2 Initiate.req PDU into `buf` (Send_Timeout 3 s, Read/Write supported, 2-byte
/// address blocks of type 0): its length.
fn initiate_pdu(buf: &mut [u8]) -> usize {
    let req = crate::dpv1::pdu::InitiateRequest {
        send_timeout: 300,
        features_supported: [1, 0],
        profile_features_supported: [0, 0],
        profile_ident_number: 0,
        source: crate::dpv1::pdu::AddressBlock { kind: 0, bytes: &[0, 0] },
        destination: crate::dpv1::pdu::AddressBlock { kind: 0, bytes: &[0, 0] },
    };
    req.emit(buf).unwrap()
}

/// The DP-V1 decision prepared while the header arrives (`prepare_dpv1`) is the last
/// character's only while it still holds: a reservation that expires between the header
/// and the last character frees its connection (the RM names it, not the one prepared),
/// a bad FCS leaves nothing behind, a staging published while the telegram arrives does
/// not change the decision, and a connection SAP's Abort PDU is decided by its full
/// parse. Every answer as the core alone's at the same time.
#[test]
fn dpv1_prepared_decision_is_rechecked_at_finish() {
    use crate::dpv1::c2;
    let mut node = crate::card::node(DpSlave::new(&crate::card::SLAVE, 8));
    let mut alone = crate::card::node(DpSlave::new(&crate::card::SLAVE, 8));
    let mut shared = Shared::new();
    let (mut fast, mut core) = shared.split(&mut node);
    let mut m = ScriptedMaster::new(2, 8);
    let t0 = Instant::from_micros(100);
    let prm = SetPrm::CARD.dpv1_status_1(0x80).pdu();
    for f in [m.srd(Some(61), &prm), m.srd(Some(62), card::MODULES[0].cfg)] {
        assert_eq!(fast.on_frame(t0, &f), Verdict::Answer(&[telegram::SC]));
        let _ = alone.on_frame(t0, &f);
    }
    core.run(&mut node);
    let mut init = [0u8; 64];
    let n = initiate_pdu(&mut init);
    let init = &init[..n];
    let alone_says = |alone: &mut Node, at: Instant, f: &[u8]| match alone.on_frame(at, f) {
        Some(a) => (1, a.to_vec()),
        None => (0, std::vec::Vec::new()),
    };
    // The line in two pieces: all but the last character (the header and the first PDU
    // octet in: prepared), then the last one and the decision at `at`.
    let split_says = |fast: &mut FastPath<'_>, at: Instant, f: &[u8]| {
        fast.begin();
        fast.bytes(&f[..f.len() - 1]);
        assert!(fast.test_dpv1_prepared(), "prepared: {f:02x?}");
        fast.bytes(&f[f.len() - 1..]);
        owned(fast.finish(at))
    };
    // Master 3 reserves SAP 48 (for 1 s, the minimum Send_Timeout).
    let f = m.request(3, Some(c2::RM_SAP), Some(40), init, true);
    let a = split_says(&mut fast, t0, &f);
    assert_eq!(a, alone_says(&mut alone, t0, &f));
    assert_eq!(parts(&a.1).1[1], 48);
    core.run(&mut node);
    // 2 s later master 4 asks: the reservation has expired by the last character, so
    // the RM names 48 again — the header's view (48 reserved) would have named 47.
    let t1 = Instant::from_micros(2_000_000);
    let f = m.request(4, Some(c2::RM_SAP), Some(41), init, true);
    let a = split_says(&mut fast, t1, &f);
    assert_eq!(a, alone_says(&mut alone, t1, &f));
    assert_eq!(parts(&a.1).1[1], 48);
    core.run(&mut node);
    // A bad FCS: nothing, and nothing prepared is left for the next telegram.
    let mut bad = m.request(5, Some(c2::RM_SAP), Some(42), init, true).to_vec();
    let k = bad.len() - 2;
    bad[k] ^= 1;
    assert_eq!(split_says(&mut fast, t1, &bad), (0, std::vec::Vec::new()));
    assert_eq!(alone_says(&mut alone, t1, &bad), (0, std::vec::Vec::new()));
    assert!(!fast.test_dpv1_prepared());
    let f = m.request(5, Some(c2::RM_SAP), Some(42), init, true);
    let a = split_says(&mut fast, t1, &f);
    assert_eq!(a, alone_says(&mut alone, t1, &f));
    assert_eq!(parts(&a.1).1[1], 47);
    core.run(&mut node);
    // A staging published while a telegram arrives: the line keeps the one of its begin
    // (both connections reserved: RR), the core alone agrees at that time.
    let f = m.request(6, Some(c2::RM_SAP), Some(43), init, true);
    fast.begin();
    fast.bytes(&f[..f.len() - 1]);
    assert!(fast.test_dpv1_prepared());
    core.poll(t1, &mut node);
    fast.bytes(&f[f.len() - 1..]);
    let a = owned(fast.finish(t1));
    assert_eq!(a, alone_says(&mut alone, t1, &f));
    assert_eq!(parts(&a.1).0, ResponseStatus::Rr as u8);
    core.run(&mut node);
    // Master 5 opens 47 (SC), then aborts it: the Abort PDU is not prepared (its full
    // parse decides), answered SC; a poll afterwards on 47 is RS.
    let f = m.request(5, Some(47), Some(42), init, true);
    assert_eq!(split_says(&mut fast, t1, &f), alone_says(&mut alone, t1, &f));
    core.run(&mut node);
    let abort = [0x58, 0, 0, 0];
    let f = m.request(5, Some(47), Some(42), &abort, true);
    fast.begin();
    fast.bytes(&f[..f.len() - 1]);
    assert!(!fast.test_dpv1_prepared(), "an Abort PDU is not prepared");
    fast.bytes(&f[f.len() - 1..]);
    assert_eq!(owned(fast.finish(t1)), (1, std::vec![telegram::SC]));
    let _ = alone_says(&mut alone, t1, &f);
    core.run(&mut node);
    let f = m.request(5, Some(47), Some(42), &[], true);
    let a = split_says(&mut fast, t1, &f);
    assert_eq!(a, alone_says(&mut alone, t1, &f));
    assert_eq!(parts(&a.1).0, ResponseStatus::Rs as u8);
    core.run(&mut node);
}

/// The benchmark's sequence: after every core run the line sees the core idle.
#[test]
fn core_idle_after_every_run() {
    let mut node = crate::card::node(DpSlave::new(&crate::card::SLAVE, 126));
    let mut shared = Shared::new();
    let (mut fast, mut core) = shared.split(&mut node);
    let mut m = ScriptedMaster::new(2, 126);
    let now = Instant::from_micros(100);
    let prm = SetPrm::CARD.no_watchdog().pdu();
    for module in [&card::MODULES[0], card::MODULES.iter().find(|m| m.reference == 101).unwrap()] {
        for f in [m.srd(Some(61), &prm), m.srd(Some(62), module.cfg), m.srd(Some(60), &[])] {
            assert!(!matches!(fast.on_frame(now, &f), Verdict::Silent), "{f:02x?}");
            core.run(&mut node);
            assert!(fast.core_idle());
        }
        for _ in 0..3 {
            let out = std::vec![0u8; module.outputs as usize];
            let Verdict::Answer(a) = fast.on_frame(now, &m.srd(None, &out)) else { panic!() };
            assert_eq!(parts(a).1.len(), module.inputs as usize);
            core.run(&mut node);
            assert!(fast.core_idle());
        }
    }
}

/// Other stations' traffic is dropped before any copy: nothing queued.
#[test]
fn foreign_traffic_is_not_queued() {
    let mut node = crate::card::node(DpSlave::new(&crate::card::SLAVE, 8));
    let mut shared = Shared::new();
    let (mut fast, core) = shared.split(&mut node);
    let mut other = ScriptedMaster::new(2, 9);
    for _ in 0..20 {
        assert_eq!(fast.on_frame(Instant::from_micros(1), &other.srd(None, &[1; 32])), Verdict::Silent);
    }
    assert_eq!(fast.on_frame(Instant::from_micros(1), &[0xDC, 8, 2]), Verdict::Silent);
    assert!(!core.pending());
    assert_eq!(fast.stats().others, 21);
    assert_eq!(fast.stats().queued, 0);
}

/// Fuzz finds, replayed.
mod regressions {
    use crate::fast::check::{self, Mode};
    /// A fuzz find (`fast_path`, Lag schedule): MSAC_C1 DS_Read, then a Chk_Cfg the core
    /// has not judged when the split's DP-V1 task runs; the poll's answer must equal the card
    /// alone's (`check::run`: the task does not overtake an unjudged Set_Prm / Chk_Cfg).
    #[test]
    fn dpv1_task_after_an_unjudged_chk_cfg() {
        let d: &[u8] = &[
            18, 0, 72, 18, 0, 72, 0, 72, 249, 72, 72, 72, 72, 72, 72, 72, 72, 93, 72, 125, 72, 249, 72, 72, 72, 72, 72,
            8, 72, 72, 249, 72, 72, 72, 91, 72, 72, 93, 72, 72, 249, 72, 72, 72, 72, 72, 8, 72, 72, 249, 72, 72, 72,
            72, 72, 249, 72, 72, 72, 72, 72, 72, 72, 78, 78, 78, 78, 48, 2, 199, 0, 0, 1, 2, 72, 93, 72, 72, 249, 72,
            72, 72, 72, 72, 5, 0, 0, 0, 224, 224, 126, 224, 224, 224, 8, 72, 72, 249, 72, 72, 72, 91, 72, 72, 72, 72,
            90, 72, 200, 0, 15,
        ];
        let r = check::run(d, Mode::Lag, 2000);
        assert!(r.is_ok(), "{r:02x?}");
    }
}
