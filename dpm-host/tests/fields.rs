//! Every field of the map, written by one side and read back by the other through the
//! transport; opening checks (magic, version, size, capabilities).
//!
//! Each test runs twice (`over_both!`): `::memory` over the memory transport, `::spi` through
//! `SpiHost` over `Loopback` (the board's reply pipeline); an SPI run also proves that frames
//! crossed and none was refused.
//! The range checks are per transport: `MemoryTransport`'s and the SPI frames' own.

#[macro_use]
mod common;

use common::{Image, Via, Wire};
use dpm_host::layout::{self, cap, BLOCKS, FIELDS};
use dpm_host::*;
use pbcard::dp::DpState;
use pbcard::dpm::{CardEvent, Dpm, MailboxResponse, StatusFlags as DpmStatusFlags};
use pbcard::profile::param::{ErrorValue, Format, ParamError};

fn status() -> Status {
    Status {
        comm: CommState::ClearMode,
        baud: 3,
        station_address: 17,
        master_address: Some(2),
        telegram: Telegram::Ppo(5),
        dp_state: DpState::WaitCfg,
        flags: DpmStatusFlags::CLEAR | DpmStatusFlags::SYNC,
        watchdog_ms: 1234,
        data_exchanges: 0x0102_0304,
        prm_faults: 5,
        cfg_faults: 6,
        watchdog_expiries: 7,
        corrupt_frames: 8,
    }
}

fn bytes(n: usize, seed: u8) -> Vec<u8> {
    (0..n).map(|i| seed.wrapping_add(i as u8) | 1).collect()
}

fn command() -> DriveCommandImage {
    DriveCommandImage {
        command: DriveCommand {
            flags: CommandFlags::RUN | CommandFlags::FIELDBUS_CONTROL | CommandFlags::RAMP_SET_2,
            speed_setpoint: -1234,
            fault_resets: 9,
            comm_loss_reaction: 3,
        },
        operate_mode: layout::operate_mode::BYPASS,
        telegram: Telegram::Ppo(2),
        outputs_seq: 0,
        extra: PzdWords::new(&(1..=16).map(|i| 0x1100 + i).collect::<Vec<_>>()).unwrap(),
    }
}

fn state() -> DriveStateImage {
    DriveStateImage {
        status: DriveStatus {
            flags: StatusFlags::READY | StatusFlags::RUNNING | StatusFlags::WARNING,
            speed: 0x2000,
            current: -3,
            torque: 0x1234,
            power: 0x0FFF,
            fault_code: 0x2310,
            warning_code: 0x0042,
            namur: 0x0101,
        },
        inputs_seq: 0,
        extra: PzdWords::new(&(1..=16).map(|i| 0x2200 + i).collect::<Vec<_>>()).unwrap(),
    }
}

/// Field bytes that were non-zero in some snapshot, so each field is proven to carry data.
fn mark(seen: &mut [bool], img: &[u8]) {
    for (s, b) in seen.iter_mut().zip(img) {
        *s |= *b != 0;
    }
}

over_both! {
fn every_field_crosses_the_transport_both_ways(via) {
    let shared = Image::new(
        via,
        Dpm::with_identity(&Identity { serial: 0xCAFE_F00D, firmware: [1, 2, 3], ..pbcard::card::IDENTITY }),
    );
    let mut host = Host::open(shared.transport(), Options::DEFAULT).unwrap();
    let mut seen = vec![false; layout::IMAGE_SIZE];

    // Card → host.
    let st = status();
    let outs = ProcessData::new(Telegram::Ppo(5), PdFlags::DATA_EXCHANGE | PdFlags::CLEAR, &bytes(64, 0x30));
    let mut report = CardReport {
        heartbeat: 0x0A0B,
        flags: CardFlags::all(),
        config_result: 2,
        config_ack: 0x0C0D,
        events: [1, 2, 3, 4, 5, 6, 7, 8],
        drive_losses: 0x1112,
        late_responses: 0x1314,
        mailbox_timeouts: 0x1516,
        boot_id: 0x1718,
    };
    let values = ParamValues::new(Format::WORD, 64, &bytes(128, 0x40)).unwrap();
    let req = MailboxRequest { id: 0x0102, axis: 3, ..MailboxRequest::write(3, 0x0304, 0x0506, values) };
    let mut cmd = command();
    {
        let mut dpm = shared.borrow_mut();
        let mut card = dpm.card();
        card.write_status(&st);
        let oseq = card.write_outputs(&outs);
        card.write_card_report(&report);
        card.write_request(&req);
        cmd.outputs_seq = oseq;
        card.write_drive_command(&cmd);
    }
    assert_eq!(host.status(), Ok(st));
    assert_eq!(host.identity().unwrap().serial, 0xCAFE_F00D);
    assert_eq!(host.identity().unwrap(), shared.borrow_mut().identity());
    let out = host.read_outputs().unwrap();
    assert_eq!((out.telegram, out.flags, out.bytes()), (outs.telegram, outs.flags, outs.bytes()));
    assert_eq!(host.card_report(), Ok(report));
    assert_eq!(host.fetch_request(), Ok(Some(req)));
    let pi = host.read_process_data().unwrap();
    assert_eq!((pi.command, pi.outputs.seq), (cmd, cmd.outputs_seq));
    assert_eq!(host.read_command().unwrap().1, cmd);
    mark(&mut seen, shared.borrow_mut().as_bytes());

    // Host → card.
    let ins = ProcessData::new(Telegram::Ppo(5), PdFlags::from_bits_retain(0xA5), &bytes(64, 0x50));
    let cfg = HostConfig {
        station_address: 33,
        profile: 1,
        operate_mode: 2,
        comm_loss_reaction: 4,
        telegram: Telegram::Standard(20),
        comm_loss_delay_ms: 0x0708,
        pzd_out_map: [1, 2, 3, 4, 5, 6, 7, 8],
        pzd_in_map: [9, 10, 11, 12, 13, 14, 15, 16],
        io_update_delay: 0x0123,
    };
    host.set_fault(0x7510);
    host.set_warning(0x1234);
    host.set_ext_diag(&bytes(32, 0x60)).unwrap();
    assert_eq!(host.set_ext_diag(&[1; 33]), Err(Error::TooLong));
    host.set_irq_mask(0x0426);
    host.poll(Instant::from_millis(1));
    let cfg_seq = host.write_config(&cfg).unwrap();
    let (iseq, sseq) = host.write_process_data(&ins, &state()).unwrap();
    host.respond(0x0102, Ok(values)).unwrap();
    let mut serial = [0u8; 16];
    serial.copy_from_slice(&bytes(16, 0x70));
    let device = pbcard::dpv1::im::DeviceIdent { serial_number: serial, hardware_revision: 0x0A0B };
    let dseq = host.write_device_ident(&device).unwrap();
    {
        let dpm = shared.borrow_mut();
        let back = dpm.inputs().unwrap();
        assert_eq!((back.seq, back.telegram, back.flags, back.bytes()), (iseq, ins.telegram, ins.flags, ins.bytes()));
        let d = dpm.drive_report().unwrap();
        assert_eq!(
            (d.heartbeat, d.fault_code, d.warning_code, d.fault_count, d.warning_count),
            (1, 0x7510, 0x1234, 1, 1)
        );
        assert_eq!(d.ext_diag(), &bytes(32, 0x60)[..]);
        assert_eq!(dpm.config(), Ok((cfg_seq, cfg)));
        assert_eq!(dpm.drive_state(), Ok((sseq, DriveStateImage { inputs_seq: iseq, ..state() })));
        assert_eq!(dpm.response(), Ok((1, MailboxResponse { id: 0x0102, outcome: Ok(values) })));
        assert_eq!(dpm.device_ident(), Ok((dseq, device)));
    }
    mark(&mut seen, shared.borrow_mut().as_bytes());
    // The error variant of the response carries ERROR / ERROR_INFO / HAS_INFO.
    let err = ParamError { value: ErrorValue::LIMIT_EXCEEDED, additional_info: Some(0x0A0B) };
    host.respond(0x0102, Err(err)).unwrap();
    assert_eq!(shared.borrow_mut().response().unwrap().1.outcome, Err(err));
    mark(&mut seen, shared.borrow_mut().as_bytes());

    // Every field that is not reserved carried a non-zero byte somewhere, in its place.
    for f in FIELDS.iter().filter(|f| f.ty != "reserved") {
        assert!(seen[f.offset..f.offset + f.size].iter().any(|&b| b), "{} never crossed", f.name);
    }
    // And every reserved byte stayed 0.
    let img = *shared.borrow_mut().as_bytes();
    for f in FIELDS.iter().filter(|f| f.ty == "reserved") {
        assert!(img[f.offset..f.offset + f.size].iter().all(|&b| b == 0), "{}", f.name);
    }
    // Events seen as counters.
    report.events[CardEvent::Watchdog as usize] = report.events[CardEvent::Watchdog as usize].wrapping_add(2);
    let _ = host.poll(Instant::from_millis(2));
    shared.borrow_mut().card().write_card_report(&report);
    let p = host.poll(Instant::from_millis(3));
    assert_eq!(p.events.iter().collect::<Vec<_>>(), vec![CardEvent::Watchdog]);
    assert_eq!(p.events.count(CardEvent::Watchdog), 2);
    shared.assert_frames_crossed();
}
}

/// The host on `dpm` through the transport `via`.
fn open(via: Via, dpm: Dpm, opts: Options) -> Result<Host<Wire>, OpenError> {
    Host::open(Image::new(via, dpm).transport(), opts)
}

over_both! {
fn open_checks_magic_version_size_and_capabilities(via) {
    let dpm = Dpm::new();
    let host = open(via, dpm, Options::DEFAULT).unwrap();
    assert_eq!(*host.header(), codec::Header::THIS_LAYOUT);
    assert!(host.has(cap::ALL));

    let mut bad = Dpm::new();
    bad.as_bytes_mut()[0] = b'X';
    assert!(matches!(open(via, bad.clone(), Options::DEFAULT), Err(OpenError::BadMagic(_))));

    let mut v0 = Dpm::new();
    v0.as_bytes_mut()[layout::header::LAYOUT_VERSION + 1] = 0;
    assert_eq!(open(via, v0.clone(), Options::DEFAULT).err(), Some(OpenError::BadVersion(0)));

    let mut small = Dpm::new();
    small.as_bytes_mut()[layout::header::IMAGE_SIZE..][..2].copy_from_slice(&624u16.to_be_bytes());
    assert_eq!(
        open(via, small.clone(), Options::DEFAULT).err(),
        Some(OpenError::BadImageSize { version: 4, size: 624 })
    );

    // A version-2 card (624 bytes, no DRIVE_CMD / DRIVE_STATE): opens, and says what it lacks.
    let mut v2 = Dpm::new();
    let b = v2.as_bytes_mut();
    b[layout::header::LAYOUT_VERSION..][..2].copy_from_slice(&2u16.to_be_bytes());
    b[layout::header::IMAGE_SIZE..][..2].copy_from_slice(&624u16.to_be_bytes());
    b[layout::header::CAPABILITIES..][..4].copy_from_slice(&0x1Fu32.to_be_bytes());
    let mut h = open(via, v2.clone(), Options::DEFAULT).unwrap();
    assert_eq!(h.read_command().err(), Some(Error::NotSupported(cap::DRIVE_CMD)));
    assert!(h.status().is_ok());
    let need = Options { required: cap::DRIVE_CMD | cap::MAILBOX, ..Options::DEFAULT };
    assert_eq!(
        open(via, v2.clone(), need).err(),
        Some(OpenError::MissingCapabilities(cap::DRIVE_CMD))
    );

    // A version-1 card: no capability word, only STATUS / OUTPUTS / INPUTS.
    let mut v1 = Dpm::new();
    let b = v1.as_bytes_mut();
    b[layout::header::LAYOUT_VERSION..][..2].copy_from_slice(&1u16.to_be_bytes());
    b[layout::header::IMAGE_SIZE..][..2].copy_from_slice(&0xC0u16.to_be_bytes());
    let mut h = open(via, v1.clone(), Options::DEFAULT).unwrap();
    assert_eq!(h.header().capabilities, 0);
    assert!(h.card_report().is_err() && h.read_outputs().is_ok());

    // A transport that fails.
    struct Dead;
    impl Transport for Dead {
        fn read(&mut self, _: u16, _: &mut [u8]) -> Result<(), TransportError> {
            Err(TransportError::NoResponse)
        }
        fn write(&mut self, _: u16, _: &[u8]) -> Result<(), TransportError> {
            Err(TransportError::NoResponse)
        }
    }
    assert_eq!(Host::open(Dead, Options::DEFAULT).err(), Some(OpenError::Transport(TransportError::NoResponse)));
    // An SPI bus that fails, and an absent card (MISO pulled up: `0xFF`, never a reply).
    struct DeadBus(Option<u8>);
    impl spi::SpiBus for DeadBus {
        fn transfer(&mut self, _: &[u8], miso: &mut [u8]) -> Result<(), spi::BusFault> {
            miso.fill(self.0.ok_or(spi::BusFault)?);
            Ok(())
        }
    }
    for bus in [DeadBus(None), DeadBus(Some(0xFF)), DeadBus(Some(0))].into_iter().filter(|_| via == Via::Spi) {
        assert_eq!(
            Host::open(spi::SpiHost::new(bus), Options::DEFAULT).err(),
            Some(OpenError::Transport(TransportError::NoResponse))
        );
    }
}
}

over_both! {
/// A host that restarts on the same card (over SPI: a new `SpiHost`, its TAGs from 0 again,
/// behind the card's pipeline that may still hold a reply for the old one).
fn a_restarted_host_continues_the_counters(via) {
    let shared = Image::new(via, Dpm::new());
    let mut h = Host::open(shared.transport(), Options::DEFAULT).unwrap();
    let s1 = h.write_config(&HostConfig::DEFAULT).unwrap();
    let i1 = h.write_inputs(&ProcessData::new(Telegram::Standard(1), PdFlags::empty(), &[0; 4])).unwrap();
    h.poll(Instant::from_millis(0));
    drop(h);
    let mut h = Host::open(shared.transport(), Options::DEFAULT).unwrap();
    assert_eq!(h.write_config(&HostConfig::DEFAULT), Ok(s1 + 1), "a new number: the card takes it as new");
    assert_eq!(h.write_inputs(&ProcessData::new(Telegram::Standard(1), PdFlags::empty(), &[0; 4])), Ok(i1 + 1));
    h.poll(Instant::from_millis(1));
    assert_eq!(shared.borrow_mut().drive_report().unwrap().heartbeat, 2, "the heartbeat goes on changing");
    shared.assert_frames_crossed();
}
}

#[test]
fn memory_transport_refuses_ranges_outside_the_image() {
    let mut t = MemoryTransport::new([0u8; 16]);
    assert_eq!(t.write(10, &[1; 6]), Ok(()));
    assert_eq!(t.write(11, &[1; 6]), Err(TransportError::OutOfRange));
    let mut b = [0u8; 4];
    assert_eq!(t.read(u16::MAX, &mut b), Err(TransportError::OutOfRange));
    assert_eq!(t.read(12, &mut b), Ok(()));
    assert_eq!(b, [1; 4]);
    let blocks: usize = BLOCKS.iter().map(|b| b.len).sum();
    assert_eq!(blocks, layout::IMAGE_SIZE);
}

/// The SPI frames as the transport: a range beyond the image is BAD_ADDRESS (or does not fit
/// a frame), a write to a block the card writes is FORBIDDEN_WRITE; neither changes a byte.
#[test]
fn spi_transport_refuses_ranges_outside_the_image_and_the_cards_blocks() {
    let mut t = spi::SpiHost::new(spi::Loopback::new(Dpm::new()));
    let before = *t.dpm().as_bytes();
    let end = layout::IMAGE_SIZE as u16;
    assert_eq!(Transport::write(&mut t, end - 4, &[1; 6]), Err(TransportError::OutOfRange));
    assert_eq!(Transport::write(&mut t, layout::status::START as u16, &[1; 2]), Err(TransportError::Refused));
    let mut b = [0u8; 4];
    assert_eq!(Transport::read(&mut t, u16::MAX, &mut b), Err(TransportError::OutOfRange));
    assert_eq!(Transport::read(&mut t, end - 2, &mut b), Err(TransportError::OutOfRange));
    assert_eq!(t.dpm().as_bytes(), &before, "nothing written");
    assert_eq!(Transport::read(&mut t, end - 4, &mut b), Ok(()));
    assert_eq!(b, before[layout::IMAGE_SIZE - 4..]);
    let s = t.bus().slave().stats();
    assert_eq!((s.bad_address, s.forbidden_writes), (2, 1), "u16::MAX is refused by the host, never sent");
}
