//! The drive's data records at slot 0, reached by DS_Read / DS_Write over MSAC_C1 or MSAC_C2:
//!
//! | index | record | manual |
//! |---|---|---|
//! | 47 | PROFIdrive base-mode parameter access: DS_Write carries the request, DS_Read fetches the response once | OPTE3/E5 §6.4, CFW500 §5.2.2, CFW-11 §4.2 |
//! | 48 | WEG simple access: 4 bytes = write, 2 bytes = select for the next read | CFW500 §5.2.3 |
//!
//! Errors (DP-V1 Error_Code_1): slot ≠ 0 → 0xB2 invalid slot; another index → 0xB0 invalid
//! index; a structurally wrong parameter request → 0xB7 at the DS_Write (VACON Table 46,
//! CFW500 §5.2.4); DS_Read of record 47 without a response waiting → 0xB5 state conflict
//! (reference §5.1: "not ready"; also after the response was fetched — it is readable once);
//! a DS_Read shorter than the response → 0xB1 (the response stays for a read with room).

use super::param::{respond, ParamRequest, ParameterAccess, MAX_LEN};
use super::weg48::SimpleAccess;
use crate::dpv1::pdu::ErrorCode1;
use crate::dpv1::records::RecordHandler;
use crate::time::Instant;

/// PROFIdrive parameter access record.
pub const INDEX_PROFIDRIVE: u8 = 47;
/// WEG simple access record.
pub const INDEX_WEG_SIMPLE: u8 = 48;
/// The axis WEG's simple access addresses (DO-ID 0).
const WEG_AXIS: u8 = 0;

/// Records 47 and 48 over one parameter table.
#[derive(Debug, Clone)]
pub struct DriveRecords {
    response: [u8; MAX_LEN],
    response_len: usize,
    weg: SimpleAccess,
}

impl Default for DriveRecords {
    fn default() -> Self {
        Self::new()
    }
}

impl DriveRecords {
    /// No response waiting, nothing selected.
    pub const fn new() -> Self {
        DriveRecords { response: [0; MAX_LEN], response_len: 0, weg: SimpleAccess::new() }
    }

    /// Forget a waiting response (the relation that carried the request ended).
    pub fn reset(&mut self) {
        self.response_len = 0;
    }

    /// This handler bound to a parameter table for one access.
    pub fn with<'a, T: ParameterAccess>(&'a mut self, table: &'a mut T) -> Bound<'a, T> {
        Bound { records: self, table }
    }
}

/// [`DriveRecords`] together with the parameter table it serves: the [`RecordHandler`].
pub struct Bound<'a, T> {
    records: &'a mut DriveRecords,
    table: &'a mut T,
}

impl<T: ParameterAccess> RecordHandler for Bound<'_, T> {
    fn read(&mut self, _now: Instant, slot: u8, index: u8, out: &mut [u8]) -> Result<usize, ErrorCode1> {
        if slot != 0 {
            return Err(ErrorCode1::INVALID_SLOT);
        }
        let r = &mut *self.records;
        match index {
            INDEX_PROFIDRIVE => {
                let n = r.response_len;
                if n == 0 {
                    return Err(ErrorCode1::STATE_CONFLICT);
                }
                if out.len() < n {
                    return Err(ErrorCode1::WRITE_LENGTH_ERROR);
                }
                out[..n].copy_from_slice(&r.response[..n]);
                r.response_len = 0;
                Ok(n)
            }
            INDEX_WEG_SIMPLE => r.weg.on_read(WEG_AXIS, self.table, out).map_err(|e| e.error_code1()),
            _ => Err(ErrorCode1::INVALID_INDEX),
        }
    }

    fn write(&mut self, _now: Instant, slot: u8, index: u8, data: &[u8]) -> Result<(), ErrorCode1> {
        if slot != 0 {
            return Err(ErrorCode1::INVALID_SLOT);
        }
        let r = &mut *self.records;
        match index {
            INDEX_PROFIDRIVE => {
                let req = ParamRequest::parse(data).map_err(|e| e.error_code1())?;
                r.response_len = respond(&req, self.table, &mut r.response);
                Ok(())
            }
            INDEX_WEG_SIMPLE => r.weg.on_write(data, WEG_AXIS, self.table).map_err(|e| e.error_code1()),
            _ => Err(ErrorCode1::INVALID_INDEX),
        }
    }
}
