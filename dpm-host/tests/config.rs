//! Configuration: refused (pending) while in data exchange, taken over after; invalid ones
//! refused; outside data exchange taken at once — the card side is pbcard's `Link`.

mod common;

use common::Card;
use dpm_host::*;
use pbcard::dp::{DpState, Events};
use pbcard::dpm::CardEvent;

#[test]
fn configuration_pending_in_data_exchange_and_taken_over_after() {
    let mut card = Card::new();
    card.bring_up();
    let mut host = Host::open(card.dpm.clone(), Options::DEFAULT).unwrap();
    assert_eq!(host.config_outcome(), Ok(ConfigOutcome::NotWritten));
    let cfg = HostConfig {
        station_address: 9,
        telegram: Telegram::Standard(1),
        comm_loss_reaction: 1,
        comm_loss_delay_ms: 500,
        ..HostConfig::DEFAULT
    };
    host.write_config(&cfg).unwrap();
    assert_eq!(host.config_outcome(), Ok(ConfigOutcome::Waiting), "the card has not looked yet");
    // The card takes CONFIG in one cycle's collect and acknowledges it in the next's CARD.
    card.cycle(1);
    assert_eq!(host.config_outcome(), Ok(ConfigOutcome::Waiting));
    for _ in 0..3 {
        card.cycle(10);
        assert_eq!(host.config_outcome(), Ok(ConfigOutcome::Pending));
        let p = host.poll(card.now);
        assert!(p.report.unwrap().flags.contains(CardFlags::CONFIG_PENDING));
    }
    assert_eq!(card.link.config(), None, "not taken over while in data exchange");
    // The master stops: the DP watchdog expires, data exchange ends, the card takes it.
    let ev = card.cycle(2000);
    assert!(ev.contains(Events::WATCHDOG_EXPIRED));
    assert_ne!(card.node.slave().state(), DpState::DataExch);
    card.cycle(1);
    assert_eq!(host.config_outcome(), Ok(ConfigOutcome::Accepted));
    assert_eq!(card.link.take_config(), Some(cfg));
    let p = host.poll(card.now);
    assert!(!p.report.unwrap().flags.contains(CardFlags::CONFIG_PENDING));
    assert!(p.events.contains(CardEvent::Watchdog) && p.events.contains(CardEvent::Offline));
    assert_eq!(host.status().unwrap().comm, CommState::Offline);

    // An invalid configuration is refused at once; the last good one stays.
    host.write_config(&HostConfig { station_address: 200, ..cfg }).unwrap();
    card.cycle(1);
    card.cycle(1);
    assert_eq!(host.config_outcome(), Ok(ConfigOutcome::Refused));
    assert_eq!(card.link.config(), Some(&cfg));
}

#[test]
fn configuration_outside_data_exchange_is_taken_at_once() {
    let mut card = Card::new();
    let mut host = Host::open(card.dpm.clone(), Options::DEFAULT).unwrap();
    let cfg = HostConfig { station_address: 3, telegram: Telegram::Ppo(2), ..HostConfig::DEFAULT };
    host.write_config(&cfg).unwrap();
    card.cycle(1);
    card.cycle(1);
    assert_eq!(host.config_outcome(), Ok(ConfigOutcome::Accepted));
    assert_eq!(card.link.take_config(), Some(cfg));
}

#[test]
fn process_data_through_the_link_reaches_the_master() {
    let mut card = Card::new();
    card.bring_up();
    let mut host = Host::open(card.dpm.clone(), Options::DEFAULT).unwrap();
    assert_eq!(card.data_exchange(&[0x04, 0x7F, 0x20, 0x00]).len(), 4);
    card.cycle(1);
    let out = host.read_outputs().unwrap();
    assert_eq!((out.telegram, out.word(0), out.word(1)), (Telegram::Standard(1), 0x047F, 0x2000));
    assert!(out.flags.contains(PdFlags::DATA_EXCHANGE));
    let st = host.status().unwrap();
    assert_eq!(
        (st.comm, st.station_address, st.master_address),
        (CommState::Online, common::SLAVE, Some(common::MASTER))
    );
    host.write_inputs(&ProcessData::new(Telegram::Standard(1), PdFlags::empty(), &[0x02, 0x37, 0x1F, 0xF0])).unwrap();
    card.cycle(1);
    assert_eq!(card.data_exchange(&[0x04, 0x7F, 0x20, 0x00]), [0x02, 0x37, 0x1F, 0xF0]);
    // Inputs for another telegram are not served.
    host.write_inputs(&ProcessData::new(Telegram::Ppo(1), PdFlags::empty(), &[0; 12])).unwrap();
    card.cycle(1);
    assert_eq!(card.data_exchange(&[0x04, 0x7F, 0x20, 0x00]), [0x02, 0x37, 0x1F, 0xF0]);
    assert_eq!(card.link.stats().stale_telegram, 1);
}
