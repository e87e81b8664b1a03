//! The drive's data records at slot 0 (the device) and at the drive module's slot 1
//! ([`RecordConfig::slots`], GSD `SlotDefinition`; this card: `card::RECORDS`), reached by DS_Read / DS_Write over
//! MSAC_C1 or MSAC_C2 — the same records at both slots:
//!
//! | index | record | manual |
//! |---|---|---|
//! | 47 | PROFIdrive base-mode parameter access: DS_Write carries the request, DS_Read fetches the response once | OPTE3/E5 §6.4, CFW500 §5.2.2, CFW-11 §4.2 |
//! | 48 | WEG simple access: 4 bytes = write, 2 bytes = select for the next read | CFW500 §5.2.3 |
//!
//! Errors (DP-V1 Error_Code_1): another slot → 0xB2 invalid slot; another index → 0xB0 invalid
//! index; a structurally wrong parameter request → 0xB7 at the DS_Write (VACON Table 46,
//! CFW500 §5.2.4); DS_Read of record 47 without a response waiting → 0xB5 state conflict
//! (reference §5.1: "not ready"; also after the response was fetched — it is readable once);
//! a DS_Read shorter than the response → 0xB1 (the response stays for a read with room).
//!
//! Asynchronous tables: a DS_Write(47) keeps the request (the job). When the table reports
//! [`ParameterAccess::pending`] after building the response, the job stays busy (DS_Read →
//! 0xB5 meanwhile) and [`DriveRecords::retry`] builds it again until it is complete; a new
//! DS_Write of the same relation replaces the job.
//!
//! Relations (MSAC_C1 and each MSAC_C2 connection) are kept apart: each fetches only its own
//! response, and one job runs at a time — a DS_Write(47) of another relation while a job is
//! busy is answered 0xC2 "resource busy" (the master repeats it). When a relation ends (MSAC_C1
//! leaves data exchange, an MSAC_C2 connection is aborted or times out) its response and its
//! job are dropped ([`DriveRecords::end_relation`]). Record 48 answers 0xC2 "resource busy" while a value is pending
//! (the master repeats the access).
//!
//! [`CardRecords`] is what the card's composition owns and passes to
//! [`Node::process_acyclic`](crate::node::Node::process_acyclic) ([`CardRecords::with`] the
//! drive's parameter table): records 47 / 48 over the card's own PNUs ([`CardTable`]: the
//! station context the node hands in, the fault buffer and the [`ProcessView`] the application
//! hands in) in front of the drive's parameters — the [`DataRecords`] the node serves behind
//! I&M.

use super::param::{respond, ParamRequest, ParameterAccess, MAX_LEN};
use super::pnu::{CardInfo, CardTable, ProcessView, FAULT_BUFFER_LEN};
use super::selection::Telegram;
use super::weg48::SimpleAccess;
use crate::dpv1::pdu::ErrorCode1;
use crate::dpv1::records::RecordHandler;
use crate::node::{DataRecords, StationInfo};
use crate::time::Instant;

/// PROFIdrive parameter access record.
pub const INDEX_PROFIDRIVE: u8 = 47;
/// WEG simple access record.
pub const INDEX_WEG_SIMPLE: u8 = 48;
/// The axis WEG's simple access addresses (DO-ID 0).
const WEG_AXIS: u8 = 0;

/// Which product's DP-V1 error list the records answer with (issue 15 item 9).
///
/// WEG (CFW500 §5.2.3, CFW-11 §4.2.3) lists B0h, B2h, B5h "modification not allowed for the
/// parameter", B6h, B7h, B8h and C3h "response not available for the reading request" — no
/// C2h, and B5h means something else there. Under a WEG telegram the card therefore answers
/// C3h where it answers B5h "state conflict" (DS_Read of record 47 before the response is
/// ready) or C2h "resource busy" (record 48 while the value is on its way; a DS_Write(47)
/// while another relation's job waits) for the others (OPTE3/E5 Table 46, reference §5.1).
/// WEG's list names B0h "invalid slot" and B2h "invalid index", the reverse of IEC 61158-6
/// (B0h invalid index, B2h invalid slot) that VACON and our slot/index routing follow; we keep
/// the standard's coding for every product (a contradiction of the WEG manual with the
/// standard, resolved for the standard).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum RecordErrors {
    /// PROFIdrive / VACON (OPTE3/E5 Table 46): B5h not ready, C2h busy.
    #[default]
    Profidrive,
    /// WEG CFW500 / CFW-11: C3h for both.
    Weg,
}

impl RecordErrors {
    /// The list for the active telegram (WEG telegrams: [`RecordErrors::Weg`]).
    pub const fn for_telegram(t: crate::profile::selection::Telegram) -> RecordErrors {
        use crate::profile::selection::{Family, Telegram};
        match t {
            Telegram::Vendor(Family::WegCfw500 | Family::WegCfw11, _) => RecordErrors::Weg,
            _ => RecordErrors::Profidrive,
        }
    }

    const fn not_ready(self) -> ErrorCode1 {
        match self {
            RecordErrors::Profidrive => ErrorCode1::STATE_CONFLICT,
            RecordErrors::Weg => ErrorCode1::RESOURCE_UNAVAILABLE,
        }
    }

    const fn busy(self) -> ErrorCode1 {
        match self {
            RecordErrors::Profidrive => ErrorCode1::RESOURCE_BUSY,
            RecordErrors::Weg => ErrorCode1::RESOURCE_UNAVAILABLE,
        }
    }
}

/// Relations with a record-47 response of their own: MSAC_C1 and every MSAC_C2 connection.
pub const RELATIONS: usize = 1 + crate::node::C2_CHANNELS;

/// Records 47 and 48 over one parameter table.
#[derive(Debug, Clone)]
pub struct DriveRecords {
    request: [u8; MAX_LEN],
    request_len: usize,
    /// The job in `request` waits for values of an asynchronous table.
    busy: bool,
    /// The relation whose job `request` is.
    owner: u8,
    /// The relation of the current access ([`RecordHandler::set_relation`]).
    relation: u8,
    building: [u8; MAX_LEN],
    responses: [[u8; MAX_LEN]; RELATIONS],
    response_lens: [usize; RELATIONS],
    weg: SimpleAccess,
    errors: RecordErrors,
    /// The slots at which the records answer ([`RecordConfig::slots`]).
    slots: &'static [u8],
}

/// What a product states about itself in its PROFIdrive data records (configuration as data:
/// the product's `card.rs` gives it, the profile layer never names the product).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RecordConfig {
    /// The DP-V1 slots at which records 47 / 48 answer (GSD `SlotDefinition`; reference §5.1:
    /// the device, slot 0, as Balluff, VACON and WEG address it, and the drive module's slot,
    /// as ABB adapters and SINAMICS address the drive object). Any other slot: 0xB2.
    pub slots: &'static [u8],
    /// PNU 964 (drive unit identification, OPTE3/E5 Table 110 structure) under the generic
    /// PROFIdrive, INVT and WEG CFW500 frames: manufacturer (PI vendor ID), drive unit type,
    /// software version (major × 100 + minor), firmware year, day/month as ddmm, number of
    /// drive objects. The VACON and CFW-11 variants are the manuals' own
    /// ([`CardInfo::DEVICE_ID_VACON`], [`CardInfo::DEVICE_ID_CFW11`]).
    pub device_id: [u16; 6],
}

impl DriveRecords {
    /// No response waiting, nothing selected; answering at `slots`.
    pub const fn new(slots: &'static [u8]) -> Self {
        DriveRecords {
            request: [0; MAX_LEN],
            request_len: 0,
            busy: false,
            owner: 0,
            relation: 0,
            building: [0; MAX_LEN],
            responses: [[0; MAX_LEN]; RELATIONS],
            response_lens: [0; RELATIONS],
            weg: SimpleAccess::new(),
            errors: RecordErrors::Profidrive,
            slots,
        }
    }

    /// Answer with `errors`' codes from now on ([`RecordErrors::for_telegram`]).
    pub fn set_errors(&mut self, errors: RecordErrors) {
        self.errors = errors;
    }

    /// Forget a waiting response or job (the relation that carried the request ended).
    pub fn reset(&mut self) {
        self.response_lens = [0; RELATIONS];
        self.busy = false;
    }

    /// The application relation `relation` ended (MSAC_C1 left data exchange, an MSAC_C2
    /// connection was aborted or timed out): its waiting response is dropped and, if the busy
    /// job is its own, the job too — an orphaned job would block the other relations with
    /// 0xC2 and a new relation must never read the old one's answer.
    pub fn end_relation(&mut self, relation: u8) {
        if let Some(len) = self.response_lens.get_mut(relation as usize) {
            *len = 0;
        }
        if self.busy && self.owner == relation {
            self.busy = false;
        }
    }

    /// Whether a record-47 job waits for values of an asynchronous table.
    pub fn is_busy(&self) -> bool {
        self.busy
    }

    /// Build the busy job's response again (its values may have arrived); it becomes readable
    /// once the table has every value. Nothing to do without a busy job.
    pub fn retry(&mut self, table: &mut impl ParameterAccess) {
        if self.busy {
            self.build(table);
        }
    }

    /// Start a job: keep the (validated) request and try to answer it.
    fn start(&mut self, data: &[u8], table: &mut impl ParameterAccess) {
        let n = data.len().min(MAX_LEN);
        self.request[..n].copy_from_slice(&data[..n]);
        self.request_len = n;
        self.owner = self.relation;
        if let Some(len) = self.response_lens.get_mut(self.owner as usize) {
            *len = 0;
        }
        self.busy = true;
        table.start_job();
        self.build(table);
    }

    fn build(&mut self, table: &mut impl ParameterAccess) {
        let Ok(req) = ParamRequest::parse(&self.request[..self.request_len]) else {
            // Unreachable: the request was validated when it was written.
            self.busy = false;
            return;
        };
        let n = respond(&req, table, &mut self.building);
        if !table.pending() {
            let o = (self.owner as usize).min(RELATIONS - 1);
            self.responses[o][..n].copy_from_slice(&self.building[..n]);
            self.response_lens[o] = n;
            self.busy = false;
        }
    }

    /// This handler bound to a parameter table for one access.
    pub fn with<'a, T: ParameterAccess>(&'a mut self, table: &'a mut T) -> Bound<'a, T> {
        Bound { records: self, table }
    }
}

/// [`DriveRecords`] together with the parameter table it serves: the [`RecordHandler`].
pub struct Bound<'a, T> {
    records: &'a mut DriveRecords,
    table: &'a mut T,
}

impl<T: ParameterAccess> RecordHandler for Bound<'_, T> {
    fn set_relation(&mut self, relation: u8) {
        self.records.relation = relation;
    }

    fn read(&mut self, _now: Instant, slot: u8, index: u8, out: &mut [u8]) -> Result<usize, ErrorCode1> {
        if !self.records.slots.contains(&slot) {
            return Err(ErrorCode1::INVALID_SLOT);
        }
        let r = &mut *self.records;
        match index {
            INDEX_PROFIDRIVE => {
                let rel = r.relation as usize;
                let n = r.response_lens.get(rel).copied().unwrap_or(0);
                if n == 0 {
                    return Err(r.errors.not_ready());
                }
                if out.len() < n {
                    return Err(ErrorCode1::WRITE_LENGTH_ERROR);
                }
                out[..n].copy_from_slice(&r.responses[rel][..n]);
                r.response_lens[rel] = 0;
                Ok(n)
            }
            INDEX_WEG_SIMPLE => {
                let result = r.weg.on_read(WEG_AXIS, self.table, out).map_err(|e| e.error_code1());
                weg_done(r, self.table, result)
            }
            _ => Err(ErrorCode1::INVALID_INDEX),
        }
    }

    fn write(&mut self, _now: Instant, slot: u8, index: u8, data: &[u8]) -> Result<(), ErrorCode1> {
        if !self.records.slots.contains(&slot) {
            return Err(ErrorCode1::INVALID_SLOT);
        }
        let r = &mut *self.records;
        match index {
            INDEX_PROFIDRIVE => {
                // Validated here (≤ 240 bytes), kept for the job.
                ParamRequest::parse(data).map_err(|e| e.error_code1())?;
                if r.busy && r.owner != r.relation {
                    // Another relation's job is waiting for the drive.
                    return Err(r.errors.busy());
                }
                r.start(data, self.table);
                Ok(())
            }
            INDEX_WEG_SIMPLE => {
                let result = r.weg.on_write(data, WEG_AXIS, self.table).map_err(|e| e.error_code1());
                weg_done(r, self.table, result)
            }
            _ => Err(ErrorCode1::INVALID_INDEX),
        }
    }
}

/// The end of a record-48 access: 0xC2 "resource busy" while the table waits for a value (the
/// master repeats the access, which then finds the value); otherwise the result, and the
/// table forgets its answers unless a record-47 job still needs them.
fn weg_done<R>(
    r: &DriveRecords,
    table: &mut impl ParameterAccess,
    result: Result<R, ErrorCode1>,
) -> Result<R, ErrorCode1> {
    if table.pending() {
        return Err(r.errors.busy());
    }
    if !r.busy {
        table.start_job();
    }
    result
}

/// The card's data records behind I&M (PROFIdrive record 47, WEG record 48, [`DriveRecords`])
/// with what they report besides the drive's parameters: the profile layer's fault buffer
/// (PNU 944 / 947) and [`ProcessView`], handed in by the application with every step, and the
/// station context the node hands in ([`DataRecords::begin`]: PNU 918, 922 from the module,
/// 963). The application owns it and passes it bound to the drive's parameter table
/// ([`with`](Self::with)) to every [`Node::process_acyclic`](crate::node::Node::process_acyclic).
#[derive(Debug, Clone)]
pub struct CardRecords {
    records: DriveRecords,
    /// The card's values as of the last [`DataRecords::begin`].
    info: CardInfo,
}

impl CardRecords {
    /// The records of the product `config` (this card: `card::RECORDS`): no response waiting,
    /// an empty fault buffer, no process view ([`ProcessView::EMPTY`]).
    pub const fn new(config: &'static RecordConfig) -> Self {
        CardRecords {
            records: DriveRecords::new(config.slots),
            info: CardInfo {
                device_id: &config.device_id,
                address: 0,
                telegram: Telegram::None,
                baud_p963: 5,
                fault_counter: 0,
                faults: [0; FAULT_BUFFER_LEN],
                process: ProcessView::EMPTY,
            },
        }
    }

    /// The profile layer's PROFIdrive fault buffer (OPTE3/E5 §6.4.6 Table 112; reference
    /// §5.2): PNU 944 `counter` (fault message counter) and PNU 947 `numbers` (fault
    /// numbers), as the records answer them over DP-V1. The application hands it in with every
    /// step (`pbcard::app::Card::apply`); a copy of 66 bytes.
    pub fn set_fault_buffer(&mut self, counter: u16, numbers: &[u16; FAULT_BUFFER_LEN]) {
        self.info.fault_counter = counter;
        self.info.faults = *numbers;
    }

    /// The profile layer's view for the card's PNUs ([`ProcessView`]): the drive's data profile
    /// and the cyclic words of the last cycle. The application hands it in with every step.
    pub fn set_process_view(&mut self, view: ProcessView) {
        self.info.process = view;
    }

    /// Records 47 and 48 (the parameter channel's state).
    pub fn drive_records(&self) -> &DriveRecords {
        &self.records
    }

    /// These records over the drive's parameter `table` (behind the card's own PNUs): the
    /// [`DataRecords`] for one [`Node::process_acyclic`](crate::node::Node::process_acyclic).
    pub fn with<T: ParameterAccess>(&mut self, table: T) -> WithTable<'_, T> {
        WithTable { card: self, table }
    }
}

/// [`CardRecords`] over the drive's parameter table `T` (a table by value, or `&mut` one): the
/// [`DataRecords`] the node serves behind I&M.
pub struct WithTable<'a, T> {
    card: &'a mut CardRecords,
    table: T,
}

impl<T: ParameterAccess> WithTable<'_, T> {
    /// The card's PNUs in front of the drive's, and records 47 / 48 over them.
    fn parts(&mut self) -> (&mut DriveRecords, CardTable<'_, T>) {
        (&mut self.card.records, CardTable { info: self.card.info, drive: &mut self.table })
    }
}

impl<T: ParameterAccess> RecordHandler for WithTable<'_, T> {
    fn read(&mut self, now: Instant, slot: u8, index: u8, out: &mut [u8]) -> Result<usize, ErrorCode1> {
        let (records, mut table) = self.parts();
        records.with(&mut table).read(now, slot, index, out)
    }

    fn write(&mut self, now: Instant, slot: u8, index: u8, data: &[u8]) -> Result<(), ErrorCode1> {
        let (records, mut table) = self.parts();
        records.with(&mut table).write(now, slot, index, data)
    }

    fn set_relation(&mut self, relation: u8) {
        self.card.records.relation = relation;
    }
}

impl<T: ParameterAccess> DataRecords for WithTable<'_, T> {
    /// The card's values for this pass (address, the telegram of the module — PNU 922 and the
    /// product's error list, [`RecordErrors::for_telegram`] —, P0963), then the busy job again
    /// ([`DriveRecords::retry`]).
    fn begin(&mut self, _now: Instant, station: &StationInfo) {
        let info = &mut self.card.info;
        info.address = station.address;
        // The telegram the drive selected (DPM CONFIG.TELEGRAM; Chk_Cfg can only select its
        // module), else the module of the last Chk_Cfg.
        info.telegram = station.module.and_then(Telegram::of_module).unwrap_or(Telegram::None);
        info.baud_p963 = station.baudrate.map_or(5, |b| u16::from(b.p0963_code()));
        self.card.records.set_errors(RecordErrors::for_telegram(info.telegram));
        let (records, mut table) = self.parts();
        records.retry(&mut table);
    }

    fn end_relation(&mut self, relation: u8) {
        self.card.records.end_relation(relation);
    }

    fn is_busy(&self) -> bool {
        self.card.records.is_busy()
    }
}
