use super::*;
use proptest::prelude::*;

#[test]
fn fresh_image_has_header_and_inactive_status() {
    let dpm = Dpm::new();
    let b = dpm.as_bytes();
    assert_eq!(&b[0..4], b"PBDM");
    assert_eq!(&b[4..8], &[0x00, 0x04, 0x02, 0xF0], "version 4, 752 bytes, big-endian");
    assert_eq!(
        &b[8..12],
        &[0, 0, 0, 0xFF],
        "capabilities: ident, card, drive, config, mailbox, drive cmd / state, device"
    );
    assert_eq!((dpm.layout_version(), dpm.capabilities()), (4, layout::cap::ALL));
    let id = dpm.identity();
    assert_eq!((id.card_type, id.ident_number, id.serial), (CARD_TYPE, 0, 0), "no product's ident yet");
    let id = Dpm::with_identity(&Identity::of_product(0x0F11)).identity();
    assert_eq!((id.card_type, id.ident_number, id.serial), (CARD_TYPE, 0x0F11, 0));
    assert_eq!(id.firmware, [0, 1, 0], "Cargo.toml version 0.1.0");
    assert_eq!(dpm.card_report().unwrap(), CardReport::default(), "never written: all zero, seq 0");
    assert_eq!(dpm.request(), Ok(None));
    assert_eq!(dpm.config().unwrap().0, 0);
    let s = dpm.status().unwrap();
    assert_eq!(s, Status::INACTIVE);
    assert_eq!(b[layout::status::START + layout::status::BAUD], 5, "P0963 5 = not detected");
    assert_eq!(dpm.outputs().unwrap().seq, 0);
    assert_eq!(dpm.inputs().unwrap().seq, 0);
}

#[test]
fn p0740_codes_are_the_manuals() {
    // CFW500 manual, P0740 (Table 4.5).
    let codes: [(CommState, u8); 7] = [
        (CommState::Inactive, 0),
        (CommState::InitError, 1),
        (CommState::Offline, 2),
        (CommState::ConfigError, 3),
        (CommState::ParameterError, 4),
        (CommState::ClearMode, 5),
        (CommState::Online, 6),
    ];
    for (s, c) in codes {
        assert_eq!(s.code(), c);
        assert_eq!(CommState::from_code(c), Some(s));
    }
    assert_eq!(CommState::from_code(7), None);
}

#[test]
fn p0963_round_trip() {
    assert_eq!(p0963(None), 5);
    for r in Baudrate::ALL {
        assert_eq!(baudrate_from_p0963(p0963(Some(r))), Some(r));
    }
    assert_eq!(baudrate_from_p0963(5), None);
    assert_eq!(baudrate_from_p0963(10), None);
}

#[test]
fn status_round_trip_and_byte_positions() {
    let s = Status {
        comm: CommState::Online,
        baud: Baudrate::B1500k.p0963_code(),
        station_address: 5,
        master_address: Some(2),
        telegram: Telegram::Standard(1),
        dp_state: crate::dp::DpState::DataExch,
        flags: StatusFlags::WATCHDOG_ON,
        watchdog_ms: 100,
        data_exchanges: 0x0102_0304,
        prm_faults: 1,
        cfg_faults: 2,
        watchdog_expiries: 3,
        corrupt_frames: 4,
    };
    let mut dpm = Dpm::new();
    let seq = dpm.card().write_status(&s);
    assert_eq!(seq, 1);
    assert_eq!(dpm.host().read_status(), Ok(s));
    let b = &dpm.as_bytes()[layout::status::START..layout::status::START + layout::status::LEN];
    assert_eq!(
        b,
        &[
            0x00, 0x01, // SEQ_HEAD
            6, 6, 5, 2, // P0740 online, P0963 1.5M, address, master
            0x00, 0x01, 2, 0x08, // telegram 1, Data_Exch, WD on
            0x00, 100, 0x01, 0x02, 0x03, 0x04, // watchdog ms, Data_Exchange count
            0, 1, 0, 2, 0, 3, 0, 4, // counters
            0, 0, 0, 0, 0, 0, // reserved
            0x00, 0x01, // SEQ_TAIL
        ]
    );
}

#[test]
fn process_data_round_trip_and_sequence() {
    let mut dpm = Dpm::new();
    let out = ProcessData::new(Telegram::Standard(1), PdFlags::DATA_EXCHANGE, &[0x04, 0x7F, 0x40, 0x00]);
    assert_eq!(dpm.card().write_outputs(&out), 1);
    assert_eq!(dpm.card().write_outputs(&out), 2);
    let got = dpm.host().read_outputs().unwrap();
    assert_eq!((got.seq, got.telegram, got.flags), (2, Telegram::Standard(1), PdFlags::DATA_EXCHANGE));
    assert_eq!((got.word(0), got.word(1), got.word(2)), (0x047F, 0x4000, 0));
    let inp = ProcessData::new(Telegram::Standard(1), PdFlags::empty(), &[0x02, 0x37, 0x3F, 0xFF]);
    assert_eq!(dpm.host().write_inputs(&inp), 1);
    let got = dpm.card().read_inputs().unwrap();
    assert_eq!(got.bytes(), inp.bytes());
}

#[test]
fn sequence_wraps_past_zero() {
    let mut dpm = Dpm::new();
    let start = layout::outputs::START;
    dpm.as_bytes_mut()[start..start + 2].copy_from_slice(&[0xFF, 0xFF]);
    let pd = ProcessData::new(Telegram::None, PdFlags::empty(), &[]);
    assert_eq!(dpm.card().write_outputs(&pd), 1, "0 stays 'never written'");
}

#[test]
fn half_written_blocks_are_torn() {
    let mut dpm = Dpm::new();
    let pd = ProcessData::new(Telegram::Standard(1), PdFlags::DATA_EXCHANGE, &[1, 2, 3, 4]);
    dpm.card().write_outputs(&pd);
    // The card starts the next write: tail first. The host sees head 1, tail 2.
    let tail = layout::outputs::START + layout::pd::SEQ_TAIL;
    dpm.as_bytes_mut()[tail + 1] = 2;
    assert_eq!(dpm.host().read_outputs(), Err(Torn { head: 1, tail: 2 }));
    // The host starts writing inputs: head first. The card sees head 1, tail 0.
    let head = layout::inputs::START + layout::pd::SEQ_HEAD;
    dpm.as_bytes_mut()[head + 1] = 1;
    assert_eq!(dpm.card().read_inputs(), Err(Torn { head: 1, tail: 0 }));
}

/// One byte access of a model writer or reader.
#[derive(Debug, Clone, Copy)]
enum Access {
    Write(usize, u8),
    Read(usize),
}

/// The accesses of a write of `new` (a whole block, counters included) over `old` in the
/// order the rule prescribes: host = ascending; card = tail, payload, head.
fn write_order(new: &[u8], card: bool) -> Vec<Access> {
    let n = new.len();
    let idx: Vec<usize> = if card { (n - 2..n).chain(2..n - 2).chain(0..2).collect() } else { (0..n).collect() };
    idx.into_iter().map(|i| Access::Write(i, new[i])).collect()
}

fn read_order(n: usize, card: bool) -> Vec<Access> {
    let idx: Vec<usize> = if card { (n - 2..n).chain(2..n - 2).chain(0..2).collect() } else { (0..n).collect() };
    idx.into_iter().map(Access::Read).collect()
}

fn block(seq: u16, fill: u8, n: usize) -> Vec<u8> {
    let mut b = vec![fill; n];
    b[..2].copy_from_slice(&seq.to_be_bytes());
    b[n - 2..].copy_from_slice(&seq.to_be_bytes());
    b
}

proptest! {
    /// The rule of the module documentation, byte by byte: for every interleaving of one
    /// writer (host or card) with one reader (the other side), a reader that finds equal
    /// counters has read one write's payload entirely — old or new, never a mix.
    #[test]
    fn seqlock_model(
        card_writes in any::<bool>(),
        seq in any::<u16>(),
        n in 6usize..12,
        schedule in proptest::collection::vec(any::<bool>(), 0..40),
    ) {
        let next = next_seq(seq);
        let (old, new) = (block(seq, 0x11, n), block(next, 0x22, n));
        let mut mem = old.clone();
        let mut w = write_order(&new, card_writes).into_iter().peekable();
        let mut r = read_order(n, !card_writes).into_iter().peekable();
        let mut seen = vec![0u8; n];
        let mut pick = schedule.into_iter();
        while w.peek().is_some() || r.peek().is_some() {
            let writer_turn = match (w.peek(), r.peek()) {
                (Some(_), Some(_)) => pick.next().unwrap_or(true),
                (Some(_), None) => true,
                _ => false,
            };
            let acc = if writer_turn { w.next() } else { r.next() };
            match acc.unwrap() {
                Access::Write(i, v) => mem[i] = v,
                Access::Read(i) => seen[i] = mem[i],
            }
        }
        let head = u16::from_be_bytes([seen[0], seen[1]]);
        let tail = u16::from_be_bytes([seen[n - 2], seen[n - 1]]);
        if head == tail {
            let payload = &seen[2..n - 2];
            prop_assert!(payload.iter().all(|&b| b == 0x11) || payload.iter().all(|&b| b == 0x22),
                "consistent counters {head} but a mixed payload {payload:?}");
            prop_assert!((head == seq && payload[0] == 0x11) || (head == next && payload[0] == 0x22));
        }
    }

    /// Whatever the host leaves in the image, the card's reads never panic and stay in bounds.
    #[test]
    fn card_reads_any_image(bytes in proptest::collection::vec(any::<u8>(), IMAGE_SIZE)) {
        let mut dpm = Dpm::new();
        dpm.as_bytes_mut().copy_from_slice(&bytes);
        if let Ok(pd) = dpm.card().read_inputs() {
            prop_assert!(pd.bytes().len() <= layout::PD_CAPACITY);
        }
        let _ = dpm.host().read_status();
        let _ = dpm.host().read_outputs();
    }

    #[test]
    fn process_data_round_trips(
        code in any::<u16>(),
        flags in any::<u8>(),
        data in proptest::collection::vec(any::<u8>(), 0..80),
    ) {
        let t = Telegram::from_code(code);
        let pd = ProcessData::new(t, PdFlags::from_bits_retain(flags), &data);
        let mut dpm = Dpm::new();
        let seq = dpm.host().write_inputs(&pd);
        let got = dpm.card().read_inputs().unwrap();
        prop_assert_eq!(got.seq, seq);
        prop_assert_eq!(got.bytes(), &data[..data.len().min(layout::PD_CAPACITY)]);
        prop_assert_eq!(got.telegram, t);
    }
}
