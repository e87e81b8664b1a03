//! The DPM's card-side link on a node under the scripted master (moved from
//! `pbcard_dpm::dpm`'s `tests_v2`: they run this card's node and modules and the tests' fake
//! drive table, issue 13 item 4): configuration take-over, the parameter mailbox end to end,
//! heartbeat supervision both ways, card events.

use crate::card;
use crate::dp::diag::Status2;
use crate::dp::{DpSlave, DpState};
use crate::dpm::mailbox::{self, DRIVE_LOST_ERROR, TIMEOUT_ERROR};
use crate::dpm::*;
use crate::fdl::telegram::{FunctionCode, Header};
use crate::node::Node;
use crate::profile::param::{ErrorValue, Format, ParamError};
use crate::testkit::{self, Frame, Rig, ScriptedMaster, SetPrm};
use crate::time::{Duration, Instant};
// ---------------------------------------------------------------------------------------
// A node on a scripted bus

const MASTER: u8 = 2;
const SLAVE: u8 = 5;

struct Bench {
    node: Node,
    dpm: Dpm,
    link: Link,
    now: Instant,
    master: ScriptedMaster,
}

impl Bench {
    fn new() -> Self {
        Bench {
            node: crate::card::node(DpSlave::new(&crate::card::SLAVE, SLAVE)),
            dpm: Dpm::new(),
            link: Link::new(crate::card::MODULES),
            now: Instant::from_millis(0),
            master: ScriptedMaster::new(MASTER, SLAVE),
        }
    }

    /// One card cycle after `ms`, with `host` doing its part on the image in between.
    fn step(&mut self, ms: u64, host: impl FnOnce(&mut HostSide<'_>)) -> Events {
        self.now = self.now + Duration::from_millis(ms);
        let ev = self.node.poll(self.now);
        self.link.publish(&mut self.node, ev, &mut self.dpm);
        host(&mut self.dpm.host());
        self.link.collect(self.now, &mut self.node, &self.dpm);
        ev
    }

    fn bring_up(&mut self) {
        Rig::bring_up(self, &SetPrm::CARD, card::MODULES[0].cfg);
    }

    fn data_exchange(&mut self, out: &[u8]) -> Vec<u8> {
        Rig::data_exchange(self, out).to_vec()
    }
}

impl Rig for Bench {
    fn master(&mut self) -> &mut ScriptedMaster {
        &mut self.master
    }
    fn deliver(&mut self, frame: &[u8]) -> Option<Frame> {
        testkit::feed(&mut self.node, self.now, frame)
    }
    fn settle(&mut self) {
        self.step(1, |_| {});
    }
    fn dp_state(&self) -> DpState {
        self.node.slave().state()
    }
    fn input_len(&self) -> usize {
        self.node.slave().input_len()
    }
}

use crate::dp::Events;

// ---------------------------------------------------------------------------------------
// Configuration

#[test]
fn configuration_is_refused_in_data_exchange_and_taken_over_after() {
    let mut b = Bench::new();
    b.bring_up();
    let cfg = HostConfig {
        station_address: 9,
        telegram: Telegram::Standard(1),
        comm_loss_reaction: 1,
        comm_loss_delay_ms: 500,
        ..HostConfig::DEFAULT
    };
    let mut seq = 0;
    b.step(1, |h| seq = h.write_config(&cfg));
    b.step(1, |_| {});
    let r = b.dpm.card_report().unwrap();
    assert_eq!((r.config_ack, r.config_result()), (seq, ConfigResult::Pending));
    assert!(r.flags.contains(CardFlags::CONFIG_PENDING));
    assert_eq!(b.link.take_config(), None, "not taken over while in data exchange");
    // Still pending on later cycles.
    for _ in 0..3 {
        b.step(10, |_| {});
    }
    assert_eq!(b.link.config(), None);
    // The master stops: the DP watchdog (100 ms × ... from Set_Prm) expires, data exchange ends.
    let ev = b.step(2000, |_| {});
    assert!(ev.contains(Events::WATCHDOG_EXPIRED));
    assert_ne!(b.node.slave().state(), DpState::DataExch);
    b.step(1, |_| {});
    let r = b.dpm.card_report().unwrap();
    assert_eq!((r.config_ack, r.config_result()), (seq, ConfigResult::Accepted));
    assert!(!r.flags.contains(CardFlags::CONFIG_PENDING));
    assert_eq!(b.link.take_config(), Some(cfg));
    assert_eq!(b.link.take_config(), None, "once");
    assert!(r.event(CardEvent::Watchdog) >= 1 && r.event(CardEvent::Offline) >= 1 && r.event(CardEvent::Online) == 1);
    // An invalid configuration is refused at once.
    let bad = HostConfig { station_address: 200, ..cfg };
    b.step(1, |h| seq = h.write_config(&bad));
    b.step(1, |_| {});
    let r = b.dpm.card_report().unwrap();
    assert_eq!((r.config_ack, r.config_result()), (seq, ConfigResult::Refused));
    assert_eq!(b.link.config(), Some(&cfg));
}

#[test]
fn configuration_outside_data_exchange_is_taken_at_once() {
    let mut b = Bench::new();
    let cfg = HostConfig { station_address: 3, ..HostConfig::DEFAULT };
    b.step(1, |h| {
        h.write_config(&cfg);
    });
    b.step(1, |_| {});
    assert_eq!(b.dpm.card_report().unwrap().config_result(), ConfigResult::Accepted);
    assert_eq!(b.link.take_config(), Some(cfg));
}

// ---------------------------------------------------------------------------------------
// Parameter mailbox (over the tests' fake drive table, `testkit::FakeDrive`: PNU 100 u16[4] ≤ 1000,
// PNU 200 read-only 0xBEEF with a description)

use crate::testkit::FakeDrive;

fn words(v: &ParamValues) -> Vec<u16> {
    v.bytes().chunks(2).map(|w| u16::from_be_bytes([w[0], w[1]])).collect()
}

#[test]
fn mailbox_end_to_end_read_write_description_and_errors() {
    let mut dpm = Dpm::new();
    let mut mbx = Mailbox::default();
    let mut srv = MailboxServer::new();
    let mut drive = FakeDrive::new();
    let mut now = Instant::from_millis(0);
    let mut ask = |dpm: &mut Dpm, mbx: &mut Mailbox, req: MailboxRequest| {
        now = now + Duration::from_millis(5);
        let id = mbx.submit(now, &req, false, &mut dpm.card()).unwrap();
        assert_eq!(mbx.submit(now, &req, false, &mut dpm.card()), Err(MailboxBusy), "one at a time");
        mbx.poll(now, dpm);
        assert_eq!(mbx.take(), None, "no answer before the host served");
        assert_eq!(srv.serve(&mut dpm.host(), &mut drive), Some(id));
        assert_eq!(srv.serve(&mut dpm.host(), &mut drive), None, "each request once");
        mbx.poll(now, dpm);
        let (got, out) = mbx.take().unwrap();
        assert_eq!(got, id);
        out
    };
    let v = ask(&mut dpm, &mut mbx, MailboxRequest::read(1, 100, 1, 2)).unwrap();
    assert_eq!((v.format, v.count, words(&v)), (Format::WORD, 2, vec![2, 3]));
    let w = ParamValues::new(Format::WORD, 2, &[0x01, 0x00, 0x02, 0x00]).unwrap();
    assert_eq!(ask(&mut dpm, &mut mbx, MailboxRequest::write(1, 100, 2, w)), Ok(ParamValues::NONE));
    let v = ask(&mut dpm, &mut mbx, MailboxRequest::read(1, 100, 0, 4)).unwrap();
    assert_eq!(words(&v), vec![1, 2, 0x100, 0x200]);
    let bad = ParamValues::new(Format::WORD, 1, &[0x10, 0x00]).unwrap();
    assert_eq!(
        ask(&mut dpm, &mut mbx, MailboxRequest::write(1, 100, 0, bad)),
        Err(ParamError { value: ErrorValue::LIMIT_EXCEEDED, additional_info: Some(0) })
    );
    assert_eq!(
        ask(&mut dpm, &mut mbx, MailboxRequest::read(1, 999, 0, 1)),
        Err(ErrorValue::IMPERMISSIBLE_PARAMETER_NUMBER.into())
    );
    assert_eq!(ask(&mut dpm, &mut mbx, MailboxRequest::read(7, 100, 0, 1)), Err(ErrorValue::AXIS_NONEXISTENT.into()));
    let one = ParamValues::new(Format::WORD, 1, &[0, 1]).unwrap();
    assert_eq!(
        ask(&mut dpm, &mut mbx, MailboxRequest::write(1, 200, 0, one)),
        Err(ErrorValue::VALUE_CANNOT_BE_CHANGED.into())
    );
    let d = ask(&mut dpm, &mut mbx, MailboxRequest::read_description(1, 200, 1)).unwrap();
    assert_eq!(words(&d), vec![6]);
    assert_eq!(
        ask(&mut dpm, &mut mbx, MailboxRequest::read_description(1, 100, 1)),
        Err(ErrorValue::NO_DESCRIPTION.into())
    );
    assert_eq!(mbx.stats().responses, 9);
    assert_eq!(mbx.stats().timeouts + mbx.stats().late_responses, 0);
}

#[test]
fn mailbox_timeout_then_late_answer_is_not_taken_for_the_next_request() {
    let mut dpm = Dpm::new();
    let mut mbx = Mailbox::new(Duration::from_millis(100));
    let mut srv = MailboxServer::new();
    let t0 = Instant::from_millis(1000);
    let id1 = mbx.submit(t0, &MailboxRequest::read(1, 100, 0, 1), false, &mut dpm.card()).unwrap();
    // The host fetches it but is slow.
    let req1 = srv.fetch(&dpm.host()).unwrap();
    assert_eq!(req1.id, id1);
    mbx.poll(t0 + Duration::from_millis(99), &dpm);
    assert_eq!(mbx.take(), None);
    mbx.poll(t0 + Duration::from_millis(100), &dpm);
    assert_eq!(mbx.take(), Some((id1, Err(TIMEOUT_ERROR))), "timeout answers 0x11 / 0xDD01, never a hang");
    assert_eq!(TIMEOUT_ERROR.value, ErrorValue::NOT_EXECUTABLE);
    // The next request goes out; then the late answer to the first one arrives.
    let t1 = t0 + Duration::from_millis(200);
    let id2 = mbx.submit(t1, &MailboxRequest::read(1, 200, 0, 1), false, &mut dpm.card()).unwrap();
    assert_ne!(id2, id1);
    MailboxServer::respond(&mut dpm.host(), id1, Ok(ParamValues::new(Format::WORD, 1, &[0, 42]).unwrap()));
    mbx.poll(t1, &dpm);
    assert_eq!(mbx.take(), None, "a late answer is never taken for the next request");
    assert_eq!(mbx.stats().late_responses, 1);
    // The real answer to the second.
    assert_eq!(srv.serve(&mut dpm.host(), &mut FakeDrive { p100: [0; 4], ..FakeDrive::new() }), Some(id2));
    mbx.poll(t1 + Duration::from_millis(1), &dpm);
    let (id, v) = mbx.take().unwrap();
    assert_eq!((id, words(&v.unwrap())), (id2, vec![0xBEEF]));
    assert_eq!(mbx.stats().timeouts, 1);
}

#[test]
fn execute_checks_write_values() {
    let mut d = FakeDrive { p100: [0; 4], ..FakeDrive::new() };
    let odd = ParamValues::new(Format::WORD, 2, &[0, 1, 0]).unwrap();
    assert_eq!(
        mailbox::execute(&MailboxRequest::write(1, 100, 0, odd), &mut d),
        Err(ErrorValue::NUMBER_OF_VALUES_INCONSISTENT.into())
    );
    let weird = ParamValues::new(Format(0x20), 1, &[0, 1]).unwrap();
    assert_eq!(
        mailbox::execute(&MailboxRequest::write(1, 100, 0, weird), &mut d),
        Err(ErrorValue::ILLEGAL_FORMAT.into())
    );
}

// ---------------------------------------------------------------------------------------
// Heartbeats both ways

#[test]
fn drive_heartbeat_loss_faults_zsw1_sets_stat_diag_refuses_parameters_and_returns() {
    let mut b = Bench::new();
    b.link.set_drive_timeout(Duration::from_millis(50));
    b.bring_up();
    let mut hb = 0u16;
    let mut drive = |h: &mut HostSide<'_>, beat: bool| {
        if beat {
            hb += 1;
        }
        let mut r = DriveReport::EMPTY;
        r.heartbeat = hb;
        h.write_drive_report(&r);
        h.write_inputs(&ProcessData::new(Telegram::Standard(1), PdFlags::empty(), &[0x02, 0x37, 0x00, 0x10]));
    };
    for _ in 0..5 {
        b.step(10, |h| drive(h, true));
    }
    assert_eq!(b.data_exchange(&[0x04, 0x7F, 0, 0]), [0x02, 0x37, 0x00, 0x10]);
    assert!(!b.link.drive_lost());
    // A request goes out; the drive then stops beating (and answering).
    let id = b.link.submit_parameter(b.now, &MailboxRequest::read(1, 100, 0, 1), &mut b.dpm).unwrap();
    for _ in 0..5 {
        b.data_exchange(&[0x04, 0x7F, 0, 0]);
        b.step(10, |h| drive(h, false));
    }
    assert!(!b.link.drive_lost(), "50 ms is not over yet");
    b.data_exchange(&[0x04, 0x7F, 0, 0]);
    b.step(10, |h| drive(h, false));
    assert!(b.link.drive_lost());
    assert_eq!(b.data_exchange(&[0x04, 0x7F, 0, 0]), [0x00, 0x08, 0x00, 0x00], "ZSW1 fault, nothing else");
    assert!(b.node.slave().standard_diag().status2.contains(Status2::STAT_DIAG));
    b.step(1, |h| drive(h, false)); // CARD shows it from the next card cycle on
    let r = b.dpm.card_report().unwrap();
    assert!(r.flags.contains(CardFlags::DRIVE_LOST));
    assert_eq!(r.drive_losses, 1);
    assert_eq!(b.link.take_parameter_response(), Some((id, Err(DRIVE_LOST_ERROR))), "the outstanding request ends");
    let id2 = b.link.submit_parameter(b.now, &MailboxRequest::read(1, 100, 0, 1), &mut b.dpm).unwrap();
    assert_eq!(b.link.take_parameter_response(), Some((id2, Err(DRIVE_LOST_ERROR))), "new ones are answered at once");
    let returned = r.event(CardEvent::DriveReturned);
    // The drive comes back.
    b.step(10, |h| drive(h, true));
    b.step(1, |h| drive(h, true));
    assert!(!b.link.drive_lost());
    assert!(!b.node.slave().standard_diag().status2.contains(Status2::STAT_DIAG));
    let r = b.dpm.card_report().unwrap();
    assert!(!r.flags.contains(CardFlags::DRIVE_LOST));
    assert_eq!(r.event(CardEvent::DriveReturned), returned.wrapping_add(1), "event raised when it returns");
    assert_eq!(b.data_exchange(&[0x04, 0x7F, 0, 0]), [0x02, 0x37, 0x00, 0x10], "the drive's inputs again");
}

#[test]
fn a_host_that_never_beats_is_not_supervised() {
    let mut b = Bench::new();
    b.bring_up();
    for _ in 0..100 {
        b.step(10, |_| {});
    }
    assert!(!b.link.drive_lost());
}

#[test]
fn drive_reports_reach_the_ext_diag_and_malformed_ones_are_refused() {
    let mut b = Bench::new();
    let mut d = DriveReport::EMPTY;
    (d.heartbeat, d.fault_code, d.fault_count) = (1, 0x7500, 1);
    d.set_ext_diag(&[0x04, 0x75, 0x00, 0x01]);
    b.step(1, |h| {
        h.write_drive_report(&d);
    });
    assert_eq!(b.link.drive_report(), &d);
    assert!(b.node.slave().standard_diag().status1.contains(crate::dp::diag::Status1::EXT_DIAG));
    d.set_ext_diag(&[0x00]);
    d.heartbeat = 2;
    b.step(1, |h| {
        h.write_drive_report(&d);
    });
    assert_eq!(b.link.stats().bad_ext_diag, 1);
}

#[test]
fn card_heartbeat_watched_by_the_drive() {
    let mut b = Bench::new();
    let mut mon = HeartbeatMonitor::new(Duration::from_millis(30));
    let mut t = Instant::from_millis(0);
    assert_eq!(mon.observe(t, b.dpm.card_report().unwrap().heartbeat), Liveness::Unknown, "card not started");
    for _ in 0..10 {
        b.step(10, |_| {});
        t = b.now;
        assert_eq!(mon.observe(t, b.dpm.card_report().unwrap().heartbeat), Liveness::Alive);
    }
    // The card stops (no more publish): the drive sees the same value.
    let hb = b.dpm.card_report().unwrap().heartbeat;
    assert_eq!(mon.observe(t + Duration::from_millis(30), hb), Liveness::Alive);
    assert_eq!(mon.observe(t + Duration::from_millis(31), hb), Liveness::Lost);
    // It comes back.
    b.step(40, |_| {});
    assert_eq!(mon.observe(b.now, b.dpm.card_report().unwrap().heartbeat), Liveness::Alive);
}

#[test]
fn card_events_count_clear_and_init_error() {
    let mut b = Bench::new();
    b.bring_up();
    // Global_Control Clear_Data (SAP 58): control 0x02, group 0.
    let hdr =
        Header { da: SLAVE, sa: MASTER, fc: FunctionCode::request(0x6, false, false), dsap: Some(58), ssap: Some(62) };
    assert_eq!(testkit::feed(&mut b.node, b.now, &testkit::frame(&hdr, &[0x02, 0x00])), None, "SDN: no answer");
    b.step(1, |_| {});
    let r = b.dpm.card_report().unwrap();
    assert_eq!(r.event(CardEvent::ClearMode), 1);
    b.link.set_init_error(true);
    b.step(1, |_| {});
    let r = b.dpm.card_report().unwrap();
    assert_eq!(r.event(CardEvent::CardFault), 1);
    assert!(r.flags.contains(CardFlags::CARD_FAULT));
}
