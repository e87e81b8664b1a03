//! Data records: what a DS_Read / DS_Write (MSAC_C1 or MSAC_C2) reaches (reference §4.2).
//!
//! The DP-V1 layer defines [`RecordHandler`]; the profile layer implements it (PROFIdrive
//! parameter access at slot 0 / index 47, WEG simple access at index 48, …). Errors are the
//! DP-V1 Error_Code_1 values ([`ErrorCode1`]): the channel turns them into the error PDU
//! `function | 0x80, 0x80, Error_Code_1, 0x00`.

use super::pdu::ErrorCode1;
use crate::time::Instant;

/// Read and write data records by slot and index.
pub trait RecordHandler {
    /// DS_Read: write at most `out.len()` bytes (the master's length, ≤ 240) of record
    /// `slot`/`index` into `out` and return how many.
    fn read(&mut self, now: Instant, slot: u8, index: u8, out: &mut [u8]) -> Result<usize, ErrorCode1>;
    /// DS_Write of `data` to record `slot`/`index`.
    fn write(&mut self, now: Instant, slot: u8, index: u8, data: &[u8]) -> Result<(), ErrorCode1>;
}

/// A handler without records: every access is "invalid slot" (0xB2).
#[derive(Debug, Default, Clone, Copy)]
pub struct NoRecords;

impl RecordHandler for NoRecords {
    fn read(&mut self, _: Instant, _: u8, _: u8, _: &mut [u8]) -> Result<usize, ErrorCode1> {
        Err(ErrorCode1::INVALID_SLOT)
    }
    fn write(&mut self, _: Instant, _: u8, _: u8, _: &[u8]) -> Result<(), ErrorCode1> {
        Err(ErrorCode1::INVALID_SLOT)
    }
}
