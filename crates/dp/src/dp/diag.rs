//! Slave_Diag (SAP 60): the six standard octets and extended diagnosis (reference §3.5).

/// The longest Slave_Diag DU the slave stages: the protocol's 244 octets (reference §3.5), so
/// any product's GSD `Max_Diag_Data_Len` ([`super::SlaveConfig::max_diag_data_len`]) fits
/// (its configuration asserts it).
pub const MAX_DIAG_DATA_LEN: usize = 244;
/// Room for extended diagnosis after the 6 standard octets ([`MAX_DIAG_DATA_LEN`] − 6).
pub const MAX_EXT_DIAG_LEN: usize = MAX_DIAG_DATA_LEN - 6;

bitflags::bitflags! {
    /// Station_status_1 (diagnosis octet 1).
    #[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
    pub struct Status1: u8 {
        /// b1 Station_Not_Ready: not ready for data exchange.
        const STATION_NOT_READY = 0x02;
        /// b2 Cfg_Fault: the last Chk_Cfg differed from the real configuration.
        const CFG_FAULT = 0x04;
        /// b3 Ext_Diag: an entry exists in the extended diagnosis.
        const EXT_DIAG = 0x08;
        /// b4 Not_Supported: a requested function is not supported.
        const NOT_SUPPORTED = 0x10;
        /// b6 Prm_Fault: the last Set_Prm was wrong.
        const PRM_FAULT = 0x40;
    }
}

bitflags::bitflags! {
    /// Station_status_2 (diagnosis octet 2).
    #[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
    pub struct Status2: u8 {
        /// b0 Prm_Req: the slave needs new Set_Prm and Chk_Cfg.
        const PRM_REQ = 0x01;
        /// b1 Stat_Diag: static diagnosis, the master must keep reading diagnosis.
        const STAT_DIAG = 0x02;
        /// b2: always 1 for a slave.
        const ALWAYS_ONE = 0x04;
        /// b3 WD_On: response monitoring active.
        const WD_ON = 0x08;
        /// b4 Freeze_Mode: a Freeze command was received.
        const FREEZE_MODE = 0x10;
        /// b5 Sync_Mode: a Sync command was received.
        const SYNC_MODE = 0x20;
    }
}

/// Station_status_3 b7: Ext_Diag_Overflow.
pub const EXT_DIAG_OVERFLOW: u8 = 0x80;

/// Why extended diagnosis blocks were refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[non_exhaustive]
pub enum DiagError {
    /// More bytes than the GSD's `Max_Diag_Data_Len` − 6.
    TooLong,
    /// A device- or identifier-related block whose length byte is < 2 or runs past the end.
    BadBlockLength {
        /// offset of the block header
        at: u8,
    },
    /// A header with the reserved type 0b11.
    ReservedBlockType {
        /// offset of the block header
        at: u8,
    },
    /// A channel-related block cut short (they are always 3 bytes).
    ShortChannelBlock {
        /// offset of the block header
        at: u8,
    },
}

/// Check that `blocks` is a sequence of well-formed extended diagnosis blocks:
/// device-related (header `00 llllll`, length incl. header 2..=63), identifier-related
/// (`01 llllll`), channel-related (`10 mmmmmm` + 2 bytes). Masters decode these blocks, and
/// a malformed one can crash a master (profirust panics on a header byte of 0). At most
/// `max_ext_len` octets: the GSD's `Max_Diag_Data_Len` − 6
/// ([`super::SlaveConfig::max_ext_diag_len`]).
pub fn validate_ext_diag(blocks: &[u8], max_ext_len: usize) -> Result<(), DiagError> {
    if blocks.len() > max_ext_len.min(MAX_EXT_DIAG_LEN) {
        return Err(DiagError::TooLong);
    }
    let mut i = 0;
    while i < blocks.len() {
        let h = blocks[i];
        let at = i as u8;
        match h >> 6 {
            0b00 | 0b01 => {
                let len = (h & 0x3F) as usize;
                if len < 2 || i + len > blocks.len() {
                    return Err(DiagError::BadBlockLength { at });
                }
                i += len;
            }
            0b10 => {
                if i + 3 > blocks.len() {
                    return Err(DiagError::ShortChannelBlock { at });
                }
                i += 3;
            }
            _ => return Err(DiagError::ReservedBlockType { at }),
        }
    }
    Ok(())
}

/// The six standard octets.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StandardDiag {
    /// Station_status_1.
    pub status1: Status1,
    /// Station_status_2 (b2 is forced to 1 when encoded).
    pub status2: Status2,
    /// Station_status_3.
    pub status3: u8,
    /// Diag.Master_Add: the locking master, 0xFF when free.
    pub master_add: u8,
    /// Ident_Number (octets 5–6): the product's, GSD `Ident_Number`
    /// ([`super::SlaveConfig::ident_number`]).
    pub ident_number: u16,
}

impl StandardDiag {
    /// The six octets on the wire.
    pub fn encode(&self) -> [u8; 6] {
        let id = self.ident_number.to_be_bytes();
        [self.status1.bits(), (self.status2 | Status2::ALWAYS_ONE).bits(), self.status3, self.master_add, id[0], id[1]]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_card;

    /// The card's limit.
    fn validate_ext_diag(blocks: &[u8]) -> Result<(), DiagError> {
        super::validate_ext_diag(blocks, test_card::MAX_EXT_DIAG_LEN)
    }

    #[test]
    fn blocks() {
        assert_eq!(validate_ext_diag(&[]), Ok(()));
        assert_eq!(validate_ext_diag(&[0x04, 1, 2, 3, 0x81, 0x41, 0x25]), Ok(()));
        assert_eq!(validate_ext_diag(&[0x42, 0x01]), Ok(()));
        assert_eq!(validate_ext_diag(&[0x00]), Err(DiagError::BadBlockLength { at: 0 }));
        assert_eq!(validate_ext_diag(&[0x05, 1, 2]), Err(DiagError::BadBlockLength { at: 0 }));
        assert_eq!(validate_ext_diag(&[0x81, 0x41]), Err(DiagError::ShortChannelBlock { at: 0 }));
        assert_eq!(validate_ext_diag(&[0xC0]), Err(DiagError::ReservedBlockType { at: 0 }));
        assert_eq!(validate_ext_diag(&[0u8; 100]), Err(DiagError::TooLong));
    }

    #[test]
    fn standard_octets() {
        let d = StandardDiag {
            status1: Status1::STATION_NOT_READY,
            status2: Status2::PRM_REQ,
            status3: 0,
            master_add: 0xFF,
            ident_number: test_card::IDENT_NUMBER,
        };
        let id = test_card::IDENT_NUMBER.to_be_bytes();
        assert_eq!(d.encode(), [0x02, 0x05, 0x00, 0xFF, id[0], id[1]]);
    }

    proptest::proptest! {
        #[test]
        fn never_panics(bytes in proptest::collection::vec(proptest::num::u8::ANY, 0..100)) {
            let _ = validate_ext_diag(&bytes);
        }
    }
}
