//! Drive profiles carried in DP-V1 data records (reference §5).
//!
//! * [`telegram`] — what each word of every telegram is, the control profile family it needs,
//!   and the PNU 915 / 916 signal lists (OPTE3/E5 §6.3.2, §6.3.9).
//! * [`cyclic`] — the cyclic engine: output image → [`drive_if::DriveCommand`] and raw words
//!   for the drive, drive status → input image, in the PROFIdrive / Bypass / Echo operate modes
//!   (OPTE3/E5 §5.1).
//! * [`drive_if`] — the drive-neutral command / status the profile exchanges with the drive
//!   through the DPM (OPTE3/E5 §11 FBFixedControlWord / FBFixedStatusWord model).
//! * [`profidrive`] — the PROFIdrive control profiles on that interface: PROFIdrive 4.1 (ST1,
//!   ST20, VACON telegrams 100/101/138/139; general state diagram, STW1/ZSW1, OPTE3/E5
//!   §6.3) and PROFIdrive 2.0 for the PPO types (§6.5), plus [`profidrive::SpeedScale`], the
//!   conversion between a profile's speed word and the neutral N2 scale.
//! * [`weg`] — WEG's profiles (CFW500 §4 / §5.1, CFW-11 §3): the manufacturer profile
//!   (P0684 / P0680, 13-bit speed P0685 / P0681) and the PROFIdrive selection (P0967 / P0968).
//! * [`invt`] — the INVT HD2 control word commands 1–9 and status word values (INVT §2.6).
//! * [`param`] — PROFIdrive base-mode parameter access, data record 47: request parser, the
//!   [`param::ParameterAccess`] trait a drive parameter table implements, and [`param::respond`],
//!   which builds the parameter response (VACON OPTE3/E5 manual §6.4, WEG CFW-11 §4.2.4,
//!   WEG CFW500 §5.2.4, reference §5.1).
//! * [`weg48`] — WEG's simple parameter access, data record 48 (CFW500 §5.2.5, CFW-11 §4.2.6).
//!
//! * [`records`] — slots 0 and 1 (`card::RECORD_SLOTS`) / records 47 and 48 as a [`crate::dpv1::records::RecordHandler`]:
//!   the one-shot response of record 47, the error codes of the routing.
//! * [`pkw`] — the PKW parameter channel of PPO 1/2/5 (four words in the cyclic data): request
//!   held, executed once against a [`param::ParameterAccess`] table, response repeated; VACON
//!   (OPTE3/E5 §6.6.2), INVT (§2.6) and PROFIdrive 2.0 (reference §5.6) codings.
//! * [`faults`] — the PROFIdrive fault buffer behind PNU 944 / 947 / 950: four fault situations
//!   of eight messages, fed by the drive's fault reports (OPTE3/E5 §6.4.6, Table 112).
//! * [`pnu`] — the PROFIdrive parameters the card owns (918, 922, 930, 944, 947, 963, 964, 965,
//!   975, 980) in front of the drive's table.
//! * [`references`] — the speed references of the profile scales, read from the drive's
//!   parameters (VACON ID 101 / 102 / 111, WEG P0403 / P0134, INVT Fmax).
//! * [`table`] — a generic, allocation-free drive parameter table ([`table::ParamDef`],
//!   [`table::Table`]) implementing [`param::ParameterAccess`]: values, arrays, limits,
//!   read-only, and the 46-byte parameter description (VACON OPTE3/E5 §6.4.3.7–6.4.3.16).
//!
//! `param` and `weg48` are codecs: which slot answers, the "write request, then poll with reads until the
//! response exists (0xB5)" sequence and the one-shot response buffer belong to the DP-V1
//! record routing above them.

pub mod cyclic;
pub mod drive_if;
#[cfg(test)]
pub(crate) mod drive_stub;
pub mod faults;
pub mod invt;
pub mod param;
pub mod pkw;
pub mod pnu;
pub mod profidrive;
pub mod records;
pub mod references;
pub mod runtime;
pub mod selection;
pub mod table;
pub mod telegram;
pub mod weg;
pub mod weg48;
