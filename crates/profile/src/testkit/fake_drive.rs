//! The one fake drive parameter table of the tests (issue 13 item 5): [`FakeDrive`].
//!
//! Every test that needs a drive's parameters — the profile's own tests (record 47 against the
//! manuals' examples, record 48, PKW, the reference reads, the card's PNUs), the DP-V1 record
//! tests (`host-tests/tests/dpv1.rs`), the DPM mailbox tests, the fast path's differential
//! check and the fuzz targets `profidrive`, `node_dpv1` and `pkw` — reads and writes this one type
//! through [`ParameterAccess`]. A test configures it instead of writing a table of its own:
//!
//! * **the standard PNUs** ([`FakeDrive::new`], [`FakeDrive::standard`]): thirteen PNUs, each
//!   exercising one rule of the PROFIdrive parameter access (reference §5.2: formats, arrays,
//!   limits, read-only, descriptions, texts), the set the card's tests and the fuzz targets use;
//! * **a drive's own parameters** as a [`Table`] of [`ParamDef`](crate::profile::table::ParamDef)s
//!   ([`FakeDrive::with_table`]): the values a manual's example shows (VACON OPTE3/E5 §6.4.4,
//!   WEG CFW-11 §4.2.5, CFW500 §5.2.5), with the table's own formats, limits and descriptions;
//! * **behaviour** a real drive has and a plain table has not: the axes (DO-IDs) it answers,
//!   VACON's indirect drive-parameter PNU 10001 with the ID in the subindex ([`Indirect`],
//!   OPTE3/E5 §6.4.4.7), a cross-parameter change rule ([`Rule`], e.g. ID 101 ≤ ID 102,
//!   §6.4.4.11), writes that accept the untyped format only — Word, or Double word for a 32-bit
//!   parameter (CFW-11 §4.2.5, VACON Table 42) —, no
//!   descriptions (VACON: the default 0x09), refused changes ([`Refusal`]: "not while running",
//!   0x11, CFW500 P0120), and PNUs that break the table contract on purpose ([`QuirkPnu`]: the
//!   response encoder must still answer a well-formed 0x05 / 0x15);
//! * **counters** of the calls that reached it, for tests that check what was asked.
//!
//! The asynchronous form (the drive behind the DPM parameter mailbox) is [`super::Mailbox`]
//! around a `FakeDrive`.
//!
//! The standard PNUs:
//!
//! | PNU | type | access |
//! |---|---|---|
//! | 1 | U16 (Word / Unsigned16), 0..=1000, text array of 3 | read/write |
//! | 2 | U16 = 0x1234 | read-only |
//! | 3 | U16\[10\], each ≤ 50000 (the failing element is named in the additional info) | read/write |
//! | 4 | U32\[4\] (Double word / Unsigned32 / Integer32) | read/write |
//! | 5 | VisibleString\[16\] | read-only |
//! | 6 | Byte\[200\] (Byte / Unsigned8 / OctetString): long reads overflow the response | read/write |
//! | 7 | FloatingPoint, finite, -1000..=1000 | read/write |
//! | 8 | a table bug: a read mixes a byte and a word (respond must answer 0x05); writes 0x0B | — |
//! | 9 | U16\[234\] (the most elements; a whole read does not fit: 0x15) | read-only |
//! | 10 | Integer16, -500..=500 | read/write |
//! | 100 | U16\[4\], each ≤ 1000 (the failing element is named) | read/write |
//! | 101 | U16 = 1234 | read-only |
//! | 200 | U16 = 0xBEEF, description element 1 (identifier) = 0x0006 | read-only |
//!
//! Axes 0 (WEG) and 1 (VACON) exist. Descriptions: element 0 (46 bytes), 1 (identifier) and
//! 6 (name) for PNUs 1..=10 except 8; PNU 200 element 1 only.
//!
//! A PNU is looked up in this order — for values, descriptions and texts alike: the quirk PNUs
//! (no description, no text), the standard PNUs (when on), the indirect PNU, the table; a PNU
//! in none of them is 0x00 "impermissible parameter number" (a text: 0x0F "no text array", as
//! VACON answers every text request). Without descriptions every description is 0x09.
//!
//! A change of a table parameter is judged in this order: a refusal, the untyped-only format,
//! the table's own checks (subindex 0x03 / 0x04, read-only 0x01, format 0x05, limits 0x02), then
//! the rule, element by element, against the table before the change; a rule that refuses
//! writes nothing.

use core::ops::{Range, RangeInclusive};

use crate::profile::param::{ErrorValue, Format, ParamAddress, ParamError, ParameterAccess, ValueBlock, ValueWriter};
use crate::profile::table::{ParamDef, Table};

/// A change rule beyond the table's own limits: given the table (the other parameters' values),
/// the PNU and one new element value, `Err` refuses the change with that error (e.g. VACON
/// §6.4.4.11: minimum frequency ID 101 ≤ maximum frequency ID 102, else 0x02).
pub type Rule<const N: usize> = fn(&Table<N>, u16, i64) -> Result<(), ErrorValue>;

/// VACON's drive parameter access (OPTE3/E5 §6.4.4.7, `pkw::VACON_DRIVE_PARAMETER`): PNU `pnu`
/// with the application ID in the subindex addresses table PNU = ID; element `k` of a request
/// is ID `subindex + k`, written one by one (the first failure ends the request, §6.4.4.11).
#[derive(Debug, Clone, PartialEq)]
pub struct Indirect {
    /// The indirect PNU (10001).
    pub pnu: u16,
    /// The error for an ID the table does not have, or that is not in `ids` (VACON: 0x6C
    /// "drive parameter not found").
    pub not_found: ErrorValue,
    /// The table PNUs that are drive parameters (application IDs): only these are reached
    /// through `pnu`.
    pub ids: RangeInclusive<u16>,
    /// Whether the drive parameters are reached through `pnu` only (0x00 when addressed
    /// directly, as VACON's are); otherwise both ways.
    pub ids_only: bool,
}

/// Changes the drive refuses in its present state (e.g. "only when stopped": 0x11 not executable).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Refusal {
    /// The PNU refused; `None`: every change.
    pub pnu: Option<u16>,
    /// The answer.
    pub error: ErrorValue,
}

/// How a [`QuirkPnu`] reads.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Quirk {
    /// This VisibleString, whatever the subindex and count (a table that ignores the address).
    Str(&'static [u8]),
    /// `count` values 0, 1, 2, … as words, whatever the subindex (an array without a bound).
    Ramp,
    /// `count` double words pushed ignoring a full writer: breaks the contract that a full
    /// [`ValueWriter`] ends the read (the encoder must still answer 0x15).
    IgnoresFull,
    /// A word then a byte under one format (inconsistent sizes: the encoder must answer 0x05).
    Mixed,
    /// Fails with this error, its additional info included.
    Fails(ParamError),
}

/// A PNU that behaves as [`Quirk`] says on reads and answers `write` to every change.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QuirkPnu {
    /// The PNU.
    pub pnu: u16,
    /// Its reads.
    pub read: Quirk,
    /// Its answer to a change.
    pub write: Result<(), ParamError>,
}

/// The fake drive: the standard PNUs and/or a table of its own, with the behaviour knobs of
/// the module documentation. `N` is the table's slot count (0: no table). Two fake drives are
/// equal when their values, knobs and counters are (the change rules: whether there is one).
#[derive(Debug, Clone)]
pub struct FakeDrive<const N: usize = 0> {
    /// Standard PNU 1.
    pub p1: u16,
    /// Standard PNU 3.
    pub p3: [u16; 10],
    /// Standard PNU 4.
    pub p4: [u32; 4],
    /// Standard PNU 6.
    pub p6: [u8; 200],
    /// Standard PNU 7.
    pub p7: f32,
    /// Standard PNU 10.
    pub p10: i16,
    /// Standard PNU 100.
    pub p100: [u16; 4],
    /// Whether the standard PNUs exist.
    pub standard: bool,
    /// The drive's own parameters.
    pub table: Table<N>,
    /// The axes (DO-IDs) that exist (others: 0x19 from the encoder).
    pub axes: RangeInclusive<u8>,
    /// VACON's indirect drive-parameter PNU, if the drive has it.
    pub indirect: Option<Indirect>,
    /// A change rule beyond the table's limits.
    pub rule: Option<Rule<N>>,
    /// Changes of table parameters accept the untyped Word / Double word only (0x05 otherwise).
    pub word_only: bool,
    /// Whether table parameters have descriptions (off: 0x09 for every description read).
    pub descriptions: bool,
    /// PNUs that break the table contract on purpose.
    pub quirks: &'static [QuirkPnu],
    /// Changes refused in the present state.
    pub refuse: Option<Refusal>,
    /// Successful writes.
    pub writes: u32,
    /// Value reads that reached the drive (successful or not).
    pub read_calls: u32,
    /// Value writes that reached the drive (successful or not).
    pub write_calls: u32,
}

impl<const N: usize> PartialEq for FakeDrive<N> {
    fn eq(&self, o: &Self) -> bool {
        let values = (self.p1, self.p3, self.p4, self.p6, self.p7, self.p10, self.p100)
            == (o.p1, o.p3, o.p4, o.p6, o.p7, o.p10, o.p100);
        let knobs = (self.standard, &self.table, &self.axes, &self.indirect, self.rule.is_some(), self.word_only)
            == (o.standard, &o.table, &o.axes, &o.indirect, o.rule.is_some(), o.word_only);
        let rest = (self.descriptions, self.quirks, self.refuse, self.writes, self.read_calls, self.write_calls)
            == (o.descriptions, o.quirks, o.refuse, o.writes, o.read_calls, o.write_calls);
        values && knobs && rest
    }
}

const P5: &[u8; 16] = b"pbcard fuzz drv ";
const P1_TEXTS: [&[u8]; 3] = [b"Off", b"On", b"Auto"];
/// The last of the small standard PNUs 1..=10 (the fuzz targets' range; 100, 101 and 200 come on top).
pub const LAST_PNU: u16 = 10;
/// Every standard PNU.
pub const PNUS: [u16; 13] = [1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 100, 101, 200];

impl Default for FakeDrive {
    fn default() -> Self {
        Self::new()
    }
}

impl FakeDrive {
    /// The standard PNUs after power-up: P1 50, P3 all 7, P4 all 0x01020304, P6 all 0xA5,
    /// P7 1.5, P10 −3, P100 1, 2, 3, 4; axes 0 and 1; no table of its own.
    pub fn new() -> Self {
        FakeDrive::standard(Table::new(&[]))
    }

    /// No parameter at all (every PNU 0x00) on every axis: a card without a drive behind it.
    pub fn empty() -> Self {
        FakeDrive { standard: false, axes: 0..=u8::MAX, ..FakeDrive::new() }
    }
}

impl<const N: usize> FakeDrive<N> {
    /// The standard PNUs (see [`FakeDrive::new`]) and `table` beside them.
    pub fn standard(table: Table<N>) -> Self {
        FakeDrive {
            p1: 50,
            p3: [7; 10],
            p4: [0x0102_0304; 4],
            p6: [0xA5; 200],
            p7: 1.5,
            p10: -3,
            p100: [1, 2, 3, 4],
            standard: true,
            table,
            axes: 0..=1,
            indirect: None,
            rule: None,
            word_only: false,
            descriptions: true,
            quirks: &[],
            refuse: None,
            writes: 0,
            read_calls: 0,
            write_calls: 0,
        }
    }

    /// A drive with `table` as its only parameters, on axes 0 and 1.
    pub fn with_table(table: Table<N>) -> Self {
        FakeDrive { standard: false, ..FakeDrive::standard(table) }
    }

    /// Only axis `axis` exists.
    pub fn on_axis(mut self, axis: u8) -> Self {
        self.axes = axis..=axis;
        self
    }

    /// Every axis exists.
    pub fn any_axis(mut self) -> Self {
        self.axes = 0..=u8::MAX;
        self
    }

    /// With VACON's indirect drive-parameter PNU.
    pub fn indirect(mut self, indirect: Indirect) -> Self {
        self.indirect = Some(indirect);
        self
    }

    /// With a change rule.
    pub fn rule(mut self, rule: Rule<N>) -> Self {
        self.rule = Some(rule);
        self
    }

    /// Changes accept the untyped format only.
    pub fn word_only(mut self) -> Self {
        self.word_only = true;
        self
    }

    /// Without descriptions.
    pub fn without_descriptions(mut self) -> Self {
        self.descriptions = false;
        self
    }

    /// With quirk PNUs.
    pub fn quirks(mut self, quirks: &'static [QuirkPnu]) -> Self {
        self.quirks = quirks;
        self
    }

    /// Element `subindex` of table parameter `pnu` (see [`Table::get`]).
    pub fn get(&self, pnu: u16, subindex: u16) -> Option<i64> {
        self.table.get(pnu, subindex)
    }

    fn quirk(&self, pnu: u16) -> Option<QuirkPnu> {
        self.quirks.iter().find(|q| q.pnu == pnu).copied()
    }

    fn is_standard(&self, pnu: u16) -> bool {
        self.standard && PNUS.contains(&pnu)
    }

    /// The table definition `pnu` addresses directly, if any.
    fn direct(&self, pnu: u16) -> Option<&'static ParamDef> {
        if self.indirect.as_ref().is_some_and(|i| i.ids_only && i.ids.contains(&pnu)) {
            return None;
        }
        self.table.def(pnu)
    }

    /// The drive parameter (table PNU) element `k` of an indirect request addresses, or the
    /// indirect PNU's not-found error.
    fn drive_parameter(&self, a: &ParamAddress, k: u8) -> Result<ParamAddress, ParamError> {
        let not_found = self.indirect.as_ref().map_or(ErrorValue::IMPERMISSIBLE_PARAMETER_NUMBER, |i| i.not_found);
        let id = a.subindex.checked_add(u16::from(k)).ok_or(ErrorValue::INVALID_SUBINDEX)?;
        if !self.indirect.as_ref().is_some_and(|i| i.ids.contains(&id)) {
            return Err(not_found.into());
        }
        self.table.def(id).ok_or(not_found)?;
        Ok(ParamAddress { attribute: a.attribute, elements: 1, pnu: id, subindex: 0 })
    }

    fn is_indirect(&self, pnu: u16) -> bool {
        self.indirect.as_ref().is_some_and(|i| i.pnu == pnu)
    }

    /// Change of table parameter `a`: the untyped-only format, the table's own checks, then
    /// the rule against the table before the change (module documentation).
    fn write_table(&mut self, axis: u8, a: &ParamAddress, v: &ValueBlock<'_>) -> Result<(), ParamError> {
        let def = self.table.def(a.pnu).ok_or(ErrorValue::IMPERMISSIBLE_PARAMETER_NUMBER)?;
        if !def.read_only && self.word_only && v.format != def.ty.untyped_format() {
            return Err(ErrorValue::INCORRECT_DATA_TYPE.into());
        }
        let Some(rule) = self.rule else { return self.table.write_value(axis, a, v) };
        let mut next = self.table.clone();
        if let Err(e) = next.write_value(axis, a, v) {
            // The table's own answer; the elements before the failing one are written.
            self.table = next;
            return Err(e);
        }
        for k in 0..a.count() {
            let sub = a.subindex.wrapping_add(u16::from(k));
            if let Some(x) = next.get(a.pnu, sub) {
                rule(&self.table, a.pnu, x).map_err(|e| at(a, usize::from(k), e, def.is_array()))?;
            }
        }
        self.table = next;
        Ok(())
    }
}

/// Element `k` of a write failed with `value`: for an array, name its subindex in the additional info.
fn at(a: &ParamAddress, k: usize, value: ErrorValue, array: bool) -> ParamError {
    ParamError { value, additional_info: array.then(|| a.subindex.wrapping_add(k as u16)) }
}

fn not_found() -> ParamError {
    ErrorValue::IMPERMISSIBLE_PARAMETER_NUMBER.into()
}

impl<const N: usize> ParameterAccess for FakeDrive<N> {
    fn has_axis(&self, axis: u8) -> bool {
        self.axes.contains(&axis)
    }

    fn read_value(&mut self, axis: u8, a: &ParamAddress, out: &mut ValueWriter<'_>) -> Result<(), ParamError> {
        self.read_calls += 1;
        if let Some(q) = self.quirk(a.pnu) {
            return read_quirk(q.read, a, out);
        }
        if self.is_standard(a.pnu) {
            return self.read_standard(a, out);
        }
        if self.is_indirect(a.pnu) {
            return (0..a.count()).try_for_each(|k| {
                let id = self.drive_parameter(a, k)?;
                self.table.read_value(axis, &id, out)
            });
        }
        match self.direct(a.pnu) {
            Some(_) => self.table.read_value(axis, a, out),
            None => Err(not_found()),
        }
    }

    fn write_value(&mut self, axis: u8, a: &ParamAddress, v: &ValueBlock<'_>) -> Result<(), ParamError> {
        self.write_calls += 1;
        if let Some(r) = self.refuse {
            if r.pnu.is_none_or(|p| p == a.pnu) {
                return Err(r.error.into());
            }
        }
        let result = if let Some(q) = self.quirk(a.pnu) {
            q.write
        } else if self.is_standard(a.pnu) {
            self.write_standard(a, v)
        } else if self.is_indirect(a.pnu) {
            // Element by element; the first failure ends the request (VACON §6.4.4.11 note).
            // An untyped-only drive refuses a typed format before looking at the IDs.
            if self.word_only && v.format != Format::WORD && v.format != Format::DOUBLE_WORD {
                return Err(ErrorValue::INCORRECT_DATA_TYPE.into());
            }
            let size = v.format.value_size().unwrap_or(2);
            (0..v.count).try_for_each(|k| {
                let id = self.drive_parameter(a, k)?;
                let bytes = v.value(k as usize).unwrap_or(&[]);
                let one = ValueBlock { format: v.format, count: 1, bytes: &bytes[..bytes.len().min(size)] };
                self.write_table(axis, &id, &one)
            })
        } else if self.direct(a.pnu).is_some() {
            self.write_table(axis, a, v)
        } else {
            Err(not_found())
        };
        if result.is_ok() {
            self.writes += 1;
        }
        result
    }

    fn read_description(&mut self, axis: u8, a: &ParamAddress, out: &mut ValueWriter<'_>) -> Result<(), ParamError> {
        if self.quirk(a.pnu).is_some() || !self.descriptions {
            return Err(ErrorValue::NO_DESCRIPTION.into());
        }
        if self.is_standard(a.pnu) {
            return self.describe_standard(a, out);
        }
        if self.is_indirect(a.pnu) {
            let id = self.drive_parameter(a, 0)?;
            return self.table.read_description(axis, &ParamAddress { subindex: 0, ..id }, out);
        }
        match self.direct(a.pnu) {
            Some(_) => self.table.read_description(axis, a, out),
            None => Err(not_found()),
        }
    }

    fn read_text(&mut self, _axis: u8, a: &ParamAddress, out: &mut ValueWriter<'_>) -> Result<(), ParamError> {
        if self.quirk(a.pnu).is_none() && self.is_standard(a.pnu) && a.pnu == 1 {
            let t = P1_TEXTS.get(a.subindex as usize).ok_or(ErrorValue::INVALID_SUBINDEX)?;
            return out.push_str(t);
        }
        // No other PNU has a text array (the table's: 0x0F too).
        Err(ErrorValue::NO_TEXT_ARRAY.into())
    }
}

fn read_quirk(q: Quirk, a: &ParamAddress, out: &mut ValueWriter<'_>) -> Result<(), ParamError> {
    match q {
        Quirk::Str(s) => out.push_str(s),
        Quirk::Ramp => (0..a.count()).try_for_each(|k| out.push_u16(u16::from(k))),
        Quirk::IgnoresFull => {
            for k in 0..a.count() {
                let _ = out.push_u32(u32::from(k));
            }
            Ok(())
        }
        Quirk::Mixed => {
            out.push_u16(1)?;
            out.push_u8(2)
        }
        Quirk::Fails(e) => Err(e),
    }
}

// ---------------------------------------------------------------------------------------------
// The standard PNUs.
// ---------------------------------------------------------------------------------------------

/// The elements `addr` addresses in an array of `len`.
fn range(len: usize, a: &ParamAddress) -> Result<Range<usize>, ParamError> {
    let first = a.subindex as usize;
    let end = first + a.count() as usize;
    if end > len {
        return Err(ParamError { value: ErrorValue::INVALID_SUBINDEX, additional_info: Some(a.subindex) });
    }
    Ok(first..end)
}

fn scalar(a: &ParamAddress) -> Result<(), ParamError> {
    if a.subindex != 0 || a.count() != 1 {
        return Err(ErrorValue::NO_ARRAY.into());
    }
    Ok(())
}

fn format_in(v: &ValueBlock<'_>, ok: &[Format]) -> Result<(), ParamError> {
    if ok.contains(&v.format) {
        Ok(())
    } else {
        Err(ErrorValue::INCORRECT_DATA_TYPE.into())
    }
}

fn bad_type() -> ParamError {
    ErrorValue::INCORRECT_DATA_TYPE.into()
}

impl<const N: usize> FakeDrive<N> {
    fn read_standard(&mut self, a: &ParamAddress, out: &mut ValueWriter<'_>) -> Result<(), ParamError> {
        match a.pnu {
            1 => {
                scalar(a)?;
                out.push_u16(self.p1)
            }
            2 => {
                scalar(a)?;
                out.set_format(Format::UNSIGNED16);
                out.push_u16(0x1234)
            }
            3 => {
                out.set_format(Format::UNSIGNED16);
                self.p3[range(10, a)?].iter().try_for_each(|&v| out.push_u16(v))
            }
            4 => self.p4[range(4, a)?].iter().try_for_each(|&v| out.push_u32(v)),
            5 => out.push_str(&P5[range(16, a)?]),
            6 => self.p6[range(200, a)?].iter().try_for_each(|&v| out.push_u8(v)),
            7 => {
                scalar(a)?;
                out.push_f32(self.p7)
            }
            8 => {
                // Deliberately inconsistent: two value sizes under one format.
                out.push_u8(1)?;
                out.push_u16(2)
            }
            9 => range(234, a)?.try_for_each(|i| out.push_u16(i as u16)),
            10 => {
                scalar(a)?;
                out.push_i16(self.p10)
            }
            100 => self.p100[range(4, a)?].iter().try_for_each(|&v| out.push_u16(v)),
            101 => out.push_u16(1234),
            200 => out.push_u16(0xBEEF),
            _ => Err(not_found()),
        }
    }

    fn write_standard(&mut self, a: &ParamAddress, v: &ValueBlock<'_>) -> Result<(), ParamError> {
        match a.pnu {
            1 => {
                scalar(a)?;
                format_in(v, &[Format::WORD, Format::UNSIGNED16])?;
                let x = v.u16(0).ok_or_else(bad_type)?;
                if x > 1000 {
                    return Err(ErrorValue::LIMIT_EXCEEDED.into());
                }
                self.p1 = x;
            }
            2 | 5 | 9 | 101 | 200 => return Err(ErrorValue::VALUE_CANNOT_BE_CHANGED.into()),
            100 => {
                for (i, e) in range(4, a)?.enumerate() {
                    let x = v.u16(i).ok_or_else(|| at(a, i, ErrorValue::INCORRECT_DATA_TYPE, true))?;
                    if x > 1000 {
                        return Err(at(a, i, ErrorValue::LIMIT_EXCEEDED, true));
                    }
                    self.p100[e] = x;
                }
            }
            3 => {
                format_in(v, &[Format::WORD, Format::UNSIGNED16])?;
                for (i, e) in range(10, a)?.enumerate() {
                    let x = v.u16(i).ok_or_else(|| at(a, i, ErrorValue::INCORRECT_DATA_TYPE, true))?;
                    if x > 50_000 {
                        return Err(at(a, i, ErrorValue::LIMIT_EXCEEDED, true));
                    }
                    self.p3[e] = x;
                }
            }
            4 => {
                format_in(v, &[Format::DOUBLE_WORD, Format::UNSIGNED32, Format::INTEGER32])?;
                for (i, e) in range(4, a)?.enumerate() {
                    self.p4[e] = v.u32(i).ok_or_else(|| at(a, i, ErrorValue::INCORRECT_DATA_TYPE, true))?;
                }
            }
            6 => {
                format_in(v, &[Format::BYTE, Format::UNSIGNED8, Format::OCTET_STRING])?;
                for (i, e) in range(200, a)?.enumerate() {
                    self.p6[e] = v.u8(i).ok_or_else(|| at(a, i, ErrorValue::INCORRECT_DATA_TYPE, true))?;
                }
            }
            7 => {
                scalar(a)?;
                format_in(v, &[Format::FLOATING_POINT])?;
                let x = v.f32(0).ok_or_else(bad_type)?;
                if !x.is_finite() || !(-1000.0..=1000.0).contains(&x) {
                    return Err(ErrorValue::VALUE_IMPERMISSIBLE.into());
                }
                self.p7 = x;
            }
            8 => return Err(ErrorValue::NO_OPERATION_PRIORITY.into()),
            10 => {
                scalar(a)?;
                format_in(v, &[Format::INTEGER16])?;
                let x = v.i16(0).ok_or_else(bad_type)?;
                if !(-500..=500).contains(&x) {
                    return Err(ErrorValue::LIMIT_EXCEEDED.into());
                }
                self.p10 = x;
            }
            _ => return Err(not_found()),
        }
        Ok(())
    }

    fn describe_standard(&mut self, a: &ParamAddress, out: &mut ValueWriter<'_>) -> Result<(), ParamError> {
        match (a.pnu, a.subindex) {
            (200, 1) => return out.push_u16(0x0006),
            (100 | 101 | 200, _) => return Err(ErrorValue::NO_DESCRIPTION.into()),
            _ => {}
        }
        if a.pnu == 0 || a.pnu > LAST_PNU {
            return Err(not_found());
        }
        if a.pnu == 8 {
            return Err(ErrorValue::NO_DESCRIPTION.into());
        }
        if a.count() != 1 {
            return Err(ErrorValue::INVALID_SUBINDEX.into());
        }
        match a.subindex {
            0 => {
                out.set_format(Format::OCTET_STRING);
                (0..46u8).try_for_each(|i| out.push_u8(i ^ a.pnu as u8))
            }
            1 => {
                out.set_format(Format::UNSIGNED16);
                out.push_u16(0x0006 | if matches!(a.pnu, 2 | 5 | 9) { 0x0200 } else { 0 })
            }
            6 => {
                out.set_format(Format::VISIBLE_STRING);
                out.push_str(P5)
            }
            _ => Err(ErrorValue::INVALID_SUBINDEX.into()),
        }
    }
}
