//! Configuration: refused (pending) while in data exchange, taken over after; invalid ones
//! refused; outside data exchange taken at once — the card side is pbcard's `Link`.
//!
//! Each test runs twice (`over_both!`): `::memory` over the memory transport, `::spi` through
//! `SpiHost` over `Loopback` (the board's reply pipeline); an SPI run also proves that frames
//! crossed and none was refused.

#[macro_use]
mod common;

use common::Card;
use dpm_host::*;
use pbcard::card;
use pbcard::dp::{DpState, Events};
use pbcard::dpm::{CardEvent, ConfigResult};
use pbcard::fdl::telegram;
use pbcard::testkit::Rig;

over_both! {
fn configuration_pending_in_data_exchange_and_taken_over_after(via) {
    let mut card = Card::via(via);
    card.bring_up();
    let mut host = Host::open(card.transport(), Options::DEFAULT).unwrap();
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
    assert_eq!(card.app.link.config(), None, "not taken over while in data exchange");
    // The master stops: the DP watchdog expires, data exchange ends, the card takes it.
    let ev = card.cycle(2000);
    assert!(ev.contains(Events::WATCHDOG_EXPIRED));
    assert_ne!(card.node.slave().state(), DpState::DataExch);
    card.cycle(1);
    assert_eq!(host.config_outcome(), Ok(ConfigOutcome::Accepted));
    assert_eq!(card.app.link.take_config(), Some(cfg));
    let p = host.poll(card.now);
    assert!(!p.report.unwrap().flags.contains(CardFlags::CONFIG_PENDING));
    assert!(p.events.contains(CardEvent::Watchdog) && p.events.contains(CardEvent::Offline));
    assert_eq!(host.status().unwrap().comm, CommState::Offline);

    // An invalid configuration is refused at once; the last good one stays.
    host.write_config(&HostConfig { station_address: 200, ..cfg }).unwrap();
    card.cycle(1);
    card.cycle(1);
    assert_eq!(host.config_outcome(), Ok(ConfigOutcome::Refused));
    assert_eq!(card.app.link.config(), Some(&cfg));
}
}

over_both! {
fn configuration_outside_data_exchange_is_taken_at_once(via) {
    let mut card = Card::via(via);
    let mut host = Host::open(card.transport(), Options::DEFAULT).unwrap();
    let cfg = HostConfig { station_address: 3, telegram: Telegram::Ppo(2), ..HostConfig::DEFAULT };
    host.write_config(&cfg).unwrap();
    card.cycle(1);
    card.cycle(1);
    assert_eq!(host.config_outcome(), Ok(ConfigOutcome::Accepted));
    assert_eq!(card.app.link.take_config(), Some(cfg));
}
}

over_both! {
fn process_data_through_the_link_reaches_the_master(via) {
    let mut card = Card::via(via);
    card.bring_up();
    let mut host = Host::open(card.transport(), Options::DEFAULT).unwrap();
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
    assert_eq!(card.app.link.stats().stale_telegram, 1);
}
}

over_both! {
/// CONFIG.STATION_ADDRESS outside data exchange: the slave takes the address, reports it as
/// ADDRESS_CHANGED (the platform stores it through its `AddressStore`, as after a
/// Set_Slave_Add), and STATUS shows it.
fn station_address_taken_outside_data_exchange_and_stored(via) {
    use pbcard::dp::slave_add::{AddressStore, MemoryStore};
    let mut card = Card::via(via);
    let mut store = MemoryStore::default();
    let mut host = Host::open(card.transport(), Options::DEFAULT).unwrap();
    host.write_config(&HostConfig { station_address: 9, ..HostConfig::DEFAULT }).unwrap();
    let mut changed = false;
    for _ in 0..3 {
        let ev = card.cycle(1);
        if ev.contains(Events::ADDRESS_CHANGED) {
            let s = card.node.slave();
            store.save(s.address(), s.no_add_chg()).unwrap();
            changed = true;
        }
    }
    assert!(changed, "ADDRESS_CHANGED reported by Node::poll");
    assert_eq!(host.config_outcome(), Ok(ConfigOutcome::Accepted));
    assert_eq!(card.node.slave().address(), 9);
    assert_eq!(store.load(), Some((9, false)));
    assert_eq!(host.status().unwrap().station_address, 9);
    // 126 = keep the card's address.
    host.write_config(&HostConfig::DEFAULT).unwrap();
    card.cycle(1);
    card.cycle(1);
    assert_eq!(host.config_outcome(), Ok(ConfigOutcome::Accepted));
    assert_eq!(card.node.slave().address(), 9);
}
}

over_both! {
/// In data exchange the address is not touched (pending), and the master keeps talking to
/// the card at its address.
fn station_address_refused_in_data_exchange(via) {
    let mut card = Card::via(via);
    card.bring_up();
    let mut host = Host::open(card.transport(), Options::DEFAULT).unwrap();
    host.write_config(&HostConfig { station_address: 9, ..HostConfig::DEFAULT }).unwrap();
    for _ in 0..3 {
        assert!(!card.cycle(5).contains(Events::ADDRESS_CHANGED));
    }
    assert_eq!(host.config_outcome(), Ok(ConfigOutcome::Pending));
    assert_eq!(card.node.slave().address(), common::SLAVE);
    assert_eq!(card.data_exchange(&[0x04, 0x7E, 0, 0]).len(), 4, "still answering at its address");
    assert_eq!(card.node.slave_mut().set_address(9).ok(), None, "the slave refuses it itself too");
}
}

over_both! {
/// No_Add_Chg (a Set_Slave_Add froze the address): the address stays, the rest of CONFIG
/// (the telegram) is taken, CONFIG_RESULT says so.
fn station_address_locked_by_no_add_chg(via) {
    use pbcard::dp::DpSlave;
    let mut card = Card::via(via);
    card.node = pbcard::card::node(DpSlave::with_address_lock(&pbcard::card::SLAVE, common::SLAVE, true));
    let mut host = Host::open(card.transport(), Options::DEFAULT).unwrap();
    let cfg = HostConfig { station_address: 9, telegram: Telegram::Ppo(2), ..HostConfig::DEFAULT };
    host.write_config(&cfg).unwrap();
    card.cycle(1);
    card.cycle(1);
    assert_eq!(host.config_outcome(), Ok(ConfigOutcome::AddressLocked));
    assert_eq!(host.card_report().unwrap().config_result(), ConfigResult::AddressLocked);
    assert_eq!(card.node.slave().address(), common::SLAVE);
    assert_eq!(card.node.slave().required_module().and_then(Telegram::of_module), Some(Telegram::Ppo(2)));
}
}

over_both! {
/// CONFIG.TELEGRAM: the master's Chk_Cfg must select the drive's telegram; another module is
/// a Cfg_Fault (P0740 "configuration data error"); 0 lifts the restriction. A telegram the
/// card has no module for is refused.
fn telegram_selected_by_the_drive_is_enforced(via) {
    let mut card = Card::via(via);
    let mut host = Host::open(card.transport(), Options::DEFAULT).unwrap();
    host.write_config(&HostConfig { telegram: Telegram::Ppo(2), ..HostConfig::DEFAULT }).unwrap();
    card.cycle(1);
    card.cycle(1);
    assert_eq!(host.config_outcome(), Ok(ConfigOutcome::Accepted));
    host.poll(card.now); // the events seen so far
                         // Set_Prm + Chk_Cfg for ST1: acknowledged, refused as Cfg_Fault.
    let mut prm = vec![0x88, 1, 100, 11, (card::IDENT_NUMBER >> 8) as u8, card::IDENT_NUMBER as u8, 0];
    prm.extend_from_slice(&card::USER_PRM_DEFAULTS);
    assert_eq!(card.srd(Some(61), &prm), [telegram::SC]);
    card.cycle(1);
    assert_eq!(card.srd(Some(62), card::MODULES[0].cfg), [telegram::SC]);
    let ev = card.cycle(1);
    assert!(ev.contains(Events::CFG_FAULT));
    assert_eq!(card.node.slave().state(), DpState::WaitPrm);
    assert_eq!(host.status().unwrap().comm, CommState::ConfigError);
    assert!(host.poll(card.now).events.contains(CardEvent::ConfigurationError));
    // The drive's telegram (PPO 2) is accepted.
    let ppo2 = card::MODULES.iter().find(|m| Telegram::of_module(m) == Some(Telegram::Ppo(2))).unwrap();
    assert_eq!(card.srd(Some(61), &prm), [telegram::SC]);
    card.cycle(1);
    assert_eq!(card.srd(Some(62), ppo2.cfg), [telegram::SC]);
    card.cycle(1);
    assert_eq!(card.node.slave().state(), DpState::DataExch);
    assert_eq!(host.status().unwrap().telegram, Telegram::Ppo(2));
    // A telegram without a module on this card: refused, the selection stays.
    let ev = card.cycle(3000); // the master stops: out of data exchange
    assert!(ev.contains(Events::WATCHDOG_EXPIRED));
    host.write_config(&HostConfig { telegram: Telegram::Standard(999), ..HostConfig::DEFAULT }).unwrap();
    card.cycle(1);
    card.cycle(1);
    assert_eq!(host.config_outcome(), Ok(ConfigOutcome::Refused));
    assert_eq!(card.node.slave().required_module().map(|m| m.reference), Some(ppo2.reference));
    // Telegram 0 ("any"): ST1 is accepted again.
    host.write_config(&HostConfig::DEFAULT).unwrap();
    card.cycle(1);
    card.cycle(1);
    assert_eq!(host.config_outcome(), Ok(ConfigOutcome::Accepted));
    card.bring_up();
}
}
