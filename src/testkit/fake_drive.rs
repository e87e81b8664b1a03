//! The one fake drive parameter table of the tests (issue 13 item 5): the fuzz targets
//! `profidrive` and `node_dpv1`, the DP-V1 record tests (`host-tests/tests/dpv1.rs`), the DPM
//! mailbox tests (`src/dpm_tests/v2_card.rs`, `dpm-host/tests/mailbox.rs`), the fast path's
//! differential check (`fast::check`) and the lean DP-V1 tests (`link_tests::fast_lean`) read
//! and write it through
//! [`ParameterAccess`]. Every PNU exercises one rule of the PROFIdrive parameter access
//! (reference §5.2: formats, arrays, limits, read-only, descriptions, texts):
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

use crate::profile::param::{ErrorValue, Format, ParamAddress, ParamError, ParameterAccess, ValueBlock, ValueWriter};

/// The fake drive's parameter values (see the module documentation for the PNUs).
#[derive(Debug, Clone, PartialEq)]
pub struct FakeDrive {
    /// PNU 1.
    pub p1: u16,
    /// PNU 3.
    pub p3: [u16; 10],
    /// PNU 4.
    pub p4: [u32; 4],
    /// PNU 6.
    pub p6: [u8; 200],
    /// PNU 7.
    pub p7: f32,
    /// PNU 10.
    pub p10: i16,
    /// PNU 100.
    pub p100: [u16; 4],
    /// Successful writes.
    pub writes: u32,
}

const P5: &[u8; 16] = b"pbcard fuzz drv ";
const P1_TEXTS: [&[u8]; 3] = [b"Off", b"On", b"Auto"];
/// The last of the small PNUs 1..=10 (the fuzz targets' range; 100, 101 and 200 come on top).
pub const LAST_PNU: u16 = 10;
/// Every PNU the table has.
pub const PNUS: [u16; 13] = [1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 100, 101, 200];

impl Default for FakeDrive {
    fn default() -> Self {
        Self::new()
    }
}

impl FakeDrive {
    /// The values after power-up: P1 50, P3 all 7, P4 all 0x01020304, P6 all 0xA5, P7 1.5,
    /// P10 −3, P100 1, 2, 3, 4.
    pub fn new() -> Self {
        FakeDrive {
            p1: 50,
            p3: [7; 10],
            p4: [0x0102_0304; 4],
            p6: [0xA5; 200],
            p7: 1.5,
            p10: -3,
            p100: [1, 2, 3, 4],
            writes: 0,
        }
    }
}

fn not_found() -> ParamError {
    ErrorValue::IMPERMISSIBLE_PARAMETER_NUMBER.into()
}

/// The elements `addr` addresses in an array of `len`.
fn range(len: usize, a: &ParamAddress) -> Result<core::ops::Range<usize>, ParamError> {
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

/// Element `i` of a write failed with `value`: name the subindex.
fn at(a: &ParamAddress, i: usize, value: ErrorValue) -> ParamError {
    ParamError { value, additional_info: Some(a.subindex.wrapping_add(i as u16)) }
}

impl ParameterAccess for FakeDrive {
    fn has_axis(&self, axis: u8) -> bool {
        axis <= 1
    }

    fn read_value(&mut self, _axis: u8, a: &ParamAddress, out: &mut ValueWriter<'_>) -> Result<(), ParamError> {
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

    fn write_value(&mut self, _axis: u8, a: &ParamAddress, v: &ValueBlock<'_>) -> Result<(), ParamError> {
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
                    let x = v.u16(i).ok_or_else(|| at(a, i, ErrorValue::INCORRECT_DATA_TYPE))?;
                    if x > 1000 {
                        return Err(at(a, i, ErrorValue::LIMIT_EXCEEDED));
                    }
                    self.p100[e] = x;
                }
            }
            3 => {
                format_in(v, &[Format::WORD, Format::UNSIGNED16])?;
                for (i, e) in range(10, a)?.enumerate() {
                    let x = v.u16(i).ok_or_else(|| at(a, i, ErrorValue::INCORRECT_DATA_TYPE))?;
                    if x > 50_000 {
                        return Err(at(a, i, ErrorValue::LIMIT_EXCEEDED));
                    }
                    self.p3[e] = x;
                }
            }
            4 => {
                format_in(v, &[Format::DOUBLE_WORD, Format::UNSIGNED32, Format::INTEGER32])?;
                for (i, e) in range(4, a)?.enumerate() {
                    self.p4[e] = v.u32(i).ok_or_else(|| at(a, i, ErrorValue::INCORRECT_DATA_TYPE))?;
                }
            }
            6 => {
                format_in(v, &[Format::BYTE, Format::UNSIGNED8, Format::OCTET_STRING])?;
                for (i, e) in range(200, a)?.enumerate() {
                    self.p6[e] = v.u8(i).ok_or_else(|| at(a, i, ErrorValue::INCORRECT_DATA_TYPE))?;
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
        self.writes += 1;
        Ok(())
    }

    fn read_description(&mut self, _axis: u8, a: &ParamAddress, out: &mut ValueWriter<'_>) -> Result<(), ParamError> {
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

    fn read_text(&mut self, _axis: u8, a: &ParamAddress, out: &mut ValueWriter<'_>) -> Result<(), ParamError> {
        if a.pnu != 1 {
            return Err(ErrorValue::NO_TEXT_ARRAY.into());
        }
        let t = P1_TEXTS.get(a.subindex as usize).ok_or(ErrorValue::INVALID_SUBINDEX)?;
        out.push_str(t)
    }
}
