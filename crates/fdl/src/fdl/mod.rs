//! PROFIBUS layer 2, the Fieldbus Data Link (FDL), as a slave (passive station) needs it.
//!
//! * [`telegram`] — the frame formats (SD1, SD2, SD3, SD4, SC), the checksum, decoding of
//!   untrusted bytes and encoding of responses (reference §2.1–2.3).
//! * [`framer`] — turns a byte stream (with idle-line gaps) into frames; drops and counts
//!   corrupt ones and resynchronises (reference §1.4).
//! * [`station`] — the passive station: own address, FDL_Status, FCB/FCV retry memory, SAP
//!   dispatch to the layer above through [`station::FdlApplication`] (reference §2.4–2.5).

pub mod framer;
pub mod station;
pub mod telegram;
