//! Issue 15: each product's PLC program runs unchanged — the profile defects, each replayed
//! through the shipped card (`Node` + `bench::Application` with the simulated drive behind the
//! DPM): bytes or a control-word sequence in, the status word / values / drive command out.
//! Each test names the manual table it follows and, where the manuals contradict themselves,
//! the reading we chose.

use crate::bench::tests::{words, Bench};
use crate::card;
use crate::dp::DpState;
use crate::dpm::HostConfig;
use crate::drive::model::FAULT_CLEAR_MODE;
use crate::fdl::telegram;
use crate::profile::drive_if::{CommandFlags, StatusFlags};
use crate::profile::profidrive::State;

fn module(reference: u16) -> &'static card::Module {
    card::MODULES.iter().find(|m| m.reference == reference).expect("module in the GSD")
}

fn bytes(w: &[u16]) -> Vec<u8> {
    w.iter().flat_map(|w| w.to_be_bytes()).collect()
}

impl Bench {
    /// Set_Prm with the card's user parameter `operate_mode` (0 local, 1 PROFIdrive, 2 Bypass,
    /// 3 Echo), then Chk_Cfg `module`.
    fn bring_up_mode(&mut self, module: &card::Module, operate_mode: u8) {
        let mut prm = vec![0x88, 1, 100, 11, (card::IDENT_NUMBER >> 8) as u8, card::IDENT_NUMBER as u8, 0];
        prm.extend_from_slice(&card::USER_PRM_DEFAULTS);
        prm[7 + card::PRM_OPERATE_MODE.offset] = operate_mode;
        assert_eq!(self.srd(Some(61), &prm), [telegram::SC]);
        self.step(1);
        assert_eq!(self.srd(Some(62), module.cfg), [telegram::SC]);
        self.step(1);
        assert_eq!(self.node.slave().state(), DpState::DataExch);
    }

    /// The drive's CONFIG block (taken over outside data exchange).
    fn config(&mut self, cfg: HostConfig) {
        self.app.host_mut().write_config(&cfg).unwrap();
        self.step(1);
        self.step(1);
        assert_eq!(self.app.link().config().map(|c| c.profile), Some(cfg.profile));
    }

    /// `n` cycles of `outputs`, 10 ms each; the last inputs.
    fn cycles(&mut self, outputs: &[u8], n: usize) -> Vec<u8> {
        let mut i = vec![];
        for _ in 0..n {
            i = self.cycle(outputs, 10);
        }
        i
    }
}

/// Item 1 — VACON telegram 139 in Bypass (OPTE3/E5 §5.1.2, §6.7, Table 25): Chk_Cfg
/// `C4 D1 D1 FE 01 00 8B`, outputs `00 01 13 88 …` run the drive at 50 % (FBFixedControlWord
/// b0 run, setpoint 5000 of 0..10000). The drive interface carries 16 raw words: the control
/// word, the setpoint and PDO1..PDO14 reach the drive; PDO15 / PDO16 stay on the card
/// (documented in `profile::cyclic`, "Bypass").
#[test]
fn vacon_139_in_bypass_runs_the_drive() {
    let m = module(1139);
    assert_eq!(m.cfg, [0xC4, 0xD1, 0xD1, 0xFE, 0x01, 0x00, 0x8B]);
    let mut b = Bench::new();
    b.bring_up_mode(m, 2);
    let mut out = vec![0x0001, 0x1388];
    out.extend((1..=16).map(|k| 0xA000 + k));
    let i = b.cycles(&bytes(&out), 80);
    let img = b.app.drive().image();
    assert_eq!(img.extra.words().len(), 16, "16 words reach the drive");
    assert_eq!(img.extra.words()[..2], [0x0001, 0x1388]);
    assert_eq!(img.extra.words()[2..], out[2..16], "PDO1..PDO14");
    assert!(b.app.drive().command().flags.contains(CommandFlags::RUN));
    assert_eq!(b.app.drive().actual_speed(), 0x2000, "50 %");
    let w = words(&i);
    assert_eq!(w.len(), 18);
    assert_eq!(w[0] & 0x0003, 0x0003, "FBFixedStatusWord: ready, running ({:04X})", w[0]);
    assert_eq!(w[1], 5000, "actual 50.00 %");
    assert_eq!(w[2..16], out[2..16], "the drive echoes PDI1..PDI14");
    assert_eq!(w[16..], [0, 0], "PDI15 / PDI16: not carried by the drive interface");
    assert!(b.app.runtime().engine().unwrap().stats().words_cut > 0);
}

/// Item 15 — a negative Bypass setpoint (0xFFFF) is out of 0..10000: refused as 0, never
/// +100 % forward.
#[test]
fn a_negative_bypass_setpoint_is_not_full_speed() {
    let mut b = Bench::new();
    b.bring_up_mode(module(1100), 2);
    b.cycles(&bytes(&[0x0001, 0xFFFF, 0, 0, 0, 0]), 40);
    assert_eq!(b.app.drive().command().speed_setpoint, 0);
    assert_eq!(b.app.drive().actual_speed(), 0);
}

/// PPO 1 output image: PKW `pkw`, then STW 047E and HSW 0.
fn ppo1(pkw: [u8; 8]) -> Vec<u8> {
    let mut q = pkw.to_vec();
    q.extend_from_slice(&[0x04, 0x7E, 0, 0]);
    q
}

/// Item 2 — the VACON PKW dialect of the PPO types (OPTE3/E5 §6.6.3): Table 124 → Table 126
/// (read ID 102 maximum frequency = 50.00 Hz), Table 128 → Table 130 (write ID 125 control
/// place = 2, answered with type 1 and value 0); a reserved request type (3) is rejected with
/// fault code 101 "unknown request type" (Table 122) and writes nothing.
#[test]
fn ppo_pkw_speaks_vacon() {
    let mut b = Bench::new();
    b.bring_up(module(101));
    let i = b.cycles(&ppo1([0x10, 0x66, 0, 0, 0, 0, 0, 0]), 6);
    assert_eq!(i[..8], [0x10, 0x66, 0x00, 0x00, 0x00, 0x00, 0x13, 0x88], "Table 126");
    let i = b.cycles(&ppo1([0x20, 0x7D, 0, 0, 0, 0, 0, 0x02]), 6);
    assert_eq!(i[..8], [0x10, 0x7D, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00], "Table 130");
    assert_eq!(b.app.drive().vacon_ids().get(125, 0), Some(2));
    let i = b.cycles(&ppo1([0x30, 0x7D, 0, 0, 0, 0, 0, 0x01]), 6);
    assert_eq!(i[..8], [0x70, 0x7D, 0, 0, 0, 0, 0, 101], "type 3 reserved: fault code 101");
    assert_eq!(b.app.drive().vacon_ids().get(125, 0), Some(2), "nothing written");
}

/// Item 3 — "no request" (request type 0, OPTE3/E5 Table 121) with non-zero other words is
/// answered with "no response" (all zero), not an error: a PLC that clears the type and waits
/// for "no response" goes on. INVT (§2.6 Table 2-10): PKW1 = 0 likewise.
#[test]
fn pkw_no_request_with_nonzero_words_gives_no_response() {
    let mut b = Bench::new();
    b.bring_up(module(101));
    let i = b.cycles(&ppo1([0x10, 0x66, 0, 0, 0, 0, 0, 0]), 6);
    assert_ne!(i[..8], [0; 8]);
    let i = b.cycles(&ppo1([0x00, 0x66, 0, 0, 0, 0, 0, 0]), 6);
    assert_eq!(i[..8], [0; 8], "VACON: type 0 → no response");
    let jobs = b.app.runtime().pkw().counters().jobs;
    assert_eq!(jobs, 1, "no job for a type-0 request");

    let mut b = Bench::new();
    b.bring_up(module(4001));
    let mut q = vec![0u8; 32];
    q[..8].copy_from_slice(&[0x00, 0x00, 0x00, 0x0A, 0, 0, 0, 0]);
    let i = b.cycles(&q, 6);
    assert_eq!(i[..8], [0; 8], "INVT: PKW1 = 0 → no response");
    assert_eq!(b.app.runtime().pkw().counters().jobs, 0);
}

/// Item 4 — WEG's PROFIdrive profile (P0741 = 0) follows P0967 (CFW500 Table 4.7), not VACON's
/// STW1 where they differ. WEG 103 with CONFIG "PROFIdrive": `047E`, `047F` runs, `007F` →
/// LOCAL (b10 "0: the drive goes to the LOCAL situation"), no fault, nothing frozen; the drive
/// stops as its local place commands nothing. Our reading of the two manuals: b10 = 0 is
/// only the control place at WEG; VACON's §6.3.3 freeze-and-fault is not applied.
#[test]
fn weg_profidrive_b10_is_local_remote() {
    let mut b = Bench::new();
    b.config(HostConfig { profile: 0, ..HostConfig::DEFAULT });
    b.bring_up(module(2103));
    let run = |cw: u16| bytes(&[cw, 0x2000, 0]);
    b.cycles(&run(0x047E), 3);
    b.cycles(&run(0x047F), 80);
    assert_eq!(b.app.profidrive_state(), Some(State::Operation));
    assert!(b.app.drive().actual_speed() > 0x1000);
    let i = b.cycles(&run(0x007F), 80);
    let cmd = *b.app.drive().command();
    assert!(!cmd.flags.contains(CommandFlags::FIELDBUS_CONTROL), "LOCAL");
    assert!(!cmd.flags.contains(CommandFlags::FIELDBUS_FAULT));
    assert_ne!(b.app.profidrive_state(), Some(State::Fault));
    assert_eq!(words(&i)[0] & 0x0008, 0, "P0968 b3: no fault");
    assert_eq!(b.app.drive().status().fault_code, 0, "the drive is not tripped");
    assert_eq!(b.app.drive().actual_speed(), 0, "the local place has no run command");
    // Back to REMOTE: the words are taken again.
    b.cycles(&run(0x047F), 80);
    assert!(b.app.drive().actual_speed() > 0x1000, "remote again");
}

/// Item 4 — P0967 b4 = 0 "disables the drive via deceleration ramp" (CFW500 Table 4.7): a ramp
/// stop (normal deceleration), not VACON's ramp-function generator reset (quick-stop ramp).
#[test]
fn weg_profidrive_b4_is_a_ramp_stop() {
    let mut b = Bench::new();
    b.config(HostConfig { profile: 0, ..HostConfig::DEFAULT });
    b.bring_up(module(2103));
    b.cycles(&bytes(&[0x047E, 0x2000, 0]), 3);
    b.cycles(&bytes(&[0x047F, 0x2000, 0]), 80);
    let before = b.app.drive().actual_speed();
    b.cycles(&bytes(&[0x046F, 0x2000, 0]), 2);
    let cmd = *b.app.drive().command();
    assert!(!cmd.flags.contains(CommandFlags::RUN), "ramp stop");
    assert!(!cmd.flags.contains(CommandFlags::RAMP_RESET));
    // 1 s ramp per 100 %: 20 ms take at most ~2 % + one cycle, the quick-stop ramp would
    // have taken 40 %.
    assert!(b.app.drive().actual_speed() > before - 0x0300, "normal deceleration");
}

/// Item 4 — P0967 b7 "1: If in a fault condition, it executes the fault reset" (CFW500 Table
/// 4.7) acts on the level: b7 held at 1 from before the trip resets the fault (VACON's edge
/// reading would need 0 → 1 after the trip).
#[test]
fn weg_profidrive_b7_resets_on_the_level() {
    let mut b = Bench::new();
    b.config(HostConfig { profile: 0, ..HostConfig::DEFAULT });
    b.bring_up(module(2103));
    b.cycles(&bytes(&[0x047E, 0x2000, 0]), 3);
    b.cycles(&bytes(&[0x047F, 0x2000, 0]), 10);
    b.cycles(&bytes(&[0x04FF, 0x2000, 0]), 3);
    b.app.drive_mut().inject_fault(0x2310, 0);
    let i = b.cycles(&bytes(&[0x04FF, 0x2000, 0]), 5);
    assert_eq!(b.app.drive().status().fault_code, 0, "reset by the held b7");
    assert_eq!(b.app.profidrive_state(), Some(State::SwitchingOnInhibited));
    assert_eq!(words(&i)[0] & 0x0008, 0);
}

/// Item 5 — Standard telegram 1 with WEG's factory data profile (CFW500 P0922 = 2 "Standard
/// Telegram 1", P0741 = 1 manufacturer; the drive's CONFIG says "manufacturer"): P0684
/// `00 17` (run, general enable, forward, remote) with P0685 `10 00` (4096 of 8192 = 50 %)
/// runs the drive; the status word is P0680.
#[test]
fn st1_with_the_weg_manufacturer_profile() {
    let mut b = Bench::new();
    b.config(HostConfig { profile: 1, ..HostConfig::DEFAULT });
    b.bring_up(module(1));
    let i = b.cycles(&[0x00, 0x17, 0x10, 0x00], 80);
    assert_eq!(b.app.profidrive_state(), None, "no PROFIdrive state machine");
    assert!(b.app.drive().command().flags.contains(CommandFlags::RUN));
    assert_eq!(b.app.drive().actual_speed(), 0x2000);
    let w = words(&i);
    assert_eq!(w[0] & 0x1700, 0x1700, "P0680 b8 running, b9 enabled, b10 forward, b12 remote ({:04X})", w[0]);
    assert_eq!(w[1], 0x1000, "P0681 4096");
    // Without a CONFIG, ST1 stays PROFIdrive 4.1 (VACON): `00 17` is no valid STW1.
    let mut b = Bench::new();
    b.bring_up(module(1));
    b.cycles(&[0x00, 0x17, 0x10, 0x00], 20);
    assert_eq!(b.app.profidrive_state(), Some(State::SwitchingOnInhibited));
    assert_eq!(b.app.drive().actual_speed(), 0);
}

/// Item 6 — leaving Clear on VACON (OPTE3/E5 §6.3.3 bit 10): Clear's outputs are zero, so STW1
/// b10 drops in operation → FAULT (the drive trips with the fieldbus fault once the master
/// operates again); the motor restarts only after a b7 acknowledge and a new switch-on.
#[test]
fn leaving_clear_needs_an_acknowledge_on_vacon() {
    let mut b = Bench::new();
    b.bring_up(module(1));
    b.cycles(&[0x04, 0x7E, 0x20, 0x00], 3);
    b.cycles(&[0x04, 0x7F, 0x20, 0x00], 80);
    assert!(b.app.drive().actual_speed() > 0x1000);
    clear(&mut b, 0x02);
    b.cycles(&[0x04, 0x7F, 0x20, 0x00], 5);
    clear(&mut b, 0x00);
    let i = b.cycles(&[0x04, 0x7F, 0x20, 0x00], 150);
    assert_eq!(b.app.profidrive_state(), Some(State::Fault));
    assert_eq!(words(&i)[0] & 0x0008, 0x0008, "ZSW1 b3 fault");
    // The drive's own action "fault" tripped it in Clear first (F238, CFW500 §6); the card's
    // frozen FIELDBUS_FAULT after Clear keeps it tripped.
    assert_eq!(b.app.drive().status().fault_code, FAULT_CLEAR_MODE);
    assert!(b.app.drive().command().flags.contains(CommandFlags::FIELDBUS_FAULT));
    assert!(!b.app.drive().model().modulating(), "no restart: the motor coasts");
    // The process data stay frozen (the last valid command) with the fieldbus fault.
    assert!(b.app.drive().command().flags.contains(CommandFlags::FIELDBUS_FAULT));
    b.cycles(&[0x04, 0xFE, 0x20, 0x00], 3);
    b.cycles(&[0x04, 0x7E, 0x20, 0x00], 3);
    assert_eq!(b.app.profidrive_state(), Some(State::ReadyToSwitchOn));
    b.cycles(&[0x04, 0x7F, 0x20, 0x00], 80);
    assert!(b.app.drive().actual_speed() > 0x1000, "runs after acknowledge and switch-on");
}

/// Global_Control `command` to all slaves (SDN to SAP 58), then a step.
fn clear(b: &mut Bench, command: u8) {
    use crate::fdl::telegram::{FunctionCode, Header};
    let hdr = Header { da: 5, sa: 2, fc: FunctionCode::request(0x6, false, false), dsap: Some(58), ssap: Some(62) };
    let mut buf = [0u8; telegram::MAX_FRAME_LEN];
    let n = telegram::emit(&mut buf, &hdr, &[command, 0x00]).unwrap();
    for &x in &buf[..n] {
        assert!(b.node.on_byte(b.now, x).is_none());
    }
    b.step(1);
}

/// Item 7 — STW1 b5 = 0 "freeze setpoint" (OPTE3/E5 Table 26) holds the setpoint only: the
/// ramp-function generator runs on to the frozen setpoint.
#[test]
fn b5_freezes_the_setpoint_not_the_ramp() {
    let mut b = Bench::new();
    b.bring_up(module(1));
    b.cycles(&[0x04, 0x7E, 0x20, 0x00], 3);
    b.cycles(&[0x04, 0x7F, 0x20, 0x00], 10);
    let ramping = b.app.drive().actual_speed();
    assert!(ramping > 0 && ramping < 0x1800, "still ramping ({ramping:#06X})");
    // b5 = 0 with a new setpoint 10 %: not taken, the ramp continues to 50 %.
    b.cycles(&[0x04, 0x5F, 0x06, 0x66], 80);
    let cmd = *b.app.drive().command();
    assert!(!cmd.flags.contains(CommandFlags::RAMP_HOLD));
    assert_eq!(cmd.speed_setpoint, 0x2000, "the frozen setpoint");
    assert_eq!(b.app.drive().actual_speed(), 0x2000, "the ramp went on");
}

/// Item 13 — a b7 edge in the cycle the drive trips acknowledges (the trip is taken first).
#[test]
fn an_acknowledge_in_the_trip_cycle_is_not_lost() {
    let mut b = Bench::new();
    b.bring_up(module(1));
    b.cycles(&[0x04, 0x7E, 0x20, 0x00], 3);
    b.cycles(&[0x04, 0x7F, 0x20, 0x00], 10);
    b.app.drive_mut().inject_fault(0x2310, 0);
    // The drive reports the trip in the step that also evaluates this word's b7 edge.
    b.cycle(&[0x04, 0xFF, 0x20, 0x00], 10);
    let i = b.cycles(&[0x04, 0xFE, 0x20, 0x00], 3);
    assert_eq!(b.app.drive().status().fault_code, 0);
    assert_eq!(b.app.profidrive_state(), Some(State::ReadyToSwitchOn), "one edge was enough");
    assert_eq!(words(&i)[0] & 0x0008, 0);
    assert!(!b.app.drive().status().flags.contains(StatusFlags::FAULT));
}

/// INVT output image: PKW zero, CW `cw`, set frequency `hz100` (0.01 Hz).
fn invt(cw: u16, hz100: u16) -> Vec<u8> {
    let mut q = vec![0u8; 32];
    q[8..10].copy_from_slice(&cw.to_be_bytes());
    q[10..12].copy_from_slice(&hz100.to_be_bytes());
    q
}

/// Item 11 — INVT: a latched run command does not survive a trip (our safety choice; the INVT
/// manual is silent): send 1, trip, send 7 → the fault is reset and the motor stays stopped;
/// a new run command (1 after another code) starts it.
#[test]
fn invt_needs_a_new_run_command_after_a_fault() {
    let mut b = Bench::new();
    b.bring_up(module(4001));
    b.cycles(&invt(1, 2500), 80);
    assert_eq!(b.app.drive().actual_speed(), 0x2000);
    b.app.drive_mut().inject_fault(0x2310, 0);
    b.cycles(&invt(1, 2500), 5);
    let i = b.cycles(&invt(7, 2500), 5);
    assert_eq!(b.app.drive().status().fault_code, 0, "code 7 reset the fault");
    assert_eq!(words(&i)[4] & 0xFF, 3, "SW: stopped");
    let i = b.cycles(&invt(0, 2500), 80);
    assert!(!b.app.drive().model().modulating(), "code 0 keeps it stopped (the motor coasts down)");
    assert!(!b.app.drive().command().flags.contains(CommandFlags::RUN));
    assert_eq!(words(&i)[4] & 0xFF, 3);
    b.cycles(&invt(1, 2500), 80);
    assert_eq!(b.app.drive().actual_speed(), 0x2000, "a new run command");
}

/// Item 8 — the "drive lost" image (the drive's heartbeat stopped) uses each profile's own
/// fault status word: PROFIdrive ZSW1 b3 (OPTE3/E5 Table 27), WEG manufacturer P0680 b15
/// "fault" (CFW500 Table 4.2), WEG PROFIdrive P0968 b3, INVT status value 4 "faulty" (INVT
/// Table 2-7); every other word 0.
#[test]
fn the_drive_lost_image_is_each_profiles_fault() {
    for (reference, profile, pkw, fault) in
        [(1u16, None, 0usize, 0x0008u16), (2103, None, 0, 0x8000), (2103, Some(0), 0, 0x0008), (4001, None, 4, 0x0004)]
    {
        let mut b = Bench::new();
        if let Some(p) = profile {
            b.config(HostConfig { profile: p, ..HostConfig::DEFAULT });
        }
        let m = module(reference);
        b.bring_up(m);
        let q = vec![0u8; m.outputs as usize];
        b.cycles(&q, 5);
        b.app.set_drive_runs(false);
        let i = b.cycles(&q, 200);
        assert!(b.app.link().drive_lost(), "{}", m.name);
        let w = words(&i);
        assert_eq!(w[pkw], fault, "{} ({profile:?})", m.name);
        assert!(w.iter().enumerate().all(|(k, &x)| k == pkw || x == 0), "{}: {w:04X?}", m.name);
    }
}

/// Item 14 — the card acts on the drive's CONFIG.COMM_LOSS_REACTION: with the master's
/// Set_Prm reaction 0 ("the drive's own setting") DRIVE_CMD carries the drive's configured
/// reaction (here 1 = ramp stop, while the simulated drive's built-in action is "fault").
#[test]
fn the_drives_configured_comm_loss_reaction_is_applied() {
    let mut b = Bench::new();
    b.config(HostConfig { comm_loss_reaction: 1, ..HostConfig::DEFAULT });
    b.bring_up(module(1));
    b.cycles(&[0x04, 0x7E, 0x20, 0x00], 3);
    b.cycles(&[0x04, 0x7F, 0x20, 0x00], 80);
    assert_eq!(b.app.drive().image().command.comm_loss_reaction, 1);
    b.step(1100); // the DP watchdog (1 s) expires
    for _ in 0..80 {
        b.step(10);
    }
    assert!(b.app.drive().image().command.flags.contains(CommandFlags::COMM_LOSS));
    assert_eq!(b.app.drive().status().fault_code, 0, "ramp stop, no fault");
    assert_eq!(b.app.drive().actual_speed(), 0);
}

/// Item 14 — WEG P0313 options 3 / 4 / 5 (CFW-11 and CFW500 manuals, P0313: change to local,
/// change to local keeping commands and reference, fault) expressed through the drive's
/// CONFIG.COMM_LOSS_REACTION 5 / 6 / 7 (the DRIVE_CMD coding): the card takes the CONFIG
/// and DRIVE_CMD carries the reaction; 8 is no reaction, CONFIG is invalid.
#[test]
fn weg_p0313_options_3_to_5_through_the_drives_config() {
    for reaction in [5u8, 6, 7] {
        let mut b = Bench::new();
        b.config(HostConfig { comm_loss_reaction: reaction, ..HostConfig::DEFAULT });
        b.bring_up(module(1));
        b.cycles(&[0x04, 0x7E, 0x20, 0x00], 3);
        b.cycles(&[0x04, 0x7F, 0x20, 0x00], 20);
        assert_eq!(b.app.drive().image().command.comm_loss_reaction, reaction, "CONFIG reaction {reaction}");
    }
    assert!(!HostConfig { comm_loss_reaction: 8, ..HostConfig::DEFAULT }.is_valid());
}

/// Item 14 — CONFIG.COMM_LOSS_DELAY_MS: a loss shorter than the delay is bridged (DRIVE_CMD
/// keeps the last command without COMM_LOSS), then the loss command follows.
#[test]
fn the_comm_loss_delay_bridges_a_short_loss() {
    let mut b = Bench::new();
    b.config(HostConfig { comm_loss_delay_ms: 300, ..HostConfig::DEFAULT });
    b.bring_up(module(1));
    b.cycles(&[0x04, 0x7E, 0x20, 0x00], 3);
    b.cycles(&[0x04, 0x7F, 0x20, 0x00], 20);
    b.step(1100);
    let cmd = b.app.drive().image().command;
    assert!(!cmd.flags.contains(CommandFlags::COMM_LOSS) && cmd.flags.contains(CommandFlags::RUN));
    b.step(250);
    assert!(!b.app.drive().image().command.flags.contains(CommandFlags::COMM_LOSS), "still bridged");
    b.step(100);
    b.step(1); // the drive reads the DRIVE_CMD of the step before
    assert!(b.app.drive().image().command.flags.contains(CommandFlags::COMM_LOSS), "after 300 ms");
    assert!(b.app.runtime().stats().bridged > 0);
}

/// Item 11 — INVT CW b8 "enable writing (mainly through PKW1 to PKW4)" (INVT Table 2-5): a
/// PKW write (PKW1 = 4) with b8 = 0 is rejected (response 3; error 4 "operation failure" is
/// our choice, the manual names none) and writes nothing; with b8 = 1 it writes.
#[test]
fn invt_pkw_writes_need_cw_b8() {
    let mut b = Bench::new();
    b.bring_up(module(4001));
    let mut q = invt(5, 0);
    q[..8].copy_from_slice(&[0x00, 0x04, 0x00, 0x64, 0x00, 0x00, 0x00, 0x4D]); // P100 = 77
    let i = b.cycles(&q, 6);
    assert_eq!(i[..8], [0x00, 0x03, 0x00, 0x64, 0x00, 0x04, 0x00, 0x00]);
    assert_eq!(b.app.drive_params().get(100, 0), Some(50), "not written");
    q[8..10].copy_from_slice(&0x0105u16.to_be_bytes());
    let i = b.cycles(&q, 6);
    assert_eq!(i[..8], [0x00, 0x01, 0x00, 0x64, 0x00, 0x00, 0x00, 0x4D]);
    assert_eq!(b.app.drive_params().get(100, 0), Some(77));
}

/// Item 15 — the simulated drive's P0680 / P0681 / P10109 are live (they show what the master
/// reads cyclically), and a P0101 written through record 47 is the deceleration ramp.
#[test]
fn the_simulated_drive_parameters_are_live() {
    let mut b = Bench::new();
    let m = module(2105);
    b.bring_up_with(m, 0x80);
    let q = bytes(&[0x0017, 0x1000, 0x1234, 0x5678, 0x9ABC]);
    let i = b.cycles(&q, 80);
    let w = words(&i);
    let p = b.app.drive_params();
    assert_eq!(p.get(680, 0), Some(i64::from(w[0])), "P0680 = the status word");
    assert_eq!(p.get(681, 0), Some(i64::from(w[1] as i16)), "P0681 = the speed word");
    assert_eq!((p.get(10109, 0), p.get(10109, 2)), (Some(0x1234), Some(0x9ABC)), "P10109");
    // P0101 = 0.1 s: a stop from 50 % takes about 50 ms instead of the bench's 500 ms.
    b.write47(&[7, 2, 1, 1, 0x10, 1, 0, 101, 0, 0, 0x42, 1, 0, 1]);
    b.step(1);
    assert_eq!(b.read47(), [7, 2, 1, 1]);
    b.cycles(&bytes(&[0x0016, 0x1000, 0, 0, 0]), 8);
    assert_eq!(b.app.drive().actual_speed(), 0, "P0101 applied");
}

/// Item 9 — WEG's record-47 error list (CFW500 §5.2.3): a DS_Read before the response is ready
/// is C3h "response not available for the reading request" under a WEG telegram (B5h means
/// "modification not allowed" there); VACON / PROFIdrive keep B5h "state conflict".
#[test]
fn weg_read_before_ready_is_c3() {
    for (reference, code) in [(2103u16, 0xC3u8), (3100, 0xC3), (1, 0xB5)] {
        let mut b = Bench::new();
        b.bring_up_with(module(reference), 0x80);
        b.write47(&[1, 1, 1, 1, 0x10, 1, 0, 100, 0, 0]);
        assert_eq!(b.read47(), [0xDE, 0x80, code, 0x00], "{reference}");
        // The first job after a Chk_Cfg of a WEG telegram may wait behind the speed-reference
        // reads (item 10, one mailbox round trip each); meanwhile the same code.
        let mut r = vec![];
        for _ in 0..5 {
            b.step(1);
            r = b.read47();
            if r[0] != 0xDE {
                break;
            }
            assert_eq!(r, [0xDE, 0x80, code, 0x00], "{reference}");
        }
        assert_eq!(r, [1, 1, 1, 1, 0x42, 1, 0, 50]);
    }
}

/// Record 47: read `n` elements of `pnu` from `sub` on axis 1, waiting for a value from the
/// drive (DS_Read answered "not ready" meanwhile); the parameter response.
fn read_pnu(b: &mut Bench, pnu: u16, sub: u16, n: u8) -> Vec<u8> {
    let [p0, p1] = pnu.to_be_bytes();
    let [s0, s1] = sub.to_be_bytes();
    b.write47(&[9, 1, 1, 1, 0x10, n, p0, p1, s0, s1]);
    for _ in 0..10 {
        let r = b.read47();
        if r[0] != 0xDE {
            return r;
        }
        b.step(1);
    }
    panic!("no response for PNU {pnu}");
}

/// The words of a record-47 value response with one parameter (after `9 1 1 1 format n`).
fn values(r: &[u8]) -> Vec<u16> {
    assert_eq!(r[..4], [9, 1, 1, 1], "a positive read response: {r:02X?}");
    words(&r[6..])
}

/// Item 12 — P0922 in WEG's option coding under the WEG telegrams (CFW500 §4 P0922: 2 =
/// Standard Telegram 1, 3..8 = telegrams 103..108; CFW-11 §3 P0922: 1 = ST1, 2..9 =
/// telegrams 100..107), the telegram number for VACON (OPTE3/E5 Table 15). ST1 is WEG's
/// (CFW500 P0922 = 2) only with the manufacturer data profile (our reading, as item 5).
#[test]
fn p0922_uses_each_products_coding() {
    for (reference, profile, p0922) in [
        (3100u16, None, 2u16),
        (3107, None, 9),
        (2103, None, 3),
        (2108, None, 8),
        (1, Some(1), 2),
        (1, None, 1),
        (1100, None, 100),
    ] {
        let mut b = Bench::new();
        if let Some(p) = profile {
            b.config(HostConfig { profile: p, ..HostConfig::DEFAULT });
        }
        b.bring_up_with(module(reference), 0x80);
        b.step(1);
        assert_eq!(values(&read_pnu(&mut b, 922, 0, 1)), [p0922], "module {reference}");
    }
}

/// Item 12 — CFW-11 P0944 "0 to 1": 1 while the drive is in a fault, 0 after the reset (CFW-11
/// §4 P0944; the CFW500 manual has no P0944 — the same meaning for both WEG families). VACON
/// keeps PNU 944 the fault message counter (OPTE3/E5 §6.4.6: +1 per change of the buffer).
#[test]
fn p0944_is_a_fault_flag_for_weg_and_a_counter_for_vacon() {
    // Idle and fault-reset control words: WEG P0684 b7; PROFIdrive STW1 b7 with b10.
    for (reference, idle, reset, during, after) in [(3100u16, 0u16, 0x0080u16, 1u16, 0u16), (1, 0x0400, 0x0480, 1, 2)] {
        let mut b = Bench::new();
        b.bring_up_with(module(reference), 0x80);
        let mut q = vec![0u8; module(reference).outputs as usize];
        q[..2].copy_from_slice(&idle.to_be_bytes());
        b.cycles(&q, 3);
        b.app.drive_mut().inject_fault(0x2310, 0);
        b.cycles(&q, 3);
        assert_eq!(values(&read_pnu(&mut b, 944, 0, 1)), [during], "module {reference} in fault");
        let mut r = q.clone();
        r[..2].copy_from_slice(&reset.to_be_bytes());
        b.cycles(&r, 3);
        b.cycles(&q, 3);
        assert_eq!(b.app.drive().status().fault_code, 0);
        assert_eq!(values(&read_pnu(&mut b, 944, 0, 1)), [after], "module {reference} after the reset");
    }
}

/// Item 12 — PNU 964 per product: under a CFW-11 telegram WEG's P0964 (CFW-11 §4: five
/// subindices, manufacturer 367, drive unit type 4; subindex 5 does not exist), under a VACON
/// telegram OPTE3/E5 Table 110's manufacturer 0x01BA and drive unit type 2 (VACON 100
/// family); the version, the firmware date and the DO count stay the card's own.
#[test]
fn pnu_964_per_product() {
    let mut b = Bench::new();
    b.bring_up_with(module(3100), 0x80);
    b.step(1);
    assert_eq!(values(&read_pnu(&mut b, 964, 0, 5)), [367, 4, 1, 2026, 2211]);
    let r = read_pnu(&mut b, 964, 5, 1);
    assert_eq!(r[4..6], [0x44, 1], "error: {r:02X?}");
    assert_eq!(r[6..8], [0x00, 0x03], "0x03 invalid subindex");
    let mut b = Bench::new();
    b.bring_up_with(module(1100), 0x80);
    b.step(1);
    assert_eq!(values(&read_pnu(&mut b, 964, 0, 6)), [0x01BA, 2, 1, 2026, 2211, 1]);
}

/// Item 12 — PNU 915 / 916 follow the drive's active data profile (WEG P0741, CONFIG.PROFILE):
/// WEG 103 with the PROFIdrive profile lists STW1 / NSOLL_A (1, 5) and ZSW1 / NIST_A (2, 6),
/// with the manufacturer profile the non-profile words 118 / 120 and 119 / 121 (OPTE3/E5
/// Table 37 coding, `profile::telegram`).
#[test]
fn pnu_915_916_follow_the_data_profile() {
    for (profile, set, act) in [(0u8, [1u16, 5, 110], [2u16, 6, 100]), (1, [118, 120, 110], [119, 121, 100])] {
        let mut b = Bench::new();
        b.config(HostConfig { profile, ..HostConfig::DEFAULT });
        b.bring_up_with(module(2103), 0x80);
        b.cycles(&[0; 6], 2);
        assert_eq!(values(&read_pnu(&mut b, 915, 0, 3)), set, "profile {profile}");
        assert_eq!(values(&read_pnu(&mut b, 916, 0, 3)), act, "profile {profile}");
    }
}

/// Item 12 — record 48 read of P0965 (select `03 C5`, CFW500 §5.2.5) gives WEG's `03 29`
/// (CFW-11 P0965: profile 3 in the high byte, version 41 in the low byte, shown as 809).
#[test]
fn record_48_reads_p0965_as_one_word() {
    let mut b = Bench::new();
    b.bring_up_with(module(2103), 0x80);
    assert_eq!(b.c1(&[0x5F, 0, 48, 2, 0x03, 0xC5]), [0x5F, 0, 48, 2]);
    // SSAP, DSAP and the 6-octet response are 8 octets: the station answers in a fixed-length
    // SD3 frame (`A2 DA SA FC 33 33 5E 00 30 02 03 29 FCS 16`), not SD2; compare the PDU.
    assert_eq!(b.send(Some(51), Some(51), &[0x5E, 0, 48, 240]), [telegram::SC]);
    b.acyclic();
    let r = b.send(Some(51), Some(51), &[]);
    assert_eq!(r[r.len() - 8..r.len() - 2], [0x5E, 0, 48, 2, 0x03, 0x29], "{r:02X?}");
}

/// Item 14 — VACON PNU 10100 … 10108 (OPTE3/E5 Table 108): the cyclic words readable
/// acyclically. ST20 running at 50 %: STW1 / NSOLL_A as the master sent them, ZSW1 / NIST_A
/// as the card answered, the drive's current / active current / power / MELD_NAMUR as ST20
/// carries them (IAIST_GLATT … PIST_GLATT; the card does not filter, NIST_A_GLATT = NIST_A).
#[test]
fn vacon_pnus_10100_to_10108_show_the_cyclic_words() {
    let mut b = Bench::new();
    b.bring_up_with(module(20), 0x80);
    b.cycles(&bytes(&[0x047E, 0x2000]), 3);
    let i = b.cycles(&bytes(&[0x047F, 0x2000]), 80);
    let w = words(&i);
    let mut got = vec![];
    for pnu in 10100..=10108u16 {
        got.extend(values(&read_pnu(&mut b, pnu, 0, 1)));
    }
    let i = b.cycles(&bytes(&[0x047F, 0x2000]), 1);
    assert_eq!(words(&i), w, "steady state");
    assert_eq!(got[..2], [0x047F, 0x2000], "STW1, NSOLL_A");
    assert_eq!(got[2], w[0], "ZSW1");
    assert_eq!(got[3], w[1], "NIST_A");
    assert_eq!(got[4..7], w[2..5], "IAIST_GLATT, ITIST_GLATT, PIST_GLATT");
    assert_eq!(got[7], w[1], "NIST_A_GLATT");
    assert_eq!(got[8], w[5], "MELD_NAMUR");
    // Read-only.
    b.write47(&[8, 2, 1, 1, 0x10, 1, 0x27, 0x74, 0, 0, 0x42, 1, 0, 0]);
    let r = b.read47();
    assert_eq!(r[..2], [8, 0x82], "write refused: {r:02X?}");
}

/// Item 14 — VACON PNU 10119 "read fault history" (BYTE[40], 8-bit codes) and 10118 "clear
/// fault history" (OPTE3/E5 Table 108), served by the drive: an overcurrent trip is VACON's
/// F1, newest first; writing 10118 clears the history.
#[test]
fn vacon_fault_history_10118_10119() {
    let mut b = Bench::new();
    b.bring_up_with(module(1), 0x80);
    b.cycles(&[0x04, 0x7E, 0, 0], 3);
    b.app.drive_mut().inject_fault(0x2310, 0);
    b.cycles(&[0x04, 0xFE, 0, 0], 3);
    b.cycles(&[0x04, 0x7E, 0, 0], 3);
    b.app.drive_mut().inject_fault(0x4310, 0);
    b.cycles(&[0x04, 0x7E, 0, 0], 3);
    let r = read_pnu(&mut b, 10119, 0, 3);
    // Three octets and the pad octet that makes the value even (PROFIdrive value alignment).
    assert_eq!(r, [9, 1, 1, 1, 0x0A, 3, 16, 1, 0, 0], "F16 motor overtemperature, then F1 overcurrent");
    assert_eq!(b.app.drive().fault_history()[..2], [16, 1]);
    b.write47(&[8, 2, 1, 1, 0x10, 1, 0x27, 0x86, 0, 0, 0x42, 1, 0, 1]);
    for _ in 0..5 {
        b.step(1);
        if b.read47() == [8, 2, 1, 1] {
            break;
        }
    }
    assert_eq!(b.app.drive().fault_history(), &[0; 40]);
    assert_eq!(read_pnu(&mut b, 10119, 0, 2), [9, 1, 1, 1, 0x0A, 2, 0, 0]);
}

impl Bench {
    /// Set_Prm with the communication-loss reaction `reaction` (user parameter
    /// `PRM_COMM_LOSS_REACTION`), DP-V1 on, then Chk_Cfg `module`.
    fn bring_up_reaction(&mut self, module: &card::Module, reaction: u8) {
        let mut prm = vec![0x88, 1, 100, 11, (card::IDENT_NUMBER >> 8) as u8, card::IDENT_NUMBER as u8, 0];
        prm.extend_from_slice(&card::USER_PRM_DEFAULTS);
        prm[7] = 0x80;
        prm[7 + card::PRM_COMM_LOSS_REACTION.offset] = reaction;
        assert_eq!(self.srd(Some(61), &prm), [telegram::SC]);
        self.step(1);
        assert_eq!(self.srd(Some(62), module.cfg), [telegram::SC]);
        self.step(1);
        assert_eq!(self.node.slave().state(), DpState::DataExch);
    }

    /// No more telegrams: the DP watchdog (1 s) expires, and the drive reacts for `ms` more
    /// (10 ms steps).
    fn lose_the_master(&mut self, ms: u64) {
        for _ in 0..(1100 + ms) / 10 {
            self.step(10);
        }
    }
}

/// Item 14 — WEG P0313 options 3 / 4 / 5 (CFW500 §4 Table 4.1, CFW-11 Table 3.3.1) through
/// DRIVE_CMD, as Set_Prm reactions 5 / 6 / 7: "change to local" (the local place takes over:
/// the simulated drive's has no run command, it ramps down, no fault, P0680 shows local),
/// "change to local keeping commands and reference" (runs on), "causes a fault" (F239).
#[test]
fn weg_p0313_options_3_4_5() {
    for (reaction, runs, fault) in [(5u8, false, 0u16), (6, true, 0), (7, false, crate::drive::model::FAULT_OFFLINE)] {
        let mut b = Bench::new();
        b.bring_up_reaction(module(2103), reaction);
        b.cycles(&bytes(&[0x0017, 0x1000, 0]), 80);
        assert_eq!(b.app.drive().actual_speed(), 0x2000);
        b.lose_the_master(1000);
        let cmd = b.app.drive().image().command;
        assert!(cmd.flags.contains(CommandFlags::COMM_LOSS), "reaction {reaction}");
        assert_eq!(cmd.comm_loss_reaction, reaction);
        assert_eq!(b.app.drive().status().fault_code, fault, "reaction {reaction}");
        assert_eq!(b.app.drive().actual_speed() == 0x2000, runs, "reaction {reaction}");
        if reaction != 7 {
            let local = !b.app.drive().status().flags.contains(StatusFlags::FIELDBUS_CONTROL);
            assert!(local, "reaction {reaction}: the control place is local");
        }
    }
}

/// Item 14 — P0313 "with exception of option 'Causes a Fault', which blocks the equipment even
/// if it is not controlled by network" (CFW500 §4): with the drive in LOCAL (P0684 b4 = 0) a
/// lost master trips it with reaction 7, and ramp stop (1) does nothing to it.
#[test]
fn weg_p0313_fault_acts_without_network_control() {
    for (reaction, fault) in [(7u8, crate::drive::model::FAULT_OFFLINE), (1, 0)] {
        let mut b = Bench::new();
        b.bring_up_reaction(module(2103), reaction);
        b.cycles(&bytes(&[0x0007, 0x1000, 0]), 20);
        assert!(!b.app.drive().command().flags.contains(CommandFlags::FIELDBUS_CONTROL), "LOCAL");
        b.lose_the_master(200);
        assert_eq!(b.app.drive().status().fault_code, fault, "reaction {reaction}");
    }
}

/// Item 15 — VACON ID 733 "response to fieldbus fault" (OPTE3/E5 Table 141, VACON 100 family
/// coding), written through the PPO's PKW (Table 128 style, ID 733 = 0x2DD), is the drive's own
/// reaction when the master leaves it to the drive (Set_Prm reaction 0): 3 "fault: stop
/// function" trips at once and ramps down (pulses on until standstill), 2 "alarm + preset
/// frequency" runs on at the preset frequency without a fault, 0 "no action" runs on.
#[test]
fn vacon_id_733_is_the_drives_fieldbus_fault_response() {
    for value in [3u8, 2, 0] {
        let mut b = Bench::new();
        b.bring_up(module(101));
        let i = b.cycles(&ppo1([0x22, 0xDD, 0, 0, 0, 0, 0, value]), 6);
        assert_eq!(i[..2], [0x12, 0xDD], "ID 733 written ({:02X?})", &i[..8]);
        assert_eq!(b.app.drive().vacon_ids().get(733, 0), Some(i64::from(value)));
        let mut q = ppo1([0; 8]);
        q[10..12].copy_from_slice(&10_000u16.to_be_bytes());
        b.cycles(&q, 3);
        q[9] = 0x7F;
        b.cycles(&q, 120);
        assert_eq!(b.app.drive().actual_speed(), 0x4000, "ID 733 = {value}: running");
        b.lose_the_master(20);
        match value {
            3 => {
                assert_eq!(b.app.drive().status().fault_code, crate::drive::model::FAULT_OFFLINE);
                assert!(b.app.drive().model().modulating(), "stop function: ramping");
                b.lose_the_master(1500);
                assert!(!b.app.drive().model().modulating());
                assert_eq!(b.app.drive().actual_speed(), 0);
            }
            2 => {
                b.lose_the_master(1500);
                assert_eq!(b.app.drive().status().fault_code, 0);
                assert_eq!(b.app.drive().actual_speed(), b.app.drive().model().config().jog_speed, "preset");
            }
            _ => {
                b.lose_the_master(500);
                assert_eq!(b.app.drive().status().fault_code, 0);
                assert_eq!(b.app.drive().actual_speed(), 0x4000);
            }
        }
    }
}

/// INVT output image: PKW `pkw`, CW `cw`, PZD2..PZD12 `pzd`.
fn invt_q(pkw: [u8; 8], cw: u16, pzd: &[u16]) -> Vec<u8> {
    let mut q = invt(cw, 0);
    q[..8].copy_from_slice(&pkw);
    for (k, w) in pzd.iter().enumerate() {
        q[10 + 2 * k..12 + 2 * k].copy_from_slice(&w.to_be_bytes());
    }
    q
}

/// Item 11 — the INVT PZD mapping P15.02–P15.23 (INVT Table 2-6 / 2-8), set through the PKW
/// (PKW1 = 4 write, address group × 256 + code: P15.02 = 0x0F02): P15.02 = 0 "invalid" →
/// PZD2 sets no frequency; P15.03 = 1 → PZD3 is the set frequency (0.01 Hz); P15.14 = 8 →
/// PZD3 of the response is the rotating speed in rpm (the manual's example 1).
#[test]
fn invt_pzd_mapping_p15() {
    let mut b = Bench::new();
    b.bring_up(module(4001));
    let w = |pnu: u16, v: u16| {
        let [a0, a1] = pnu.to_be_bytes();
        let [v0, v1] = v.to_be_bytes();
        [0x00, 0x04, a0, a1, 0x00, 0x00, v0, v1]
    };
    // The factory-commissioned drive: PZD2 is the set frequency.
    b.cycles(&invt_q([0; 8], 1, &[2500, 1000]), 80);
    assert_eq!(b.app.drive().actual_speed(), 0x2000);
    // P15.02 = 0 (invalid): PZD2 no longer sets the frequency.
    let i = b.cycles(&invt_q(w(0x0F02, 0), 0x0101, &[2500, 1000]), 80);
    assert_eq!(i[..4], [0x00, 0x01, 0x0F, 0x02], "written ({:02X?})", &i[..8]);
    assert_eq!(b.app.drive_params().get(0x0F02, 0), Some(0));
    assert_eq!(b.app.drive().actual_speed(), 0, "no frequency from the bus");
    // P15.03 = 1: PZD3 (10.00 Hz of Fmax 50.00 Hz = 20 %) is the set frequency.
    b.cycles(&invt_q(w(0x0F03, 1), 0x0101, &[2500, 1000]), 80);
    assert_eq!(b.app.drive().actual_speed(), 0x0CCD, "1000 / 5000 of 0x4000, rounded");
    // P15.14 = 8: PZD3 of the response is the speed in rpm (20 % of 1800 rpm).
    let i = b.cycles(&invt_q(w(0x0F0E, 8), 0x0101, &[2500, 1000]), 10);
    assert_eq!(words(&i)[6], 360, "rpm (0x0CCD of 1800 rpm)");
    // P15.13 (PZD2 of the response, the card's running frequency) accepts only 1.
    let i = b.cycles(&invt_q(w(0x0F0D, 0), 0x0101, &[2500, 1000]), 10);
    assert_eq!(i[..2], [0x00, 0x03], "refused ({:02X?})", &i[..8]);
}

/// Item 11 — INVT heartbeat (Table 2-5 CW b15 / Table 2-7 SW b15): the SW echoes b15; a PLC
/// that toggles b15 and then stops toggling for `INVT_HEARTBEAT_TIMEOUT` (1 s, our choice) is
/// a communication loss (the drive's reaction: here a trip with the fieldbus fault); toggling
/// again ends it, and the motor needs a fault reset and a new run command.
#[test]
fn invt_heartbeat_is_supervised() {
    use crate::profile::runtime::INVT_HEARTBEAT_TIMEOUT;
    let mut b = Bench::new();
    b.bring_up(module(4001));
    let mut hb = 0u16;
    for k in 0..40 {
        let before = hb;
        hb ^= 0x8000;
        let i = b.cycle(&invt(1 | hb, 2500), 20);
        if k > 0 {
            // The answer to Data_Exchange n carries the reaction to the outputs of n − 1.
            assert_eq!(words(&i)[4] & 0x8000, before, "SW b15 echoes CW b15");
        }
    }
    assert_eq!(b.app.drive().actual_speed(), 0x2000);
    // A PLC holding b15 (here at its last value) for longer than the timeout.
    let held = INVT_HEARTBEAT_TIMEOUT.as_micros() as usize / 10_000;
    b.cycles(&invt(1 | hb, 2500), held - 10);
    assert!(!b.app.drive().command().flags.contains(CommandFlags::COMM_LOSS), "within the timeout");
    b.cycles(&invt(1 | hb, 2500), 20);
    assert!(b.app.drive().command().flags.contains(CommandFlags::COMM_LOSS), "heartbeat lost");
    assert_eq!(b.app.runtime().stats().heartbeat_losses, 1);
    assert_eq!(b.app.drive().status().fault_code, crate::drive::model::FAULT_FIELDBUS);
    // Toggling again: the communication is back.
    for _ in 0..5 {
        hb ^= 0x8000;
        b.cycle(&invt(7 | hb, 2500), 20);
    }
    assert!(!b.app.drive().command().flags.contains(CommandFlags::COMM_LOSS));
    assert_eq!(b.app.drive().status().fault_code, 0, "code 7 reset it");
    // A PLC that never toggles (b15 held at 1) is not supervised.
    let mut b = Bench::new();
    b.bring_up(module(4001));
    b.cycles(&invt(0x8001, 2500), 300);
    assert_eq!(b.app.runtime().stats().heartbeat_losses, 0);
    assert_eq!(b.app.drive().actual_speed(), 0x2000);
}

/// Item 10 — the speed references come from the drive's parameters (`profile::references`,
/// read through the mailbox after the selection), not a fixed 50 Hz:
/// * VACON PPO (OPTE3/E5 §6.3.5 Table 29: 0..10000 = minimum..maximum frequency): ID 102 =
///   25.00 Hz with the motor's nominal frequency ID 111 = 50.00 Hz (N2 0x4000) → HSW 10000 is
///   N2 0x2000;
/// * WEG PROFIdrive (CFW500 P0741: 16384 = P0134): P0134 = 900 rpm of the synchronous 1800 rpm
///   (P10111) at P0403 = 60 Hz → 16384 is 30 Hz = N2 0x2000; the 13-bit scale (8192 = P0403)
///   stays N2 0x4000;
/// * INVT (Table 2-6: 0..Fmax): P00.03 Fmax = 100.00 Hz, P02.02 rated 50.00 Hz → 75.00 Hz is
///   N2 0x6000 (with the 50 Hz default it was cut to Fmax, 0x4000).
#[test]
fn speed_references_come_from_the_drive() {
    use crate::drive::params;
    let mut b = Bench::new();
    b.app.drive_mut().vacon_ids_mut().set(params::ID_MAX_FREQUENCY, 0, 2500).unwrap();
    b.bring_up(module(101));
    let mut q = ppo1([0; 8]);
    q[10..12].copy_from_slice(&10_000u16.to_be_bytes());
    b.cycles(&q, 5);
    assert_eq!(b.app.references().stats().applied, 1);
    assert_eq!(b.app.runtime().scales().bypass_max, 2500);
    q[9] = 0x7F;
    b.cycles(&q, 5);
    assert_eq!(b.app.drive().command().speed_setpoint, 0x2000, "VACON: HSW 10000 = 25 Hz");

    let mut b = Bench::new();
    b.app.drive_mut().params_mut().set(params::P_RATED_FREQUENCY, 0, 60).unwrap();
    b.app.drive_mut().params_mut().set(params::P_MAX_SPEED, 0, 900).unwrap();
    b.config(HostConfig { profile: 0, ..HostConfig::DEFAULT });
    b.bring_up(module(2103));
    b.cycles(&bytes(&[0x047E, 0x4000, 0]), 5);
    b.cycles(&bytes(&[0x047F, 0x4000, 0]), 3);
    assert_eq!(b.app.drive().command().speed_setpoint, 0x2000, "WEG PROFIdrive: 16384 = P0134 = 30 Hz");
    let mut b = Bench::new();
    b.app.drive_mut().params_mut().set(params::P_RATED_FREQUENCY, 0, 60).unwrap();
    b.bring_up(module(2103));
    b.cycles(&bytes(&[0x0017, 0x2000, 0]), 5);
    assert_eq!(b.app.drive().command().speed_setpoint, 0x4000, "WEG 13 bits: 8192 = P0403 = N2 100 %");

    let mut b = Bench::new();
    b.app.drive_mut().params_mut().set(params::P_INVT_FMAX, 0, 10_000).unwrap();
    b.bring_up(module(4001));
    b.cycles(&invt(1, 7500), 5);
    assert_eq!(b.app.drive().command().speed_setpoint, 0x6000, "INVT: 75 Hz of Fmax 100 Hz, N2 100 % = 50 Hz");
    assert_eq!(b.app.references().stats().gave_up, 0);
}
