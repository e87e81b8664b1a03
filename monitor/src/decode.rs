//! Field-by-field text of the DP, DP-V1 and PROFIdrive data units, with the project's parsers
//! (`pbcard::dp`, `pbcard::dpv1::pdu`, `pbcard::profile::param`, `pbcard::profile::pkw`) and the
//! names of the reference and the manuals (reference §2–§5). The record data of DS_Write /
//! DS_Read and of MSAC_C2 Data_Transport go through one decoder ([`record_write`],
//! [`record_read`]): record 47 as PROFIdrive, index 255 as I&M ([`crate::im`]).

use std::fmt::Write as _;

use pbcard::dp::cfg;
use pbcard::dp::diag::{Status1, Status2};
use pbcard::dp::global_control::{ControlCommand, GlobalControl};
use pbcard::dp::prm::{Dpv1Status1, SetPrm, StationStatus};
use pbcard::dpv1::pdu::{self, ErrorClass, ErrorCode1, Request, Response};
use pbcard::fdl::telegram::{FunctionCode, RequestFunction};
use pbcard::profile::param::{Attribute, ErrorValue, Format, ParamRequest, ParamResponse, RequestId, ValueBlock};
use pbcard::profile::pkw::PkwWords;

use crate::im;
use crate::product::Product;
use pbcard_softslave::hex;

/// Names of set bits, `(mask, name)`, joined with spaces; "-" when none.
pub fn bits(value: u8, names: &[(u8, &str)]) -> String {
    let v: Vec<&str> = names.iter().filter(|(m, _)| value & m != 0).map(|(_, n)| *n).collect();
    if v.is_empty() {
        "-".into()
    } else {
        v.join(" ")
    }
}

/// The FC of a request: `SRD_high FCB=1 FCV=1`; of a response: `DL`, with the station type of an
/// FDL_Status answer (reference §2.3).
pub fn fc_name(fc: FunctionCode) -> String {
    if fc.is_request() {
        let f = match fc.function() {
            RequestFunction::TimeEvent => "Time_Event".to_string(),
            RequestFunction::SdaLow => "SDA_low".into(),
            RequestFunction::SdnLow => "SDN_low".into(),
            RequestFunction::SdaHigh => "SDA_high".into(),
            RequestFunction::SdnHigh => "SDN_high".into(),
            RequestFunction::Msrd => "MSRD".into(),
            RequestFunction::FdlStatus => "FDL_Status".into(),
            RequestFunction::SrdLow => "SRD_low".into(),
            RequestFunction::SrdHigh => "SRD_high".into(),
            RequestFunction::Ident => "Ident".into(),
            RequestFunction::LsapStatus => "LSAP_Status".into(),
            RequestFunction::Other(x) => format!("FC{x:X}"),
        };
        if fc.fcv() {
            format!("{f} FCB={} FCV=1", u8::from(fc.fcb()))
        } else {
            format!("{f} FCV=0")
        }
    } else {
        response_status(fc).to_string()
    }
}

/// The status of a response FC (bits 3..0, reference §2.3).
pub fn response_status(fc: FunctionCode) -> &'static str {
    match fc.0 & 0x0F {
        0x0 => "OK",
        0x1 => "UE",
        0x2 => "RR",
        0x3 => "RS",
        0x8 => "DL",
        0x9 => "NR",
        0xA => "DH",
        0xC => "RDL",
        0xD => "RDH",
        _ => "reserved",
    }
}

/// The station type of an FDL_Status answer (FC bits 5..4).
pub fn station_type(fc: FunctionCode) -> &'static str {
    match (fc.0 >> 4) & 3 {
        0 => "slave",
        1 => "master not ready",
        2 => "master ready for the token ring",
        _ => "master in the token ring",
    }
}

/// What a response status means, when it is not the normal answer.
pub fn response_meaning(fc: FunctionCode) -> Option<&'static str> {
    Some(match fc.0 & 0x0F {
        0x1 => "user error",
        0x2 => "no resources",
        0x3 => "no service activated (SAP not enabled)",
        0x9 => "no response data",
        0xA => "response data, high priority: new diagnosis",
        0xC => "data not received, response data low",
        0xD => "data not received, response data high",
        _ => return None,
    })
}

const STATION_STATUS: &[(u8, &str)] = &[
    (StationStatus::LOCK_REQ.bits(), "Lock_Req"),
    (StationStatus::UNLOCK_REQ.bits(), "Unlock_Req"),
    (StationStatus::SYNC_REQ.bits(), "Sync_Req"),
    (StationStatus::FREEZE_REQ.bits(), "Freeze_Req"),
    (StationStatus::WD_ON.bits(), "WD_On"),
    (0x07, "reserved-bits"),
];
const DPV1_STATUS_1: &[(u8, &str)] = &[
    (Dpv1Status1::DPV1_ENABLE.bits(), "DPV1_Enable"),
    (Dpv1Status1::FAIL_SAFE.bits(), "Fail_Safe"),
    (Dpv1Status1::PUBLISHER_ENABLE.bits(), "Publisher_Enable"),
    (Dpv1Status1::WD_BASE_1MS.bits(), "WD_Base_1ms"),
    (0x1B, "reserved-bits"),
];
const DPV1_STATUS_2: &[(u8, &str)] = &[
    (0x80, "Enable_Pull_Plug_Alarm"),
    (0x40, "Enable_Process_Alarm"),
    (0x20, "Enable_Diagnostic_Alarm"),
    (0x10, "Enable_Manufacturer_Specific_Alarm"),
    (0x08, "Enable_Status_Alarm"),
    (0x04, "Enable_Update_Alarm"),
    (0x01, "Check_Cfg_Mode"),
];
const DPV1_STATUS_3: &[(u8, &str)] = &[(0x80, "Prm_Structure"), (0x10, "IsoM_Req"), (0x08, "PrmCmd")];

/// Set_Prm (reference §3.3): every field, User_Prm_Data by the product's names, and whether the
/// pbcard card would accept it.
pub fn set_prm(pdu: &[u8], product: &Product) -> String {
    if pdu.len() < 7 {
        return format!("too short ({} bytes, at least 7): {}", pdu.len(), hex(pdu));
    }
    let user = &pdu[7..];
    let st1 = user.first().copied().unwrap_or(0);
    let base = if st1 & Dpv1Status1::WD_BASE_1MS.bits() != 0 { 1 } else { 10 };
    let ident = u16::from_be_bytes([pdu[4], pdu[5]]);
    let mut s = format!("Station_Status {:02X} ({})", pdu[0], bits(pdu[0], STATION_STATUS));
    if pdu[0] & StationStatus::WD_ON.bits() != 0 {
        let _ = write!(
            s,
            ", watchdog {}×{}×{base} ms = {} ms",
            pdu[1],
            pdu[2],
            u32::from(pdu[1]) * u32::from(pdu[2]) * base
        );
    } else {
        let _ = write!(s, ", watchdog off (WD_Fact {} {})", pdu[1], pdu[2]);
    }
    match pdu[3] {
        0 => s.push_str(", min_TSDR kept"),
        t => {
            let _ = write!(s, ", min_TSDR {t} bit");
        }
    }
    let _ = write!(s, ", Ident_Number 0x{ident:04X}");
    if ident != product.ident {
        let _ = write!(s, " (≠ GSD 0x{:04X})", product.ident);
    }
    let _ = write!(s, ", Group_Ident 0x{:02X}", pdu[6]);
    if !user.is_empty() {
        let b = |i: usize| user.get(i).copied().unwrap_or(0);
        let _ = write!(s, ", DPV1_Status {:02X} ({})", b(0), bits(b(0), DPV1_STATUS_1));
        if user.len() > 1 {
            let _ = write!(s, " {:02X} ({})", b(1), bits(b(1), DPV1_STATUS_2));
        }
        if user.len() > 2 {
            let alarm_mode = [1, 2, 4, 8, 12, 16, 24, 32][usize::from(b(2) & 7)];
            let _ = write!(s, " {:02X} (Alarm_Mode {alarm_mode}; {})", b(2), bits(b(2), DPV1_STATUS_3));
        }
    }
    let named: Vec<String> =
        product.user_prms.iter().filter_map(|p| p.value(user).map(|v| format!("{} = {v}", p.name))).collect();
    if !named.is_empty() {
        let _ = write!(s, ", {}", named.join(", "));
    }
    let covered = 3 + product.user_prms.iter().map(|p| p.offset + 1).max().unwrap_or(0).saturating_sub(3);
    if user.len() > covered.max(3) {
        let _ = write!(s, ", more User_Prm_Data {}", hex(&user[covered.max(3)..]));
    }
    if ident == pbcard::card::IDENT_NUMBER {
        if let Err(e) = SetPrm::parse(pdu, &pbcard::card::SLAVE) {
            let _ = write!(s, " — the pbcard card refuses it: {e:?} (Prm_Fault)");
        }
    }
    s
}

/// One identifier list (Chk_Cfg / Get_Cfg, reference §3.4): the module, the I/O lengths.
pub fn cfg_data(bytes: &[u8], product: &Product) -> String {
    let module =
        product.module(bytes).map_or_else(|| "no GSD module".to_string(), |m| format!("module \"{}\"", m.name));
    match cfg::io_lengths(bytes) {
        Ok(io) => format!("{} = {module}, inputs {} bytes, outputs {} bytes", hex(bytes), io.inputs, io.outputs),
        Err(e) => format!("{} = malformed identifier list ({e:?})", hex(bytes)),
    }
}

const STATUS_1: &[(u8, &str)] = &[
    (0x80, "Master_Lock"),
    (Status1::PRM_FAULT.bits(), "Prm_Fault"),
    (0x20, "Invalid_Slave_Response"),
    (Status1::NOT_SUPPORTED.bits(), "Not_Supported"),
    (Status1::EXT_DIAG.bits(), "Ext_Diag"),
    (Status1::CFG_FAULT.bits(), "Cfg_Fault"),
    (Status1::STATION_NOT_READY.bits(), "Station_Not_Ready"),
    (0x01, "Station_Non_Existent"),
];
const STATUS_2: &[(u8, &str)] = &[
    (0x80, "Deactivated"),
    (Status2::SYNC_MODE.bits(), "Sync_Mode"),
    (Status2::FREEZE_MODE.bits(), "Freeze_Mode"),
    (Status2::WD_ON.bits(), "WD_On"),
    (Status2::STAT_DIAG.bits(), "Stat_Diag"),
    (Status2::PRM_REQ.bits(), "Prm_Req"),
];

/// Slave_Diag response (reference §3.5): the six octets by bit name, then the extended blocks.
pub fn slave_diag(d: &[u8], product: &Product, dpv1: bool) -> String {
    if d.len() < 6 {
        return format!("too short ({} bytes, 6 standard octets): {}", d.len(), hex(d));
    }
    let ident = u16::from_be_bytes([d[4], d[5]]);
    let mut s = format!(
        "Station_status_1 {:02X} ({}), Station_status_2 {:02X} ({}{}), Station_status_3 {:02X}{}, Master_Add {}, Ident_Number 0x{ident:04X}",
        d[0],
        bits(d[0], STATUS_1),
        d[1],
        bits(d[1], STATUS_2),
        if d[1] & 0x04 == 0 { ", b2 not set!" } else { "" },
        d[2],
        if d[2] & 0x80 != 0 { " (Ext_Diag_Overflow)" } else { "" },
        if d[3] == 0xFF { "none".to_string() } else { d[3].to_string() },
    );
    if ident != product.ident {
        let _ = write!(s, " (≠ GSD 0x{:04X})", product.ident);
    }
    let mut i = 6;
    while i < d.len() {
        let h = d[i];
        match h >> 6 {
            0b00 => {
                let len = usize::from(h & 0x3F);
                if len < 2 || i + len > d.len() {
                    let _ = write!(s, "; bad device-related block at {i}: {}", hex(&d[i..]));
                    break;
                }
                let body = &d[i + 1..i + len];
                let _ = write!(s, "; device-related {}", device_block(body, dpv1));
                i += len;
            }
            0b01 => {
                let len = usize::from(h & 0x3F);
                if len < 2 || i + len > d.len() {
                    let _ = write!(s, "; bad identifier-related block at {i}: {}", hex(&d[i..]));
                    break;
                }
                let slots: Vec<String> = d[i + 1..i + len]
                    .iter()
                    .enumerate()
                    .flat_map(|(k, b)| {
                        (0..8).filter(move |bit| b & (1 << bit) != 0).map(move |bit| (k * 8 + bit).to_string())
                    })
                    .collect();
                let _ = write!(
                    s,
                    "; identifier-related: modules with diagnosis {}",
                    if slots.is_empty() { "none".into() } else { slots.join(",") }
                );
                i += len;
            }
            0b10 => {
                if i + 3 > d.len() {
                    let _ = write!(s, "; short channel-related block: {}", hex(&d[i..]));
                    break;
                }
                let (ch, ty) = (d[i + 1], d[i + 2]);
                let _ = write!(
                    s,
                    "; channel-related: module {}, channel {} {}, {}",
                    h & 0x3F,
                    ch & 0x3F,
                    ["", "input", "output", "in/out"][usize::from(ch >> 6)],
                    channel_error(ty & 0x1F)
                );
                i += 3;
            }
            _ => {
                let _ = write!(s, "; reserved block type at {i}: {}", hex(&d[i..]));
                break;
            }
        }
    }
    s
}

fn channel_error(t: u8) -> String {
    let name = match t {
        1 => "short circuit",
        2 => "undervoltage",
        3 => "overvoltage",
        4 => "overload",
        5 => "overtemperature",
        6 => "line break",
        7 => "upper limit exceeded",
        8 => "lower limit exceeded",
        9 => "error",
        _ => return format!("error type {t}"),
    };
    name.into()
}

/// A device-related block (DP-V1: alarm or status, reference §3.5 / §4.4).
fn device_block(b: &[u8], dpv1: bool) -> String {
    if dpv1 && b.len() >= 3 {
        let t = b[0];
        let kind = if t & 0x80 == 0 {
            match t & 0x7F {
                1 => "Diagnosis_Alarm",
                2 => "Process_Alarm",
                3 => "Pull_Alarm",
                4 => "Plug_Alarm",
                5 => "Status_Alarm",
                6 => "Update_Alarm",
                32..=126 => "manufacturer alarm",
                _ => "alarm type ?",
            }
        } else {
            match t & 0x7F {
                1 => "Status_Message",
                2 => "Modul_Status",
                _ => "status type ?",
            }
        };
        let spec = b[2];
        return format!(
            "{kind} (type {:02X}), slot {}, Seq_Nr {}, {}{}, data {}",
            t,
            b[1],
            spec >> 3,
            ["no specifier", "appears", "disappears", "disappears, other errors remain"][usize::from(spec & 3)],
            if spec & 0x04 != 0 { ", Add_Ack" } else { "" },
            hex(&b[3..])
        );
    }
    hex(b)
}

/// Global_Control (reference §3.6).
pub fn global_control(pdu: &[u8]) -> String {
    match GlobalControl::parse(pdu) {
        Some(g) => {
            let names: &[(u8, &str)] = &[
                (ControlCommand::CLEAR_DATA.bits(), "Clear_Data"),
                (ControlCommand::UNFREEZE.bits(), "Unfreeze"),
                (ControlCommand::FREEZE.bits(), "Freeze"),
                (ControlCommand::UNSYNC.bits(), "Unsync"),
                (ControlCommand::SYNC.bits(), "Sync"),
            ];
            let cmd =
                if g.command.is_empty() { "operate (no command)".to_string() } else { bits(g.command.bits(), names) };
            let group =
                if g.group_select == 0 { "all groups".to_string() } else { format!("groups {:08b}", g.group_select) };
            let reserved = if g.reserved != 0 { format!(", reserved bits {:02X}", g.reserved) } else { String::new() };
            format!("Control_Command {:02X} ({cmd}), Group_Select {:02X} ({group}){reserved}", pdu[0], g.group_select)
        }
        None => format!("wrong length ({} bytes, 2 expected): {}", pdu.len(), hex(pdu)),
    }
}

/// Set_Slave_Add (reference §3.9).
pub fn set_slave_add(pdu: &[u8], product: &Product) -> String {
    if pdu.len() < 4 {
        return format!("too short ({} bytes, at least 4): {}", pdu.len(), hex(pdu));
    }
    let ident = u16::from_be_bytes([pdu[1], pdu[2]]);
    format!(
        "New_Slave_Address {}, Ident_Number 0x{ident:04X}{}, No_Add_Chg {}{}",
        pdu[0],
        if ident != product.ident { format!(" (≠ GSD 0x{:04X})", product.ident) } else { String::new() },
        pdu[3],
        if pdu.len() > 4 { format!(", Rem_Slave_Data {}", hex(&pdu[4..])) } else { String::new() }
    )
}

/// The DP-V1 service name of a function (reference §4.2).
pub fn dpv1_service(f: pdu::Function) -> &'static str {
    match f {
        pdu::Function::Read => "DS_Read",
        pdu::Function::Write => "DS_Write",
        pdu::Function::AlarmAck => "Alarm_Ack",
        pdu::Function::Initiate => "Initiate",
        pdu::Function::Abort => "Abort",
        pdu::Function::DataTransport => "Data_Transport",
        pdu::Function::Idle => "Idle",
        pdu::Function::ResourceManager => "Initiate",
    }
}

/// Error_Code_1 by name (reference §4.2; VACON OPTE3/E5 §6.4.3.3 Table 46).
pub fn error_code1(e: ErrorCode1) -> String {
    let name = match e {
        ErrorCode1::READ_ERROR => "application: read error",
        ErrorCode1::WRITE_ERROR => "application: write error",
        ErrorCode1::MODULE_FAILURE => "application: module failure",
        ErrorCode1::VERSION_CONFLICT => "application: version conflict",
        ErrorCode1::FEATURE_NOT_SUPPORTED => "application: feature not supported",
        ErrorCode1::INVALID_INDEX => "access: invalid index",
        ErrorCode1::WRITE_LENGTH_ERROR => "access: write length error",
        ErrorCode1::INVALID_SLOT => "access: invalid slot",
        ErrorCode1::TYPE_CONFLICT => "access: type conflict",
        ErrorCode1::INVALID_AREA => "access: invalid area",
        ErrorCode1::STATE_CONFLICT => "access: state conflict",
        ErrorCode1::ACCESS_DENIED => "access: access denied",
        ErrorCode1::INVALID_RANGE => "access: invalid range",
        ErrorCode1::INVALID_PARAMETER => "access: invalid parameter",
        ErrorCode1::INVALID_TYPE => "access: invalid type",
        ErrorCode1::READ_CONSTRAIN_CONFLICT => "resource: read constrain conflict",
        ErrorCode1::WRITE_CONSTRAIN_CONFLICT => "resource: write constrain conflict",
        ErrorCode1::RESOURCE_BUSY => "resource: resource busy",
        ErrorCode1::RESOURCE_UNAVAILABLE => "resource: resource unavailable",
        other => {
            return match other.class() {
                ErrorClass::Application => format!("application: code {}", other.code()),
                ErrorClass::Access => format!("access: code {}", other.code()),
                ErrorClass::Resource => format!("resource: code {}", other.code()),
                ErrorClass::User(c) => format!("user specific class {c:X} code {}", other.code()),
                ErrorClass::Reserved(c) => format!("reserved class {c:X} code {}", other.code()),
            }
        }
    };
    name.into()
}

/// A PROFIdrive error value by name (VACON OPTE3/E5 §6.4.3.4 Table 47; reference §5.1).
pub fn error_value(e: ErrorValue) -> String {
    let name = match e {
        ErrorValue::IMPERMISSIBLE_PARAMETER_NUMBER => "impermissible parameter number",
        ErrorValue::VALUE_CANNOT_BE_CHANGED => "parameter value cannot be changed",
        ErrorValue::LIMIT_EXCEEDED => "low or high limit exceeded",
        ErrorValue::INVALID_SUBINDEX => "invalid subindex",
        ErrorValue::NO_ARRAY => "non-array parameter",
        ErrorValue::INCORRECT_DATA_TYPE => "incorrect data type",
        ErrorValue::SETTING_NOT_PERMITTED => "setting not permitted (may only be reset)",
        ErrorValue::DESCRIPTION_CANNOT_BE_CHANGED => "description element cannot be changed",
        ErrorValue::NO_DESCRIPTION => "no description data available",
        ErrorValue::NO_OPERATION_PRIORITY => "no operation priority",
        ErrorValue::NO_TEXT_ARRAY => "no text array available",
        ErrorValue::NOT_EXECUTABLE => "request cannot be executed (operating state)",
        ErrorValue::VALUE_IMPERMISSIBLE => "value impermissible",
        ErrorValue::RESPONSE_TOO_LONG => "response too long",
        ErrorValue::IMPERMISSIBLE_ADDRESS => "impermissible parameter address",
        ErrorValue::ILLEGAL_FORMAT => "illegal format",
        ErrorValue::NUMBER_OF_VALUES_INCONSISTENT => "number of values inconsistent",
        ErrorValue::AXIS_NONEXISTENT => "axis / drive object non-existent",
        ErrorValue::TEXT_CANNOT_BE_CHANGED => "parameter text element cannot be changed",
        ErrorValue::INVALID_REQUEST_ID => "invalid request ID",
        ErrorValue::VACON_INVALID_REQUEST_REFERENCE => "VACON: invalid request reference",
        ErrorValue::VACON_INVALID_REQUEST_ID => "VACON: invalid request ID",
        ErrorValue::VACON_INVALID_PARAMETER_COUNT => "VACON: invalid number of parameters",
        ErrorValue::VACON_INVALID_ATTRIBUTE => "VACON: invalid attribute",
        ErrorValue::VACON_REQUEST_TOO_SHORT => "VACON: request too short",
        ErrorValue::VACON_DRIVE_PARAMETER_NOT_FOUND => "VACON: drive parameter not found",
        ErrorValue::VACON_INVALID_CHANGE_REQUEST => "VACON: invalid change request",
        v if v.is_manufacturer_specific() => return format!("manufacturer specific 0x{:02X}", v.0),
        v => return format!("0x{:02X}", v.0),
    };
    format!("0x{:02X} {name}", e.0)
}

/// PROFIdrive PNU names the card and the manuals use (reference §5.2; OPTE3/E5 §6.4.5).
pub fn pnu_name(pnu: u16) -> Option<&'static str> {
    Some(match pnu {
        915 => "PZD setpoint assignment",
        916 => "PZD actual value assignment",
        918 => "station address",
        922 => "telegram selection",
        923 => "list of all signals",
        930 => "operating mode",
        944 => "fault message counter",
        947 => "fault numbers",
        950 => "scaling of the fault buffer",
        963 => "baud rate",
        964 => "device identification",
        965 => "profile identification",
        967 => "control word 1",
        968 => "status word 1",
        975 => "drive object identification",
        980..=989 => "number list of defined parameters",
        10001 => "drive parameter (application ID in the subindex)",
        _ => return None,
    })
}

fn attribute(a: Attribute) -> String {
    match a {
        Attribute::Value => "value".into(),
        Attribute::Description => "description".into(),
        Attribute::Text => "text".into(),
        Attribute::Other(b) => format!("attribute 0x{b:02X}"),
    }
}

fn format_name(f: Format) -> &'static str {
    match f {
        Format::BOOLEAN => "Boolean",
        Format::INTEGER8 => "Integer8",
        Format::INTEGER16 => "Integer16",
        Format::INTEGER32 => "Integer32",
        Format::UNSIGNED8 => "Unsigned8",
        Format::UNSIGNED16 => "Unsigned16",
        Format::UNSIGNED32 => "Unsigned32",
        Format::FLOATING_POINT => "FloatingPoint",
        Format::VISIBLE_STRING => "VisibleString",
        Format::OCTET_STRING => "OctetString",
        Format::ZERO => "Zero",
        Format::BYTE => "Byte",
        Format::WORD => "Word",
        Format::DOUBLE_WORD => "DWord",
        Format::ERROR => "Error",
        _ => "format ?",
    }
}

/// The values of a value block: `Word 3` / `VisibleString "OPTE5"` / `error 0x00 …`.
pub fn values(v: &ValueBlock<'_>) -> String {
    if let Some(e) = v.error() {
        let extra = e.additional_info.map_or(String::new(), |a| format!(" (additional info {a})"));
        return format!("error {}{extra}", error_value(e.value));
    }
    if v.format == Format::VISIBLE_STRING {
        let text: String = v.bytes.iter().map(|&b| if (0x20..0x7F).contains(&b) { b as char } else { '.' }).collect();
        return format!("VisibleString \"{text}\"");
    }
    let list: Vec<String> = (0..usize::from(v.count))
        .map(|i| {
            match v.format {
                Format::INTEGER8 => v.u8(i).map(|b| (b as i8).to_string()),
                Format::INTEGER16 => v.i16(i).map(|x| x.to_string()),
                Format::INTEGER32 => v.u32(i).map(|x| (x as i32).to_string()),
                Format::FLOATING_POINT => v.f32(i).map(|x| x.to_string()),
                Format::OCTET_STRING => v.u8(i).map(|b| format!("0x{b:02X}")),
                // Untyped: hex, and the unsigned value.
                Format::BYTE => v.u8(i).map(|b| format!("0x{b:02X} ({b})")),
                Format::WORD => v.u16(i).map(|w| format!("0x{w:04X} ({w})")),
                Format::DOUBLE_WORD => v.u32(i).map(|w| format!("0x{w:08X} ({w})")),
                _ => match v.value(i).map(<[u8]>::len) {
                    Some(1) => v.u8(i).map(|x| x.to_string()),
                    Some(2) => v.u16(i).map(|x| x.to_string()),
                    Some(4) => v.u32(i).map(|x| x.to_string()),
                    _ => None,
                },
            }
            .unwrap_or_else(|| "?".into())
        })
        .collect();
    if v.format == Format::ZERO {
        return "Zero (ok)".into();
    }
    format!("{} {}", format_name(v.format), list.join(" "))
}

fn pnu_text(pnu: u16, sub: u16) -> String {
    let name = pnu_name(pnu).map_or(String::new(), |n| format!(" ({n})"));
    if sub != 0 || pnu == 10001 {
        format!("PNU {pnu}[{sub}]{name}")
    } else {
        format!("PNU {pnu}{name}")
    }
}

/// A PROFIdrive parameter request (record 47 DS_Write data, reference §5.1); the PNUs it
/// addresses.
pub fn param_request(data: &[u8]) -> (String, Vec<u16>) {
    match ParamRequest::parse(data) {
        Ok(r) => {
            let mut pnus = Vec::new();
            let parts: Vec<String> = r
                .parameters()
                .map(|p| {
                    let a = p.address;
                    pnus.push(a.pnu);
                    let mut s = format!("{} {}", pnu_text(a.pnu, a.subindex), attribute(a.attribute));
                    if a.elements > 1 {
                        let _ = write!(s, " ×{}", a.elements);
                    }
                    if let Some(v) = p.value {
                        let _ = write!(s, " := {}", values(&v));
                    }
                    s
                })
                .collect();
            let what = if r.id == RequestId::Read { "request parameter" } else { "change parameter" };
            (format!("PROFIdrive {what}, ref {}, axis {}: {}", r.reference, r.axis, parts.join("; ")), pnus)
        }
        Err(e) => (format!("PROFIdrive parameter request, malformed: {:?} ({})", e.kind, hex(data)), Vec::new()),
    }
}

/// A PROFIdrive parameter response (record 47 DS_Read data), the PNUs taken from the request.
pub fn param_response(data: &[u8], pnus: &[u16]) -> (String, Option<u16>) {
    match ParamResponse::parse(data) {
        Ok(r) => {
            let what = match r.id.0 {
                0x01 => "request parameter ok",
                0x02 => "change parameter ok",
                0x80 => "invalid request ID",
                0x81 => "request parameter NEGATIVE",
                0x82 => "change parameter NEGATIVE",
                _ => "response ID ?",
            };
            let mut first_err = None;
            let parts: Vec<String> = r
                .values()
                .enumerate()
                .map(|(i, v)| {
                    if let (Some(e), None) = (v.error(), first_err) {
                        first_err = Some(e.value.0);
                    }
                    match pnus.get(i) {
                        Some(p) => format!("PNU {p} = {}", values(&v)),
                        None => values(&v),
                    }
                })
                .collect();
            let body = if parts.is_empty() { String::new() } else { format!(": {}", parts.join("; ")) };
            (
                format!(
                    "PROFIdrive response {:02X} {what}, ref {}, axis {}, {} parameters{body}",
                    r.id.0, r.reference, r.axis, r.count
                ),
                first_err,
            )
        }
        Err(e) => (format!("PROFIdrive parameter response, malformed: {e:?} ({})", hex(data)), None),
    }
}

/// The data a master writes to a record — a DS_Write, or the request half of an MSAC_C2
/// Data_Transport (reference §4.2): record 47 a PROFIdrive parameter request
/// ([`param_request`]), index 255 an I&M call ([`im::call`]), others the bytes.
pub fn record_write(index: u8, data: &[u8]) -> String {
    if index == pbcard::profile::param::RECORD_INDEX {
        param_request(data).0
    } else if index == im::INDEX {
        im::call(data)
    } else {
        hex(data)
    }
}

/// The data a record answers — a DS_Read response, or the response half of an MSAC_C2
/// Data_Transport: record 47 a PROFIdrive parameter response ([`param_response`], named by
/// the request's `pnus`; the error value by name is returned too), index 255 the I&M record
/// ([`im::response`], `im_selected` = the relation's last call), others the bytes.
pub fn record_read(index: u8, data: &[u8], pnus: &[u16], im_selected: Option<u16>) -> (String, Option<String>) {
    if index == pbcard::profile::param::RECORD_INDEX {
        let (t, e) = param_response(data, pnus);
        (t, e.map(|v| error_value(ErrorValue(v))))
    } else if index == im::INDEX {
        (im::response(data, im_selected), None)
    } else {
        (hex(data), None)
    }
}

/// A DP-V1 request PDU (reference §4.2) with its PROFIdrive content.
pub fn dpv1_request(r: &Request<'_>) -> String {
    match r {
        Request::Read(x) => format!("slot {} index {} length {}", x.slot, x.index, x.length),
        Request::Write(x) | Request::DataTransport(x) => {
            format!("slot {} index {} length {}: {}", x.slot, x.index, x.data.len(), record_write(x.index, x.data))
        }
        Request::AlarmAck(a) => format!(
            "slot {} Alarm_Type {} Seq_Nr {} {}",
            a.slot,
            a.alarm_type,
            a.seq_nr(),
            if a.add_ack() { "Add_Ack" } else { "" }
        ),
        Request::Initiate(i) => format!(
            "Send_Timeout {} ms, Features {:02X} {:02X}, Profile_Ident 0x{:04X}, source API {} SCL {}, destination API {} SCL {}",
            u32::from(i.send_timeout) * 10,
            i.features_supported[0],
            i.features_supported[1],
            i.profile_ident_number,
            i.source.api(),
            i.source.scl(),
            i.destination.api(),
            i.destination.scl()
        ),
        Request::Abort(a) => format!("{:?}, instance {:?}, reason {:?}", a.subnet, a.instance, a.reason),
        Request::Idle => "keep-alive".into(),
    }
}

/// A DP-V1 response PDU; `pnus` are the record-47 request's PNUs, `im_selected` the FI_Index
/// the last I&M call on this relation selected. Returns the text and the error text (negative
/// response or PROFIdrive error value).
pub fn dpv1_response(r: &Response<'_>, pnus: &[u16], im_selected: Option<u16>) -> (String, Option<String>) {
    match r {
        Response::Read(x) | Response::DataTransport(x) => {
            let (t, err) = record_read(x.index, x.data, pnus, im_selected);
            (format!("slot {} index {} length {}: {t}", x.slot, x.index, x.data.len()), err)
        }
        Response::Write { slot, index, length } => (format!("slot {slot} index {index} length {length} written"), None),
        Response::AlarmAck(a) => {
            (format!("slot {} Alarm_Type {} Seq_Nr {} acknowledged", a.slot, a.alarm_type, a.seq_nr()), None)
        }
        Response::Initiate(i) => (
            format!(
                "connection open: Max_Len_Data_Unit {}, Features {:02X} {:02X}, Profile_Ident 0x{:04X}",
                i.max_len_data_unit, i.features_supported[0], i.features_supported[1], i.profile_ident_number
            ),
            None,
        ),
        Response::Idle => ("keep-alive answered".into(), None),
        Response::ResourceManager { server_sap, poll_timeout } => {
            (format!("resource manager: continue on SAP {server_sap}, poll timeout {poll_timeout}"), None)
        }
        Response::Abort(a) => (
            format!("Abort: {:?}, instance {:?}, reason {:?}", a.subnet, a.instance, a.reason),
            Some(format!("Abort {:?}", a.reason)),
        ),
        Response::Error { function, decode, code1, code2 } => {
            let e = error_code1(*code1);
            (
                format!(
                    "NEGATIVE {}: Error_Decode {decode:02X}{}, Error_Code_1 {:02X} ({e}), Error_Code_2 {code2:02X}",
                    dpv1_service(*function),
                    if *decode == pdu::ERROR_DECODE_DPV1 { " (DP-V1)" } else { "" },
                    code1.0
                ),
                Some(format!("{:02X} {e}", code1.0)),
            )
        }
    }
}

const STW1: &[(u16, &str)] = &[
    (0x0001, "ON"),
    (0x0002, "No_OFF2"),
    (0x0004, "No_OFF3"),
    (0x0008, "Enable_operation"),
    (0x0010, "Enable_ramp"),
    (0x0020, "Unfreeze_ramp"),
    (0x0040, "Enable_setpoint"),
    (0x0080, "Fault_ack"),
    (0x0100, "Jog1"),
    (0x0200, "Jog2"),
    (0x0400, "Control_by_PLC"),
];
const ZSW1: &[(u16, &str)] = &[
    (0x0001, "Ready_to_switch_on"),
    (0x0002, "Ready_to_operate"),
    (0x0004, "Operation_enabled"),
    (0x0008, "Fault"),
    (0x0010, "No_OFF2"),
    (0x0020, "No_OFF3"),
    (0x0040, "Switching_on_inhibited"),
    (0x0080, "Warning"),
    (0x0100, "Speed_in_tolerance"),
    (0x0200, "Control_requested"),
    (0x0400, "Setpoint_reached"),
];

fn bits16(v: u16, names: &[(u16, &str)]) -> String {
    let n: Vec<&str> = names.iter().filter(|(m, _)| v & m != 0).map(|(_, n)| *n).collect();
    if n.is_empty() {
        "-".into()
    } else {
        n.join(" ")
    }
}

/// The PKW words (PROFIdrive 2.0 coding, reference §5.6).
fn pkw(b: &[u8], request: bool) -> String {
    let mut a = [0u8; 8];
    a.copy_from_slice(&b[..8]);
    let w = PkwWords::from_bytes(a);
    let ak = w.id >> 12;
    let pnu = w.id & pbcard::profile::pkw::PNU_MASK;
    if w.id == 0 && w.index == 0 && w.value() == 0 {
        return "PKW none".into();
    }
    let what = if request {
        match ak {
            1 => "read",
            2 => "change word",
            3 => "change dword",
            4 => "read description",
            6 => "read array",
            7 => "change array word",
            9 => "read array length",
            _ => "AK ?",
        }
    } else {
        match ak {
            1 => "value word",
            2 => "value dword",
            3 => "description",
            4 => "array word",
            5 => "array dword",
            6 => "array length",
            7 => "REJECTED",
            8 => "no change rights",
            _ => "AK ?",
        }
    };
    format!("PKW AK {ak} {what} PNU {pnu} IND {:04X} PWE {:04X} {:04X}", w.index, w.high, w.low)
}

/// The cyclic words of a known telegram: PKW, then STW1/ZSW1 by bit name, the main setpoint /
/// actual value as a percentage (0x4000 = 100 %), the other PZD words.
pub fn process_data(bytes: &[u8], telegram: pbcard::dpm::Telegram, outputs: bool) -> String {
    let pkw_words = telegram.pkw_words();
    let mut parts = Vec::new();
    let mut at = 0;
    if pkw_words > 0 && bytes.len() >= 8 {
        parts.push(pkw(bytes, outputs));
        at = 8;
    }
    let words: Vec<u16> = bytes[at..].chunks(2).map(|c| u16::from_be_bytes([c[0], *c.get(1).unwrap_or(&0)])).collect();
    let (w1, w2, names) = match (telegram, outputs) {
        (pbcard::dpm::Telegram::Standard(_), true) => ("STW1", "NSOLL_A", STW1),
        (pbcard::dpm::Telegram::Standard(_), false) => ("ZSW1", "NIST_A", ZSW1),
        (_, true) => ("STW", "HSW", STW1),
        (_, false) => ("ZSW", "HIW", ZSW1),
    };
    for (i, w) in words.iter().enumerate() {
        parts.push(match i {
            0 => format!("{w1} {w:04X} ({})", bits16(*w, names)),
            1 => format!("{w2} {w:04X} ({:+.1} %)", f64::from(*w as i16) * 100.0 / 16384.0),
            _ => format!("PZD{} {w:04X}", i + 1),
        });
    }
    parts.join(", ")
}
