//! The PKW channel (`profile::pkw`) on arbitrary request sequences.
//!
//! Input: byte 0 selects the dialect (VACON, INVT, PROFIdrive 2.0) and how slow the drive is
//! (bits 2–3: 0 answers at once; 1..=3: behind the mailbox, answering after every that many
//! services); then steps of 9 bytes — an operation byte (bit 0: give the request, bit 1:
//! service, bit 2: repeat the held request, bit 3: reset, bit 4: the drive behind the mailbox
//! answers now) and the 8 request bytes.
//!
//! Checks, after every step: no panic; the response is the 8-byte field and all zero while no
//! answered job is held; an answered response echoes the request's PNU / address / index as the
//! dialect does and carries one of its response codes; a synchronous-looking table never gets
//! more writes than there were jobs (a job writes once, however often it is repeated or
//! serviced). The whole run is done twice and must give the same responses (determinism).
#![no_main]

use libfuzzer_sys::fuzz_target;
use pbcard::profile::pkw::{PkwDialect, PkwServer, PkwWords, PKW_LEN, PNU_MASK, VACON_DRIVE_PARAMETER};
use pbcard::profile::table::{slots, ParamDef, Table, Type};
use pbcard::testkit::{FakeDrive, Mailbox};

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

/// The drive: the one fake drive (`pbcard::testkit::FakeDrive`) with the table above, either
/// answering at once or behind the asynchronous mailbox (`pbcard::testkit::Mailbox`, as over
/// the DPM), where it answers only when a step lets it.
enum Drive {
    Sync(FakeDrive<N>),
    Async(Mailbox<FakeDrive<N>>),
}

impl Drive {
    /// Value writes that reached the drive.
    fn writes(&self) -> u32 {
        match self {
            Drive::Sync(d) => d.write_calls,
            Drive::Async(m) => m.drive.write_calls,
        }
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
    let fake = FakeDrive::with_table(Table::new(DEFS));
    let slow = u32::from((head >> 2) & 3);
    let mut table = if slow == 0 { Drive::Sync(fake) } else { Drive::Async(Mailbox::new(fake)) };
    let mut services = 0u32;
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
            match &mut table {
                Drive::Sync(d) => s.service(d),
                Drive::Async(m) => {
                    s.service(m);
                    services += 1;
                    if services % slow == 0 {
                        m.deliver();
                    }
                }
            }
        }
        if op & 0x10 != 0 {
            if let Drive::Async(m) = &mut table {
                m.deliver();
            }
        }
        if op & 8 != 0 {
            s.reset();
        }
        check(dialect, &s);
        let c = s.counters();
        assert!(c.completed <= c.jobs && c.rejected <= c.completed, "{c:?}");
        assert!(table.writes() <= c.jobs, "{} writes for {} jobs", table.writes(), c.jobs);
        trace.push(s.response());
    }
    trace
}

fuzz_target!(|data: &[u8]| {
    let first = run(data);
    assert_eq!(first, run(data), "not deterministic");
});
