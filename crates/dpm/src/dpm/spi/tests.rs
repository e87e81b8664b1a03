//! The SPI frame protocol: golden bytes, every block through the loopback, every single-bit
//! flip, cut and overlong transactions, forbidden writes, events / IRQ, a busy card, and
//! property tests on arbitrary bytes.

use super::*;
use crate::dpm::layout::{self, Block, FIELDS};
use crate::dpm::{PdFlags, ProcessData, Status, Telegram};
use proptest::prelude::*;

/// A request frame as a drive maker would build it by hand (no codec).
fn frame(cmd: u8, tag: u8, addr: u16, len: u16, data: &[u8]) -> Vec<u8> {
    let mut f = vec![cmd, tag];
    f.extend_from_slice(&addr.to_be_bytes());
    f.extend_from_slice(&len.to_be_bytes());
    f.extend_from_slice(data);
    let crc = crc16(&f);
    f.extend_from_slice(&crc.to_be_bytes());
    f
}

fn read_frame(tag: u8, addr: u16, len: u16) -> Vec<u8> {
    frame(Command::Read as u8, tag, addr, len, &[])
}

fn write_frame(tag: u8, addr: u16, data: &[u8]) -> Vec<u8> {
    frame(Command::Write as u8, tag, addr, data.len() as u16, data)
}

/// A card image whose every byte is set (card blocks written by the card, host blocks by a
/// host pass), so that reads compare something other than zeros.
fn busy_image() -> Dpm {
    let mut dpm = Dpm::new();
    for (i, b) in dpm.as_bytes_mut().iter_mut().enumerate() {
        *b = (i as u8).wrapping_mul(37).wrapping_add(11);
    }
    dpm
}

fn handle(slave: &mut SpiSlave, dpm: &mut Dpm, rx: &[u8]) -> (ResultCode, Vec<u8>) {
    let mut reply = [0u8; MAX_REPLY];
    let n = slave.handle(rx, dpm, &mut reply);
    let r = SpiHostCodec::decode(&reply[..n]).expect("the card's reply decodes");
    (r.result, reply[..n].to_vec())
}

fn host_blocks() -> impl Iterator<Item = &'static Block> {
    layout::BLOCKS.iter().filter(|b| b.writer == layout::Writer::Host)
}

fn card_blocks() -> impl Iterator<Item = &'static Block> {
    layout::BLOCKS.iter().filter(|b| b.writer == layout::Writer::Card)
}

// ---------------------------------------------------------------------------------------
// CRC and golden frames (module docs)

#[test]
fn crc16_ccitt_false_check_value() {
    // The catalogue check value of CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF).
    assert_eq!(crc16(b"123456789"), 0x29B1);
    assert_eq!(crc16(b""), 0xFFFF);
    assert_eq!(crc16_update(crc16(b"1234"), b"56789"), 0x29B1);
    // A frame followed by its CRC (high byte first) leaves a zero remainder.
    let mut f = b"123456789".to_vec();
    f.extend_from_slice(&0x29B1u16.to_be_bytes());
    assert_eq!(crc16(&f), 0);
}

#[test]
fn golden_request_frames_of_the_docs() {
    // Independently computed with Python's binascii.crc_hqx(frame, 0xFFFF).
    let read = [0xA1, 0x01, 0x00, 0x10, 0x00, 0x20, 0x67, 0xC8];
    let write = [0xB2, 0x02, 0x00, 0x78, 0x00, 0x02, 0x12, 0x34, 0x07, 0x2B];
    let status = [0xC4, 0x03, 0x00, 0x00, 0x00, 0x00, 0x58, 0x53];
    assert_eq!(read_frame(1, 0x10, 32), read);
    assert_eq!(write_frame(2, 0x78, &[0x12, 0x34]), write);
    assert_eq!(frame(0xC4, 3, 0, 0, &[]), status);

    let mut codec = SpiHostCodec::new();
    let mut out = [0xEEu8; 16];
    codec.encode(Command::Status, 0, 0, &[], &mut out).unwrap(); // TAG 0
    assert_eq!(codec.encode(Command::Read, 0x10, 32, &[], &mut out), Some((1, 8)));
    assert_eq!(&out[..8], &read);
    assert!(out[8..].iter().all(|&b| b == 0), "zero padding");
    assert_eq!(codec.encode(Command::Write, 0x78, 2, &[0x12, 0x34], &mut out), Some((2, 10)));
    assert_eq!(&out[..10], &write);
    assert_eq!(codec.encode(Command::Status, 0, 0, &[], &mut out), Some((3, 8)));
    assert_eq!(&out[..8], &status);
    assert_eq!(codec.encode(Command::Write, 0, 20, &[0; 20], &mut out), None, "too short a buffer");

    let (mut slave, mut dpm) = (SpiSlave::new(), Dpm::new());
    let (r, reply) = handle(&mut slave, &mut dpm, &read);
    assert_eq!(r, ResultCode::Ok);
    // RESULT, TAG, CMD, FLAGS, ADDR, LEN, then the 32 bytes of STATUS, then the CRC.
    assert_eq!(&reply[..8], &[0x80, 0x01, 0xA1, 0x00, 0x00, 0x10, 0x00, 0x20]);
    assert_eq!(&reply[8..40], &dpm.as_bytes()[0x10..0x30]);
    assert_eq!(reply.len(), 42);
    assert_eq!(crc16(&reply), 0);
}

#[test]
fn command_codes_are_apart_and_not_stuck_line_values() {
    let codes = [Command::Read as u8, Command::Write as u8, Command::Status as u8, Command::Cyclic as u8];
    for (i, a) in codes.iter().enumerate() {
        assert!(*a != 0x00 && *a != 0xFF);
        assert_eq!(Command::from_code(*a).map(|c| c as u8), Some(*a));
        for b in &codes[i + 1..] {
            assert!((a ^ b).count_ones() >= 3, "{a:#x} / {b:#x}");
        }
    }
    for c in 0..=255u8 {
        if !codes.contains(&c) {
            assert_eq!(Command::from_code(c), None);
        }
    }
    for r in ResultCode::ALL {
        assert_ne!(r as u8, NO_REPLY);
        assert_eq!(ResultCode::from_code(r as u8), Some(r));
    }
}

// ---------------------------------------------------------------------------------------
// Every block and field through the loopback

#[test]
fn every_block_and_field_reads_through_the_loopback_as_the_image() {
    let mut host = SpiHost::new(Loopback::new(busy_image()));
    for b in layout::BLOCKS {
        let mut buf = vec![0u8; b.len];
        host.read(b.start as u16, &mut buf).unwrap();
        assert_eq!(buf, &host.bus().dpm().as_bytes()[b.start..b.start + b.len], "{}", b.name);
    }
    for f in FIELDS {
        let mut buf = vec![0u8; f.size];
        host.read(f.offset as u16, &mut buf).unwrap();
        assert_eq!(buf, &host.bus().dpm().as_bytes()[f.offset..f.offset + f.size], "{}", f.name);
    }
    let mut all = [0u8; IMAGE_SIZE];
    host.read(0, &mut all).unwrap();
    assert_eq!(&all, host.bus().dpm().as_bytes());
    assert_eq!(host.retried(), 0);
    assert_eq!(host.bus().slave().stats().refused(), 0);
}

#[test]
fn every_host_block_writes_through_the_loopback_and_card_blocks_are_refused() {
    let mut host = SpiHost::new(Loopback::new(Dpm::new()));
    for (k, b) in host_blocks().enumerate() {
        let data: Vec<u8> = (0..b.len).map(|i| (i as u8) ^ (k as u8 * 0x31) ^ 0xA5).collect();
        let before = host.bus().dpm().clone();
        host.write(b.start as u16, &data).unwrap();
        let img = host.bus().dpm().as_bytes();
        assert_eq!(&img[b.start..b.start + b.len], &data[..], "{}", b.name);
        // Nothing else changed.
        for i in (0..IMAGE_SIZE).filter(|i| !(b.start..b.start + b.len).contains(i)) {
            assert_eq!(img[i], before.as_bytes()[i], "{} changed byte {i:#x}", b.name);
        }
    }
    for b in card_blocks() {
        let before = host.bus().dpm().clone();
        assert_eq!(
            host.write(b.start as u16, &vec![0x5A; b.len]),
            Err(HostError::Refused(ResultCode::ForbiddenWrite)),
            "{}",
            b.name
        );
        // Every single byte of the block, too.
        for i in b.start..b.start + b.len {
            assert_eq!(host.write(i as u16, &[0x5A]), Err(HostError::Refused(ResultCode::ForbiddenWrite)));
        }
        assert_eq!(host.bus().dpm(), &before, "{}", b.name);
    }
    // Contiguous host blocks (DRIVE + CONFIG) in one write are fine; across into a card
    // block (INPUTS's last byte + IDENT's first) is not.
    host.write(layout::drive::START as u16, &[7; layout::drive::LEN + layout::config::LEN]).unwrap();
    assert_eq!(
        host.write((layout::ident::START - 1) as u16, &[1, 2]),
        Err(HostError::Refused(ResultCode::ForbiddenWrite))
    );
    let n = card_blocks().map(|b| 1 + b.len as u32).sum::<u32>() + 1;
    assert_eq!(host.bus().slave().stats().forbidden_writes, n);
}

#[test]
fn the_typed_host_side_over_spi_is_what_the_card_reads() {
    // The drive keeps a mirror of the image, writes INPUTS with the typed host side and
    // moves the block's bytes over SPI; the card reads them back as ProcessData.
    let mut host = SpiHost::new(Loopback::new(Dpm::new()));
    let mut mirror = Dpm::new();
    let pd = ProcessData::new(Telegram::Standard(1), PdFlags::empty(), &[0x0B, 0x37, 0x40, 0x00]);
    let seq = mirror.host().write_inputs(&pd);
    let (s, n) = (layout::inputs::START, layout::inputs::LEN);
    host.write(s as u16, &mirror.as_bytes()[s..s + n]).unwrap();
    let got = host.bus().dpm().inputs().unwrap();
    assert_eq!((got.seq, got.telegram, got.bytes()), (seq, Telegram::Standard(1), pd.bytes()));

    // And the card's STATUS, read over SPI into the mirror, decodes as the card wrote it.
    let mut status = Status::INACTIVE;
    status.station_address = 7;
    host.bus_mut().dpm_mut().card().write_status(&status);
    let (s, n) = (layout::status::START, layout::status::LEN);
    host.read(s as u16, &mut mirror.as_bytes_mut()[s..s + n]).unwrap();
    assert_eq!(mirror.status(), Ok(status));
}

// ---------------------------------------------------------------------------------------
// Corrupted, cut and overlong frames

fn valid_frames() -> Vec<Vec<u8>> {
    vec![
        read_frame(1, 0x10, 32),
        read_frame(0x80, 0, IMAGE_SIZE as u16),
        write_frame(2, layout::inputs::START as u16, &[0x12, 0x34, 0x56]),
        write_frame(3, layout::config::START as u16, &[0xFF; layout::config::LEN]),
        write_frame(4, layout::mbx_rsp::START as u16, &[0; layout::mbx_rsp::LEN]),
        frame(Command::Status as u8, 5, 0, 0, &[]),
    ]
}

#[test]
fn every_single_bit_flip_is_refused_counted_and_changes_nothing() {
    for f in valid_frames() {
        // The frame itself is accepted (and a WRITE lands).
        let (mut slave, mut dpm) = (SpiSlave::new(), busy_image());
        assert_eq!(handle(&mut slave, &mut dpm, &f).0, ResultCode::Ok);
        for bit in 0..f.len() * 8 {
            let mut g = f.clone();
            g[bit / 8] ^= 1 << (bit % 8);
            let (mut slave, mut dpm) = (SpiSlave::new(), busy_image());
            let before = dpm.clone();
            let (r, _) = handle(&mut slave, &mut dpm, &g);
            assert_ne!(r, ResultCode::Ok, "flip of bit {bit} accepted: {g:02x?}");
            assert_eq!(dpm, before, "flip of bit {bit} changed the image");
            let s = slave.stats();
            assert_eq!((s.frames_ok, s.refused()), (0, 1), "flip of bit {bit}: {s:?}");
            // A flip in the covered bytes that keeps the frame length is a CRC error.
            let len_bytes = bit / 8 == 4 || bit / 8 == 5 || bit / 8 == 0;
            if !len_bytes || f[0] != Command::Write as u8 {
                assert_eq!(r, ResultCode::CrcError, "flip of bit {bit}");
            }
        }
    }
}

#[test]
fn cut_frames_are_refused_as_bad_length() {
    for f in valid_frames() {
        for n in 0..f.len() {
            let (mut slave, mut dpm) = (SpiSlave::new(), busy_image());
            let before = dpm.clone();
            let (r, _) = handle(&mut slave, &mut dpm, &f[..n]);
            // A cut WRITE whose remaining bytes happen to end in a CRC of the shorter frame
            // cannot exist: the LEN field still announces the full length.
            assert_eq!(r, ResultCode::BadLength, "{n} of {} bytes", f.len());
            assert_eq!(dpm, before);
            assert_eq!(slave.stats().bad_length, 1);
        }
    }
}

#[test]
fn padding_must_be_zero_and_transactions_have_a_maximum() {
    for f in valid_frames() {
        let (mut slave, mut dpm) = (SpiSlave::new(), busy_image());
        // Zero padding up to MAX_TRANSACTION is fine.
        let mut padded = f.clone();
        padded.resize(MAX_TRANSACTION, 0);
        assert_eq!(handle(&mut slave, &mut dpm, &padded).0, ResultCode::Ok);
        // One byte more is overlong.
        padded.push(0);
        let before = dpm.clone();
        assert_eq!(handle(&mut slave, &mut dpm, &padded).0, ResultCode::BadLength);
        assert_eq!(dpm, before);
        // Non-zero padding (a frame slip, two frames in one transaction) is refused.
        for fill in [0x01u8, 0xFF] {
            let mut g = f.clone();
            g.push(fill);
            assert_eq!(handle(&mut slave, &mut dpm, &g).0, ResultCode::BadLength);
            let mut two = f.clone();
            two.extend_from_slice(&f);
            assert_eq!(handle(&mut slave, &mut dpm, &two).0, ResultCode::BadLength);
        }
        assert_eq!(dpm, before);
        assert_eq!(slave.stats().bad_length, 5);
    }
}

#[test]
fn lengths_addresses_and_commands_are_checked() {
    let (mut slave, mut dpm) = (SpiSlave::new(), busy_image());
    let before = dpm.clone();
    let cases: Vec<(Vec<u8>, ResultCode)> = vec![
        (read_frame(0, 0, 0), ResultCode::BadLength),
        (read_frame(0, 0, (MAX_DATA + 1) as u16), ResultCode::BadLength),
        (frame(Command::Write as u8, 0, layout::inputs::START as u16, 0, &[]), ResultCode::BadLength),
        (read_frame(0, (IMAGE_SIZE - 3) as u16, 4), ResultCode::BadAddress),
        (read_frame(0, IMAGE_SIZE as u16, 1), ResultCode::BadAddress),
        (read_frame(0, 0xFFFF, 1), ResultCode::BadAddress),
        (write_frame(0, (IMAGE_SIZE - 1) as u16, &[1, 2]), ResultCode::BadAddress),
        (frame(Command::Status as u8, 0, 1, 0, &[]), ResultCode::BadLength),
        (frame(Command::Status as u8, 0, 0, 1, &[]), ResultCode::BadLength),
        (frame(0x00, 0, 0, 0, &[]), ResultCode::BadCommand),
        (frame(0xFF, 0, 0, 0, &[]), ResultCode::BadCommand),
        (frame(0x52, 0, 0, 4, &[]), ResultCode::BadCommand),
        (vec![0u8; 8], ResultCode::CrcError),
        (vec![0xFFu8; 8], ResultCode::CrcError),
    ];
    for (f, want) in &cases {
        assert_eq!(handle(&mut slave, &mut dpm, f).0, *want, "{f:02x?}");
    }
    // The last byte of the image reads; MAX_DATA reads are accepted where they fit.
    assert_eq!(handle(&mut slave, &mut dpm, &read_frame(0, (IMAGE_SIZE - 1) as u16, 1)).0, ResultCode::Ok);
    assert_eq!(dpm, before);
    let s = slave.stats();
    assert_eq!((s.bad_length, s.bad_address, s.bad_command, s.crc_errors, s.frames_ok), (5, 4, 3, 2, 1));

    // STATUS shows the counters.
    let (r, reply) = handle(&mut slave, &mut dpm, &frame(Command::Status as u8, 9, 0, 0, &[]));
    assert_eq!(r, ResultCode::Ok);
    let st = StatusData::decode(SpiHostCodec::decode(&reply).unwrap().data).unwrap();
    assert_eq!((st.version, st.max_data as usize, st.image_size as usize), (PROTOCOL_VERSION, MAX_DATA, IMAGE_SIZE));
    assert_eq!(st.stats, [2, 2, 3, 5, 4, 0], "frames_ok counts the STATUS itself");
}

#[test]
fn refusals_echo_what_was_received() {
    let (mut slave, mut dpm) = (SpiSlave::new(), Dpm::new());
    let f = write_frame(0x42, layout::ident::START as u16, &[1]);
    let (r, reply) = handle(&mut slave, &mut dpm, &f);
    assert_eq!(r, ResultCode::ForbiddenWrite);
    let rep = SpiHostCodec::decode(&reply).unwrap();
    assert_eq!(
        (rep.tag, rep.cmd, rep.addr, rep.data.len()),
        (0x42, Command::Write as u8, layout::ident::START as u16, 0)
    );
    let (r, reply) = handle(&mut slave, &mut dpm, &[0xA1]);
    assert_eq!(r, ResultCode::BadLength);
    // A transaction too short for a header echoes what there is (CMD) and zeros: TAG,
    // CMD, FLAGS, ADDR, LEN.
    assert_eq!(&reply[1..8], &[0x00, 0xA1, 0x00, 0x00, 0x00, 0x00, 0x00]);
}

#[test]
fn reply_decoding_errors() {
    assert_eq!(SpiHostCodec::decode(&[]), Err(ReplyError::Truncated));
    assert_eq!(SpiHostCodec::decode(&[0; 40]), Err(ReplyError::NoReply));
    assert_eq!(SpiHostCodec::decode(&[0xFF; 40]), Err(ReplyError::BadResult(0xFF)));
    let (mut slave, mut dpm) = (SpiSlave::new(), Dpm::new());
    let (_, reply) = handle(&mut slave, &mut dpm, &read_frame(1, 0, 16));
    assert_eq!(SpiHostCodec::decode(&reply[..reply.len() - 1]), Err(ReplyError::Truncated));
    assert_eq!(SpiHostCodec::decode(&reply[..5]), Err(ReplyError::Truncated));
    for bit in 8..reply.len() * 8 {
        let mut g = reply.clone();
        g[bit / 8] ^= 1 << (bit % 8);
        // A flip in LEN may announce more bytes than there are.
        assert!(
            matches!(SpiHostCodec::decode(&g), Err(ReplyError::Crc | ReplyError::Truncated)),
            "reply flip {bit} accepted"
        );
    }
}

// ---------------------------------------------------------------------------------------
// Events and the IRQ line

#[test]
fn events_are_set_by_card_writes_and_cleared_by_reading_seq_head() {
    let mut host = SpiHost::new(Loopback::new(Dpm::new()));
    let lb = host.bus_mut();
    assert_eq!(lb.slave().events(lb.dpm()), 0, "a fresh image has no sequenced write yet");
    assert!(!lb.irq());
    assert_eq!(EVENT_BLOCKS, 0b101_0010_0110, "STATUS, OUTPUTS, CARD, MBX_REQ, DRIVE_CMD (layout 3)");

    lb.dpm_mut().card().write_status(&Status::INACTIVE);
    let pd = ProcessData::new(Telegram::Standard(1), PdFlags::DATA_EXCHANGE, &[1, 2, 3, 4]);
    lb.dpm_mut().card().write_outputs(&pd);
    assert_eq!(lb.slave().events(lb.dpm()), 0b110);
    assert!(lb.irq());

    // The STATUS reply's events and FLAGS show it.
    let st = host.status().unwrap();
    assert_eq!(st.events, 0b110);
    assert!(host.events_pending());

    // Reading OUTPUTS without its SEQ_HEAD does not clear; with it does.
    let mut buf = [0u8; 8];
    host.read((layout::outputs::START + 2) as u16, &mut buf).unwrap();
    assert_eq!(host.bus().slave().events(host.bus().dpm()), 0b110);
    let mut one = [0u8; 1];
    host.read(layout::outputs::START as u16, &mut one).unwrap();
    assert_eq!(host.bus().slave().events(host.bus().dpm()), 0b110, "half a SEQ_HEAD is not a read of it");
    let mut block = [0u8; layout::outputs::LEN];
    host.read(layout::outputs::START as u16, &mut block).unwrap();
    assert_eq!(host.bus().slave().events(host.bus().dpm()), 0b010);

    // An update after the read sets it again; reading STATUS and OUTPUTS in one READ clears both.
    host.bus_mut().dpm_mut().card().write_outputs(&pd);
    assert_eq!(host.bus().slave().events(host.bus().dpm()), 0b110);
    let mut both = [0u8; layout::status::LEN + layout::outputs::LEN];
    host.read(layout::status::START as u16, &mut both).unwrap();
    assert_eq!(host.bus().slave().events(host.bus().dpm()), 0);
    assert!(!host.bus().irq());
    host.status().unwrap();
    assert!(!host.events_pending());

    // Host writes never raise an event.
    host.write(layout::inputs::START as u16, &[1; 4]).unwrap();
    assert!(!host.bus().irq());
    // CARD and MBX_REQ do.
    let lb = host.bus_mut();
    lb.dpm_mut().card().write_card_report(&Default::default());
    assert_eq!(lb.slave().events(lb.dpm()), 1 << 5);
}

/// Issue 16 item 4: the host's `DRIVE.IRQ_MASK` keeps the per-cycle blocks off the IRQ line
/// (the bitmap still shows them); an MBX_REQ fragment from offset 0 in a CYCLIC reply counts
/// as a read of MBX_REQ.
#[test]
fn the_irq_mask_keeps_masked_events_off_the_line_and_a_fragment_reads_mbx_req() {
    let mut host = SpiHost::new(Loopback::new(Dpm::new()));
    let lb = host.bus_mut();
    lb.dpm_mut().card().write_card_report(&Default::default());
    lb.dpm_mut().card().write_status(&Status::INACTIVE);
    assert!(lb.irq(), "unmasked: CARD and STATUS assert IRQ");
    let mask = EVENT_BLOCKS & !(1 << 8);
    assert_eq!(mask, 0x0426, "STATUS, OUTPUTS, CARD, DRIVE_CMD: the value the docs suggest");
    lb.dpm_mut().host().write_drive_report(&crate::dpm::DriveReport {
        heartbeat: 1,
        irq_mask: mask,
        ..Default::default()
    });
    assert_eq!(irq_mask(lb.dpm()), mask);
    assert!(!lb.irq(), "masked");
    assert_eq!(lb.slave().events(lb.dpm()), 0b10_0010, "the bitmap is not masked");
    // A parameter request asserts IRQ, and the reply FLAGS mirror the line.
    let req = crate::dpm::MailboxRequest { id: 7, ..crate::dpm::MailboxRequest::read(1, 100, 0, 1) };
    lb.dpm_mut().card().write_request(&req);
    assert!(lb.irq());
    host.status().unwrap();
    assert!(host.events_pending());
    // A CYCLIC exchange asking MBX_REQ from offset 0 takes the request and clears the event.
    let r = cyclic::CyclicRequest { heartbeat: 1, drive_seq: 0, state_seq: 0, state: &[], rsp: (0, &[]), req: (0, 32) };
    let d = host.cyclic(&r).unwrap();
    let reply = cyclic::CyclicReply::decode(d).unwrap();
    assert_eq!(reply.request.len(), 32);
    assert_eq!(u16::from_be_bytes([reply.request[2], reply.request[3]]), 7, "REQ_ID");
    assert!(!host.bus().irq(), "the fragment read MBX_REQ");
    // A fragment elsewhere is no read of SEQ_HEAD (the armed reply of the last request is
    // refreshed with its own fragment first: one exchange to pass it).
    let r = cyclic::CyclicRequest { req: (2, 8), ..r };
    host.cyclic(&r).unwrap();
    let req = crate::dpm::MailboxRequest { id: 8, ..req };
    host.bus_mut().dpm_mut().card().write_request(&req);
    host.cyclic(&r).unwrap();
    host.cyclic(&r).unwrap();
    assert!(host.bus().irq(), "MBX_REQ still unread");
}

// ---------------------------------------------------------------------------------------
// The pipelined host against a busy card

#[test]
fn the_reply_to_transaction_k_is_clocked_out_in_k_plus_1_exactly() {
    let mut card = Loopback::new(busy_image());
    let mut miso = [0u8; 64];
    // k = 0: a READ; its MISO carries nothing (no earlier request).
    let req = read_frame(7, 0x30, 16);
    let mut mosi = [0u8; 64];
    mosi[..req.len()].copy_from_slice(&req);
    card.transfer(&mosi, &mut miso).unwrap();
    assert!(miso.iter().all(|&b| b == 0));
    // k = 1: a STATUS request; MISO carries the READ's reply.
    let poll = frame(Command::Status as u8, 8, 0, 0, &[]);
    let mut mosi = [0u8; 64];
    mosi[..poll.len()].copy_from_slice(&poll);
    card.transfer(&mosi, &mut miso).unwrap();
    let r = SpiHostCodec::decode(&miso).unwrap();
    assert_eq!((r.tag, r.cmd, r.addr, r.data), (7, Command::Read as u8, 0x30, &busy_image().as_bytes()[0x30..0x40]));
    // k = 2: zeros; MISO carries the STATUS reply, never the READ's again.
    card.transfer(&[0; 64], &mut miso).unwrap();
    assert_eq!(SpiHostCodec::decode(&miso).unwrap().tag, 8);
    // A late reply is discarded: the next transaction carries 0x00, the one after that the
    // reply to the transaction in between (here an all-zero one, refused for its CRC), never the late one.
    card.set_late(1);
    card.transfer(&mosi, &mut miso).unwrap(); // STATUS tag 8 again, reply late
    card.transfer(&[0; 64], &mut miso).unwrap();
    assert_eq!(miso[0], NO_REPLY);
    card.transfer(&[0; 64], &mut miso).unwrap();
    assert_eq!(SpiHostCodec::decode(&miso).unwrap().result, ResultCode::CrcError);
    assert_eq!(card.pipeline().late, 1);
}

#[test]
fn the_host_resends_after_a_late_or_dropped_reply() {
    // The request itself is dropped (the card was busy): the fetch sees 0x00, the host
    // sends the request again.
    let mut host = SpiHost::new(Loopback::new(busy_image()));
    host.bus_mut().set_busy(1);
    let mut buf = [0u8; 16];
    host.read(0x30, &mut buf).unwrap();
    assert_eq!(&buf, &host.bus().dpm().as_bytes()[0x30..0x40]);
    assert_eq!(host.retried(), 1);
    assert_eq!(host.traffic().0, 4, "request + fetch, twice");

    // The reply is late (the board's frame task behind a longer job): the same.
    let mut host = SpiHost::new(Loopback::new(busy_image()));
    host.bus_mut().set_late(1);
    host.write(layout::inputs::START as u16, &[8; 2]).unwrap();
    assert_eq!(host.retried(), 1);
    assert_eq!(&host.bus().dpm().as_bytes()[layout::inputs::START..][..2], &[8, 8]);
    // On time: one request, one fetch.
    let before = host.traffic().0;
    host.write(layout::inputs::START as u16, &[9; 2]).unwrap();
    assert_eq!(host.traffic().0 - before, 2);

    // A card that never answers: NoReply after every retry, nothing written.
    let mut host = SpiHost::new(Loopback::new(Dpm::new()));
    host.bus_mut().set_busy(u32::MAX);
    assert_eq!(host.write(layout::inputs::START as u16, &[1]), Err(HostError::NoReply));
    assert_eq!(host.bus().dpm(), &Dpm::new());
    assert_eq!(host.retried(), 3);
    assert_eq!(host.bus().dropped(), 4 * 2);
}

/// The pipeline of the first board driver (the reply to *k* in *k + 2*), as a bus: the
/// reference host must not take anything from it for a reply, and must not panic.
struct TwoDeep {
    card: Loopback,
    held: Vec<u8>,
}

impl SpiBus for TwoDeep {
    fn transfer(&mut self, mosi: &[u8], miso: &mut [u8]) -> Result<(), BusFault> {
        let mut now = vec![0u8; miso.len()];
        self.card.transfer(mosi, &mut now)?;
        let k = self.held.len().min(miso.len());
        miso.fill(0);
        miso[..k].copy_from_slice(&self.held[..k]);
        self.held = now;
        Ok(())
    }
}

#[test]
fn a_reply_one_transaction_too_late_is_never_taken() {
    let mut host = SpiHost::new(TwoDeep { card: Loopback::new(busy_image()), held: Vec::new() });
    let mut buf = [0u8; 16];
    assert_eq!(host.read(0x30, &mut buf), Err(HostError::NoReply));
    assert_eq!(host.write(layout::inputs::START as u16, &[1, 2]), Err(HostError::NoReply));
}

/// A bus that replays one recorded MISO once (a reply of the host's previous life, TAG
/// sequence restarted) and then behaves.
struct Stale {
    card: Loopback,
    replay: Option<Vec<u8>>,
    n: u32,
}

impl SpiBus for Stale {
    fn transfer(&mut self, mosi: &[u8], miso: &mut [u8]) -> Result<(), BusFault> {
        self.card.transfer(mosi, miso)?;
        self.n += 1;
        if self.n == 2 {
            if let Some(r) = self.replay.take() {
                let k = r.len().min(miso.len());
                miso.fill(0);
                miso[..k].copy_from_slice(&r[..k]);
            }
        }
        Ok(())
    }
}

#[test]
fn stale_replies_with_our_tag_are_never_taken_and_never_panic() {
    // Replies with TAG 0 (the first TAG of a restarted host) to other requests: another
    // address, another command, another length, another WRITE (same address and length).
    let mut stale = Vec::new();
    let mut dpm = busy_image();
    let mut slave = SpiSlave::new();
    let inputs = layout::inputs::START as u16;
    for req in [
        read_frame(0, 0x32, 16),
        read_frame(0, 0x30, 4),
        read_frame(0, 0x30, 200),
        write_frame(0, 0x30, &[1; 16]),
        write_frame(0, inputs, &[7, 7]),
        frame(Command::Status as u8, 0, 0, 0, &[]),
    ] {
        stale.push(handle(&mut slave, &mut dpm, &req).1);
    }
    for (i, r) in stale.into_iter().enumerate() {
        let card = Loopback::new(busy_image());
        let mut host = SpiHost::new(Stale { card, replay: Some(r), n: 0 });
        if i == 4 {
            host.write(inputs, &[5, 5]).unwrap();
            assert_eq!(&host.bus().card.dpm().as_bytes()[usize::from(inputs)..][..2], &[5, 5]);
        } else {
            let mut buf = [0u8; 16];
            host.read(0x30, &mut buf).unwrap();
            assert_eq!(&buf, &busy_image().as_bytes()[0x30..0x40], "stale reply {i} taken");
        }
        assert_eq!(host.retried(), 1, "stale reply {i}: one retry");
    }
}

/// A bus that flips one bit of one chosen transaction (MOSI or MISO side) in front of a
/// loopback card.
struct Flaky {
    card: Loopback,
    n: u32,
    flip_mosi: Option<(u32, usize)>,
    flip_miso: Option<(u32, usize)>,
}

impl SpiBus for Flaky {
    fn transfer(&mut self, mosi: &[u8], miso: &mut [u8]) -> Result<(), BusFault> {
        let mut m = mosi.to_vec();
        if let Some((k, bit)) = self.flip_mosi {
            if k == self.n && bit / 8 < m.len() {
                m[bit / 8] ^= 1 << (bit % 8);
            }
        }
        self.card.transfer(&m, miso)?;
        if let Some((k, bit)) = self.flip_miso {
            if k == self.n && bit / 8 < miso.len() {
                miso[bit / 8] ^= 1 << (bit % 8);
            }
        }
        self.n += 1;
        Ok(())
    }
}

#[test]
fn the_host_recovers_from_any_single_bit_error_on_either_line() {
    let data = [0xC0, 0xFF, 0xEE, 0x01];
    let at = layout::drive::START as u16;
    // Transaction 0 carries the WRITE, 1 the poll that fetches its reply.
    for k in 0..2u32 {
        for bit in 0..(REQUEST_HEADER + data.len() + CRC_LEN) * 8 {
            for side in [true, false] {
                let card = Loopback::new(Dpm::new());
                let flip = Some((k, bit));
                let (flip_mosi, flip_miso) = if side { (flip, None) } else { (None, flip) };
                let mut host = SpiHost::new(Flaky { card, n: 0, flip_mosi, flip_miso });
                host.write(at, &data).unwrap_or_else(|e| panic!("k {k} bit {bit} mosi {side}: {e:?}"));
                let img = host.bus().card.dpm().as_bytes();
                assert_eq!(&img[usize::from(at)..][..4], &data);
                let mut back = [0u8; 4];
                host.read(at, &mut back).unwrap();
                assert_eq!(back, data);
            }
        }
    }
}

#[test]
fn host_request_checks() {
    let mut host = SpiHost::new(Loopback::new(Dpm::new()));
    assert_eq!(host.read(0, &mut []), Err(HostError::BadRequest));
    assert_eq!(host.write(0xFFFF, &[1, 2]), Err(HostError::BadRequest));
    assert_eq!(host.read(0xFFFF, &mut [0]), Err(HostError::Refused(ResultCode::BadAddress)));
    // Longer than MAX_DATA is split into frames (and refused here for the image size).
    let mut big = vec![0u8; MAX_DATA + 1];
    assert_eq!(host.read(0, &mut big), Err(HostError::Refused(ResultCode::BadAddress)));
}

// ---------------------------------------------------------------------------------------
// Properties

/// What an accepted frame may have changed: only a WRITE's range, only host blocks.
fn check_effect(rx: &[u8], before: &Dpm, after: &Dpm, result: ResultCode) {
    let changed: Vec<usize> = (0..IMAGE_SIZE).filter(|&i| before.as_bytes()[i] != after.as_bytes()[i]).collect();
    if changed.is_empty() {
        return;
    }
    assert_eq!(result, ResultCode::Ok, "a refused frame changed {changed:?}");
    let req = parse_request(rx).expect("an accepted frame parses");
    assert_eq!(req.cmd, Command::Write);
    let (a, n) = (usize::from(req.addr), usize::from(req.len));
    assert!(changed.iter().all(|&i| (a..a + n).contains(&i)));
    assert!(host_writable(a, n));
    assert_eq!(&after.as_bytes()[a..a + n], req.data);
}

proptest! {
    #[test]
    fn arbitrary_bytes_never_panic_nor_change_the_image_unless_a_valid_host_write(
        rx in proptest::collection::vec(any::<u8>(), 0..64)
    ) {
        let (mut slave, mut dpm) = (SpiSlave::new(), busy_image());
        let before = dpm.clone();
        let mut reply = [0u8; MAX_REPLY];
        let n = slave.handle(&rx, &mut dpm, &mut reply);
        let r = SpiHostCodec::decode(&reply[..n]).unwrap();
        check_effect(&rx, &before, &dpm, r.result);
        let s = slave.stats();
        prop_assert_eq!(s.frames_ok + s.refused(), 1);
    }

    #[test]
    fn mutated_valid_frames_are_either_the_same_request_or_refused(
        cmd in prop_oneof![Just(Command::Read as u8), Just(Command::Write as u8), Just(Command::Status as u8), any::<u8>()],
        addr in 0u16..700,
        data in proptest::collection::vec(any::<u8>(), 0..48),
        len in 0u16..80,
        edits in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 0..3),
        pad in 0usize..4,
        cut in 0usize..3,
    ) {
        let len = if cmd == Command::Write as u8 { data.len() as u16 } else { len };
        let data = if cmd == Command::Write as u8 { &data[..] } else { &[][..] };
        let (addr, len) = if cmd == Command::Status as u8 { (0, 0) } else { (addr, len) };
        let mut rx = frame(cmd, 7, addr, len, data);
        rx.resize(rx.len() + pad, 0);
        for (i, v) in &edits {
            let i = i.index(rx.len());
            rx[i] = *v;
        }
        rx.truncate(rx.len() - cut.min(rx.len()));
        let (mut slave, mut dpm) = (SpiSlave::new(), busy_image());
        let before = dpm.clone();
        let mut reply = [0u8; MAX_REPLY];
        let n = slave.handle(&rx, &mut dpm, &mut reply);
        let r = SpiHostCodec::decode(&reply[..n]).unwrap();
        check_effect(&rx, &before, &dpm, r.result);
        if r.result == ResultCode::Ok && r.cmd == Command::Read as u8 {
            let a = usize::from(r.addr);
            prop_assert_eq!(r.data, &before.as_bytes()[a..a + r.data.len()]);
        }
    }

    #[test]
    fn host_block_writes_round_trip(block in 0usize..4, off in 0usize..144, data in proptest::collection::vec(any::<u8>(), 1..144)) {
        let b = host_blocks().nth(block).unwrap();
        let off = off % b.len;
        let n = data.len().min(b.len - off);
        let at = (b.start + off) as u16;
        let mut host = SpiHost::new(Loopback::new(busy_image()));
        host.write(at, &data[..n]).unwrap();
        let mut back = vec![0u8; n];
        host.read(at, &mut back).unwrap();
        prop_assert_eq!(&back[..], &data[..n]);
        prop_assert_eq!(&host.bus().dpm().as_bytes()[usize::from(at)..][..n], &data[..n]);
    }
}

/// `docs/SPI.md`: the byte-level specification of the module docs above, with every constant
/// it names resolved to its value, so a drive maker can integrate from `docs/` alone; the
/// example frames it quotes are checked here (CRC and the card's parser).
fn spi_markdown() -> String {
    let src = include_str!("../spi.rs");
    let consts: [(&str, String); 12] = [
        ("[`MAX_TRANSACTION`]", format!("{MAX_TRANSACTION}")),
        ("[`MAX_DATA`]", format!("{MAX_DATA}")),
        ("[`T_READY_US`]", format!("{T_READY_US}")),
        ("[`STATUS_LEN`]", format!("{STATUS_LEN}")),
        ("[`crc16`]", "CRC-16/CCITT-FALSE".to_string()),
        ("[`Command`]", "CMD".to_string()),
        ("[`ResultCode`]", "RESULT".to_string()),
        ("[`SpiStats`]", "the card's SPI counters".to_string()),
        ("[`SpiHost`]", "the reference host (`pbcard::dpm::spi::SpiHost`)".to_string()),
        ("`layout::BLOCKS`", "the block table of `docs/DPM.md`".to_string()),
        ("[`SpiHost::cyclic`]", "the reference host's `SpiHost::cyclic`".to_string()),
        ("[`cyclic`]", "the CYCLIC exchange below".to_string()),
    ];
    let mut out = String::from(
        "# DPM transport over SPI (board)\n\n\
         Generated from the module documentation of `crates/dpm/src/dpm/spi.rs` (constants resolved); \
         regenerate with\n`DPM_DOC_WRITE=1 cargo test -p pbcard-dpm --lib --target x86_64-unknown-linux-gnu \
         dpm::spi::tests::spi_doc_is_current`.\nThe image the frames address is `docs/DPM.md`.\n\n",
    );
    let mut on = false;
    for line in src.lines() {
        let Some(text) = line.strip_prefix("//!") else { break };
        let text = text.strip_prefix(' ').unwrap_or(text);
        if text.starts_with("# Byte-level specification") {
            on = true;
            out.push_str("## Byte-level specification (protocol version 2)\n");
            continue;
        }
        if on {
            let mut t = text.to_string();
            for (name, value) in &consts {
                t = t.replace(name, value);
            }
            out.push_str(&t);
            out.push('\n');
        }
    }
    out.push_str("\n## The CYCLIC exchange (protocol version 2)\n\n");
    for line in include_str!("cyclic.rs").lines() {
        let Some(text) = line.strip_prefix("//!") else { break };
        let text = text.strip_prefix(' ').unwrap_or(text);
        out.push_str(&text.replace("`SpiSlave::refresh`", "the card's refresh"));
        out.push('\n');
    }
    out
}

#[test]
fn spi_doc_is_current() {
    let doc = spi_markdown();
    assert!(!doc.contains("[`"), "an unresolved link in the SPI doc: {doc}");
    // The example frames the document quotes are valid requests with the CRC they show.
    let examples: Vec<Vec<u8>> = doc
        .split('`')
        .filter(|s| s.len() > 20 && s.split(' ').all(|h| h.len() == 2 && u8::from_str_radix(h, 16).is_ok()))
        .map(|s| s.split(' ').map(|h| u8::from_str_radix(h, 16).unwrap()).collect())
        .collect();
    assert_eq!(examples.len(), 3, "READ, WRITE, STATUS examples");
    for f in &examples {
        let n = f.len();
        assert_eq!(crc16(&f[..n - 2]).to_be_bytes(), [f[n - 2], f[n - 1]], "example CRC {f:02X?}");
        assert!(parse_request(f).is_ok(), "the card accepts the example {f:02X?}");
    }
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/SPI.md");
    if std::env::var_os("DPM_DOC_WRITE").is_some() {
        std::fs::write(path, &doc).unwrap();
    }
    let committed = std::fs::read_to_string(path).unwrap_or_default();
    assert!(
        committed == doc,
        "docs/SPI.md differs from crates/dpm/src/dpm/spi.rs; regenerate it with\n  \
         DPM_DOC_WRITE=1 cargo test -p pbcard-dpm --lib --target x86_64-unknown-linux-gnu dpm::spi::tests::spi_doc_is_current"
    );
}
