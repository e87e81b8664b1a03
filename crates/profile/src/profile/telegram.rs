//! What each word of a telegram's cyclic images is (issue 6, "the drive profile"), and which
//! [`ControlProfile`](super::drive_if::ControlProfile) family interprets the control word.
//!
//! Every telegram the card offers ([`Telegram`], `card::MODULES`) has the same shape:
//!
//! ```text
//! [PKW 4 words] control/status word, main setpoint/actual, [ST20 extras], programmable PZD 1..n
//! ```
//!
//! | telegram | PKW | fixed out | fixed in | programmable | profile family |
//! |---|---|---|---|---|---|
//! | ST1 (OPTE3/E5 §6.3.2.1 Table 16) | – | STW1 NSOLL_A | ZSW1 NIST_A | 0 | PROFIdrive 4.1 |
//! | ST20 (§6.3.2.2 Table 17) | – | STW1 NSOLL_A | ZSW1 NIST_A_GLATT IAIST_GLATT ITIST_GLATT PIST_GLATT MELD_NAMUR | 0 | PROFIdrive 4.1 |
//! | VACON 100/101/138/139 (§6.3.2.3 Tables 22–25) | – | STW1 NSOLL_A | ZSW1 NIST_A | PDI/PDO 1..4/8/12/16 | PROFIdrive 4.1 |
//! | PPO 1..6 (§6.5.4) | 1, 2, 5 | STW HSW | ZSW HIW | PZD3..PZD2/6/10 | PROFIdrive 2.0 |
//! | WEG CFW500 103–108 (CFW500 P0922, P0742–P0755) | – | control word, speed reference | status word, motor speed | 1..6 | WEG manufacturer or WEG PROFIdrive (P0741) |
//! | WEG CFW-11 100–107 (CFW-11 P0922) | – | as CFW500 | as CFW500 | 1..8 | as CFW500 |
//! | INVT (INVT §2.6 Figure 2-4) | yes | CW, PZD2 (REF) | SW, PZD2 (ACT) | PZD3..PZD12 = 1..10 | INVT |
//!
//! The INVT frame has no fixed main setpoint: PZD2..PZD12 are all mapped by P15.02–P15.12
//! (receive) and P15.13–P15.23 (transmit). PZD2 is taken as the main setpoint / actual value
//! here — its mapping "1: set frequency" (P15.02) / running frequency (P15.13) is the one that
//! drives the motor — and the INVT profile scales it; a drive mapping something else there
//! still receives the raw word as the profile's setpoint.
//!
//! PNU 915 / 916 (OPTE3/E5 Table 108: UINT\[18\], "selection switch for DO IO data in setpoint /
//! actual value telegram") list the signal number of each PZD (PKW excluded; 0 = unused) in
//! the coding of OPTE3/E5 §6.3.9 Table 37: 1 STW1, 2 ZSW1, 5 NSOLL_A, 6 NIST_A, 51
//! IAIST_GLATT, 52 ITIST_GLATT, 54 PIST_GLATT, 57 NIST_A_GLATT, 58 MELD_NAMUR, 100..107 /
//! 140..147 PDO1..16, 110..117 / 148..155 PDI1..16, 118..121 the non-profile control word,
//! status word, speed setpoint and actual value (used for the WEG manufacturer and INVT
//! profiles, whose words are not PROFIdrive's). Programmable words of every family are numbered
//! as VACON's PDI/PDO (the card's convention: WEG and INVT do not number signals).

use crate::profile::selection::{Family, Telegram};

/// Elements of PNU 915 / 916 (OPTE3/E5 Table 108: UINT\[18\]) — also the most PZD words of any
/// telegram (VACON 139).
pub const PZD_SIGNALS: usize = 18;

/// The most programmable PZD words of any telegram (VACON 139: PD 1..16).
pub const MAX_PROGRAMMABLE: usize = 16;

/// The control-word interpretation a telegram needs (OPTE3/E5 §5.1 note: ST1 / ST20 use the
/// PROFIdrive 4.1 state machine, the PPO types PROFIdrive 2.0).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum ProfileFamily {
    /// PROFIdrive 4.1 STW1/ZSW1 and state machine (ST1, ST20, VACON telegrams; OPTE3/E5 §6.3).
    Profidrive41,
    /// PROFIdrive 2.0 STW/ZSW (PPO types; OPTE3/E5 §6.5).
    Profidrive20,
    /// WEG manufacturer profile: P0684 control word, P0685 speed reference (13 bits), P0680
    /// status word, P0681 speed (CFW500 §5.1, P0741 = 1 "manufacturer", the default).
    WegManufacturer,
    /// WEG drive with P0741 = 0 "PROFIdrive": P0967 control word, P0968 status word.
    WegProfidrive,
    /// INVT control word commands 1–9 and status word (INVT §2.6 Tables 2-5, 2-7).
    Invt,
}

/// Which data profile the drive selected for the control and status words where the
/// telegram leaves it open (WEG P0741; the DPM `HostConfig::profile`: 0 PROFIdrive, 1
/// manufacturer; no CONFIG block: [`DataProfile::Factory`]).
///
/// Standard Telegram 1 is the one telegram two products share: VACON's (PROFIdrive 4.1,
/// OPTE3/E5 §6.3.2.1) and WEG's P0922 = 2 (CFW500 §4, the factory setting, with P0741's
/// factory setting 1 = manufacturer words P0684 / P0680). Our reading: ST1 runs WEG's
/// manufacturer profile when the drive's CONFIG says "manufacturer" (a VACON drive has no
/// manufacturer data profile with ST1 — its own words are the Bypass operate mode), and
/// PROFIdrive 4.1 otherwise (CONFIG "PROFIdrive", or no CONFIG). ST1 with CONFIG
/// "PROFIdrive" is VACON's PROFIdrive 4.1, not WEG's P0967 reading: a WEG drive that wants
/// P0967 uses a WEG telegram (103..108 / 100..107).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum DataProfile {
    /// PROFIdrive words.
    Profidrive,
    /// The manufacturer's words.
    Manufacturer,
    /// No CONFIG from the drive: each telegram's factory reading (WEG telegrams: P0741 = 1
    /// manufacturer; ST1: PROFIdrive 4.1).
    Factory,
}

impl DataProfile {
    /// The data profile of the drive's CONFIG.PROFILE (`None`: no CONFIG yet → [`Self::Factory`];
    /// 0 PROFIdrive; anything else manufacturer).
    pub const fn of_config(profile: Option<u8>) -> DataProfile {
        match profile {
            None => DataProfile::Factory,
            Some(0) => DataProfile::Profidrive,
            Some(_) => DataProfile::Manufacturer,
        }
    }
}

impl ProfileFamily {
    /// The status word the master reads while the drive is lost (its heartbeat stopped; every
    /// other word 0): each profile's own "fault" — PROFIdrive ZSW1 / WEG P0968 b3 "fault present"
    /// (OPTE3/E5 Table 27, CFW500 Table 4.8), WEG P0680 b15 "fault" (CFW500 Table 4.2), INVT
    /// status value 4 "faulty" (INVT Table 2-7).
    pub const fn fault_status_word(self) -> u16 {
        match self {
            ProfileFamily::Profidrive41 | ProfileFamily::Profidrive20 | ProfileFamily::WegProfidrive => 1 << 3,
            ProfileFamily::WegManufacturer => 1 << 15,
            ProfileFamily::Invt => 4,
        }
    }
}

/// What one word of a cyclic image is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum Word {
    /// PKW word 0..=3: PKE (parameter id), IND (index), PWE high, PWE low (OPTE3/E5 §6.5.2,
    /// INVT Table 2-9).
    Pkw(u8),
    /// Control word (STW1 / STW / WEG control word / INVT CW), output.
    Control,
    /// Main setpoint (NSOLL_A / HSW / speed reference / INVT PZD2), output.
    MainSetpoint,
    /// Status word (ZSW1 / ZSW / WEG status word / INVT SW), input.
    Status,
    /// Main actual value (NIST_A, NIST_A_GLATT in ST20 / HIW / motor speed / INVT PZD2), input.
    MainActual,
    /// ST20 IAIST_GLATT: filtered output current, N2 (0x4000 = PNU 10116).
    OutputCurrent,
    /// ST20 ITIST_GLATT: filtered active current (torque), N2.
    ActiveCurrent,
    /// ST20 PIST_GLATT: filtered active power, N2.
    ActivePower,
    /// ST20 MELD_NAMUR: drive status / fault word (OPTE3/E5 Table 21).
    MeldNamur,
    /// Programmable word `n` (1-based): VACON PDI/PDO n, PPO PZD(n + 2), WEG word n + 2
    /// (P0742.. / P0750..), INVT PZD(n + 2). The drive maps it; the card passes it through.
    Programmable(u8),
}

/// The words of an image after the PKW, in order, for every input position of ST20.
const ST20_INPUTS: [Word; 6] =
    [Word::Status, Word::MainActual, Word::OutputCurrent, Word::ActiveCurrent, Word::ActivePower, Word::MeldNamur];

/// The layout of one known telegram.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Layout {
    /// The telegram.
    pub telegram: Telegram,
    /// PKW words at the start of both images (0 or 4).
    pub pkw: usize,
    /// PZD words of the output image.
    pub pzd_out: usize,
    /// PZD words of the input image.
    pub pzd_in: usize,
}

impl Layout {
    /// The layout of `telegram`, `None` for an unknown one.
    ///
    /// Out of line: several tasks call it (footprint, issue 13 item 1).
    #[inline(never)]
    pub const fn of(telegram: Telegram) -> Option<Layout> {
        if !telegram.is_known() {
            return None;
        }
        Some(Layout {
            telegram,
            pkw: telegram.pkw_words(),
            pzd_out: telegram.pzd_out_words(),
            pzd_in: telegram.pzd_words(),
        })
    }

    /// Whether this is Standard Telegram 20 (the only one with extra fixed input words).
    pub const fn is_st20(&self) -> bool {
        matches!(self.telegram, Telegram::Standard(20))
    }

    /// Fixed input PZD words (status word, main actual value, ST20's four extras).
    pub const fn fixed_in(&self) -> usize {
        if self.is_st20() {
            6
        } else {
            2
        }
    }

    /// Programmable output words (to the drive).
    pub const fn programmable_out(&self) -> usize {
        self.pzd_out - 2
    }

    /// Programmable input words (from the drive).
    pub const fn programmable_in(&self) -> usize {
        self.pzd_in - self.fixed_in()
    }

    /// Output image bytes.
    pub const fn output_bytes(&self) -> usize {
        2 * (self.pkw + self.pzd_out)
    }

    /// Input image bytes.
    pub const fn input_bytes(&self) -> usize {
        2 * (self.pkw + self.pzd_in)
    }

    /// Word `i` of the output image (counted from the image's start, PKW included).
    pub fn output_word(&self, i: usize) -> Option<Word> {
        if i < self.pkw {
            return Some(Word::Pkw(i as u8));
        }
        match i - self.pkw {
            0 => Some(Word::Control),
            1 => Some(Word::MainSetpoint),
            k if k < self.pzd_out => Some(Word::Programmable((k - 1) as u8)),
            _ => None,
        }
    }

    /// Word `i` of the input image (counted from the image's start, PKW included).
    pub fn input_word(&self, i: usize) -> Option<Word> {
        if i < self.pkw {
            return Some(Word::Pkw(i as u8));
        }
        let k = i - self.pkw;
        if k >= self.pzd_in {
            None
        } else if self.is_st20() {
            Some(ST20_INPUTS[k])
        } else {
            Some(match k {
                0 => Word::Status,
                1 => Word::MainActual,
                k => Word::Programmable((k - 1) as u8),
            })
        }
    }

    /// The control profile family for the drive's data profile (only WEG telegrams depend
    /// on it, WEG P0741).
    ///
    /// Out of line: several tasks call it (footprint, issue 13 item 1).
    #[inline(never)]
    pub const fn profile(&self, data: DataProfile) -> ProfileFamily {
        match self.telegram {
            Telegram::Ppo(_) => ProfileFamily::Profidrive20,
            Telegram::Vendor(Family::Invt, _) => ProfileFamily::Invt,
            Telegram::Vendor(Family::WegCfw500 | Family::WegCfw11, _) => match data {
                DataProfile::Profidrive => ProfileFamily::WegProfidrive,
                DataProfile::Manufacturer | DataProfile::Factory => ProfileFamily::WegManufacturer,
            },
            // WEG P0922 = 2 with P0741 = 1 (see [`DataProfile`]).
            Telegram::Standard(1) if matches!(data, DataProfile::Manufacturer) => ProfileFamily::WegManufacturer,
            _ => ProfileFamily::Profidrive41,
        }
    }

    /// The family with the drive's factory data profile (WEG P0741 default 1 =
    /// manufacturer, CFW500 and CFW-11 manuals; ST1 PROFIdrive 4.1) — what PNU 915 / 916
    /// describe without a CONFIG.
    pub const fn default_profile(&self) -> ProfileFamily {
        self.profile(DataProfile::Factory)
    }

    /// PNU 915: the signal number of each output PZD (OPTE3/E5 Table 37), 0 = unused.
    pub fn setpoint_signals(&self, family: ProfileFamily) -> [u16; PZD_SIGNALS] {
        let mut s = [0u16; PZD_SIGNALS];
        for (k, v) in s.iter_mut().enumerate().take(self.pzd_out) {
            *v = self.output_word(self.pkw + k).map_or(0, |w| signal(w, family, true, self.is_st20()));
        }
        s
    }

    /// PNU 916: the signal number of each input PZD (OPTE3/E5 Table 37), 0 = unused.
    pub fn actual_signals(&self, family: ProfileFamily) -> [u16; PZD_SIGNALS] {
        let mut s = [0u16; PZD_SIGNALS];
        for (k, v) in s.iter_mut().enumerate().take(self.pzd_in) {
            *v = self.input_word(self.pkw + k).map_or(0, |w| signal(w, family, false, self.is_st20()));
        }
        s
    }
}

/// The OPTE3/E5 Table 37 signal number of `word` (`setpoint`: in the output image).
fn signal(word: Word, family: ProfileFamily, setpoint: bool, st20: bool) -> u16 {
    let profile =
        matches!(family, ProfileFamily::Profidrive41 | ProfileFamily::Profidrive20 | ProfileFamily::WegProfidrive);
    match word {
        Word::Pkw(_) => 0,
        Word::Control => {
            if profile {
                1
            } else {
                118
            }
        }
        Word::Status => {
            if profile {
                2
            } else {
                119
            }
        }
        Word::MainSetpoint => {
            if profile {
                5
            } else {
                120
            }
        }
        Word::MainActual if st20 => 57,
        Word::MainActual => {
            if profile {
                6
            } else {
                121
            }
        }
        Word::OutputCurrent => 51,
        Word::ActiveCurrent => 52,
        Word::ActivePower => 54,
        Word::MeldNamur => 58,
        Word::Programmable(n) => {
            let n = u16::from(n);
            match (setpoint, n) {
                (_, 0) => 0,
                (true, 1..=8) => 109 + n,
                (true, _) => 139 + n,
                (false, 1..=8) => 99 + n,
                (false, _) => 131 + n,
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn telegram_identity_is_unambiguous() {
        let vacon100 = Telegram::Vendor(Family::Vacon, 100);
        let cfw11_100 = Telegram::Vendor(Family::WegCfw11, 100);
        assert_ne!(vacon100.code(), cfw11_100.code());
        assert_eq!((vacon100.pnu922(), cfw11_100.pnu922()), (100, 100));
        assert_eq!((vacon100.pzd_words(), cfw11_100.pzd_words()), (6, 3));
        assert_eq!(Telegram::Vendor(Family::WegCfw500, 103).pzd_words(), 3);
        assert_eq!(Telegram::Vendor(Family::WegCfw11, 103).pzd_words(), 6);
        assert_eq!(Telegram::Vendor(Family::Vacon, 102), Telegram::from_code(0x4166));
        assert!(!Telegram::Vendor(Family::Vacon, 102).is_known());
        // An unknown family tag is an unknown standard telegram, and writes back the same.
        assert_eq!(Telegram::from_code(0x4764), Telegram::Standard(0x4764));
        assert_eq!(Telegram::Standard(0x4764).code(), 0x4764);
        assert_eq!(Telegram::Standard(1).pnu922(), 1);
        assert_eq!(Telegram::Standard(20).pnu922(), 20);
        assert_eq!(Telegram::Ppo(2).pnu922(), 0);
        assert_eq!(Telegram::Vendor(Family::Invt, 1).pnu922(), 0);
        assert_eq!(Telegram::None.pnu922(), 0);
    }
}
