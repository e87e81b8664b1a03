//! Bad bytes from the drive's side of the DPM: a whole `pbcard_sim::bench::Application` (card-side
//! `Link`, profile runtime, parameter caches, and the simulated drive on the host reference
//! implementation `dpm::host`) with a `Node` brought to data exchange by the scripted master
//! of `pbcard::testkit`, and arbitrary bytes written into the image between the drive's turn
//! and the card's collect (so the card reads exactly what the fuzzer wrote).
//!
//! Input: a control byte choosing the module, then operations, each a control byte `c`:
//! * `c % 8 == 0`: raw bytes into a host-written block (INPUTS, DRIVE, CONFIG, MBX_RSP,
//!   DRIVE_STATE): offset and length from the input, the counters left as they fall (torn
//!   blocks included).
//! * `c % 8 == 1`: a whole host-written block of input bytes with `SEQ_HEAD` = `SEQ_TAIL` (a
//!   complete write of arbitrary content: the decoders see it).
//! * `c % 8 == 2`: a valid-looking CONFIG with a new sequence counter and fuzzed fields.
//! * `c % 8 == 3`: raw bytes into a card-written block (what the host reference
//!   implementation then reads); from here on the card-written blocks are not checked.
//! * `c % 8 == 4`: a Data_Exchange with input bytes as outputs.
//! * `c % 8 == 5`: time passes (up to 1 s; heartbeat supervision, DP watchdog).
//! * otherwise: one plain `Application::step`.
//!
//! Every scribble is followed by the card's `step_collect`, then by a whole step.
//!
//! Checks: no panic; the card-written blocks stay well-formed (HEADER is this layout, IDENT
//! the card's, STATUS, OUTPUTS, CARD, MBX_REQ and DRIVE_CMD decode with equal counters) until
//! the fuzzer writes into one of them; a torn DRIVE or CONFIG read is counted; a CONFIG that
//! fails `is_valid` gets `CONFIG_RESULT` = refused with its counter acknowledged; the link's
//! counters never go back; every Data_Exchange answer is one valid telegram with the
//! configured input length; the DP images keep their sizes and data exchange implies a
//! master and a module.
#![no_main]

#[path = "common/src.rs"]
#[macro_use]
mod src;

use libfuzzer_sys::fuzz_target;
use pbcard::card;
use pbcard::dp::DpState;
use pbcard::dpm::layout::{Writer, BLOCKS};
use pbcard::dpm::{codec, ConfigResult, Dpm, HostConfig, LinkStats};
use pbcard::fdl::telegram::{self, Decoded, Telegram};
use pbcard::node::Node;
use pbcard::time::{Baudrate, Duration};
use pbcard_sim::bench::Application;
use pbcard_sim::drive::DriveConfig;
use pbcard_sim::testkit::{CardRig, Rig, SetPrm};
use src::Src;

const ME: u8 = 5;
const MASTER: u8 = 2;

/// The card publishes, the drive runs, `scribble` writes into the image, the card collects:
/// the card reads the scribbled bytes.
fn step_with(c: &mut CardRig<Application>, scribble: impl FnOnce(&mut Dpm)) {
    c.now = c.now + Duration::from_millis(1);
    c.app.step_publish(c.now, &mut c.node);
    c.app.step_drive(c.now);
    scribble(c.app.dpm_mut());
    c.app.step_collect(c.now, &mut c.node);
}

fn host_blocks() -> impl Iterator<Item = &'static pbcard::dpm::layout::Block> {
    BLOCKS.iter().filter(|b| b.writer == Writer::Host)
}

fn card_blocks() -> impl Iterator<Item = &'static pbcard::dpm::layout::Block> {
    BLOCKS.iter().filter(|b| b.writer == Writer::Card)
}

/// The card-written blocks are well-formed.
fn check_card_blocks(dpm: &Dpm) {
    let b = dpm.as_bytes();
    let at = |start: usize, len: usize| &b[start..start + len];
    let (_, h) = codec::HEADER.decode(at(codec::HEADER.start(), codec::HEADER.len())).unwrap();
    assert_eq!(h, codec::Header::THIS_LAYOUT);
    let (_, id) = codec::IDENT.decode(at(codec::IDENT.start(), codec::IDENT.len())).unwrap();
    assert_eq!(id.ident_number, card::IDENT_NUMBER);
    codec::STATUS.decode(at(codec::STATUS.start(), codec::STATUS.len())).expect("STATUS");
    let (_, out) = codec::OUTPUTS.decode(at(codec::OUTPUTS.start(), codec::OUTPUTS.len())).expect("OUTPUTS");
    assert!(out.bytes().len() <= pbcard::dpm::layout::PD_CAPACITY);
    codec::CARD.decode(at(codec::CARD.start(), codec::CARD.len())).expect("CARD");
    codec::MBX_REQ.decode(at(codec::MBX_REQ.start(), codec::MBX_REQ.len())).expect("MBX_REQ");
    codec::DRIVE_CMD.decode(at(codec::DRIVE_CMD.start(), codec::DRIVE_CMD.len())).expect("DRIVE_CMD");
}

fn check_node(node: &Node) {
    let s = node.slave();
    assert_eq!(s.outputs().len(), s.output_len());
    assert_eq!(s.inputs().len(), s.input_len());
    if s.state() == DpState::DataExch {
        assert!(s.master_address().is_some() && s.module().is_some(), "Data_Exch without master/module");
    }
}

fn check_counters(a: LinkStats, b: LinkStats) {
    let pairs = [
        (a.torn_reads, b.torn_reads),
        (a.stale_telegram, b.stale_telegram),
        (a.inputs_taken, b.inputs_taken),
        (a.outputs_written, b.outputs_written),
        (a.status_written, b.status_written),
        (a.torn_host_blocks, b.torn_host_blocks),
        (a.bad_ext_diag, b.bad_ext_diag),
        (a.configs_taken, b.configs_taken),
        (a.commands_written, b.commands_written),
    ];
    for (i, (x, y)) in pairs.into_iter().enumerate() {
        assert!(y >= x, "link counter {i} went back: {a:?} -> {b:?}");
    }
}

fuzz_target!(|data: &[u8]| {
    let mut src = Src::new(data);
    let mut app = Application::new(DriveConfig::DEFAULT);
    app.set_baudrate(Some(Baudrate::B1500k));
    let mut c = CardRig::new(app, MASTER, ME);
    let module = &card::MODULES[usize::from(src.u8()) % card::MODULES.len()];
    c.bring_up(&SetPrm::CARD, module.cfg);
    let mut card_trusted = true;
    // Every CONFIG counter the image has shown: a new configuration needs another one.
    let mut config_seqs = std::collections::HashSet::new();
    let mut config_seq = 0u16;
    let mut steps = 0;
    while !src.is_empty() && steps < 200 {
        steps += 1;
        let op = src.u8();
        let before = c.app.link().stats();
        let kind = op % 8;
        match kind {
            0 | 3 => {
                let blocks: Vec<_> = if kind == 0 { host_blocks().collect() } else { card_blocks().collect() };
                let blk = blocks[usize::from(src.u8()) % blocks.len()];
                let off = usize::from(src.u8()) % blk.len;
                let n = usize::from(src.u8()) % (blk.len - off + 1);
                let bytes = src.bytes(n);
                trace!("scribble {} +{off}: {bytes:02x?}", blk.name);
                if kind == 3 {
                    card_trusted = false;
                    // The drive reads the card's blocks in its turn.
                    c.app.dpm_mut().as_bytes_mut()[blk.start + off..blk.start + off + bytes.len()]
                        .copy_from_slice(bytes);
                    c.step(1);
                } else {
                    let mut torn = None;
                    step_with(&mut c, |dpm| {
                        let img = dpm.as_bytes_mut();
                        img[blk.start + off..blk.start + off + bytes.len()].copy_from_slice(bytes);
                        let s = &img[blk.start..blk.start + blk.len];
                        torn = blk.sequenced.then(|| s[..2] != s[blk.len - 2..]).filter(|&t| t);
                    });
                    if torn.is_some() && (blk.name == "DRIVE" || blk.name == "CONFIG") {
                        assert!(
                            c.app.link().stats().torn_host_blocks > before.torn_host_blocks,
                            "torn {} not counted",
                            blk.name
                        );
                    }
                }
            }
            1 => {
                let blocks: Vec<_> = host_blocks().collect();
                let blk = blocks[usize::from(src.u8()) % blocks.len()];
                let mut content = src.bytes(blk.len).to_vec();
                content.resize(blk.len, 0);
                let seq = src.u16();
                content[..2].copy_from_slice(&seq.to_be_bytes());
                content[blk.len - 2..].copy_from_slice(&seq.to_be_bytes());
                trace!("block {} = {content:02x?}", blk.name);
                step_with(&mut c, |dpm| dpm.as_bytes_mut()[blk.start..blk.start + blk.len].copy_from_slice(&content));
            }
            2 => {
                while config_seq == 0 || config_seqs.contains(&config_seq) {
                    config_seq = config_seq.wrapping_add(1);
                }
                let cfg = HostConfig {
                    station_address: src.u8(),
                    profile: src.u8() % 3,
                    comm_loss_reaction: src.u8() % 6,
                    operate_mode: src.u8() % 5,
                    io_update_delay: u16::from(src.u8() & 0x0F),
                    ..HostConfig::DEFAULT
                };
                let mut bytes = [0u8; codec::CONFIG.len()];
                codec::CONFIG.encode(&cfg, config_seq, &mut bytes).unwrap();
                // Re-read what the card will see (unknown field values decode as they are).
                let (_, seen) = codec::CONFIG.decode(&bytes).unwrap();
                trace!("config {seen:?} seq {config_seq}");
                let start = codec::CONFIG.start();
                step_with(&mut c, |dpm| dpm.as_bytes_mut()[start..start + bytes.len()].copy_from_slice(&bytes));
                if !seen.is_valid() {
                    let r = c.app.link().card_report();
                    assert_eq!((r.config_ack, r.config_result()), (config_seq, ConfigResult::Refused), "{seen:?}");
                }
            }
            4 => {
                let n = c.node.slave().output_len();
                let mut out = src.bytes(n).to_vec();
                out.resize(n, 0);
                let f = c.master.srd(None, &out);
                c.now = c.now + Duration::from_micros(500);
                if let Some(r) = c.deliver(&f) {
                    match telegram::decode(&r) {
                        Decoded::Frame(Telegram::Data(t), k) if k == r.len() => {
                            assert_eq!((t.da, t.sa), (MASTER, ME));
                            if c.node.slave().state() == DpState::DataExch && t.dsap.is_none() && !t.pdu.is_empty() {
                                assert_eq!(t.pdu.len(), c.node.slave().input_len());
                            }
                        }
                        Decoded::Frame(Telegram::ShortAck, 1) => {}
                        other => panic!("answer {r:02x?} = {other:?}"),
                    }
                }
                c.step(1);
            }
            5 => {
                c.step(u64::from(src.u8()) * 4);
            }
            _ => {
                c.step(1);
            }
        }
        let cs = codec::CONFIG.start();
        config_seqs.insert(u16::from_be_bytes([c.app.dpm().as_bytes()[cs], c.app.dpm().as_bytes()[cs + 1]]));
        check_counters(before, c.app.link().stats());
        check_node(&c.node);
        if card_trusted {
            check_card_blocks(c.app.dpm());
        }
    }
});
