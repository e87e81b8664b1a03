//! Which process-data layout is selected: a PROFIdrive standard telegram, a PPO type, or a
//! manufacturer's telegram of one [`Family`] (PROFIdrive profile P922, the four manuals'
//! telegram lists). A profile concept: the DP layer's Chk_Cfg picks a module, the profile
//! runtime works on its layout, and the DPM (`pbcard::dpm`, which re-exports both types)
//! carries the layout's code to the drive.

use crate::dp::Module;

/// The manufacturer family of a vendor-specific telegram ([`Telegram::Vendor`]). Telegram
/// numbers of different families overlap — WEG CFW-11 telegrams 100–107 (3–10 words, CFW-11
/// manual P0922) against VACON telegrams 100/101 (6/10 words, OPTE3/E5 §6.3.2.3) and WEG CFW500
/// telegrams 103–108 (3–8 words, CFW500 manual P0922) — so the family is part of the
/// telegram's identity: in the DPM code, in the GSD module's manufacturer bytes and in
/// `card::Module::reference` (family × 1000 + number).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[repr(u8)]
pub enum Family {
    /// VACON (Danfoss) OPTE3/E5: telegrams 100, 101, 138, 139 = ST1 + 4/8/12/16 PD words.
    Vacon = 1,
    /// WEG CFW500 (CFW500-CPRO): telegrams 103–108 = 3–8 I/O words.
    WegCfw500 = 2,
    /// WEG CFW-11 (PROFIBUSDP-01): telegrams 100–107 = 3–10 I/O words.
    WegCfw11 = 3,
    /// INVT/IMO HD2 PROFIBUS-DP card: PKW + CW/SW + PZD2..PZD12 (INVT manual §2.6), telegram 1.
    Invt = 4,
}

impl Family {
    /// Every family, in tag order.
    pub const ALL: [Family; 4] = [Family::Vacon, Family::WegCfw500, Family::WegCfw11, Family::Invt];

    /// The family of a tag (1..=4).
    pub const fn from_tag(tag: u8) -> Option<Family> {
        match tag {
            1 => Some(Family::Vacon),
            2 => Some(Family::WegCfw500),
            3 => Some(Family::WegCfw11),
            4 => Some(Family::Invt),
            _ => None,
        }
    }

    /// The tag (DPM code bits 13..8, GSD manufacturer byte 2, module reference thousands).
    pub const fn tag(self) -> u8 {
        self as u8
    }
}

/// Which process-data layout is active: a PROFIdrive standard telegram (P922 number), a PPO
/// type of PROFIdrive 2.0, or a manufacturer's telegram tagged with its [`Family`].
///
/// DPM code (u16): 0 = none; 0x0001..=0x3FFF = standard telegram number; 0x4000 | tag << 8 |
/// number = vendor telegram (tag 1..=4, number 0..=255); 0x8000 | n = PPO n. A code with bit
/// 14 set and an unknown family tag reads as `Standard(code)`, a layout nobody knows — every
/// code read back from the DPM writes the same code again.
///
/// Layouts (words; `profile::telegram` says what each word is):
///
/// | telegram | PKW | PZD out | PZD in | module |
/// |---|---|---|---|---|
/// | `Standard(1)` ST1 | 0 | 2 | 2 | `C3 C1 C1 FD 00 01` |
/// | `Standard(20)` ST20 | 0 | 2 | 6 | `C3 C1 C5 FD 00 14` |
/// | `Vendor(Vacon, 100/101/138/139)` | 0 | 6/10/14/18 | same | `C4 L L FE 01 00 nn` |
/// | `Vendor(WegCfw500, 103..=108)` | 0 | 3..=8 | same | `C4 L L FE 02 00 nn` |
/// | `Vendor(WegCfw11, 100..=107)` | 0 | 3..=10 | same | `C4 L L FE 03 00 nn` |
/// | `Vendor(Invt, 1)` | 4 | 12 | 12 | `F3 FB` |
/// | `Ppo(1/2/5)` | 4 | 2/6/10 | same | `F3 F1` / `F3 F5` / `F3 F9` |
/// | `Ppo(3/4/6)` | 0 | 2/6/10 | same | `F1` / `F5` / `F9` |
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum Telegram {
    /// No module configured.
    None,
    /// PROFIdrive standard telegram number (1 = Standard Telegram 1, 20 = Standard Telegram
    /// 20, OPTE3/E5 §6.3.2.1–6.3.2.2).
    Standard(u16),
    /// PPO type 1..=6 (PROFIdrive 2.0, OPTE3/E5 §6.5.4).
    Ppo(u8),
    /// A manufacturer's telegram: family and the number its manual gives it.
    Vendor(Family, u16),
}

impl Telegram {
    /// The DPM code.
    pub const fn code(self) -> u16 {
        match self {
            Telegram::None => 0,
            Telegram::Standard(n) => n & 0x7FFF,
            Telegram::Ppo(n) => 0x8000 | n as u16,
            Telegram::Vendor(f, n) => 0x4000 | (f.tag() as u16) << 8 | (n & 0xFF),
        }
    }

    /// The telegram of a DPM code (PPO numbers above 255 read as PPO 0, i.e. unknown).
    pub const fn from_code(code: u16) -> Telegram {
        match code {
            0 => Telegram::None,
            c if c & 0x8000 != 0 => Telegram::Ppo(if c & 0x7F00 == 0 { c as u8 } else { 0 }),
            c if c & 0x4000 != 0 => match Family::from_tag(((c >> 8) & 0x3F) as u8) {
                Some(f) => Telegram::Vendor(f, c & 0xFF),
                None => Telegram::Standard(c),
            },
            c => Telegram::Standard(c),
        }
    }

    /// The telegram a GSD module carries (`card::Module::reference`: 1 / 20 = Standard
    /// Telegram 1 / 20, 101..=106 = PPO 1..6, family tag × 1000 + number = a vendor
    /// telegram). `None` for a module this map does not know.
    ///
    /// Out of line: the step and the DP-V1 task both call it (footprint, issue 13 item 1).
    #[inline(never)]
    pub const fn of_module(module: &Module) -> Option<Telegram> {
        let t = match module.reference {
            1 => Telegram::Standard(1),
            20 => Telegram::Standard(20),
            r @ 101..=106 => Telegram::Ppo((r - 100) as u8),
            r => match Family::from_tag((r / 1000) as u8) {
                Some(f) => Telegram::Vendor(f, r % 1000),
                None => return None,
            },
        };
        if t.is_known() {
            Some(t)
        } else {
            None
        }
    }

    /// PKW words at the start of the image, both directions (4 for PPO 1, 2 and 5 and the
    /// INVT telegram; 0 otherwise).
    pub const fn pkw_words(self) -> usize {
        match self {
            Telegram::Ppo(1 | 2 | 5) | Telegram::Vendor(Family::Invt, 1) => 4,
            _ => 0,
        }
    }

    /// PZD words after the PKW in the **input** image (slave → master; what the drive
    /// answers), 0 for an unknown layout. Only ST20 differs from [`Self::pzd_out_words`].
    pub const fn pzd_words(self) -> usize {
        match self {
            Telegram::Standard(20) => 6,
            t => t.pzd_out_words(),
        }
    }

    /// PZD words after the PKW in the **output** image (master → slave), 0 for an unknown
    /// layout.
    pub const fn pzd_out_words(self) -> usize {
        match self {
            Telegram::Standard(1 | 20) | Telegram::Ppo(1 | 3) => 2,
            Telegram::Ppo(2 | 4) => 6,
            Telegram::Ppo(5 | 6) => 10,
            Telegram::Vendor(Family::Vacon, 100) => 6,
            Telegram::Vendor(Family::Vacon, 101) => 10,
            Telegram::Vendor(Family::Vacon, 138) => 14,
            Telegram::Vendor(Family::Vacon, 139) => 18,
            Telegram::Vendor(Family::WegCfw500, n @ 103..=108) => (n - 100) as usize,
            Telegram::Vendor(Family::WegCfw11, n @ 100..=107) => (n - 97) as usize,
            Telegram::Vendor(Family::Invt, 1) => 12,
            _ => 0,
        }
    }

    /// Input image bytes (PKW + input PZD).
    pub const fn input_bytes(self) -> usize {
        2 * (self.pkw_words() + self.pzd_words())
    }

    /// Output image bytes (PKW + output PZD).
    pub const fn output_bytes(self) -> usize {
        2 * (self.pkw_words() + self.pzd_out_words())
    }

    /// Whether the layout is known ([`Self::pzd_words`] > 0).
    pub const fn is_known(self) -> bool {
        self.pzd_words() > 0
    }

    /// The value of PNU 922 "telegram selection" (OPTE3/E5 Table 15, CFW-11 / CFW500 P0922
    /// telegram names): the telegram number its manual gives it; 0 for the PPO types, the INVT
    /// frame (neither has a PROFIdrive telegram number) and no module. The number alone is
    /// ambiguous across families (CFW-11 100 ≠ VACON 100); the family is [`Self::code`]'s
    /// tag in the DPM, the GSD module's manufacturer bytes and PNU 964's drive unit type.
    pub const fn pnu922(self) -> u16 {
        match self {
            Telegram::Standard(n) if self.is_known() => n,
            Telegram::Vendor(Family::Invt, _) => 0,
            Telegram::Vendor(_, n) if self.is_known() => n,
            _ => 0,
        }
    }
}
