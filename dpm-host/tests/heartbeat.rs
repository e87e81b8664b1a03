//! Heartbeats both ways: the card's `Link` watches the host's DRIVE.HEARTBEAT (lost: ZSW1
//! fault to the master, Stat_Diag, CARD.FLAGS, DriveReturned event); the host watches
//! CARD.HEARTBEAT (lost = the A140 situation, reported once; also when the link dies).
//!
//! Each test runs twice (`over_both!`): `::memory` over the memory transport, `::spi` through
//! `SpiHost` over `Loopback` (the board's reply pipeline); an SPI run also proves that frames
//! crossed and none was refused.
//! The dead link is cut above the transport (`Cuttable`), the same cut over both.

#[macro_use]
mod common;

use common::{Card, Wire};
use dpm_host::*;
use pbcard::dp::diag::Status2;
use pbcard::dpm::CardEvent;

over_both! {
fn drive_heartbeat_loss_is_seen_by_the_card_and_its_return_by_the_host(via) {
    let mut card = Card::via(via);
    card.app.link.set_drive_timeout(Duration::from_millis(50));
    card.bring_up();
    let mut host = Host::open(card.transport(), Options::DEFAULT).unwrap();
    let inputs = ProcessData::new(Telegram::Standard(1), PdFlags::empty(), &[0x02, 0x37, 0x00, 0x10]);
    for _ in 0..5 {
        host.poll(card.now);
        host.write_inputs(&inputs).unwrap();
        card.cycle(10);
    }
    assert_eq!(card.data_exchange(&[0x04, 0x7F, 0, 0]), [0x02, 0x37, 0x00, 0x10]);
    assert!(!card.app.link.drive_lost());
    // The drive stops (no poll): after 50 ms the card counts it lost.
    for _ in 0..5 {
        card.cycle(10);
    }
    assert!(!card.app.link.drive_lost(), "50 ms is not over yet");
    card.cycle(10);
    assert!(card.app.link.drive_lost());
    assert_eq!(card.data_exchange(&[0x04, 0x7F, 0, 0]), [0x00, 0x08, 0x00, 0x00], "ZSW1 fault to the master");
    assert!(card.node.slave().standard_diag().status2.contains(Status2::STAT_DIAG));
    card.cycle(1);
    let r = host.card_report().unwrap();
    assert!(r.flags.contains(CardFlags::DRIVE_LOST));
    assert_eq!(r.drive_losses, 1);
    // The drive comes back: the card serves its inputs again and raises DriveReturned.
    let p = host.poll(card.now);
    assert!(p.events.is_empty() || !p.events.contains(CardEvent::DriveReturned));
    host.write_inputs(&inputs).unwrap();
    card.cycle(1);
    card.cycle(1);
    assert!(!card.app.link.drive_lost());
    let p = host.poll(card.now);
    assert!(p.events.contains(CardEvent::DriveReturned));
    assert!(!p.report.unwrap().flags.contains(CardFlags::DRIVE_LOST));
    assert_eq!(card.data_exchange(&[0x04, 0x7F, 0, 0]), [0x02, 0x37, 0x00, 0x10]);
}
}

over_both! {
fn card_heartbeat_loss_is_reported_once_and_its_return_too(via) {
    let mut card = Card::via(via);
    let opts = Options { card_timeout: Duration::from_millis(30), ..Options::DEFAULT };
    let mut host = Host::open(card.transport(), opts).unwrap();
    let p = host.poll(card.now);
    assert_eq!(p.card, Liveness::Unknown, "the card has not started");
    for _ in 0..10 {
        card.cycle(10);
        let p = host.poll(card.now);
        assert_eq!((p.card, p.card_lost, p.card_returned), (Liveness::Alive, false, false));
    }
    // The card stops publishing (it still reads): its heartbeat freezes.
    card.collect_only(30);
    assert_eq!(host.poll(card.now).card, Liveness::Alive, "30 ms is not over yet");
    card.collect_only(1);
    let p = host.poll(card.now);
    assert_eq!((p.card, p.card_lost), (Liveness::Lost, true), "A140: card lost");
    card.collect_only(10);
    let p = host.poll(card.now);
    assert_eq!((p.card, p.card_lost), (Liveness::Lost, false), "reported once");
    assert_eq!(host.card_liveness(), Liveness::Lost);
    // It comes back.
    card.cycle(10);
    let p = host.poll(card.now);
    assert_eq!((p.card, p.card_returned), (Liveness::Alive, true));
    card.cycle(10);
    assert!(!host.poll(card.now).card_returned, "once");
    assert_eq!(host.stats().card_losses, 1);
}
}

/// A link that can be cut.
struct Cuttable(Wire, bool);

impl Transport for Cuttable {
    fn read(&mut self, offset: u16, buf: &mut [u8]) -> Result<(), TransportError> {
        if self.1 {
            return Err(TransportError::NoResponse);
        }
        self.0.read(offset, buf)
    }
    fn write(&mut self, offset: u16, data: &[u8]) -> Result<(), TransportError> {
        if self.1 {
            return Err(TransportError::Corrupt);
        }
        self.0.write(offset, data)
    }
}

over_both! {
fn a_dead_link_is_a_lost_card_and_a_lost_drive(via) {
    let mut card = Card::via(via);
    card.app.link.set_drive_timeout(Duration::from_millis(50));
    let opts = Options { card_timeout: Duration::from_millis(50), ..Options::DEFAULT };
    let mut host = Host::open(Cuttable(card.transport(), false), opts).unwrap();
    for _ in 0..3 {
        card.cycle(10);
        assert_eq!(host.poll(card.now).card, Liveness::Alive);
    }
    host.transport_mut().1 = true;
    let mut lost_at = None;
    for i in 0..10 {
        card.cycle(10);
        let p = host.poll(card.now);
        assert_eq!(p.error, Some(Error::Transport(TransportError::Corrupt)), "the DRIVE write failed first");
        if p.card_lost {
            lost_at = Some(i);
        }
    }
    // Last change seen at 30 ms; lost when more than 50 ms passed: at 90 ms, the sixth poll.
    assert_eq!(lost_at, Some(5), "lost once, after the timeout");
    assert!(card.app.link.drive_lost(), "and the card lost the drive");
    assert!(host.stats().transport_errors >= 20);
}
}
