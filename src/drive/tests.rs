use super::*;
use crate::dpm::Dpm;

/// The drive behind a DPM whose outputs the test writes as the card would.
struct Rig {
    dpm: Dpm,
    drive: SimDrive,
    now: Instant,
    telegram: Telegram,
}

impl Rig {
    fn new(telegram: Telegram) -> Self {
        let cfg = DriveConfig {
            ramp_time: Duration::from_millis(1000),
            quick_stop_time: Duration::from_millis(100),
            ..DriveConfig::DEFAULT
        };
        Rig { dpm: Dpm::new(), drive: SimDrive::new(cfg), now: Instant::from_millis(0), telegram }
    }

    /// Outputs STW1 / NSOLL_A (after the PKW), then `ms` of drive time in 1 ms steps.
    fn run(&mut self, stw1: u16, nsoll: i16, ms: u64) {
        let pkw = self.telegram.pkw_words();
        let mut b = [0u8; 28];
        b[2 * pkw..2 * pkw + 2].copy_from_slice(&stw1.to_be_bytes());
        b[2 * pkw + 2..2 * pkw + 4].copy_from_slice(&nsoll.to_be_bytes());
        let n = 2 * (pkw + self.telegram.pzd_words());
        self.dpm.card().write_outputs(&ProcessData::new(self.telegram, PdFlags::DATA_EXCHANGE, &b[..n]));
        self.tick(ms.max(1));
    }

    /// `ms` of drive time in 1 ms steps, outputs unchanged.
    fn tick(&mut self, ms: u64) {
        for _ in 0..ms {
            self.now = self.now + Duration::from_millis(1);
            self.drive.step(self.now, &mut self.dpm.host());
        }
    }

    fn inputs(&self) -> ProcessData {
        self.dpm.inputs().unwrap()
    }
}

#[test]
fn ramp_takes_the_configured_time() {
    let mut r = Rig::new(Telegram::Standard(1));
    r.run(0x047E, 0x4000, 1);
    r.run(0x047F, 0x4000, 250);
    // 250 ms of a 1 s ramp: 25 % = 0x1000 (exact: the ramp integrates in micro-counts).
    assert_eq!(r.drive.actual_speed(), 0x1000);
    assert_eq!(r.inputs().word(1), 0x1000);
    r.run(0x047F, 0x4000, 750);
    assert_eq!(r.drive.actual_speed(), 0x4000);
    let z = r.inputs().word(0);
    assert_eq!(z, 0x0737, "S4, no OFF2/OFF3, at setpoint, control requested, n reached");
}

#[test]
fn reverse_and_setpoint_changes_follow_the_ramp() {
    let mut r = Rig::new(Telegram::Standard(1));
    r.run(0x047E, 0, 1);
    r.run(0x047F, -0x2000, 600);
    assert_eq!(r.drive.actual_speed(), -0x2000);
    r.run(0x047F, 0x2000, 500);
    assert_eq!(r.drive.actual_speed(), 0x0000, "half way: 0.5 s covers 50 % of the 100 % swing");
    r.run(0x047F, 0x2000, 500);
    assert_eq!(r.drive.actual_speed(), 0x2000);
}

#[test]
fn control_word_bits_4_5_6() {
    let mut r = Rig::new(Telegram::Standard(1));
    r.run(0x047E, 0x4000, 1);
    r.run(0x047F, 0x4000, 500);
    let n = r.drive.actual_speed();
    // b5 = 0: hold the ramp.
    r.run(0x045F, 0x4000, 200);
    assert_eq!(r.drive.actual_speed(), n);
    // b6 = 0: setpoint 0 along the ramp.
    r.run(0x043F, 0x4000, 100);
    assert_eq!(r.drive.actual_speed(), n - 0x0667, "0.1 s of the 1 s ramp: 1638.4 counts");
    // b4 = 0: quick to 0 (0.1 s from 100 %).
    r.run(0x046F, 0x4000, 100);
    assert_eq!(r.drive.actual_speed(), 0);
    assert_eq!(r.drive.state(), DriveState::Operation);
}

#[test]
fn stops_off1_off2_off3() {
    let mut r = Rig::new(Telegram::Standard(1));
    r.run(0x047E, 0x4000, 1);
    r.run(0x047F, 0x4000, 1000);
    r.run(0x047B, 0x4000, 50); // OFF3: quick stop
    assert_eq!(r.drive.state(), DriveState::SwitchingOff(StopKind::Quick));
    assert_eq!(r.inputs().word(0) & 0x0027, 0x0003, "S5: b0, b1, quick stop active");
    r.run(0x047B, 0x4000, 60);
    assert_eq!(r.drive.state(), DriveState::SwitchingOnInhibited);
    r.run(0x047E, 0x4000, 1);
    r.run(0x047F, 0x4000, 1000);
    r.run(0x047D, 0x4000, 1); // OFF2: coast
    assert_eq!((r.drive.state(), r.drive.actual_speed()), (DriveState::SwitchingOnInhibited, 0));
    assert_eq!(r.inputs().word(0) & 0x0050, 0x0040, "S1, coast stop active");
}

#[test]
fn losing_plc_control_while_running_is_a_fault() {
    let mut r = Rig::new(Telegram::Standard(1));
    r.run(0x047E, 0x4000, 1);
    r.run(0x047F, 0x4000, 100);
    // The card clears the outputs (watchdog, Clear): STW1 = 0, b10 = 0.
    r.run(0x0000, 0, 1);
    assert_eq!((r.drive.state(), r.drive.fault()), (DriveState::Fault, Some(FaultCause::ControlLost)));
    assert_eq!(r.inputs().word(0) & 0x000F, 0x0008);
    r.run(0x047E, 0, 5);
    assert_eq!(r.drive.state(), DriveState::Fault, "no acknowledge edge yet");
    r.run(0x04FE, 0, 5);
    assert_eq!((r.drive.state(), r.drive.fault()), (DriveState::ReadyToSwitchOn, None));
    // Not running: b10 = 0 leaves the state alone.
    r.run(0x0000, 0, 5);
    assert_eq!(r.drive.state(), DriveState::ReadyToSwitchOn);
}

#[test]
fn ppo_words_after_the_pkw() {
    let mut r = Rig::new(Telegram::Ppo(2));
    r.run(0x047E, 0x1000, 2);
    let i = r.inputs();
    assert_eq!(i.bytes().len(), 20);
    assert_eq!((0..4).map(|k| i.word(k)).collect::<Vec<_>>(), [0, 0, 0, 0], "PKW = 0");
    assert_eq!(i.word(4) & 0x0277, 0x0231, "ZSW in S2");
    r.run(0x047F, 0x1000, 1000);
    assert_eq!(r.inputs().word(5), 0x1000, "HIW");
}

#[test]
fn inputs_are_written_per_new_output_image_or_change() {
    let mut r = Rig::new(Telegram::Standard(1));
    r.run(0x047E, 0, 1);
    let s1 = r.inputs().seq;
    r.tick(10); // same outputs block, nothing changes: no new write
    assert_eq!(r.inputs().seq, s1);
    r.run(0x047E, 0, 1); // a new OUTPUTS write (new cycle): answered
    assert_eq!(r.inputs().seq, s1.wrapping_add(1));
}

#[test]
fn injected_fault_and_warning() {
    let mut r = Rig::new(Telegram::Standard(1));
    r.run(0x047E, 0, 1);
    r.drive.set_warning(true);
    r.drive.inject_fault();
    r.run(0x047E, 0, 1);
    assert_eq!(r.inputs().word(0) & 0x0088, 0x0088);
    r.run(0x04FE, 0, 1);
    assert_eq!(r.drive.state(), DriveState::ReadyToSwitchOn);
}
