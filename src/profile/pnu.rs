//! The PROFIdrive parameters the card itself owns (reference §5.2; OPTE3/E5 §6.4.5 list of
//! supported PNUs; CFW-11 §4.2: P0918, P0922, P0944, P0947, P0963, P0964, P0965). Every other
//! PNU belongs to the drive: [`CardTable`] passes it to the drive's table.

use super::param::Attribute;
use super::param::{ErrorValue, ParamAddress, ParamError, ParameterAccess, ValueBlock, ValueWriter};
use super::table::{slots, ParamDef, Table, Type};
use super::telegram::{Layout, PZD_SIGNALS};
use crate::card;
use crate::dpm::Telegram;

/// PNU 915: PZD assignment of the setpoint telegram — the signal number of each output PZD
/// (OPTE3/E5 Table 108 UINT[18], coding §6.3.9 Table 37; see [`super::telegram`]).
pub const PNU_PZD_SETPOINTS: u16 = 915;
/// PNU 916: PZD assignment of the actual value telegram — the signal number of each input
/// PZD (OPTE3/E5 Table 108 UINT[18]).
pub const PNU_PZD_ACTUALS: u16 = 916;
/// PNU 918: station address (read-only here; set by Set_Slave_Add or the drive).
pub const PNU_STATION_ADDRESS: u16 = 918;
/// PNU 922: telegram selection — the active telegram's number ([`Telegram::pnu922`]: 1, 20,
/// VACON 100/101/138/139, CFW500 103–108, CFW-11 100–107; 0 = a PPO type, the INVT frame or
/// no module).
pub const PNU_TELEGRAM: u16 = 922;
/// PNU 930: operating mode (1 = speed control).
pub const PNU_OPERATING_MODE: u16 = 930;
/// PNU 944: fault message counter.
pub const PNU_FAULT_COUNTER: u16 = 944;
/// PNU 947: fault numbers (four fault situations × eight messages, OPTE3/E5 §6.4.6).
pub const PNU_FAULT_NUMBERS: u16 = 947;
/// PNU 950: scaling of the fault buffer, [situations, messages] = [4, 8] (OPTE3/E5 Table 112;
/// [`super::faults::SCALING`]).
pub const PNU_FAULT_SCALING: u16 = 950;
/// PNU 963: detected baud rate (P0963 coding).
pub const PNU_BAUD_RATE: u16 = 963;
/// PNU 964: device identification (six elements).
pub const PNU_DEVICE_ID: u16 = 964;
/// PNU 965: profile identification number, BYTE[2]: profile 3 (PROFIdrive), version 41 (4.1)
/// (OPTE3/E5 §6.4.5; CFW-11 P0965).
pub const PNU_PROFILE_ID: u16 = 965;
/// PNU 975: drive object identification.
pub const PNU_DO_ID: u16 = 975;
/// PNU 980: list of defined parameters (zero-terminated; continued in 981… when longer).
pub const PNU_PARAMETER_LIST: u16 = 980;

/// Every PNU the card answers itself, ascending (the content of PNU 980).
pub const CARD_PNUS: [u16; 13] = [
    PNU_PZD_SETPOINTS,
    PNU_PZD_ACTUALS,
    PNU_STATION_ADDRESS,
    PNU_TELEGRAM,
    PNU_OPERATING_MODE,
    PNU_FAULT_COUNTER,
    PNU_FAULT_NUMBERS,
    PNU_FAULT_SCALING,
    PNU_BAUD_RATE,
    PNU_DEVICE_ID,
    PNU_PROFILE_ID,
    PNU_DO_ID,
    PNU_PARAMETER_LIST,
];

/// The card's PNUs as description entries (attribute 0x20): names, types, array sizes,
/// read-only. Values are not kept here ([`CardTable`] reads them from [`CardInfo`]).
const CARD_DEFS: &[ParamDef] = &[
    ParamDef::new(PNU_PZD_SETPOINTS, "PZD setpoints", Type::U16).array(PZD_SIGNALS as u16).read_only(),
    ParamDef::new(PNU_PZD_ACTUALS, "PZD actuals", Type::U16).array(PZD_SIGNALS as u16).read_only(),
    ParamDef::new(PNU_STATION_ADDRESS, "Station address", Type::U16).limits(0, 126).read_only(),
    ParamDef::new(PNU_TELEGRAM, "Telegram select", Type::U16).read_only(),
    ParamDef::new(PNU_OPERATING_MODE, "Operating mode", Type::U16).read_only(),
    ParamDef::new(PNU_FAULT_COUNTER, "Fault msg count", Type::U16).read_only(),
    ParamDef::new(PNU_FAULT_NUMBERS, "Fault numbers", Type::U16).array(FAULT_BUFFER_LEN as u16).read_only(),
    ParamDef::new(PNU_FAULT_SCALING, "Fault scaling", Type::U16).array(2).read_only(),
    ParamDef::new(PNU_BAUD_RATE, "Baud rate", Type::U16).limits(0, 11).read_only(),
    ParamDef::new(PNU_DEVICE_ID, "Drive unit ident", Type::U16).array(6).read_only(),
    ParamDef::new(PNU_DO_ID, "DO ident", Type::U16).array(7).read_only(),
    ParamDef::new(PNU_PARAMETER_LIST, "Parameter list", Type::U16).array(PARAMETER_LIST.len() as u16).read_only(),
];

/// [`CARD_DEFS`] as a table, for its descriptions.
const CARD_DESCRIPTIONS: Table<{ slots(CARD_DEFS) }> = Table::new(CARD_DEFS);

/// Elements of PNU 947 (4 fault situations × 8 messages).
pub const FAULT_BUFFER_LEN: usize = 32;

/// What the card knows about itself when a PNU is read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CardInfo {
    /// Station address.
    pub address: u8,
    /// Active telegram (PNU 922, and PNU 915 / 916 from its layout).
    pub telegram: Telegram,
    /// Detected baud rate, P0963 coding (5 = not detected).
    pub baud_p963: u16,
    /// Fault message counter (PNU 944).
    pub fault_counter: u16,
    /// Fault numbers (PNU 947).
    pub faults: [u16; FAULT_BUFFER_LEN],
}

impl CardInfo {
    /// PNU 964 (OPTE3/E5 Table 110): manufacturer (PI vendor ID — 0, a placeholder until
    /// registered), drive unit type, software version (major × 100 + minor), firmware year,
    /// day/month as ddmm, number of drive objects.
    pub const DEVICE_ID: [u16; 6] = [0, card::IDENT_NUMBER, 1, 2026, 2211, 1];
    /// PNU 975 (OPTE3/E5 Table 111): manufacturer, DO type, version, year, ddmm, PROFIdrive
    /// DO type class (1 = axis), DO subclass 1.
    pub const DO_ID: [u16; 7] = [0, 1, 1, 2026, 2211, 1, 1];
}

/// The card's PNUs in front of the drive's parameter table.
pub struct CardTable<'a, D> {
    /// What the card reports.
    pub info: CardInfo,
    /// Every other PNU.
    pub drive: &'a mut D,
}

enum Value<'v> {
    Signals([u16; PZD_SIGNALS]),
    Word(u16),
    Words(&'v [u16]),
    Octets(&'v [u8]),
}

impl<D: ParameterAccess> CardTable<'_, D> {
    fn lookup(&self, pnu: u16) -> Option<Value<'static>> {
        let info = self.info;
        Some(match pnu {
            PNU_STATION_ADDRESS => Value::Word(u16::from(info.address)),
            PNU_PZD_SETPOINTS => Value::Signals(pzd_signals(info.telegram, true)),
            PNU_PZD_ACTUALS => Value::Signals(pzd_signals(info.telegram, false)),
            PNU_TELEGRAM => Value::Word(info.telegram.pnu922()),
            PNU_OPERATING_MODE => Value::Word(1),
            PNU_FAULT_COUNTER => Value::Word(info.fault_counter),
            PNU_FAULT_SCALING => Value::Words(&super::faults::SCALING),
            PNU_BAUD_RATE => Value::Word(info.baud_p963),
            PNU_DEVICE_ID => Value::Words(&CardInfo::DEVICE_ID),
            PNU_PROFILE_ID => Value::Octets(&[3, 41]),
            PNU_DO_ID => Value::Words(&CardInfo::DO_ID),
            PNU_PARAMETER_LIST => Value::Words(&PARAMETER_LIST),
            _ => return None,
        })
    }
}

/// PNU 915 (`setpoints`) / 916: the signal numbers of the telegram's PZD with the drive
/// family's factory data profile ([`Layout::default_profile`]); all 0 without a module.
fn pzd_signals(telegram: Telegram, setpoints: bool) -> [u16; PZD_SIGNALS] {
    match Layout::of(telegram) {
        Some(l) if setpoints => l.setpoint_signals(l.default_profile()),
        Some(l) => l.actual_signals(l.default_profile()),
        None => [0; PZD_SIGNALS],
    }
}

/// PNU 980: the card's PNUs, zero-terminated.
const PARAMETER_LIST: [u16; 14] = [915, 916, 918, 922, 930, 944, 947, 950, 963, 964, 965, 975, 980, 0];

fn elements<'v, T: Copy>(all: &'v [T], addr: &ParamAddress) -> Result<&'v [T], ParamError> {
    let first = addr.subindex as usize;
    let n = addr.count() as usize;
    if first >= all.len() {
        return Err(ErrorValue::INVALID_SUBINDEX.into());
    }
    all.get(first..first + n).ok_or_else(|| ErrorValue::INVALID_SUBINDEX.into())
}

impl<D: ParameterAccess> ParameterAccess for CardTable<'_, D> {
    /// A single-axis drive: DO-ID / axis 0 (WEG) or 1 (VACON); anything else is answered
    /// 0x19 for every parameter, whatever the drive's table would say.
    fn has_axis(&self, axis: u8) -> bool {
        axis <= 1 && self.drive.has_axis(axis)
    }

    fn read_value(&mut self, axis: u8, addr: &ParamAddress, out: &mut ValueWriter<'_>) -> Result<(), ParamError> {
        if addr.pnu == PNU_FAULT_NUMBERS {
            let faults = self.info.faults;
            for &v in elements(&faults, addr)? {
                out.push_u16(v)?;
            }
            return Ok(());
        }
        match self.lookup(addr.pnu) {
            None => self.drive.read_value(axis, addr, out),
            Some(Value::Word(v)) => {
                if addr.subindex != 0 || addr.count() != 1 {
                    return Err(ErrorValue::NO_ARRAY.into());
                }
                out.push_u16(v)
            }
            Some(Value::Words(all)) => elements(all, addr)?.iter().try_for_each(|&v| out.push_u16(v)),
            Some(Value::Signals(all)) => elements(&all, addr)?.iter().try_for_each(|&v| out.push_u16(v)),
            Some(Value::Octets(all)) => {
                out.set_format(super::param::Format::OCTET_STRING);
                elements(all, addr)?.iter().try_for_each(|&v| out.push_u8(v))
            }
        }
    }

    fn write_value(&mut self, axis: u8, addr: &ParamAddress, values: &ValueBlock<'_>) -> Result<(), ParamError> {
        if addr.pnu == PNU_FAULT_NUMBERS || self.lookup(addr.pnu).is_some() {
            return Err(ErrorValue::VALUE_CANNOT_BE_CHANGED.into());
        }
        self.drive.write_value(axis, addr, values)
    }

    fn read_description(&mut self, axis: u8, addr: &ParamAddress, out: &mut ValueWriter<'_>) -> Result<(), ParamError> {
        debug_assert_eq!(addr.attribute, Attribute::Description);
        if addr.pnu == PNU_FAULT_NUMBERS || self.lookup(addr.pnu).is_some() {
            // The 46-byte description of the card's own PNUs (965 is an OctetString2, which
            // the description table does not model: 0x09 no description data).
            let mut t = CARD_DESCRIPTIONS;
            return if t.def(addr.pnu).is_some() {
                t.read_description(axis, addr, out)
            } else {
                Err(ErrorValue::NO_DESCRIPTION.into())
            };
        }
        self.drive.read_description(axis, addr, out)
    }

    fn read_text(&mut self, axis: u8, addr: &ParamAddress, out: &mut ValueWriter<'_>) -> Result<(), ParamError> {
        if addr.pnu == PNU_FAULT_NUMBERS || self.lookup(addr.pnu).is_some() {
            return Err(ErrorValue::NO_TEXT_ARRAY.into());
        }
        self.drive.read_text(axis, addr, out)
    }

    fn pending(&self) -> bool {
        self.drive.pending()
    }

    fn start_job(&mut self) {
        self.drive.start_job();
    }
}

/// PNU 915 / 916 / 922 through [`CardTable`] (the telegram PNUs; OPTE3/E5 Table 108).
#[cfg(test)]
mod telegram_pnu_tests {
    use super::*;
    use crate::dpm::Family;
    use crate::profile::param::ParamError;

    struct NoDrive;
    impl ParameterAccess for NoDrive {
        fn has_axis(&self, _: u8) -> bool {
            true
        }
        fn read_value(&mut self, _: u8, _: &ParamAddress, _: &mut ValueWriter<'_>) -> Result<(), ParamError> {
            Err(ErrorValue::IMPERMISSIBLE_PARAMETER_NUMBER.into())
        }
        fn write_value(&mut self, _: u8, _: &ParamAddress, _: &ValueBlock<'_>) -> Result<(), ParamError> {
            Err(ErrorValue::IMPERMISSIBLE_PARAMETER_NUMBER.into())
        }
    }

    fn info(telegram: Telegram) -> CardInfo {
        CardInfo { address: 3, telegram, baud_p963: 5, fault_counter: 0, faults: [0; FAULT_BUFFER_LEN] }
    }

    fn read(telegram: Telegram, pnu: u16, subindex: u16, elements: u8) -> Result<Vec<u16>, ParamError> {
        let mut drive = NoDrive;
        let mut t = CardTable { info: info(telegram), drive: &mut drive };
        let addr = ParamAddress { attribute: Attribute::Value, elements, pnu, subindex };
        let mut buf = [0u8; 240];
        let mut w = ValueWriter::new(&mut buf);
        t.read_value(1, &addr, &mut w)?;
        Ok(w.bytes().chunks(2).map(|c| u16::from_be_bytes([c[0], c[1]])).collect())
    }

    #[test]
    fn pnu_922_is_the_telegram_number() {
        for (t, n) in [
            (Telegram::Standard(1), 1),
            (Telegram::Standard(20), 20),
            (Telegram::Vendor(Family::Vacon, 139), 139),
            (Telegram::Vendor(Family::WegCfw500, 108), 108),
            (Telegram::Vendor(Family::WegCfw11, 100), 100),
            (Telegram::Ppo(5), 0),
            (Telegram::Vendor(Family::Invt, 1), 0),
            (Telegram::None, 0),
        ] {
            assert_eq!(read(t, PNU_TELEGRAM, 0, 1), Ok(vec![n]), "{t:?}");
        }
    }

    #[test]
    fn pnu_915_916_list_the_signals() {
        let st20 = Telegram::Standard(20);
        let set = read(st20, PNU_PZD_SETPOINTS, 0, 18).unwrap();
        assert_eq!(set.len(), 18);
        assert_eq!(&set[..3], &[1, 5, 0]);
        assert_eq!(read(st20, PNU_PZD_ACTUALS, 0, 6), Ok(vec![2, 57, 51, 52, 54, 58]));
        // Subindex access and its limit.
        assert_eq!(read(Telegram::Vendor(Family::Vacon, 100), PNU_PZD_ACTUALS, 2, 2), Ok(vec![100, 101]));
        assert!(read(st20, PNU_PZD_ACTUALS, 18, 1).is_err());
        assert!(read(st20, PNU_PZD_ACTUALS, 17, 2).is_err());
        // WEG with its factory profile (manufacturer): non-profile control/status words.
        assert_eq!(read(Telegram::Vendor(Family::WegCfw11, 100), PNU_PZD_SETPOINTS, 0, 4), Ok(vec![118, 120, 110, 0]));
        // No module: zeros.
        assert_eq!(read(Telegram::None, PNU_PZD_SETPOINTS, 0, 18), Ok(vec![0; 18]));
    }

    #[test]
    fn telegram_pnus_have_descriptions_and_are_listed() {
        let mut drive = NoDrive;
        let mut t = CardTable { info: info(Telegram::Standard(1)), drive: &mut drive };
        for pnu in [PNU_PZD_SETPOINTS, PNU_PZD_ACTUALS, PNU_TELEGRAM] {
            assert!(CARD_PNUS.contains(&pnu) && PARAMETER_LIST.contains(&pnu));
            let addr = ParamAddress { attribute: Attribute::Description, elements: 1, pnu, subindex: 0 };
            let mut buf = [0u8; 240];
            let mut w = ValueWriter::new(&mut buf);
            assert_eq!(t.read_description(1, &addr, &mut w), Ok(()), "PNU {pnu} description");
        }
        assert!(CARD_PNUS.windows(2).all(|w| w[0] < w[1]));
        assert_eq!(&PARAMETER_LIST[..CARD_PNUS.len()], &CARD_PNUS);
    }
}
