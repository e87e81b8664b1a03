//! INVT
