//! The parameter mailbox between the card's `Link` (pbcard) and the `Host`: answers, the
//! drive's errors, timeouts, late answers never taken for the next request.
//!
//! Each test runs twice (`over_both!`): `::memory` over the memory transport, `::spi` through
//! `SpiHost` over `Loopback` (the board's reply pipeline); an SPI run also proves that frames
//! crossed and none was refused.

#[macro_use]
mod common;

use common::{Card, Wire};
use dpm_host::*;
use pbcard::dpm::mailbox::{DRIVE_LOST_ERROR, TIMEOUT_ERROR};
use pbcard::profile::param::{ErrorValue, Format, ParamError};
use pbcard::testkit::FakeDrive;

fn words(v: &ParamValues) -> Vec<u16> {
    v.bytes().chunks(2).map(|w| u16::from_be_bytes([w[0], w[1]])).collect()
}

/// The card asks, the host serves from its table, the card takes the answer.
fn ask(
    card: &mut Card,
    host: &mut Host<Wire>,
    t: &mut FakeDrive,
    req: MailboxRequest,
) -> Result<ParamValues, ParamError> {
    let id = card.0.app.link.submit_parameter(card.0.now, &req, &mut card.0.app.dpm.borrow_mut()).unwrap();
    card.cycle(1);
    assert_eq!(card.app.link.take_parameter_response(), None, "not answered yet");
    assert_eq!(host.serve_parameters(&mut Table(t)), Ok(Some(id)));
    assert_eq!(host.serve_parameters(&mut Table(t)), Ok(None), "each request once");
    card.cycle(1);
    let (got, out) = card.app.link.take_parameter_response().unwrap();
    assert_eq!(got, id);
    out
}

over_both! {
fn reads_writes_and_the_drives_errors(via) {
    let mut card = Card::via(via);
    let mut host = Host::open(card.transport(), Options::DEFAULT).unwrap();
    let mut t = FakeDrive::new();
    let v = ask(&mut card, &mut host, &mut t, MailboxRequest::read(1, 100, 1, 2)).unwrap();
    assert_eq!((v.format, words(&v)), (Format::WORD, vec![2, 3]));
    let w = ParamValues::new(Format::WORD, 2, &[0x01, 0x00, 0x02, 0x00]).unwrap();
    assert_eq!(ask(&mut card, &mut host, &mut t, MailboxRequest::write(1, 100, 2, w)), Ok(ParamValues::NONE));
    assert_eq!(t.p100, [1, 2, 0x100, 0x200]);
    let big = ParamValues::new(Format::WORD, 1, &[0x10, 0x00]).unwrap();
    assert_eq!(
        ask(&mut card, &mut host, &mut t, MailboxRequest::write(1, 100, 0, big)),
        Err(ParamError { value: ErrorValue::LIMIT_EXCEEDED, additional_info: Some(0) })
    );
    assert_eq!(
        ask(&mut card, &mut host, &mut t, MailboxRequest::read(1, 999, 0, 1)),
        Err(ErrorValue::IMPERMISSIBLE_PARAMETER_NUMBER.into())
    );
    assert_eq!(
        ask(&mut card, &mut host, &mut t, MailboxRequest::read(4, 100, 0, 1)),
        Err(ErrorValue::AXIS_NONEXISTENT.into())
    );
    assert_eq!(
        ask(&mut card, &mut host, &mut t, MailboxRequest::read_description(1, 100, 1)),
        Err(ErrorValue::NO_DESCRIPTION.into())
    );
    // A closure as the server.
    let id =
        card.0.app.link.submit_parameter(card.0.now, &MailboxRequest::read(1, 7, 0, 1), &mut card.0.app.dpm.borrow_mut()).unwrap();
    let mut f = |r: &MailboxRequest| {
        Answer::Now(ParamValues::new(Format::WORD, 1, &r.pnu.to_be_bytes()).ok_or(ErrorValue::NOT_EXECUTABLE.into()))
    };
    assert_eq!(host.serve_parameters(&mut f), Ok(Some(id)));
    card.cycle(1);
    assert_eq!(card.app.link.take_parameter_response().map(|(i, v)| (i, words(&v.unwrap()))), Some((id, vec![7])));
    let s = host.stats();
    assert_eq!((s.requests, s.responses, s.stale_responses), (7, 7, 0));
    assert_eq!(card.app.link.mailbox().stats().late_responses, 0);
}
}

over_both! {
fn timeout_then_late_answer_is_refused_and_never_taken_for_the_next_request(via) {
    let mut card = Card::via(via);
    card.app.link.set_mailbox_timeout(Duration::from_millis(100));
    let mut host = Host::open(card.transport(), Options::DEFAULT).unwrap();
    let id1 =
        card.0.app.link.submit_parameter(card.0.now, &MailboxRequest::read(1, 100, 0, 1), &mut card.0.app.dpm.borrow_mut()).unwrap();
    // The drive takes it but answers later.
    let mut slow = |_: &MailboxRequest| Answer::Later;
    assert_eq!(host.serve_parameters(&mut slow), Ok(Some(id1)));
    assert_eq!(host.open_request(), Some(id1));
    card.cycle(99);
    assert_eq!(card.app.link.take_parameter_response(), None);
    card.cycle(1);
    assert_eq!(card.app.link.take_parameter_response(), Some((id1, Err(TIMEOUT_ERROR))), "0x11 / 0xDD01, never a hang");
    // The card asks the next thing; then the drive's late answer to the first arrives.
    let id2 =
        card.0.app.link.submit_parameter(card.0.now, &MailboxRequest::read(1, 200, 0, 1), &mut card.0.app.dpm.borrow_mut()).unwrap();
    assert_ne!(id2, id1);
    let late = ParamValues::new(Format::WORD, 1, &[0, 42]).unwrap();
    assert_eq!(host.respond(id1, Ok(late)), Err(Error::StaleResponse { id: id1, current: id2 }));
    assert_eq!(host.open_request(), None);
    card.cycle(1);
    assert_eq!(card.app.link.take_parameter_response(), None, "nothing taken for the second request");
    // The real answer to the second.
    let mut t = FakeDrive { p100: [0; 4], ..FakeDrive::new() };
    assert_eq!(host.serve_parameters(&mut Table(&mut t)), Ok(Some(id2)));
    card.cycle(1);
    let (id, v) = card.app.link.take_parameter_response().unwrap();
    assert_eq!((id, words(&v.unwrap())), (id2, vec![0xBEEF]));
    assert_eq!(host.stats().stale_responses, 1);
}
}

over_both! {
fn a_late_answer_with_no_new_request_is_ignored_by_the_card(via) {
    let mut card = Card::via(via);
    card.app.link.set_mailbox_timeout(Duration::from_millis(50));
    let mut host = Host::open(card.transport(), Options::DEFAULT).unwrap();
    let id =
        card.0.app.link.submit_parameter(card.0.now, &MailboxRequest::read(1, 100, 0, 1), &mut card.0.app.dpm.borrow_mut()).unwrap();
    assert_eq!(host.fetch_request().unwrap().map(|r| r.id), Some(id));
    card.cycle(60);
    assert_eq!(card.app.link.take_parameter_response(), Some((id, Err(TIMEOUT_ERROR))));
    // Still the card's current request in MBX_REQ: the host may write it; the card ignores it.
    host.respond(id, Ok(ParamValues::NONE)).unwrap();
    card.cycle(1);
    assert_eq!(card.app.link.take_parameter_response(), None);
    assert_eq!(card.app.link.mailbox().stats().late_responses, 1);
    card.cycle(1);
    assert_eq!(host.poll(card.now).report.unwrap().late_responses, 1, "the host sees the card's counters");
}
}

over_both! {
fn requests_while_the_drive_is_lost_are_answered_by_the_card(via) {
    let mut card = Card::via(via);
    card.app.link.set_drive_timeout(Duration::from_millis(30));
    let mut host = Host::open(card.transport(), Options::DEFAULT).unwrap();
    host.poll(card.now);
    card.cycle(10);
    card.cycle(40);
    assert!(card.app.link.drive_lost());
    let id =
        card.0.app.link.submit_parameter(card.0.now, &MailboxRequest::read(1, 100, 0, 1), &mut card.0.app.dpm.borrow_mut()).unwrap();
    assert_eq!(card.app.link.take_parameter_response(), Some((id, Err(DRIVE_LOST_ERROR))));
    assert_eq!(host.fetch_request(), Ok(None), "not even written to the drive");
}
}
