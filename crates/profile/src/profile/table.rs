//! A generic, allocation-free drive parameter table that implements [`ParameterAccess`]
//! (VACON OPTE3/E5 manual §6.4.2–6.4.3.16; WEG CFW-11 §4.2.4; WEG CFW500 §5.2.4).
//!
//! [`ParamDef`]s describe the parameters (a `&'static` slice, in flash); a [`Table`] holds their
//! values, one `u32` slot per element — `N` is [`slots`] of the definitions, so a table is a
//! `const` item: `const T: Table<{ slots(DEFS) }> = Table::new(DEFS);` ([`Table::new`] checks
//! the definitions at compile time in a const context).
//!
//! **Values** (attribute 0x10). A non-array parameter is addressed with subindex 0 and 0 or 1
//! elements (VACON Table 41), otherwise 0x04 "no array"; an array with `subindex .. subindex +
//! count` inside its elements, otherwise 0x03 "invalid subindex"; an unknown PNU is 0x00. Reads
//! answer with Word 0x42 / Double word 0x43 as VACON (Table 42, §6.4.4.2) and WEG (CFW-11 §4.2.5)
//! do, or with the PROFIdrive data type (Unsigned16 0x06, Integer16 0x03, Unsigned32 0x07,
//! Integer32 0x04) under [`FormatStyle::Typed`]; a response that does not fit is 0x15 from the
//! [`ValueWriter`]. Writes accept the untyped format of the right size and the exact data type
//! (Siemens: "bytes, words and double words are also possible as a substitute"), anything else
//! is 0x05; a read-only parameter is 0x01; a value outside `min..=max` is 0x02 (for an array
//! with the failing subindex as additional info). Array elements are written in order and the
//! first failing one ends the write, the earlier ones stay written (VACON §6.4.4.11 method 2:
//! "the remaining operations are skipped").
//!
//! **Descriptions** (attribute 0x20, VACON §6.4.3.7–6.4.3.16, Table 49): subindex 0 is the whole
//! 46-byte description element as OctetString, subindex 1..12 one field, with one element per
//! request (more is 0x16), 13 and above 0x03:
//!
//! | subindex | bytes | field | format |
//! |---|---|---|---|
//! | 1 | 0..2 | identifier (Table 50, [`ParamDef::identifier`]) | Unsigned16 0x06 |
//! | 2 | 2..4 | number of array elements (0 for a non-array parameter) | Unsigned16 0x06 |
//! | 3 | 4..8 | standardisation factor | FloatingPoint 0x08 |
//! | 4 | 8..10 | variable attribute: variable index, conversion index (Tables 51–52) | OctetString 0x0A × 2 |
//! | 5 | 10..14 | reserved, 0 | OctetString × 4 |
//! | 6 | 14..30 | name, 16 ASCII characters, padded with spaces | VisibleString 0x09 × 16 |
//! | 7 | 30..34 | low limit | OctetString × 4 |
//! | 8 | 34..38 | high limit | OctetString × 4 |
//! | 9 | 38..40 | reserved, 0 | OctetString × 2 |
//! | 10 | 40..42 | ID extension, 0 (§6.4.3.14) | Unsigned16 |
//! | 11 | 42..44 | normalisation reference parameter (PNU or 0, §6.4.3.15) | Unsigned16 |
//! | 12 | 44..46 | normalisation field: bit 15 valid, bits 0–5 the bit worth 100 % (Table 53) | Unsigned16 |
//!
//! The manual gives the limits as "Array of four Unsigned8" without saying how a 16-bit value
//! sits in them: here a limit is the value as a big-endian 32-bit integer of the parameter's
//! signedness (an Integer16 limit sign-extended, an Unsigned16 one zero-extended), so a master
//! reading the four bytes as Integer32 / Unsigned32 gets the number. A parameter without a
//! [`Scale`] sets identifier bit 8 ("standardisation factor and variable attribute not
//! relevant") and sends factor 1.0 with variable attribute 0, 0.
//!
//! **Texts** (attribute 0x30): 0x0F "no text array" (VACON Table 41: texts are not supported),
//! 0x00 for an unknown PNU.

use core::ops::Range;

use super::param::{Attribute, ErrorValue, Format, ParamAddress, ParamError, ParameterAccess, ValueBlock, ValueWriter};

/// Characters of the name field (VACON §6.4.3.12).
pub const NAME_LEN: usize = 16;
/// Bytes of a complete description element (VACON §6.4.3.7).
pub const DESCRIPTION_LEN: usize = 46;
/// Highest description subindex (the twelve fields of VACON Table 49).
pub const DESCRIPTION_FIELDS: u16 = 12;

/// Variable index 0: no dimension (VACON Table 51).
pub const VAR_NO_DIMENSION: u8 = 0;
/// Variable index 4: time, base unit second. Not in VACON Table 51; from the PROFIdrive
/// variable-index list (power 9, speed 11, current 22 and ratio 24 there agree with Table 51).
pub const VAR_TIME: u8 = 4;
/// Variable index 9: power, base unit watt (VACON Table 51).
pub const VAR_POWER: u8 = 9;
/// Variable index 11: speed, base unit 1/second (VACON Table 51).
pub const VAR_SPEED: u8 = 11;
/// Variable index 22: electrical current, base unit ampere (VACON Table 51).
pub const VAR_CURRENT: u8 = 22;
/// Variable index 24: ratio, percent (VACON Table 51).
pub const VAR_RATIO: u8 = 24;
/// Conversion index 0: the base unit (VACON Table 52: A n/a, B 0).
pub const CONV_BASE: i8 = 0;
/// Conversion index −1: a tenth of the base unit (0.1 A; VACON Table 52: A = 1.0E−1).
pub const CONV_TENTH: i8 = -1;
/// Conversion index 3: kilo (kilowatt; VACON Table 51).
pub const CONV_KILO: i8 = 3;
/// Conversion index 67: 1/minute (VACON Table 52: A = 1/60).
pub const CONV_PER_MINUTE: i8 = 67;
/// Conversion index 72: 1/hour (VACON Table 52: A = 1/3600).
pub const CONV_PER_HOUR: i8 = 72;

/// Data type of one element of a parameter (VACON Table 107: UINT, INT, LONG; the
/// identifier's low byte, Table 50).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum Type {
    /// Unsigned16 (data type 6; VACON "UINT").
    U16,
    /// Integer16 (data type 3; VACON "INT").
    I16,
    /// Unsigned32 (data type 7; VACON "LONG").
    U32,
    /// Integer32 (data type 4).
    I32,
}

impl Type {
    /// The PROFIdrive data type number (identifier bits 0–7; also the typed format code).
    pub const fn code(self) -> u8 {
        match self {
            Type::U16 => 6,
            Type::I16 => 3,
            Type::U32 => 7,
            Type::I32 => 4,
        }
    }
    /// Bytes per value.
    pub const fn size(self) -> usize {
        match self {
            Type::U16 | Type::I16 => 2,
            Type::U32 | Type::I32 => 4,
        }
    }
    /// Smallest value of the type.
    pub const fn min(self) -> i64 {
        match self {
            Type::U16 | Type::U32 => 0,
            Type::I16 => i16::MIN as i64,
            Type::I32 => i32::MIN as i64,
        }
    }
    /// Largest value of the type.
    pub const fn max(self) -> i64 {
        match self {
            Type::U16 => u16::MAX as i64,
            Type::I16 => i16::MAX as i64,
            Type::U32 => u32::MAX as i64,
            Type::I32 => i32::MAX as i64,
        }
    }
    /// The format with the data type: Unsigned16 0x06, Integer16 0x03, Unsigned32 0x07, Integer32 0x04.
    pub const fn typed_format(self) -> Format {
        Format(self.code())
    }
    /// The untyped format of the same size: Word 0x42 or Double word 0x43 (VACON Table 42).
    pub const fn untyped_format(self) -> Format {
        match self.size() {
            2 => Format::WORD,
            _ => Format::DOUBLE_WORD,
        }
    }
    /// `v` as stored (and sent): two's complement, truncated to the type's size.
    const fn encode(self, v: i64) -> u32 {
        match self.size() {
            2 => (v as u32) & 0xFFFF,
            _ => v as u32,
        }
    }
    /// The number a stored / received value stands for.
    const fn decode(self, raw: u32) -> i64 {
        match self {
            Type::U16 => (raw as u16) as i64,
            Type::I16 => (raw as u16 as i16) as i64,
            Type::U32 => raw as i64,
            Type::I32 => (raw as i32) as i64,
        }
    }
}

/// Standardisation factor and variable attribute of a parameter (VACON §6.4.3.10–6.4.3.11):
/// physical value in the unit given by the conversion index = transmitted value × `factor`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scale {
    /// Standardisation factor (e.g. 0.1 for a time in 0.1 s).
    pub factor: f32,
    /// Variable index: the physical quantity and its base unit ([`VAR_SPEED`] …).
    pub variable_index: u8,
    /// Conversion index: the unit relative to the base unit ([`CONV_PER_MINUTE`] …).
    pub conversion_index: i8,
}

impl Scale {
    /// A scale.
    pub const fn new(factor: f32, variable_index: u8, conversion_index: i8) -> Self {
        Scale { factor, variable_index, conversion_index }
    }
}

/// Normalisation of a ratio parameter (VACON §6.4.3.15–6.4.3.16): bit `bit` of the value
/// corresponds to the value of parameter `reference_pnu` (e.g. bit 14, 0x4000 = 100 % of PNU
/// 10111, the reference speed).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Normalisation {
    /// The physical reference parameter.
    pub reference_pnu: u16,
    /// The normalisation bit, 0..=31 (Table 53).
    pub bit: u8,
}

impl Normalisation {
    /// The normalisation field: bit 15 "normalisation valid", bits 0–5 the bit (Table 53).
    pub const fn field(self) -> u16 {
        0x8000 | (self.bit as u16 & 0x3F)
    }
}

/// One parameter: number, name, type, limits, default, access and description data.
///
/// Build one with [`ParamDef::new`] and the `const` modifiers:
/// `ParamDef::new(100, "Accel. Time", Type::U16).limits(0, 9999).with_default(50).scaled(0.1, VAR_TIME, CONV_BASE)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamDef {
    /// Parameter number.
    pub pnu: u16,
    /// Symbolic name, at most 16 printable ASCII characters (the description's name field).
    pub name: &'static str,
    /// Data type of each element.
    pub ty: Type,
    /// Number of array elements; 0 = a single value (not an array).
    pub elements: u16,
    /// Low limit (in the value's own units, e.g. tenths of a second).
    pub min: i64,
    /// High limit.
    pub max: i64,
    /// Factory setting of every element not listed in [`ParamDef::defaults`].
    pub default: i64,
    /// Factory settings per array element (empty: all [`ParamDef::default`]).
    pub defaults: &'static [i64],
    /// Whether a change request is refused with 0x01 (the drive itself may still [`Table::set`] it).
    pub read_only: bool,
    /// Standardisation factor and variable attribute; `None` = not relevant (identifier bit 8).
    pub scale: Option<Scale>,
    /// Normalisation reference (ratio parameters).
    pub normalisation: Option<Normalisation>,
}

impl ParamDef {
    /// A writeable single value over the whole range of `ty`, default 0, no scale.
    pub const fn new(pnu: u16, name: &'static str, ty: Type) -> Self {
        ParamDef {
            pnu,
            name,
            ty,
            elements: 0,
            min: ty.min(),
            max: ty.max(),
            default: 0,
            defaults: &[],
            read_only: false,
            scale: None,
            normalisation: None,
        }
    }
    /// An array of `elements` values (1..).
    pub const fn array(mut self, elements: u16) -> Self {
        self.elements = elements;
        self
    }
    /// Low and high limit.
    pub const fn limits(mut self, min: i64, max: i64) -> Self {
        self.min = min;
        self.max = max;
        self
    }
    /// Factory setting (of every element).
    pub const fn with_default(mut self, default: i64) -> Self {
        self.default = default;
        self
    }
    /// Factory settings per array element (as many as the array has).
    pub const fn with_defaults(mut self, defaults: &'static [i64]) -> Self {
        self.defaults = defaults;
        self
    }
    /// Refuse change requests (0x01).
    pub const fn read_only(mut self) -> Self {
        self.read_only = true;
        self
    }
    /// Standardisation factor and variable attribute.
    pub const fn scaled(mut self, factor: f32, variable_index: u8, conversion_index: i8) -> Self {
        self.scale = Some(Scale::new(factor, variable_index, conversion_index));
        self
    }
    /// Normalisation: bit `bit` of the value = the value of `reference_pnu`.
    pub const fn normalised(mut self, reference_pnu: u16, bit: u8) -> Self {
        self.normalisation = Some(Normalisation { reference_pnu, bit });
        self
    }

    /// Whether the parameter is an array.
    pub const fn is_array(&self) -> bool {
        self.elements > 0
    }
    /// Value slots the parameter takes in a [`Table`]: its elements, 1 for a single value.
    pub const fn slots(&self) -> usize {
        if self.elements == 0 {
            1
        } else {
            self.elements as usize
        }
    }
    /// Factory setting of element `k`.
    pub const fn default_of(&self, k: usize) -> i64 {
        if k < self.defaults.len() {
            self.defaults[k]
        } else {
            self.default
        }
    }
    /// The identifier field (VACON Table 50): bits 0–7 data type, 8 standardisation factor and
    /// variable attribute not relevant, 9 read-only, 10 text array (never), 12 `changed` from
    /// the factory setting, 13 reset only (never), 14 array.
    pub const fn identifier(&self, changed: bool) -> u16 {
        let mut id = self.ty.code() as u16;
        if self.scale.is_none() {
            id |= 1 << 8;
        }
        if self.read_only {
            id |= 1 << 9;
        }
        if changed {
            id |= 1 << 12;
        }
        if self.is_array() {
            id |= 1 << 14;
        }
        id
    }

    /// The addressed elements as a range of element numbers (0x04, 0x03).
    fn range(&self, addr: &ParamAddress) -> Result<Range<usize>, ParamError> {
        let n = addr.count() as usize;
        if !self.is_array() {
            return if addr.subindex == 0 && n == 1 { Ok(0..1) } else { Err(ErrorValue::NO_ARRAY.into()) };
        }
        let first = addr.subindex as usize;
        if first + n > self.elements as usize {
            return Err(ErrorValue::INVALID_SUBINDEX.into());
        }
        Ok(first..first + n)
    }

    /// Panics (at compile time in a const context) when the definition is inconsistent.
    const fn check(&self) {
        let name = self.name.as_bytes();
        assert!(name.len() <= NAME_LEN, "ParamDef: name longer than 16 characters");
        let mut i = 0;
        while i < name.len() {
            assert!(name[i] >= 0x20 && name[i] <= 0x7E, "ParamDef: name not printable ASCII");
            i += 1;
        }
        assert!(self.ty.min() <= self.min && self.min <= self.max && self.max <= self.ty.max(), "ParamDef: limits");
        assert!(self.min <= self.default && self.default <= self.max, "ParamDef: default outside the limits");
        assert!(
            self.defaults.is_empty() || self.defaults.len() == self.elements as usize,
            "ParamDef: defaults must cover the array"
        );
        let mut k = 0;
        while k < self.defaults.len() {
            assert!(
                self.min <= self.defaults[k] && self.defaults[k] <= self.max,
                "ParamDef: default outside the limits"
            );
            k += 1;
        }
        if let Some(n) = self.normalisation {
            assert!(n.bit <= 31, "ParamDef: normalisation bit above 31");
        }
    }
}

/// Value slots a table over `defs` needs (the `N` of [`Table`]).
pub const fn slots(defs: &[ParamDef]) -> usize {
    let mut n = 0;
    let mut i = 0;
    while i < defs.len() {
        n += defs[i].slots();
        i += 1;
    }
    n
}

/// Which formats reads answer with.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum FormatStyle {
    /// Word 0x42 / Double word 0x43, as VACON (Table 42, §6.4.4.2) and WEG (CFW-11 §4.2.5) answer.
    Untyped,
    /// The PROFIdrive data type: Unsigned16 0x06, Integer16 0x03, Unsigned32 0x07, Integer32 0x04.
    Typed,
}

/// The values of the parameters `defs`, with `N` = [`slots`]`(defs)`.
#[derive(Debug, Clone, PartialEq)]
pub struct Table<const N: usize> {
    defs: &'static [ParamDef],
    values: [u32; N],
    style: FormatStyle,
    axis: Option<u8>,
}

/// The 46-byte description split into its fields: (format, first byte, length), index = subindex.
const FIELDS: [(Format, usize, usize); 13] = [
    (Format::OCTET_STRING, 0, DESCRIPTION_LEN),
    (Format::UNSIGNED16, 0, 2),
    (Format::UNSIGNED16, 2, 2),
    (Format::FLOATING_POINT, 4, 4),
    (Format::OCTET_STRING, 8, 2),
    (Format::OCTET_STRING, 10, 4),
    (Format::VISIBLE_STRING, 14, NAME_LEN),
    (Format::OCTET_STRING, 30, 4),
    (Format::OCTET_STRING, 34, 4),
    (Format::OCTET_STRING, 38, 2),
    (Format::UNSIGNED16, 40, 2),
    (Format::UNSIGNED16, 42, 2),
    (Format::UNSIGNED16, 44, 2),
];

impl<const N: usize> Table<N> {
    /// A table over `defs` with every value at its factory setting, answering axes 0 and 1
    /// (WEG uses 0, VACON 1) with [`FormatStyle::Untyped`].
    ///
    /// # Panics
    ///
    /// If `N` is not [`slots`]`(defs)`, the PNUs are not strictly ascending, or a definition is
    /// inconsistent (name longer than 16 characters or not printable ASCII, limits outside the
    /// type, a default outside the limits, per-element defaults not covering the array). In a
    /// const item that is a compile error.
    pub const fn new(defs: &'static [ParamDef]) -> Self {
        assert!(slots(defs) == N, "Table: N must be slots(defs)");
        let mut values = [0u32; N];
        let mut i = 0;
        let mut off = 0;
        while i < defs.len() {
            let d = &defs[i];
            d.check();
            assert!(i == 0 || defs[i - 1].pnu < d.pnu, "Table: PNUs must be strictly ascending");
            let mut k = 0;
            while k < d.slots() {
                values[off + k] = d.ty.encode(d.default_of(k));
                k += 1;
            }
            off += d.slots();
            i += 1;
        }
        Table { defs, values, style: FormatStyle::Untyped, axis: None }
    }

    /// Answer reads with `style`.
    pub const fn with_formats(mut self, style: FormatStyle) -> Self {
        self.style = style;
        self
    }

    /// Answer only DO-ID / axis `axis` (others: 0x19).
    pub const fn with_axis(mut self, axis: u8) -> Self {
        self.axis = Some(axis);
        self
    }

    /// The definitions, ascending by PNU.
    pub fn defs(&self) -> &'static [ParamDef] {
        self.defs
    }

    /// The definition of `pnu`.
    pub fn def(&self, pnu: u16) -> Option<&'static ParamDef> {
        self.find(pnu).map(|(d, _)| d)
    }

    /// Element `subindex` (0 for a single value) of `pnu`.
    pub fn get(&self, pnu: u16, subindex: u16) -> Option<i64> {
        let (d, off) = self.find(pnu)?;
        let k = subindex as usize;
        (k < d.slots()).then(|| d.ty.decode(self.values[off + k]))
    }

    /// Set element `subindex` of `pnu` from the drive's side: read-only parameters too, but
    /// only within the limits. Errors as for a change request: 0x00, 0x03 / 0x04, 0x02.
    pub fn set(&mut self, pnu: u16, subindex: u16, value: i64) -> Result<(), ParamError> {
        let (d, off) = self.find(pnu).ok_or(ErrorValue::IMPERMISSIBLE_PARAMETER_NUMBER)?;
        let addr = ParamAddress { attribute: Attribute::Value, elements: 1, pnu, subindex };
        let k = d.range(&addr)?.start;
        if value < d.min || value > d.max {
            return Err(ErrorValue::LIMIT_EXCEEDED.into());
        }
        self.values[off + k] = d.ty.encode(value);
        Ok(())
    }

    /// Every value back to its factory setting.
    pub fn reset(&mut self) {
        let mut off = 0;
        for d in self.defs {
            for k in 0..d.slots() {
                self.values[off + k] = d.ty.encode(d.default_of(k));
            }
            off += d.slots();
        }
    }

    /// Whether any element of `pnu` differs from its factory setting (identifier bit 12).
    pub fn is_changed(&self, pnu: u16) -> bool {
        self.find(pnu).is_some_and(|(d, off)| self.changed(d, off))
    }

    /// The complete 46-byte description element of `pnu` (VACON §6.4.3.7, Table 49).
    pub fn description(&self, pnu: u16) -> Option<[u8; DESCRIPTION_LEN]> {
        self.find(pnu).map(|(d, off)| self.describe(d, off))
    }

    fn find(&self, pnu: u16) -> Option<(&'static ParamDef, usize)> {
        let mut off = 0;
        for d in self.defs {
            if d.pnu == pnu {
                return Some((d, off));
            }
            off += d.slots();
        }
        None
    }

    fn changed(&self, d: &ParamDef, off: usize) -> bool {
        (0..d.slots()).any(|k| self.values[off + k] != d.ty.encode(d.default_of(k)))
    }

    fn describe(&self, d: &ParamDef, off: usize) -> [u8; DESCRIPTION_LEN] {
        describe(d, self.changed(d, off))
    }

    fn read_format(&self, ty: Type) -> Format {
        match self.style {
            FormatStyle::Untyped => ty.untyped_format(),
            FormatStyle::Typed => ty.typed_format(),
        }
    }
}

/// The 46-byte description element of `d` (VACON §6.4.3.7, Table 49); `changed`: a value
/// differs from its factory setting (identifier bit 12).
fn describe(d: &ParamDef, changed: bool) -> [u8; DESCRIPTION_LEN] {
    let mut b = [0u8; DESCRIPTION_LEN];
    b[0..2].copy_from_slice(&d.identifier(changed).to_be_bytes());
    b[2..4].copy_from_slice(&d.elements.to_be_bytes());
    let (factor, var, conv) = match d.scale {
        Some(s) => (s.factor, s.variable_index, s.conversion_index as u8),
        None => (1.0, 0, 0),
    };
    b[4..8].copy_from_slice(&factor.to_bits().to_be_bytes());
    b[8..10].copy_from_slice(&[var, conv]);
    // 10..14 reserved.
    b[14..30].fill(b' ');
    b[14..14 + d.name.len()].copy_from_slice(d.name.as_bytes());
    // A limit as a 32-bit integer of the parameter's signedness (see the module doc).
    b[30..34].copy_from_slice(&(d.min as u32).to_be_bytes());
    b[34..38].copy_from_slice(&(d.max as u32).to_be_bytes());
    // 38..40 reserved, 40..42 ID extension.
    if let Some(n) = d.normalisation {
        b[42..44].copy_from_slice(&n.reference_pnu.to_be_bytes());
        b[44..46].copy_from_slice(&n.field().to_be_bytes());
    }
    b
}

/// Attribute 0x20 of `d` (subindex = field, 0 the whole element) into `out`; `changed` is
/// asked only for a valid request.
fn read_description_of(
    d: &ParamDef,
    changed: impl FnOnce() -> bool,
    addr: &ParamAddress,
    out: &mut ValueWriter<'_>,
) -> Result<(), ParamError> {
    if addr.count() != 1 {
        return Err(ErrorValue::IMPERMISSIBLE_ADDRESS.into());
    }
    let &(format, start, len) = FIELDS.get(addr.subindex as usize).ok_or(ErrorValue::INVALID_SUBINDEX)?;
    let size = format.value_size().unwrap_or(1);
    let b = describe(d, changed());
    out.set_format(format);
    b[start..start + len].chunks(size).try_for_each(|v| out.push_raw(v))
}

/// [`Table::read_description`] of a table over `defs` whose values are all at their factory
/// setting, without the table: the descriptions of parameters whose values are kept elsewhere
/// (the card's PNUs, [`super::pnu::CardTable`]) need no copy of a value array.
pub fn read_factory_description(
    defs: &[ParamDef],
    addr: &ParamAddress,
    out: &mut ValueWriter<'_>,
) -> Result<(), ParamError> {
    let d = defs.iter().find(|d| d.pnu == addr.pnu).ok_or(ErrorValue::IMPERMISSIBLE_PARAMETER_NUMBER)?;
    read_description_of(d, || false, addr, out)
}

impl<const N: usize> ParameterAccess for Table<N> {
    fn has_axis(&self, axis: u8) -> bool {
        match self.axis {
            Some(a) => a == axis,
            None => axis <= 1,
        }
    }

    fn read_value(&mut self, _axis: u8, addr: &ParamAddress, out: &mut ValueWriter<'_>) -> Result<(), ParamError> {
        let (d, off) = self.find(addr.pnu).ok_or(ErrorValue::IMPERMISSIBLE_PARAMETER_NUMBER)?;
        let range = d.range(addr)?;
        out.set_format(self.read_format(d.ty));
        for &raw in &self.values[off + range.start..off + range.end] {
            match d.ty.size() {
                2 => out.push_u16(raw as u16)?,
                _ => out.push_u32(raw)?,
            }
        }
        Ok(())
    }

    fn write_value(&mut self, _axis: u8, addr: &ParamAddress, values: &ValueBlock<'_>) -> Result<(), ParamError> {
        let (d, off) = self.find(addr.pnu).ok_or(ErrorValue::IMPERMISSIBLE_PARAMETER_NUMBER)?;
        let range = d.range(addr)?;
        if d.read_only {
            return Err(ErrorValue::VALUE_CANNOT_BE_CHANGED.into());
        }
        if values.format != d.ty.untyped_format() && values.format != d.ty.typed_format() {
            return Err(ErrorValue::INCORRECT_DATA_TYPE.into());
        }
        for (i, k) in range.enumerate() {
            let raw = match d.ty.size() {
                2 => values.u16(i).map(u32::from),
                _ => values.u32(i),
            };
            // The codec checked `values.count == addr.count()`; a short block cannot reach here.
            let raw = raw.ok_or(ErrorValue::NUMBER_OF_VALUES_INCONSISTENT)?;
            let v = d.ty.decode(raw);
            if v < d.min || v > d.max {
                let info = if d.is_array() { Some(k as u16) } else { None };
                return Err(ParamError { value: ErrorValue::LIMIT_EXCEEDED, additional_info: info });
            }
            self.values[off + k] = raw;
        }
        Ok(())
    }

    fn read_description(
        &mut self,
        _axis: u8,
        addr: &ParamAddress,
        out: &mut ValueWriter<'_>,
    ) -> Result<(), ParamError> {
        let (d, off) = self.find(addr.pnu).ok_or(ErrorValue::IMPERMISSIBLE_PARAMETER_NUMBER)?;
        read_description_of(d, || self.changed(d, off), addr, out)
    }

    fn read_text(&mut self, _axis: u8, addr: &ParamAddress, _out: &mut ValueWriter<'_>) -> Result<(), ParamError> {
        match self.find(addr.pnu) {
            None => Err(ErrorValue::IMPERMISSIBLE_PARAMETER_NUMBER.into()),
            Some(_) => Err(ErrorValue::NO_TEXT_ARRAY.into()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::param::{respond, ParamRequest, ParamResponse, MAX_LEN};
    use super::*;

    /// One of each kind: U16 scaled time, I16 normalised ratio, U32, I32, read-only U16 without
    /// scale, a writeable U16 array and a read-only one with per-element defaults.
    const DEFS: &[ParamDef] = &[
        ParamDef::new(100, "Accel. Time", Type::U16).limits(0, 9999).with_default(50).scaled(0.1, VAR_TIME, CONV_BASE),
        ParamDef::new(200, "Speed Ref", Type::I16)
            .limits(-16384, 16384)
            .scaled(100.0 / 16384.0, VAR_RATIO, 0)
            .normalised(10111, 14),
        ParamDef::new(300, "Operation Time", Type::U32).with_default(0xFFFF_FFF0),
        ParamDef::new(301, "Offset", Type::I32).limits(-100_000, 100_000).with_default(-5),
        ParamDef::new(680, "Status Word", Type::U16).read_only().with_default(0x1234),
        ParamDef::new(9901, "Dummy Array", Type::U16).array(8).limits(0, 1000),
        ParamDef::new(10109, "PD In", Type::U16).array(4).read_only().with_defaults(&[1, 2, 3, 4]),
    ];
    const N: usize = slots(DEFS);
    const TABLE: Table<N> = Table::new(DEFS);

    fn addr(attribute: Attribute, pnu: u16, elements: u8, subindex: u16) -> ParamAddress {
        ParamAddress { attribute, elements, pnu, subindex }
    }
    fn value(pnu: u16, elements: u8, subindex: u16) -> ParamAddress {
        addr(Attribute::Value, pnu, elements, subindex)
    }
    fn desc(pnu: u16, subindex: u16) -> ParamAddress {
        addr(Attribute::Description, pnu, 1, subindex)
    }

    /// (format, count, bytes) of a read, or its error.
    fn read(t: &mut Table<N>, a: ParamAddress) -> Result<(u8, u8, Vec<u8>), ParamError> {
        let mut buf = [0u8; 236];
        let mut w = ValueWriter::new(&mut buf);
        match a.attribute {
            Attribute::Value => t.read_value(1, &a, &mut w),
            Attribute::Description => t.read_description(1, &a, &mut w),
            _ => t.read_text(1, &a, &mut w),
        }?;
        Ok((w.format().unwrap().0, w.count(), w.bytes().to_vec()))
    }

    fn write(t: &mut Table<N>, a: ParamAddress, format: Format, bytes: &[u8]) -> Result<(), ParamError> {
        let count = (bytes.len() / format.value_size().unwrap()) as u8;
        t.write_value(1, &a, &ValueBlock { format, count, bytes })
    }

    fn err(v: u16) -> Result<(), ParamError> {
        Err(ErrorValue(v).into())
    }

    #[test]
    fn construction_and_slots() {
        assert_eq!(N, 1 + 1 + 1 + 1 + 1 + 8 + 4);
        let t = TABLE;
        assert_eq!(t.defs().len(), 7);
        assert_eq!(t.get(100, 0), Some(50));
        assert_eq!(t.get(300, 0), Some(0xFFFF_FFF0));
        assert_eq!(t.get(301, 0), Some(-5));
        assert_eq!((t.get(10109, 3), t.get(10109, 4), t.get(999, 0)), (Some(4), None, None));
        assert_eq!(t.def(9901).map(|d| d.elements), Some(8));
        assert!(t.has_axis(0) && t.has_axis(1) && !t.has_axis(2));
        let only2 = TABLE.with_axis(2);
        assert!(only2.has_axis(2) && !only2.has_axis(1));
    }

    #[test]
    #[should_panic(expected = "N must be slots")]
    fn wrong_n_panics() {
        let _ = Table::<3>::new(DEFS);
    }

    #[test]
    #[should_panic(expected = "strictly ascending")]
    fn duplicate_pnu_panics() {
        static D: [ParamDef; 2] = [ParamDef::new(5, "a", Type::U16), ParamDef::new(5, "b", Type::U16)];
        let _ = Table::<2>::new(&D);
    }

    #[test]
    #[should_panic(expected = "longer than 16")]
    fn long_name_panics() {
        static D: [ParamDef; 1] = [ParamDef::new(5, "Acceleration Time", Type::U16)];
        let _ = Table::<1>::new(&D);
    }

    #[test]
    #[should_panic(expected = "default outside")]
    fn default_outside_limits_panics() {
        static D: [ParamDef; 1] = [ParamDef::new(5, "a", Type::U16).limits(1, 10)];
        let _ = Table::<1>::new(&D);
    }

    #[test]
    #[should_panic(expected = "limits")]
    fn limits_outside_type_panic() {
        static D: [ParamDef; 1] = [ParamDef::new(5, "a", Type::I16).limits(0, 40000)];
        let _ = Table::<1>::new(&D);
    }

    #[test]
    #[should_panic(expected = "cover the array")]
    fn short_defaults_panic() {
        static D: [ParamDef; 1] = [ParamDef::new(5, "a", Type::U16).array(3).with_defaults(&[1, 2])];
        let _ = Table::<3>::new(&D);
    }

    #[test]
    fn read_values_untyped_and_typed() {
        let mut t = TABLE;
        assert_eq!(read(&mut t, value(100, 1, 0)), Ok((0x42, 1, vec![0, 50])));
        assert_eq!(read(&mut t, value(100, 0, 0)), Ok((0x42, 1, vec![0, 50])), "0 elements = 1");
        t.set(200, 0, -2).unwrap();
        assert_eq!(read(&mut t, value(200, 1, 0)), Ok((0x42, 1, vec![0xFF, 0xFE])));
        assert_eq!(read(&mut t, value(300, 1, 0)), Ok((0x43, 1, vec![0xFF, 0xFF, 0xFF, 0xF0])));
        assert_eq!(read(&mut t, value(301, 1, 0)), Ok((0x43, 1, vec![0xFF, 0xFF, 0xFF, 0xFB])));
        let mut t = t.with_formats(FormatStyle::Typed);
        assert_eq!(read(&mut t, value(100, 1, 0)), Ok((0x06, 1, vec![0, 50])));
        assert_eq!(read(&mut t, value(200, 1, 0)), Ok((0x03, 1, vec![0xFF, 0xFE])));
        assert_eq!(read(&mut t, value(300, 1, 0)), Ok((0x07, 1, vec![0xFF, 0xFF, 0xFF, 0xF0])));
        assert_eq!(read(&mut t, value(301, 1, 0)), Ok((0x04, 1, vec![0xFF, 0xFF, 0xFF, 0xFB])));
    }

    #[test]
    fn read_arrays() {
        let mut t = TABLE;
        assert_eq!(read(&mut t, value(10109, 4, 0)), Ok((0x42, 4, vec![0, 1, 0, 2, 0, 3, 0, 4])));
        assert_eq!(read(&mut t, value(10109, 2, 1)), Ok((0x42, 2, vec![0, 2, 0, 3])));
        assert_eq!(read(&mut t, value(10109, 1, 3)), Ok((0x42, 1, vec![0, 4])));
        assert_eq!(read(&mut t, value(10109, 0, 2)), Ok((0x42, 1, vec![0, 3])));
        assert_eq!(read(&mut t, value(9901, 8, 0)).map(|r| r.1), Ok(8));
    }

    #[test]
    fn read_errors() {
        let mut t = TABLE;
        let e = |v: u16| Err(ErrorValue(v).into());
        assert_eq!(read(&mut t, value(101, 1, 0)), e(0x00), "unknown PNU");
        assert_eq!(read(&mut t, value(100, 1, 1)), e(0x04), "subindex on a single value");
        assert_eq!(read(&mut t, value(100, 2, 0)), e(0x04), "two elements of a single value");
        assert_eq!(read(&mut t, value(10109, 1, 4)), e(0x03), "subindex past the end");
        assert_eq!(read(&mut t, value(10109, 2, 3)), e(0x03), "elements past the end");
        assert_eq!(read(&mut t, value(10109, 5, 0)), e(0x03));
        assert_eq!(read(&mut t, value(10109, 1, 0xFFFF)), e(0x03));
        // A full writer: 0x15, and it remembers the overflow for `respond`.
        let mut buf = [0u8; 6];
        let mut w = ValueWriter::new(&mut buf);
        assert_eq!(t.read_value(1, &value(10109, 4, 0), &mut w), err(0x15));
        assert!(w.overflowed());
    }

    #[test]
    fn writes() {
        let mut t = TABLE;
        assert_eq!(write(&mut t, value(100, 1, 0), Format::WORD, &[0x27, 0x0F]), Ok(()));
        assert_eq!(t.get(100, 0), Some(9999));
        assert_eq!(write(&mut t, value(100, 0, 0), Format::UNSIGNED16, &[0, 0]), Ok(()), "low limit, typed");
        assert_eq!(t.get(100, 0), Some(0));
        assert_eq!(write(&mut t, value(100, 1, 0), Format::WORD, &[0x27, 0x10]), err(0x02), "10000 > 9999");
        assert_eq!(t.get(100, 0), Some(0));
        // I16: Word and Integer16; −16385 and 16385 are outside; 0xC000 = −16384 inside.
        assert_eq!(write(&mut t, value(200, 1, 0), Format::WORD, &[0xC0, 0x00]), Ok(()));
        assert_eq!(t.get(200, 0), Some(-16384));
        assert_eq!(write(&mut t, value(200, 1, 0), Format::INTEGER16, &[0xBF, 0xFF]), err(0x02));
        assert_eq!(write(&mut t, value(200, 1, 0), Format::INTEGER16, &[0x40, 0x01]), err(0x02));
        assert_eq!(write(&mut t, value(200, 1, 0), Format::UNSIGNED16, &[0, 1]), err(0x05), "not its type");
        // U32 / I32: Double word and the type.
        assert_eq!(write(&mut t, value(300, 1, 0), Format::DOUBLE_WORD, &[0xFF; 4]), Ok(()));
        assert_eq!(t.get(300, 0), Some(0xFFFF_FFFF));
        assert_eq!(write(&mut t, value(300, 1, 0), Format::UNSIGNED32, &[0, 0, 0, 7]), Ok(()));
        assert_eq!(write(&mut t, value(301, 1, 0), Format::INTEGER32, &(-100_000i32).to_be_bytes()), Ok(()));
        assert_eq!(t.get(301, 0), Some(-100_000));
        assert_eq!(write(&mut t, value(301, 1, 0), Format::INTEGER32, &(-100_001i32).to_be_bytes()), err(0x02));
        assert_eq!(write(&mut t, value(301, 1, 0), Format::WORD, &[0, 1]), err(0x05), "Word for a 32-bit value");
        assert_eq!(write(&mut t, value(300, 1, 0), Format::INTEGER32, &[0, 0, 0, 1]), err(0x05));
        assert_eq!(write(&mut t, value(100, 1, 0), Format::DOUBLE_WORD, &[0, 0, 0, 1]), err(0x05));
        assert_eq!(write(&mut t, value(100, 1, 0), Format::BYTE, &[1]), err(0x05));
        assert_eq!(write(&mut t, value(100, 1, 0), Format::FLOATING_POINT, &[0, 0, 0, 0]), err(0x05));
        // Read-only, unknown, address errors.
        assert_eq!(write(&mut t, value(680, 1, 0), Format::WORD, &[0, 1]), err(0x01));
        assert_eq!(t.get(680, 0), Some(0x1234));
        assert_eq!(write(&mut t, value(10109, 1, 0), Format::WORD, &[0, 1]), err(0x01));
        assert_eq!(write(&mut t, value(101, 1, 0), Format::WORD, &[0, 1]), err(0x00));
        assert_eq!(write(&mut t, value(100, 1, 1), Format::WORD, &[0, 1]), err(0x04));
        assert_eq!(write(&mut t, value(100, 2, 0), Format::WORD, &[0, 1, 0, 2]), err(0x04));
        assert_eq!(write(&mut t, value(9901, 2, 7), Format::WORD, &[0, 1, 0, 2]), err(0x03));
    }

    #[test]
    fn array_writes_stop_at_the_first_bad_element() {
        let mut t = TABLE;
        assert_eq!(write(&mut t, value(9901, 3, 2), Format::WORD, &[0, 10, 0, 20, 0, 30]), Ok(()));
        assert_eq!((0..8).map(|k| t.get(9901, k).unwrap()).collect::<Vec<_>>(), [0, 0, 10, 20, 30, 0, 0, 0]);
        // Element 6 (1001) is beyond the limit: 5 written, 6 and 7 not; the subindex is named.
        let r = write(&mut t, value(9901, 3, 5), Format::WORD, &[0, 55, 0x03, 0xE9, 0, 77]);
        assert_eq!(r, Err(ParamError { value: ErrorValue::LIMIT_EXCEEDED, additional_info: Some(6) }));
        assert_eq!((t.get(9901, 5), t.get(9901, 6), t.get(9901, 7)), (Some(55), Some(0), Some(0)));
        assert!(t.is_changed(9901) && !t.is_changed(100));
        t.reset();
        assert!(!t.is_changed(9901));
    }

    #[test]
    fn drive_side_set() {
        let mut t = TABLE;
        assert_eq!(t.set(680, 0, 0xBEEF), Ok(()), "read-only for the master, not for the drive");
        assert_eq!(t.get(680, 0), Some(0xBEEF));
        assert_eq!(t.set(100, 0, 10_000), err(0x02));
        assert_eq!(t.set(100, 1, 1), err(0x04));
        assert_eq!(t.set(10109, 4, 1), err(0x03));
        assert_eq!(t.set(10109, 3, 9), Ok(()));
        assert_eq!(t.set(1, 0, 0), err(0x00));
    }

    /// P100 "Accel. Time", 0..9999 in 0.1 s, default 50: the 46 bytes of VACON Table 49.
    const P100_DESCRIPTION: [u8; DESCRIPTION_LEN] = [
        0x00, 0x06, // identifier: Unsigned16, scaled, writeable, unchanged, single
        0x00, 0x00, // number of array elements
        0x3D, 0xCC, 0xCC, 0xCD, // standardisation factor 0.1f32
        0x04, 0x00, // variable index 4 (time, s), conversion index 0
        0x00, 0x00, 0x00, 0x00, // reserved
        b'A', b'c', b'c', b'e', b'l', b'.', b' ', b'T', b'i', b'm', b'e', b' ', b' ', b' ', b' ', b' ', // name
        0x00, 0x00, 0x00, 0x00, // low limit 0
        0x00, 0x00, 0x27, 0x0F, // high limit 9999
        0x00, 0x00, // reserved
        0x00, 0x00, // ID extension
        0x00, 0x00, // normalisation reference parameter
        0x00, 0x00, // normalisation field
    ];

    #[test]
    fn description_whole_byte_by_byte() {
        let mut t = TABLE;
        assert_eq!(t.description(100), Some(P100_DESCRIPTION));
        assert_eq!(read(&mut t, desc(100, 0)), Ok((0x0A, 46, P100_DESCRIPTION.to_vec())));
        assert_eq!(read(&mut t, addr(Attribute::Description, 100, 0, 0)).map(|r| r.1), Ok(46), "0 elements = 1");
        assert_eq!(f32::from_bits(u32::from_be_bytes([0x3D, 0xCC, 0xCC, 0xCD])), 0.1);
    }

    #[test]
    fn description_fields() {
        let mut t = TABLE;
        let field = |t: &mut Table<N>, pnu, sub| read(t, desc(pnu, sub)).unwrap();
        assert_eq!(field(&mut t, 100, 1), (0x06, 1, vec![0x00, 0x06]));
        assert_eq!(field(&mut t, 100, 2), (0x06, 1, vec![0, 0]));
        assert_eq!(field(&mut t, 100, 3), (0x08, 1, vec![0x3D, 0xCC, 0xCC, 0xCD]));
        assert_eq!(field(&mut t, 100, 4), (0x0A, 2, vec![4, 0]));
        assert_eq!(field(&mut t, 100, 5), (0x0A, 4, vec![0; 4]));
        assert_eq!(field(&mut t, 100, 6), (0x09, 16, b"Accel. Time     ".to_vec()));
        assert_eq!(field(&mut t, 100, 7), (0x0A, 4, vec![0; 4]));
        assert_eq!(field(&mut t, 100, 8), (0x0A, 4, vec![0, 0, 0x27, 0x0F]));
        assert_eq!(field(&mut t, 100, 9), (0x0A, 2, vec![0; 2]));
        assert_eq!(field(&mut t, 100, 10), (0x06, 1, vec![0; 2]));
        assert_eq!(field(&mut t, 100, 11), (0x06, 1, vec![0; 2]));
        assert_eq!(field(&mut t, 100, 12), (0x06, 1, vec![0; 2]));
        // Each field is the same bytes as in the whole element.
        for sub in 1..=DESCRIPTION_FIELDS {
            let (_, start, len) = FIELDS[sub as usize];
            assert_eq!(field(&mut t, 200, sub).2, t.description(200).unwrap()[start..start + len]);
        }

        // I16 ratio, normalised to PNU 10111 bit 14; limits sign-extended.
        assert_eq!(field(&mut t, 200, 1), (0x06, 1, vec![0x00, 0x03]));
        assert_eq!(field(&mut t, 200, 4), (0x0A, 2, vec![24, 0]));
        assert_eq!(field(&mut t, 200, 3).2, (100.0f32 / 16384.0).to_bits().to_be_bytes());
        assert_eq!(field(&mut t, 200, 7).2, [0xFF, 0xFF, 0xC0, 0x00]);
        assert_eq!(field(&mut t, 200, 8).2, [0x00, 0x00, 0x40, 0x00]);
        assert_eq!(field(&mut t, 200, 11).2, [0x27, 0x7F]);
        assert_eq!(field(&mut t, 200, 12).2, [0x80, 0x0E]);
        // U32 over its whole range; I32.
        assert_eq!(field(&mut t, 300, 1).2, [0x01, 0x07], "bit 8: no scale");
        assert_eq!(field(&mut t, 300, 8).2, [0xFF; 4]);
        assert_eq!(field(&mut t, 301, 7).2, (-100_000i32).to_be_bytes());
        // Read-only without scale: bits 8, 9; factor 1.0, attribute 0 0.
        assert_eq!(field(&mut t, 680, 1).2, [0x03, 0x06]);
        assert_eq!(field(&mut t, 680, 3).2, [0x3F, 0x80, 0, 0]);
        assert_eq!(field(&mut t, 680, 4).2, [0, 0]);
        assert_eq!(field(&mut t, 680, 6).2, b"Status Word     ");
        // Arrays: bit 14 and the number of elements; changed: bit 12.
        assert_eq!(field(&mut t, 10109, 1).2, [0x43, 0x06]);
        assert_eq!(field(&mut t, 10109, 2).2, [0, 4]);
        assert_eq!(field(&mut t, 9901, 1).2, [0x41, 0x06]);
        write(&mut t, value(9901, 1, 7), Format::WORD, &[0, 1]).unwrap();
        assert_eq!(field(&mut t, 9901, 1).2, [0x51, 0x06]);
        assert_eq!(field(&mut t, 9901, 2).2, [0, 8]);
    }

    #[test]
    fn description_errors_and_texts() {
        let mut t = TABLE;
        let e = |v: u16| Err(ErrorValue(v).into());
        assert_eq!(read(&mut t, desc(101, 0)), e(0x00));
        assert_eq!(read(&mut t, desc(100, 13)), e(0x03));
        assert_eq!(read(&mut t, desc(100, 0xFFFF)), e(0x03));
        assert_eq!(read(&mut t, addr(Attribute::Description, 100, 2, 1)), e(0x16));
        assert_eq!(read(&mut t, addr(Attribute::Text, 100, 1, 0)), e(0x0F));
        assert_eq!(read(&mut t, addr(Attribute::Text, 101, 1, 0)), e(0x00));
        let mut buf = [0u8; 40];
        let mut w = ValueWriter::new(&mut buf);
        assert_eq!(t.read_description(1, &desc(100, 0), &mut w), err(0x15));
    }

    /// Through the codec: a read of three parameters, a description, a change with one bad value.
    #[test]
    fn through_respond() {
        let mut t = TABLE;
        let mut out = [0u8; MAX_LEN];
        let req = [
            1, 1, 1, 3, 0x10, 1, 0, 100, 0, 0, 0x10, 2, 0x27, 0x7D, 0, 1, 0x20, 1, 0, 100, 0, 6, //
        ];
        let n = respond(&ParamRequest::parse(&req).unwrap(), &mut t, &mut out);
        let mut expected = vec![1, 1, 1, 3, 0x42, 1, 0, 50, 0x42, 2, 0, 2, 0, 3, 0x09, 16];
        expected.extend_from_slice(b"Accel. Time     ");
        assert_eq!(&out[..n], &expected[..]);
        assert_eq!(ParamResponse::parse(&out[..n]).unwrap().values().count(), 3);
        // Change P100 = 85 (CFW-11 §4.2.5 Exemplo 2) and P680 (read-only).
        let req = [2, 2, 0, 2, 0x10, 1, 0, 100, 0, 0, 0x10, 1, 0x02, 0xA8, 0, 0, 0x42, 1, 0, 0x55, 0x42, 1, 0, 1];
        let n = respond(&ParamRequest::parse(&req).unwrap(), &mut t, &mut out);
        assert_eq!(&out[..n], &[2, 0x82, 0, 2, 0x40, 0, 0x44, 1, 0, 0x01]);
        assert_eq!(t.get(100, 0), Some(85));
        // Axis 2 does not exist.
        let req = [3, 1, 2, 1, 0x10, 1, 0, 100, 0, 0];
        let n = respond(&ParamRequest::parse(&req).unwrap(), &mut t, &mut out);
        assert_eq!(&out[..n], &[3, 0x81, 2, 1, 0x44, 1, 0, 0x19]);
    }
}
