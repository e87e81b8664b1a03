//! Issue 16 item 3 through the shipped card: the start-up gate (Set_Prm before the drive's
//! CONFIG), `CARD.BOOT_ID` and the host's restart handling, the fail-safe command reaching
//! the drive over the SPI frames.

use crate::bench::Application;
use crate::card;
use crate::dp::diag::{Status1, Status2};
use crate::dp::{DpSlave, DpState, Events};
use crate::dpm::host::{Host, Options};
use crate::dpm::spi::{Loopback, SpiHost, SpiSlave};
use crate::dpm::{ConfigResult, Dpm, HostConfig, Link};
use crate::fdl::telegram;
use crate::node::Node;
use crate::profile::drive_if::CommandFlags;
use crate::testkit::{CardRig, Rig, SetPrm};
use crate::time::{Duration, Instant};

const MASTER: u8 = 2;
const SLAVE: u8 = 5;

/// The card alone under the scripted master: [`CardRig`] with `step` = one 1 ms step.
struct Card(CardRig<Application>);

impl Card {
    fn card_only() -> Self {
        Card(CardRig::new(Application::card_only(), MASTER, SLAVE))
    }

    fn step(&mut self) {
        self.0.step(1);
    }

    fn srd(&mut self, dsap: u8, pdu: &[u8]) -> Vec<u8> {
        self.0.srd(Some(dsap), pdu).to_vec()
    }
}

impl core::ops::Deref for Card {
    type Target = CardRig<Application>;
    fn deref(&self) -> &CardRig<Application> {
        &self.0
    }
}

impl core::ops::DerefMut for Card {
    fn deref_mut(&mut self) -> &mut CardRig<Application> {
        &mut self.0
    }
}

#[test]
fn the_start_up_gate_holds_set_prm_until_the_drive_wrote_a_valid_config() {
    let mut c = Card::card_only();
    c.step();
    // Set_Prm is acknowledged but not taken: Wait_Prm, Station_Not_Ready + Prm_Req, no
    // Prm_Fault (the master keeps parameterising).
    assert_eq!(c.srd(61, &SetPrm::CARD.pdu()), [telegram::SC]);
    c.step();
    assert_eq!(c.node.slave().state(), DpState::WaitPrm);
    let d = c.node.slave().standard_diag();
    assert!(d.status1.contains(Status1::STATION_NOT_READY) && !d.status1.contains(Status1::PRM_FAULT));
    assert!(d.status2.contains(Status2::PRM_REQ));
    assert_eq!(c.node.slave().stats().prm_faults, 0);
    // An invalid CONFIG does not open the gate.
    let bad = HostConfig { profile: 9, ..HostConfig::DEFAULT };
    assert!(!bad.is_valid());
    c.app.host_mut().write_config(&bad).unwrap();
    c.step();
    assert_eq!(c.app.link().card_report().config_result(), ConfigResult::Refused);
    assert_eq!(c.srd(61, &SetPrm::CARD.pdu()), [telegram::SC]);
    c.step();
    assert_eq!(c.node.slave().state(), DpState::WaitPrm);
    // The drive's valid CONFIG (through the SPI frames): the next Set_Prm is taken.
    c.app.host_mut().write_config(&HostConfig::DEFAULT).unwrap();
    c.step();
    assert_eq!(c.app.link().card_report().config_result(), ConfigResult::Accepted);
    assert_eq!(c.srd(61, &SetPrm::CARD.pdu()), [telegram::SC]);
    c.step();
    assert_eq!(c.node.slave().state(), DpState::WaitCfg);
    assert_eq!(c.srd(62, card::MODULES[0].cfg), [telegram::SC]);
    c.step();
    assert_eq!(c.node.slave().state(), DpState::DataExch);
}

#[test]
fn a_card_with_a_simulated_drive_has_no_gate() {
    let mut c = Card::card_only();
    c.app = Application::new(crate::drive::DriveConfig::DEFAULT);
    c.step();
    assert_eq!(c.srd(61, &SetPrm::CARD.pdu()), [telegram::SC]);
    assert_eq!(c.node.slave().state(), DpState::WaitCfg);
}

/// The card side of a restart test: a node, its link and a boot id, publishing into the
/// image behind the host's loopback.
fn publish(link: &mut Link, node: &mut Node, dpm: &mut Dpm, now: Instant) {
    link.publish(node, Events::empty(), dpm);
    link.collect(now, node, dpm);
}

#[test]
fn a_new_boot_id_makes_the_host_reopen_rewrite_config_and_resync_events() {
    let t = Instant::from_millis(0);
    let (mut link, mut node) =
        (Link::new(crate::card::MODULES), crate::card::node(DpSlave::new(&crate::card::SLAVE, SLAVE)));
    link.set_boot_id(0x1234);
    link.set_startup_gate(true);
    let mut host = Host::open(SpiHost::new(Loopback::new(Dpm::new())), Options::DEFAULT).unwrap();
    publish(&mut link, &mut node, host.transport_mut().dpm_mut(), t);
    assert!(!host.poll(t).card_restarted);
    assert_eq!(host.boot_id(), 0x1234);
    let cfg = HostConfig { station_address: 9, ..HostConfig::DEFAULT };
    host.write_config(&cfg).unwrap();
    publish(&mut link, &mut node, host.transport_mut().dpm_mut(), t);
    assert!(node.slave().is_ready() && node.slave().address() == 9);
    // Events happened before the restart (the counters are high).
    for _ in 0..3 {
        link.publish(&mut node, Events::WATCHDOG_EXPIRED, host.transport_mut().dpm_mut());
    }
    assert!(!host.poll(t).events.is_empty());

    // The card restarts: a fresh image, a fresh protocol state, another boot id, the gate
    // closed again, the address from its store (here the default).
    let (mut link, mut node) =
        (Link::new(crate::card::MODULES), crate::card::node(DpSlave::new(&crate::card::SLAVE, SLAVE)));
    link.set_boot_id(0x1235);
    link.set_startup_gate(true);
    *host.transport_mut().dpm_mut() = Dpm::new();
    *host.transport_mut().bus_mut().slave_mut() = SpiSlave::new();
    publish(&mut link, &mut node, host.transport_mut().dpm_mut(), t);
    assert!(!node.slave().is_ready(), "gated until the host rewrites CONFIG");
    let p = host.poll(t + Duration::from_millis(1));
    assert!(p.card_restarted && p.error.is_none(), "{p:?}");
    assert!(p.events.is_empty(), "the restart's counter reset is no event: {:?}", p.events);
    assert_eq!((host.boot_id(), host.stats().card_restarts), (0x1235, 1));
    // CONFIG was rewritten: the card takes it over, the gate opens, the address applies.
    publish(&mut link, &mut node, host.transport_mut().dpm_mut(), t);
    assert!(node.slave().is_ready());
    assert_eq!(node.slave().address(), 9);
    assert_eq!(link.card_report().config_result(), ConfigResult::Accepted);
    // Events after the restart are reported again.
    link.publish(&mut node, Events::WATCHDOG_EXPIRED, host.transport_mut().dpm_mut());
    assert!(!host.poll(t + Duration::from_millis(2)).card_restarted);
}

#[test]
fn the_fail_safe_command_reaches_the_drive_over_the_frames() {
    let mut c = Card::card_only();
    c.step();
    c.app.fail_safe();
    let img = c.app.host_mut().read_process_data().expect("paired: OUTPUTS_SEQ names the safe OUTPUTS");
    assert!(img.command.command.flags.contains(CommandFlags::COAST | CommandFlags::COMM_LOSS));
    assert_eq!(img.command.outputs_seq, img.outputs.seq);
    assert_eq!(c.app.host().stats().unpaired_retries, 0);
}

#[test]
fn config_operate_mode_is_1_to_3_or_0_and_other_values_are_refused() {
    for (mode, valid) in [(0, true), (1, true), (2, true), (3, true), (4, false), (0xFF, false)] {
        let mut c = Card::card_only();
        c.step();
        c.app.host_mut().write_config(&HostConfig { operate_mode: mode, ..HostConfig::DEFAULT }).unwrap();
        c.step();
        let want = if valid { ConfigResult::Accepted } else { ConfigResult::Refused };
        assert_eq!(c.app.link().card_report().config_result(), want, "operate mode {mode}");
    }
}
