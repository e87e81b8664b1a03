//! Identification & Maintenance (I&M0 … I&M4) over DP-V1 (reference §4.7; PROFIBUS Profile
//! Guidelines Part 1 "Identification & Maintenance Functions", the CALL service of
//! IEC 61158-6-3; ABB FPBA-01 manual p. 128 for the bytes on the wire).
//!
//! I&M is reached through data record **slot 0, index 255** with the *I&M call header*
//! `08 00 FI_Index` (Extended_Function_Num 0x08 = "call", a reserved byte, FI_Index U16 BE,
//! 65000 = I&M0 … 65004 = I&M4):
//!
//! ```text
//! DS_Write 5F 00 FF 04 | 08 00 FD E8            select I&M0 for the next read  → 5F 00 FF 04
//! DS_Read  5E 00 FF F0                          → 5E 00 FF 44 | 08 00 FD E8 | 64-byte I&M0
//! DS_Write 5F 00 FF 44 | 08 00 FD E9 | 64 bytes write I&M1 (header + 54 bytes)  → 5F 00 FF 44
//! ```
//!
//! Every I&M record is 64 bytes: a 10-byte manufacturer-specific header (zeros here; ignored
//! on a write) and 54 bytes of content. I&M0 (read only):
//!
//! | bytes | field | here |
//! |---|---|---|
//! | 0..10 | header | zeros |
//! | 10..12 | MANUFACTURER_ID | [`ImDevice::manufacturer_id`] (this card: `card::IM_MANUFACTURER_ID`) |
//! | 12..32 | ORDER_ID (visible string, blank-padded) | [`ImDevice::order_id`] (`card::IM_ORDER_ID`) |
//! | 32..48 | SERIAL_NUMBER (visible string) | from the drive (DPM `IDENT`), else blanks |
//! | 48..50 | HARDWARE_REVISION | from the drive, else [`ImDevice::hardware_revision`] (`card::IM_HARDWARE_REVISION`) |
//! | 50..54 | SOFTWARE_REVISION `V` x y z | [`ImDevice::software_revision`] (`card::IM_SOFTWARE_REVISION`) |
//! | 54..56 | REVISION_COUNTER | 0 |
//! | 56..58 | PROFILE_ID | 0x3A00 PROFIdrive |
//! | 58..60 | PROFILE_SPECIFIC_TYPE | 0 |
//! | 60..62 | IM_VERSION | 0x0101 (1.1) |
//! | 62..64 | IM_SUPPORTED | [`IM_SUPPORTED`]: I&M1–I&M4 |
//!
//! I&M1 TAG_FUNCTION (32) and TAG_LOCATION (22); I&M2 INSTALLATION_DATE (16, "YYYY-MM-DD
//! hh:mm") and 38 reserved bytes; I&M3 DESCRIPTOR (54); I&M4 SIGNATURE (54). I&M1–3 are blanks (0x20) and
//! I&M4 zeros until written (as the ABB adapters ship them). They are kept in RAM here
//! ([`Im::data`]); [`Im::take_changed`] hands a written set to the platform, which stores it in
//! its power-cut-safe journal (`pbcard::store::Journal`, the same one as the station address:
//! F411 flash, the soft slave's `--state` file; QEMU keeps them in RAM) and gives it back at
//! boot ([`Im::set_data`]).
//!
//! **Errors** (the error PDU `DE|DF 80 Error_Code_1 00`; the guideline's classes, our choice of
//! codes where it leaves one open):
//!
//! | situation | answer |
//! |---|---|
//! | index 255 on a slot other than 0 | 0xB2 invalid slot |
//! | DS_Write shorter than the 4-byte call header | 0xB1 write length error |
//! | Extended_Function_Num ≠ 0x08 or reserved byte ≠ 0 | 0xB8 invalid parameter (our choice, UNVERIFIED: the reference names the class only) |
//! | FI_Index outside 65000..=65004 (also the reserved 65005..65199) | 0xB0 invalid index |
//! | a write (call header + data) to I&M0 | 0xB6 access denied |
//! | a write to I&M1–4 with other than 64 data bytes | 0xB1 write length error |
//! | DS_Read without a preceding call on this relation | 0xB5 state conflict |
//! | DS_Read shorter than 68 bytes | 0xB1 (the selection stays for a read with room, as record 47) |
//!
//! A call selects the record per relation (MSAC_C1, each MSAC_C2 connection): each master
//! reads what it asked for; the selection stays for further reads until the next call or the
//! end of the relation ([`Im::end_relation`]).

use super::pdu::ErrorCode1;
use super::records::RecordHandler;
use crate::time::Instant;

/// The record index of the I&M call (slot 0).
pub const INDEX: u8 = 255;
/// Extended_Function_Num of the CALL service.
pub const CALL: u8 = 0x08;
/// Length of the call header `08 00 FI_Index`.
pub const CALL_HEADER_LEN: usize = 4;
/// FI_Index of I&M0.
pub const FI_IM0: u16 = 65000;
/// FI_Index of I&M4 (the last one this card has).
pub const FI_IM4: u16 = 65004;
/// Bytes of every I&M record.
pub const RECORD_LEN: usize = 64;
/// Bytes of the manufacturer-specific header of a record.
pub const HEADER_LEN: usize = 10;
/// Content bytes of I&M1 … I&M4 (what is stored).
pub const CONTENT_LEN: usize = RECORD_LEN - HEADER_LEN;
/// IM_SUPPORTED: bit 0 = I&M1 … bit 3 = I&M4 (ABB FPBA-01 p. 128: "3 = I&M0, I&M1 and I&M2").
/// UNVERIFIED against the PI I&M guideline: the reference (§4.7) gives only "bit map of
/// I&M1–4", derived from the field list.
pub const IM_SUPPORTED: u16 = 0x000F;
/// IM_VERSION 1.1.
pub const IM_VERSION: u16 = 0x0101;
/// PROFILE_ID of PROFIdrive.
pub const PROFILE_ID_PROFIDRIVE: u16 = 0x3A00;
/// Relations with a call selection of their own: MSAC_C1 and every MSAC_C2 connection, as
/// many as the protocol allows (49 MSAC_C2 SAPs, [`super::c2::C2`]), so any product's GSD
/// `C2_Max_Count_Channels` fits.
pub const RELATIONS: usize = 1 + super::c2::HIGHEST_SAP as usize + 1;

/// The product's own I&M0 values ([`im0`]): what the GSD and the product's order data say
/// (this card: `card::IM`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ImDevice {
    /// I&M0 MANUFACTURER_ID: the PI vendor ID.
    pub manufacturer_id: u16,
    /// I&M0 ORDER_ID (≤ 20 characters, blank-padded; longer is cut): the GSD's `OrderNumber`.
    pub order_id: &'static str,
    /// I&M0 HARDWARE_REVISION when the drive reports none (the GSD's `Hardware_Release`).
    pub hardware_revision: u16,
    /// I&M0 SOFTWARE_REVISION: `V` + major, minor, patch (the GSD's `Software_Release`).
    pub software_revision: [u8; 4],
    /// I&M0 PROFILE_ID: the application profile the device follows (reference §4.7;
    /// [`PROFILE_ID_PROFIDRIVE`] 0x3A00 for a drive, 0xF600 a generic device).
    pub profile_id: u16,
}

impl ImDevice {
    /// Nothing known from the drive: blank serial number, the product's hardware revision.
    pub const fn unknown_ident(&self) -> DeviceIdent {
        DeviceIdent { serial_number: [b' '; 16], hardware_revision: self.hardware_revision }
    }
}

/// I&M1 … I&M4 content (54 bytes each, without the header): what is writable and stored.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ImData {
    /// `records[0]` = I&M1 … `records[3]` = I&M4.
    pub records: [[u8; CONTENT_LEN]; 4],
}

impl ImData {
    /// Bytes of [`Self::encode`].
    pub const LEN: usize = 4 * CONTENT_LEN;

    /// As shipped: I&M1–3 blanks, I&M4 zeros.
    pub const DEFAULT: ImData =
        ImData { records: [[b' '; CONTENT_LEN], [b' '; CONTENT_LEN], [b' '; CONTENT_LEN], [0; CONTENT_LEN]] };

    /// I&M1 … I&M4 one after the other.
    pub fn encode(&self) -> [u8; Self::LEN] {
        let mut b = [0u8; Self::LEN];
        for (i, r) in self.records.iter().enumerate() {
            b[i * CONTENT_LEN..(i + 1) * CONTENT_LEN].copy_from_slice(r);
        }
        b
    }

    /// From [`Self::encode`]'s bytes.
    pub fn decode(b: &[u8; Self::LEN]) -> ImData {
        let mut d = ImData::DEFAULT;
        for (i, r) in d.records.iter_mut().enumerate() {
            r.copy_from_slice(&b[i * CONTENT_LEN..(i + 1) * CONTENT_LEN]);
        }
        d
    }
}

impl Default for ImData {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// What the drive tells the card about the device for I&M0 (DPM `IDENT`): the serial number
/// and hardware revision of the drive the card sits in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DeviceIdent {
    /// SERIAL_NUMBER, visible string (blank-padded; blanks = not known).
    pub serial_number: [u8; 16],
    /// HARDWARE_REVISION.
    pub hardware_revision: u16,
}

/// The I&M0 record of the product `device` for `ident`.
pub fn im0(device: &ImDevice, ident: &DeviceIdent) -> [u8; RECORD_LEN] {
    let mut r = [0u8; RECORD_LEN];
    r[10..12].copy_from_slice(&device.manufacturer_id.to_be_bytes());
    r[12..32].fill(b' ');
    let n = device.order_id.len().min(20);
    r[12..12 + n].copy_from_slice(&device.order_id.as_bytes()[..n]);
    r[32..48].copy_from_slice(&ident.serial_number);
    r[48..50].copy_from_slice(&ident.hardware_revision.to_be_bytes());
    r[50..54].copy_from_slice(&device.software_revision);
    // REVISION_COUNTER 54..56 = 0; PROFILE_SPECIFIC_TYPE 58..60 = 0.
    r[56..58].copy_from_slice(&device.profile_id.to_be_bytes());
    r[60..62].copy_from_slice(&IM_VERSION.to_be_bytes());
    r[62..64].copy_from_slice(&IM_SUPPORTED.to_be_bytes());
    r
}

/// Why an I&M call was refused (each maps to one Error_Code_1, module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[non_exhaustive]
pub enum ImError {
    /// Index 255 on a slot other than 0.
    Slot(u8),
    /// Fewer than 4 bytes, or a record write of other than 64 data bytes.
    Length(usize),
    /// Not the CALL header `08 00`.
    NotACall,
    /// FI_Index this card does not have.
    FiIndex(u16),
    /// A write to I&M0.
    ReadOnly,
    /// A read with no call before it.
    NoCall,
    /// A read with less room than the 68-byte answer.
    ReadTooShort(usize),
}

impl ImError {
    /// The DP-V1 Error_Code_1 of the answer.
    pub const fn error_code1(self) -> ErrorCode1 {
        match self {
            ImError::Slot(_) => ErrorCode1::INVALID_SLOT,
            ImError::Length(_) | ImError::ReadTooShort(_) => ErrorCode1::WRITE_LENGTH_ERROR,
            ImError::NotACall => ErrorCode1::INVALID_PARAMETER,
            ImError::FiIndex(_) => ErrorCode1::INVALID_INDEX,
            ImError::ReadOnly => ErrorCode1::ACCESS_DENIED,
            ImError::NoCall => ErrorCode1::STATE_CONFLICT,
        }
    }
}

/// A checked I&M call (the data of a DS_Write to index 255).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Call<'a> {
    /// FI_Index, 65000..=65004.
    pub fi_index: u16,
    /// Record data after the call header (empty = a read selection; else exactly 64 bytes).
    pub data: &'a [u8],
}

impl<'a> Call<'a> {
    /// Parse and check the data of a DS_Write to index 255.
    pub fn parse(bytes: &'a [u8]) -> Result<Call<'a>, ImError> {
        if bytes.len() < CALL_HEADER_LEN {
            return Err(ImError::Length(bytes.len()));
        }
        if bytes[0] != CALL || bytes[1] != 0 {
            return Err(ImError::NotACall);
        }
        let fi_index = u16::from_be_bytes([bytes[2], bytes[3]]);
        if !(FI_IM0..=FI_IM4).contains(&fi_index) {
            return Err(ImError::FiIndex(fi_index));
        }
        let data = &bytes[CALL_HEADER_LEN..];
        if !data.is_empty() {
            if fi_index == FI_IM0 {
                return Err(ImError::ReadOnly);
            }
            if data.len() != RECORD_LEN {
                return Err(ImError::Length(bytes.len()));
            }
        }
        Ok(Call { fi_index, data })
    }
}

/// Counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct ImStats {
    /// Calls accepted.
    pub calls: u32,
    /// Records written (I&M1–4).
    pub writes: u32,
    /// Calls and reads refused.
    pub errors: u32,
}

/// The card's I&M function: the records, the drive's identity and each relation's selection.
#[derive(Debug, Clone)]
pub struct Im {
    device: &'static ImDevice,
    data: ImData,
    ident: DeviceIdent,
    selected: [Option<u16>; RELATIONS],
    relation: u8,
    changed: bool,
    stats: ImStats,
}

impl Im {
    /// Records as shipped, no identity from the drive, nothing selected, for the product
    /// `device`.
    pub const fn new(device: &'static ImDevice) -> Self {
        Im {
            device,
            data: ImData::DEFAULT,
            ident: device.unknown_ident(),
            selected: [None; RELATIONS],
            relation: 0,
            changed: false,
            stats: ImStats { calls: 0, writes: 0, errors: 0 },
        }
    }

    /// I&M1–4 as they are now.
    pub fn data(&self) -> &ImData {
        &self.data
    }
    /// I&M1–4 from the platform's store (at boot); not reported as a change.
    pub fn set_data(&mut self, data: ImData) {
        self.data = data;
    }
    /// The drive's serial number and hardware revision for I&M0; a hardware revision 0 (not
    /// known to the drive) reads as the device's own ([`ImDevice::hardware_revision`]).
    pub fn set_ident(&mut self, ident: DeviceIdent) {
        let hardware_revision =
            if ident.hardware_revision == 0 { self.device.hardware_revision } else { ident.hardware_revision };
        self.ident = DeviceIdent { hardware_revision, ..ident };
    }
    /// The identity I&M0 reports.
    pub fn ident(&self) -> &DeviceIdent {
        &self.ident
    }
    /// I&M1–4 once after a master wrote one of them (the platform stores them), else `None`.
    pub fn take_changed(&mut self) -> Option<ImData> {
        core::mem::take(&mut self.changed).then_some(self.data)
    }
    /// Counters.
    pub fn stats(&self) -> ImStats {
        self.stats
    }
    /// The relation the next access comes from ([`RecordHandler::set_relation`]).
    pub fn set_relation(&mut self, relation: u8) {
        self.relation = relation;
    }
    /// The relation ended (MSAC_C1 left data exchange, an MSAC_C2 connection closed): its call
    /// is forgotten.
    pub fn end_relation(&mut self, relation: u8) {
        if let Some(s) = self.selected.get_mut(relation as usize) {
            *s = None;
        }
    }

    fn record(&self, fi_index: u16) -> [u8; RECORD_LEN] {
        match fi_index {
            FI_IM0 => im0(self.device, &self.ident),
            fi => {
                let mut r = [0u8; RECORD_LEN];
                let i = ((fi - FI_IM0 - 1) as usize).min(3);
                r[HEADER_LEN..].copy_from_slice(&self.data.records[i]);
                r
            }
        }
    }

    fn fail<T>(&mut self, e: ImError) -> Result<T, ImError> {
        self.stats.errors = self.stats.errors.wrapping_add(1);
        Err(e)
    }

    /// DS_Write to `slot` / index 255: an I&M call.
    pub fn write(&mut self, slot: u8, bytes: &[u8]) -> Result<(), ImError> {
        if slot != 0 {
            return self.fail(ImError::Slot(slot));
        }
        let call = match Call::parse(bytes) {
            Ok(c) => c,
            Err(e) => return self.fail(e),
        };
        if !call.data.is_empty() {
            let i = (call.fi_index - FI_IM0 - 1) as usize;
            let mut content = [0u8; CONTENT_LEN];
            content.copy_from_slice(&call.data[HEADER_LEN..]);
            if self.data.records[i] != content {
                self.data.records[i] = content;
                self.changed = true;
            }
            self.stats.writes = self.stats.writes.wrapping_add(1);
        }
        self.stats.calls = self.stats.calls.wrapping_add(1);
        let rel = (self.relation as usize).min(RELATIONS - 1);
        self.selected[rel] = Some(call.fi_index);
        Ok(())
    }

    /// DS_Read of `slot` / index 255 into `out` (the master's length): the call header of the
    /// selected record and the record.
    pub fn read(&mut self, slot: u8, out: &mut [u8]) -> Result<usize, ImError> {
        if slot != 0 {
            return self.fail(ImError::Slot(slot));
        }
        let rel = (self.relation as usize).min(RELATIONS - 1);
        let Some(fi) = self.selected[rel] else { return self.fail(ImError::NoCall) };
        let n = CALL_HEADER_LEN + RECORD_LEN;
        if out.len() < n {
            return self.fail(ImError::ReadTooShort(out.len()));
        }
        out[..2].copy_from_slice(&[CALL, 0]);
        out[2..4].copy_from_slice(&fi.to_be_bytes());
        out[4..n].copy_from_slice(&self.record(fi));
        Ok(n)
    }

    /// `inner` with I&M in front of it at index 255: the [`RecordHandler`] the DP-V1 services
    /// work on.
    pub fn with<'a, R: RecordHandler>(&'a mut self, inner: &'a mut R) -> WithIm<'a, R> {
        WithIm { im: self, inner }
    }
}

/// [`Im`] in front of another record handler (every index but 255 goes to it).
pub struct WithIm<'a, R> {
    im: &'a mut Im,
    inner: &'a mut R,
}

impl<R: RecordHandler> RecordHandler for WithIm<'_, R> {
    fn read(&mut self, now: Instant, slot: u8, index: u8, out: &mut [u8]) -> Result<usize, ErrorCode1> {
        if index == INDEX {
            return self.im.read(slot, out).map_err(ImError::error_code1);
        }
        self.inner.read(now, slot, index, out)
    }

    fn write(&mut self, now: Instant, slot: u8, index: u8, data: &[u8]) -> Result<(), ErrorCode1> {
        if index == INDEX {
            return self.im.write(slot, data).map_err(ImError::error_code1);
        }
        self.inner.write(now, slot, index, data)
    }

    fn set_relation(&mut self, relation: u8) {
        self.im.set_relation(relation);
        self.inner.set_relation(relation);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dpv1::records::NoRecords;
    use crate::test_card;
    use std::vec::Vec;

    fn call(fi: u16, data: &[u8]) -> Vec<u8> {
        let mut v = vec![CALL, 0];
        v.extend_from_slice(&fi.to_be_bytes());
        v.extend_from_slice(data);
        v
    }

    #[test]
    fn im0_layout() {
        let ident = DeviceIdent { serial_number: *b"SN-0001         ", hardware_revision: 3 };
        let r = im0(&test_card::IM, &ident);
        assert_eq!(&r[..10], &[0; 10], "manufacturer-specific header");
        assert_eq!(&r[10..12], &test_card::IM_MANUFACTURER_ID.to_be_bytes());
        assert_eq!(&r[12..19], b"ODC-PB1");
        assert!(r[19..32].iter().all(|&b| b == b' '), "ORDER_ID blank-padded");
        assert_eq!(&r[32..48], b"SN-0001         ");
        assert_eq!(&r[48..50], &[0, 3]);
        assert_eq!(r[50], b'V', "SOFTWARE_REVISION prefix");
        assert_eq!(&r[54..56], &[0, 0], "REVISION_COUNTER");
        assert_eq!(&r[56..58], &[0x3A, 0x00], "PROFILE_ID PROFIdrive");
        assert_eq!(&r[58..60], &[0, 0]);
        assert_eq!(&r[60..62], &[0x01, 0x01], "IM_VERSION 1.1");
        assert_eq!(&r[62..64], &[0x00, 0x0F], "IM_SUPPORTED I&M1-4");
    }

    #[test]
    fn call_then_read_per_relation() {
        let mut im = Im::new(&test_card::IM);
        let mut out = [0u8; 240];
        assert_eq!(im.read(0, &mut out), Err(ImError::NoCall));
        im.write(0, &[0x08, 0x00, 0xFD, 0xE8]).unwrap();
        let n = im.read(0, &mut out).unwrap();
        assert_eq!(n, 68);
        assert_eq!(&out[..4], &[0x08, 0x00, 0xFD, 0xE8]);
        assert_eq!(&out[4..68], &im0(&test_card::IM, &test_card::IM.unknown_ident()));
        // Read again: the selection stays.
        assert_eq!(im.read(0, &mut out), Ok(68));
        // Another relation has made no call.
        im.set_relation(1);
        assert_eq!(im.read(0, &mut out), Err(ImError::NoCall));
        im.set_relation(0);
        im.end_relation(0);
        assert_eq!(im.read(0, &mut out), Err(ImError::NoCall));
    }

    #[test]
    fn write_im1_to_im4() {
        let mut im = Im::new(&test_card::IM);
        let mut out = [0u8; 68];
        for fi in 65001..=65004u16 {
            let mut rec = [0xEEu8; RECORD_LEN];
            rec[HEADER_LEN..].iter_mut().enumerate().for_each(|(i, b)| *b = (i as u8) ^ fi as u8);
            im.write(0, &call(fi, &rec)).unwrap();
            assert_eq!(im.read(0, &mut out), Ok(68));
            assert_eq!(&out[2..4], &fi.to_be_bytes());
            assert_eq!(&out[4..14], &[0; 10], "the header is not kept");
            assert_eq!(&out[14..68], &rec[HEADER_LEN..]);
        }
        let stored = im.take_changed().expect("changed");
        assert_eq!(im.take_changed(), None, "reported once");
        assert_eq!(stored, *im.data());
        assert_eq!(ImData::decode(&stored.encode()), stored);
        // The same content again is no change.
        im.write(0, &call(65001, &[&[0u8; 10][..], &stored.records[0]].concat())).unwrap();
        assert_eq!(im.take_changed(), None);
        // Defaults: I&M1 blanks, I&M4 zeros.
        let mut fresh = Im::new(&test_card::IM);
        fresh.write(0, &call(65001, &[])).unwrap();
        fresh.read(0, &mut out).unwrap();
        assert!(out[14..68].iter().all(|&b| b == b' '));
        fresh.write(0, &call(65004, &[])).unwrap();
        fresh.read(0, &mut out).unwrap();
        assert!(out[14..68].iter().all(|&b| b == 0));
    }

    #[test]
    fn errors_are_the_guidelines() {
        let mut im = Im::new(&test_card::IM);
        let mut out = [0u8; 240];
        let e = |r: Result<(), ImError>| r.map_err(ImError::error_code1);
        assert_eq!(e(im.write(1, &call(65000, &[]))), Err(ErrorCode1::INVALID_SLOT));
        assert_eq!(e(im.write(0, &[0x08, 0x00, 0xFD])), Err(ErrorCode1::WRITE_LENGTH_ERROR));
        assert_eq!(e(im.write(0, &[0x09, 0x00, 0xFD, 0xE8])), Err(ErrorCode1::INVALID_PARAMETER));
        assert_eq!(e(im.write(0, &[0x08, 0x01, 0xFD, 0xE8])), Err(ErrorCode1::INVALID_PARAMETER));
        assert_eq!(e(im.write(0, &call(65005, &[]))), Err(ErrorCode1::INVALID_INDEX));
        assert_eq!(e(im.write(0, &call(64999, &[]))), Err(ErrorCode1::INVALID_INDEX));
        assert_eq!(e(im.write(0, &call(65000, &[0; 64]))), Err(ErrorCode1::ACCESS_DENIED));
        assert_eq!(e(im.write(0, &call(65001, &[0; 63]))), Err(ErrorCode1::WRITE_LENGTH_ERROR));
        assert_eq!(e(im.write(0, &call(65001, &[0; 65]))), Err(ErrorCode1::WRITE_LENGTH_ERROR));
        assert_eq!(im.read(0, &mut out).map_err(ImError::error_code1), Err(ErrorCode1::STATE_CONFLICT));
        im.write(0, &call(65000, &[])).unwrap();
        assert_eq!(im.read(0, &mut out[..67]).map_err(ImError::error_code1), Err(ErrorCode1::WRITE_LENGTH_ERROR));
        assert_eq!(im.read(0, &mut out), Ok(68), "the selection stayed");
        assert_eq!(im.read(3, &mut out).map_err(ImError::error_code1), Err(ErrorCode1::INVALID_SLOT));
        assert_eq!(im.stats().errors, 12);
        assert_eq!(im.take_changed(), None, "nothing was written");
    }

    #[test]
    fn other_indices_go_to_the_inner_handler() {
        let mut im = Im::new(&test_card::IM);
        let mut inner = NoRecords;
        let mut h = im.with(&mut inner);
        let now = Instant::from_millis(0);
        assert_eq!(h.write(now, 0, 47, &[1]), Err(ErrorCode1::INVALID_SLOT));
        assert_eq!(h.write(now, 0, 255, &call(65000, &[])), Ok(()));
        let mut out = [0u8; 240];
        assert_eq!(h.read(now, 0, 255, &mut out), Ok(68));
    }

    proptest::proptest! {
        /// Any bytes: never a panic; accepted calls are well-formed, and a read after one
        /// returns the selected FI_Index.
        #[test]
        fn any_call(bytes in proptest::collection::vec(proptest::num::u8::ANY, 0..80), slot in 0u8..3) {
            let mut im = Im::new(&test_card::IM);
            let mut out = [0u8; 240];
            match im.write(slot, &bytes) {
                Ok(()) => {
                    proptest::prop_assert_eq!(slot, 0);
                    proptest::prop_assert!(bytes.len() == 4 || bytes.len() == 68);
                    proptest::prop_assert_eq!(im.read(0, &mut out), Ok(68));
                    proptest::prop_assert_eq!(&out[..4], &bytes[..4]);
                }
                Err(e) => {
                    let _ = e.error_code1();
                    proptest::prop_assert_eq!(im.read(0, &mut out), Err(ImError::NoCall));
                }
            }
        }
    }
}
