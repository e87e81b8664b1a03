//! Layout version 2: the map and its document, every field read back, the exhaustive
//! interleaving proof of the sequenced blocks, configuration take-over, the parameter
//! mailbox and heartbeat supervision both ways.

use super::blocks::*;
use super::layout::{self, BLOCKS, FIELDS};
use super::*;
use crate::profile::param::{ErrorValue, Format, ParamError};

// ---------------------------------------------------------------------------------------
// The map and its document

#[test]
fn fields_cover_the_image_exactly_once() {
    let mut at = 0;
    for f in FIELDS {
        assert_eq!(f.offset, at, "{} must start where the previous field ends", f.name);
        assert!(f.size > 0, "{}", f.name);
        at += f.size;
        let block = BLOCKS.iter().find(|b| f.offset >= b.start && f.offset < b.start + b.len).unwrap();
        assert!(f.offset + f.size <= block.start + block.len, "{} crosses its block", f.name);
        assert!(
            f.name.starts_with(block.name) && f.name[block.name.len()..].starts_with('.'),
            "{} not in {}",
            f.name,
            block.name
        );
        assert_eq!(f.writer, block.writer, "{}", f.name);
        let expect = match f.ty {
            "u8" => 1,
            "u16" | "i16" => 2,
            "u32" => 4,
            "reserved" => f.size,
            t => {
                let n: usize = t[t.find('[').unwrap() + 1..t.len() - 1].parse().unwrap();
                n * if t.starts_with("u16") { 2 } else { 1 }
            }
        };
        assert_eq!(f.size, expect, "{}: size and type {}", f.name, f.ty);
    }
    assert_eq!(at, IMAGE_SIZE);
    let mut at = 0;
    for b in BLOCKS {
        assert_eq!(b.start, at, "{}", b.name);
        at += b.len;
        if b.sequenced {
            let head = FIELDS.iter().find(|f| f.offset == b.start).unwrap();
            let tail = FIELDS.iter().find(|f| f.offset == b.start + b.len - 2).unwrap();
            assert!(head.name.ends_with(".SEQ_HEAD") && tail.name.ends_with(".SEQ_TAIL"), "{}", b.name);
        }
    }
    assert_eq!(at, IMAGE_SIZE);
    // Version 1 offsets stay where they were.
    assert_eq!((layout::status::START, layout::outputs::START, layout::inputs::START), (0x10, 0x30, 0x78));
}

#[test]
fn doc_is_current() {
    let mut doc = String::new();
    layout::write_markdown(&mut doc).unwrap();
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/DPM.md");
    if std::env::var_os("DPM_DOC_WRITE").is_some() {
        std::fs::create_dir_all(concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs")).unwrap();
        std::fs::write(path, &doc).unwrap();
    }
    let committed = std::fs::read_to_string(path).unwrap_or_default();
    assert!(
        committed == doc,
        "docs/DPM.md differs from crates/dpm/src/dpm/layout.rs; regenerate it with\n  \
         DPM_DOC_WRITE=1 cargo test -p pbcard-dpm --lib --target x86_64-unknown-linux-gnu dpm::tests_v2::doc_is_current"
    );
}

fn field(name: &str) -> &'static layout::Field {
    FIELDS.iter().find(|f| f.name == name).unwrap_or_else(|| panic!("no field {name}"))
}

/// Decode block `name` from an image and encode it into a zeroed image (the API's view).
fn roundtrip(name: &str, image: &[u8; IMAGE_SIZE]) -> [u8; IMAGE_SIZE] {
    let b = BLOCKS.iter().find(|b| b.name == name).unwrap();
    let src = &image[b.start..b.start + b.len];
    let mut out = [0u8; IMAGE_SIZE];
    let dst = &mut out[b.start..b.start + b.len];
    match name {
        "IDENT" => Identity::decode(src).encode(dst),
        "CARD" => CardReport::decode(src).encode(dst),
        "DRIVE" => DriveReport::decode(src).encode(dst),
        "CONFIG" => HostConfig::decode(src).encode(dst),
        "MBX_REQ" => MailboxRequest::decode(src).unwrap().encode(dst),
        "MBX_RSP" => MailboxResponse::decode(src).encode(dst),
        "STATUS" => Status::decode(src).encode(dst),
        "DRIVE_CMD" => DriveCommandImage::decode(src).encode(dst),
        "DRIVE_STATE" => DriveStateImage::decode(src).encode(dst),
        "DEVICE" => (super::codec::DEVICE_ENCODE)(&(super::codec::DEVICE_DECODE)(src), dst),
        _ => unreachable!(),
    }
    out
}

/// Every field of every decoded block: a pattern written at its offset comes back through
/// decode + encode at the same offset (so every field is read, and at the documented place).
#[test]
fn every_field_read_back() {
    let skip = |n: &str| n.ends_with("SEQ_HEAD") || n.ends_with("SEQ_TAIL") || n.ends_with(".reserved");
    for b in BLOCKS.iter().filter(|b| !matches!(b.name, "HEADER" | "OUTPUTS" | "INPUTS")) {
        let prefix = format!("{}.", b.name);
        for f in FIELDS.iter().filter(|f| f.name.starts_with(&prefix) && !skip(f.name)) {
            let mut img = [0u8; IMAGE_SIZE];
            // A base that makes every field meaningful.
            let set = |img: &mut [u8; IMAGE_SIZE], n: &str, v: &[u8]| {
                let f = field(n);
                img[f.offset..f.offset + v.len()].copy_from_slice(v);
            };
            match b.name {
                "DRIVE" => set(&mut img, "DRIVE.EXT_DIAG_LEN", &[32]),
                "MBX_REQ" => {
                    set(&mut img, "MBX_REQ.REQ_ID", &[0, 9]);
                    set(&mut img, "MBX_REQ.KIND", &[2]);
                    set(&mut img, "MBX_REQ.VALUES_LEN", &[128]);
                }
                "MBX_RSP" => {
                    let err = matches!(
                        f.name,
                        "MBX_RSP.ERROR" | "MBX_RSP.ERROR_INFO" | "MBX_RSP.HAS_INFO" | "MBX_RSP.RESULT"
                    );
                    set(&mut img, "MBX_RSP.RESULT", &[err as u8]);
                    set(&mut img, "MBX_RSP.HAS_INFO", &[err as u8]);
                    set(&mut img, "MBX_RSP.VALUES_LEN", &[128]);
                    if err {
                        set(&mut img, "MBX_RSP.FORMAT", &[0x44]);
                    }
                }
                "STATUS" => set(&mut img, "STATUS.MASTER_ADDRESS", &[0xFF]),
                "DRIVE_CMD" => set(&mut img, "DRIVE_CMD.EXTRA_COUNT", &[16]),
                "DRIVE_STATE" => set(&mut img, "DRIVE_STATE.EXTRA_COUNT", &[16]),
                _ => {}
            }
            let pattern: Vec<u8> = match (f.name, f.size) {
                (
                    "STATUS.COMM_STATE" | "STATUS.DP_STATE" | "MBX_REQ.KIND" | "MBX_RSP.RESULT" | "MBX_RSP.HAS_INFO",
                    _,
                ) => vec![1],
                (_, 1) => vec![0x05],
                (_, n) => (0..n).map(|i| 0x11 + i as u8).collect(),
            };
            set(&mut img, f.name, &pattern);
            let back = roundtrip(b.name, &img);
            assert_eq!(&back[f.offset..f.offset + f.size], &pattern[..], "{} not read back", f.name);
        }
    }
}

#[test]
fn new_blocks_round_trip_through_the_sides() {
    let mut dpm = Dpm::with_identity(&Identity { serial: 0x1234_5678, ..Identity::of_product(0x0F11) });
    assert_eq!(dpm.host().read_identity().serial, 0x1234_5678);
    let b = dpm.as_bytes();
    assert_eq!(&b[field("IDENT.SERIAL").offset..][..4], &[0x12, 0x34, 0x56, 0x78], "big-endian");

    let mut r = CardReport { heartbeat: 7, flags: CardFlags::DRIVE_LOST, config_ack: 3, ..Default::default() };
    r.events[CardEvent::Watchdog as usize] = 2;
    assert_eq!(dpm.card().write_card_report(&r), 1);
    assert_eq!(dpm.host().read_card_report(), Ok(r));
    assert_eq!(dpm.card_report().unwrap().event(CardEvent::Watchdog), 2);

    let mut d = DriveReport { heartbeat: 1, fault_code: 0x2310, warning_code: 5, fault_count: 1, ..DriveReport::EMPTY };
    d.set_ext_diag(&[0x05, 0x81, 0x00, 0x23, 0x10]);
    dpm.host().write_drive_report(&d);
    assert_eq!(dpm.card().read_drive_report(), Ok(d));

    let c =
        HostConfig { station_address: 9, telegram: Telegram::Ppo(2), comm_loss_delay_ms: 300, ..HostConfig::DEFAULT };
    assert_eq!(dpm.host().write_config(&c), 1);
    assert_eq!(dpm.card().read_config(), Ok((1, c)));

    let v = ParamValues::new(Format::WORD, 2, &[0, 1, 0, 2]).unwrap();
    let req = MailboxRequest { id: 5, ..MailboxRequest::write(1, 100, 0, v) };
    dpm.card().write_request(&req);
    assert_eq!(dpm.host().read_request(), Ok(Some(req)));
    let rsp = MailboxResponse {
        id: 5,
        outcome: Err(ParamError { value: ErrorValue::LIMIT_EXCEEDED, additional_info: Some(1) }),
    };
    dpm.host().write_response(&rsp);
    assert_eq!(dpm.card().read_response(), Ok((1, rsp)));
    let rsp = MailboxResponse { id: 6, outcome: Ok(v) };
    dpm.host().write_response(&rsp);
    assert_eq!(dpm.card().read_response(), Ok((2, rsp)));
}

// ---------------------------------------------------------------------------------------
// Consistency: every interleaving

#[derive(Debug, Clone, Copy)]
enum Step {
    Write(usize, u8),
    Read(usize),
}

/// Byte order of a pass over a block of `n` bytes: host = ascending; card = tail, payload, head.
fn order(n: usize, card: bool) -> Vec<usize> {
    if card {
        (n - 2..n).chain(2..n - 2).chain(0..2).collect()
    } else {
        (0..n).collect()
    }
}

fn image(seq: u16, fill: u8, n: usize) -> Vec<u8> {
    let mut b = vec![fill; n];
    b[..2].copy_from_slice(&seq.to_be_bytes());
    b[n - 2..].copy_from_slice(&seq.to_be_bytes());
    b
}

/// Run every interleaving of `writer` and `reader` (each kept in its own order) from `mem`;
/// call `check` with what the reader saw. Returns the number of interleavings.
fn interleavings(mem: &mut Vec<u8>, seen: &mut Vec<u8>, w: &[Step], r: &[Step], check: &mut dyn FnMut(&[u8])) -> usize {
    if w.is_empty() && r.is_empty() {
        check(seen);
        return 1;
    }
    let mut n = 0;
    if let Some((&s, rest)) = w.split_first() {
        let Step::Write(i, v) = s else { unreachable!() };
        let old = mem[i];
        mem[i] = v;
        n += interleavings(mem, seen, rest, r, check);
        mem[i] = old;
    }
    if let Some((&s, rest)) = r.split_first() {
        let Step::Read(i) = s else { unreachable!() };
        let old = seen[i];
        seen[i] = mem[i];
        n += interleavings(mem, seen, w, rest, check);
        seen[i] = old;
    }
    n
}

fn binomial(n: usize, k: usize) -> usize {
    (0..k).fold(1, |acc, i| acc * (n - i) / (i + 1))
}

/// Exhaustive: for both directions, block sizes 5..=8 and one or two back-to-back writes,
/// every interleaving of the writer's byte writes with the reader's byte reads gives a read
/// that is either torn (counters differ) or exactly one whole image — never a mix accepted.
#[test]
fn every_interleaving_reads_whole_or_torn() {
    for card_writes in [true, false] {
        for n in 5..=8 {
            for writes in 1..=2u8 {
                let images: Vec<Vec<u8>> = (0..=writes).map(|k| image(100 + k as u16, 0x10 * (k + 1), n)).collect();
                let mut w = vec![];
                for img in &images[1..] {
                    w.extend(order(n, card_writes).into_iter().map(|i| Step::Write(i, img[i])));
                }
                let r: Vec<Step> = order(n, !card_writes).into_iter().map(Step::Read).collect();
                let (mut whole, mut torn) = (0, 0);
                let mut check = |seen: &[u8]| {
                    let head = u16::from_be_bytes([seen[0], seen[1]]);
                    let tail = u16::from_be_bytes([seen[n - 2], seen[n - 1]]);
                    if head == tail {
                        assert!(images.iter().any(|img| img == seen), "accepted a mix: {seen:02X?}");
                        whole += 1;
                    } else {
                        torn += 1;
                    }
                };
                let mut mem = images[0].clone();
                let mut seen = vec![0u8; n];
                let count = interleavings(&mut mem, &mut seen, &w, &r, &mut check);
                assert_eq!(count, binomial(w.len() + r.len(), r.len()), "all interleavings enumerated");
                assert!(whole > 0 && torn > 0, "both outcomes occur (n {n}, writes {writes})");
            }
        }
    }
}

/// The counter the writer writes first must be the one the reader reads last: the wrong
/// order (both ascending) is caught by the same enumeration.
#[test]
fn the_enumeration_catches_a_wrong_order() {
    let n = 6;
    let (old, new) = (image(1, 0x11, n), image(2, 0x22, n));
    // Host writer ascending (head first); a reader that also reads the head first.
    let w: Vec<Step> = (0..n).map(|i| Step::Write(i, new[i])).collect();
    let asc: Vec<Step> = (0..n).map(Step::Read).collect();
    let mut mixes = 0;
    let mut check = |seen: &[u8]| {
        let (h, t) = (u16::from_be_bytes([seen[0], seen[1]]), u16::from_be_bytes([seen[n - 2], seen[n - 1]]));
        if h == t && seen != &old[..] && seen != &new[..] {
            mixes += 1;
        }
    };
    interleavings(&mut old.clone(), &mut vec![0; n], &w, &asc, &mut check);
    assert!(mixes > 0, "reading in the writer's order accepts mixes");
}

// ---------------------------------------------------------------------------------------
// Layout version 3: DRIVE_CMD / DRIVE_STATE, the codecs on raw bytes

#[test]
fn header_texts_name_this_version_and_size() {
    let v = field("HEADER.LAYOUT_VERSION").valid;
    assert!(v.starts_with(&format!("always: {} ", layout::LAYOUT_VERSION)), "{v}");
    let n = field("HEADER.IMAGE_SIZE").valid;
    assert!(n.contains(&format!("({}; ", IMAGE_SIZE)), "{n}");
    for (ver, size) in layout::IMAGE_SIZE_OF_VERSION.iter().enumerate().skip(1).take(3) {
        assert!(n.contains(&format!("version {ver}: {size}")), "{n}");
        // Every block of that version ends within its size, every later one after it.
        for b in BLOCKS {
            assert_eq!(b.start + b.len <= *size, b.since as usize <= ver, "{} in version {ver}", b.name);
        }
    }
    let caps = field("HEADER.CAPABILITIES").valid;
    assert!(caps.contains("5 DRIVE_CMD, 6 DRIVE_STATE, 7 DEVICE"));
    assert_eq!(layout::cap::ALL, 0xFF);
}

fn sample_command() -> DriveCommandImage {
    use crate::profile::drive_if::{CommandFlags, DriveCommand};
    DriveCommandImage {
        command: DriveCommand {
            flags: CommandFlags::RUN | CommandFlags::FIELDBUS_CONTROL | CommandFlags::REVERSE,
            speed_setpoint: -0x2000,
            fault_resets: 3,
            comm_loss_reaction: 2,
        },
        operate_mode: layout::operate_mode::PROFIDRIVE,
        telegram: Telegram::Ppo(2),
        outputs_seq: 77,
        extra: PzdWords::new(&[1, 2, 0xFFFF, 0x8000]).unwrap(),
    }
}

fn sample_state() -> DriveStateImage {
    use crate::profile::drive_if::{DriveStatus, StatusFlags as S};
    DriveStateImage {
        status: DriveStatus {
            flags: S::READY | S::RUNNING | S::REVERSE | S::WARNING,
            speed: -0x1FF0,
            current: 0x3000,
            torque: -5,
            power: 0x4000,
            fault_code: 0,
            warning_code: 0x0102,
            namur: 0x0004,
        },
        inputs_seq: 9,
        extra: PzdWords::new(&[0xAAAA; 16]).unwrap(),
    }
}

#[test]
fn drive_command_and_state_round_trip_through_the_sides() {
    let mut dpm = Dpm::new();
    assert_eq!(dpm.drive_command(), Ok((0, DriveCommandImage::EMPTY)), "never written");
    let c = sample_command();
    assert_eq!(dpm.card().write_drive_command(&c), 1);
    assert_eq!(dpm.host().read_drive_command(), Ok((1, c)));
    let b = dpm.as_bytes();
    let at = field("DRIVE_CMD.SPEED_SETPOINT").offset;
    assert_eq!(&b[at..at + 2], &[0xE0, 0x00], "i16 big-endian, two's complement");
    let s = sample_state();
    assert_eq!(dpm.host().write_drive_state(&s), 1);
    assert_eq!(dpm.card().read_drive_state(), Ok((1, s)));
    assert_eq!(dpm.drive_state(), Ok((1, s)));
    assert_eq!(PzdWords::new(&[0; 17]), None, "at most 16 extra words");
    assert_eq!(s.extra.word(15), 0xAAAA);
    assert_eq!(c.extra.word(4), 0, "beyond the count");
}

#[test]
fn codec_handles_match_the_map_and_the_sides() {
    use super::codec;
    let names = [
        codec::HEADER.block().name,
        codec::STATUS.block().name,
        codec::OUTPUTS.block().name,
        codec::INPUTS.block().name,
        codec::IDENT.block().name,
        codec::CARD.block().name,
        codec::DRIVE.block().name,
        codec::CONFIG.block().name,
        codec::MBX_REQ.block().name,
        codec::MBX_RSP.block().name,
        codec::DRIVE_CMD.block().name,
        codec::DRIVE_STATE.block().name,
        codec::DEVICE.block().name,
    ];
    assert_eq!(names.to_vec(), BLOCKS.iter().map(|b| b.name).collect::<Vec<_>>());

    let mut dpm = Dpm::new();
    let img = |dpm: &Dpm, c: &codec::BlockCodec<_>| dpm.as_bytes()[c.start()..c.start() + c.len()].to_vec();
    let hdr = codec::HEADER.decode(&img(&dpm, &codec::HEADER)).unwrap();
    assert_eq!(hdr, (0, codec::Header::THIS_LAYOUT));
    // A block the card wrote decodes as the host side reads it; the host's encoding is
    // byte for byte what HostSide writes.
    let c = sample_command();
    dpm.card().write_drive_command(&c);
    dpm.card().write_drive_command(&c);
    let raw = &dpm.as_bytes()[codec::DRIVE_CMD.start()..][..codec::DRIVE_CMD.len()];
    assert_eq!(codec::DRIVE_CMD.decode(raw), Ok((2, c)));
    let s = sample_state();
    let mut out = vec![0u8; codec::DRIVE_STATE.len()];
    codec::DRIVE_STATE.encode(&s, 1, &mut out).unwrap();
    dpm.host().write_drive_state(&s);
    assert_eq!(out, &dpm.as_bytes()[codec::DRIVE_STATE.start()..][..codec::DRIVE_STATE.len()]);
    // Wrong length and torn reads give nothing.
    assert_eq!(
        codec::DRIVE_STATE.decode(&out[1..]),
        Err(codec::BlockError::Length { expected: codec::DRIVE_STATE.len(), got: codec::DRIVE_STATE.len() - 1 })
    );
    assert!(codec::DRIVE_STATE.encode(&s, 1, &mut [0u8; 3]).is_err());
    let n = out.len();
    out[n - 1] = 2;
    assert_eq!(codec::DRIVE_STATE.decode(&out), Err(codec::BlockError::Torn(Torn { head: 1, tail: 2 })));
    assert_eq!(codec::DRIVE_STATE.counters(&out), Some((1, 2)));
    assert_eq!(codec::HEADER.counters(&img(&dpm, &codec::HEADER)), None, "not sequenced");
    // MBX_REQ: no request = None; a request round-trips.
    let mut req = vec![0u8; codec::MBX_REQ.len()];
    assert_eq!(codec::MBX_REQ.decode(&req), Ok((0, None)));
    let v = ParamValues::new(Format::WORD, 2, &[0, 1, 0, 2]).unwrap();
    let r = MailboxRequest { id: 4, ..MailboxRequest::write(1, 100, 2, v) };
    codec::MBX_REQ.encode(&Some(r), 7, &mut req).unwrap();
    assert_eq!(codec::MBX_REQ.decode(&req), Ok((7, Some(r))));
}

#[test]
fn request_ids_skip_zero() {
    let mut dpm = Dpm::new();
    let mut mbx = Mailbox::new(crate::time::Duration::from_millis(1));
    mbx.last_id_for_test(u16::MAX);
    let id = mbx
        .submit(crate::time::Instant::from_millis(0), &MailboxRequest::read(1, 1, 0, 1), false, &mut dpm.card())
        .unwrap();
    assert_eq!(id, 1);
}
