//! Drive profiles carried in DP-V1 data records (reference §5).
//!
//! * [`param`] — PROFIdrive base-mode parameter access, data record 47: request parser, the
//!   [`param::ParameterAccess`] trait a drive parameter table implements, and [`param::respond`],
//!   which builds the parameter response (VACON OPTE3/E5 manual §6.4, WEG CFW-11 §4.2.4,
//!   WEG CFW500 §5.2.4, reference §5.1).
//! * [`weg48`] — WEG's simple parameter access, data record 48 (CFW500 §5.2.5, CFW-11 §4.2.6).
//!
//! Both are codecs: which slot answers, the "write request, then poll with reads until the
//! response exists (0xB5)" sequence and the one-shot response buffer belong to the DP-V1
//! record routing above them.

pub mod param;
pub mod weg48;
