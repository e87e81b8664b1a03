//! A stand-in for the product in the unit tests of this crate: the few values of a card
//! (`pbcard::card`'s, copied) that tests of product-independent code take as arguments. The
//! tests that check the DP layers against the product's whole configuration (its modules,
//! User_Prm_Data, Chk_Cfg policy, the scripted master's Set_Prm) are in `pbcard`
//! (`src/dp_tests/`), where the product is.

use crate::dpv1::im::{ImDevice, PROFILE_ID_PROFIDRIVE};

/// The PROFIBUS ident number (`pbcard::card::IDENT_NUMBER`).
pub const IDENT_NUMBER: u16 = 0x0F11;
/// The extended diagnosis limit, `Max_Diag_Data_Len` − 6 (`pbcard::card::MAX_EXT_DIAG_LEN`).
pub const MAX_EXT_DIAG_LEN: usize = 64 - 6;
/// The MSAC_C2 Initiate response's Profile_Ident_Number (`pbcard::card::PROFILE_IDENT_NUMBER`).
pub const PROFILE_IDENT_NUMBER: u16 = 0x3A00;
/// I&M0 MANUFACTURER_ID (`pbcard::card::IM_MANUFACTURER_ID`).
pub const IM_MANUFACTURER_ID: u16 = 0;
/// The I&M0 values (`pbcard::card::IM`).
pub const IM: ImDevice = ImDevice {
    manufacturer_id: IM_MANUFACTURER_ID,
    order_id: "ODC-PB1",
    hardware_revision: 1,
    software_revision: [b'V', 0, 1, 0],
    profile_id: PROFILE_ID_PROFIDRIVE,
};
