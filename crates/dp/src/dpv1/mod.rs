//! DP-V1: the acyclic services (MSAC_C1 on SAP 51, MSAC_C2 on the resource manager SAP 49 and the
//! connection SAPs 0..48; reference §4).
//!
//! * [`im`] — Identification & Maintenance I&M0–I&M4 at slot 0 / index 255 (reference §4.7).
//! * [`pdu`] — the PDU codec: function numbers, request views ([`pdu::parse`]), response
//!   emitters, the Error_Code_1 table and the 240-byte data limit.
//!
//! The connection state machines (C1 started with Data_Exch, C2 Initiate/Idle/Abort with
//! Send_Timeout monitoring) and the slot/index routing to data records such as PROFIdrive's
//! record 47 (`pbcard::profile`) build on this codec.

pub mod c1;
pub mod c2;
pub mod channel;
pub mod im;
pub mod pdu;
pub mod records;
