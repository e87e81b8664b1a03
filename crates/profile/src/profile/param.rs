//! PROFIdrive base-mode parameter access over DP-V1 data record 47 (reference §5.1; VACON OPTE3/E5
//! manual §6.4.2–6.4.3; WEG CFW-11 §4.2.4 Tabela 4.1/4.2; WEG CFW500 §5.2.4 Table 5.1/5.2).
//!
//! The master writes a *parameter request* with DS_Write to index 47 and reads the *parameter
//! response* with DS_Read. Both are at most 240 bytes, all numbers big-endian.
//!
//! Request:
//!
//! | bytes | field |
//! |---|---|
//! | 1 | Request_Reference 1..255 (mirrored) |
//! | 1 | Request_ID: 0x01 request (read) parameter, 0x02 change parameter |
//! | 1 | DO-ID / axis (VACON uses 1, WEG 0) |
//! | 1 | No_of_Parameters 1..39 |
//! | 6 × n | Attribute (0x10 value, 0x20 description, 0x30 text), No_of_Elements, PNU (U16), Subindex (U16) |
//! | change only, n × | Format, No_of_Values, values (padded to an even byte count) |
//!
//! Response: Request_Reference, Response_ID (0x01 / 0x02; 0x81 / 0x82 when any parameter
//! failed), axis, No_of_Parameters, then one sub-response per parameter: `Format, No_of_Values,
//! values` or `0x44, 1, error value (U16)` [`, additional info (U16)`]. A fully successful change
//! response is the 4-byte header alone; in a negative one the successful parameters show
//! `0x40 (Zero), 0` (VACON §6.4.4.8 Table 78 and §6.4.4.11 Table 99–100; CFW-11 §4.2.5 Exemplo 2).
//!
//! [`ParamRequest::parse`] validates a request's *structure*; what a failure there means for the
//! DS_Write is in [`RequestError`]. [`respond`] runs a valid request against anything that
//! implements [`ParameterAccess`] (the drive's parameter table) and writes the response.
//! [`emit_request`] and [`ParamResponse::parse`] are the master's side, for tests and simulators.

use crate::dpv1::pdu::{EmitError, ErrorCode1};

/// The DP-V1 data record (index) of PROFIdrive parameter access.
pub const RECORD_INDEX: u8 = 47;
/// Largest parameter request or response (the DP-V1 data limit).
pub const MAX_LEN: usize = 240;
/// Most parameters in one request (VACON Table 40: "Values 1 to 39 are allowed").
pub const MAX_PARAMETERS: u8 = 39;
/// Most array elements / values addressed by one parameter (VACON Tables 41–42: 1..234).
pub const MAX_ELEMENTS: u8 = 234;
/// Request / response header: reference, ID, axis, number of parameters.
pub const HEADER_LEN: usize = 4;
/// One parameter address: attribute, elements, PNU, subindex.
pub const ADDRESS_LEN: usize = 6;

/// Request_ID (VACON Table 40; CFW-11/CFW500 "Request ID": 1 = read, 2 = change).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[repr(u8)]
pub enum RequestId {
    /// 0x01 "Request parameter": read values, descriptions or texts.
    Read = 0x01,
    /// 0x02 "Change parameter": write values.
    Change = 0x02,
}

/// Response_ID (VACON Table 48; CFW-11 Tabela 4.2: 1, 2, 129, 130).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct ResponseId(pub u8);

impl ResponseId {
    /// 0x01: request parameter, all successful.
    pub const READ_OK: Self = Self(0x01);
    /// 0x02: change parameter, all successful.
    pub const CHANGE_OK: Self = Self(0x02);
    /// 0x80: the request ID was invalid (VACON Table 48).
    pub const INVALID_REQUEST_ID: Self = Self(0x80);
    /// 0x81: request parameter, at least one parameter failed.
    pub const READ_ERROR: Self = Self(0x81);
    /// 0x82: change parameter, at least one parameter failed.
    pub const CHANGE_ERROR: Self = Self(0x82);

    /// Whether bit 7 (negative) is set.
    pub const fn is_error(self) -> bool {
        self.0 & 0x80 != 0
    }
}

/// Attribute of a parameter address (VACON Table 41).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum Attribute {
    /// 0x10: the value.
    Value,
    /// 0x20: the description (subindex = description element, 0 = all 46 bytes; VACON §6.4.3.7).
    Description,
    /// 0x30: the text array.
    Text,
    /// Any other byte (answered per parameter with 0x16 impermissible parameter address).
    Other(u8),
}

impl Attribute {
    /// Decode the attribute byte.
    pub const fn from_u8(b: u8) -> Attribute {
        match b {
            0x10 => Attribute::Value,
            0x20 => Attribute::Description,
            0x30 => Attribute::Text,
            other => Attribute::Other(other),
        }
    }
    /// Encode the attribute byte.
    pub const fn to_u8(self) -> u8 {
        match self {
            Attribute::Value => 0x10,
            Attribute::Description => 0x20,
            Attribute::Text => 0x30,
            Attribute::Other(b) => b,
        }
    }
}

/// Format (data type) of a value block (reference §5.1 format table; VACON Table 42;
/// CFW-11/CFW500: 0x42 for every drive parameter, 0x44 error).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct Format(pub u8);

impl Format {
    /// 0x01 Boolean (one byte per value).
    pub const BOOLEAN: Self = Self(0x01);
    /// 0x02 Integer8.
    pub const INTEGER8: Self = Self(0x02);
    /// 0x03 Integer16.
    pub const INTEGER16: Self = Self(0x03);
    /// 0x04 Integer32.
    pub const INTEGER32: Self = Self(0x04);
    /// 0x05 Unsigned8.
    pub const UNSIGNED8: Self = Self(0x05);
    /// 0x06 Unsigned16.
    pub const UNSIGNED16: Self = Self(0x06);
    /// 0x07 Unsigned32.
    pub const UNSIGNED32: Self = Self(0x07);
    /// 0x08 FloatingPoint (IEEE 754 single).
    pub const FLOATING_POINT: Self = Self(0x08);
    /// 0x09 VisibleString (one character per value).
    pub const VISIBLE_STRING: Self = Self(0x09);
    /// 0x0A OctetString (one byte per value).
    pub const OCTET_STRING: Self = Self(0x0A);
    /// 0x40 Zero: no values (a successful change in a negative change response).
    pub const ZERO: Self = Self(0x40);
    /// 0x41 Byte.
    pub const BYTE: Self = Self(0x41);
    /// 0x42 Word.
    pub const WORD: Self = Self(0x42);
    /// 0x43 Double word.
    pub const DOUBLE_WORD: Self = Self(0x43);
    /// 0x44 Error: the value is an error value (U16), optionally followed by additional info.
    pub const ERROR: Self = Self(0x44);

    /// Bytes per value, for the formats this codec can carry in a change request or response
    /// (0x01..0x0A, 0x40..0x44). The time types 0x0B..0x36 and the reserved codes give `None`:
    /// a change request using them cannot be delimited and is refused as 0x17 illegal format.
    pub const fn value_size(self) -> Option<usize> {
        match self.0 {
            0x01 | 0x02 | 0x05 | 0x09 | 0x0A | 0x41 => Some(1),
            0x03 | 0x06 | 0x42 | 0x44 => Some(2),
            0x04 | 0x07 | 0x08 | 0x43 => Some(4),
            0x40 => Some(0),
            _ => None,
        }
    }
}

/// A PROFIdrive error value (the U16 after format 0x44). Constants: VACON OPTE3/E5 manual
/// §6.4.3.4 Table 47, which lists the PROFIdrive 4.1 values 0x00..0x21 and VACON's own
/// 0x65..0x6D. WEG (CFW-11 §4.2.4, CFW500 §5.2.4) uses 0x00–0x05, 0x09, 0x0F, 0x16–0x18 with the
/// same meanings. Values 0x65..0xFF are manufacturer specific (reference §5.1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct ErrorValue(pub u16);

impl ErrorValue {
    /// 0x00 impermissible parameter number: access to an unavailable parameter.
    pub const IMPERMISSIBLE_PARAMETER_NUMBER: Self = Self(0x00);
    /// 0x01 parameter value cannot be changed: change request to a read-only parameter.
    pub const VALUE_CANNOT_BE_CHANGED: Self = Self(0x01);
    /// 0x02 low or high limit exceeded.
    pub const LIMIT_EXCEEDED: Self = Self(0x02);
    /// 0x03 invalid subindex: access to an unavailable subindex of an array parameter.
    pub const INVALID_SUBINDEX: Self = Self(0x03);
    /// 0x04 non-array parameter: subindex access to a parameter that is no array.
    pub const NO_ARRAY: Self = Self(0x04);
    /// 0x05 incorrect data type: the change request's format does not fit the parameter.
    pub const INCORRECT_DATA_TYPE: Self = Self(0x05);
    /// 0x06 setting not permitted (may only be reset to 0).
    pub const SETTING_NOT_PERMITTED: Self = Self(0x06);
    /// 0x07 description element cannot be changed.
    pub const DESCRIPTION_CANNOT_BE_CHANGED: Self = Self(0x07);
    /// 0x09 no description data available.
    pub const NO_DESCRIPTION: Self = Self(0x09);
    /// 0x0B no operation priority: change without the right to change.
    pub const NO_OPERATION_PRIORITY: Self = Self(0x0B);
    /// 0x0F no text array available.
    pub const NO_TEXT_ARRAY: Self = Self(0x0F);
    /// 0x11 request cannot be executed (operating state; temporarily not possible).
    pub const NOT_EXECUTABLE: Self = Self(0x11);
    /// 0x14 value impermissible: within the limits but otherwise not allowed.
    pub const VALUE_IMPERMISSIBLE: Self = Self(0x14);
    /// 0x15 response too long: exceeds the 240 bytes that can be transmitted.
    pub const RESPONSE_TOO_LONG: Self = Self(0x15);
    /// 0x16 impermissible parameter address: attribute, number of elements, PNU or subindex.
    pub const IMPERMISSIBLE_ADDRESS: Self = Self(0x16);
    /// 0x17 illegal format (change request).
    pub const ILLEGAL_FORMAT: Self = Self(0x17);
    /// 0x18 number of values inconsistent (change request).
    pub const NUMBER_OF_VALUES_INCONSISTENT: Self = Self(0x18);
    /// 0x19 axis / drive object non-existent.
    pub const AXIS_NONEXISTENT: Self = Self(0x19);
    /// 0x20 parameter text element cannot be changed.
    pub const TEXT_CANNOT_BE_CHANGED: Self = Self(0x20);
    /// 0x21 invalid request ID (neither 0x01 nor 0x02).
    pub const INVALID_REQUEST_ID: Self = Self(0x21);
    /// 0x65 (VACON) invalid request reference (0).
    pub const VACON_INVALID_REQUEST_REFERENCE: Self = Self(0x65);
    /// 0x66 (VACON) invalid request ID — the same condition as 0x21 in the same table.
    pub const VACON_INVALID_REQUEST_ID: Self = Self(0x66);
    /// 0x68 (VACON) invalid number of parameters (0 or more than 39).
    pub const VACON_INVALID_PARAMETER_COUNT: Self = Self(0x68);
    /// 0x69 (VACON) invalid attribute.
    pub const VACON_INVALID_ATTRIBUTE: Self = Self(0x69);
    /// 0x6B (VACON) request too short: incomplete parameter address or value data.
    pub const VACON_REQUEST_TOO_SHORT: Self = Self(0x6B);
    /// 0x6C (VACON) drive parameter not found (through PNU 10001).
    pub const VACON_DRIVE_PARAMETER_NOT_FOUND: Self = Self(0x6C);
    /// 0x6D (VACON) invalid change request: length and contents could not be verified.
    pub const VACON_INVALID_CHANGE_REQUEST: Self = Self(0x6D);

    /// Whether the value is in the manufacturer-specific range 0x65..0xFF (or above).
    pub const fn is_manufacturer_specific(self) -> bool {
        self.0 >= 0x65
    }
}

/// Why one parameter of a request failed: the error value and, optionally, additional
/// information (SINAMICS-style: e.g. the failing subindex), sent as a second value.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct ParamError {
    /// The error value.
    pub value: ErrorValue,
    /// Additional information, sent as a second U16 when present.
    pub additional_info: Option<u16>,
}

impl From<ErrorValue> for ParamError {
    fn from(value: ErrorValue) -> Self {
        ParamError { value, additional_info: None }
    }
}

/// One parameter address.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct ParamAddress {
    /// What is accessed.
    pub attribute: Attribute,
    /// No_of_Elements: 0 or 1 for a non-array parameter, 1..234 array elements (VACON Table 41;
    /// CFW-11/CFW500: "must be set in 0 or 1" for single-valued parameters). 0 does **not** mean
    /// "the whole array".
    pub elements: u8,
    /// Parameter number.
    pub pnu: u16,
    /// First array element / description element / text index.
    pub subindex: u16,
}

impl ParamAddress {
    /// Number of values addressed: `elements`, with 0 counting as 1.
    pub const fn count(&self) -> u8 {
        if self.elements == 0 {
            1
        } else {
            self.elements
        }
    }
    fn parse(b: &[u8]) -> ParamAddress {
        ParamAddress {
            attribute: Attribute::from_u8(b[0]),
            elements: b[1],
            pnu: u16::from_be_bytes([b[2], b[3]]),
            subindex: u16::from_be_bytes([b[4], b[5]]),
        }
    }
    fn emit(&self, out: &mut [u8]) {
        let [p0, p1] = self.pnu.to_be_bytes();
        let [s0, s1] = self.subindex.to_be_bytes();
        out[..ADDRESS_LEN].copy_from_slice(&[self.attribute.to_u8(), self.elements, p0, p1, s0, s1]);
    }
}

/// A value block of a change request or a sub-response: format, number of values, the values
/// (big-endian; without the pad byte that follows an odd byte count).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct ValueBlock<'a> {
    /// Format of the values.
    pub format: Format,
    /// No_of_Values.
    pub count: u8,
    /// `count × format size` bytes.
    pub bytes: &'a [u8],
}

impl<'a> ValueBlock<'a> {
    /// The bytes of value `i`.
    pub fn value(&self, i: usize) -> Option<&'a [u8]> {
        let size = self.format.value_size()?;
        if i >= self.count as usize {
            return None;
        }
        self.bytes.get(i * size..(i + 1) * size)
    }
    /// Value `i` as a byte (1-byte formats).
    pub fn u8(&self, i: usize) -> Option<u8> {
        match self.value(i)? {
            &[b] => Some(b),
            _ => None,
        }
    }
    /// Value `i` as U16 (2-byte formats: Word, Integer16, Unsigned16).
    pub fn u16(&self, i: usize) -> Option<u16> {
        match self.value(i)? {
            &[a, b] => Some(u16::from_be_bytes([a, b])),
            _ => None,
        }
    }
    /// Value `i` as I16.
    pub fn i16(&self, i: usize) -> Option<i16> {
        self.u16(i).map(|v| v as i16)
    }
    /// Value `i` as U32 (4-byte formats).
    pub fn u32(&self, i: usize) -> Option<u32> {
        match self.value(i)? {
            &[a, b, c, d] => Some(u32::from_be_bytes([a, b, c, d])),
            _ => None,
        }
    }
    /// Value `i` as an IEEE 754 single (FloatingPoint).
    pub fn f32(&self, i: usize) -> Option<f32> {
        self.u32(i).map(f32::from_bits)
    }
    /// For an error block (format 0x44): the error value and the additional info, if any.
    pub fn error(&self) -> Option<ParamError> {
        if self.format != Format::ERROR {
            return None;
        }
        Some(ParamError { value: ErrorValue(self.u16(0)?), additional_info: self.u16(1) })
    }
}

/// One parameter of a request: its address and, in a change request, its values.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct Parameter<'a> {
    /// The address.
    pub address: ParamAddress,
    /// The values (change requests only).
    pub value: Option<ValueBlock<'a>>,
}

/// A structurally valid parameter request (zero-copy view).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct ParamRequest<'a> {
    /// Request_Reference (1..255), mirrored in the response.
    pub reference: u8,
    /// Request_ID.
    pub id: RequestId,
    /// DO-ID / axis, mirrored.
    pub axis: u8,
    count: u8,
    addresses: &'a [u8],
    values: &'a [u8],
}

/// What is structurally wrong with a parameter request.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[non_exhaustive]
pub enum RequestErrorKind {
    /// Fewer than the 4 header bytes.
    TooShort,
    /// More than 240 bytes.
    TooLong,
    /// Request_Reference 0 (VACON Table 40: only 1..255).
    InvalidReference,
    /// Request_ID neither 0x01 nor 0x02.
    InvalidRequestId,
    /// No_of_Parameters 0 or above 39.
    InvalidParameterCount,
    /// A parameter address or value block is cut off.
    Truncated,
    /// A change request's value block has a format whose size is unknown (reserved, time types).
    IllegalFormat(u8),
    /// Bytes after the last parameter address (read) or value block (change).
    TrailingBytes,
}

/// A parameter request that is not structurally valid, with the header bytes it had (0 where
/// missing).
///
/// The manuals reject such requests at the DS_Write: CFW500 §5.2.4 step 2 / CFW-11 §4.2.4 ("if
/// errors in the request format are not found, it will respond positively") and VACON Table 46
/// (0xB7: "Write request with error in the parameter request header"). So the intended use is
/// `DF 80 B7 00` ([`RequestError::error_code1`]); [`RequestError::error_value`] names the cause
/// in PROFIdrive terms, and [`RequestError::emit_response`] builds a negative parameter response
/// for a router that prefers accepting the write and answering at the read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct RequestError {
    /// What is wrong.
    pub kind: RequestErrorKind,
    /// Request_Reference as received.
    pub reference: u8,
    /// Request_ID as received.
    pub request_id: u8,
    /// Axis as received.
    pub axis: u8,
    /// No_of_Parameters as received.
    pub count: u8,
}

impl RequestError {
    /// The DP-V1 Error_Code_1 for refusing the DS_Write: 0xB7 (VACON Table 46; WEG CFW500
    /// §5.2.3 "B7h: incorrect values for parameter access").
    pub const fn error_code1(&self) -> ErrorCode1 {
        ErrorCode1::INVALID_RANGE
    }

    /// The PROFIdrive error value naming the cause (VACON Table 47). Where PROFIdrive has a
    /// value it is used (0x17 illegal format, 0x21 invalid request ID — VACON lists both 0x21 and
    /// 0x66 for that; we take the profile's 0x21); otherwise VACON's: 0x65 reference,
    /// 0x68 parameter count, 0x6B too short / truncated, 0x6D length not verifiable.
    pub const fn error_value(&self) -> ErrorValue {
        match self.kind {
            RequestErrorKind::TooShort | RequestErrorKind::Truncated => ErrorValue::VACON_REQUEST_TOO_SHORT,
            RequestErrorKind::TooLong | RequestErrorKind::TrailingBytes => ErrorValue::VACON_INVALID_CHANGE_REQUEST,
            RequestErrorKind::InvalidReference => ErrorValue::VACON_INVALID_REQUEST_REFERENCE,
            RequestErrorKind::InvalidRequestId => ErrorValue::INVALID_REQUEST_ID,
            RequestErrorKind::InvalidParameterCount => ErrorValue::VACON_INVALID_PARAMETER_COUNT,
            RequestErrorKind::IllegalFormat(_) => ErrorValue::ILLEGAL_FORMAT,
        }
    }

    /// A negative parameter response for this request: reference and axis mirrored, Response_ID
    /// 0x81 / 0x82 (0x80 for an invalid request ID, VACON Table 48), and each of the request's
    /// parameters (one when the count itself is invalid) answered `44 01` + [`Self::error_value`].
    /// Returns its length (≤ 160).
    pub fn emit_response(&self, out: &mut [u8; MAX_LEN]) -> usize {
        let id = match self.request_id {
            0x01 => ResponseId::READ_ERROR,
            0x02 => ResponseId::CHANGE_ERROR,
            _ => ResponseId::INVALID_REQUEST_ID,
        };
        let n = if (1..=MAX_PARAMETERS).contains(&self.count) { self.count } else { 1 };
        out[..HEADER_LEN].copy_from_slice(&[self.reference, id.0, self.axis, n]);
        let mut pos = HEADER_LEN;
        for _ in 0..n {
            pos += emit_error_block(&mut out[pos..], &self.error_value().into(), false);
        }
        pos
    }
}

impl<'a> ParamRequest<'a> {
    /// Validate the structure of a parameter request (the DS_Write data of record 47).
    ///
    /// Checked here: length ≤ 240, reference ≠ 0, request ID, 1..39 parameters, complete
    /// addresses and (change) value blocks with a known format, nothing left over. Value blocks
    /// with an odd byte count are followed by a pad byte (reference §5.1); after the last block
    /// the pad is optional. Attribute, number of elements and whether the number of values fits
    /// are checked per parameter by [`respond`].
    pub fn parse(data: &'a [u8]) -> Result<Self, RequestError> {
        let at = |i: usize| data.get(i).copied().unwrap_or(0);
        let err = |kind| RequestError { kind, reference: at(0), request_id: at(1), axis: at(2), count: at(3) };
        if data.len() < HEADER_LEN {
            return Err(err(RequestErrorKind::TooShort));
        }
        if data.len() > MAX_LEN {
            return Err(err(RequestErrorKind::TooLong));
        }
        let (reference, axis, count) = (data[0], data[2], data[3]);
        if reference == 0 {
            return Err(err(RequestErrorKind::InvalidReference));
        }
        let id = match data[1] {
            0x01 => RequestId::Read,
            0x02 => RequestId::Change,
            _ => return Err(err(RequestErrorKind::InvalidRequestId)),
        };
        if count == 0 || count > MAX_PARAMETERS {
            return Err(err(RequestErrorKind::InvalidParameterCount));
        }
        let addr_end = HEADER_LEN + ADDRESS_LEN * count as usize;
        if data.len() < addr_end {
            return Err(err(RequestErrorKind::Truncated));
        }
        let (addresses, values) = (&data[HEADER_LEN..addr_end], &data[addr_end..]);
        if id == RequestId::Read {
            if !values.is_empty() {
                return Err(err(RequestErrorKind::TrailingBytes));
            }
        } else {
            let mut pos = 0;
            for _ in 0..count {
                // The pad after an odd block is mandatory between blocks (a missing one shifts the
                // next header and fails); clamping only makes it optional after the last block.
                pos = value_block(values, pos).map_err(err)?.1.min(values.len());
            }
            if pos != values.len() {
                return Err(err(RequestErrorKind::TrailingBytes));
            }
        }
        Ok(ParamRequest { reference, id, axis, count, addresses, values })
    }

    /// No_of_Parameters (1..39).
    pub const fn len(&self) -> usize {
        self.count as usize
    }

    /// Always false: a valid request has at least one parameter.
    pub const fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// The parameters, in request order.
    pub fn parameters(&self) -> Parameters<'a> {
        Parameters { addresses: self.addresses, values: self.values, change: self.id == RequestId::Change, pos: 0 }
    }
}

/// Read the value block at `values[pos..]`; returns it and where the next block starts (after the
/// pad byte of an odd block — possibly one past the end for the last block).
fn value_block(values: &[u8], pos: usize) -> Result<(ValueBlock<'_>, usize), RequestErrorKind> {
    let (&format, &count) = match values.get(pos..pos + 2) {
        Some([f, c]) => (f, c),
        _ => return Err(RequestErrorKind::Truncated),
    };
    let size = Format(format).value_size().ok_or(RequestErrorKind::IllegalFormat(format))?;
    let len = size * count as usize;
    let bytes = values.get(pos + 2..pos + 2 + len).ok_or(RequestErrorKind::Truncated)?;
    let next = pos + 2 + len + (len & 1);
    Ok((ValueBlock { format: Format(format), count, bytes }, next))
}

/// Iterator over the parameters of a [`ParamRequest`].
#[derive(Debug, Clone)]
pub struct Parameters<'a> {
    addresses: &'a [u8],
    values: &'a [u8],
    change: bool,
    pos: usize,
}

impl<'a> Iterator for Parameters<'a> {
    type Item = Parameter<'a>;
    fn next(&mut self) -> Option<Parameter<'a>> {
        let (a, rest) = self.addresses.split_at_checked(ADDRESS_LEN)?;
        self.addresses = rest;
        let value = if self.change {
            // Validated by `ParamRequest::parse`; a failure here cannot happen and ends the walk.
            let (block, next) = value_block(self.values, self.pos).ok()?;
            self.pos = next;
            Some(block)
        } else {
            None
        };
        Some(Parameter { address: ParamAddress::parse(a), value })
    }
}

/// Collects the values of one sub-response of a read, inside the 240-byte response.
///
/// The typed `push_*` methods set the format if none was set yet (u8 → Byte 0x41, u16 → Word
/// 0x42, u32 → Double word 0x43, raw bytes → OctetString 0x0A); [`ValueWriter::set_format`]
/// chooses another (e.g. Unsigned16 0x06, VisibleString 0x09). A push that does not fit, or a
/// 235th value, fails with 0x15 "response too long" — which [`respond`] reports for this
/// parameter even if the table ignores the error.
#[derive(Debug)]
pub struct ValueWriter<'b> {
    buf: &'b mut [u8],
    len: usize,
    count: u8,
    format: Option<Format>,
    overflow: bool,
}

impl<'b> ValueWriter<'b> {
    /// A writer into `buf` (its capacity).
    pub fn new(buf: &'b mut [u8]) -> Self {
        ValueWriter { buf, len: 0, count: 0, format: None, overflow: false }
    }
    /// Set the format of the values.
    pub fn set_format(&mut self, format: Format) {
        self.format = Some(format);
    }
    /// The format (set or implied by the first push).
    pub fn format(&self) -> Option<Format> {
        self.format
    }
    /// Number of values written.
    pub fn count(&self) -> u8 {
        self.count
    }
    /// Bytes written.
    pub fn len(&self) -> usize {
        self.len
    }
    /// Whether nothing was written.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
    /// The values written so far.
    pub fn bytes(&self) -> &[u8] {
        &self.buf[..self.len]
    }
    /// Whether a push was refused for lack of space.
    pub fn overflowed(&self) -> bool {
        self.overflow
    }
    /// Append one value given as its big-endian bytes.
    pub fn push_raw(&mut self, value: &[u8]) -> Result<(), ParamError> {
        self.push(Format::OCTET_STRING, value)
    }
    /// Append a byte (Byte / Unsigned8 / Integer8 / Boolean / one string character).
    pub fn push_u8(&mut self, v: u8) -> Result<(), ParamError> {
        self.push(Format::BYTE, &[v])
    }
    /// Append a 16-bit value (Word / Unsigned16).
    pub fn push_u16(&mut self, v: u16) -> Result<(), ParamError> {
        self.push(Format::WORD, &v.to_be_bytes())
    }
    /// Append a signed 16-bit value (sets Integer16 if no format was set).
    pub fn push_i16(&mut self, v: i16) -> Result<(), ParamError> {
        self.push(Format::INTEGER16, &v.to_be_bytes())
    }
    /// Append a 32-bit value (Double word / Unsigned32).
    pub fn push_u32(&mut self, v: u32) -> Result<(), ParamError> {
        self.push(Format::DOUBLE_WORD, &v.to_be_bytes())
    }
    /// Append a signed 32-bit value (sets Integer32 if no format was set).
    pub fn push_i32(&mut self, v: i32) -> Result<(), ParamError> {
        self.push(Format::INTEGER32, &v.to_be_bytes())
    }
    /// Append an IEEE 754 single (sets FloatingPoint if no format was set).
    pub fn push_f32(&mut self, v: f32) -> Result<(), ParamError> {
        self.push(Format::FLOATING_POINT, &v.to_bits().to_be_bytes())
    }
    /// Append a string, one value per byte (sets VisibleString if no format was set).
    pub fn push_str(&mut self, s: &[u8]) -> Result<(), ParamError> {
        self.format.get_or_insert(Format::VISIBLE_STRING);
        s.iter().try_for_each(|&c| self.push_u8(c))
    }

    #[inline(never)]
    fn push(&mut self, implied: Format, value: &[u8]) -> Result<(), ParamError> {
        let end = self.len + value.len();
        if self.count >= MAX_ELEMENTS || end > self.buf.len() {
            self.overflow = true;
            return Err(ErrorValue::RESPONSE_TOO_LONG.into());
        }
        self.format.get_or_insert(implied);
        self.buf[self.len..end].copy_from_slice(value);
        self.len = end;
        self.count += 1;
        Ok(())
    }
}

/// What the parameter channel needs from the drive's parameter table. The codec checks the
/// request structure, the attribute, the number of elements (≤ 234), the formats Zero/Error in
/// change requests and the number of values; everything about the parameters themselves is
/// the table's.
pub trait ParameterAccess {
    /// Whether the DO-ID / axis of the request exists; if not, every parameter is answered with
    /// 0x19 (VACON: axis 1; WEG: 0).
    fn has_axis(&self, axis: u8) -> bool;

    /// Read `addr.count()` values of `addr.pnu` starting at element `addr.subindex` (attribute
    /// 0x10) into `out`. Typical errors: 0x00 no such PNU, 0x03 subindex out of range, 0x04
    /// subindex ≠ 0 on a non-array parameter, 0x15 from a full `out` (propagate it with `?`).
    fn read_value(&mut self, axis: u8, addr: &ParamAddress, out: &mut ValueWriter<'_>) -> Result<(), ParamError>;

    /// Write `values` (already checked: `values.count == addr.count()`, format not Zero/Error)
    /// to `addr.pnu` from element `addr.subindex` on. Typical errors: 0x00, 0x01 read-only,
    /// 0x02 limits, 0x05 data type, 0x06, 0x0B, 0x11, 0x14. For several elements, stop at the
    /// first failing one (VACON §6.4.4.11 note) and, if useful, name it in `additional_info`.
    fn write_value(&mut self, axis: u8, addr: &ParamAddress, values: &ValueBlock<'_>) -> Result<(), ParamError>;

    /// Read description element `addr.subindex` (0 = the complete 46-byte description; VACON
    /// §6.4.3.7) of `addr.pnu` (attribute 0x20). Default: 0x09 no description data.
    fn read_description(&mut self, axis: u8, addr: &ParamAddress, out: &mut ValueWriter<'_>) -> Result<(), ParamError> {
        let _ = (axis, addr, out);
        Err(ErrorValue::NO_DESCRIPTION.into())
    }

    /// Read text `addr.subindex` of `addr.pnu` (attribute 0x30). Default: 0x0F no text array
    /// (VACON: texts "not supported").
    fn read_text(&mut self, axis: u8, addr: &ParamAddress, out: &mut ValueWriter<'_>) -> Result<(), ParamError> {
        let _ = (axis, addr, out);
        Err(ErrorValue::NO_TEXT_ARRAY.into())
    }

    /// Whether some value asked for was not available yet (an asynchronous table, e.g. the
    /// drive behind the DPM parameter mailbox, has sent for it): the response built now is
    /// incomplete and must not be sent; build it again later. Default: never (a synchronous
    /// table).
    fn pending(&self) -> bool {
        false
    }

    /// A new parameter request (job) begins: an asynchronous table forgets the answers it kept
    /// for the previous one. Default: nothing to forget.
    fn start_job(&mut self) {}
}

/// A borrowed table is a table (for [`super::records::CardRecords::with`]).
impl<T: ParameterAccess + ?Sized> ParameterAccess for &mut T {
    fn has_axis(&self, axis: u8) -> bool {
        (**self).has_axis(axis)
    }
    fn read_value(&mut self, axis: u8, addr: &ParamAddress, out: &mut ValueWriter<'_>) -> Result<(), ParamError> {
        (**self).read_value(axis, addr, out)
    }
    fn write_value(&mut self, axis: u8, addr: &ParamAddress, values: &ValueBlock<'_>) -> Result<(), ParamError> {
        (**self).write_value(axis, addr, values)
    }
    fn read_description(&mut self, axis: u8, addr: &ParamAddress, out: &mut ValueWriter<'_>) -> Result<(), ParamError> {
        (**self).read_description(axis, addr, out)
    }
    fn read_text(&mut self, axis: u8, addr: &ParamAddress, out: &mut ValueWriter<'_>) -> Result<(), ParamError> {
        (**self).read_text(axis, addr, out)
    }
    fn pending(&self) -> bool {
        (**self).pending()
    }
    fn start_job(&mut self) {
        (**self).start_job();
    }
}

/// Execute a valid parameter request against `table` and write the parameter response into
/// `out`. Returns the response length (4..=240).
///
/// * Reference and axis are mirrored; No_of_Parameters is the request's.
/// * Read: one sub-response per parameter — `format, n, values` (padded to an even length) or
///   `44 01 error` (`44 02 error info` with additional info); Response_ID 0x81 if any failed.
/// * Change: parameters are written in order, each independently (no roll-back, VACON Table
///   99–100). All good → the 4-byte header alone, Response_ID 0x02. Any failure → 0x82 and one
///   sub-response per parameter: `40 00` for the good ones, `44 01 error` for the failed.
/// * The response never exceeds 240 bytes: each parameter's values get the room left after
///   reserving 4 bytes for every later parameter; a parameter whose values do not fit is
///   answered 0x15 "response too long".
pub fn respond(req: &ParamRequest<'_>, table: &mut impl ParameterAccess, out: &mut [u8; MAX_LEN]) -> usize {
    let n = req.len();
    out[..HEADER_LEN].copy_from_slice(&[req.reference, req.id as u8, req.axis, req.count]);
    let mut pos = HEADER_LEN;
    let mut failed = false;
    for (i, p) in req.parameters().enumerate() {
        // Invariant: pos + 4 × (n − i) ≤ MAX_LEN, so every remaining parameter can be answered.
        let limit = MAX_LEN - 4 * (n - i - 1);
        let result = match req.id {
            RequestId::Read => read_one(table, req.axis, &p.address, &mut out[pos..limit]),
            RequestId::Change => change_one(table, req.axis, &p).map(|()| {
                out[pos..pos + 2].copy_from_slice(&[Format::ZERO.0, 0]);
                2
            }),
        };
        match result {
            Ok(len) => pos += len,
            Err(e) => {
                failed = true;
                pos += emit_error_block(&mut out[pos..limit], &e, true);
            }
        }
    }
    match (req.id, failed) {
        (RequestId::Change, false) => HEADER_LEN,
        (_, false) => pos,
        (_, true) => {
            out[1] |= 0x80;
            pos
        }
    }
}

/// A read sub-response into `out` (its room); returns its length.
fn read_one(
    table: &mut impl ParameterAccess,
    axis: u8,
    addr: &ParamAddress,
    out: &mut [u8],
) -> Result<usize, ParamError> {
    if !table.has_axis(axis) {
        return Err(ErrorValue::AXIS_NONEXISTENT.into());
    }
    if addr.elements > MAX_ELEMENTS {
        return Err(ErrorValue::IMPERMISSIBLE_ADDRESS.into());
    }
    let (head, body) = out.split_at_mut(2);
    // Even capacity, so that an odd byte count still has room for its pad byte.
    let cap = body.len() & !1;
    let mut w = ValueWriter::new(&mut body[..cap]);
    match addr.attribute {
        Attribute::Value => table.read_value(axis, addr, &mut w),
        Attribute::Description => table.read_description(axis, addr, &mut w),
        Attribute::Text => table.read_text(axis, addr, &mut w),
        Attribute::Other(_) => Err(ErrorValue::IMPERMISSIBLE_ADDRESS.into()),
    }?;
    if w.overflowed() {
        return Err(ErrorValue::RESPONSE_TOO_LONG.into());
    }
    let (format, count, len) = (w.format().unwrap_or(Format::ZERO), w.count(), w.len());
    if format.value_size().map(|s| s * count as usize) != Some(len) {
        // The table mixed value sizes or set a format that does not match them (or one this
        // codec cannot size): a table bug, reported as 0x05 rather than sent malformed.
        return Err(ErrorValue::INCORRECT_DATA_TYPE.into());
    }
    head.copy_from_slice(&[format.0, count]);
    if len & 1 == 1 {
        body[len] = 0;
    }
    Ok(2 + len + (len & 1))
}

fn change_one(table: &mut impl ParameterAccess, axis: u8, p: &Parameter<'_>) -> Result<(), ParamError> {
    let addr = &p.address;
    if !table.has_axis(axis) {
        return Err(ErrorValue::AXIS_NONEXISTENT.into());
    }
    if addr.elements > MAX_ELEMENTS {
        return Err(ErrorValue::IMPERMISSIBLE_ADDRESS.into());
    }
    match addr.attribute {
        Attribute::Value => {}
        Attribute::Description => return Err(ErrorValue::DESCRIPTION_CANNOT_BE_CHANGED.into()),
        Attribute::Text => return Err(ErrorValue::TEXT_CANNOT_BE_CHANGED.into()),
        Attribute::Other(_) => return Err(ErrorValue::IMPERMISSIBLE_ADDRESS.into()),
    }
    // `parse` guarantees a block for every parameter of a change request.
    let Some(values) = p.value else { return Err(ErrorValue::VACON_INVALID_CHANGE_REQUEST.into()) };
    if values.format == Format::ZERO || values.format == Format::ERROR {
        return Err(ErrorValue::ILLEGAL_FORMAT.into());
    }
    if values.count != addr.count() {
        return Err(ErrorValue::NUMBER_OF_VALUES_INCONSISTENT.into());
    }
    table.write_value(axis, addr, &values)
}

/// `44 01 error` or, with additional info and room for it, `44 02 error info`. `out` has ≥ 4 bytes.
fn emit_error_block(out: &mut [u8], e: &ParamError, with_info: bool) -> usize {
    let [e0, e1] = e.value.0.to_be_bytes();
    match e.additional_info {
        Some(info) if with_info && out.len() >= 6 => {
            let [i0, i1] = info.to_be_bytes();
            out[..6].copy_from_slice(&[Format::ERROR.0, 2, e0, e1, i0, i1]);
            6
        }
        _ => {
            out[..4].copy_from_slice(&[Format::ERROR.0, 1, e0, e1]);
            4
        }
    }
}

/// Emit a parameter request (the master's side): header, addresses, and for a change request
/// each parameter's value block (padded to an even length). Every parameter of a change request
/// needs a value block whose `bytes` match `count × format size`.
pub fn emit_request(
    out: &mut [u8],
    reference: u8,
    id: RequestId,
    axis: u8,
    params: &[Parameter<'_>],
) -> Result<usize, EmitError> {
    let mut n = HEADER_LEN + ADDRESS_LEN * params.len();
    if id == RequestId::Change {
        for p in params {
            let v = p.value.ok_or(EmitError::TooLong)?;
            if v.format.value_size().map(|s| s * v.count as usize) != Some(v.bytes.len()) {
                return Err(EmitError::TooLong);
            }
            n += 2 + v.bytes.len() + (v.bytes.len() & 1);
        }
    }
    if n > MAX_LEN || params.len() > u8::MAX as usize {
        return Err(EmitError::TooLong);
    }
    let out = out.get_mut(..n).ok_or(EmitError::BufferTooSmall { needed: n })?;
    out[..HEADER_LEN].copy_from_slice(&[reference, id as u8, axis, params.len() as u8]);
    let mut pos = HEADER_LEN;
    for p in params {
        p.address.emit(&mut out[pos..]);
        pos += ADDRESS_LEN;
    }
    if id == RequestId::Change {
        for v in params.iter().filter_map(|p| p.value) {
            out[pos..pos + 2].copy_from_slice(&[v.format.0, v.count]);
            out[pos + 2..pos + 2 + v.bytes.len()].copy_from_slice(v.bytes);
            pos += 2 + v.bytes.len();
            if v.bytes.len() & 1 == 1 {
                out[pos] = 0;
                pos += 1;
            }
        }
    }
    Ok(n)
}

/// A parameter response (the master's side, zero-copy view).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct ParamResponse<'a> {
    /// Mirrored Request_Reference.
    pub reference: u8,
    /// Response_ID.
    pub id: ResponseId,
    /// Mirrored axis.
    pub axis: u8,
    /// No_of_Parameters.
    pub count: u8,
    body: &'a [u8],
}

impl<'a> ParamResponse<'a> {
    /// Parse a parameter response: the header, then (except for a positive change response,
    /// which is the header alone) `count` sub-responses filling the rest exactly.
    pub fn parse(data: &'a [u8]) -> Result<Self, RequestErrorKind> {
        if data.len() < HEADER_LEN {
            return Err(RequestErrorKind::TooShort);
        }
        if data.len() > MAX_LEN {
            return Err(RequestErrorKind::TooLong);
        }
        let (id, count, body) = (ResponseId(data[1]), data[3], &data[HEADER_LEN..]);
        let blocks = if id == ResponseId::CHANGE_OK { 0 } else { count };
        let mut pos = 0;
        for _ in 0..blocks {
            pos = value_block(body, pos)?.1.min(body.len());
        }
        if pos != body.len() {
            return Err(RequestErrorKind::TrailingBytes);
        }
        Ok(ParamResponse { reference: data[0], id, axis: data[2], count, body })
    }

    /// The sub-responses (none for a positive change response).
    pub fn values(&self) -> impl Iterator<Item = ValueBlock<'a>> + 'a {
        let body = self.body;
        let mut pos = 0;
        core::iter::from_fn(move || {
            let (block, next) = value_block(body, pos).ok()?;
            pos = next;
            Some(block)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dpv1::pdu::{self, DataRequest, Function, PduError, ReadRequest, Request, Response};
    use crate::profile::table::{slots, ParamDef, Table, Type};
    use crate::testkit::{FakeDrive, Indirect, Quirk, QuirkPnu};
    use proptest::prelude::*;

    // ---------------------------------------------------------------------------------------
    // Fake parameter tables holding exactly what the manuals' examples show.
    // ---------------------------------------------------------------------------------------

    /// VACON OPTE3/E5 as §6.4.4 shows it, as the one fake drive (`testkit::FakeDrive`): axis 1;
    /// PNU 918 = 3 (§6.4.4.2: "The node address used in the example was 3"); PNU 964 = Table 65;
    /// PNU 900 absent; PNU 10001 = drive parameter with the ID in the subindex (§6.4.4.7), Word
    /// only: ID 101 minimum frequency, ID 102 maximum frequency (101 ≤ 102, §6.4.4.11), ID 103
    /// acceleration time 30 = 3.0 s (Table 74), 0 not allowed (§6.4.4.9); no descriptions.
    const VACON_DEFS: &[ParamDef] = &[
        ParamDef::new(101, "Min frequency", Type::U16).limits(0, 32000),
        ParamDef::new(102, "Max frequency", Type::U16).limits(0, 32000).with_default(5000),
        ParamDef::new(103, "Accel time", Type::U16).limits(1, 30000).with_default(30),
        ParamDef::new(918, "Node address", Type::U16).read_only().with_default(3),
        ParamDef::new(964, "Device ident", Type::U16)
            .array(6)
            .read_only()
            .with_defaults(&[0x01BA, 0x0002, 0x006B, 0x07DA, 0x0A2D, 0x0001]),
    ];
    const VN: usize = slots(VACON_DEFS);
    type Vacon = FakeDrive<VN>;

    /// §6.4.4.11: the minimum frequency (ID 101) never above the maximum (ID 102).
    fn min_le_max(t: &Table<VN>, id: u16, v: i64) -> Result<(), ErrorValue> {
        match id {
            101 if v > t.get(102, 0).unwrap_or(0) => Err(ErrorValue::LIMIT_EXCEEDED),
            102 if v < t.get(101, 0).unwrap_or(0) => Err(ErrorValue::LIMIT_EXCEEDED),
            _ => Ok(()),
        }
    }

    fn vacon() -> Vacon {
        let ids = Indirect {
            pnu: 10001,
            not_found: ErrorValue::VACON_DRIVE_PARAMETER_NOT_FOUND,
            ids: 1..=900,
            ids_only: true,
        };
        FakeDrive::with_table(Table::new(VACON_DEFS))
            .on_axis(1)
            .indirect(ids)
            .rule(min_le_max)
            .word_only()
            .without_descriptions()
    }

    /// WEG CFW-11 as §4.2.5 assumes, as the one fake drive: DO-ID 0, every parameter a Word,
    /// P0002 = 100 rpm, P0003 = 5.0 A (50; absent for the negative example), P0100
    /// acceleration time ×0.1 s (limited to 8.0 s for the negative example); no descriptions.
    const CFW11_DEFS: &[ParamDef] = &[
        ParamDef::new(2, "Motor speed", Type::U16).read_only().with_default(100),
        ParamDef::new(3, "Motor current", Type::U16).read_only().with_default(50),
        ParamDef::new(100, "Accel. time", Type::U16).limits(0, 9999).with_default(50),
    ];
    const CFW11_NO_P0003: &[ParamDef] = &[CFW11_DEFS[0], CFW11_DEFS[2]];

    fn cfw11<const N: usize>(defs: &'static [ParamDef]) -> FakeDrive<N> {
        FakeDrive::with_table(Table::new(defs)).on_axis(0).word_only().without_descriptions()
    }

    /// P0100 at most 80 (8.0 s): the negative example's limit.
    fn p0100_at_most_80<const N: usize>(_: &Table<N>, pnu: u16, v: i64) -> Result<(), ErrorValue> {
        if pnu == 100 && v > 80 {
            return Err(ErrorValue::LIMIT_EXCEEDED);
        }
        Ok(())
    }

    // ---------------------------------------------------------------------------------------
    // Replay helpers.
    // ---------------------------------------------------------------------------------------

    fn request(write: &[u8]) -> ParamRequest<'_> {
        match pdu::parse(write) {
            Ok(Request::Write(DataRequest { slot: 0, index: RECORD_INDEX, data })) => {
                ParamRequest::parse(data).unwrap()
            }
            other => panic!("{other:?}"),
        }
    }

    fn params<'a>(r: &ParamRequest<'a>) -> Vec<Parameter<'a>> {
        r.parameters().collect()
    }

    fn value(pnu: u16, elements: u8, subindex: u16) -> ParamAddress {
        ParamAddress { attribute: Attribute::Value, elements, pnu, subindex }
    }

    fn read_param(address: ParamAddress) -> Parameter<'static> {
        Parameter { address, value: None }
    }

    /// One DS_Write / write response / DS_Read / read response on slot 0 index 47, byte for byte.
    fn exchange(table: &mut impl ParameterAccess, write: &[u8], ack: &[u8], read: &[u8], expected: &[u8]) {
        let req = request(write);
        let mut buf = [0u8; pdu::MAX_PDU_LEN];
        let n = Response::Write { slot: 0, index: RECORD_INDEX, length: write[3] }.emit(&mut buf).unwrap();
        assert_eq!(&buf[..n], ack, "write response");
        assert_eq!(pdu::parse(read), Ok(Request::Read(ReadRequest { slot: 0, index: RECORD_INDEX, length: 240 })));
        let mut resp = [0u8; MAX_LEN];
        let m = respond(&req, table, &mut resp);
        let n = Response::Read(DataRequest { slot: 0, index: RECORD_INDEX, data: &resp[..m] }).emit(&mut buf).unwrap();
        assert_eq!(&buf[..n], expected, "read response");
        let parsed = ParamResponse::parse(&resp[..m]).unwrap();
        assert_eq!((parsed.reference, parsed.axis), (req.reference, req.axis));
    }

    fn with(bytes: &[u8], fixes: &[(usize, u8)]) -> Vec<u8> {
        let mut v = bytes.to_vec();
        for &(i, b) in fixes {
            v[i] = b;
        }
        v
    }

    // ---------------------------------------------------------------------------------------
    // VACON OPTE3/E5 manual (shared/seeds/002_efeb549351216a08.txt) §6.4.4, in its order.
    // ---------------------------------------------------------------------------------------

    /// The DS_Read every example uses: Tables 57, 63, 69, 73, 77, 81 (and Tables 86, 92, 98,
    /// 104, which print it as `0x5F …`, see the contradictions below).
    const V_READ: [u8; 4] = [0x5E, 0x00, 0x2F, 0xF0];
    const V_ACK_0A: [u8; 4] = [0x5F, 0x00, 0x2F, 0x0A];
    const V_ACK_0E: [u8; 4] = [0x5F, 0x00, 0x2F, 0x0E];

    /// §6.4.4.1 Table 55 (write), Table 56 (ack); §6.4.4.2 Table 58 (response): PNU 918.
    const V1_WRITE: [u8; 14] = [0x5F, 0x00, 0x2F, 0x0A, 0x01, 0x01, 0x01, 0x01, 0x10, 0x01, 0x03, 0x96, 0x00, 0x00];
    const V1_RESP: [u8; 12] = [0x5E, 0x00, 0x2F, 0x08, 0x01, 0x01, 0x01, 0x01, 0x42, 0x01, 0x00, 0x03];
    /// §6.4.4.3 Table 61 / 62; §6.4.4.4 Table 64: all six elements of PNU 964.
    const V2_WRITE: [u8; 14] = [0x5F, 0x00, 0x2F, 0x0A, 0x02, 0x01, 0x01, 0x01, 0x10, 0x06, 0x03, 0xC4, 0x00, 0x00];
    const V2_RESP: [u8; 22] = [
        0x5E, 0x00, 0x2F, 0x12, 0x02, 0x01, 0x01, 0x01, 0x42, 0x06, 0x01, 0xBA, 0x00, 0x02, 0x00, 0x6B, 0x07, 0xDA,
        0x0A, 0x2D, 0x00, 0x01,
    ];
    /// §6.4.4.5 Table 67 / 68; §6.4.4.6 Table 70: unsupported PNU 900 → error 0x00.
    const V3_WRITE: [u8; 14] = [0x5F, 0x00, 0x2F, 0x0A, 0x03, 0x01, 0x01, 0x01, 0x10, 0x01, 0x03, 0x84, 0x00, 0x00];
    const V3_RESP: [u8; 12] = [0x5E, 0x00, 0x2F, 0x08, 0x03, 0x81, 0x01, 0x01, 0x44, 0x01, 0x00, 0x00];
    /// §6.4.4.7 Table 71 / 72 / 74: drive parameter ID 103 through PNU 10001 → 30.
    const V4_WRITE: [u8; 14] = [0x5F, 0x00, 0x2F, 0x0A, 0x04, 0x01, 0x01, 0x01, 0x10, 0x01, 0x27, 0x11, 0x00, 0x67];
    const V4_RESP: [u8; 12] = [0x5E, 0x00, 0x2F, 0x08, 0x04, 0x01, 0x01, 0x01, 0x42, 0x01, 0x00, 0x1E];
    /// §6.4.4.8 Table 75 / 76 / 78: change ID 103 to 40 — the positive change response is the
    /// header alone.
    const V5_WRITE: [u8; 18] =
        [0x5F, 0x00, 0x2F, 0x0E, 0x05, 0x02, 0x01, 0x01, 0x10, 0x01, 0x27, 0x11, 0x00, 0x67, 0x42, 0x01, 0x00, 0x28];
    const V5_RESP: [u8; 8] = [0x5E, 0x00, 0x2F, 0x04, 0x05, 0x02, 0x01, 0x01];
    /// §6.4.4.9 Table 79 / 80 / 82: change ID 103 to 0 → error 0x02 limit exceeded.
    const V6_WRITE: [u8; 18] =
        [0x5F, 0x00, 0x2F, 0x0E, 0x06, 0x02, 0x01, 0x01, 0x10, 0x01, 0x27, 0x11, 0x00, 0x67, 0x42, 0x01, 0x00, 0x00];
    const V6_RESP: [u8; 12] = [0x5E, 0x00, 0x2F, 0x08, 0x06, 0x82, 0x01, 0x01, 0x44, 0x01, 0x00, 0x02];
    /// §6.4.4.10 method 1, Table 84 / 85 / 87 as printed: ID 101 = 1000, ID 102 = 4000 as two
    /// parameters.
    const V7_WRITE: [u8; 28] = [
        0x5F, 0x00, 0x2F, 0x0E, 0x06, 0x02, 0x01, 0x02, 0x10, 0x01, 0x27, 0x11, 0x00, 0x65, 0x10, 0x01, 0x27, 0x11,
        0x00, 0x66, 0x42, 0x01, 0x03, 0xE8, 0x42, 0x01, 0x0F, 0xA0,
    ];
    const V7_RESP: [u8; 8] = [0x5E, 0x00, 0x2F, 0x0E, 0x06, 0x02, 0x01, 0x02];
    /// §6.4.4.10 method 2, Table 90 / 91 / 93 as printed: the same as two elements of one parameter.
    const V8_WRITE: [u8; 20] = [
        0x5F, 0x00, 0x2F, 0x0E, 0x06, 0x02, 0x01, 0x01, 0x10, 0x02, 0x27, 0x11, 0x00, 0x65, 0x42, 0x02, 0x03, 0xE8,
        0x0F, 0xA0,
    ];
    const V8_RESP: [u8; 8] = [0x5E, 0x00, 0x2F, 0x0E, 0x06, 0x02, 0x01, 0x01];
    /// §6.4.4.11 method 1, Table 96 / 97 / 99 as printed: ID 101 = 1000, ID 102 = 500 < 1000.
    const V9_WRITE: [u8; 28] = [
        0x5F, 0x00, 0x2F, 0x0E, 0x07, 0x02, 0x01, 0x02, 0x10, 0x01, 0x27, 0x11, 0x00, 0x65, 0x10, 0x01, 0x27, 0x11,
        0x00, 0x66, 0x42, 0x01, 0x03, 0xE8, 0x42, 0x01, 0x0F, 0xF4,
    ];
    const V9_RESP: [u8; 14] = [0x5E, 0x00, 0x2F, 0x0E, 0x07, 0x82, 0x01, 0x02, 0x40, 0x00, 0x44, 0x01, 0x00, 0x02];
    /// §6.4.4.11 method 2, Table 102 / 103 / 105 as printed.
    const V10_WRITE: [u8; 20] = [
        0x5F, 0x00, 0x2F, 0x0E, 0x07, 0x02, 0x01, 0x01, 0x10, 0x02, 0x27, 0x11, 0x00, 0x65, 0x42, 0x02, 0x03, 0xE8,
        0x01, 0xF4,
    ];
    const V10_RESP: [u8; 13] = [0x5E, 0x00, 0x2F, 0x0E, 0x07, 0x82, 0x01, 0x01, 0x01, 0x44, 0x01, 0x00, 0x02];

    /// §6.4.4.1–6.4.4.9: the consistent examples, replayed as one session on one table.
    #[test]
    fn vacon_6_4_4_1_to_9_replay() {
        let mut t = vacon();

        // 6.4.4.1/2 (Table 54: reference 1, read, axis 1, one parameter, 0x10, 1 element, PNU 918, subindex 0).
        let r = request(&V1_WRITE);
        assert_eq!((r.reference, r.id, r.axis, r.len()), (1, RequestId::Read, 1, 1));
        assert_eq!(params(&r), [read_param(value(918, 1, 0))]);
        exchange(&mut t, &V1_WRITE, &V_ACK_0A, &V_READ, &V1_RESP);

        // 6.4.4.3/4 (Table 60). Table 65 labels the response reference "0x01" while Table 64's
        // bytes (and the mirroring rule, Table 48) give 0x02: we mirror.
        let r = request(&V2_WRITE);
        assert_eq!((r.reference, r.id, r.axis), (2, RequestId::Read, 1));
        assert_eq!(params(&r), [read_param(value(964, 6, 0))]);
        exchange(&mut t, &V2_WRITE, &V_ACK_0A, &V_READ, &V2_RESP);

        // 6.4.4.5/6 (Table 66). The text says the Response ID "contains 0x80" where Table 70 and
        // Table 48 give 0x81 (read, negative): we send 0x81. It also says the fourth octet of the
        // parameter value names the first failing array element, while §6.4.3.4 says octets 3–4
        // are the error number (0x00 0x00 here): we follow §6.4.3.4 and PROFIdrive, where such
        // information is a second value (`ParamError::additional_info`).
        let r = request(&V3_WRITE);
        assert_eq!(params(&r), [read_param(value(900, 1, 0))]);
        exchange(&mut t, &V3_WRITE, &V_ACK_0A, &V_READ, &V3_RESP);

        // 6.4.4.7: PNU 10001 (0x2711), subindex = drive parameter ID 103.
        assert_eq!(params(&request(&V4_WRITE)), [read_param(value(10001, 1, 103))]);
        exchange(&mut t, &V4_WRITE, &V_ACK_0A, &V_READ, &V4_RESP);

        // 6.4.4.8: change ID 103 to 40 (0x0028); positive change response = header only.
        let r = request(&V5_WRITE);
        assert_eq!((r.reference, r.id, r.axis, r.len()), (5, RequestId::Change, 1, 1));
        let block = ValueBlock { format: Format::WORD, count: 1, bytes: &[0x00, 0x28] };
        assert_eq!(params(&r), [Parameter { address: value(10001, 1, 103), value: Some(block) }]);
        exchange(&mut t, &V5_WRITE, &V_ACK_0E, &V_READ, &V5_RESP);
        assert_eq!(t.get(103, 0), Some(40));

        // 6.4.4.9: change ID 103 to 0 → 0x82, `44 01 00 02`; the value stays.
        assert_eq!(params(&request(&V6_WRITE))[0].value.unwrap().u16(0), Some(0));
        exchange(&mut t, &V6_WRITE, &V_ACK_0E, &V_READ, &V6_RESP);
        assert_eq!(t.get(103, 0), Some(40));
    }

    /// §6.4.4.10–6.4.4.11: the multi-parameter examples contradict themselves; each is replayed
    /// with the protocol rule applied and the printed bytes shown to be what a slave must refuse.
    ///
    /// * Every DP-V1 length byte printed is `0x0E` (14): the method-1 writes carry 24 data bytes
    ///   (0x18), the method-2 writes 16 (0x10); the write responses mirror the request length
    ///   (Tables 85, 91, 97, 103 print 0x0E); the responses carry 4, 4, 10, 8 bytes (0x04, 0x04,
    ///   0x0A, 0x08), not 0x0E (Tables 87, 93, 99, 105).
    /// * The DS_Reads are printed as `0x5F 0x00 0x2F 0xF0` (Tables 86, 92, 98, 104): a read is 0x5E.
    /// * Table 96 prints the second value as `0x0F 0xF4` (4084), Table 95 and the text as 0x01F4
    ///   (500, below the minimum frequency 1000 — the point of the example): we use 0x01F4.
    /// * Table 105 has a stray `0x01` between the header and `0x44 0x01 0x00 0x02`; Table 106
    ///   expands the response without it: we send it without.
    /// * Tables 88 and 94 label the response ID field "Request ID"; the bytes are the Response ID.
    #[test]
    fn vacon_6_4_4_10_and_11_replay_with_corrections() {
        let mut t = vacon();
        t.table.set(103, 0, 40).unwrap(); // the state after §6.4.4.8/9

        // The printed bytes are refused at the DP-V1 layer.
        assert_eq!(
            pdu::parse(&V7_WRITE),
            Err(PduError::DataLengthMismatch { function: Function::Write, declared: 0x0E, actual: 24 })
        );
        assert_eq!(
            pdu::parse(&V8_WRITE),
            Err(PduError::DataLengthMismatch { function: Function::Write, declared: 0x0E, actual: 16 })
        );
        assert_eq!(
            pdu::parse(&[0x5F, 0x00, 0x2F, 0xF0]),
            Err(PduError::DataLengthMismatch { function: Function::Write, declared: 0xF0, actual: 0 })
        );
        // Table 105's response does not parse: 0x01 is read as a format (Boolean) with 0x44 values.
        assert_eq!(ParamResponse::parse(&V10_RESP[4..]), Err(RequestErrorKind::Truncated));

        // 6.4.4.10 method 1 (Table 83): two parameters, one Word each.
        let w = with(&V7_WRITE, &[(3, 0x18)]);
        let r = request(&w);
        assert_eq!((r.reference, r.id, r.axis, r.len()), (6, RequestId::Change, 1, 2));
        let p = params(&r);
        assert_eq!((p[0].address, p[1].address), (value(10001, 1, 101), value(10001, 1, 102)));
        assert_eq!((p[0].value.unwrap().u16(0), p[1].value.unwrap().u16(0)), (Some(1000), Some(4000)));
        exchange(&mut t, &w, &[0x5F, 0x00, 0x2F, 0x18], &V_READ, &with(&V7_RESP, &[(3, 0x04)]));
        assert_eq!((t.get(101, 0), t.get(102, 0)), (Some(1000), Some(4000)));

        // 6.4.4.10 method 2 (Table 89): one parameter, two elements.
        let w = with(&V8_WRITE, &[(3, 0x10)]);
        let p = params(&request(&w));
        assert_eq!(p.len(), 1);
        assert_eq!(p[0].address, value(10001, 2, 101));
        assert_eq!(p[0].value, Some(ValueBlock { format: Format::WORD, count: 2, bytes: &[0x03, 0xE8, 0x0F, 0xA0] }));
        exchange(&mut t, &w, &[0x5F, 0x00, 0x2F, 0x10], &V_READ, &with(&V8_RESP, &[(3, 0x04)]));

        // 6.4.4.11 method 1 as printed (0x0FF4 = 4084) would succeed — not the manual's answer.
        let printed = with(&V9_WRITE, &[(3, 0x18)]);
        let mut out = [0u8; MAX_LEN];
        let n = respond(&request(&printed), &mut t.clone(), &mut out);
        assert_eq!(&out[..n], &[0x07, 0x02, 0x01, 0x02]);
        // With Table 95's 0x01F4: parameter 1 succeeds (`40 00`), parameter 2 fails (`44 01 00 02`).
        let w = with(&V9_WRITE, &[(3, 0x18), (26, 0x01)]);
        assert_eq!(params(&request(&w))[1].value.unwrap().u16(0), Some(500));
        exchange(&mut t, &w, &[0x5F, 0x00, 0x2F, 0x18], &V_READ, &with(&V9_RESP, &[(3, 0x0A)]));
        assert_eq!((t.get(101, 0), t.get(102, 0)), (Some(1000), Some(4000)));

        // 6.4.4.11 method 2 (Table 101/102): element 101 written, element 102 fails.
        let w = with(&V10_WRITE, &[(3, 0x10)]);
        assert_eq!(params(&request(&w))[0].value.unwrap().u16(1), Some(500));
        let expected = [0x5E, 0x00, 0x2F, 0x08, 0x07, 0x82, 0x01, 0x01, 0x44, 0x01, 0x00, 0x02];
        assert_eq!(&expected[4..], &[&V10_RESP[4..8], &V10_RESP[9..]].concat()[..]);
        exchange(&mut t, &w, &[0x5F, 0x00, 0x2F, 0x10], &V_READ, &expected);
        assert_eq!((t.get(101, 0), t.get(102, 0)), (Some(1000), Some(4000)));
    }

    // ---------------------------------------------------------------------------------------
    // WEG CFW-11 manual (shared/seeds/001_606fd1a48149efbc.txt) §4.2.5 "Exemplo de Telegramas",
    // data bytes as the tables number them; DP-V1 framing from §4.2.3.
    // ---------------------------------------------------------------------------------------

    /// Exemplo 1: read P0002 and P0003.
    const W1_REQUEST: [u8; 16] =
        [0x01, 0x01, 0x00, 0x02, 0x10, 0x01, 0x00, 0x02, 0x00, 0x00, 0x10, 0x01, 0x00, 0x03, 0x00, 0x00];
    /// Exemplo 1, "Resposta positiva" (P0002 = 100 rpm, P0003 = 5,0 A). The table numbers the
    /// bytes 1–8 then 11–14 (9 and 10 skipped); the response is 12 bytes.
    const W1_POSITIVE: [u8; 12] = [0x01, 0x01, 0x00, 0x02, 0x42, 0x01, 0x00, 0x64, 0x42, 0x01, 0x00, 0x32];
    /// Exemplo 1, "Resposta negativa" (P0003 not existing): P0002's value stays in the response.
    const W1_NEGATIVE: [u8; 12] = [0x01, 0x81, 0x00, 0x02, 0x42, 0x01, 0x00, 0x64, 0x44, 0x01, 0x00, 0x00];
    /// Exemplo 2: change P0100 to 8,5 s (85).
    const W2_REQUEST: [u8; 14] = [0x01, 0x02, 0x00, 0x01, 0x10, 0x01, 0x00, 0x64, 0x00, 0x00, 0x42, 0x01, 0x00, 0x55];
    /// Exemplo 2, "Resposta positiva": the header alone.
    const W2_POSITIVE: [u8; 4] = [0x01, 0x02, 0x00, 0x01];
    /// Exemplo 2, "Resposta negativa" (value out of limits). The table prints No. de Parâmetros
    /// "2" next to "Alteração de 1 parâmetro"; the number is mirrored from the request: 1.
    const W2_NEGATIVE: [u8; 8] = [0x01, 0x82, 0x00, 0x01, 0x44, 0x01, 0x00, 0x02];

    /// DS_Write `5F 00 2F n data` (§4.2.3).
    fn ds_write(data: &[u8]) -> Vec<u8> {
        [&[0x5F, 0x00, 0x2F, data.len() as u8][..], data].concat()
    }

    fn ds_read_response(data: &[u8]) -> Vec<u8> {
        [&[0x5E, 0x00, 0x2F, data.len() as u8][..], data].concat()
    }

    /// The write response mirrors the length (DP-V1, profichip, VACON Table 56). CFW-11 §4.2.3
    /// (and CFW500 §5.2.3) print "Tamanho 0" / "Size 0" for it: we follow the protocol.
    fn ds_write_ack(data: &[u8]) -> [u8; 4] {
        [0x5F, 0x00, 0x2F, data.len() as u8]
    }

    #[test]
    fn cfw11_4_2_5_replay() {
        let mut t = cfw11::<{ slots(CFW11_DEFS) }>(CFW11_DEFS);

        let w = ds_write(&W1_REQUEST);
        let r = request(&w);
        assert_eq!((r.reference, r.id, r.axis, r.len()), (1, RequestId::Read, 0, 2));
        assert_eq!(params(&r), [read_param(value(2, 1, 0)), read_param(value(3, 1, 0))]);
        exchange(&mut t, &w, &ds_write_ack(&W1_REQUEST), &V_READ, &ds_read_response(&W1_POSITIVE));

        let mut missing = cfw11::<{ slots(CFW11_NO_P0003) }>(CFW11_NO_P0003);
        exchange(&mut missing, &w, &ds_write_ack(&W1_REQUEST), &V_READ, &ds_read_response(&W1_NEGATIVE));

        let w = ds_write(&W2_REQUEST);
        let r = request(&w);
        assert_eq!((r.reference, r.id, r.axis, r.len()), (1, RequestId::Change, 0, 1));
        let block = ValueBlock { format: Format::WORD, count: 1, bytes: &[0x00, 0x55] };
        assert_eq!(params(&r), [Parameter { address: value(100, 1, 0), value: Some(block) }]);
        exchange(&mut t, &w, &ds_write_ack(&W2_REQUEST), &V_READ, &ds_read_response(&W2_POSITIVE));
        assert_eq!(t.get(100, 0), Some(85));

        let mut limited = cfw11::<{ slots(CFW11_DEFS) }>(CFW11_DEFS).rule(p0100_at_most_80);
        exchange(&mut limited, &w, &ds_write_ack(&W2_REQUEST), &V_READ, &ds_read_response(&W2_NEGATIVE));
        assert_eq!(limited.get(100, 0), Some(50));
    }

    // ---------------------------------------------------------------------------------------
    // Structure checks, per-parameter checks, limits.
    // ---------------------------------------------------------------------------------------

    #[test]
    fn request_errors() {
        let kind = |d: &[u8]| ParamRequest::parse(d).unwrap_err().kind;
        let v1 = &V1_WRITE[4..];
        assert_eq!(kind(&[]), RequestErrorKind::TooShort);
        assert_eq!(kind(&v1[..3]), RequestErrorKind::TooShort);
        assert_eq!(kind(&with(v1, &[(0, 0)])), RequestErrorKind::InvalidReference);
        assert_eq!(kind(&with(v1, &[(1, 3)])), RequestErrorKind::InvalidRequestId);
        assert_eq!(kind(&with(v1, &[(3, 0)])), RequestErrorKind::InvalidParameterCount);
        assert_eq!(kind(&with(v1, &[(3, 40)])), RequestErrorKind::InvalidParameterCount);
        assert_eq!(kind(&with(v1, &[(3, 2)])), RequestErrorKind::Truncated);
        assert_eq!(kind(&[v1, &[0]].concat()), RequestErrorKind::TrailingBytes);
        assert_eq!(kind(&[0u8; 241]), RequestErrorKind::TooLong);
        let v5 = &V5_WRITE[4..];
        assert_eq!(kind(&v5[..13]), RequestErrorKind::Truncated);
        assert_eq!(kind(&v5[..10]), RequestErrorKind::Truncated);
        assert_eq!(kind(&with(v5, &[(10, 0x0D)])), RequestErrorKind::IllegalFormat(0x0D));
        assert_eq!(kind(&with(v5, &[(10, 0x45)])), RequestErrorKind::IllegalFormat(0x45));
        assert_eq!(kind(&[v5, &[0, 0]].concat()), RequestErrorKind::TrailingBytes);

        let e = ParamRequest::parse(&with(v1, &[(1, 3)])).unwrap_err();
        assert_eq!((e.reference, e.request_id, e.axis, e.count), (1, 3, 1, 1));
        assert_eq!(e.error_code1(), ErrorCode1(0xB7));
        assert_eq!(e.error_value(), ErrorValue(0x21));
        let mut out = [0u8; MAX_LEN];
        let n = e.emit_response(&mut out);
        assert_eq!(&out[..n], &[0x01, 0x80, 0x01, 0x01, 0x44, 0x01, 0x00, 0x21]);

        let e = ParamRequest::parse(&with(v5, &[(3, 0)])).unwrap_err();
        assert_eq!(e.error_value(), ErrorValue(0x68));
        let n = e.emit_response(&mut out);
        assert_eq!(&out[..n], &[0x05, 0x82, 0x01, 0x01, 0x44, 0x01, 0x00, 0x68]);
        assert_eq!(ParamRequest::parse(&with(v1, &[(0, 0)])).unwrap_err().error_value(), ErrorValue(0x65));
        assert_eq!(ParamRequest::parse(&v5[..13]).unwrap_err().error_value(), ErrorValue(0x6B));
        assert_eq!(ParamRequest::parse(&with(v5, &[(10, 0x0D)])).unwrap_err().error_value(), ErrorValue(0x17));

        // Three parameters, truncated: each answered with 0x6B.
        let e = ParamRequest::parse(&with(v1, &[(3, 3)])).unwrap_err();
        let n = e.emit_response(&mut out);
        assert_eq!(&out[..n], &[1, 0x81, 1, 3, 0x44, 1, 0, 0x6B, 0x44, 1, 0, 0x6B, 0x44, 1, 0, 0x6B]);
    }

    /// Every proper prefix of a valid request is refused, and so is every single-bit flip of its
    /// header, except where the flip yields another valid header (reference, axis).
    #[test]
    fn every_prefix_and_header_flip() {
        for data in [&V1_WRITE[4..], &V5_WRITE[4..], &V2_WRITE[4..], &W1_REQUEST[..]] {
            for k in 0..data.len() {
                assert!(ParamRequest::parse(&data[..k]).is_err(), "{data:02X?} prefix {k}");
            }
            let orig = ParamRequest::parse(data).unwrap();
            for byte in 0..HEADER_LEN {
                for bit in 0..8 {
                    let f = with(data, &[(byte, data[byte] ^ (1 << bit))]);
                    match ParamRequest::parse(&f) {
                        Ok(r) => {
                            assert!(byte == 0 || byte == 2, "flip {byte}.{bit} accepted");
                            assert_ne!((r.reference, r.axis), (orig.reference, orig.axis));
                        }
                        Err(_) => assert!(byte == 0 || byte == 1 || byte == 3),
                    }
                }
            }
        }
    }

    #[test]
    fn odd_value_blocks_are_padded() {
        // Two parameters: Byte ×1 (+ pad), then Word ×1.
        let p = [
            Parameter {
                address: value(1, 1, 0),
                value: Some(ValueBlock { format: Format::BYTE, count: 1, bytes: &[7] }),
            },
            Parameter {
                address: value(2, 1, 0),
                value: Some(ValueBlock { format: Format::WORD, count: 1, bytes: &[0x12, 0x34] }),
            },
        ];
        let mut out = [0u8; MAX_LEN];
        let n = emit_request(&mut out, 9, RequestId::Change, 0, &p).unwrap();
        let golden = [9, 2, 0, 2, 0x10, 1, 0, 1, 0, 0, 0x10, 1, 0, 2, 0, 0, 0x41, 1, 7, 0, 0x42, 1, 0x12, 0x34];
        assert_eq!(&out[..n], &golden);
        assert_eq!(params(&ParamRequest::parse(&golden).unwrap()), p);
        // Without the pad between blocks the second header is misplaced → refused.
        let unpadded = [&golden[..19], &golden[20..]].concat();
        assert!(ParamRequest::parse(&unpadded).is_err());
        // After the last block the pad is optional.
        let last_odd = [9, 2, 0, 1, 0x10, 2, 0, 1, 0, 0, 0x41, 2, 7, 8];
        let last_odd3 = [9, 2, 0, 1, 0x10, 3, 0, 1, 0, 0, 0x41, 3, 7, 8, 9];
        assert!(ParamRequest::parse(&last_odd).is_ok());
        assert!(ParamRequest::parse(&last_odd3).is_ok());
        assert!(ParamRequest::parse(&[&last_odd3[..], &[0]].concat()).is_ok());
        assert!(ParamRequest::parse(&[&last_odd3[..], &[0, 0]].concat()).is_err());

        // Read sub-responses with an odd byte count carry a pad byte: VisibleString "abc".
        const NAME: &[QuirkPnu] = &[
            QuirkPnu { pnu: 1, read: Quirk::Str(b"abc"), write: Ok(()) },
            QuirkPnu { pnu: 2, read: Quirk::Str(b"abc"), write: Ok(()) },
        ];
        let req = [1, 1, 0, 2, 0x10, 1, 0, 1, 0, 0, 0x10, 1, 0, 2, 0, 0];
        let n = respond(&ParamRequest::parse(&req).unwrap(), &mut FakeDrive::empty().quirks(NAME), &mut out);
        assert_eq!(&out[..n], &[1, 1, 0, 2, 0x09, 3, b'a', b'b', b'c', 0, 0x09, 3, b'a', b'b', b'c', 0]);
        let r = ParamResponse::parse(&out[..n]).unwrap();
        assert_eq!(r.values().map(|v| v.bytes).collect::<Vec<_>>(), [b"abc", b"abc"]);
    }

    #[test]
    fn per_parameter_checks() {
        let mut t = vacon();
        let mut out = [0u8; MAX_LEN];
        let mut run = |data: &[u8], t: &mut Vacon| {
            let n = respond(&ParamRequest::parse(data).unwrap(), t, &mut out);
            out[..n].to_vec()
        };
        // Description (default 0x09), text (default 0x0F), attribute 0x40 (0x16), 235 elements (0x16).
        let read = [
            7, 1, 1, 4, 0x20, 1, 0x03, 0x96, 0, 0, 0x30, 1, 0x03, 0x96, 0, 0, 0x40, 1, 0x03, 0x96, 0, 0, 0x10, 235,
            0x03, 0xC4, 0, 0,
        ];
        assert_eq!(
            run(&read, &mut t),
            [7, 0x81, 1, 4, 0x44, 1, 0, 0x09, 0x44, 1, 0, 0x0F, 0x44, 1, 0, 0x16, 0x44, 1, 0, 0x16]
        );
        // Wrong axis: every parameter 0x19.
        assert_eq!(run(&with(&read, &[(2, 2)]), &mut t)[4..8], [0x44, 1, 0, 0x19]);
        // Subindex past the end of PNU 964 (0x03), elements 0 = one value.
        let r = [8, 1, 1, 2, 0x10, 2, 0x03, 0xC4, 0, 5, 0x10, 0, 0x03, 0x96, 0, 0];
        assert_eq!(run(&r, &mut t), [8, 0x81, 1, 2, 0x44, 1, 0, 0x03, 0x42, 1, 0, 3]);

        // Change: description 0x07, text 0x20, Zero format 0x17, Error format 0x17, count 0x18, read-only 0x01.
        let change = [
            9, 2, 1, 6, //
            0x20, 1, 0x27, 0x11, 0, 0x67, 0x30, 1, 0x27, 0x11, 0, 0x67, 0x10, 1, 0x27, 0x11, 0, 0x67, //
            0x10, 1, 0x27, 0x11, 0, 0x67, 0x10, 2, 0x27, 0x11, 0, 0x65, 0x10, 1, 0x03, 0x96, 0, 0, //
            0x42, 1, 0, 1, 0x42, 1, 0, 1, 0x40, 0, 0x44, 1, 0, 0, 0x42, 1, 0, 1, 0x42, 1, 0, 4,
        ];
        assert_eq!(
            run(&change, &mut t),
            [
                9, 0x82, 1, 6, 0x44, 1, 0, 0x07, 0x44, 1, 0, 0x20, 0x44, 1, 0, 0x17, 0x44, 1, 0, 0x17, 0x44, 1, 0,
                0x18, 0x44, 1, 0, 0x01
            ]
        );
        assert_eq!(t.get(103, 0), Some(30));
    }

    /// A table with an unbounded array PNU 1 (234 elements read), PNU 2 that reports additional
    /// info, PNU 3 whose reader ignores a full buffer, PNU 4 that mixes value sizes: the one fake
    /// drive with these quirk PNUs only.
    const BIG: &[QuirkPnu] = &[
        QuirkPnu { pnu: 1, read: Quirk::Ramp, write: Ok(()) },
        QuirkPnu {
            pnu: 2,
            read: Quirk::Fails(ParamError { value: ErrorValue::INVALID_SUBINDEX, additional_info: Some(0x66) }),
            write: Err(ParamError { value: ErrorValue::LIMIT_EXCEEDED, additional_info: Some(0x0101) }),
        },
        QuirkPnu { pnu: 3, read: Quirk::IgnoresFull, write: Ok(()) },
        QuirkPnu { pnu: 4, read: Quirk::Mixed, write: Ok(()) },
    ];

    fn big() -> FakeDrive {
        FakeDrive::empty().quirks(BIG)
    }

    #[test]
    fn response_limits_and_additional_info() {
        let mut out = [0u8; MAX_LEN];
        let reads = |ps: &[(u16, u8)]| {
            let p: Vec<_> = ps.iter().map(|&(pnu, el)| read_param(value(pnu, el, 0))).collect();
            let mut buf = [0u8; MAX_LEN];
            let n = emit_request(&mut buf, 1, RequestId::Read, 0, &p).unwrap();
            buf[..n].to_vec()
        };
        // 234 words do not fit: 0x15, and the second parameter is still answered.
        let req = reads(&[(1, 234), (1, 1)]);
        let n = respond(&ParamRequest::parse(&req).unwrap(), &mut big(), &mut out);
        assert_eq!(&out[..n], &[1, 0x81, 0, 2, 0x44, 1, 0, 0x15, 0x42, 1, 0, 0]);
        // 100 words fit (206 bytes); the next 100 do not, the third (1 word) still does.
        let req = reads(&[(1, 100), (1, 100), (1, 1)]);
        let n = respond(&ParamRequest::parse(&req).unwrap(), &mut big(), &mut out);
        assert_eq!(n, 4 + 202 + 4 + 4);
        assert_eq!(&out[206..n], &[0x44, 1, 0, 0x15, 0x42, 1, 0, 0]);
        // 117 words: exactly 4 + 2 + 234 = 240.
        let n = respond(&ParamRequest::parse(&reads(&[(1, 117)])).unwrap(), &mut big(), &mut out);
        assert_eq!((n, out[1], out[5]), (240, 0x01, 117));
        // A table that ignores the overflow is still reported 0x15; mixed sizes 0x05.
        let n = respond(&ParamRequest::parse(&reads(&[(3, 100), (4, 1)])).unwrap(), &mut big(), &mut out);
        assert_eq!(&out[..n], &[1, 0x81, 0, 2, 0x44, 1, 0, 0x15, 0x44, 1, 0, 0x05]);
        // Additional info as a second value.
        let n = respond(&ParamRequest::parse(&reads(&[(2, 1)])).unwrap(), &mut big(), &mut out);
        assert_eq!(&out[..n], &[1, 0x81, 0, 1, 0x44, 2, 0, 0x03, 0, 0x66]);
        let e = ParamResponse::parse(&out[..n]).unwrap().values().next().unwrap().error();
        assert_eq!(e, Some(ParamError { value: ErrorValue(3), additional_info: Some(0x66) }));
        // 39 parameters of one word each: 4 + 39 × 4 = 160.
        let n = respond(&ParamRequest::parse(&reads(&[(1, 1); 39])).unwrap(), &mut big(), &mut out);
        assert_eq!(n, 160);
        // A change with additional info.
        let blk = Some(ValueBlock { format: Format::WORD, count: 1, bytes: &[0, 9] });
        let p = [Parameter { address: value(1, 1, 0), value: blk }, Parameter { address: value(2, 1, 0), value: blk }];
        let mut buf = [0u8; MAX_LEN];
        let m = emit_request(&mut buf, 3, RequestId::Change, 0, &p).unwrap();
        let n = respond(&ParamRequest::parse(&buf[..m]).unwrap(), &mut big(), &mut out);
        assert_eq!(&out[..n], &[3, 0x82, 0, 2, 0x40, 0, 0x44, 2, 0, 0x02, 0x01, 0x01]);
    }

    #[test]
    fn emit_request_limits() {
        let p = read_param(value(1, 1, 0));
        let mut out = [0u8; MAX_LEN];
        assert_eq!(emit_request(&mut out, 1, RequestId::Read, 0, &[p; 39]), Ok(238));
        assert_eq!(emit_request(&mut out, 1, RequestId::Read, 0, &[p; 40]), Err(EmitError::TooLong));
        assert_eq!(emit_request(&mut out, 1, RequestId::Change, 0, &[p]), Err(EmitError::TooLong));
        assert_eq!(
            emit_request(&mut [0u8; 9], 1, RequestId::Read, 0, &[p]),
            Err(EmitError::BufferTooSmall { needed: 10 })
        );
        let bad = Parameter { value: Some(ValueBlock { format: Format::WORD, count: 2, bytes: &[0, 1] }), ..p };
        assert_eq!(emit_request(&mut out, 1, RequestId::Change, 0, &[bad]), Err(EmitError::TooLong));
    }

    #[test]
    fn value_accessors_and_codes() {
        let b =
            ValueBlock { format: Format::DOUBLE_WORD, count: 2, bytes: &[0x3F, 0x80, 0, 0, 0xFF, 0xFF, 0xFF, 0xFE] };
        assert_eq!((b.f32(0), b.u32(1), b.u16(0), b.value(2)), (Some(1.0), Some(0xFFFF_FFFE), None, None));
        let w = ValueBlock { format: Format::INTEGER16, count: 1, bytes: &[0xFF, 0xFE] };
        assert_eq!((w.i16(0), w.u8(0), w.error()), (Some(-2), None, None));
        assert!(ResponseId::CHANGE_ERROR.is_error() && !ResponseId::READ_OK.is_error());
        assert!(ErrorValue::VACON_INVALID_CHANGE_REQUEST.is_manufacturer_specific());
        assert!(!ErrorValue::AXIS_NONEXISTENT.is_manufacturer_specific());
        // VACON Table 47, every number.
        let table = [
            (ErrorValue::IMPERMISSIBLE_PARAMETER_NUMBER, 0x00),
            (ErrorValue::VALUE_CANNOT_BE_CHANGED, 0x01),
            (ErrorValue::LIMIT_EXCEEDED, 0x02),
            (ErrorValue::INVALID_SUBINDEX, 0x03),
            (ErrorValue::NO_ARRAY, 0x04),
            (ErrorValue::INCORRECT_DATA_TYPE, 0x05),
            (ErrorValue::SETTING_NOT_PERMITTED, 0x06),
            (ErrorValue::DESCRIPTION_CANNOT_BE_CHANGED, 0x07),
            (ErrorValue::NO_DESCRIPTION, 0x09),
            (ErrorValue::NO_OPERATION_PRIORITY, 0x0B),
            (ErrorValue::NO_TEXT_ARRAY, 0x0F),
            (ErrorValue::NOT_EXECUTABLE, 0x11),
            (ErrorValue::VALUE_IMPERMISSIBLE, 0x14),
            (ErrorValue::RESPONSE_TOO_LONG, 0x15),
            (ErrorValue::IMPERMISSIBLE_ADDRESS, 0x16),
            (ErrorValue::ILLEGAL_FORMAT, 0x17),
            (ErrorValue::NUMBER_OF_VALUES_INCONSISTENT, 0x18),
            (ErrorValue::AXIS_NONEXISTENT, 0x19),
            (ErrorValue::TEXT_CANNOT_BE_CHANGED, 0x20),
            (ErrorValue::INVALID_REQUEST_ID, 0x21),
            (ErrorValue::VACON_INVALID_REQUEST_REFERENCE, 0x65),
            (ErrorValue::VACON_INVALID_REQUEST_ID, 0x66),
            (ErrorValue::VACON_INVALID_PARAMETER_COUNT, 0x68),
            (ErrorValue::VACON_INVALID_ATTRIBUTE, 0x69),
            (ErrorValue::VACON_REQUEST_TOO_SHORT, 0x6B),
            (ErrorValue::VACON_DRIVE_PARAMETER_NOT_FOUND, 0x6C),
            (ErrorValue::VACON_INVALID_CHANGE_REQUEST, 0x6D),
        ];
        for (e, v) in table {
            assert_eq!(e.0, v);
        }
    }

    // ---------------------------------------------------------------------------------------
    // Property tests.
    // ---------------------------------------------------------------------------------------

    const SIZED_FORMATS: [u8; 15] = [1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 0x40, 0x41, 0x42, 0x43, 0x44];

    /// (attribute, elements, pnu, subindex, format, raw value bytes)
    type RawParam = (u8, u8, u16, u16, u8, Vec<u8>);

    fn arb_param() -> impl Strategy<Value = RawParam> {
        (
            prop_oneof![6 => Just(0x10u8), 1 => Just(0x20), 1 => Just(0x30), 1 => any::<u8>()],
            any::<u8>(),
            prop_oneof![Just(918u16), Just(964), Just(10001), any::<u16>()],
            prop_oneof![0u16..8, Just(101), Just(103), any::<u16>()],
            proptest::sample::select(SIZED_FORMATS.to_vec()),
            proptest::collection::vec(any::<u8>(), 0..12),
        )
    }

    fn build(raw: &[RawParam], change: bool) -> Vec<Parameter<'_>> {
        raw.iter()
            .map(|(attr, el, pnu, sub, f, bytes)| {
                let format = Format(*f);
                let size = format.value_size().unwrap();
                let (count, len) = match bytes.len().checked_div(size) {
                    Some(c) => (c as u8, c * size),
                    None => (bytes.len() as u8 % 3, 0), // Zero format: no value bytes
                };
                // Half of the change requests address exactly as many elements as they carry values.
                let elements = if change && el % 2 == 0 && count > 0 { count } else { *el };
                let address =
                    ParamAddress { attribute: Attribute::from_u8(*attr), elements, pnu: *pnu, subindex: *sub };
                Parameter { address, value: change.then_some(ValueBlock { format, count, bytes: &bytes[..len] }) }
            })
            .collect()
    }

    proptest! {
        #[test]
        fn request_roundtrip(reference in 1u8..=255, change: bool, axis: u8, raw in proptest::collection::vec(arb_param(), 1..=39)) {
            let p = build(&raw, change);
            let id = if change { RequestId::Change } else { RequestId::Read };
            let mut out = [0u8; 300];
            match emit_request(&mut out, reference, id, axis, &p) {
                Ok(n) => {
                    let r = ParamRequest::parse(&out[..n]).unwrap();
                    prop_assert_eq!((r.reference, r.id, r.axis), (reference, id, axis));
                    prop_assert_eq!(params(&r), p);
                }
                Err(e) => prop_assert_eq!(e, EmitError::TooLong),
            }
        }

        /// Whatever the request and the table, the response is ≤ 240 bytes, well-formed, mirrors
        /// the header, and has one sub-response per parameter (none for a positive change).
        #[test]
        fn respond_is_bounded_and_well_formed(reference in 1u8..=255, change: bool, axis in 0u8..3, big: bool,
                                              raw in proptest::collection::vec(arb_param(), 1..=39)) {
            let raw: Vec<_> = raw.into_iter().map(|mut r| { if big && r.2 > 4 { r.2 %= 5; } r }).collect();
            let p = build(&raw, change);
            let id = if change { RequestId::Change } else { RequestId::Read };
            let mut buf = [0u8; 300];
            let Ok(n) = emit_request(&mut buf, reference, id, axis, &p) else { return Ok(()) };
            let req = ParamRequest::parse(&buf[..n]).unwrap();
            let mut out = [0u8; MAX_LEN];
            let m = if big { respond(&req, &mut self::big(), &mut out) } else { respond(&req, &mut vacon(), &mut out) };
            prop_assert!((HEADER_LEN..=MAX_LEN).contains(&m));
            let r = ParamResponse::parse(&out[..m]).unwrap();
            prop_assert_eq!((r.reference, r.axis, r.count as usize), (reference, axis, p.len()));
            let subs: Vec<_> = r.values().collect();
            let failed = subs.iter().any(|s| s.format == Format::ERROR);
            prop_assert_eq!(r.id.is_error(), failed);
            prop_assert_eq!(r.id.0 & 0x7F, id as u8);
            if change && !failed {
                prop_assert_eq!(m, HEADER_LEN);
            } else {
                prop_assert_eq!(subs.len(), p.len());
            }
        }

        #[test]
        fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..260)) {
            match ParamRequest::parse(&bytes) {
                Ok(req) => {
                    let mut out = [0u8; MAX_LEN];
                    let m = respond(&req, &mut vacon(), &mut out);
                    prop_assert!(ParamResponse::parse(&out[..m]).is_ok());
                    let m = respond(&req, &mut big(), &mut out);
                    prop_assert!(ParamResponse::parse(&out[..m]).is_ok());
                }
                Err(e) => {
                    let mut out = [0u8; MAX_LEN];
                    let m = e.emit_response(&mut out);
                    prop_assert!(ParamResponse::parse(&out[..m]).is_ok());
                    let _ = (e.error_code1(), e.error_value());
                }
            }
            let _ = ParamResponse::parse(&bytes).map(|r| r.values().count());
        }
    }
}
