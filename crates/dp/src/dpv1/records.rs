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

    /// The application relation the next accesses come from: 0 = MSAC_C1, 1 + n = MSAC_C2
    /// connection n. Records with a per-relation state (PROFIdrive record 47: each master
    /// fetches its own response) keep them apart by it.
    fn set_relation(&mut self, relation: u8) {
        let _ = relation;
    }
}

/// The relation number of MSAC_C1.
pub const RELATION_C1: u8 = 0;

/// The relation number of MSAC_C2 connection `n`.
pub const fn relation_c2(n: usize) -> u8 {
    1 + n as u8
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
