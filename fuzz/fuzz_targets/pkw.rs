//! The PKW channel (`profile::pkw`) on arbitrary request sequences.
//!
//! Input: byte 0 selects the dialect (VACON, INVT, PROFIdrive 2.0) and how slow the table is
//! (0..=3 calls pending per job); then steps of 9 bytes — an operation byte (bit 0: give the
//! request, bit 1: service, bit 2: repeat the held request, bit 3: reset) and the 8 request bytes.
//!
//! Checks, after every step: no panic; the response is the 8-byte field and all zero while no
//! answered job is held; an answered response echoes the request's PNU / address / index as the
//! dialect does and carries one of its response codes; a synchronous-looking table never gets
//! more writes than there were jobs (a job writes once, however often it is repeated or
//! serviced). The whole run is done twice and must give the same responses (determinism).
#![no_main]

use libfuzzer_sys::fuzz_target;
use pbcard::profile::param::{ParamAddress, ParamError, ParameterAccess, ValueBlock, ValueWriter};
use pbcard::profile::pkw::{PkwDialect, PkwServer, PkwWords, PKW_LEN, PNU_MASK, VACON_DRIVE_PARAMETER};
use pbcard::profile::table::{slots, ParamDef, Table, Type};

const DEFS: &[ParamDef] = &[
    ParamDef::new(1, "Word", Type::U16).limits(0, 1000),
    ParamDef::new(2, "Read only", Type::U16).read_only().with_default(0x1234),
    ParamDef::new(3, "Word array", Type::U16).array(10).limits(0, 50000),
    ParamDef::new(4, "Dword array", Type::U32).array(4),
    ParamDef::new(10, "Signed", Type::I16).limits(-500, 500),
    ParamDef::new(11, "Signed dword", Type::I32).limits(-100_000, 100_000),
    // VACON's drive parameters by application ID (PKW PNU 0..=2047 → PNU 10001 subindex ID).
    ParamDef::new(VACON_DRIVE_PARAMETER, "Drive params", Type::U16).array(2048).limits(0, 30000),
];
const N: usize = slots(DEFS);

/// The table, pending for the first `slow` calls of each job, counting what reaches it.
struct Slow {
    table: Table<N>,
    slow: u8,
    left: u8,
    pending: bool,
    writes: u32,
}

impl Slow {
    /// Whether this call waits (and the table is not touched).
    fn wait(&mut self) -> bool {
        self.pending = self.left > 0;
        self.left = self.left.saturating_sub(1);
        self.pending
    }
}

fn waiting() -> ParamError {
    pbcard::profile::param::ErrorValue::NOT_EXECUTABLE.into()
}

impl ParameterAccess for Slow {
    fn has_axis(&self, axis: u8) -> bool {
        self.table.has_axis(axis)
    }
    fn read_value(&mut self, axis: u8, a: &ParamAddress, out: &mut ValueWriter<'_>) -> Result<(), ParamError> {
        if self.wait() {
            return Err(waiting());
        }
        self.table.read_value(axis, a, out)
    }
    fn write_value(&mut self, axis: u8, a: &ParamAddress, v: &ValueBlock<'_>) -> Result<(), ParamError> {
        if self.wait() {
            return Err(waiting());
        }
        self.writes += 1;
        self.table.write_value(axis, a, v)
    }
    fn read_description(&mut self, axis: u8, a: &ParamAddress, out: &mut ValueWriter<'_>) -> Result<(), ParamError> {
        if self.wait() {
            return Err(waiting());
        }
        self.table.read_description(axis, a, out)
    }
    fn pending(&self) -> bool {
        self.pending
    }
    fn start_job(&mut self) {
        self.left = self.slow;
        self.pending = false;
    }
}

fn check(dialect: PkwDialect, s: &PkwServer) {
    let rsp = s.response();
    assert_eq!(rsp.len(), PKW_LEN);
    if s.is_busy() || pbcard::profile::pkw::is_no_request(dialect, s.request()) {
        assert_eq!(rsp, [0; PKW_LEN], "{dialect:?}: response {rsp:02x?} without an answered job");
        return;
    }
    let (req, rsp) = (PkwWords::from_bytes(s.request()), PkwWords::from_bytes(rsp));
    match dialect {
        PkwDialect::Vacon => {
            assert_eq!(rsp.id & PNU_MASK, req.id & PNU_MASK);
            assert!(matches!(rsp.id >> 12, 1 | 7) && rsp.index == 0 && rsp.high == 0, "{rsp:?}");
        }
        PkwDialect::Invt => {
            assert!(matches!(rsp.id, 1..=3) && rsp.index == req.index, "{rsp:?}");
        }
        PkwDialect::Profidrive2 => {
            assert_eq!((rsp.id & PNU_MASK, rsp.index), (req.id & PNU_MASK, req.index));
            assert!(matches!(rsp.id >> 12, 1..=8), "{rsp:?}");
        }
    }
}

fn run(data: &[u8]) -> Vec<[u8; PKW_LEN]> {
    let Some((&head, steps)) = data.split_first() else { return Vec::new() };
    let dialect = match head % 3 {
        0 => PkwDialect::Vacon,
        1 => PkwDialect::Invt,
        _ => PkwDialect::Profidrive2,
    };
    let mut table = Slow { table: Table::new(DEFS), slow: (head >> 2) & 3, left: 0, pending: false, writes: 0 };
    let mut s = PkwServer::new(dialect);
    let mut trace = Vec::new();
    for step in steps.chunks_exact(1 + PKW_LEN) {
        let op = step[0];
        let mut req = [0u8; PKW_LEN];
        req.copy_from_slice(&step[1..]);
        if op & 1 != 0 {
            s.on_request(req);
        }
        if op & 4 != 0 {
            let held = s.request();
            s.on_request(held);
        }
        if op & 2 != 0 {
            s.service(&mut table);
        }
        if op & 8 != 0 {
            s.reset();
        }
        check(dialect, &s);
        let c = s.counters();
        assert!(c.completed <= c.jobs && c.rejected <= c.completed, "{c:?}");
        assert!(table.writes <= c.jobs, "{} writes for {} jobs", table.writes, c.jobs);
        trace.push(s.response());
    }
    trace
}

fuzz_target!(|data: &[u8]| {
    let first = run(data);
    assert_eq!(first, run(data), "not deterministic");
});
