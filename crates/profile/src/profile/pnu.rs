//! The PROFIdrive parameters the card itself owns (reference §5.2; OPTE3/E5 §6.4.5 list of
//! supported PNUs; CFW-11 §4.2: P0918, P0922, P0944, P0947, P0963, P0964, P0965), and VACON's
//! PNU 10100 … 10108, the cyclic words readable acyclically (OPTE3/E5 Table 108). Every other
//! PNU belongs to the drive: [`CardTable`] passes it to the drive's table.
//!
//! **Per product (issue 15 item 12)**, chosen by the active telegram and the drive's data
//! profile ([`ProcessView`]): P0922 in WEG's option coding under a WEG telegram
//! ([`CardInfo::p0922`]), P0944 as WEG's 0/1 fault flag there and VACON's message counter
//! elsewhere ([`CardInfo::p0944`]), PNU 964 with the product's manufacturer / drive unit type
//! ([`CardInfo::device_id`]), PNU 915 / 916 with the words of the active data profile.

use super::param::Attribute;
use super::param::{ErrorValue, ParamAddress, ParamError, ParameterAccess, ValueBlock, ValueWriter};
use super::table::{self, slots, ParamDef, Table, Type};
use super::telegram::{DataProfile, Layout, PZD_SIGNALS};
use crate::profile::selection::{Family, Telegram};

/// PNU 915: PZD assignment of the setpoint telegram — the signal number of each output PZD
/// (OPTE3/E5 Table 108 UINT\[18\], coding §6.3.9 Table 37; see [`super::telegram`]).
pub const PNU_PZD_SETPOINTS: u16 = 915;
/// PNU 916: PZD assignment of the actual value telegram — the signal number of each input
/// PZD (OPTE3/E5 Table 108 UINT\[18\]).
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
/// PNU 965: profile identification number, BYTE\[2\]: profile 3 (PROFIdrive), version 41 (4.1)
/// (OPTE3/E5 §6.4.5; CFW-11 P0965).
pub const PNU_PROFILE_ID: u16 = 965;
/// PNU 975: drive object identification, eight elements (PROFIdrive; [`CardInfo::DO_ID`]).
pub const PNU_DO_ID: u16 = 975;
/// PNU 10100 … 10108: the cyclic words readable acyclically (OPTE3/E5 Table 108): STW1,
/// NSOLL_A, ZSW1, NIST_A, IAIST_GLATT, ITIST_GLATT, PIST_GLATT, NIST_A_GLATT, MELD_NAMUR —
/// [`ProcessView`].
pub const PNU_PROCESS_FIRST: u16 = 10100;
/// The last of the cyclic-word PNUs (10108 MELD_NAMUR).
pub const PNU_PROCESS_LAST: u16 = 10108;
/// PNU 980: number list of defined parameters, continued in 981 … 989
/// ([`PNU_PARAMETER_LIST_LAST`]): see [`CardTable`] "Number list".
pub const PNU_PARAMETER_LIST: u16 = 980;
/// The last PNU of the number list (reference §5.2: 980–989).
pub const PNU_PARAMETER_LIST_LAST: u16 = 989;
/// Elements of each number-list PNU 980 … 989. 64 words are also what one DPM mailbox
/// answer carries (`dpm::MBX_CAPACITY` = 128 bytes), so the drive's part of one list PNU is
/// one mailbox request.
pub const LIST_LEN: usize = 64;
/// PNU 965's value: profile 3 (PROFIdrive), version 41 (4.1) — OPTE3/E5 Table 108 "BYTE\[2\]
/// Byte 1 = 3 (PROFIdrive), Byte 2 = 41 (Version 4.1)", CFW-11 P0965 = (3, 41).
pub const PROFILE_ID: [u8; 2] = [3, 41];

/// Every PNU the card answers itself, ascending (the head of the number list 980 …).
pub const CARD_PNUS: [u16; 31] = [
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
    980,
    981,
    982,
    983,
    984,
    985,
    986,
    987,
    988,
    989,
    10100,
    10101,
    10102,
    10103,
    10104,
    10105,
    10106,
    10107,
    10108,
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
    ParamDef::new(PNU_DO_ID, "DO ident", Type::U16).array(CardInfo::DO_ID.len() as u16).read_only(),
    ParamDef::new(980, "Parameter list", Type::U16).array(LIST_LEN as u16).read_only(),
    ParamDef::new(981, "Parameter list 2", Type::U16).array(LIST_LEN as u16).read_only(),
    ParamDef::new(982, "Parameter list 3", Type::U16).array(LIST_LEN as u16).read_only(),
    ParamDef::new(983, "Parameter list 4", Type::U16).array(LIST_LEN as u16).read_only(),
    ParamDef::new(984, "Parameter list 5", Type::U16).array(LIST_LEN as u16).read_only(),
    ParamDef::new(985, "Parameter list 6", Type::U16).array(LIST_LEN as u16).read_only(),
    ParamDef::new(986, "Parameter list 7", Type::U16).array(LIST_LEN as u16).read_only(),
    ParamDef::new(987, "Parameter list 8", Type::U16).array(LIST_LEN as u16).read_only(),
    ParamDef::new(988, "Parameter list 9", Type::U16).array(LIST_LEN as u16).read_only(),
    ParamDef::new(989, "Param list 10", Type::U16).array(LIST_LEN as u16).read_only(),
    ParamDef::new(10100, "STW1", Type::U16).read_only(),
    ParamDef::new(10101, "NSOLL_A", Type::I16).read_only(),
    ParamDef::new(10102, "ZSW1", Type::U16).read_only(),
    ParamDef::new(10103, "NIST_A", Type::I16).read_only(),
    ParamDef::new(10104, "IAIST_GLATT", Type::I16).read_only(),
    ParamDef::new(10105, "ITIST_GLATT", Type::I16).read_only(),
    ParamDef::new(10106, "PIST_GLATT", Type::I16).read_only(),
    ParamDef::new(10107, "NIST_A_GLATT", Type::I16).read_only(),
    ParamDef::new(10108, "MELD_NAMUR", Type::U16).read_only(),
];

/// [`CARD_DEFS`] checked as a table's definitions at compile time (their descriptions are read
/// without a table, [`table::read_factory_description`]: the values are in [`CardInfo`]).
const _: Table<{ slots(CARD_DEFS) }> = Table::new(CARD_DEFS);

/// Elements of PNU 947 (4 fault situations × 8 messages).
pub const FAULT_BUFFER_LEN: usize = 32;

/// What the profile layer reports for the card's PNUs (handed to the card's data records with every step,
/// [`super::records::CardRecords::set_process_view`]): the active data profile (PNU 915 / 916, P0922, P0944,
/// P0964 per product) and the cyclic words of the last cycle (PNU 10100 … 10108).
///
/// PNU 10100 … 10108 (OPTE3/E5 Table 108) are the last evaluated output image's control word
/// and main setpoint (raw, as on the wire), the status word and main actual value the card
/// sent, and the drive's current, active current (torque), power and MELD_NAMUR in N2 (Table
/// 20: 0x4000 = 100 %). The card does not filter: the "filtered" (GLATT) values are the
/// drive's latest, and NIST_A_GLATT = NIST_A. Under a non-PROFIdrive profile (WEG
/// manufacturer, INVT, Bypass) the same PNUs show that profile's words (P0684 / P0685 /
/// P0680 / P0681, INVT CW / PZD2 / SW / PZD2).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ProcessView {
    /// The drive's data profile (WEG P0741; the DPM CONFIG.PROFILE).
    pub data: DataProfile,
    /// PNU 10100 … 10108, in order.
    pub words: [u16; 9],
}

impl ProcessView {
    /// No cycle yet: factory data profile, every word 0.
    pub const EMPTY: ProcessView = ProcessView { data: DataProfile::Factory, words: [0; 9] };
}

impl Default for ProcessView {
    fn default() -> Self {
        Self::EMPTY
    }
}

/// The product a PLC program was written for, as the active telegram and data profile show
/// it (issue 15 item 12: the profile parameters per product).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Product {
    /// VACON OPTE3/E5 (ST1 / ST20 with PROFIdrive, VACON telegrams, PPO types).
    Vacon,
    /// WEG CFW500 (telegrams 103..108; ST1 with the manufacturer data profile, P0922 = 2).
    Cfw500,
    /// WEG CFW-11 (telegrams 100..107).
    Cfw11,
    /// INVT, or no module.
    Other,
}

impl Product {
    fn of(telegram: Telegram, data: DataProfile) -> Product {
        match telegram {
            Telegram::Vendor(Family::WegCfw500, _) => Product::Cfw500,
            Telegram::Vendor(Family::WegCfw11, _) => Product::Cfw11,
            Telegram::Standard(1) if data == DataProfile::Manufacturer => Product::Cfw500,
            Telegram::Standard(_) | Telegram::Ppo(_) | Telegram::Vendor(Family::Vacon, _) => Product::Vacon,
            _ => Product::Other,
        }
    }
}

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
    /// The profile layer's data profile and cyclic words.
    pub process: ProcessView,
    /// PNU 964 under the generic frames: the product's own
    /// ([`super::records::RecordConfig::device_id`]).
    pub device_id: &'static [u16; 6],
}

impl CardInfo {
    /// PNU 964 under a VACON telegram (OPTE3/E5 Table 110): manufacturer 0x01BA (VACON), drive
    /// unit type 0x0002 (VACON 100 family), then the card's own version, firmware date and
    /// one DO — a PLC program that checks subindex 0 / 1 finds the board it was written for;
    /// the version and date stay ours (as do PNU 975 and I&M0).
    pub const DEVICE_ID_VACON: [u16; 6] = [0x01BA, 0x0002, 1, 2026, 2211, 1];
    /// P0964 under a CFW-11 telegram (CFW-11 §4 P0964, five subindices): manufacturer 367
    /// (WEG), drive unit type 4, then the card's own version and firmware date. Subindex 5
    /// does not exist there (error 0x03).
    pub const DEVICE_ID_CFW11: [u16; 5] = [367, 4, 1, 2026, 2211];

    fn product(&self) -> Product {
        Product::of(self.telegram, self.process.data)
    }

    /// PNU 922 (P0922): the telegram number (OPTE3/E5 Table 15), or WEG's option coding of
    /// P0922 under a WEG product — CFW500 §4: 2 = Standard Telegram 1, 3..8 = telegrams
    /// 103..108; CFW-11 §3: 1 = Standard Telegram 1, 2..9 = telegrams 100..107.
    pub fn p0922(&self) -> u16 {
        match (self.product(), self.telegram) {
            (Product::Cfw500, Telegram::Standard(1)) => 2,
            (Product::Cfw500, Telegram::Vendor(_, n)) => n.saturating_sub(100),
            (Product::Cfw11, Telegram::Vendor(_, n)) => n.saturating_sub(98),
            _ => self.telegram.pnu922(),
        }
    }

    /// PNU 944: VACON's fault message counter (OPTE3/E5 §6.4.6), or under a WEG product P0944
    /// as CFW-11 §4 defines it: "0 to 1", 1 while a fault is active, 0 after the reset (the
    /// CFW500 manual lists no P0944; we use CFW-11's meaning for both WEG families).
    pub fn p0944(&self) -> u16 {
        match self.product() {
            Product::Cfw500 | Product::Cfw11 => u16::from(self.faults[0] != 0),
            _ => self.fault_counter,
        }
    }

    /// PNU 964 for the product ([`Self::device_id`](CardInfo::device_id) under the generic
    /// PROFIdrive, INVT and WEG CFW500 frames — neither of the last two manuals defines P0964 —,
    /// [`Self::DEVICE_ID_VACON`], [`Self::DEVICE_ID_CFW11`]).
    pub fn device_id(&self) -> &'static [u16] {
        match self.product() {
            Product::Vacon => &Self::DEVICE_ID_VACON,
            Product::Cfw11 => &Self::DEVICE_ID_CFW11,
            _ => self.device_id,
        }
    }
    /// PNU 975, DO identification, the eight elements PROFIdrive defines: manufacturer, DO
    /// type, version, firmware year, ddmm, PROFIdrive DO type class (1 = axis), DO subclass 1,
    /// DO-ID (1, the drive's one axis). OPTE3/E5 Table 111 lists subindices 0–6 (UINT\[7\]);
    /// subindex 7 is PROFIdrive's DO-ID (SINAMICS r0975\[7\] "drive object number").
    pub const DO_ID: [u16; 8] = [0, 1, 1, 2026, 2211, 1, 1, 1];
}

/// The card's PNUs in front of the drive's parameter table.
///
/// **Number list (PNU 980 … 989, reference §5.2 "list of all PNUs, continued across
/// 980..989").** One list of every defined parameter, split into ten arrays of [`LIST_LEN`]
/// elements: element *k* of PNU 980 + *j* is list entry *j* × 64 + *k*. The list is the
/// card's [`CARD_PNUS`] (ascending), then the drive's own parameters, then 0 (end of list)
/// and zeros to the end of the array; a list PNU that the list does not reach reads all
/// zeros. The drive's part comes from the drive's table as *its* PNU 980 read as one flat
/// array (subindex = entry of the drive's list, past its end zeros — [`NumberList`] does that
/// for a [`Table`]); through the DPM that is one parameter-mailbox read per list PNU. A drive
/// that answers its PNU 980 with an error has no list: the card's PNUs end the list.
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
    /// One OctetString value (PNU 965: OctetString2).
    Octets(&'v [u8]),
    /// The number list 980 … 989.
    List,
}

impl<D: ParameterAccess> CardTable<'_, D> {
    /// PNU 980 … 989 (see the type's "Number list"): elements `subindex ..` of list PNU
    /// `addr.pnu`, the card's PNUs first, then the drive's list.
    fn read_number_list(&mut self, axis: u8, addr: &ParamAddress, out: &mut ValueWriter<'_>) -> Result<(), ParamError> {
        let first = addr.subindex as usize;
        let n = addr.count() as usize;
        if first >= LIST_LEN || first + n > LIST_LEN {
            return Err(ErrorValue::INVALID_SUBINDEX.into());
        }
        let start = usize::from(addr.pnu - PNU_PARAMETER_LIST) * LIST_LEN + first;
        let end = start + n;
        let card_end = end.min(CARD_PNUS.len());
        for &pnu in CARD_PNUS.get(start..card_end).unwrap_or(&[]) {
            out.push_u16(pnu)?;
        }
        if end <= CARD_PNUS.len() {
            return Ok(());
        }
        // The drive's part: elements of its own flat number list.
        let from = start.max(CARD_PNUS.len()) - CARD_PNUS.len();
        let count = end - CARD_PNUS.len() - from;
        let drive_addr = ParamAddress {
            attribute: Attribute::Value,
            elements: count as u8,
            pnu: PNU_PARAMETER_LIST,
            subindex: from as u16,
        };
        let mut buf = [0u8; 2 * LIST_LEN];
        let mut w = ValueWriter::new(&mut buf);
        match self.drive.read_value(axis, &drive_addr, &mut w) {
            Ok(()) => {
                let got = w.bytes();
                for k in 0..count {
                    let v = got.get(2 * k..2 * k + 2).map_or(0, |b| u16::from_be_bytes([b[0], b[1]]));
                    out.push_u16(v)?;
                }
                Ok(())
            }
            // The drive's values are on their way (the job is built again).
            Err(e) if self.drive.pending() => Err(e),
            // A drive without a number list: the card's PNUs end the list.
            Err(_) => (0..count).try_for_each(|_| out.push_u16(0)),
        }
    }

    fn lookup(&self, pnu: u16) -> Option<Value<'static>> {
        let info = self.info;
        Some(match pnu {
            PNU_STATION_ADDRESS => Value::Word(u16::from(info.address)),
            PNU_PZD_SETPOINTS => Value::Signals(pzd_signals(info.telegram, info.process.data, true)),
            PNU_PZD_ACTUALS => Value::Signals(pzd_signals(info.telegram, info.process.data, false)),
            PNU_TELEGRAM => Value::Word(info.p0922()),
            PNU_OPERATING_MODE => Value::Word(1),
            PNU_FAULT_COUNTER => Value::Word(info.p0944()),
            PNU_FAULT_SCALING => Value::Words(&super::faults::SCALING),
            PNU_BAUD_RATE => Value::Word(info.baud_p963),
            PNU_DEVICE_ID => Value::Words(info.device_id()),
            PNU_PROCESS_FIRST..=PNU_PROCESS_LAST => {
                Value::Word(info.process.words[usize::from(pnu - PNU_PROCESS_FIRST)])
            }
            PNU_PROFILE_ID => Value::Octets(&PROFILE_ID),
            PNU_DO_ID => Value::Words(&CardInfo::DO_ID),
            PNU_PARAMETER_LIST..=PNU_PARAMETER_LIST_LAST => Value::List,
            _ => return None,
        })
    }
}

/// PNU 915 (`setpoints`) / 916: the signal numbers of the telegram's PZD with the drive's
/// active data profile `data` (WEG P0741: PROFIdrive words 1 / 2 / 5 / 6, manufacturer words
/// 118..121; without a CONFIG the factory profile, [`Layout::default_profile`]); all 0
/// without a module.
fn pzd_signals(telegram: Telegram, data: DataProfile, setpoints: bool) -> [u16; PZD_SIGNALS] {
    match Layout::of(telegram) {
        Some(l) if setpoints => l.setpoint_signals(l.profile(data)),
        Some(l) => l.actual_signals(l.profile(data)),
        None => [0; PZD_SIGNALS],
    }
}

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
            Some(Value::Octets(v)) => match (v, addr.subindex, addr.count()) {
                // One OctetString2 value (PROFIdrive PNU 965), the two octets together: format
                // Word (0x42, the untyped 2-octet substitute the card answers every value in),
                // one value, `42 01 03 29` — CFW-11 P0965 is likewise one 16-bit word, profile
                // in the high byte.
                (&[hi, lo], 0, 1) => out.push_u16(u16::from_be_bytes([hi, lo])),
                // VACON's view of the same value, BYTE[2] (OPTE3/E5 Table 108): octets by
                // element, `0A 02 03 29` for elements 0..2.
                _ => {
                    out.set_format(super::param::Format::OCTET_STRING);
                    elements(v, addr)?.iter().try_for_each(|&b| out.push_u8(b))
                }
            },
            Some(Value::List) => self.read_number_list(axis, addr, out),
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
            return if CARD_DEFS.iter().any(|d| d.pnu == addr.pnu) {
                table::read_factory_description(CARD_DEFS, addr, out)
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

/// A drive's parameter [`Table`] with its own number list, as [`CardTable`] reads it: PNU
/// 980 as one flat array of the table's PNUs (ascending), zeros past the end (any subindex),
/// read-only. Every other access goes to the table. The drive side of a card (the simulated
/// drive behind the DPM mailbox) serves its table through this.
pub struct NumberList<'a, const N: usize>(pub &'a mut Table<N>);

impl<const N: usize> ParameterAccess for NumberList<'_, N> {
    fn has_axis(&self, axis: u8) -> bool {
        self.0.has_axis(axis)
    }

    fn read_value(&mut self, axis: u8, addr: &ParamAddress, out: &mut ValueWriter<'_>) -> Result<(), ParamError> {
        if addr.pnu != PNU_PARAMETER_LIST || self.0.def(PNU_PARAMETER_LIST).is_some() {
            return self.0.read_value(axis, addr, out);
        }
        if !self.0.has_axis(axis) {
            return Err(ErrorValue::AXIS_NONEXISTENT.into());
        }
        let defs = self.0.defs();
        let first = addr.subindex as usize;
        (first..first + addr.count() as usize).try_for_each(|k| out.push_u16(defs.get(k).map_or(0, |d| d.pnu)))
    }

    fn write_value(&mut self, axis: u8, addr: &ParamAddress, values: &ValueBlock<'_>) -> Result<(), ParamError> {
        if addr.pnu == PNU_PARAMETER_LIST && self.0.def(PNU_PARAMETER_LIST).is_none() {
            return Err(ErrorValue::VALUE_CANNOT_BE_CHANGED.into());
        }
        self.0.write_value(axis, addr, values)
    }

    fn read_description(&mut self, axis: u8, addr: &ParamAddress, out: &mut ValueWriter<'_>) -> Result<(), ParamError> {
        self.0.read_description(axis, addr, out)
    }

    fn read_text(&mut self, axis: u8, addr: &ParamAddress, out: &mut ValueWriter<'_>) -> Result<(), ParamError> {
        self.0.read_text(axis, addr, out)
    }

    fn pending(&self) -> bool {
        self.0.pending()
    }

    fn start_job(&mut self) {
        self.0.start_job();
    }
}

/// PNU 915 / 916 / 922 through [`CardTable`] (the telegram PNUs; OPTE3/E5 Table 108).
#[cfg(test)]
mod telegram_pnu_tests {
    use super::*;
    use crate::profile::param::ParamError;
    use crate::profile::selection::Family;
    use crate::testkit::FakeDrive;

    fn info(telegram: Telegram) -> CardInfo {
        CardInfo {
            address: 3,
            telegram,
            baud_p963: 5,
            fault_counter: 0,
            faults: [0; FAULT_BUFFER_LEN],
            process: ProcessView::EMPTY,
            device_id: &[0, 0x0F11, 1, 2026, 2211, 1],
        }
    }

    fn read(telegram: Telegram, pnu: u16, subindex: u16, elements: u8) -> Result<Vec<u16>, ParamError> {
        let mut drive = FakeDrive::empty();
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
            // WEG's P0922 option coding (CFW500 §4: 103..108 → 3..8; CFW-11 §3: 100..107 → 2..9).
            (Telegram::Vendor(Family::WegCfw500, 108), 8),
            (Telegram::Vendor(Family::WegCfw11, 100), 2),
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
        let mut drive = FakeDrive::empty();
        let mut t = CardTable { info: info(Telegram::Standard(1)), drive: &mut drive };
        for pnu in [PNU_PZD_SETPOINTS, PNU_PZD_ACTUALS, PNU_TELEGRAM] {
            assert!(CARD_PNUS.contains(&pnu));
            let addr = ParamAddress { attribute: Attribute::Description, elements: 1, pnu, subindex: 0 };
            let mut buf = [0u8; 240];
            let mut w = ValueWriter::new(&mut buf);
            assert_eq!(t.read_description(1, &addr, &mut w), Ok(()), "PNU {pnu} description");
        }
        assert!(CARD_PNUS.windows(2).all(|w| w[0] < w[1]));
        assert_eq!(read(Telegram::Standard(1), PNU_PARAMETER_LIST, 0, CARD_PNUS.len() as u8 + 1).unwrap(), {
            let mut l = CARD_PNUS.to_vec();
            l.push(0);
            l
        });
    }
}
