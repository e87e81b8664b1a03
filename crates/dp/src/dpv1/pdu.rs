//! DP-V1 PDUs (IEC 61158-6-3 MSAC_C1 / MSAC_C2; reference §4.2, §4.5).
//!
//! | function | code | request | positive response |
//! |---|---|---|---|
//! | Read | `5E` | `5E slot index length` (length = bytes wanted, 1..240) | `5E slot index n data[n]` |
//! | Write | `5F` | `5F slot index n data[n]` | `5F slot index n` |
//! | Data_Transport (C2) | `51` | `51 slot index n data[n]` | `51 slot index m data[m]` |
//! | Alarm_Ack (C1) | `5C` | `5C slot alarm_type specifier` | the same four bytes |
//! | Initiate (C2) | `57` | 16-byte header + S and D address blocks | 12-byte header + blocks, S and D swapped |
//! | Abort (C2) | `58` | `58 subnet instance_reason [detail]` | — |
//! | Idle (C2) | `48` | `48 [reserved]` | `48 00` |
//! | RM (C2 resource manager) | `56` | — | `56 server_sap poll_timeout(BE)` |
//!
//! A negative response is always 4 bytes: `function | 0x80, Error_Decode (0x80 = DP-V1),
//! Error_Code_1, Error_Code_2` ([`Response::Error`], [`ErrorCode1`]).
//!
//! The data unit reaches this codec already framed by FDL, so there is no "incomplete" outcome:
//! [`parse`] either gives a zero-copy [`Request`] view or says why the bytes are not one
//! ([`PduError`]). Responses are plain values ([`Response`]) emitted into a caller's buffer;
//! [`emit_data_header`] writes only the 4-byte header for a response whose data the caller has
//! already placed at `out[4..]` (no intermediate copy).

/// Largest user data of one MSAC_C1/C2 PDU, excluding the 4-byte header (`C1_Max_Data_Len` ≤ 240;
/// reference §4.2, §4.6).
pub const MAX_DATA_LEN: usize = 240;
/// The DP-V1 header: function, slot, index, length.
pub const HEADER_LEN: usize = 4;
/// Largest PDU: header + 240 data bytes.
pub const MAX_PDU_LEN: usize = HEADER_LEN + MAX_DATA_LEN;
/// Set in the function number of a negative response (`DPV1_ERROR_BIT_RESPONSE`).
pub const ERROR_BIT: u8 = 0x80;
/// Error_Decode of DP-V1 errors (0xFE = FMS, 0xFF = HART are other users).
pub const ERROR_DECODE_DPV1: u8 = 0x80;
/// The MSAC_C2 "extension" bit: C2 function numbers are the C1 ones with 0x40 set (reference §4.2).
pub const C2_EXTENSION_BIT: u8 = 0x40;
/// Initiate.req without address blocks (function, 3 reserved, Send_Timeout, features, profile
/// features, profile ident, S_Type, S_Len, D_Type, D_Len).
pub const INITIATE_REQ_HEADER_LEN: usize = 16;
/// The shortest Initiate.req: header + two 2-byte address blocks (`MSAC_C2_MIN_CR_PDU_SIZE`).
pub const INITIATE_REQ_MIN_LEN: usize = INITIATE_REQ_HEADER_LEN + 4;
/// Initiate.res without address blocks (`MSAC_C2_LEN_INITIATE_RES_HEAD`).
pub const INITIATE_RES_HEADER_LEN: usize = 12;

/// DP-V1 function number (the first PDU byte; reference §4.2, profichip `DPV1_FC_*`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[repr(u8)]
pub enum Function {
    /// Data_Transport (MSAC_C2 only).
    DataTransport = 0x51,
    /// Initiate: open an MSAC_C2 connection.
    Initiate = 0x57,
    /// Abort: close an MSAC_C2 connection.
    Abort = 0x58,
    /// Alarm_Ack (MSAC_C1).
    AlarmAck = 0x5C,
    /// DS_Read (Read data record).
    Read = 0x5E,
    /// DS_Write (Write data record).
    Write = 0x5F,
    /// Idle: MSAC_C2 keep-alive.
    Idle = 0x48,
    /// The resource manager's immediate answer to an Initiate on SAP 49 (slave → master only).
    ResourceManager = 0x56,
}

impl Function {
    /// The function with this number (the error bit must be clear).
    pub const fn from_code(code: u8) -> Option<Function> {
        Some(match code {
            0x51 => Function::DataTransport,
            0x57 => Function::Initiate,
            0x58 => Function::Abort,
            0x5C => Function::AlarmAck,
            0x5E => Function::Read,
            0x5F => Function::Write,
            0x48 => Function::Idle,
            0x56 => Function::ResourceManager,
            _ => return None,
        })
    }
    /// The function number.
    pub const fn code(self) -> u8 {
        self as u8
    }
    /// The function byte of a negative response (`code | 0x80`).
    pub const fn error_code(self) -> u8 {
        self as u8 | ERROR_BIT
    }
}

/// Error class: the high nibble of Error_Code_1 (reference §4.2).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum ErrorClass {
    /// 0x0..0x9: reserved.
    Reserved(u8),
    /// 0xA: application.
    Application,
    /// 0xB: access.
    Access,
    /// 0xC: resource.
    Resource,
    /// 0xD..0xF: user specific.
    User(u8),
}

/// Error_Code_1 of a negative response: class (high nibble) | code (low nibble). The named
/// constants are the IEC 61158-6 table (reference §4.2; profichip `DPV1_ERRCL_*`; VACON OPTE3/E5
/// manual §6.4.3.3 Table 46). Values outside it (user-specific codes) are kept as they are.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct ErrorCode1(pub u8);

impl ErrorCode1 {
    /// 0xA0 application: read error.
    pub const READ_ERROR: Self = Self(0xA0);
    /// 0xA1 application: write error.
    pub const WRITE_ERROR: Self = Self(0xA1);
    /// 0xA2 application: module failure.
    pub const MODULE_FAILURE: Self = Self(0xA2);
    /// 0xA8 application: version conflict.
    pub const VERSION_CONFLICT: Self = Self(0xA8);
    /// 0xA9 application: feature not supported.
    pub const FEATURE_NOT_SUPPORTED: Self = Self(0xA9);
    /// 0xB0 access: invalid index (VACON: "parameter requests are not supported" for a wrong
    /// index; note that the WEG manuals call 0xB0 "invalid slot", see `pbcard::profile::weg48`).
    pub const INVALID_INDEX: Self = Self(0xB0);
    /// 0xB1 access: write length error.
    pub const WRITE_LENGTH_ERROR: Self = Self(0xB1);
    /// 0xB2 access: invalid slot.
    pub const INVALID_SLOT: Self = Self(0xB2);
    /// 0xB3 access: type conflict (profichip's answer to a Read of length 0 or > 240).
    pub const TYPE_CONFLICT: Self = Self(0xB3);
    /// 0xB4 access: invalid area.
    pub const INVALID_AREA: Self = Self(0xB4);
    /// 0xB5 access: state conflict — PROFIdrive's "parameter response not yet available"
    /// (VACON Table 46: "temporarily not possible due to internal processing status").
    pub const STATE_CONFLICT: Self = Self(0xB5);
    /// 0xB6 access: access denied.
    pub const ACCESS_DENIED: Self = Self(0xB6);
    /// 0xB7 access: invalid range (VACON Table 46: "Write request with error in the parameter
    /// request header").
    pub const INVALID_RANGE: Self = Self(0xB7);
    /// 0xB8 access: invalid parameter.
    pub const INVALID_PARAMETER: Self = Self(0xB8);
    /// 0xB9 access: invalid type.
    pub const INVALID_TYPE: Self = Self(0xB9);
    /// 0xC0 resource: read constrain conflict.
    pub const READ_CONSTRAIN_CONFLICT: Self = Self(0xC0);
    /// 0xC1 resource: write constrain conflict.
    pub const WRITE_CONSTRAIN_CONFLICT: Self = Self(0xC1);
    /// 0xC2 resource: resource busy.
    pub const RESOURCE_BUSY: Self = Self(0xC2);
    /// 0xC3 resource: resource unavailable.
    pub const RESOURCE_UNAVAILABLE: Self = Self(0xC3);

    /// The error class (high nibble).
    pub const fn class(self) -> ErrorClass {
        match self.0 >> 4 {
            0xA => ErrorClass::Application,
            0xB => ErrorClass::Access,
            0xC => ErrorClass::Resource,
            c @ 0xD..=0xF => ErrorClass::User(c),
            c => ErrorClass::Reserved(c),
        }
    }
    /// The error code within the class (low nibble).
    pub const fn code(self) -> u8 {
        self.0 & 0x0F
    }
}

/// Why bytes are not a DP-V1 request (or response, for [`Response::parse`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[non_exhaustive]
pub enum PduError {
    /// No bytes at all.
    Empty,
    /// The first byte is no DP-V1 function number (for requests: also any byte with the error
    /// bit set).
    UnknownFunction(u8),
    /// A function that only ever travels the other way (the RM PDU 0x56 is slave → master).
    WrongDirection(Function),
    /// A PDU of fixed size (Read, Alarm_Ack, Abort, Idle, RM, error response, the header of
    /// Write/Data_Transport, the Initiate header) with the wrong number of bytes.
    WrongLength {
        /// the function
        function: Function,
        /// bytes received
        len: usize,
    },
    /// The length byte does not match the data that follows (Write, Data_Transport, read response).
    DataLengthMismatch {
        /// the function
        function: Function,
        /// the length byte
        declared: u8,
        /// data bytes present
        actual: usize,
    },
    /// Length byte 0 or above 240 (a Read asking for nothing or too much, an empty or oversize
    /// Write / Data_Transport).
    InvalidLength {
        /// the function
        function: Function,
        /// the length byte
        length: u8,
    },
    /// Initiate: S/D address blocks inconsistent — S_Len/D_Len ≠ 2 with type 0, a typed block
    /// shorter than API + SCL + Network_Address\[6\], or blocks not filling the PDU exactly.
    InitiateAddress {
        /// S_Type
        s_type: u8,
        /// S_Len
        s_len: u8,
        /// D_Type
        d_type: u8,
        /// D_Len
        d_len: u8,
    },
}

impl PduError {
    /// The function the bytes announced, if known.
    pub const fn function(&self) -> Option<Function> {
        match *self {
            PduError::Empty | PduError::UnknownFunction(_) => None,
            PduError::WrongDirection(function)
            | PduError::WrongLength { function, .. }
            | PduError::DataLengthMismatch { function, .. }
            | PduError::InvalidLength { function, .. } => Some(function),
            PduError::InitiateAddress { .. } => Some(Function::Initiate),
        }
    }

    /// The Error_Code_1 for a negative response to a malformed Read / Write / Data_Transport /
    /// Alarm_Ack (`None` for the MSAC_C2 connection PDUs, which are answered with an Abort — see
    /// [`PduError::abort_reason`] — and for bytes without a known function).
    ///
    /// Choice \[M\]: a Read of length 0 or > 240 gets 0xB3 type conflict as profichip's driver
    /// answers it; length errors of data-carrying requests get 0xB1 write length error.
    pub const fn error_code1(&self) -> Option<ErrorCode1> {
        match *self {
            PduError::Empty | PduError::UnknownFunction(_) | PduError::InitiateAddress { .. } => None,
            PduError::WrongDirection(_) => None,
            PduError::WrongLength { function, .. } | PduError::InvalidLength { function, .. } => match function {
                Function::Read | Function::AlarmAck => Some(ErrorCode1::TYPE_CONFLICT),
                Function::Write | Function::DataTransport => Some(ErrorCode1::WRITE_LENGTH_ERROR),
                _ => None,
            },
            PduError::DataLengthMismatch { function, .. } => match function {
                Function::Write | Function::DataTransport => Some(ErrorCode1::WRITE_LENGTH_ERROR),
                _ => None,
            },
        }
    }

    /// The Abort reason for a malformed MSAC_C2 connection PDU (Initiate, Abort, Idle):
    /// 7 invalid additional address information for bad S/D blocks, 2 invalid request PDU otherwise
    /// (reference §4.2, §4.5).
    pub const fn abort_reason(&self) -> Option<AbortReason> {
        match *self {
            PduError::InitiateAddress { .. } => Some(AbortReason::InvalidAddressInfo),
            PduError::WrongLength { function: Function::Initiate | Function::Abort | Function::Idle, .. } => {
                Some(AbortReason::InvalidRequestPdu)
            }
            _ => None,
        }
    }
}

/// Why a response could not be emitted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[non_exhaustive]
pub enum EmitError {
    /// More than 240 data bytes, or an address block that does not fit its length byte.
    TooLong,
    /// The output buffer is shorter than the PDU.
    BufferTooSmall {
        /// bytes the PDU needs
        needed: usize,
    },
}

/// Read request: `5E slot index length`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct ReadRequest {
    /// Slot number.
    pub slot: u8,
    /// Index (data record) within the slot.
    pub index: u8,
    /// Maximum number of bytes the master accepts (1..240; PROFIdrive masters ask for 240).
    pub length: u8,
}

/// Write or Data_Transport request: `5F|51 slot index n data[n]` (zero-copy: `data` borrows the PDU).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct DataRequest<'a> {
    /// Slot number.
    pub slot: u8,
    /// Index (data record) within the slot.
    pub index: u8,
    /// The record data (1..240 bytes).
    pub data: &'a [u8],
}

/// Alarm_Ack (request and positive response): `5C slot alarm_type specifier`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct AlarmAck {
    /// Slot that raised the alarm.
    pub slot: u8,
    /// Alarm_Type (1 diagnostic, 2 process, 3 pull, 4 plug, 5 status, 6 update, 32..126 manufacturer).
    pub alarm_type: u8,
    /// Specifier byte: b7..b3 Seq_Nr, b2 Add_Ack, b1..b0 alarm specifier.
    pub specifier: u8,
}

impl AlarmAck {
    /// Seq_Nr 0..31 (specifier b7..b3).
    pub const fn seq_nr(&self) -> u8 {
        self.specifier >> 3
    }
    /// Add_Ack (specifier b2): the alarm also needs a user acknowledgement.
    pub const fn add_ack(&self) -> bool {
        self.specifier & 0x04 != 0
    }
    /// Alarm specifier (b1..b0): 0 none, 1 appears, 2 disappears (slot ok), 3 disappears (slot still disturbed).
    pub const fn alarm_specifier(&self) -> u8 {
        self.specifier & 0x03
    }
}

/// Abort Subnet byte (reference §4.2).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum Subnet {
    /// 0: no subnet information.
    None,
    /// 1: local subnet.
    Local,
    /// 2: remote subnet.
    Remote,
    /// Anything else.
    Other(u8),
}

impl Subnet {
    /// Decode the Subnet byte.
    pub const fn from_u8(b: u8) -> Subnet {
        match b {
            0 => Subnet::None,
            1 => Subnet::Local,
            2 => Subnet::Remote,
            other => Subnet::Other(other),
        }
    }
    /// Encode the Subnet byte.
    pub const fn to_u8(self) -> u8 {
        match self {
            Subnet::None => 0,
            Subnet::Local => 1,
            Subnet::Remote => 2,
            Subnet::Other(b) => b,
        }
    }
}

/// Abort Instance (b5..b4 of the Instance/Reason byte): the layer that aborted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum Instance {
    /// 0x00: FDL.
    Fdl,
    /// 0x10: MSAC_C2.
    MsacC2,
    /// 0x20: user.
    User,
    /// 0x30: reserved.
    Reserved,
}

impl Instance {
    const fn from_bits(b: u8) -> Instance {
        match (b >> 4) & 0x03 {
            0 => Instance::Fdl,
            1 => Instance::MsacC2,
            2 => Instance::User,
            _ => Instance::Reserved,
        }
    }
    const fn bits(self) -> u8 {
        match self {
            Instance::Fdl => 0x00,
            Instance::MsacC2 => 0x10,
            Instance::User => 0x20,
            Instance::Reserved => 0x30,
        }
    }
}

/// Abort Reason_Code (b3..b0 of the Instance/Reason byte; reference §4.2, profichip).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum AbortReason {
    /// 1: sequence error.
    SequenceError,
    /// 2: invalid request PDU.
    InvalidRequestPdu,
    /// 3: connection (Send_Timeout) timeout.
    Timeout,
    /// 4: invalid response PDU.
    InvalidResponsePdu,
    /// 5: invalid service from the user.
    InvalidService,
    /// 6: Send_Timeout too small.
    SendTimeoutTooSmall,
    /// 7: invalid additional address information.
    InvalidAddressInfo,
    /// 8: waiting for FDL_DATA_REPLY.con.
    WaitingForReplyCon,
    /// 0xF: resource error.
    ResourceError,
    /// Any other code (0, 9..0xE; user-specific with instance USER).
    Other(u8),
}

impl AbortReason {
    /// Decode the low nibble.
    pub const fn from_bits(b: u8) -> AbortReason {
        match b & 0x0F {
            1 => AbortReason::SequenceError,
            2 => AbortReason::InvalidRequestPdu,
            3 => AbortReason::Timeout,
            4 => AbortReason::InvalidResponsePdu,
            5 => AbortReason::InvalidService,
            6 => AbortReason::SendTimeoutTooSmall,
            7 => AbortReason::InvalidAddressInfo,
            8 => AbortReason::WaitingForReplyCon,
            0xF => AbortReason::ResourceError,
            other => AbortReason::Other(other),
        }
    }
    /// The low nibble.
    pub const fn bits(self) -> u8 {
        match self {
            AbortReason::SequenceError => 1,
            AbortReason::InvalidRequestPdu => 2,
            AbortReason::Timeout => 3,
            AbortReason::InvalidResponsePdu => 4,
            AbortReason::InvalidService => 5,
            AbortReason::SendTimeoutTooSmall => 6,
            AbortReason::InvalidAddressInfo => 7,
            AbortReason::WaitingForReplyCon => 8,
            AbortReason::ResourceError => 0xF,
            AbortReason::Other(b) => b & 0x0F,
        }
    }
}

/// Abort PDU: `58 subnet instance_reason [detail]` (either direction).
///
/// The reference table gives 4 bytes; profichip's structure has a fourth "reserved" byte and its
/// own aborts are sent 3 bytes long, so [`parse`] accepts 3 or 4 bytes and [`Response::emit`]
/// sends 4 with `detail` (0 when `None`) \[U — check against a class-2 master trace\].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct Abort {
    /// Subnet.
    pub subnet: Subnet,
    /// The instance that aborted (b5..b4).
    pub instance: Instance,
    /// Reason_Code (b3..b0).
    pub reason: AbortReason,
    /// The additional detail byte, when present.
    pub detail: Option<u8>,
}

/// One Initiate address block (Add_Addr_Param): type 0 = `API, SCL` (2 bytes); type ≠ 0 =
/// `API, SCL, Network_Address[6], MAC_Address[n]` (reference §4.5).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct AddressBlock<'a> {
    /// S_Type / D_Type (0 = no network/MAC address).
    pub kind: u8,
    /// The block (S_Len / D_Len bytes).
    pub bytes: &'a [u8],
}

impl<'a> AddressBlock<'a> {
    /// API (application process instance).
    pub fn api(&self) -> u8 {
        self.bytes.first().copied().unwrap_or(0)
    }
    /// SCL (access level).
    pub fn scl(&self) -> u8 {
        self.bytes.get(1).copied().unwrap_or(0)
    }
    /// Network_Address (6 bytes), typed blocks only.
    pub fn network_address(&self) -> Option<&'a [u8]> {
        if self.kind == 0 {
            None
        } else {
            self.bytes.get(2..8)
        }
    }
    /// MAC_Address (the rest), typed blocks only.
    pub fn mac_address(&self) -> Option<&'a [u8]> {
        if self.kind == 0 {
            None
        } else {
            self.bytes.get(8..)
        }
    }
    fn is_valid(&self) -> bool {
        if self.kind == 0 {
            self.bytes.len() == 2
        } else {
            self.bytes.len() >= 8
        }
    }
}

/// Initiate.req (MSAC_C2 connect): zero-copy view (reference §4.5).
///
/// | offset | field |
/// |---|---|
/// | 0 | 0x57 |
/// | 1–3 | reserved |
/// | 4–5 | Send_Timeout (U16 BE, 10 ms) |
/// | 6–7 | Features_Supported_1/2 |
/// | 8–9 | Profile_Features_Supported_1/2 |
/// | 10–11 | Profile_Ident_Number |
/// | 12–15 | S_Type, S_Len, D_Type, D_Len |
/// | 16… | source block (S_Len), destination block (D_Len) |
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct InitiateRequest<'a> {
    /// Connection monitoring time the master asks for (unit 10 ms \[M\]).
    pub send_timeout: u16,
    /// Features_Supported_1/2 (b0 of byte 1: Read/Write supported).
    pub features_supported: [u8; 2],
    /// Profile_Features_Supported_1/2.
    pub profile_features_supported: [u8; 2],
    /// Profile_Ident_Number.
    pub profile_ident_number: u16,
    /// Source (the master's endpoint).
    pub source: AddressBlock<'a>,
    /// Destination (this slave's endpoint).
    pub destination: AddressBlock<'a>,
}

impl<'a> InitiateRequest<'a> {
    /// Whether the master supports DP-V1 Read/Write on the connection (Features_Supported_1 b0).
    pub const fn read_write_supported(&self) -> bool {
        self.features_supported[0] & 0x01 != 0
    }
    /// Bytes this request occupies.
    pub fn buffer_len(&self) -> usize {
        INITIATE_REQ_HEADER_LEN + self.source.bytes.len() + self.destination.bytes.len()
    }
    fn parse(pdu: &'a [u8]) -> Result<Self, PduError> {
        if pdu.len() < INITIATE_REQ_HEADER_LEN {
            return Err(PduError::WrongLength { function: Function::Initiate, len: pdu.len() });
        }
        let (source, destination) = address_blocks(pdu, 12, INITIATE_REQ_HEADER_LEN)?;
        Ok(InitiateRequest {
            send_timeout: be16(pdu, 4),
            features_supported: [pdu[6], pdu[7]],
            profile_features_supported: [pdu[8], pdu[9]],
            profile_ident_number: be16(pdu, 10),
            source,
            destination,
        })
    }
    /// Emit the request (what a class-2 master sends; for tests and simulated masters).
    pub fn emit(&self, out: &mut [u8]) -> Result<usize, EmitError> {
        let n = self.buffer_len();
        if n > MAX_PDU_LEN || self.source.bytes.len() > 255 || self.destination.bytes.len() > 255 {
            return Err(EmitError::TooLong);
        }
        let out = buffer(out, n)?;
        out[..4].copy_from_slice(&[Function::Initiate.code(), 0, 0, 0]);
        out[4..6].copy_from_slice(&self.send_timeout.to_be_bytes());
        out[6..8].copy_from_slice(&self.features_supported);
        out[8..10].copy_from_slice(&self.profile_features_supported);
        out[10..12].copy_from_slice(&self.profile_ident_number.to_be_bytes());
        emit_blocks(&mut out[12..], &self.source, &self.destination);
        Ok(n)
    }
}

/// Initiate.res (reference §4.5; profichip `MSAC_C2_INITIATE_RES_PDU_t`):
/// `57 Max_Len_Data_Unit Features_Supported_1/2 Profile_Features_Supported_1/2
/// Profile_Ident_Number(BE) S_Type S_Len D_Type D_Len source destination`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct InitiateResponse<'a> {
    /// Largest data unit the slave accepts on this connection (C2 buffer − 4, ≤ 240).
    pub max_len_data_unit: u8,
    /// Features_Supported_1/2 of the slave.
    pub features_supported: [u8; 2],
    /// Profile_Features_Supported_1/2 of the slave.
    pub profile_features_supported: [u8; 2],
    /// Profile_Ident_Number of the slave (0 = none).
    pub profile_ident_number: u16,
    /// Source: the slave's endpoint (the request's destination block).
    pub source: AddressBlock<'a>,
    /// Destination: the master's endpoint (the request's source block).
    pub destination: AddressBlock<'a>,
}

impl<'a> InitiateResponse<'a> {
    /// The positive answer to `req`, with the request's S and D blocks swapped (the slave's own
    /// endpoint becomes S), as profichip builds it.
    pub fn answering(
        req: &InitiateRequest<'a>,
        max_len_data_unit: u8,
        features_supported: [u8; 2],
        profile_features_supported: [u8; 2],
        profile_ident_number: u16,
    ) -> Self {
        InitiateResponse {
            max_len_data_unit,
            features_supported,
            profile_features_supported,
            profile_ident_number,
            source: req.destination,
            destination: req.source,
        }
    }
    /// Bytes this response occupies.
    pub fn buffer_len(&self) -> usize {
        INITIATE_RES_HEADER_LEN + self.source.bytes.len() + self.destination.bytes.len()
    }
    fn parse(pdu: &'a [u8]) -> Result<Self, PduError> {
        if pdu.len() < INITIATE_RES_HEADER_LEN {
            return Err(PduError::WrongLength { function: Function::Initiate, len: pdu.len() });
        }
        let (source, destination) = address_blocks(pdu, 8, INITIATE_RES_HEADER_LEN)?;
        Ok(InitiateResponse {
            max_len_data_unit: pdu[1],
            features_supported: [pdu[2], pdu[3]],
            profile_features_supported: [pdu[4], pdu[5]],
            profile_ident_number: be16(pdu, 6),
            source,
            destination,
        })
    }
    fn emit_into(&self, out: &mut [u8]) {
        out[0] = Function::Initiate.code();
        out[1] = self.max_len_data_unit;
        out[2..4].copy_from_slice(&self.features_supported);
        out[4..6].copy_from_slice(&self.profile_features_supported);
        out[6..8].copy_from_slice(&self.profile_ident_number.to_be_bytes());
        emit_blocks(&mut out[8..], &self.source, &self.destination);
    }
}

/// A DP-V1 request from a master (zero-copy view into the PDU).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum Request<'a> {
    /// DS_Read.
    Read(ReadRequest),
    /// DS_Write.
    Write(DataRequest<'a>),
    /// Data_Transport (MSAC_C2).
    DataTransport(DataRequest<'a>),
    /// Alarm_Ack (MSAC_C1).
    AlarmAck(AlarmAck),
    /// Initiate (MSAC_C2).
    Initiate(InitiateRequest<'a>),
    /// Abort (MSAC_C2).
    Abort(Abort),
    /// Idle (MSAC_C2 keep-alive).
    Idle,
}

impl<'a> Request<'a> {
    /// The function number of this request.
    pub const fn function(&self) -> Function {
        match self {
            Request::Read(_) => Function::Read,
            Request::Write(_) => Function::Write,
            Request::DataTransport(_) => Function::DataTransport,
            Request::AlarmAck(_) => Function::AlarmAck,
            Request::Initiate(_) => Function::Initiate,
            Request::Abort(_) => Function::Abort,
            Request::Idle => Function::Idle,
        }
    }

    /// Bytes the request occupies on the wire.
    pub fn buffer_len(&self) -> usize {
        match self {
            Request::Read(_) | Request::AlarmAck(_) | Request::Abort(_) => 4,
            Request::Write(w) | Request::DataTransport(w) => HEADER_LEN + w.data.len(),
            Request::Initiate(i) => i.buffer_len(),
            Request::Idle => 2,
        }
    }

    /// Emit the request (what a master sends; for tests and simulated masters).
    pub fn emit(&self, out: &mut [u8]) -> Result<usize, EmitError> {
        match self {
            Request::Read(r) => emit_fixed(out, [Function::Read.code(), r.slot, r.index, r.length]),
            Request::Write(w) => emit_data(out, Function::Write, w.slot, w.index, w.data),
            Request::DataTransport(w) => emit_data(out, Function::DataTransport, w.slot, w.index, w.data),
            Request::AlarmAck(a) => emit_alarm_ack(out, a),
            Request::Initiate(i) => i.emit(out),
            Request::Abort(a) => emit_abort(out, a),
            Request::Idle => emit_fixed(out, [Function::Idle.code(), 0]),
        }
    }
}

/// Parse a DP-V1 request PDU (the FDL data unit after the SAPs).
///
/// Checks everything the PDU itself can tell: a known function without the error bit, the
/// fixed sizes, a Read length of 1..240, a Write/Data_Transport length byte equal to the data
/// that follows and within 1..240, and Initiate S/D blocks that fill the PDU exactly. Whether
/// the slot, index or connection state fit is the caller's business.
pub fn parse(pdu: &[u8]) -> Result<Request<'_>, PduError> {
    let &code = pdu.first().ok_or(PduError::Empty)?;
    let function = Function::from_code(code).ok_or(PduError::UnknownFunction(code))?;
    let wrong_length = PduError::WrongLength { function, len: pdu.len() };
    match function {
        Function::Read => {
            let [_, slot, index, length] = *pdu else { return Err(wrong_length) };
            if length == 0 || length as usize > MAX_DATA_LEN {
                return Err(PduError::InvalidLength { function, length });
            }
            Ok(Request::Read(ReadRequest { slot, index, length }))
        }
        Function::Write | Function::DataTransport => {
            let r = parse_data(pdu, function)?;
            if r.data.is_empty() {
                return Err(PduError::InvalidLength { function, length: 0 });
            }
            Ok(if function == Function::Write { Request::Write(r) } else { Request::DataTransport(r) })
        }
        Function::AlarmAck => {
            let [_, slot, alarm_type, specifier] = *pdu else { return Err(wrong_length) };
            Ok(Request::AlarmAck(AlarmAck { slot, alarm_type, specifier }))
        }
        Function::Initiate => InitiateRequest::parse(pdu).map(Request::Initiate),
        Function::Abort => parse_abort(pdu).map(Request::Abort),
        Function::Idle => match pdu.len() {
            1 | 2 => Ok(Request::Idle),
            _ => Err(wrong_length),
        },
        Function::ResourceManager => Err(PduError::WrongDirection(function)),
    }
}

/// A DP-V1 response from the slave.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum Response<'a> {
    /// Positive DS_Read response: `5E slot index n data[n]`.
    Read(DataRequest<'a>),
    /// Positive DS_Write response: `5F slot index length` — `length` mirrors the request's length
    /// byte (DP-V1, profichip, the VACON OPTE3/E5 examples; the WEG manuals print 0 here).
    Write {
        /// Slot.
        slot: u8,
        /// Index.
        index: u8,
        /// Length of the data written.
        length: u8,
    },
    /// Positive Data_Transport response: `51 slot index n data[n]`.
    DataTransport(DataRequest<'a>),
    /// Positive Alarm_Ack response: the request's four bytes.
    AlarmAck(AlarmAck),
    /// Positive Initiate response.
    Initiate(InitiateResponse<'a>),
    /// Idle response `48 00` (2 bytes, profichip `MSAC_C2_LEN_IDLE_PDU`) \[U\].
    Idle,
    /// The resource manager's answer to Initiate on SAP 49: `56 server_sap poll_timeout(BE)`.
    ResourceManager {
        /// The connection SAP (0..48) the master continues on.
        server_sap: u8,
        /// Poll timeout (profichip: 0x64 at ≥ 1.5 Mbit/s, 0xC8 at 500k, 0x190 at 187.5k) \[U: unit\].
        poll_timeout: u16,
    },
    /// An Abort from the slave side (connection closed).
    Abort(Abort),
    /// Negative response: `function|0x80, Error_Decode, Error_Code_1, Error_Code_2`.
    Error {
        /// The function that failed.
        function: Function,
        /// Error_Decode (0x80 = DP-V1).
        decode: u8,
        /// Error_Code_1 (class | code).
        code1: ErrorCode1,
        /// Error_Code_2 (user specific; PROFIdrive: always 0).
        code2: u8,
    },
}

impl<'a> Response<'a> {
    /// A DP-V1 negative response (`Error_Decode` 0x80, `Error_Code_2` 0).
    pub const fn error(function: Function, code1: ErrorCode1) -> Response<'static> {
        Response::Error { function, decode: ERROR_DECODE_DPV1, code1, code2: 0 }
    }

    /// Bytes the response occupies.
    pub fn buffer_len(&self) -> usize {
        match self {
            Response::Read(d) | Response::DataTransport(d) => HEADER_LEN + d.data.len(),
            Response::Write { .. }
            | Response::AlarmAck(_)
            | Response::ResourceManager { .. }
            | Response::Abort(_)
            | Response::Error { .. } => 4,
            Response::Initiate(i) => i.buffer_len(),
            Response::Idle => 2,
        }
    }

    /// Emit the response into `out`; returns its length.
    pub fn emit(&self, out: &mut [u8]) -> Result<usize, EmitError> {
        match self {
            Response::Read(d) => emit_data(out, Function::Read, d.slot, d.index, d.data),
            Response::DataTransport(d) => emit_data(out, Function::DataTransport, d.slot, d.index, d.data),
            Response::Write { slot, index, length } => {
                emit_fixed(out, [Function::Write.code(), *slot, *index, *length])
            }
            Response::AlarmAck(a) => emit_alarm_ack(out, a),
            Response::Initiate(i) => {
                if i.buffer_len() > MAX_PDU_LEN || i.source.bytes.len() > 255 || i.destination.bytes.len() > 255 {
                    return Err(EmitError::TooLong);
                }
                let n = i.buffer_len();
                i.emit_into(buffer(out, n)?);
                Ok(n)
            }
            Response::Idle => emit_fixed(out, [Function::Idle.code(), 0]),
            Response::ResourceManager { server_sap, poll_timeout } => {
                let [hi, lo] = poll_timeout.to_be_bytes();
                emit_fixed(out, [Function::ResourceManager.code(), *server_sap, hi, lo])
            }
            Response::Abort(a) => emit_abort(out, a),
            Response::Error { function, decode, code1, code2 } => {
                emit_fixed(out, [function.error_code(), *decode, code1.0, *code2])
            }
        }
    }

    /// Parse a response PDU (the master's side; for tests and simulated masters).
    pub fn parse(pdu: &'a [u8]) -> Result<Self, PduError> {
        let &code = pdu.first().ok_or(PduError::Empty)?;
        let function = Function::from_code(code & !ERROR_BIT).ok_or(PduError::UnknownFunction(code))?;
        let wrong_length = PduError::WrongLength { function, len: pdu.len() };
        if code & ERROR_BIT != 0 {
            let [_, decode, code1, code2] = *pdu else { return Err(wrong_length) };
            return Ok(Response::Error { function, decode, code1: ErrorCode1(code1), code2 });
        }
        match function {
            Function::Read => {
                let r = parse_data(pdu, function)?;
                if r.data.len() > MAX_DATA_LEN {
                    return Err(PduError::InvalidLength { function, length: pdu[3] });
                }
                Ok(Response::Read(r))
            }
            Function::DataTransport => {
                let r = parse_data(pdu, function)?;
                if r.data.len() > MAX_DATA_LEN {
                    return Err(PduError::InvalidLength { function, length: pdu[3] });
                }
                Ok(Response::DataTransport(r))
            }
            Function::Write => {
                let [_, slot, index, length] = *pdu else { return Err(wrong_length) };
                Ok(Response::Write { slot, index, length })
            }
            Function::AlarmAck => {
                let [_, slot, alarm_type, specifier] = *pdu else { return Err(wrong_length) };
                Ok(Response::AlarmAck(AlarmAck { slot, alarm_type, specifier }))
            }
            Function::Initiate => InitiateResponse::parse(pdu).map(Response::Initiate),
            Function::Idle => match pdu.len() {
                1 | 2 => Ok(Response::Idle),
                _ => Err(wrong_length),
            },
            Function::ResourceManager => {
                let [_, server_sap, hi, lo] = *pdu else { return Err(wrong_length) };
                Ok(Response::ResourceManager { server_sap, poll_timeout: u16::from_be_bytes([hi, lo]) })
            }
            Function::Abort => parse_abort(pdu).map(Response::Abort),
        }
    }
}

/// Write the 4-byte header of a positive Read or Data_Transport response whose `data_len` data
/// bytes the caller has already placed at `out[4..4 + data_len]` (e.g. a PROFIdrive parameter
/// response built in place). Returns the PDU length.
pub fn emit_data_header(
    out: &mut [u8],
    function: Function,
    slot: u8,
    index: u8,
    data_len: usize,
) -> Result<usize, EmitError> {
    if data_len > MAX_DATA_LEN {
        return Err(EmitError::TooLong);
    }
    let n = HEADER_LEN + data_len;
    let out = buffer(out, n)?;
    out[..4].copy_from_slice(&[function.code(), slot, index, data_len as u8]);
    Ok(n)
}

fn be16(b: &[u8], at: usize) -> u16 {
    u16::from_be_bytes([b[at], b[at + 1]])
}

fn buffer(out: &mut [u8], n: usize) -> Result<&mut [u8], EmitError> {
    out.get_mut(..n).ok_or(EmitError::BufferTooSmall { needed: n })
}

fn emit_fixed<const N: usize>(out: &mut [u8], bytes: [u8; N]) -> Result<usize, EmitError> {
    buffer(out, N)?.copy_from_slice(&bytes);
    Ok(N)
}

fn emit_data(out: &mut [u8], function: Function, slot: u8, index: u8, data: &[u8]) -> Result<usize, EmitError> {
    let n = emit_data_header(out, function, slot, index, data.len())?;
    out[HEADER_LEN..n].copy_from_slice(data);
    Ok(n)
}

fn emit_alarm_ack(out: &mut [u8], a: &AlarmAck) -> Result<usize, EmitError> {
    emit_fixed(out, [Function::AlarmAck.code(), a.slot, a.alarm_type, a.specifier])
}

fn emit_abort(out: &mut [u8], a: &Abort) -> Result<usize, EmitError> {
    let ir = a.instance.bits() | a.reason.bits();
    emit_fixed(out, [Function::Abort.code(), a.subnet.to_u8(), ir, a.detail.unwrap_or(0)])
}

fn parse_data(pdu: &[u8], function: Function) -> Result<DataRequest<'_>, PduError> {
    if pdu.len() < HEADER_LEN {
        return Err(PduError::WrongLength { function, len: pdu.len() });
    }
    let declared = pdu[3];
    let data = &pdu[HEADER_LEN..];
    if data.len() != declared as usize {
        return Err(PduError::DataLengthMismatch { function, declared, actual: data.len() });
    }
    if data.len() > MAX_DATA_LEN {
        return Err(PduError::InvalidLength { function, length: declared });
    }
    Ok(DataRequest { slot: pdu[1], index: pdu[2], data })
}

fn parse_abort(pdu: &[u8]) -> Result<Abort, PduError> {
    let (subnet, ir, detail) = match *pdu {
        [_, subnet, ir] => (subnet, ir, None),
        [_, subnet, ir, detail] => (subnet, ir, Some(detail)),
        _ => return Err(PduError::WrongLength { function: Function::Abort, len: pdu.len() }),
    };
    Ok(Abort {
        subnet: Subnet::from_u8(subnet),
        instance: Instance::from_bits(ir),
        reason: AbortReason::from_bits(ir),
        detail,
    })
}

/// Split the S/D address blocks whose `S_Type S_Len D_Type D_Len` start at `at`, the blocks at `start`.
fn address_blocks(pdu: &[u8], at: usize, start: usize) -> Result<(AddressBlock<'_>, AddressBlock<'_>), PduError> {
    let (s_type, s_len, d_type, d_len) = (pdu[at], pdu[at + 1], pdu[at + 2], pdu[at + 3]);
    let bad = PduError::InitiateAddress { s_type, s_len, d_type, d_len };
    let blocks = &pdu[start..];
    if blocks.len() != s_len as usize + d_len as usize {
        return Err(bad);
    }
    let (s, d) = blocks.split_at(s_len as usize);
    let source = AddressBlock { kind: s_type, bytes: s };
    let destination = AddressBlock { kind: d_type, bytes: d };
    if !source.is_valid() || !destination.is_valid() {
        return Err(bad);
    }
    Ok((source, destination))
}

/// Write `S_Type S_Len D_Type D_Len` and both blocks; `out` is exactly long enough.
fn emit_blocks(out: &mut [u8], s: &AddressBlock<'_>, d: &AddressBlock<'_>) {
    out[..4].copy_from_slice(&[s.kind, s.bytes.len() as u8, d.kind, d.bytes.len() as u8]);
    let (sb, db) = out[4..].split_at_mut(s.bytes.len());
    sb.copy_from_slice(s.bytes);
    db.copy_from_slice(d.bytes);
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// VACON OPTE3/E5 manual §6.4.4.1 Table 55: DS_Write of a PROFIdrive request for PNU 918.
    const VACON_WRITE_918: [u8; 14] =
        [0x5F, 0x00, 0x2F, 0x0A, 0x01, 0x01, 0x01, 0x01, 0x10, 0x01, 0x03, 0x96, 0x00, 0x00];
    /// VACON §6.4.4.1 Table 56: the slave's write response.
    const VACON_WRITE_ACK: [u8; 4] = [0x5F, 0x00, 0x2F, 0x0A];
    /// VACON §6.4.4.2 Table 57 (and CFW500 §5.2.3 / CFW-11 §4.2.3: "Tamanho 240"): DS_Read of record 47.
    const VACON_READ_47: [u8; 4] = [0x5E, 0x00, 0x2F, 0xF0];
    /// VACON §6.4.4.2 Table 58: the read response carrying the parameter response.
    const VACON_READ_918_RESP: [u8; 12] = [0x5E, 0x00, 0x2F, 0x08, 0x01, 0x01, 0x01, 0x01, 0x42, 0x01, 0x00, 0x03];

    /// A class-2 Initiate with type-0 blocks: Send_Timeout 0x012C (3 s), Read/Write supported,
    /// profile ident 0x3A00 (hand-built after profichip's `MSAC_C2_INITIATE_REQ_PDU_t`).
    const INITIATE_TYPE0: [u8; 20] =
        [0x57, 0, 0, 0, 0x01, 0x2C, 0x01, 0x00, 0x00, 0x00, 0x3A, 0x00, 0, 2, 0, 2, 0x11, 0x22, 0x33, 0x44];

    #[test]
    fn golden_vacon_headers() {
        assert_eq!(
            parse(&VACON_WRITE_918),
            Ok(Request::Write(DataRequest { slot: 0, index: 47, data: &VACON_WRITE_918[4..] }))
        );
        assert_eq!(parse(&VACON_READ_47), Ok(Request::Read(ReadRequest { slot: 0, index: 47, length: 240 })));
        let mut out = [0u8; MAX_PDU_LEN];
        let n = Response::Write { slot: 0, index: 47, length: 10 }.emit(&mut out).unwrap();
        assert_eq!(&out[..n], &VACON_WRITE_ACK);
        let n =
            Response::Read(DataRequest { slot: 0, index: 47, data: &VACON_READ_918_RESP[4..] }).emit(&mut out).unwrap();
        assert_eq!(&out[..n], &VACON_READ_918_RESP);
        // In-place variant: data already at out[4..].
        let mut out = [0u8; MAX_PDU_LEN];
        out[4..12].copy_from_slice(&VACON_READ_918_RESP[4..]);
        let n = emit_data_header(&mut out, Function::Read, 0, 47, 8).unwrap();
        assert_eq!(&out[..n], &VACON_READ_918_RESP);
    }

    #[test]
    fn golden_error_responses() {
        // PROFIdrive "response not yet available": DE 80 B5 00 (reference §5.1; VACON Table 45/46).
        let mut out = [0u8; 4];
        let n = Response::error(Function::Read, ErrorCode1::STATE_CONFLICT).emit(&mut out).unwrap();
        assert_eq!(&out[..n], &[0xDE, 0x80, 0xB5, 0x00]);
        // WEG CFW500 §5.2.3 negative write response: DF 80 ec1 00.
        Response::error(Function::Write, ErrorCode1::INVALID_PARAMETER).emit(&mut out).unwrap();
        assert_eq!(out, [0xDF, 0x80, 0xB8, 0x00]);
        assert_eq!(
            Response::parse(&[0xDE, 0x80, 0xB5, 0x00]),
            Ok(Response::Error { function: Function::Read, decode: 0x80, code1: ErrorCode1(0xB5), code2: 0 })
        );
        assert_eq!(Function::Initiate.error_code(), 0xD7);
        assert_eq!(Function::DataTransport.error_code(), 0xD1);
        assert_eq!(Function::AlarmAck.error_code(), 0xDC);
    }

    #[test]
    fn error_code_classes() {
        assert_eq!(ErrorCode1::STATE_CONFLICT.class(), ErrorClass::Access);
        assert_eq!(ErrorCode1::STATE_CONFLICT.code(), 5);
        assert_eq!(ErrorCode1::FEATURE_NOT_SUPPORTED.class(), ErrorClass::Application);
        assert_eq!(ErrorCode1::RESOURCE_UNAVAILABLE.class(), ErrorClass::Resource);
        assert_eq!(ErrorCode1(0xD3).class(), ErrorClass::User(0xD));
        assert_eq!(ErrorCode1(0x42).class(), ErrorClass::Reserved(4));
        let table = [
            (ErrorCode1::READ_ERROR, 0xA0),
            (ErrorCode1::WRITE_ERROR, 0xA1),
            (ErrorCode1::MODULE_FAILURE, 0xA2),
            (ErrorCode1::VERSION_CONFLICT, 0xA8),
            (ErrorCode1::FEATURE_NOT_SUPPORTED, 0xA9),
            (ErrorCode1::INVALID_INDEX, 0xB0),
            (ErrorCode1::WRITE_LENGTH_ERROR, 0xB1),
            (ErrorCode1::INVALID_SLOT, 0xB2),
            (ErrorCode1::TYPE_CONFLICT, 0xB3),
            (ErrorCode1::INVALID_AREA, 0xB4),
            (ErrorCode1::STATE_CONFLICT, 0xB5),
            (ErrorCode1::ACCESS_DENIED, 0xB6),
            (ErrorCode1::INVALID_RANGE, 0xB7),
            (ErrorCode1::INVALID_PARAMETER, 0xB8),
            (ErrorCode1::INVALID_TYPE, 0xB9),
            (ErrorCode1::READ_CONSTRAIN_CONFLICT, 0xC0),
            (ErrorCode1::WRITE_CONSTRAIN_CONFLICT, 0xC1),
            (ErrorCode1::RESOURCE_BUSY, 0xC2),
            (ErrorCode1::RESOURCE_UNAVAILABLE, 0xC3),
        ];
        for (c, v) in table {
            assert_eq!(c.0, v);
        }
    }

    #[test]
    fn function_numbers() {
        for (f, code) in [
            (Function::Read, 0x5E),
            (Function::Write, 0x5F),
            (Function::AlarmAck, 0x5C),
            (Function::Initiate, 0x57),
            (Function::Abort, 0x58),
            (Function::DataTransport, 0x51),
            (Function::Idle, 0x48),
            (Function::ResourceManager, 0x56),
        ] {
            assert_eq!(f.code(), code);
            assert_eq!(Function::from_code(code), Some(f));
            assert_eq!(Function::from_code(code | ERROR_BIT), None);
        }
        // C2 numbers are the C1 ones with the extension bit (profichip MSAC_C2_FN_*).
        assert_eq!(Function::Initiate.code(), C2_EXTENSION_BIT | 0x17);
        assert_eq!(Function::Idle.code(), C2_EXTENSION_BIT | 0x08);
        assert_eq!(Function::Abort.code(), C2_EXTENSION_BIT | 0x18);
        assert_eq!(Function::DataTransport.code(), C2_EXTENSION_BIT | 0x11);
    }

    #[test]
    fn read_length_limits() {
        assert_eq!(parse(&[0x5E, 0, 47, 0]), Err(PduError::InvalidLength { function: Function::Read, length: 0 }));
        assert_eq!(parse(&[0x5E, 0, 47, 241]), Err(PduError::InvalidLength { function: Function::Read, length: 241 }));
        assert_eq!(parse(&[0x5E, 0, 47, 1]), Ok(Request::Read(ReadRequest { slot: 0, index: 47, length: 1 })));
        assert_eq!(
            PduError::InvalidLength { function: Function::Read, length: 0 }.error_code1(),
            Some(ErrorCode1(0xB3))
        );
        assert_eq!(parse(&[0x5E, 0, 47, 240, 0]), Err(PduError::WrongLength { function: Function::Read, len: 5 }));
    }

    #[test]
    fn write_length_limits() {
        let mut pdu = [0u8; MAX_PDU_LEN + 2];
        pdu[0] = 0x5F;
        pdu[3] = 240;
        assert!(matches!(parse(&pdu[..244]), Ok(Request::Write(DataRequest { data, .. })) if data.len() == 240));
        pdu[3] = 241;
        let e = parse(&pdu[..245]).unwrap_err();
        assert_eq!(e, PduError::InvalidLength { function: Function::Write, length: 241 });
        assert_eq!(e.error_code1(), Some(ErrorCode1::WRITE_LENGTH_ERROR));
        assert_eq!(parse(&[0x5F, 0, 47, 0]), Err(PduError::InvalidLength { function: Function::Write, length: 0 }));
        assert_eq!(
            parse(&[0x5F, 0, 47, 3, 1, 2]),
            Err(PduError::DataLengthMismatch { function: Function::Write, declared: 3, actual: 2 })
        );
        assert_eq!(
            parse(&[0x51, 1, 2, 1, 9, 9]),
            Err(PduError::DataLengthMismatch { function: Function::DataTransport, declared: 1, actual: 2 })
        );
        assert_eq!(
            parse(&[0x51, 1, 2, 1, 9]),
            Ok(Request::DataTransport(DataRequest { slot: 1, index: 2, data: &[9] }))
        );
        let mut out = [0u8; 8];
        assert_eq!(
            Response::Read(DataRequest { slot: 0, index: 0, data: &[0; 241] }).emit(&mut [0u8; 300]),
            Err(EmitError::TooLong)
        );
        assert_eq!(
            Response::Read(DataRequest { slot: 0, index: 0, data: &[0; 5] }).emit(&mut out),
            Err(EmitError::BufferTooSmall { needed: 9 })
        );
    }

    #[test]
    fn initiate_and_swapped_response() {
        let Ok(Request::Initiate(req)) = parse(&INITIATE_TYPE0) else { panic!("{:?}", parse(&INITIATE_TYPE0)) };
        assert_eq!(req.send_timeout, 300);
        assert!(req.read_write_supported());
        assert_eq!(req.profile_ident_number, 0x3A00);
        assert_eq!(req.source, AddressBlock { kind: 0, bytes: &[0x11, 0x22] });
        assert_eq!(req.destination, AddressBlock { kind: 0, bytes: &[0x33, 0x44] });
        assert_eq!((req.source.api(), req.source.scl(), req.source.network_address()), (0x11, 0x22, None));
        let resp = Response::Initiate(InitiateResponse::answering(&req, 236, [1, 0], [0, 0], 0x3A00));
        let mut out = [0u8; 32];
        let n = resp.emit(&mut out).unwrap();
        // 57, Max_Len_Data_Unit, features, profile features, ident, S = request's D, D = request's S.
        assert_eq!(&out[..n], &[0x57, 236, 1, 0, 0, 0, 0x3A, 0x00, 0, 2, 0, 2, 0x33, 0x44, 0x11, 0x22]);
        assert_eq!(Response::parse(&out[..n]), Ok(resp));

        // Typed blocks (API, SCL, Network_Address[6], MAC[n]): 10-byte S, 2-byte D.
        let mut typed = [0u8; 28];
        typed[..16].copy_from_slice(&[0x57, 0, 0, 0, 0, 100, 1, 0, 0, 0, 0, 0, 1, 10, 0, 2]);
        typed[16..26].copy_from_slice(&[1, 2, 10, 11, 12, 13, 14, 15, 0xAA, 0xBB]);
        typed[26..].copy_from_slice(&[0, 0]);
        let Ok(Request::Initiate(t)) = parse(&typed) else { panic!() };
        assert_eq!(t.source.network_address(), Some(&[10, 11, 12, 13, 14, 15][..]));
        assert_eq!(t.source.mac_address(), Some(&[0xAA, 0xBB][..]));
        let n = Response::Initiate(InitiateResponse::answering(&t, 240, [1, 0], [0, 0], 0)).emit(&mut out).unwrap();
        assert_eq!(&out[8..12], &[0, 2, 1, 10]);
        assert_eq!(&out[12..n], &[0, 0, 1, 2, 10, 11, 12, 13, 14, 15, 0xAA, 0xBB]);
    }

    #[test]
    fn initiate_rejections() {
        let bad = |s_type, s_len, d_type, d_len| PduError::InitiateAddress { s_type, s_len, d_type, d_len };
        let mut p = INITIATE_TYPE0;
        p[13] = 3; // S_Len ≠ 2 with S_Type 0
        assert_eq!(parse(&p), Err(bad(0, 3, 0, 2)));
        assert_eq!(bad(0, 3, 0, 2).abort_reason(), Some(AbortReason::InvalidAddressInfo));
        let mut p = INITIATE_TYPE0;
        p[12] = 1; // typed block needs ≥ 8 bytes
        assert_eq!(parse(&p), Err(bad(1, 2, 0, 2)));
        // Blocks must fill the PDU exactly.
        assert_eq!(parse(&INITIATE_TYPE0[..19]), Err(bad(0, 2, 0, 2)));
        let mut long = [0u8; 21];
        long[..20].copy_from_slice(&INITIATE_TYPE0);
        assert_eq!(parse(&long), Err(bad(0, 2, 0, 2)));
        let e = parse(&INITIATE_TYPE0[..15]).unwrap_err();
        assert_eq!(e, PduError::WrongLength { function: Function::Initiate, len: 15 });
        assert_eq!(e.abort_reason(), Some(AbortReason::InvalidRequestPdu));
        assert_eq!(e.error_code1(), None);
    }

    #[test]
    fn abort_idle_alarm_rm() {
        // Abort from the master: local subnet, instance MSAC_C2, reason 3 (timeout).
        let a =
            Abort { subnet: Subnet::Local, instance: Instance::MsacC2, reason: AbortReason::Timeout, detail: Some(0) };
        assert_eq!(parse(&[0x58, 0x01, 0x13, 0x00]), Ok(Request::Abort(a)));
        assert_eq!(parse(&[0x58, 0x01, 0x13]), Ok(Request::Abort(Abort { detail: None, ..a })));
        assert!(matches!(parse(&[0x58, 0x01]), Err(PduError::WrongLength { .. })));
        assert_eq!(
            parse(&[0x58, 0x00, 0x2A, 0x00]),
            Ok(Request::Abort(Abort {
                subnet: Subnet::None,
                instance: Instance::User,
                reason: AbortReason::Other(0xA),
                detail: Some(0)
            }))
        );
        let mut out = [0u8; 4];
        Response::Abort(a).emit(&mut out).unwrap();
        assert_eq!(out, [0x58, 0x01, 0x13, 0x00]);

        assert_eq!(parse(&[0x48]), Ok(Request::Idle));
        assert_eq!(parse(&[0x48, 0x00]), Ok(Request::Idle));
        assert!(parse(&[0x48, 0, 0]).is_err());
        assert_eq!(Response::Idle.emit(&mut out), Ok(2));
        assert_eq!(&out[..2], &[0x48, 0x00]);

        // Alarm_Ack: diagnostic alarm on slot 1, Seq_Nr 5, Add_Ack, "appears".
        let ack = AlarmAck { slot: 1, alarm_type: 1, specifier: (5 << 3) | 0x04 | 0x01 };
        assert_eq!(parse(&[0x5C, 1, 1, 0x2D]), Ok(Request::AlarmAck(ack)));
        assert_eq!((ack.seq_nr(), ack.add_ack(), ack.alarm_specifier()), (5, true, 1));
        Response::AlarmAck(ack).emit(&mut out).unwrap();
        assert_eq!(out, [0x5C, 1, 1, 0x2D]);

        // RM: server SAP 48, poll timeout 0x0064 (profichip at ≥ 1.5 Mbit/s).
        Response::ResourceManager { server_sap: 48, poll_timeout: 0x64 }.emit(&mut out).unwrap();
        assert_eq!(out, [0x56, 48, 0x00, 0x64]);
        assert_eq!(parse(&out), Err(PduError::WrongDirection(Function::ResourceManager)));
    }

    #[test]
    fn unknown_and_error_bit() {
        assert_eq!(parse(&[]), Err(PduError::Empty));
        assert_eq!(parse(&[0xDE, 0x80, 0xB5, 0]), Err(PduError::UnknownFunction(0xDE)));
        assert_eq!(parse(&[0x08, 0, 0xFD, 0xE8]), Err(PduError::UnknownFunction(0x08)));
        assert_eq!(PduError::UnknownFunction(0x08).error_code1(), None);
    }

    /// Every proper prefix of a valid request is rejected (never mistaken for a shorter valid PDU),
    /// except where the shorter form is itself valid (Abort without detail, Idle without reserved byte).
    #[test]
    fn every_prefix_rejected() {
        let samples: [&[u8]; 5] =
            [&VACON_WRITE_918, &VACON_READ_47, &INITIATE_TYPE0, &[0x5C, 1, 1, 0x2D], &[0x51, 0, 3, 2, 7, 8]];
        for s in samples {
            for k in 0..s.len() {
                assert!(parse(&s[..k]).is_err(), "{s:02X?} prefix {k} accepted");
            }
        }
    }

    /// Bit flips in a fixed-size or length-checked header are either rejected or change the
    /// decoded fields (nothing is silently reinterpreted as the original request).
    #[test]
    fn bit_flips_in_write_header() {
        let orig = parse(&VACON_WRITE_918).unwrap();
        for byte in 0..4 {
            for bit in 0..8 {
                let mut f = VACON_WRITE_918;
                f[byte] ^= 1 << bit;
                match parse(&f) {
                    Ok(r) => {
                        assert_ne!(r, orig, "flip {byte}.{bit}");
                        assert!(byte == 1 || byte == 2, "flip {byte}.{bit} accepted: {r:?}");
                    }
                    Err(_) => assert!(byte == 0 || byte == 3),
                }
            }
        }
    }

    fn arb_block() -> impl Strategy<Value = (u8, Vec<u8>)> {
        prop_oneof![
            proptest::collection::vec(any::<u8>(), 2..=2).prop_map(|b| (0u8, b)),
            (1u8..=255, proptest::collection::vec(any::<u8>(), 8..40)),
        ]
    }

    proptest! {
        #[test]
        fn data_request_roundtrip(write: bool, slot: u8, index: u8, data in proptest::collection::vec(any::<u8>(), 1..=240)) {
            let d = DataRequest { slot, index, data: &data };
            let r = if write { Request::Write(d) } else { Request::DataTransport(d) };
            let mut out = [0u8; MAX_PDU_LEN];
            let n = r.emit(&mut out).unwrap();
            prop_assert_eq!(n, r.buffer_len());
            prop_assert_eq!(parse(&out[..n]), Ok(r));
            let resp = if write { Response::Write { slot, index, length: data.len() as u8 } } else { Response::DataTransport(d) };
            let n = resp.emit(&mut out).unwrap();
            prop_assert_eq!(Response::parse(&out[..n]), Ok(resp));
            let rd = Response::Read(d);
            let n = rd.emit(&mut out).unwrap();
            prop_assert_eq!(Response::parse(&out[..n]), Ok(rd));
        }

        #[test]
        fn small_request_roundtrip(slot: u8, index: u8, length in 1u8..=240, t: u8, sp: u8, subnet: u8, ir in 0u8..0x40, detail: u8) {
            let mut out = [0u8; 8];
            for r in [
                Request::Read(ReadRequest { slot, index, length }),
                Request::AlarmAck(AlarmAck { slot, alarm_type: t, specifier: sp }),
                Request::Abort(Abort { subnet: Subnet::from_u8(subnet), instance: Instance::from_bits(ir), reason: AbortReason::from_bits(ir), detail: Some(detail) }),
                Request::Idle,
            ] {
                let n = r.emit(&mut out).unwrap();
                prop_assert_eq!(n, r.buffer_len());
                prop_assert_eq!(parse(&out[..n]), Ok(r));
            }
        }

        #[test]
        fn initiate_roundtrip(st: u16, f: [u8; 2], pf: [u8; 2], ident: u16, s in arb_block(), d in arb_block(), mldu: u8) {
            let req = InitiateRequest {
                send_timeout: st, features_supported: f, profile_features_supported: pf, profile_ident_number: ident,
                source: AddressBlock { kind: s.0, bytes: &s.1 }, destination: AddressBlock { kind: d.0, bytes: &d.1 },
            };
            let mut out = [0u8; MAX_PDU_LEN];
            let n = req.emit(&mut out).unwrap();
            prop_assert_eq!(parse(&out[..n]), Ok(Request::Initiate(req)));
            let resp = Response::Initiate(InitiateResponse::answering(&req, mldu, f, pf, ident));
            let n = resp.emit(&mut out).unwrap();
            prop_assert_eq!(n, INITIATE_RES_HEADER_LEN + s.1.len() + d.1.len());
            prop_assert_eq!(&out[INITIATE_RES_HEADER_LEN..INITIATE_RES_HEADER_LEN + d.1.len()], &d.1[..]);
            prop_assert_eq!(Response::parse(&out[..n]), Ok(resp));
        }

        #[test]
        fn error_roundtrip(f in prop_oneof![Just(Function::Read), Just(Function::Write), Just(Function::Initiate), Just(Function::DataTransport), Just(Function::AlarmAck)], c1: u8, c2: u8) {
            let e = Response::Error { function: f, decode: ERROR_DECODE_DPV1, code1: ErrorCode1(c1), code2: c2 };
            let mut out = [0u8; 4];
            e.emit(&mut out).unwrap();
            prop_assert_eq!(out[0], f.code() | 0x80);
            prop_assert_eq!(Response::parse(&out), Ok(e));
        }

        #[test]
        fn never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..260)) {
            if let Ok(r) = parse(&bytes) {
                // Whatever parses re-emits to the same bytes (Abort/Idle: canonical form;
                // Initiate: reserved bytes 1..3 are sent as 0).
                let mut out = [0u8; 260];
                let n = r.emit(&mut out).unwrap();
                let canonical = match r {
                    Request::Abort(_) | Request::Idle => false,
                    Request::Initiate(_) => bytes[1..4] == [0, 0, 0],
                    _ => true,
                };
                if canonical {
                    prop_assert_eq!(&out[..n], &bytes[..]);
                }
            }
            let _ = Response::parse(&bytes);
            let _ = parse(&bytes).map_err(|e| (e.error_code1(), e.abort_reason(), e.function()));
        }
    }
}
