//! WEG simple parameter access, DP-V1 data record 48 (WEG CFW500 manual §5.2.5; the same text in
//! CFW-11 §4.2.6; error codes CFW500 §5.2.3 / CFW-11 §4.2.3).
//!
//! * DS_Write of **4 bytes** `PNU(U16) value(U16)` (MSB first) changes a parameter; the write
//!   response says whether it worked.
//! * DS_Write of **2 bytes** `PNU(U16)` selects a parameter; the next DS_Read returns its value
//!   as 2 bytes.
//! * Failures are negative DP-V1 responses `DF|DE 80 ec1 00` with the WEG codes of [`Weg48Error`].
//!
//! [`Request::parse`] and [`emit_read_data`] are the codec; [`SimpleAccess`] is optional glue
//! that runs the requests against the same [`ParameterAccess`] table as record 47 and remembers
//! the selected parameter between the write and the read.

use super::param::{Attribute, ErrorValue, Format, ParamAddress, ParamError, ParameterAccess, ValueBlock, ValueWriter};
use crate::dpv1::pdu::{EmitError, ErrorCode1};

/// The DP-V1 data record (index) of WEG's simple access.
pub const RECORD_INDEX: u8 = 48;
/// DS_Write data of a parameter change: PNU, value.
pub const WRITE_LEN: usize = 4;
/// DS_Write data of a parameter selection: PNU.
pub const SELECT_LEN: usize = 2;
/// DS_Read data: the value.
pub const READ_LEN: usize = 2;

/// A record-48 DS_Write.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum Request {
    /// 2 bytes: select `pnu` for the next DS_Read.
    Select {
        /// Parameter number.
        pnu: u16,
    },
    /// 4 bytes: write `value` to `pnu`.
    Write {
        /// Parameter number.
        pnu: u16,
        /// New value.
        value: u16,
    },
}

impl Request {
    /// Decode the DS_Write data. Any length other than 2 or 4 is refused with 0xB7 "incorrect
    /// values for parameter access" (the manual names no code for it; B7 is its general
    /// "request malformed" code, \[M\]).
    pub fn parse(data: &[u8]) -> Result<Request, Weg48Error> {
        match *data {
            [p0, p1] => Ok(Request::Select { pnu: u16::from_be_bytes([p0, p1]) }),
            [p0, p1, v0, v1] => {
                Ok(Request::Write { pnu: u16::from_be_bytes([p0, p1]), value: u16::from_be_bytes([v0, v1]) })
            }
            _ => Err(Weg48Error::InvalidValues),
        }
    }

    /// Emit the DS_Write data (the master's side).
    pub fn emit(&self, out: &mut [u8]) -> Result<usize, EmitError> {
        match *self {
            Request::Select { pnu } => {
                let out = out.get_mut(..SELECT_LEN).ok_or(EmitError::BufferTooSmall { needed: SELECT_LEN })?;
                out.copy_from_slice(&pnu.to_be_bytes());
                Ok(SELECT_LEN)
            }
            Request::Write { pnu, value } => {
                let out = out.get_mut(..WRITE_LEN).ok_or(EmitError::BufferTooSmall { needed: WRITE_LEN })?;
                out[..2].copy_from_slice(&pnu.to_be_bytes());
                out[2..].copy_from_slice(&value.to_be_bytes());
                Ok(WRITE_LEN)
            }
        }
    }
}

/// Emit the DS_Read data: the selected parameter's value, MSB first. Returns 2.
pub fn emit_read_data(value: u16, out: &mut [u8]) -> Result<usize, EmitError> {
    let out = out.get_mut(..READ_LEN).ok_or(EmitError::BufferTooSmall { needed: READ_LEN })?;
    out.copy_from_slice(&value.to_be_bytes());
    Ok(READ_LEN)
}

/// Decode the DS_Read data (the master's side).
pub fn parse_read_data(data: &[u8]) -> Option<u16> {
    match *data {
        [a, b] => Some(u16::from_be_bytes([a, b])),
        _ => None,
    }
}

/// Error_Code_1 values of WEG's DP-V1 parameter access, with the meanings the manual gives
/// (CFW500 §5.2.3; CFW-11 §4.2.3 says the same in Portuguese). Error_Decode is 128 and
/// Error_Code_2 is 0.
///
/// Note: WEG's 0xB0 "invalid slot" and 0xB2 "invalid index" are swapped with respect to the
/// DP-V1 table (0xB0 invalid index, 0xB2 invalid slot; reference §4.2, profichip
/// `DPV1_ERRCL_ACC_INV_INDEX`/`_INV_SLOT`, VACON Table 46). This enum reproduces WEG's codes for
/// WEG compatibility; a router answering other records should use
/// [`ErrorCode1::INVALID_INDEX`] / [`ErrorCode1::INVALID_SLOT`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[repr(u8)]
pub enum Weg48Error {
    /// 0xB0 "access error – invalid slot" (WEG meaning; DP-V1: invalid index).
    InvalidSlot = 0xB0,
    /// 0xB2 "access error – invalid index" (WEG meaning; DP-V1: invalid slot).
    InvalidIndex = 0xB2,
    /// 0xB5 "access error – modification not allowed for the parameter".
    ChangeNotAllowed = 0xB5,
    /// 0xB6 "access error – modification in read-only parameter".
    ReadOnly = 0xB6,
    /// 0xB7 "access error – incorrect values for parameter access".
    InvalidValues = 0xB7,
    /// 0xB8 "access error – invalid parameter number".
    InvalidParameter = 0xB8,
    /// 0xC3 "resource error – response not available for the reading request".
    ResponseNotAvailable = 0xC3,
}

impl Weg48Error {
    /// The Error_Code_1 byte.
    pub const fn error_code1(self) -> ErrorCode1 {
        ErrorCode1(self as u8)
    }

    /// The WEG error for an Error_Code_1 byte, if it is one of the seven.
    pub const fn from_error_code1(code: ErrorCode1) -> Option<Weg48Error> {
        Some(match code.0 {
            0xB0 => Weg48Error::InvalidSlot,
            0xB2 => Weg48Error::InvalidIndex,
            0xB5 => Weg48Error::ChangeNotAllowed,
            0xB6 => Weg48Error::ReadOnly,
            0xB7 => Weg48Error::InvalidValues,
            0xB8 => Weg48Error::InvalidParameter,
            0xC3 => Weg48Error::ResponseNotAvailable,
            _ => return None,
        })
    }

    /// Map a PROFIdrive error value from the parameter table onto WEG's codes \[M\]:
    /// 0x00 → B8; 0x01 → B6; 0x06 setting not permitted, 0x0B no operation priority,
    /// 0x11 operating state → B5; everything else (limits, data type, subindex, …) → B7.
    pub const fn from_error_value(e: ErrorValue) -> Weg48Error {
        match e.0 {
            0x00 => Weg48Error::InvalidParameter,
            0x01 => Weg48Error::ReadOnly,
            0x06 | 0x0B | 0x11 => Weg48Error::ChangeNotAllowed,
            _ => Weg48Error::InvalidValues,
        }
    }
}

impl From<ParamError> for Weg48Error {
    fn from(e: ParamError) -> Self {
        Weg48Error::from_error_value(e.value)
    }
}

/// Record 48 against a [`ParameterAccess`] table: remembers the parameter selected by a 2-byte
/// DS_Write for the following DS_Read(s). Parameters are addressed as attribute 0x10, one
/// element, subindex 0, on the given axis (WEG uses DO-ID 0), format Word.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct SimpleAccess {
    selected: Option<u16>,
}

impl SimpleAccess {
    /// Nothing selected.
    pub const fn new() -> Self {
        SimpleAccess { selected: None }
    }

    /// The parameter a DS_Read would return.
    pub const fn selected(&self) -> Option<u16> {
        self.selected
    }

    /// Handle a record-48 DS_Write. A selection is checked by reading the parameter once (an
    /// unknown or non-16-bit parameter fails now, and leaves nothing selected); a change is
    /// executed at once. `Ok` → positive write response, `Err(e)` → `DF 80 e 00`.
    pub fn on_write(&mut self, data: &[u8], axis: u8, table: &mut impl ParameterAccess) -> Result<(), Weg48Error> {
        match Request::parse(data)? {
            Request::Select { pnu } => {
                self.selected = None;
                read_word(table, axis, pnu)?;
                self.selected = Some(pnu);
                Ok(())
            }
            Request::Write { pnu, value } => {
                let bytes = value.to_be_bytes();
                let block = ValueBlock { format: Format::WORD, count: 1, bytes: &bytes };
                table.write_value(axis, &address(pnu), &block).map_err(Weg48Error::from)
            }
        }
    }

    /// Handle a record-48 DS_Read: the selected parameter's current value (2 bytes into `out`).
    /// Nothing selected → 0xC3 "response not available".
    pub fn on_read(&self, axis: u8, table: &mut impl ParameterAccess, out: &mut [u8]) -> Result<usize, Weg48Error> {
        let pnu = self.selected.ok_or(Weg48Error::ResponseNotAvailable)?;
        let value = read_word(table, axis, pnu)?;
        emit_read_data(value, out).map_err(|_| Weg48Error::InvalidValues)
    }
}

fn address(pnu: u16) -> ParamAddress {
    ParamAddress { attribute: Attribute::Value, elements: 1, pnu, subindex: 0 }
}

fn read_word(table: &mut impl ParameterAccess, axis: u8, pnu: u16) -> Result<u16, Weg48Error> {
    let mut buf = [0u8; 4];
    let mut w = ValueWriter::new(&mut buf);
    table.read_value(axis, &address(pnu), &mut w)?;
    match (w.count(), w.bytes()) {
        (1, &[a, b]) => Ok(u16::from_be_bytes([a, b])),
        // A parameter that is not one 16-bit value cannot be carried by record 48.
        _ => Err(Weg48Error::InvalidValues),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dpv1::pdu::{self, Function, ReadRequest, Response};
    use crate::profile::table::{slots, ParamDef, Table, Type};
    use crate::testkit::{FakeDrive, Refusal};

    /// A CFW500-like drive, as the one fake drive (`testkit::FakeDrive`): P0100 acceleration
    /// time (0..=9999, ×0.1 s), P0002 speed (read-only), P0680 status word (read-only), P0204
    /// "load factory settings" (only 0 / 5 allowed → 0x14), P0299 a 32-bit parameter (not
    /// carried by record 48), P0120 changeable only when stopped ([`running`]).
    const CFW500: &[ParamDef] = &[
        ParamDef::new(2, "Motor speed", Type::U16).read_only().with_default(1800),
        ParamDef::new(100, "Accel. time", Type::U16).limits(0, 9999).with_default(50),
        ParamDef::new(120, "Ramp ref backup", Type::U16),
        ParamDef::new(204, "Load factory", Type::U16),
        ParamDef::new(299, "32-bit param", Type::U32).with_default(70_000),
        ParamDef::new(680, "Status word", Type::U16).read_only().with_default(0x0233),
    ];
    const N: usize = slots(CFW500);

    /// P0204 takes 0 or 5 only (0x14 "value impermissible").
    fn factory_settings(_: &Table<N>, pnu: u16, v: i64) -> Result<(), ErrorValue> {
        match pnu {
            204 if v != 0 && v != 5 => Err(ErrorValue::VALUE_IMPERMISSIBLE),
            _ => Ok(()),
        }
    }

    fn cfw500() -> FakeDrive<N> {
        FakeDrive::with_table(Table::new(CFW500)).on_axis(0).rule(factory_settings).without_descriptions()
    }

    /// The motor runs: P0120 is refused with 0x11 "not executable".
    fn running(t: &mut FakeDrive<N>) {
        t.refuse = Some(Refusal { pnu: Some(120), error: ErrorValue::NOT_EXECUTABLE });
    }

    #[test]
    fn codes_as_the_manual_states() {
        // CFW500 §5.2.3 / CFW-11 §4.2.3 Error Code 1 list.
        for (e, code) in [
            (Weg48Error::InvalidSlot, 0xB0),
            (Weg48Error::InvalidIndex, 0xB2),
            (Weg48Error::ChangeNotAllowed, 0xB5),
            (Weg48Error::ReadOnly, 0xB6),
            (Weg48Error::InvalidValues, 0xB7),
            (Weg48Error::InvalidParameter, 0xB8),
            (Weg48Error::ResponseNotAvailable, 0xC3),
        ] {
            assert_eq!(e.error_code1(), ErrorCode1(code));
            assert_eq!(Weg48Error::from_error_code1(ErrorCode1(code)), Some(e));
        }
        assert_eq!(Weg48Error::from_error_code1(ErrorCode1::INVALID_SLOT), Some(Weg48Error::InvalidIndex));
        assert_eq!(Weg48Error::from_error_code1(ErrorCode1(0xB1)), None);
    }

    #[test]
    fn parse_and_emit() {
        // Write P0100 = 85 (8.5 s): 00 64 00 55 (MSB first, CFW500 §5.2.5).
        assert_eq!(Request::parse(&[0x00, 0x64, 0x00, 0x55]), Ok(Request::Write { pnu: 100, value: 85 }));
        assert_eq!(Request::parse(&[0x02, 0xA8]), Ok(Request::Select { pnu: 680 }));
        for bad in [&[][..], &[1], &[1, 2, 3], &[1, 2, 3, 4, 5]] {
            assert_eq!(Request::parse(bad), Err(Weg48Error::InvalidValues));
        }
        let mut out = [0u8; 4];
        assert_eq!(Request::Write { pnu: 100, value: 85 }.emit(&mut out), Ok(4));
        assert_eq!(out, [0x00, 0x64, 0x00, 0x55]);
        assert_eq!(Request::Select { pnu: 680 }.emit(&mut out), Ok(2));
        assert_eq!(&out[..2], &[0x02, 0xA8]);
        assert_eq!(emit_read_data(0x0233, &mut out), Ok(2));
        assert_eq!(&out[..2], &[0x02, 0x33]);
        assert_eq!(parse_read_data(&out[..2]), Some(0x0233));
        assert_eq!(emit_read_data(1, &mut [0u8; 1]), Err(EmitError::BufferTooSmall { needed: 2 }));
    }

    /// The whole record-48 exchange at the DP-V1 level: DS_Write select, DS_Read value; DS_Write
    /// change; the negative responses with WEG's codes.
    #[test]
    fn session_on_slot0_index48() {
        let mut t = cfw500();
        let mut ch = SimpleAccess::new();
        let mut buf = [0u8; pdu::MAX_PDU_LEN];

        // A read before any selection: DE 80 C3 00.
        let Ok(pdu::Request::Read(ReadRequest { slot: 0, index: 48, length: 240 })) = pdu::parse(&[0x5E, 0, 48, 240])
        else {
            panic!()
        };
        let e = ch.on_read(0, &mut t, &mut buf[4..]).unwrap_err();
        let n = Response::error(Function::Read, e.error_code1()).emit(&mut buf).unwrap();
        assert_eq!(&buf[..n], &[0xDE, 0x80, 0xC3, 0x00]);

        // Select P0680, then read it: 5E 00 30 02 02 33.
        let Ok(pdu::Request::Write(w)) = pdu::parse(&[0x5F, 0, 48, 2, 0x02, 0xA8]) else { panic!() };
        assert_eq!(ch.on_write(w.data, 0, &mut t), Ok(()));
        let n = Response::Write { slot: 0, index: 48, length: 2 }.emit(&mut buf).unwrap();
        assert_eq!(&buf[..n], &[0x5F, 0x00, 0x30, 0x02]);
        let m = ch.on_read(0, &mut t, &mut buf[4..]).unwrap();
        let n = pdu::emit_data_header(&mut buf, Function::Read, 0, 48, m).unwrap();
        assert_eq!(&buf[..n], &[0x5E, 0x00, 0x30, 0x02, 0x02, 0x33]);

        // Change P0100 to 85, read it back.
        assert_eq!(ch.on_write(&[0x00, 0x64, 0x00, 0x55], 0, &mut t), Ok(()));
        assert_eq!(ch.on_write(&[0x00, 0x64], 0, &mut t), Ok(()));
        let m = ch.on_read(0, &mut t, &mut buf).unwrap();
        assert_eq!(&buf[..m], &[0x00, 0x55]);

        // The error codes, as negative write responses DF 80 ec1 00.
        let cases: [(&[u8], Weg48Error); 8] = [
            (&[0x00, 0x64, 0x27, 0x10], Weg48Error::InvalidValues), // 10000 > 9999 (0x02)
            (&[0x00, 0x02, 0x00, 0x00], Weg48Error::ReadOnly),      // P0002 read-only (0x01)
            (&[0x03, 0xE7, 0x00, 0x00], Weg48Error::InvalidParameter), // P0999 missing (0x00)
            (&[0x03, 0xE7], Weg48Error::InvalidParameter),          // select P0999
            (&[0x01, 0x2B], Weg48Error::InvalidValues),             // select P0299: 32 bits
            (&[0x00, 0xCC, 0x00, 0x07], Weg48Error::InvalidValues), // P0204 = 7 (0x14)
            (&[0x00, 0x64, 0x00], Weg48Error::InvalidValues),       // 3 bytes
            (&[0x00, 0x64, 0x00, 0x55, 0x00], Weg48Error::InvalidValues),
        ];
        for (data, expected) in cases {
            let e = ch.on_write(data, 0, &mut t).unwrap_err();
            assert_eq!(e, expected, "{data:02X?}");
            Response::error(Function::Write, e.error_code1()).emit(&mut buf).unwrap();
            assert_eq!(&buf[..4], &[0xDF, 0x80, expected as u8, 0x00]);
        }
        // A failed selection leaves nothing selected.
        assert_eq!(ch.selected(), None);
        assert_eq!(ch.on_read(0, &mut t, &mut buf), Err(Weg48Error::ResponseNotAvailable));

        // Changing while running: 0x11 → B5 "modification not allowed".
        running(&mut t);
        assert_eq!(ch.on_write(&[0x00, 0x78, 0x00, 0x01], 0, &mut t), Err(Weg48Error::ChangeNotAllowed));
    }

    #[test]
    fn error_value_mapping() {
        use ErrorValue as V;
        for (v, w) in [
            (V::IMPERMISSIBLE_PARAMETER_NUMBER, Weg48Error::InvalidParameter),
            (V::VALUE_CANNOT_BE_CHANGED, Weg48Error::ReadOnly),
            (V::LIMIT_EXCEEDED, Weg48Error::InvalidValues),
            (V::SETTING_NOT_PERMITTED, Weg48Error::ChangeNotAllowed),
            (V::NO_OPERATION_PRIORITY, Weg48Error::ChangeNotAllowed),
            (V::NOT_EXECUTABLE, Weg48Error::ChangeNotAllowed),
            (V::VALUE_IMPERMISSIBLE, Weg48Error::InvalidValues),
            (V::INCORRECT_DATA_TYPE, Weg48Error::InvalidValues),
        ] {
            assert_eq!(Weg48Error::from_error_value(v), w);
        }
    }

    proptest::proptest! {
        #[test]
        fn roundtrip_and_never_panics(pnu: u16, value: u16, bytes in proptest::collection::vec(proptest::num::u8::ANY, 0..8)) {
            let mut out = [0u8; 4];
            for r in [Request::Select { pnu }, Request::Write { pnu, value }] {
                let n = r.emit(&mut out).unwrap();
                proptest::prop_assert_eq!(Request::parse(&out[..n]), Ok(r));
            }
            let mut t = cfw500();
            let mut ch = SimpleAccess::new();
            let _ = ch.on_write(&bytes, 0, &mut t);
            let _ = ch.on_read(0, &mut t, &mut out);
        }
    }
}
