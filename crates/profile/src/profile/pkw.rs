//! The PKW parameter channel: four words at the start of the cyclic data of PPO types 1, 2 and 5
//! (VACON OPTE3/E5 §6.5.4 / §6.6.2; INVT/IMO PROFIBUS-DP card §2.6; reference §5.5–5.6).
//!
//! | word | VACON §6.6.2 (Tables 119–123) | INVT §2.6 (Table 2-9) | PROFIdrive 2.0 (reference §5.6) |
//! |---|---|---|---|
//! | 1 | ID: type b15..b12, b11 unused, PNU b10..b0 | PKW1: request / response number | PKE: AK b15..b12, SPM b11, PNU b10..b0 |
//! | 2 | index: unused, 0 | PKW2: parameter address | IND: subindex in the high byte |
//! | 3 | value high (0) | PKW3: value high, or the error number | PWE1: value high |
//! | 4 | value low (value, or the fault code) | PKW4: value low | PWE2: value low, or the error number |
//!
//! All words are big-endian. Which dialect a variant speaks ([`PkwDialect`]):
//!
//! * **VACON** (OPTE3/E5 §6.6.2, Tables 120–122, examples §6.6.3): request 1 read (word),
//!   2 write (word); response 1 "parameter value ready (word)" — also after a write, with the
//!   value 0 (Table 130) — or 7 "request rejected" with a fault code of Table 122 in the low
//!   value word. The PNU is the drive's *application ID* and reaches "parameters from the drive
//!   only" (§6.6.1): it is executed as PNU [`VACON_DRIVE_PARAMETER`] (10001) with the ID as
//!   subindex, exactly as a DP-V1 request reaches a drive parameter (§6.4.4.7), so the card's
//!   own PNUs are never hit and the drive sees one addressing for both channels.
//! * **INVT** (§2.6, Tables 2-9 to 2-11 and the PKW example): PKW1 is a whole-word request
//!   number — 1 read, 4 write one word to RAM and EEPROM; 2, 3 and 5 exist but "are not
//!   supported currently" and are refused like an unknown number (error 1 "invalid command").
//!   Response 1 (one word in PKW4) or 2 (two words), or 3 with one of the error numbers 1–9 in
//!   PKW3. PKW2 is the parameter number as is.
//! * **PROFIdrive 2.0** (reference §5.6): the AK codes 1–9 (value, description element,
//!   array, number of array elements), responses 1–7 and 8 "no operator change rights"; the
//!   error number of AK 7 is the PROFIdrive error value itself (reference §5.1).
//!
//! Values: a read answers one element as the table gives it — one or two bytes as a word, four
//! bytes as a double word (VACON, which has no double-word response, sends a 32-bit value only
//! if it fits a word, §6.6.2.3 "Data word 1 (HIGH) is zero"). A word write takes the low value
//! word, the high one being 0 or the low word's sign extension (otherwise "out of limits"); it is
//! handed to the table as one Word (0x42), a double-word write as one Double word (0x43). INVT
//! and PROFIdrive 2.0 answer a write with the value written, VACON with 0 (Table 130). The
//! table's error additional info has no place in the PKW and is dropped; the error value is
//! translated per dialect ([`vacon_fault_code`], [`invt_error_number`]).
//!
//! Handshake (OPTE3/E5 §6.6.2: "The master repeats this request until it receives a response
//! from the slave. The slave repeats its response until it receives a new request"; reference
//! §5.6): [`PkwServer::on_request`] gets the PKW request of every Data_Exchange output. A
//! request that differs from the held one in any of its 8 bytes is a new job; the same bytes
//! again are the master repeating it and change nothing. A request of type 0 (INVT: PKW1 = 0)
//! is "no request", whatever the other words hold ([`is_no_request`]), and is answered with the
//! all-zero "no response". [`PkwServer::service`] (the DP-V1 / acyclic
//! task, not the interrupt) executes a job once against a [`ParameterAccess`] table; the
//! response then stays in [`PkwServer::response`] until the request changes. While a job has
//! no answer yet — not serviced, or an asynchronous table ([`ParameterAccess::pending`]) still
//! waiting for the drive — the response is all zero ("no response"): keeping the previous
//! response instead could be mistaken for the new job's (VACON answers a read and a write of
//! the same PNU with the same ID word, Tables 126 and 130).
//!
//! One job at a time on an asynchronous table: [`ParameterAccess::start_job`] empties the
//! table's answers, so the caller serves a PKW job and a record-47 job
//! ([`super::records::DriveRecords::is_busy`]) one after the other, not interleaved.

use super::param::{Attribute, ErrorValue, Format, ParamAddress, ParamError, ParameterAccess, ValueBlock, ValueWriter};

/// Bytes of the PKW field (four words).
pub const PKW_LEN: usize = 8;

/// The PNU through which a VACON PKW request reaches a drive parameter: "Parameter in drive",
/// the application ID as subindex (OPTE3/E5 Table 108, §6.4.4.7).
pub const VACON_DRIVE_PARAMETER: u16 = 10001;

/// The parameter number field of a PKE / VACON ID word: bits 10..0 (OPTE3/E5 Table 120;
/// reference §5.6).
pub const PNU_MASK: u16 = 0x07FF;

/// Which PKW coding a variant speaks (see the module documentation for the manual sections).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum PkwDialect {
    /// VACON OPTE3/E5 in PROFIdrive 2.0 mode with PPO 1/2/5 (§6.6.2–6.6.3).
    Vacon,
    /// The INVT/IMO PROFIBUS-DP card (§2.6, Tables 2-9 to 2-11).
    Invt,
    /// Generic PROFIdrive 2.0 PKW (reference §5.6).
    Profidrive2,
}

/// The four PKW words (request or response), in the order they are sent.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct PkwWords {
    /// Word 1: ID / PKE / PKW1.
    pub id: u16,
    /// Word 2: index / IND / PKW2.
    pub index: u16,
    /// Word 3: value high / PWE1 / PKW3.
    pub high: u16,
    /// Word 4: value low / PWE2 / PKW4.
    pub low: u16,
}

impl PkwWords {
    /// The words of an 8-byte PKW field (big-endian).
    pub const fn from_bytes(b: [u8; PKW_LEN]) -> Self {
        PkwWords {
            id: u16::from_be_bytes([b[0], b[1]]),
            index: u16::from_be_bytes([b[2], b[3]]),
            high: u16::from_be_bytes([b[4], b[5]]),
            low: u16::from_be_bytes([b[6], b[7]]),
        }
    }
    /// The 8 bytes of the field.
    pub const fn to_bytes(self) -> [u8; PKW_LEN] {
        let [a, b] = self.id.to_be_bytes();
        let [c, d] = self.index.to_be_bytes();
        let [e, f] = self.high.to_be_bytes();
        let [g, h] = self.low.to_be_bytes();
        [a, b, c, d, e, f, g, h]
    }
    /// The value words as one 32-bit value (high, low).
    pub const fn value(self) -> u32 {
        (self.high as u32) << 16 | self.low as u32
    }
}

/// VACON request / response types (OPTE3/E5 Table 121) and fault codes (Table 122).
pub mod vacon {
    /// Request 1: read parameter value (word); response 1: parameter value ready (word).
    pub const READ: u16 = 1;
    /// Request 2: write parameter value (word).
    pub const WRITE: u16 = 2;
    /// Response 7: request rejected (+ fault code).
    pub const REJECTED: u16 = 7;
    /// Fault code 0: illegal parameter.
    pub const ILLEGAL_PARAMETER: u16 = 0;
    /// Fault code 1: parameter is read-only.
    pub const READ_ONLY: u16 = 1;
    /// Fault code 2: parameter value is out of limits.
    pub const OUT_OF_LIMITS: u16 = 2;
    /// Fault code 17: request is temporarily rejected (e.g. only in STOP).
    pub const TEMPORARILY_REJECTED: u16 = 17;
    /// Fault code 18: unspecified fault.
    pub const UNSPECIFIED: u16 = 18;
    /// Fault code 101: unknown request type.
    pub const UNKNOWN_REQUEST: u16 = 101;
}

/// INVT request / response numbers (§2.6 Tables 2-10, 2-11) and error numbers (Table 2-11).
pub mod invt {
    /// Request 1: requesting the value of a parameter.
    pub const READ: u16 = 1;
    /// Request 2: modify one word in RAM ("not supported currently").
    pub const WRITE_WORD_RAM: u16 = 2;
    /// Request 3: modify two words in RAM ("not supported currently").
    pub const WRITE_DWORD_RAM: u16 = 3;
    /// Request 4: modify one word in RAM and EEPROM.
    pub const WRITE_WORD_EEPROM: u16 = 4;
    /// Request 5: modify two words in RAM and EEPROM ("not supported currently").
    pub const WRITE_DWORD_EEPROM: u16 = 5;
    /// Response 1: the value of a parameter (one word).
    pub const VALUE_WORD: u16 = 1;
    /// Response 2: the value of a parameter (two words).
    pub const VALUE_DWORD: u16 = 2;
    /// Response 3: the task cannot be executed, error number in PKW3.
    pub const REJECTED: u16 = 3;
    /// Error 1: invalid command.
    pub const INVALID_COMMAND: u16 = 1;
    /// Error 2: invalid data address.
    pub const INVALID_ADDRESS: u16 = 2;
    /// Error 3: invalid data value.
    pub const INVALID_VALUE: u16 = 3;
    /// Error 4: operation failure.
    pub const OPERATION_FAILURE: u16 = 4;
    /// Error 5: password error.
    pub const PASSWORD_ERROR: u16 = 5;
    /// Error 6: data frame error.
    pub const FRAME_ERROR: u16 = 6;
    /// Error 7: parameter read only.
    pub const READ_ONLY: u16 = 7;
    /// Error 8: parameter cannot be modified during inverter running.
    pub const NOT_WHILE_RUNNING: u16 = 8;
    /// Error 9: password protection.
    pub const PASSWORD_PROTECTED: u16 = 9;
}

/// PROFIdrive 2.0 AK codes (reference §5.6).
pub mod pd2 {
    /// Request AK 1: request parameter value; response AK 1: value (word).
    pub const READ: u16 = 1;
    /// Request AK 2: change parameter value (word); response AK 2: value (double word).
    pub const CHANGE_WORD: u16 = 2;
    /// Request AK 3: change parameter value (double word); response AK 3: description element.
    pub const CHANGE_DWORD: u16 = 3;
    /// Request AK 4: request description element; response AK 4: array value (word).
    pub const READ_DESCRIPTION: u16 = 4;
    /// Request AK 5: change description element; response AK 5: array value (double word).
    pub const CHANGE_DESCRIPTION: u16 = 5;
    /// Request AK 6: request parameter value (array); response AK 6: number of array elements.
    pub const READ_ARRAY: u16 = 6;
    /// Request AK 7: change parameter value (array, word); response AK 7: request cannot be
    /// executed (error number in PWE2).
    pub const CHANGE_ARRAY_WORD: u16 = 7;
    /// Request AK 8: change parameter value (array, double word); response AK 8: no operator
    /// change rights for the PKW interface.
    pub const CHANGE_ARRAY_DWORD: u16 = 8;
    /// Request AK 9: request number of array elements.
    pub const READ_ARRAY_LENGTH: u16 = 9;
    /// Response AK 7: request cannot be executed.
    pub const REJECTED: u16 = 7;
    /// Response AK 8: no operator change rights.
    pub const NO_CHANGE_RIGHTS: u16 = 8;
    /// The error number of an AK outside 1..=9 (the Siemens EEPROM/text codes 10–15 included):
    /// 0x6A "request not supported" (Siemens, reference §5.1; PROFIdrive 2.0 has no own number).
    pub const REQUEST_NOT_SUPPORTED: u16 = 0x6A;
}

/// The description element "number of array elements" (VACON Table 49, subindex 2), read for
/// PROFIdrive 2.0 AK 9.
const DESCRIPTION_ARRAY_ELEMENTS: u16 = 2;

/// What the channel has done, for the diagnosis / DPM status.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct PkwCounters {
    /// New jobs: non-zero requests that differ from the one before.
    pub jobs: u32,
    /// Jobs answered (positively or with an error).
    pub completed: u32,
    /// Jobs answered with an error (VACON 7, INVT 3, PROFIdrive 2.0 7 or 8).
    pub rejected: u32,
    /// Jobs replaced by a new request before they were answered.
    pub abandoned: u32,
}

/// Where the held request is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
enum Job {
    /// No request (all zero): the response is zero.
    Idle,
    /// A new request, not serviced yet.
    New,
    /// Serviced, but the asynchronous table is still waiting for the drive.
    Waiting,
    /// Answered: the response is held until the request changes.
    Done,
}

/// The slave's side of the PKW channel (sans-IO).
#[derive(Debug, Clone)]
pub struct PkwServer {
    dialect: PkwDialect,
    axis: u8,
    request: [u8; PKW_LEN],
    /// Writes are enabled for the held request ([`Self::on_request_enabled`]).
    enabled: bool,
    response: [u8; PKW_LEN],
    job: Job,
    counters: PkwCounters,
}

impl PkwServer {
    /// A server speaking `dialect`, with no request, addressing the table's axis 1 (VACON's
    /// DO-ID, OPTE3/E5 §6.4; [`ParameterAccess::has_axis`]).
    pub const fn new(dialect: PkwDialect) -> Self {
        PkwServer {
            dialect,
            axis: 1,
            request: [0; PKW_LEN],
            enabled: true,
            response: [0; PKW_LEN],
            job: Job::Idle,
            counters: PkwCounters { jobs: 0, completed: 0, rejected: 0, abandoned: 0 },
        }
    }

    /// Address axis `axis` of the table instead (WEG-style tables use 0).
    pub const fn with_axis(mut self, axis: u8) -> Self {
        self.axis = axis;
        self
    }

    /// The dialect.
    pub const fn dialect(&self) -> PkwDialect {
        self.dialect
    }

    /// The PKW request of a Data_Exchange output (the first 8 bytes of the PPO). Cheap: it only
    /// compares and copies 8 bytes, so it may run in the interrupt. A request different from
    /// the held one starts a new job (its response is zero until [`Self::service`] answers it);
    /// the same request again changes nothing; type 0 is "no request" ([`is_no_request`]).
    pub fn on_request(&mut self, request: [u8; PKW_LEN]) {
        self.on_request_enabled(request, true);
    }

    /// [`Self::on_request`] with the write permission of the cyclic data (INVT CW b8 "enable
    /// writing", INVT §2.6 Table 2-5; `true` for the other dialects): a write request with
    /// `write_enabled` false is rejected (INVT response 3, error 4 "operation failure" — the
    /// manual names no number for it, this is our choice) without reaching the table. The
    /// request together with the permission is the job: setting b8 later starts it anew.
    pub fn on_request_enabled(&mut self, request: [u8; PKW_LEN], write_enabled: bool) {
        if request == self.request && write_enabled == self.enabled {
            return;
        }
        self.enabled = write_enabled;
        if matches!(self.job, Job::New | Job::Waiting) {
            self.counters.abandoned = self.counters.abandoned.wrapping_add(1);
        }
        self.request = request;
        self.response = [0; PKW_LEN];
        self.job = if is_no_request(self.dialect, request) {
            Job::Idle
        } else {
            self.counters.jobs = self.counters.jobs.wrapping_add(1);
            Job::New
        };
    }

    /// Whether a job waits for [`Self::service`] (new, or waiting for an asynchronous table).
    pub fn is_busy(&self) -> bool {
        matches!(self.job, Job::New | Job::Waiting)
    }

    /// Execute the held job against `table` (the DP-V1 / acyclic task). A new job starts the
    /// table's job ([`ParameterAccess::start_job`]) and runs; while the table reports
    /// [`ParameterAccess::pending`] the job is run again on each call (an asynchronous table
    /// sends each drive request once per job and answers later calls from what it kept) and the
    /// response stays zero. An answered job is never run again: a write reaches a synchronous
    /// table once, however often the master repeats the request.
    pub fn service(&mut self, table: &mut impl ParameterAccess) {
        match self.job {
            Job::Idle | Job::Done => return,
            Job::New => {
                table.start_job();
                self.job = Job::Waiting;
            }
            Job::Waiting => {}
        }
        let req = PkwWords::from_bytes(self.request);
        let (response, rejected) = execute(self.dialect, self.axis, req, self.enabled, table);
        if table.pending() {
            return;
        }
        self.response = response.to_bytes();
        self.job = Job::Done;
        self.counters.completed = self.counters.completed.wrapping_add(1);
        if rejected {
            self.counters.rejected = self.counters.rejected.wrapping_add(1);
        }
    }

    /// The PKW response for the Data_Exchange input (the first 8 bytes of the PPO).
    pub fn response(&self) -> [u8; PKW_LEN] {
        self.response
    }

    /// The held request.
    pub fn request(&self) -> [u8; PKW_LEN] {
        self.request
    }

    /// The counters.
    pub fn counters(&self) -> PkwCounters {
        self.counters
    }

    /// Back to "no request" (the cyclic exchange ended); the counters stay.
    pub fn reset(&mut self) {
        if self.is_busy() {
            self.counters.abandoned = self.counters.abandoned.wrapping_add(1);
        }
        self.request = [0; PKW_LEN];
        self.response = [0; PKW_LEN];
        self.job = Job::Idle;
    }
}

/// Whether `request` is "no request" in `dialect`: request type 0 whatever the other words
/// hold (VACON OPTE3/E5 Table 121 "0 No request — No response"; PROFIdrive 2.0 AK 0,
/// reference §5.6), INVT PKW1 = 0 (§2.6 Table 2-10). It is answered with the all-zero "no
/// response", so a PLC handshake that waits for "no response" after clearing the type goes on.
pub fn is_no_request(dialect: PkwDialect, request: [u8; PKW_LEN]) -> bool {
    let id = u16::from_be_bytes([request[0], request[1]]);
    match dialect {
        PkwDialect::Vacon | PkwDialect::Profidrive2 => id >> 12 == 0,
        PkwDialect::Invt => id == 0,
    }
}

/// What a PKW request asks of the table.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Task {
    /// Read one element.
    Read { pnu: u16, subindex: u16 },
    /// Write one element from the value words (`dword`: both words, else the low one).
    Write { pnu: u16, subindex: u16, dword: bool },
    /// Read a description element (PROFIdrive 2.0 AK 4).
    Description { pnu: u16, element: u16 },
    /// Read the number of array elements (PROFIdrive 2.0 AK 9).
    ArrayLength { pnu: u16 },
}

/// A value read from the table: one word, or two.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Value {
    Word(u16),
    Dword(u32),
}

impl Value {
    /// The value words as one 32-bit value (a word in the low half).
    const fn raw(self) -> u32 {
        match self {
            Value::Word(w) => w as u32,
            Value::Dword(d) => d,
        }
    }
}

/// Why a job failed: a PROFIdrive error value from the table (or the checks here), or a request
/// the dialect does not know (answered with the dialect's own number).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Failure {
    Param(ErrorValue),
    UnknownRequest,
    /// A write without the cyclic data's write enable (INVT CW b8).
    WriteDisabled,
}

impl From<ParamError> for Failure {
    fn from(e: ParamError) -> Self {
        Failure::Param(e.value)
    }
}

impl From<ErrorValue> for Failure {
    fn from(e: ErrorValue) -> Self {
        Failure::Param(e)
    }
}

/// Run `req` against `table`; the response words and whether it is a rejection.
fn execute(
    dialect: PkwDialect,
    axis: u8,
    req: PkwWords,
    write_enabled: bool,
    table: &mut impl ParameterAccess,
) -> (PkwWords, bool) {
    let outcome = decode(dialect, req).and_then(|task| match task {
        Task::Write { .. } if !write_enabled => Err(Failure::WriteDisabled),
        task => run(dialect, axis, task, req, table),
    });
    let response = encode(dialect, req, outcome);
    (response, outcome.is_err())
}

/// The task of a (non-zero) request.
fn decode(dialect: PkwDialect, req: PkwWords) -> Result<Task, Failure> {
    let (kind, pnu) = (req.id >> 12, req.id & PNU_MASK);
    match dialect {
        PkwDialect::Vacon => {
            // The application ID, through PNU 10001 (§6.6.1, §6.4.4.7); the index is unused.
            let (pnu, subindex) = (VACON_DRIVE_PARAMETER, pnu);
            match kind {
                vacon::READ => Ok(Task::Read { pnu, subindex }),
                vacon::WRITE => Ok(Task::Write { pnu, subindex, dword: false }),
                _ => Err(Failure::UnknownRequest),
            }
        }
        PkwDialect::Invt => {
            let pnu = req.index;
            match req.id {
                invt::READ => Ok(Task::Read { pnu, subindex: 0 }),
                invt::WRITE_WORD_EEPROM => Ok(Task::Write { pnu, subindex: 0, dword: false }),
                // 2, 3, 5: "not supported currently" (§2.6 under Table 2-10); others unknown.
                _ => Err(Failure::UnknownRequest),
            }
        }
        PkwDialect::Profidrive2 => {
            let subindex = req.index >> 8;
            match kind {
                pd2::READ => Ok(Task::Read { pnu, subindex }),
                pd2::CHANGE_WORD => Ok(Task::Write { pnu, subindex, dword: false }),
                pd2::CHANGE_DWORD => Ok(Task::Write { pnu, subindex, dword: true }),
                pd2::READ_DESCRIPTION => Ok(Task::Description { pnu, element: subindex }),
                pd2::CHANGE_DESCRIPTION => Err(ErrorValue::DESCRIPTION_CANNOT_BE_CHANGED.into()),
                pd2::READ_ARRAY => Ok(Task::Read { pnu, subindex }),
                pd2::CHANGE_ARRAY_WORD => Ok(Task::Write { pnu, subindex, dword: false }),
                pd2::CHANGE_ARRAY_DWORD => Ok(Task::Write { pnu, subindex, dword: true }),
                pd2::READ_ARRAY_LENGTH => Ok(Task::ArrayLength { pnu }),
                _ => Err(Failure::UnknownRequest),
            }
        }
    }
}

/// Execute `task`: the value read (for a write: `None`).
fn run(
    dialect: PkwDialect,
    axis: u8,
    task: Task,
    req: PkwWords,
    table: &mut impl ParameterAccess,
) -> Result<Option<Value>, Failure> {
    if !table.has_axis(axis) {
        return Err(ErrorValue::AXIS_NONEXISTENT.into());
    }
    let address = |attribute, pnu, subindex| ParamAddress { attribute, elements: 1, pnu, subindex };
    match task {
        Task::Read { pnu, subindex } => {
            let v = read(table, axis, &address(Attribute::Value, pnu, subindex), false)?;
            // VACON has only the word response; its high value word is zero (§6.6.2.3).
            match (dialect, v) {
                (PkwDialect::Vacon, Value::Dword(d)) => word_of(d).map(|w| Some(Value::Word(w))),
                _ => Ok(Some(v)),
            }
        }
        Task::Write { pnu, subindex, dword } => {
            let (format, bytes): (Format, [u8; 4]) = if dword {
                (Format::DOUBLE_WORD, req.value().to_be_bytes())
            } else {
                // A word write carries the value in the low word; the high one is 0 (or the
                // sign extension of a negative value).
                let w = word_of(req.value()).map_err(|_| ErrorValue::LIMIT_EXCEEDED)?;
                let [a, b] = w.to_be_bytes();
                (Format::WORD, [a, b, 0, 0])
            };
            let len = format.value_size().unwrap_or(2);
            let block = ValueBlock { format, count: 1, bytes: &bytes[..len] };
            table.write_value(axis, &address(Attribute::Value, pnu, subindex), &block)?;
            Ok(None)
        }
        Task::Description { pnu, element } => {
            read(table, axis, &address(Attribute::Description, pnu, element), true).map(Some)
        }
        Task::ArrayLength { pnu } => {
            let v = read(table, axis, &address(Attribute::Description, pnu, DESCRIPTION_ARRAY_ELEMENTS), true)?;
            match v {
                Value::Word(n) => Ok(Some(Value::Word(n))),
                Value::Dword(n) => word_of(n).map(|w| Some(Value::Word(w))),
            }
        }
    }
}

/// A 32-bit value that fits one word: high word 0, or the sign extension of the low word.
fn word_of(v: u32) -> Result<u16, Failure> {
    let (high, low) = ((v >> 16) as u16, v as u16);
    match high {
        0 => Ok(low),
        0xFFFF if low & 0x8000 != 0 => Ok(low),
        _ => Err(ErrorValue::RESPONSE_TOO_LONG.into()),
    }
}

/// Read one value (or, with `bytes`, up to four bytes of a description element) from `table`.
fn read(table: &mut impl ParameterAccess, axis: u8, addr: &ParamAddress, bytes: bool) -> Result<Value, Failure> {
    let mut buf = [0u8; 8];
    let mut w = ValueWriter::new(&mut buf);
    match addr.attribute {
        Attribute::Description => table.read_description(axis, addr, &mut w),
        _ => table.read_value(axis, addr, &mut w),
    }?;
    let format = w.format().unwrap_or(Format::ZERO);
    let size = format.value_size().unwrap_or(0);
    if w.overflowed() {
        return Err(ErrorValue::RESPONSE_TOO_LONG.into());
    }
    if size == 0 || size * w.count() as usize != w.len() || (!bytes && w.count() != 1) {
        // A value this channel cannot carry, or a table that mixed sizes (as `param::respond`).
        return Err(ErrorValue::INCORRECT_DATA_TYPE.into());
    }
    let b = w.bytes();
    Ok(match b.len() {
        1 if format == Format::INTEGER8 => Value::Word(b[0] as i8 as i16 as u16),
        1 => Value::Word(u16::from(b[0])),
        2 => Value::Word(u16::from_be_bytes([b[0], b[1]])),
        4 => Value::Dword(u32::from_be_bytes([b[0], b[1], b[2], b[3]])),
        _ => return Err(ErrorValue::RESPONSE_TOO_LONG.into()),
    })
}

/// The response words of a job.
fn encode(dialect: PkwDialect, req: PkwWords, outcome: Result<Option<Value>, Failure>) -> PkwWords {
    let pnu = req.id & PNU_MASK;
    let kind = req.id >> 12;
    let words = |id: u16, index: u16, value: u32| PkwWords { id, index, high: (value >> 16) as u16, low: value as u16 };
    match dialect {
        PkwDialect::Vacon => match outcome {
            // Table 127; after a write, Table 130: type 1, value 0.
            Ok(Some(Value::Word(v))) => words(vacon::READ << 12 | pnu, 0, u32::from(v)),
            Ok(_) => words(vacon::READ << 12 | pnu, 0, 0),
            Err(f) => words(vacon::REJECTED << 12 | pnu, 0, u32::from(vacon_fault(f))),
        },
        PkwDialect::Invt => match outcome {
            Ok(Some(Value::Word(v))) => words(invt::VALUE_WORD, req.index, u32::from(v)),
            Ok(Some(Value::Dword(v))) => words(invt::VALUE_DWORD, req.index, v),
            // A one-word write answers with the value written (response 1, Table 2-10).
            Ok(None) => words(invt::VALUE_WORD, req.index, u32::from(req.low)),
            Err(f) => PkwWords { id: invt::REJECTED, index: req.index, high: invt_error(f), low: 0 },
        },
        PkwDialect::Profidrive2 => {
            let array = matches!(kind, pd2::READ_ARRAY | pd2::CHANGE_ARRAY_WORD | pd2::CHANGE_ARRAY_DWORD);
            let ak = |v: &Value| match (v, array) {
                (Value::Word(_), false) => 1,
                (Value::Dword(_), false) => 2,
                (Value::Word(_), true) => 4,
                (Value::Dword(_), true) => 5,
            };
            match outcome {
                Ok(Some(v)) => {
                    let code = match kind {
                        pd2::READ_DESCRIPTION => 3,
                        pd2::READ_ARRAY_LENGTH => 6,
                        _ => ak(&v),
                    };
                    words(code << 12 | pnu, req.index, v.raw())
                }
                // A change answers with the value written.
                Ok(None) => {
                    let v = match kind {
                        pd2::CHANGE_DWORD | pd2::CHANGE_ARRAY_DWORD => Value::Dword(req.value()),
                        _ => Value::Word(req.low),
                    };
                    words(ak(&v) << 12 | pnu, req.index, v.raw())
                }
                Err(Failure::Param(ErrorValue::NO_OPERATION_PRIORITY)) if is_change(kind) => {
                    words(pd2::NO_CHANGE_RIGHTS << 12 | pnu, req.index, 0)
                }
                Err(Failure::Param(e)) => words(pd2::REJECTED << 12 | pnu, req.index, u32::from(e.0)),
                Err(Failure::UnknownRequest) => {
                    words(pd2::REJECTED << 12 | pnu, req.index, u32::from(pd2::REQUEST_NOT_SUPPORTED))
                }
                Err(Failure::WriteDisabled) => words(pd2::NO_CHANGE_RIGHTS << 12 | pnu, req.index, 0),
            }
        }
    }
}

/// PROFIdrive 2.0 AKs that change a value.
fn is_change(kind: u16) -> bool {
    matches!(kind, pd2::CHANGE_WORD | pd2::CHANGE_DWORD | pd2::CHANGE_ARRAY_WORD | pd2::CHANGE_ARRAY_DWORD)
}

/// A failure as a VACON fault code (OPTE3/E5 Table 122). The mapping of PROFIdrive error values
/// onto the six codes is ours (the manual lists the codes only): parameter address errors → 0,
/// "cannot be changed" → 1, limits / value not permitted → 2, operating state / no operation
/// priority → 17, everything else → 18.
pub const fn vacon_fault_code(e: ErrorValue) -> u16 {
    match e {
        ErrorValue::IMPERMISSIBLE_PARAMETER_NUMBER
        | ErrorValue::INVALID_SUBINDEX
        | ErrorValue::NO_ARRAY
        | ErrorValue::IMPERMISSIBLE_ADDRESS
        | ErrorValue::AXIS_NONEXISTENT
        | ErrorValue::VACON_DRIVE_PARAMETER_NOT_FOUND => vacon::ILLEGAL_PARAMETER,
        ErrorValue::VALUE_CANNOT_BE_CHANGED
        | ErrorValue::DESCRIPTION_CANNOT_BE_CHANGED
        | ErrorValue::TEXT_CANNOT_BE_CHANGED => vacon::READ_ONLY,
        ErrorValue::LIMIT_EXCEEDED | ErrorValue::SETTING_NOT_PERMITTED | ErrorValue::VALUE_IMPERMISSIBLE => {
            vacon::OUT_OF_LIMITS
        }
        ErrorValue::NOT_EXECUTABLE | ErrorValue::NO_OPERATION_PRIORITY => vacon::TEMPORARILY_REJECTED,
        _ => vacon::UNSPECIFIED,
    }
}

fn vacon_fault(f: Failure) -> u16 {
    match f {
        Failure::Param(e) => vacon_fault_code(e),
        Failure::UnknownRequest => vacon::UNKNOWN_REQUEST,
        Failure::WriteDisabled => vacon::TEMPORARILY_REJECTED,
    }
}

/// A failure as an INVT error number (§2.6 Table 2-11). The mapping is ours (the manual lists
/// the numbers only): address errors → 2, limits / value not permitted → 3, "cannot be
/// changed" → 7, operating state → 8, no operation priority → 9 "password protection",
/// data type / format / number of values → 6 "data frame error", everything else → 4.
pub const fn invt_error_number(e: ErrorValue) -> u16 {
    match e {
        ErrorValue::IMPERMISSIBLE_PARAMETER_NUMBER
        | ErrorValue::INVALID_SUBINDEX
        | ErrorValue::NO_ARRAY
        | ErrorValue::IMPERMISSIBLE_ADDRESS
        | ErrorValue::AXIS_NONEXISTENT
        | ErrorValue::VACON_DRIVE_PARAMETER_NOT_FOUND => invt::INVALID_ADDRESS,
        ErrorValue::LIMIT_EXCEEDED | ErrorValue::SETTING_NOT_PERMITTED | ErrorValue::VALUE_IMPERMISSIBLE => {
            invt::INVALID_VALUE
        }
        ErrorValue::VALUE_CANNOT_BE_CHANGED
        | ErrorValue::DESCRIPTION_CANNOT_BE_CHANGED
        | ErrorValue::TEXT_CANNOT_BE_CHANGED => invt::READ_ONLY,
        ErrorValue::NOT_EXECUTABLE => invt::NOT_WHILE_RUNNING,
        ErrorValue::NO_OPERATION_PRIORITY => invt::PASSWORD_PROTECTED,
        ErrorValue::INCORRECT_DATA_TYPE | ErrorValue::ILLEGAL_FORMAT | ErrorValue::NUMBER_OF_VALUES_INCONSISTENT => {
            invt::FRAME_ERROR
        }
        _ => invt::OPERATION_FAILURE,
    }
}

fn invt_error(f: Failure) -> u16 {
    match f {
        Failure::Param(e) => invt_error_number(e),
        Failure::UnknownRequest => invt::INVALID_COMMAND,
        Failure::WriteDisabled => invt::OPERATION_FAILURE,
    }
}

#[cfg(test)]
mod tests {
    use super::super::table::{slots, ParamDef, Table, Type};
    use super::*;
    use crate::testkit::{FakeDrive, Indirect, Mailbox, Refusal};
    use proptest::prelude::*;

    /// One small drive: VACON application IDs 1, 102, 125 (OPTE3/E5 §6.6.3: maximum frequency
    /// 50.00 Hz = 5000, control place), the INVT example's address 0x0010 = 0x5000 (§2.6), the
    /// reference's 32-bit example 0x0A5CDD50 (§5.6), and one of each kind besides.
    const DEFS: &[ParamDef] = &[
        ParamDef::new(1, "Output freq", Type::U16).read_only().with_default(1234),
        ParamDef::new(0x0010, "Keypad freq", Type::U16).with_default(0x5000),
        ParamDef::new(21, "Status", Type::U16).read_only().with_default(7),
        ParamDef::new(30, "Counter", Type::U32).with_default(0x0A5C_DD50),
        ParamDef::new(31, "Offset", Type::I32).limits(-100_000, 100_000).with_default(-5),
        ParamDef::new(40, "Array", Type::U16).array(4).limits(0, 1000).with_defaults(&[1, 2, 3, 4]),
        ParamDef::new(50, "Small", Type::I16).limits(-100, 100).with_default(-3),
        ParamDef::new(102, "Max frequency", Type::U16).limits(0, 32000).with_default(5000),
        ParamDef::new(125, "Control place", Type::U16).limits(0, 3).with_default(1),
    ];
    const N: usize = slots(DEFS);
    const TABLE: Table<N> = Table::new(DEFS);

    /// A synchronous table that counts what reaches it (the one fake drive,
    /// `testkit::FakeDrive`, with the table above); VACON's PNU 10001 with the application ID
    /// as subindex is the table's PNU = ID (OPTE3/E5 §6.4.4.7).
    type Drive = FakeDrive<N>;

    fn drive() -> Drive {
        let ids = Indirect {
            pnu: VACON_DRIVE_PARAMETER,
            not_found: ErrorValue::IMPERMISSIBLE_PARAMETER_NUMBER,
            ids: 0..=u16::MAX,
            ids_only: false,
        };
        FakeDrive::with_table(TABLE).indirect(ids)
    }

    /// Every change refused with `error` (the drive's state).
    fn refuse(error: ErrorValue) -> Option<Refusal> {
        Some(Refusal { pnu: None, error })
    }

    /// An asynchronous table like the DPM mailbox (`dpm::params`): the one fake drive behind
    /// `testkit::Mailbox` (a value not answered yet is sent for, one at a time, and the table is
    /// pending; `deliver` lets the drive answer; answers are kept for the job).
    fn mailbox() -> Mailbox<Drive> {
        Mailbox::new(drive())
    }

    fn words(id: u16, index: u16, high: u16, low: u16) -> [u8; 8] {
        PkwWords { id, index, high, low }.to_bytes()
    }

    /// Give `req` once and service it: the response.
    fn exchange(s: &mut PkwServer, t: &mut impl ParameterAccess, req: [u8; 8]) -> [u8; 8] {
        s.on_request(req);
        s.service(t);
        s.response()
    }

    #[test]
    fn words_round_trip() {
        let b = [0x10, 0x66, 0x00, 0x00, 0x0A, 0x5C, 0xDD, 0x50];
        let w = PkwWords::from_bytes(b);
        assert_eq!((w.id, w.index, w.high, w.low, w.value()), (0x1066, 0, 0x0A5C, 0xDD50, 0x0A5C_DD50));
        assert_eq!(w.to_bytes(), b);
    }

    /// OPTE3/E5 §6.6.3.1 "Reading maximum frequency (ID=102)": request Table 124, response
    /// Table 126 (maximum frequency 50.00 Hz = 5000).
    #[test]
    fn vacon_6_6_3_1_read_maximum_frequency() {
        let mut s = PkwServer::new(PkwDialect::Vacon);
        let mut d = drive();
        let rsp = exchange(&mut s, &mut d, [0x10, 0x66, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00]);
        assert_eq!(rsp, [0x10, 0x66, 0x00, 0x00, 0x00, 0x00, 0x13, 0x88]);
    }

    /// OPTE3/E5 §6.6.3.2 "Writing control place (ID=125)": request Table 128, response Table
    /// 130. The manual contradicts itself: Table 131 explains the response's ID as "0x1066"
    /// while Table 130's bytes are 0x10 0x7D (and its own text says "0x07D = 125d"); the bytes
    /// of Table 130 are replayed.
    #[test]
    fn vacon_6_6_3_2_write_control_place() {
        let mut s = PkwServer::new(PkwDialect::Vacon);
        let mut d = drive();
        let rsp = exchange(&mut s, &mut d, [0x20, 0x7D, 0x00, 0x00, 0x00, 0x00, 0x00, 0x02]);
        assert_eq!(rsp, [0x10, 0x7D, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00]);
        assert_eq!(d.table.get(125, 0), Some(2));
    }

    /// INVT §2.6 "Example 1: Reading the value of a parameter", the only PKW example of the
    /// manual (the other two are PZD examples). Request `00 01 00 10 00 00 00 00`, response
    /// `00 01 00 10 00 00 50 00`. The text calls the address "10" and the value "5000" while the
    /// bytes are 0x0010 and 0x5000 (decimal numbers written as hex digits); the bytes are
    /// replayed literally, with address 0x0010 holding 0x5000.
    #[test]
    fn invt_example_1_read_keypad_frequency() {
        let mut s = PkwServer::new(PkwDialect::Invt);
        let mut d = drive();
        let rsp = exchange(&mut s, &mut d, [0x00, 0x01, 0x00, 0x10, 0x00, 0x00, 0x00, 0x00]);
        assert_eq!(rsp, [0x00, 0x01, 0x00, 0x10, 0x00, 0x00, 0x50, 0x00]);
    }

    /// Reference §5.6 (VAT): a 32-bit value 0x0A5CDD50 is PWE1 0x0A5C, PWE2 0xDD50.
    #[test]
    fn profidrive2_double_word_value() {
        let mut s = PkwServer::new(PkwDialect::Profidrive2);
        let mut d = drive();
        assert_eq!(exchange(&mut s, &mut d, words(0x1000 | 30, 0, 0, 0)), words(0x2000 | 30, 0, 0x0A5C, 0xDD50));
        // INVT: response 2 "two words" (Table 2-11).
        let mut s = PkwServer::new(PkwDialect::Invt);
        assert_eq!(exchange(&mut s, &mut d, words(1, 30, 0, 0)), words(2, 30, 0x0A5C, 0xDD50));
    }

    #[test]
    fn response_is_held_and_the_request_executed_once() {
        let mut s = PkwServer::new(PkwDialect::Vacon);
        let mut d = drive();
        let req = [0x20, 0x7D, 0, 0, 0, 0, 0, 3];
        s.on_request(req);
        assert!(s.is_busy());
        assert_eq!(s.response(), [0; 8], "no response before the job is serviced");
        for _ in 0..5 {
            s.on_request(req); // the master repeats the request every cycle
            s.service(&mut d);
            assert_eq!(s.response(), [0x10, 0x7D, 0, 0, 0, 0, 0, 0]);
        }
        assert_eq!(d.write_calls, 1, "a repeated request is not a new job");
        assert_eq!(d.table.get(125, 0), Some(3));
        let c = s.counters();
        assert_eq!((c.jobs, c.completed, c.rejected, c.abandoned), (1, 1, 0, 0));
        assert!(!s.is_busy());
    }

    #[test]
    fn new_job_only_on_change() {
        let mut s = PkwServer::new(PkwDialect::Vacon);
        let mut d = drive();
        let read = [0x10, 0x66, 0, 0, 0, 0, 0, 0];
        assert_eq!(exchange(&mut s, &mut d, read), [0x10, 0x66, 0, 0, 0, 0, 0x13, 0x88]);
        // The drive changes the value; the same request is not read again.
        d.table.set(102, 0, 4000).unwrap();
        assert_eq!(exchange(&mut s, &mut d, read), [0x10, 0x66, 0, 0, 0, 0, 0x13, 0x88]);
        assert_eq!(d.read_calls, 1);
        // "No request" in between (all zero), then the same request again: a new job.
        assert_eq!(exchange(&mut s, &mut d, [0; 8]), [0; 8]);
        assert!(!s.is_busy());
        assert_eq!(exchange(&mut s, &mut d, read), [0x10, 0x66, 0, 0, 0, 0, 0x0F, 0xA0]);
        assert_eq!(d.read_calls, 2);
        // Any changed byte is a new job, even one the dialect ignores (VACON's index).
        s.on_request([0x10, 0x66, 0, 1, 0, 0, 0, 0]);
        assert_eq!(s.response(), [0; 8], "the old response is not shown for the new job");
        s.service(&mut d);
        assert_eq!(d.read_calls, 3);
        assert_eq!(s.counters().jobs, 3);
    }

    #[test]
    fn asynchronous_table_pending_then_complete() {
        let mut s = PkwServer::new(PkwDialect::Vacon);
        let mut t = mailbox();
        let read = [0x10, 0x66, 0, 0, 0, 0, 0, 0];
        s.on_request(read);
        s.service(&mut t);
        assert!(s.is_busy() && t.inflight().is_some());
        assert_eq!(s.response(), [0; 8], "no response while the drive has not answered");
        s.service(&mut t); // the answer has not come: still nothing
        assert_eq!(s.response(), [0; 8]);
        t.deliver();
        s.on_request(read);
        s.service(&mut t);
        assert_eq!(s.response(), [0x10, 0x66, 0, 0, 0, 0, 0x13, 0x88]);
        assert!(!s.is_busy());
        assert_eq!(t.drive.read_calls, 1);
    }

    #[test]
    fn asynchronous_write_reaches_the_drive_once() {
        let mut s = PkwServer::new(PkwDialect::Invt);
        let mut t = mailbox();
        let write = words(invt::WRITE_WORD_EEPROM, 102, 0, 4200);
        for _ in 0..3 {
            s.on_request(write);
            s.service(&mut t);
            assert_eq!(s.response(), [0; 8]);
        }
        t.deliver();
        for _ in 0..3 {
            s.on_request(write);
            s.service(&mut t);
            assert_eq!(s.response(), words(invt::VALUE_WORD, 102, 0, 4200));
        }
        assert_eq!((t.drive.write_calls, t.drive.table.get(102, 0)), (1, Some(4200)));
        // A refused asynchronous write: the drive's error.
        let mut s = PkwServer::new(PkwDialect::Invt);
        let bad = words(invt::WRITE_WORD_EEPROM, 21, 0, 1);
        s.on_request(bad);
        s.service(&mut t);
        t.deliver();
        s.service(&mut t);
        assert_eq!(s.response(), words(invt::REJECTED, 21, invt::READ_ONLY, 0));
        assert_eq!(t.drive.write_calls, 2);
    }

    #[test]
    fn a_changed_request_replaces_a_waiting_job() {
        let mut s = PkwServer::new(PkwDialect::Vacon);
        let mut t = mailbox();
        s.on_request([0x20, 0x7D, 0, 0, 0, 0, 0, 2]);
        s.service(&mut t);
        s.on_request([0x10, 0x66, 0, 0, 0, 0, 0, 0]);
        assert_eq!(s.counters().abandoned, 1);
        s.service(&mut t); // start_job: the table forgets the write in flight
        t.deliver();
        s.service(&mut t);
        assert_eq!(s.response(), [0x10, 0x66, 0, 0, 0, 0, 0x13, 0x88]);
        assert_eq!(t.drive.write_calls, 0);
        s.reset();
        assert_eq!((s.request(), s.response(), s.is_busy()), ([0; 8], [0; 8], false));
    }

    #[test]
    fn vacon_fault_codes() {
        let mut d = drive();
        let ask = |req: [u8; 8], d: &mut Drive| exchange(&mut PkwServer::new(PkwDialect::Vacon), d, req);
        // Unknown ID: 0 illegal parameter.
        assert_eq!(ask([0x10, 0x07, 0, 0, 0, 0, 0, 0], &mut d), [0x70, 0x07, 0, 0, 0, 0, 0, 0]);
        // Read-only (ID 1): 1.
        assert_eq!(ask([0x20, 0x01, 0, 0, 0, 0, 0, 5], &mut d), [0x70, 0x01, 0, 0, 0, 0, 0, 1]);
        // Control place 9 is out of 0..=3: 2.
        assert_eq!(ask([0x20, 0x7D, 0, 0, 0, 0, 0, 9], &mut d), [0x70, 0x7D, 0, 0, 0, 0, 0, 2]);
        // A word write with a high word that is no sign extension: 2.
        assert_eq!(ask([0x20, 0x66, 0, 0, 0, 1, 0, 0], &mut d), [0x70, 0x66, 0, 0, 0, 0, 0, 2]);
        // Request types 3..=15 are unknown: 101.
        for t in 3..=15u8 {
            assert_eq!(ask([t << 4, 0x66, 0, 0, 0, 0, 0, 0], &mut d), [0x70, 0x66, 0, 0, 0, 0, 0, 101]);
        }
        // Temporarily rejected (the drive runs): 17; anything else: 18.
        d.refuse = refuse(ErrorValue::NOT_EXECUTABLE);
        assert_eq!(ask([0x20, 0x66, 0, 0, 0, 0, 0x13, 0x88], &mut d), [0x70, 0x66, 0, 0, 0, 0, 0, 17]);
        d.refuse = refuse(ErrorValue::RESPONSE_TOO_LONG);
        assert_eq!(ask([0x20, 0x66, 0, 0, 0, 0, 0x13, 0x88], &mut d), [0x70, 0x66, 0, 0, 0, 0, 0, 18]);
        // Bit 11 is not used; the index is ignored and answered 0.
        d.refuse = None;
        assert_eq!(ask([0x18, 0x66, 0x12, 0x34, 0, 0, 0, 0], &mut d), [0x10, 0x66, 0, 0, 0, 0, 0x13, 0x88]);
        assert_eq!(d.table.get(102, 0), Some(5000));
    }

    #[test]
    fn vacon_maps_every_error_value() {
        let cases = [
            (0x00, 0),
            (0x01, 1),
            (0x02, 2),
            (0x03, 0),
            (0x04, 0),
            (0x05, 18),
            (0x06, 2),
            (0x07, 1),
            (0x0B, 17),
            (0x11, 17),
            (0x14, 2),
            (0x16, 0),
            (0x19, 0),
            (0x6C, 0),
            (0x6D, 18),
        ];
        for (e, code) in cases {
            assert_eq!(vacon_fault_code(ErrorValue(e)), code, "error value {e:#x}");
        }
    }

    #[test]
    fn invt_error_numbers() {
        let mut d = drive();
        let ask = |req: [u8; 8], d: &mut Drive| exchange(&mut PkwServer::new(PkwDialect::Invt), d, req);
        assert_eq!(ask(words(1, 0x99, 0, 0), &mut d), words(3, 0x99, invt::INVALID_ADDRESS, 0));
        assert_eq!(ask(words(4, 21, 0, 1), &mut d), words(3, 21, invt::READ_ONLY, 0));
        assert_eq!(ask(words(4, 125, 0, 4), &mut d), words(3, 125, invt::INVALID_VALUE, 0));
        // Requests 2, 3, 5 are "not supported currently"; 6.. do not exist: 1 invalid command.
        for r in [2, 3, 5, 6, 0x1001, 0xFFFF] {
            assert_eq!(ask(words(r, 102, 0, 1), &mut d), words(3, 102, invt::INVALID_COMMAND, 0), "request {r}");
        }
        assert_eq!(d.write_calls, 2);
        // A one-word write to a 32-bit parameter: the data type does not fit (6).
        assert_eq!(ask(words(4, 30, 0, 1), &mut d), words(3, 30, invt::FRAME_ERROR, 0));
        d.refuse = refuse(ErrorValue::NOT_EXECUTABLE);
        assert_eq!(ask(words(4, 102, 0, 1), &mut d), words(3, 102, invt::NOT_WHILE_RUNNING, 0));
        d.refuse = refuse(ErrorValue::NO_OPERATION_PRIORITY);
        assert_eq!(ask(words(4, 102, 0, 1), &mut d), words(3, 102, invt::PASSWORD_PROTECTED, 0));
        d.refuse = refuse(ErrorValue::VACON_INVALID_CHANGE_REQUEST);
        assert_eq!(ask(words(4, 102, 0, 1), &mut d), words(3, 102, invt::OPERATION_FAILURE, 0));
        // Writes: response 1 with the value written; a negative Integer16.
        d.refuse = None;
        assert_eq!(ask(words(4, 50, 0xFFFF, 0xFFF6), &mut d), words(1, 50, 0, 0xFFF6));
        assert_eq!(d.table.get(50, 0), Some(-10));
        assert_eq!(ask(words(1, 50, 0, 0), &mut d), words(1, 50, 0, 0xFFF6));
    }

    #[test]
    fn profidrive2_requests() {
        let mut d = drive();
        let ask = |req: [u8; 8], d: &mut Drive| exchange(&mut PkwServer::new(PkwDialect::Profidrive2), d, req);
        // AK 1 → 1 (word); the IND is mirrored, the SPM bit is not answered.
        assert_eq!(ask(words(0x1800 | 102, 0, 0, 0), &mut d), words(0x1000 | 102, 0, 0, 5000));
        // AK 6 array element 2 → 4; IND subindex in the high byte, the low byte reserved.
        assert_eq!(ask(words(0x6000 | 40, 0x02AA, 0, 0), &mut d), words(0x4000 | 40, 0x02AA, 0, 3));
        // AK 7 change array word → 4 with the value.
        assert_eq!(ask(words(0x7000 | 40, 0x0300, 0, 999), &mut d), words(0x4000 | 40, 0x0300, 0, 999));
        assert_eq!(d.table.get(40, 3), Some(999));
        // AK 2 change word → 1; AK 3 change double word → 2.
        assert_eq!(ask(words(0x2000 | 125, 0, 0, 2), &mut d), words(0x1000 | 125, 0, 0, 2));
        assert_eq!(ask(words(0x3000 | 31, 0, 0xFFFE, 0x7960), &mut d), words(0x2000 | 31, 0, 0xFFFE, 0x7960));
        assert_eq!(d.table.get(31, 0), Some(-100_000));
        // AK 8 change array double word on a word array: incorrect data type (5).
        assert_eq!(ask(words(0x8000 | 40, 0, 0, 1), &mut d), words(0x7000 | 40, 0, 0, 5));
        // AK 9 number of array elements → 6.
        assert_eq!(ask(words(0x9000 | 40, 0, 0, 0), &mut d), words(0x6000 | 40, 0, 0, 4));
        // AK 4 description element 1 (identifier, Unsigned16) → 3; element 6 (the name, 16
        // characters) does not fit the PKW: 0x15.
        let id = d.table.description(102).map(|b| u16::from_be_bytes([b[0], b[1]])).unwrap();
        assert_eq!(ask(words(0x4000 | 102, 0x0100, 0, 0), &mut d), words(0x3000 | 102, 0x0100, 0, id));
        assert_eq!(ask(words(0x4000 | 102, 0x0600, 0, 0), &mut d), words(0x7000 | 102, 0x0600, 0, 0x15));
        // Errors: the PROFIdrive error value in PWE2.
        assert_eq!(ask(words(0x1000 | 99, 0, 0, 0), &mut d), words(0x7000 | 99, 0, 0, 0));
        assert_eq!(ask(words(0x2000 | 1, 0, 0, 1), &mut d), words(0x7000 | 1, 0, 0, 1));
        assert_eq!(ask(words(0x2000 | 125, 0, 0, 4), &mut d), words(0x7000 | 125, 0, 0, 2));
        assert_eq!(ask(words(0x6000 | 40, 0x0400, 0, 0), &mut d), words(0x7000 | 40, 0x0400, 0, 3));
        assert_eq!(ask(words(0x1000 | 102, 0x0100, 0, 0), &mut d), words(0x7000 | 102, 0x0100, 0, 4));
        assert_eq!(ask(words(0x5000 | 102, 0, 0, 0), &mut d), words(0x7000 | 102, 0, 0, 7));
        for ak in 10..=15u16 {
            assert_eq!(ask(words(ak << 12 | 102, 0, 0, 0), &mut d), words(0x7000 | 102, 0, 0, 0x6A));
        }
        // No operator change rights: AK 8 (for changes), AK 7 + 11 otherwise never arises.
        d.refuse = refuse(ErrorValue::NO_OPERATION_PRIORITY);
        assert_eq!(ask(words(0x2000 | 125, 0, 0, 2), &mut d), words(0x8000 | 125, 0, 0, 0));
    }

    #[test]
    fn missing_axis() {
        let mut d = drive();
        let mut s = PkwServer::new(PkwDialect::Profidrive2).with_axis(7);
        assert_eq!(exchange(&mut s, &mut d, words(0x1066, 0, 0, 0)), words(0x7066, 0, 0, 0x19));
        let mut s = PkwServer::new(PkwDialect::Vacon).with_axis(7);
        assert_eq!(exchange(&mut s, &mut d, words(0x1066, 0, 0, 0)), words(0x7066, 0, 0, 0));
        let mut s = PkwServer::new(PkwDialect::Invt).with_axis(0);
        assert_eq!(exchange(&mut s, &mut d, words(1, 102, 0, 0)), words(1, 102, 0, 5000));
        assert_eq!(s.dialect(), PkwDialect::Invt);
    }

    #[test]
    fn vacon_read_of_a_wide_value() {
        // VACON has only the word response: a 32-bit value that fits is sent, another is 18.
        let mut d = drive();
        let mut s = PkwServer::new(PkwDialect::Vacon);
        assert_eq!(exchange(&mut s, &mut d, [0x10, 31, 0, 0, 0, 0, 0, 0]), [0x10, 31, 0, 0, 0, 0, 0xFF, 0xFB]);
        assert_eq!(exchange(&mut s, &mut d, [0x10, 30, 0, 0, 0, 0, 0, 0]), [0x70, 30, 0, 0, 0, 0, 0, 18]);
    }

    #[derive(Debug, Clone)]
    enum Step {
        Request([u8; 8]),
        Service,
        Deliver,
    }

    fn request() -> impl Strategy<Value = [u8; 8]> {
        let pnu = prop_oneof![
            Just(0u16),
            Just(1),
            Just(0x10),
            Just(21),
            Just(30),
            Just(40),
            Just(102),
            Just(125),
            any::<u16>()
        ];
        let structured = (0u16..16, pnu, 0u16..6, any::<u16>(), any::<u16>(), any::<bool>()).prop_map(
            |(kind, pnu, index, high, low, invt_style)| {
                if invt_style {
                    words(kind, pnu, high, low)
                } else {
                    words(kind << 12 | (pnu & PNU_MASK), index << 8, high, low)
                }
            },
        );
        prop_oneof![Just([0u8; 8]), structured, any::<[u8; 8]>()]
    }

    fn steps() -> impl Strategy<Value = Vec<Step>> {
        let step = prop_oneof![
            3 => request().prop_map(Step::Request),
            3 => Just(Step::Service),
            1 => Just(Step::Deliver),
        ];
        proptest::collection::vec(step, 0..40)
    }

    fn dialect() -> impl Strategy<Value = PkwDialect> {
        prop_oneof![Just(PkwDialect::Vacon), Just(PkwDialect::Invt), Just(PkwDialect::Profidrive2)]
    }

    /// Run `steps`; the response after each step.
    fn replay(dialect: PkwDialect, steps: &[Step]) -> (Vec<[u8; 8]>, PkwCounters, u32) {
        let mut s = PkwServer::new(dialect);
        let mut t = mailbox();
        let mut trace = Vec::new();
        for step in steps {
            match step {
                Step::Request(r) => s.on_request(*r),
                Step::Service => s.service(&mut t),
                Step::Deliver => t.deliver(),
            }
            let rsp = s.response();
            // Invariants after every step.
            if s.is_busy() || is_no_request(dialect, s.request()) {
                assert_eq!(rsp, [0; 8], "{dialect:?}: a response without an answered job");
            } else {
                let (req, rsp) = (PkwWords::from_bytes(s.request()), PkwWords::from_bytes(rsp));
                match dialect {
                    PkwDialect::Vacon => {
                        assert_eq!(rsp.id & PNU_MASK, req.id & PNU_MASK);
                        assert!(matches!(rsp.id >> 12, 1 | 7) && rsp.index == 0 && rsp.high == 0, "{rsp:?}");
                    }
                    PkwDialect::Invt => {
                        assert!(matches!(rsp.id, 1..=3) && rsp.index == req.index, "{rsp:?}");
                        assert!(rsp.id != 1 || rsp.high == 0);
                    }
                    PkwDialect::Profidrive2 => {
                        assert_eq!((rsp.id & PNU_MASK, rsp.index), (req.id & PNU_MASK, req.index));
                        assert!(matches!(rsp.id >> 12, 1..=8) && rsp.id & 0x0800 == 0, "{rsp:?}");
                    }
                }
            }
            trace.push(rsp);
        }
        let c = s.counters();
        assert!(c.completed <= c.jobs && c.rejected <= c.completed);
        assert!(t.drive.write_calls <= c.jobs, "a job wrote more than once");
        (trace, c, t.drive.write_calls)
    }

    proptest! {
        #[test]
        fn any_sequence_keeps_the_invariants_and_is_deterministic(d in dialect(), steps in steps()) {
            let first = replay(d, &steps);
            let second = replay(d, &steps);
            prop_assert_eq!(first.0, second.0);
            prop_assert_eq!(first.1, second.1);
        }

        #[test]
        fn a_synchronous_table_answers_at_once(d in dialect(), reqs in proptest::collection::vec(request(), 1..20)) {
            let mut s = PkwServer::new(d);
            let mut t = drive();
            for r in reqs {
                let writes = t.write_calls;
                let was = s.request();
                s.on_request(r);
                s.service(&mut t);
                prop_assert!(!s.is_busy());
                prop_assert_eq!(s.response() == [0; 8], is_no_request(d, r));
                // Repeating it changes nothing.
                let rsp = s.response();
                let writes_after = t.write_calls;
                s.on_request(r);
                s.service(&mut t);
                prop_assert_eq!(s.response(), rsp);
                prop_assert_eq!(t.write_calls, writes_after);
                prop_assert!(t.write_calls - writes <= u32::from(r != was));
            }
        }
    }
}
