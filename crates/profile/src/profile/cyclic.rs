//! The cyclic engine (issue 6): one bus cycle of process data through the active telegram,
//! sans-IO. In: the master's output image, the drive's [`DriveStatus`], the drive's raw PZD
//! words and the PKW server's response. Out: the input image for the master, the
//! [`DriveCommand`], the raw PZD words for the drive and the PKW request.
//!
//! Operate modes (OPTE3/E5 §5.1.1–5.1.5, Set_Prm user parameter `card::PRM_OPERATE_MODE`,
//! Table 13):
//!
//! * **PROFIdrive** (§5.1.1): the [`ControlProfile`] turns the control word and main setpoint
//!   into the [`DriveCommand`] and builds the status word and main actual value from the
//!   [`DriveStatus`]; ST20's extra words come from the status (IAIST_GLATT = current,
//!   ITIST_GLATT = torque, PIST_GLATT = power, MELD_NAMUR = namur). Programmable words pass
//!   raw both ways ([`Cycle::drive_words`] out, `drive_words` in).
//! * **Bypass** (§5.1.2, §6.7): every PZD word passes unchanged both ways — the drive gets
//!   the whole output PZD as [`Cycle::drive_words`] and answers the whole input PZD in
//!   `drive_words`; no [`DriveCommand`] (the drive reads the raw words itself) except the
//!   communication-loss one. The drive interface (DPM `DRIVE_CMD.EXTRA` / `DRIVE_STATE.EXTRA`)
//!   carries [`MAX_DRIVE_WORDS`] = 16 words each way; VACON telegram 139 has 18, so in Bypass
//!   the drive gets words 1..16 — the control word, the setpoint and PDO1..PDO14 — and PDO15 /
//!   PDO16 stay on the card (counted in [`CyclicStats::words_cut`]); PDI15 / PDI16 read 0. In
//!   PROFIdrive mode 139's control word and setpoint go through the [`DriveCommand`], so its
//!   16 programmable words all fit.
//! * **Echo** (§5.1.3, §6.8): the input image is the output image; nothing reaches the drive.
//!
//! ST20 runs in PROFIdrive mode only (§5.1.5): [`Cyclic::new`] refuses Bypass / Echo with it
//! ([`CyclicError::ModeNotAllowed`]). A mode forced by the master (Remote Bypass / Echo in
//! Set_Prm) never gets here with ST20: Chk_Cfg already refused the pair with Cfg_Fault
//! (the card's Chk_Cfg rule, `card::OperateModePolicy`). The error is for a mode chosen locally in the drive (operate
//! mode 0 "Local"): the caller then keeps the card's fault image (ZSW1 fault) and reports it.
//!
//! The PKW channel (PPO 1/2/5, INVT) is the same in PROFIdrive and Bypass mode: the request
//! goes to the PKW server, its response into the input image.

use super::drive_if::{ControlProfile, DriveCommand, DriveStatus};
use super::telegram::{Layout, Word, PZD_SIGNALS};
use crate::profile::selection::Telegram;

/// The raw words the drive interface carries each way (DPM `EXTRA`, 16 words): the most
/// programmable words of any telegram.
pub const MAX_DRIVE_WORDS: usize = super::telegram::MAX_PROGRAMMABLE;

/// The largest image in bytes (PKW + 18 PZD words).
pub const MAX_IMAGE: usize = 2 * (4 + PZD_SIGNALS);

/// Operate mode (OPTE3/E5 §5.1, Table 13 values 1..=3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum OperateMode {
    /// 1: the profile driver in the card (§5.1.1).
    Profidrive,
    /// 2: raw words to and from the drive (§5.1.2).
    Bypass,
    /// 3: outputs echoed as inputs (§5.1.3).
    Echo,
}

impl OperateMode {
    /// The mode of a Set_Prm / drive code 1..=3 (0 "Local" and anything else: `None`, the
    /// drive's own setting decides).
    pub const fn from_code(code: u8) -> Option<OperateMode> {
        match code {
            1 => Some(OperateMode::Profidrive),
            2 => Some(OperateMode::Bypass),
            3 => Some(OperateMode::Echo),
            _ => None,
        }
    }
}

/// Why the engine cannot run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum CyclicError {
    /// No layout is known for the telegram.
    UnknownTelegram,
    /// Bypass or Echo with Standard Telegram 20 (OPTE3/E5 §5.1.5).
    ModeNotAllowed,
}

/// What the drive side gives the engine for one cycle.
#[derive(Debug, Clone, Copy)]
pub struct DriveSide<'a> {
    /// The drive's latest status.
    pub status: &'a DriveStatus,
    /// The drive's raw input words: the programmable input words (PROFIdrive mode), every
    /// input PZD word (Bypass). Missing words read 0, extra words are ignored.
    pub words: &'a [u16],
    /// The PKW server's response (PKE, IND, PWE high, PWE low; big-endian bytes).
    pub pkw_response: [u8; 8],
}

/// The result of one cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Cycle {
    inputs: [u8; MAX_IMAGE],
    input_len: usize,
    /// The command for the drive (PROFIdrive mode; Bypass only while the communication is
    /// lost; never in Echo).
    pub command: Option<DriveCommand>,
    words: [u16; PZD_SIGNALS],
    word_count: usize,
    /// The PKW request for the PKW server (telegrams with PKW, not in Echo, not while the
    /// communication is lost).
    pub pkw_request: Option<[u8; 8]>,
    /// The control word of the output image the cycle evaluated (the first PZD word; INVT
    /// CW b8 "enable writing" gates the PKW writes).
    pub control_word: u16,
    /// The main setpoint word of that image (the second PZD word; PNU 10101).
    pub setpoint_word: u16,
}

impl Cycle {
    /// The input image for the master (the telegram's input length).
    pub fn inputs(&self) -> &[u8] {
        &self.inputs[..self.input_len]
    }
    /// The raw words for the drive: the programmable output words (PROFIdrive mode), every
    /// output PZD word (Bypass), none (Echo).
    pub fn drive_words(&self) -> &[u16] {
        &self.words[..self.word_count]
    }
}

/// Counters.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct CyclicStats {
    /// Output images of the wrong length (refused, the last good one stays in force).
    pub wrong_length: u32,
    /// Cycles run while the communication was lost.
    pub comm_lost: u32,
    /// Bypass cycles whose output PZD had more words than the drive interface carries
    /// ([`MAX_DRIVE_WORDS`]; VACON 139: PDO15 / PDO16 not passed).
    pub words_cut: u32,
}

/// The cyclic engine for one telegram and operate mode.
#[derive(Debug, Clone)]
pub struct Cyclic {
    layout: Layout,
    mode: OperateMode,
    comm_loss_reaction: u8,
    last: [u8; MAX_IMAGE],
    have_last: bool,
    /// The next [`Self::run`] is a Clear cycle ([`Self::clear`]).
    clear_next: bool,
    stats: CyclicStats,
}

#[inline(never)]
fn word(b: &[u8], i: usize) -> u16 {
    b.get(2 * i..2 * i + 2).map_or(0, |w| u16::from_be_bytes([w[0], w[1]]))
}

impl Cyclic {
    /// An engine for `telegram` in `mode`; `comm_loss_reaction` is the Set_Prm user
    /// parameter `card::PRM_COMM_LOSS_REACTION` copied into every [`DriveCommand`].
    pub fn new(telegram: Telegram, mode: OperateMode, comm_loss_reaction: u8) -> Result<Cyclic, CyclicError> {
        let layout = Layout::of(telegram).ok_or(CyclicError::UnknownTelegram)?;
        if layout.is_st20() && mode != OperateMode::Profidrive {
            return Err(CyclicError::ModeNotAllowed);
        }
        Ok(Cyclic {
            layout,
            mode,
            comm_loss_reaction,
            last: [0; MAX_IMAGE],
            have_last: false,
            clear_next: false,
            stats: CyclicStats::default(),
        })
    }

    /// The layout in force.
    pub fn layout(&self) -> &Layout {
        &self.layout
    }
    /// The operate mode in force.
    pub fn mode(&self) -> OperateMode {
        self.mode
    }
    /// Counters.
    pub fn stats(&self) -> CyclicStats {
        self.stats
    }

    /// A new output image from the master. An image of the wrong length is refused (counted;
    /// `None`) and the last good one stays in force.
    pub fn exchange(
        &mut self,
        profile: &mut impl ControlProfile,
        outputs: &[u8],
        drive: DriveSide<'_>,
    ) -> Option<Cycle> {
        if outputs.len() != self.layout.output_bytes() {
            self.stats.wrong_length = self.stats.wrong_length.wrapping_add(1);
            return None;
        }
        self.last[..outputs.len()].copy_from_slice(outputs);
        self.have_last = true;
        Some(self.run(profile, drive, false))
    }

    /// A housekeeping step with the last output image (all zeros before the first), so
    /// transitions that wait for the drive happen without new bus traffic. Sends no PKW
    /// request (the server already has it).
    pub fn step(&mut self, profile: &mut impl ControlProfile, drive: DriveSide<'_>) -> Cycle {
        let mut c = self.run(profile, drive, false);
        c.pkw_request = None;
        c
    }

    /// The communication is lost (DP watchdog expired, master in Clear, master gone): the
    /// profile's [`ControlProfile::comm_lost`] command (Bypass: a communication-loss
    /// command), the last output words stay with the drive, no PKW request.
    pub fn comm_lost(&mut self, profile: &mut impl ControlProfile, drive: DriveSide<'_>) -> Cycle {
        self.stats.comm_lost = self.stats.comm_lost.wrapping_add(1);
        self.run(profile, drive, true)
    }

    /// The master is in Clear: as [`Self::comm_lost`], with the profile's
    /// [`ControlProfile::clear`] (its reaction to the zero outputs of Clear).
    pub fn clear(&mut self, profile: &mut impl ControlProfile, drive: DriveSide<'_>) -> Cycle {
        self.stats.comm_lost = self.stats.comm_lost.wrapping_add(1);
        self.clear_next = true;
        let c = self.run(profile, drive, true);
        self.clear_next = false;
        c
    }

    /// The master's outputs are held back (the I/O update delay after going online, CFW-11
    /// P0799): a new image of the right length (`outputs`) is only kept for
    /// [`Self::resume`]; the inputs come from the drive's latest status as in
    /// [`Self::comm_lost`] (the profile keeps its state); the command and the drive's words
    /// are those of `before` (the previous cycle; none: no command, zero words); no PKW
    /// request; not counted as a loss.
    pub fn hold(
        &mut self,
        profile: &mut impl ControlProfile,
        outputs: Option<&[u8]>,
        drive: DriveSide<'_>,
        before: Option<&Cycle>,
    ) -> Cycle {
        let mut c = self.run(profile, drive, true);
        if let Some(out) = outputs.filter(|o| o.len() == self.layout.output_bytes()) {
            self.last[..out.len()].copy_from_slice(out);
            self.have_last = true;
        }
        match before {
            Some(b) => {
                c.command = b.command;
                c.words = b.words;
                c.word_count = b.word_count;
            }
            None => {
                c.command = c.command.map(|_| DriveCommand::default());
                c.words = [0; PZD_SIGNALS];
            }
        }
        c
    }

    /// The hold is over: the last output image (the newest one kept by [`Self::hold`]) is
    /// evaluated like a new one, PKW request included.
    pub fn resume(&mut self, profile: &mut impl ControlProfile, drive: DriveSide<'_>) -> Cycle {
        self.run(profile, drive, false)
    }

    fn run(&mut self, profile: &mut impl ControlProfile, drive: DriveSide<'_>, lost: bool) -> Cycle {
        let l = self.layout;
        let out = &self.last[..l.output_bytes()];
        let mut c = Cycle {
            inputs: [0; MAX_IMAGE],
            input_len: l.input_bytes(),
            command: None,
            words: [0; PZD_SIGNALS],
            word_count: 0,
            pkw_request: None,
            control_word: word(out, l.pkw),
            setpoint_word: word(out, l.pkw + 1),
        };
        if self.mode == OperateMode::Echo {
            // Both lengths are equal: ST20 (the only asymmetric telegram) is refused in new().
            c.inputs[..out.len()].copy_from_slice(out);
            return c;
        }
        let pkw_bytes = 2 * l.pkw;
        if l.pkw > 0 {
            c.inputs[..pkw_bytes].copy_from_slice(&drive.pkw_response);
            if !lost && self.have_last {
                let mut req = [0u8; 8];
                req.copy_from_slice(&out[..8]);
                c.pkw_request = Some(req);
            }
        }
        let put = |c: &mut Cycle, i: usize, w: u16| c.inputs[2 * i..2 * i + 2].copy_from_slice(&w.to_be_bytes());
        let from_drive = |k: usize| drive.words.get(k).copied().unwrap_or(0);
        match self.mode {
            OperateMode::Bypass => {
                for k in 0..l.pzd_out {
                    c.words[k] = word(out, l.pkw + k);
                }
                c.word_count = l.pzd_out;
                for k in 0..l.pzd_in {
                    put(&mut c, l.pkw + k, from_drive(k));
                }
                if lost {
                    let mut cmd = profile.comm_lost(drive.status);
                    cmd.comm_loss_reaction = self.comm_loss_reaction;
                    c.command = Some(cmd);
                }
                if l.pzd_out > MAX_DRIVE_WORDS {
                    // VACON 139 (18 words): the drive interface carries 16; PDO15 / PDO16 stay
                    // on the card (module docs, "Bypass").
                    self.stats.words_cut = self.stats.words_cut.wrapping_add(1);
                    c.word_count = MAX_DRIVE_WORDS;
                }
            }
            OperateMode::Profidrive | OperateMode::Echo => {
                let mut cmd = if lost && self.clear_next {
                    profile.clear(drive.status)
                } else if lost {
                    profile.comm_lost(drive.status)
                } else {
                    profile.command(word(out, l.pkw), word(out, l.pkw + 1), drive.status)
                };
                cmd.comm_loss_reaction = self.comm_loss_reaction;
                c.command = Some(cmd);
                for k in 0..l.programmable_out() {
                    c.words[k] = word(out, l.pkw + 2 + k);
                }
                c.word_count = l.programmable_out();
                let s = drive.status;
                for i in l.pkw..l.pkw + l.pzd_in {
                    let w = match l.input_word(i) {
                        Some(Word::Status) => profile.status_word(s),
                        Some(Word::MainActual) => profile.actual_value(s),
                        Some(Word::OutputCurrent) => s.current as u16,
                        Some(Word::ActiveCurrent) => s.torque as u16,
                        Some(Word::ActivePower) => s.power as u16,
                        Some(Word::MeldNamur) => s.namur,
                        Some(Word::Programmable(n)) => from_drive(usize::from(n) - 1),
                        _ => 0,
                    };
                    put(&mut c, i, w);
                }
            }
        }
        c
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::profile::drive_if::{CommandFlags, StatusFlags};
    use crate::profile::selection::Family;

    /// A stub profile: RUN = control word b0, the setpoint passes as N2; status word = the
    /// drive's flags, actual = its speed. Logs what it was asked.
    #[derive(Default)]
    struct Stub {
        calls: Vec<(u16, u16)>,
        lost: u32,
    }

    impl ControlProfile for Stub {
        fn command(&mut self, cw: u16, setpoint: u16, _drive: &DriveStatus) -> DriveCommand {
            self.calls.push((cw, setpoint));
            let mut flags = CommandFlags::FIELDBUS_CONTROL;
            flags.set(CommandFlags::RUN, cw & 1 != 0);
            DriveCommand { flags, speed_setpoint: setpoint as i16, ..DriveCommand::default() }
        }
        fn comm_lost(&mut self, _drive: &DriveStatus) -> DriveCommand {
            self.lost += 1;
            DriveCommand { flags: CommandFlags::COMM_LOSS, ..DriveCommand::default() }
        }
        fn status_word(&self, drive: &DriveStatus) -> u16 {
            0x8000 | drive.flags.bits()
        }
        fn actual_value(&self, drive: &DriveStatus) -> u16 {
            drive.speed as u16
        }
    }

    fn status() -> DriveStatus {
        DriveStatus {
            flags: StatusFlags::READY | StatusFlags::RUNNING,
            speed: 0x2000,
            current: 0x1111,
            torque: -0x0222,
            power: 0x0333,
            namur: 0x8000,
            ..DriveStatus::default()
        }
    }

    fn words(b: &[u8]) -> Vec<u16> {
        b.chunks(2).map(|w| u16::from_be_bytes([w[0], w[1]])).collect()
    }

    fn bytes(w: &[u16]) -> Vec<u8> {
        w.iter().flat_map(|w| w.to_be_bytes()).collect()
    }

    const PKW_RESP: [u8; 8] = [0x10, 0x02, 0, 0, 0, 0, 0x12, 0x34];

    #[test]
    fn st1_profidrive() {
        let mut e = Cyclic::new(Telegram::Standard(1), OperateMode::Profidrive, 2).unwrap();
        let mut p = Stub::default();
        let s = status();
        let c = e
            .exchange(&mut p, &bytes(&[0x047F, 0x4000]), DriveSide { status: &s, words: &[], pkw_response: [0; 8] })
            .unwrap();
        assert_eq!(p.calls, [(0x047F, 0x4000)]);
        let cmd = c.command.unwrap();
        assert!(cmd.flags.contains(CommandFlags::RUN));
        assert_eq!((cmd.speed_setpoint, cmd.comm_loss_reaction), (0x4000, 2));
        assert_eq!(words(c.inputs()), [0x8003, 0x2000]);
        assert!(c.drive_words().is_empty() && c.pkw_request.is_none());
    }

    #[test]
    fn st20_extra_words_from_the_status() {
        let mut e = Cyclic::new(Telegram::Standard(20), OperateMode::Profidrive, 0).unwrap();
        let mut p = Stub::default();
        let s = status();
        let c = e
            .exchange(&mut p, &bytes(&[0x047F, 0x1000]), DriveSide { status: &s, words: &[9, 9], pkw_response: [0; 8] })
            .unwrap();
        assert_eq!(words(c.inputs()), [0x8003, 0x2000, 0x1111, (-0x0222i16) as u16, 0x0333, 0x8000]);
        // Wrong length (ST20 outputs are 2 words) is refused and counted.
        assert!(e.exchange(&mut p, &[0; 12], DriveSide { status: &s, words: &[], pkw_response: [0; 8] }).is_none());
        assert_eq!(e.stats().wrong_length, 1);
    }

    #[test]
    fn st20_refuses_bypass_and_echo() {
        for mode in [OperateMode::Bypass, OperateMode::Echo] {
            assert_eq!(Cyclic::new(Telegram::Standard(20), mode, 0).err(), Some(CyclicError::ModeNotAllowed));
            assert!(Cyclic::new(Telegram::Standard(1), mode, 0).is_ok());
        }
        assert_eq!(
            Cyclic::new(Telegram::Standard(2), OperateMode::Profidrive, 0).err(),
            Some(CyclicError::UnknownTelegram)
        );
        assert_eq!(Cyclic::new(Telegram::None, OperateMode::Echo, 0).err(), Some(CyclicError::UnknownTelegram));
    }

    #[test]
    fn vacon_programmable_words_pass_both_ways() {
        let mut e = Cyclic::new(Telegram::Vendor(Family::Vacon, 100), OperateMode::Profidrive, 0).unwrap();
        let mut p = Stub::default();
        let s = status();
        let out = bytes(&[0x047E, 0x0100, 1, 2, 3, 4]);
        let c = e.exchange(&mut p, &out, DriveSide { status: &s, words: &[11, 12, 13], pkw_response: [0; 8] }).unwrap();
        assert_eq!(c.drive_words(), [1, 2, 3, 4]);
        // The fourth drive word is missing: 0.
        assert_eq!(words(c.inputs()), [0x8003, 0x2000, 11, 12, 13, 0]);
    }

    #[test]
    fn ppo_pkw_to_the_server_and_back() {
        let mut e = Cyclic::new(Telegram::Ppo(2), OperateMode::Profidrive, 0).unwrap();
        let mut p = Stub::default();
        let s = status();
        let out = bytes(&[0x1002, 0, 0, 0, 0x047F, 0x0800, 7, 8, 9, 10]);
        let c = e
            .exchange(&mut p, &out, DriveSide { status: &s, words: &[21, 22, 23, 24], pkw_response: PKW_RESP })
            .unwrap();
        assert_eq!(c.pkw_request, Some([0x10, 0x02, 0, 0, 0, 0, 0, 0]));
        assert_eq!(&c.inputs()[..8], &PKW_RESP);
        assert_eq!(words(&c.inputs()[8..]), [0x8003, 0x2000, 21, 22, 23, 24]);
        assert_eq!(p.calls, [(0x047F, 0x0800)]);
        assert_eq!(c.drive_words(), [7, 8, 9, 10]);
        // Housekeeping: the profile sees the last words again, no new PKW request.
        let c = e.step(&mut p, DriveSide { status: &s, words: &[], pkw_response: PKW_RESP });
        assert_eq!(p.calls.len(), 2);
        assert_eq!(c.pkw_request, None);
    }

    #[test]
    fn bypass_passes_raw_words() {
        let mut e = Cyclic::new(Telegram::Vendor(Family::Invt, 1), OperateMode::Bypass, 4).unwrap();
        let mut p = Stub::default();
        let s = status();
        let mut out = vec![0x10, 0x01, 0, 0x10, 0, 0, 0, 0];
        let pzd: Vec<u16> = (0..12).map(|k| 0x0100 + k).collect();
        out.extend(bytes(&pzd));
        let back: Vec<u16> = (0..12).map(|k| 0x0200 + k).collect();
        let c = e.exchange(&mut p, &out, DriveSide { status: &s, words: &back, pkw_response: PKW_RESP }).unwrap();
        assert_eq!(c.drive_words(), &pzd[..]);
        assert_eq!(&c.inputs()[..8], &PKW_RESP);
        assert_eq!(words(&c.inputs()[8..]), back);
        assert_eq!(c.command, None);
        assert!(p.calls.is_empty(), "no profile in bypass");
        let c = e.comm_lost(&mut p, DriveSide { status: &s, words: &back, pkw_response: PKW_RESP });
        let cmd = c.command.unwrap();
        assert!(cmd.flags.contains(CommandFlags::COMM_LOSS));
        assert_eq!(cmd.comm_loss_reaction, 4);
        assert_eq!(c.pkw_request, None);
        assert_eq!(c.drive_words(), &pzd[..], "the last words stay");
    }

    #[test]
    fn echo_returns_the_outputs() {
        let mut e = Cyclic::new(Telegram::Ppo(5), OperateMode::Echo, 0).unwrap();
        let mut p = Stub::default();
        let s = status();
        let out: Vec<u8> = (0..28).collect();
        let c = e.exchange(&mut p, &out, DriveSide { status: &s, words: &[5; 18], pkw_response: PKW_RESP }).unwrap();
        assert_eq!(c.inputs(), &out[..]);
        assert_eq!((c.command, c.pkw_request, c.drive_words().len()), (None, None, 0));
        assert!(p.calls.is_empty());
    }

    #[test]
    fn comm_lost_in_profidrive_mode() {
        let mut e = Cyclic::new(Telegram::Vendor(Family::WegCfw500, 104), OperateMode::Profidrive, 1).unwrap();
        let mut p = Stub::default();
        let s = status();
        e.exchange(
            &mut p,
            &bytes(&[0x0013, 0x1000, 5, 6]),
            DriveSide { status: &s, words: &[1, 2], pkw_response: [0; 8] },
        );
        let c = e.comm_lost(&mut p, DriveSide { status: &s, words: &[1, 2], pkw_response: [0; 8] });
        assert_eq!(p.lost, 1);
        let cmd = c.command.unwrap();
        assert!(cmd.flags.contains(CommandFlags::COMM_LOSS));
        assert_eq!(cmd.comm_loss_reaction, 1);
        assert_eq!(c.drive_words(), [5, 6]);
        assert_eq!(words(c.inputs()), [0x8003, 0x2000, 1, 2]);
        assert_eq!(e.stats().comm_lost, 1);
    }

    proptest::proptest! {
        #[test]
        fn never_panics(
            code in proptest::num::u16::ANY,
            mode in 1u8..=3,
            out in proptest::collection::vec(proptest::num::u8::ANY, 0..50),
            drive_words in proptest::collection::vec(proptest::num::u16::ANY, 0..24),
        ) {
            let t = Telegram::from_code(code);
            if let Ok(mut e) = Cyclic::new(t, OperateMode::from_code(mode).unwrap(), 0) {
                let mut p = Stub::default();
                let s = status();
                let d = DriveSide { status: &s, words: &drive_words, pkw_response: PKW_RESP };
                if let Some(c) = e.exchange(&mut p, &out, d) {
                    proptest::prop_assert_eq!(c.inputs().len(), e.layout().input_bytes());
                    proptest::prop_assert_eq!(out.len(), e.layout().output_bytes());
                } else {
                    proptest::prop_assert_ne!(out.len(), e.layout().output_bytes());
                }
                let c = e.step(&mut p, d);
                proptest::prop_assert_eq!(c.inputs().len(), e.layout().input_bytes());
                let _ = e.comm_lost(&mut p, d);
            }
        }
    }
}
