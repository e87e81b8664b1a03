//! Our own class-1 DP-V1 test master (neither profirust nor pyprofibus speaks DP-V1): it
//! talks to a whole [`Node`] frame by frame — Set_Prm with DPV1_Enable, Chk_Cfg, then
//! MSAC_C1 DS_Write / poll / DS_Read on SAP 51 — and checks the PDUs byte for byte, including
//! the VACON OPTE3/E5 §6.4.4.1 example (read PNU 918 of station 3) through the whole stack.

use host_tests::scripted::Ans;
use pbcard::card;
use pbcard::dp::DpState;
use pbcard::dpv1::pdu::ErrorCode1;
use pbcard::fdl::telegram::{FunctionCode, Header};
use pbcard::profile::records::CardRecords;
use pbcard::testkit::{self, FakeDrive, NodeRig, Rig, SetPrm};
use pbcard::time::{Duration, Instant};

const ME: u8 = 3;
const M1: u8 = 2;
const M2: u8 = 4;

/// The shared node rig ([`NodeRig`]: the node, the scripted master, the clock 500 µs on per
/// request) with what the DP-V1 tests add: the card's records and the fake drive behind them.
struct Master {
    rig: NodeRig,
    /// The card's data records (records 47 / 48), owned by the application.
    records: CardRecords,
    /// The tests' fake drive table (PNU 100 u16[4] ≤ 1000, PNU 101 read-only 1234).
    drive: FakeDrive,
}

impl Master {
    fn new() -> Self {
        Master {
            rig: NodeRig::node_only(M1, ME),
            records: CardRecords::new(&pbcard::card::RECORDS),
            drive: FakeDrive { p100: [50, 0, 0, 0], ..FakeDrive::new() },
        }
    }

    fn send(&mut self, sa: u8, dsap: Option<u8>, ssap: Option<u8>, pdu: &[u8], toggle: bool) -> Ans {
        let f = self.rig.master.request(sa, dsap, ssap, pdu, toggle);
        let r = self.rig.deliver(&f);
        Ans::of(&f, r.as_deref(), Some(0x08))
    }

    fn c1(&mut self, sa: u8, pdu: &[u8]) -> Ans {
        self.send(sa, Some(51), Some(51), pdu, true)
    }

    /// Let the card's DP-V1 task run.
    fn process(&mut self) {
        self.rig.node.process_acyclic(self.rig.now, &mut self.records.with(&mut self.drive));
    }

    /// Request, then poll until the response (at most 3 polls), as a class-1 master does.
    fn transact(&mut self, pdu: &[u8]) -> Vec<u8> {
        assert_eq!(self.c1(M1, pdu), Ans::Sc, "request acknowledged with SC");
        assert_eq!(self.c1(M1, &[]), Ans::Sc, "poll before processing: not ready");
        self.process();
        match self.c1(M1, &[]) {
            Ans::Pdu(p) => p,
            other => panic!("poll after processing: {other:?}"),
        }
    }

    fn bring_up(&mut self, dpv1_status_1: u8) {
        let prm = SetPrm::CARD.watchdog(10, 10).user([dpv1_status_1, 0, 0, 0, 0]).pdu();
        assert_eq!(self.send(M1, Some(61), Some(62), &prm, true), Ans::Sc);
        assert_eq!(self.send(M1, Some(62), Some(62), card::MODULES[0].cfg, true), Ans::Sc);
        assert_eq!(self.rig.node.slave().state(), DpState::DataExch);
    }
}

/// VACON OPTE3/E5 §6.4.4.1 (Tables 62–65): read PNU 918 (station address) of station 3:
/// DS_Write `5F 00 2F 0A | 01 01 01 01 10 01 03 96 00 00`, write response `5F 00 2F 0A`,
/// DS_Read `5E 00 2F F0`, read response `5E 00 2F 08 | 01 01 01 01 42 01 00 03`.
#[test]
fn vacon_read_station_address_through_the_stack() {
    let mut m = Master::new();
    m.bring_up(0x80);
    let w = m.transact(&[0x5F, 0x00, 0x2F, 0x0A, 0x01, 0x01, 0x01, 0x01, 0x10, 0x01, 0x03, 0x96, 0x00, 0x00]);
    assert_eq!(w, [0x5F, 0x00, 0x2F, 0x0A]);
    let r = m.transact(&[0x5E, 0x00, 0x2F, 0xF0]);
    assert_eq!(r, [0x5E, 0x00, 0x2F, 0x08, 0x01, 0x01, 0x01, 0x01, 0x42, 0x01, 0x00, 0x03]);
    // The response is readable once: a second DS_Read is a state conflict (0xB5).
    assert_eq!(m.transact(&[0x5E, 0x00, 0x2F, 0xF0]), [0xDE, 0x80, 0xB5, 0x00]);
}

#[test]
fn change_and_read_back_a_drive_parameter() {
    let mut m = Master::new();
    m.bring_up(0x80);
    // Change PNU 100 to 1000 (0x03E8): ref 7, ID 2, axis 1, 1 parameter, 10 01 0064 0000, 42 01 03E8.
    let req = [0x5F, 0, 47, 14, 7, 2, 1, 1, 0x10, 1, 0, 100, 0, 0, 0x42, 1, 0x03, 0xE8];
    assert_eq!(m.transact(&req), [0x5F, 0, 47, 14]);
    assert_eq!(m.transact(&[0x5E, 0, 47, 240]), [0x5E, 0, 47, 4, 7, 2, 1, 1]);
    assert_eq!(m.drive.p100[0], 1000);
    // Beyond the limit: 0x82 with error 0x02 and the failing element (subindex 0) as the
    // additional information of an array parameter; read-only PNU 101: error 0x01.
    let req = [0x5F, 0, 47, 14, 8, 2, 1, 1, 0x10, 1, 0, 100, 0, 0, 0x42, 1, 0x17, 0x70];
    m.transact(&req);
    assert_eq!(m.transact(&[0x5E, 0, 47, 240]), [0x5E, 0, 47, 10, 8, 0x82, 1, 1, 0x44, 2, 0, 2, 0, 0]);
    assert_eq!(m.drive.p100[0], 1000);
    // Profile identification PNU 965 (card-owned, BYTE[2]): both elements = 3, 41.
    m.transact(&[0x5F, 0, 47, 10, 9, 1, 1, 1, 0x10, 2, 0x03, 0xC5, 0, 0]);
    assert_eq!(m.transact(&[0x5E, 0, 47, 240]), [0x5E, 0, 47, 8, 9, 1, 1, 1, 0x0A, 2, 3, 41]);
}

#[test]
fn weg_simple_access_record_48() {
    let mut m = Master::new();
    m.bring_up(0x80);
    // Write PNU 100 = 300, select it, read it.
    assert_eq!(m.transact(&[0x5F, 0, 48, 4, 0, 100, 0x01, 0x2C]), [0x5F, 0, 48, 4]);
    assert_eq!(m.drive.p100[0], 300);
    assert_eq!(m.transact(&[0x5F, 0, 48, 2, 0, 100]), [0x5F, 0, 48, 2]);
    assert_eq!(m.transact(&[0x5E, 0, 48, 240]), [0x5E, 0, 48, 2, 0x01, 0x2C]);
    // Read-only parameter: B6; unknown parameter: B8.
    assert_eq!(m.transact(&[0x5F, 0, 48, 4, 0, 101, 0, 1]), [0xDF, 0x80, 0xB6, 0x00]);
    assert_eq!(m.transact(&[0x5F, 0, 48, 2, 0x27, 0x0F]), [0xDF, 0x80, 0xB8, 0x00]);
}

#[test]
fn record_routing_errors() {
    let mut m = Master::new();
    m.bring_up(0x80);
    // Slot 1 is the drive module's (GSD SlotDefinition): record 47 there, nothing to read yet.
    assert_eq!(m.transact(&[0x5E, 1, 47, 240]), [0xDE, 0x80, 0xB5, 0x00], "slot 1: no response waiting");
    assert_eq!(m.transact(&[0x5E, 2, 47, 240]), [0xDE, 0x80, 0xB2, 0x00], "slot 2: invalid slot");
    assert_eq!(m.transact(&[0x5E, 0, 99, 240]), [0xDE, 0x80, 0xB0, 0x00], "index 99: invalid index");
    // A parameter request with reference 0 is refused at the DS_Write (0xB7).
    assert_eq!(m.transact(&[0x5F, 0, 47, 6, 0, 1, 1, 1, 0x10, 1]), [0xDF, 0x80, 0xB7, 0x00]);
    // Read length 0 is malformed.
    assert!(matches!(m.transact(&[0x5E, 0, 47, 0]).as_slice(), [0xDE, 0x80, _, 0x00]));
    // Alarm_Ack without an alarm: state conflict.
    assert_eq!(m.transact(&[0x5C, 0, 1, 0]), [0xDC, 0x80, 0xB5, 0x00]);
}

#[test]
fn c1_is_open_only_in_data_exchange_with_dpv1_enable_for_the_locking_master() {
    let mut m = Master::new();
    assert_eq!(m.c1(M1, &[0x5E, 0, 47, 240]), Ans::Sd1(0x03), "Wait_Prm: RS");
    m.bring_up(0x00);
    assert_eq!(m.c1(M1, &[0x5E, 0, 47, 240]), Ans::Sd1(0x03), "no DPV1_Enable: RS");
    let mut m = Master::new();
    m.bring_up(0x80);
    assert_eq!(m.c1(M2, &[0x5E, 0, 47, 240]), Ans::Sd1(0x03), "another master: RS");
    assert_eq!(m.send(M1, Some(51), Some(62), &[0x5E, 0, 47, 240], true), Ans::Sd1(0x03), "wrong SSAP: RS");
    // Leaving data exchange drops a request in flight.
    assert_eq!(m.c1(M1, &[0x5E, 0, 47, 240]), Ans::Sc);
    let id = card::IDENT_NUMBER.to_be_bytes();
    assert_eq!(m.send(M1, Some(61), Some(62), &[0x40, 1, 1, 11, id[0], id[1], 0], true), Ans::Sc);
    m.process();
    assert_eq!(m.c1(M1, &[]), Ans::Sd1(0x03));
}

#[test]
fn fcb_retries_are_safe() {
    let mut m = Master::new();
    m.bring_up(0x80);
    // A retried write request (same FCB, same bytes) is answered from the station's memory
    // and not queued twice; a retried poll gets the same response frame.
    let req = [0x5F, 0, 47, 14, 7, 2, 1, 1, 0x10, 1, 0, 100, 0, 0, 0x42, 1, 0x03, 0xE8];
    assert_eq!(m.c1(M1, &req), Ans::Sc);
    assert_eq!(m.send(M1, Some(51), Some(51), &req, false), Ans::Sc);
    m.process();
    let first = m.c1(M1, &[]);
    assert_eq!(first, Ans::Pdu(vec![0x5F, 0, 47, 14]));
    assert_eq!(m.send(M1, Some(51), Some(51), &[], false), first, "retried poll: same answer");
    assert_eq!(m.c1(M1, &[]), Ans::Sc, "nothing more to fetch");
    m.process();
    assert_eq!(m.transact(&[0x5E, 0, 47, 240]), [0x5E, 0, 47, 4, 7, 2, 1, 1], "executed once");
}

// ----- MSAC_C2: our class-2 test master -----

/// Initiate.req: Send_Timeout (10 ms units), Read/Write supported, S and D type 0 with
/// 2-byte address blocks (API 0, SCL 0).
fn initiate(send_timeout: u16) -> Vec<u8> {
    let t = send_timeout.to_be_bytes();
    vec![0x57, 0, 0, 0, t[0], t[1], 0x01, 0x00, 0, 0, 0, 0, 0, 2, 0, 2, 0, 0, 0, 0]
}

impl Master {
    fn c2(&mut self, sa: u8, sap: u8, pdu: &[u8]) -> Ans {
        self.send(sa, Some(sap), Some(50), pdu, true)
    }

    /// Open a connection: Initiate to the resource manager (SAP 49), then on the server SAP.
    fn connect(&mut self, sa: u8) -> u8 {
        let rm = match self.c2(sa, 49, &initiate(300)) {
            Ans::Pdu(p) => p,
            other => panic!("RM answer {other:?}"),
        };
        assert_eq!((rm.len(), rm[0]), (4, 0x56), "RM PDU 56 sap poll_timeout");
        let sap = rm[1];
        assert_eq!(self.c2(sa, sap, &initiate(300)), Ans::Sc);
        match self.c2(sa, sap, &[]) {
            Ans::Pdu(p) => assert_eq!(p[0], 0x57, "Initiate.res"),
            other => panic!("Initiate.res {other:?}"),
        }
        sap
    }

    fn c2_transact(&mut self, sa: u8, sap: u8, pdu: &[u8]) -> Vec<u8> {
        assert_eq!(self.c2(sa, sap, pdu), Ans::Sc);
        self.process();
        match self.c2(sa, sap, &[]) {
            Ans::Pdu(p) => p,
            other => panic!("C2 poll {other:?}"),
        }
    }
}

#[test]
fn two_class2_connections_independent_of_the_cyclic_state() {
    let mut m = Master::new();
    // The slave is not parameterized (Wait_Prm) and nobody holds the lock: C2 still works.
    let a = m.connect(10);
    let b = m.connect(11);
    assert_ne!(a, b);
    // A third master is refused cleanly (RR: no resources).
    assert_eq!(m.c2(12, 49, &initiate(300)), Ans::Sd1(0x02));
    // Each connection reads PNU 918 (station address 3) through record 47.
    for (sa, sap) in [(10, a), (11, b)] {
        let req = [0x5F, 0, 47, 10, sa, 1, 1, 1, 0x10, 1, 0x03, 0x96, 0, 0];
        assert_eq!(m.c2_transact(sa, sap, &req), [0x5F, 0, 47, 10]);
        assert_eq!(m.c2_transact(sa, sap, &[0x5E, 0, 47, 240]), [0x5E, 0, 47, 8, sa, 1, 1, 1, 0x42, 1, 0, 3]);
    }
    // Another master on a connection's SAP: RS.
    assert_eq!(m.c2(12, a, &[0x5E, 0, 47, 240]), Ans::Sd1(0x03));
    // Abort by the master closes the SAP: later requests get RS.
    assert_eq!(m.c2(10, a, &[0x58, 0x00, 0x20, 0x00]), Ans::Sc);
    assert_eq!(m.c2(10, a, &[0x5E, 0, 47, 240]), Ans::Sd1(0x03));
    // The freed connection can be opened again.
    assert_eq!(m.connect(12), a);
}

#[test]
fn class2_send_timeout_aborts_the_connection() {
    let mut m = Master::new();
    let sap = m.connect(10);
    // 3 s of silence (Send_Timeout 300 × 10 ms): the connection is aborted by the slave.
    m.rig.now = m.rig.now + Duration::from_micros(3_100_000);
    m.rig.node.poll(m.rig.now);
    match m.c2(10, sap, &[0x5E, 0, 47, 240]) {
        Ans::Pdu(p) => assert_eq!((p[0], p[2] & 0x0F), (0x58, 3), "Abort, reason 3 timeout"),
        Ans::Sd1(0x03) => {}
        other => panic!("after the timeout: {other:?}"),
    }
    assert_eq!(m.c2(10, sap, &[0x5E, 0, 47, 240]), Ans::Sd1(0x03));
}

// ----- The simulated drive's parameter table (pbcard::profile::table) behind the node -----

use pbcard_sim::drive::params::{self, DriveTable};

/// Request, process with `table` as the drive, poll: one MSAC_C1 exchange.
fn table_transact(m: &mut Master, table: &mut DriveTable, pdu: &[u8]) -> Vec<u8> {
    assert_eq!(m.c1(M1, pdu), Ans::Sc, "request acknowledged with SC");
    m.rig.node.process_acyclic(m.rig.now, &mut m.records.with(table));
    match m.c1(M1, &[]) {
        Ans::Pdu(p) => p,
        other => panic!("poll after processing: {other:?}"),
    }
}

/// DS_Write `req` to record 47 (checking the write response), DS_Read 240 bytes; returns the
/// parameter response (after the DP-V1 header, whose length byte is checked).
fn param_request(m: &mut Master, table: &mut DriveTable, req: &[u8]) -> Vec<u8> {
    let n = req.len() as u8;
    assert_eq!(table_transact(m, table, &[&[0x5F, 0, 47, n][..], req].concat()), [0x5F, 0, 47, n]);
    let r = table_transact(m, table, &[0x5E, 0, 47, 240]);
    assert_eq!((&r[..3], r[3] as usize), (&[0x5E, 0, 47][..], r.len() - 4), "read response header");
    r[4..].to_vec()
}

fn table_master() -> (Master, DriveTable) {
    let mut m = Master::new();
    m.bring_up(0x80);
    (m, params::sim_drive_table())
}

/// P100 "Accel. Time" (WEG P0100, 0.1 s, 0..9999, default 50): the whole 46-byte description
/// element (VACON §6.4.3.7, Table 49) and the name field alone.
#[test]
fn sim_table_description_of_p100() {
    let (mut m, mut t) = table_master();
    let r = param_request(&mut m, &mut t, &[1, 1, 1, 1, 0x20, 1, 0, 100, 0, 0]);
    let mut expected = vec![1, 1, 1, 1, 0x0A, 46];
    expected.extend_from_slice(&[0x00, 0x06]); // identifier: Unsigned16, scaled, writeable, unchanged
    expected.extend_from_slice(&[0x00, 0x00]); // no array
    expected.extend_from_slice(&[0x3D, 0xCC, 0xCC, 0xCD]); // standardisation factor 0.1
    expected.extend_from_slice(&[0x04, 0x00]); // variable index 4 (time), conversion index 0 (s)
    expected.extend_from_slice(&[0; 4]); // reserved
    expected.extend_from_slice(b"Accel. Time     "); // name
    expected.extend_from_slice(&[0, 0, 0, 0, 0, 0, 0x27, 0x0F]); // low limit 0, high limit 9999
    expected.extend_from_slice(&[0; 8]); // reserved, ID extension, normalisation reference, field
    assert_eq!(r, expected);
    // Subindex 6: the name, VisibleString 16.
    let r = param_request(&mut m, &mut t, &[2, 1, 1, 1, 0x20, 1, 0, 100, 0, 6]);
    assert_eq!(r, [&[2, 1, 1, 1, 0x09, 16][..], b"Accel. Time     "].concat());
    // After a change, identifier bit 12 (changed from the factory setting) is set.
    assert_eq!(param_request(&mut m, &mut t, &[3, 2, 1, 1, 0x10, 1, 0, 100, 0, 0, 0x42, 1, 0, 85]), [3, 2, 1, 1]);
    assert_eq!(param_request(&mut m, &mut t, &[4, 1, 1, 1, 0x20, 1, 0, 100, 0, 1]), [4, 1, 1, 1, 0x06, 1, 0x10, 0x06]);
    assert_eq!(params::acceleration_time(&t).as_millis(), 8500);
}

/// VACON's test array PNU 9901 (UINT[8]): write elements 2..4, read them back with subindex 2
/// and 3 elements, read the whole array; past the end is 0x03.
#[test]
fn sim_table_array_p9901() {
    let (mut m, mut t) = table_master();
    // 10 03 26AD 0002 | 42 03 0064 00C8 012C
    let w = [5, 2, 1, 1, 0x10, 3, 0x26, 0xAD, 0, 2, 0x42, 3, 0, 100, 0, 200, 0x01, 0x2C];
    assert_eq!(param_request(&mut m, &mut t, &w), [5, 2, 1, 1]);
    let r = param_request(&mut m, &mut t, &[6, 1, 1, 1, 0x10, 3, 0x26, 0xAD, 0, 2]);
    assert_eq!(r, [6, 1, 1, 1, 0x42, 3, 0, 100, 0, 200, 0x01, 0x2C]);
    let r = param_request(&mut m, &mut t, &[7, 1, 1, 1, 0x10, 8, 0x26, 0xAD, 0, 0]);
    assert_eq!(r, [7, 1, 1, 1, 0x42, 8, 0, 0, 0, 0, 0, 100, 0, 200, 0x01, 0x2C, 0, 0, 0, 0, 0, 0]);
    let r = param_request(&mut m, &mut t, &[8, 1, 1, 1, 0x10, 2, 0x26, 0xAD, 0, 7]);
    assert_eq!(r, [8, 0x81, 1, 1, 0x44, 1, 0, 0x03]);
    // The dummy single parameter 9900 is no array: subindex 1 is 0x04.
    let r = param_request(&mut m, &mut t, &[9, 1, 1, 1, 0x10, 1, 0x26, 0xAC, 0, 1]);
    assert_eq!(r, [9, 0x81, 1, 1, 0x44, 1, 0, 0x04]);
}

/// Change errors: P100 = 10000 beyond 9999 (0x02, CFW-11 §4.2.5 Exemplo 2 negative), the
/// read-only status word P680 (0x01); neither value changes.
#[test]
fn sim_table_change_errors() {
    let (mut m, mut t) = table_master();
    let r = param_request(&mut m, &mut t, &[10, 2, 1, 1, 0x10, 1, 0, 100, 0, 0, 0x42, 1, 0x27, 0x10]);
    assert_eq!(r, [10, 0x82, 1, 1, 0x44, 1, 0, 0x02]);
    let r = param_request(&mut m, &mut t, &[11, 2, 1, 1, 0x10, 1, 0x02, 0xA8, 0, 0, 0x42, 1, 0, 1]);
    assert_eq!(r, [11, 0x82, 1, 1, 0x44, 1, 0, 0x01]);
    assert_eq!((t.get(100, 0), t.get(680, 0)), (Some(50), Some(0)));
    // Both in one request, with a good one between: 44 / 40 00 / 44.
    let r = param_request(
        &mut m,
        &mut t,
        &[
            12, 2, 1, 3, 0x10, 1, 0, 100, 0, 0, 0x10, 1, 0, 101, 0, 0, 0x10, 1, 0x02, 0xA8, 0, 0, //
            0x42, 1, 0x27, 0x10, 0x42, 1, 0, 20, 0x42, 1, 0, 1,
        ],
    );
    assert_eq!(r, [12, 0x82, 1, 3, 0x44, 1, 0, 0x02, 0x40, 0, 0x44, 1, 0, 0x01]);
    assert_eq!(params::deceleration_time(&t).as_millis(), 2000);
}

/// Texts are not supported (VACON Table 41): 0x0F.
#[test]
fn sim_table_text_request() {
    let (mut m, mut t) = table_master();
    let r = param_request(&mut m, &mut t, &[13, 1, 1, 1, 0x30, 1, 0, 100, 0, 0]);
    assert_eq!(r, [13, 0x81, 1, 1, 0x44, 1, 0, 0x0F]);
}

/// One request, three parameters: P100 = 50, P134 = 1800 rpm, P10111 = 1800 rpm; and card-owned
/// PNU 918 mixed with the drive's P681 (set by the drive to −2000h, full reverse).
#[test]
fn sim_table_multi_parameter_read() {
    let (mut m, mut t) = table_master();
    let req = [14, 1, 1, 3, 0x10, 1, 0, 100, 0, 0, 0x10, 1, 0, 134, 0, 0, 0x10, 1, 0x27, 0x7F, 0, 0];
    let r = param_request(&mut m, &mut t, &req);
    assert_eq!(r, [14, 1, 1, 3, 0x42, 1, 0, 50, 0x42, 1, 0x07, 0x08, 0x42, 1, 0x07, 0x08]);
    t.set(params::P_SPEED_13BIT, 0, -params::SPEED_13BIT_100).unwrap();
    let r = param_request(&mut m, &mut t, &[15, 1, 1, 2, 0x10, 1, 0x03, 0x96, 0, 0, 0x10, 1, 0x02, 0xA9, 0, 0]);
    assert_eq!(r, [15, 1, 1, 2, 0x42, 1, 0, 3, 0x42, 1, 0xE0, 0x00]);
}

/// Seven reads of all 16 elements of P10109 need 4 + 7 × 34 = 242 bytes: the seventh is
/// answered 0x15 "response too long" and the response stays within 240 bytes.
#[test]
fn sim_table_response_too_long() {
    let (mut m, mut t) = table_master();
    for k in 0..16 {
        t.set(params::P_PD_IN, k, 0x100 + i64::from(k)).unwrap();
    }
    let mut req = vec![16, 1, 1, 7];
    for _ in 0..7 {
        req.extend_from_slice(&[0x10, 16, 0x27, 0x7D, 0, 0]);
    }
    let r = param_request(&mut m, &mut t, &req);
    assert_eq!(r.len(), 4 + 6 * 34 + 4);
    assert_eq!(&r[..4], &[16, 0x81, 1, 7]);
    let words: Vec<u8> = (0..16u16).flat_map(|k| (0x100 + k).to_be_bytes()).collect();
    for p in 0..6 {
        assert_eq!(&r[4 + 34 * p..4 + 34 * (p + 1)], &[&[0x42, 16][..], &words].concat()[..]);
    }
    assert_eq!(&r[4 + 6 * 34..], &[0x44, 1, 0, 0x15]);
}

#[test]
fn axis_other_than_0_or_1_is_refused() {
    let mut m = Master::new();
    m.bring_up(0x80);
    // Read PNU 918 on axis 2: every parameter answered 0x19 "axis/DO nonexistent".
    m.transact(&[0x5F, 0, 47, 10, 5, 1, 2, 1, 0x10, 1, 0x03, 0x96, 0, 0]);
    assert_eq!(m.transact(&[0x5E, 0, 47, 240]), [0x5E, 0, 47, 8, 5, 0x81, 2, 1, 0x44, 1, 0x00, 0x19]);
}

/// Found by the `node_dpv1` fuzz target: an SDN on SAP 51 (broadcast or addressed) is no
/// MSAC_C1 request and must neither replace nor consume the one in flight; a request in
/// flight does not survive a re-parameterization.
#[test]
fn c1_ignores_sdn_and_drops_requests_across_sessions() {
    let mut m = Master::new();
    m.bring_up(0x80);
    assert_eq!(m.c1(M1, &[0x5F, 0, 47, 10, 1, 1, 1, 1, 0x10, 1, 0x03, 0x96, 0, 0]), Ans::Sc);
    // SDN high from the locking master on SAP 51 with an Alarm_Ack PDU: ignored.
    let hdr = Header { da: 127, sa: M1, fc: FunctionCode::request(0x06, false, false), dsap: Some(51), ssap: Some(51) };
    let now = m.rig.now;
    assert_eq!(testkit::feed(&mut m.rig.node, now, &testkit::frame(&hdr, &[0x5C, 0, 1, 2])), None);
    m.process();
    assert_eq!(m.c1(M1, &[]), Ans::Pdu(vec![0x5F, 0, 47, 10]), "the write's answer, not an Alarm_Ack error");
    // A request acknowledged, then Set_Prm + Chk_Cfg: the old request is gone.
    assert_eq!(m.c1(M1, &[0x5E, 0, 47, 240]), Ans::Sc);
    m.bring_up(0x80);
    m.process();
    assert_eq!(m.c1(M1, &[]), Ans::Sc, "nothing from the previous session");
}

#[test]
fn card_pnu_descriptions() {
    let mut m = Master::new();
    m.bring_up(0x80);
    // Description element 6 (name, VisibleString16) of PNU 918; of PNU 964 the number of array
    // elements (element 2); PNU 965 (OctetString2) has none: 0x09.
    m.transact(&[0x5F, 0, 47, 10, 0x30, 1, 1, 1, 0x20, 1, 0x03, 0x96, 0, 6]);
    let r = m.transact(&[0x5E, 0, 47, 240]);
    assert_eq!(&r[..10], &[0x5E, 0, 47, 22, 0x30, 1, 1, 1, r[8], 16]);
    assert_eq!(&r[10..], b"Station address ");
    m.transact(&[0x5F, 0, 47, 10, 0x31, 1, 1, 1, 0x20, 1, 0x03, 0xC4, 0, 2]);
    let r = m.transact(&[0x5E, 0, 47, 240]);
    assert_eq!(&r[4..8], &[0x31, 1, 1, 1]);
    assert_eq!(&r[r.len() - 2..], &[0, 6], "PNU 964 has 6 elements: {r:02X?}");
    m.transact(&[0x5F, 0, 47, 10, 0x32, 1, 1, 1, 0x20, 1, 0x03, 0xC5, 0, 0]);
    assert_eq!(m.transact(&[0x5E, 0, 47, 240]), [0x5E, 0, 47, 8, 0x32, 0x81, 1, 1, 0x44, 1, 0, 0x09]);
}

/// Issue 12 item 1: I&M0 over MSAC_C1 and MSAC_C2 (reference §4.7, ABB FPBA-01 p. 128):
/// DS_Write slot 0 index 255 `08 00 FD E8` → `5F 00 FF 04`; DS_Read → `08 00 FD E8` + the
/// 64-byte I&M0; I&M1 written over C1 is read back over C2; the guideline's error answers.
#[test]
fn identification_and_maintenance_over_c1_and_c2() {
    let mut m = Master::new();
    m.bring_up(0x80);
    let mut im0 = vec![0u8; 10];
    im0.extend_from_slice(&card::IM_MANUFACTURER_ID.to_be_bytes());
    im0.extend_from_slice(b"ODC-PB1             ");
    im0.extend_from_slice(&[b' '; 16]); // no serial number from a drive here
    im0.extend_from_slice(&card::IM_HARDWARE_REVISION.to_be_bytes());
    im0.extend_from_slice(&card::IM_SOFTWARE_REVISION);
    im0.extend_from_slice(&[0, 0, 0x3A, 0x00, 0, 0, 0x01, 0x01, 0x00, 0x0F]);
    assert_eq!(im0.len(), 64);
    let read_answer = [&[0x5E, 0x00, 0xFF, 68, 0x08, 0x00, 0xFD, 0xE8][..], &im0].concat();

    // MSAC_C1.
    assert_eq!(m.transact(&[0x5E, 0x00, 0xFF, 0xF0]), [0xDE, 0x80, 0xB5, 0x00], "read without a call");
    assert_eq!(m.transact(&[0x5F, 0x00, 0xFF, 0x04, 0x08, 0x00, 0xFD, 0xE8]), [0x5F, 0x00, 0xFF, 0x04]);
    assert_eq!(m.transact(&[0x5E, 0x00, 0xFF, 0xF0]), read_answer);
    // I&M1: TAG_FUNCTION + TAG_LOCATION.
    let mut im1 = vec![0u8; 10];
    im1.extend_from_slice(b"Conveyor 3 main drive           ");
    im1.extend_from_slice(b"Hall B, cabinet 12    ");
    let write = [&[0x5F, 0x00, 0xFF, 68, 0x08, 0x00, 0xFD, 0xE9][..], &im1].concat();
    assert_eq!(m.transact(&write), [0x5F, 0x00, 0xFF, 68]);
    assert_eq!(m.rig.node.im_mut().take_changed().map(|d| d.records[0].to_vec()), Some(im1[10..].to_vec()));
    // Errors: write to I&M0, unknown FI_Index, wrong length, not a call, another slot.
    let mut w0 = vec![0x5F, 0x00, 0xFF, 68, 0x08, 0x00, 0xFD, 0xE8];
    w0.extend_from_slice(&[0; 64]);
    assert_eq!(m.transact(&w0), [0xDF, 0x80, 0xB6, 0x00]);
    assert_eq!(m.transact(&[0x5F, 0x00, 0xFF, 0x04, 0x08, 0x00, 0xFD, 0xED]), [0xDF, 0x80, 0xB0, 0x00]);
    assert_eq!(m.transact(&[0x5F, 0x00, 0xFF, 0x06, 0x08, 0x00, 0xFD, 0xE9, 1, 2]), [0xDF, 0x80, 0xB1, 0x00]);
    assert_eq!(m.transact(&[0x5F, 0x00, 0xFF, 0x04, 0x09, 0x00, 0xFD, 0xE8]), [0xDF, 0x80, 0xB8, 0x00]);
    assert_eq!(m.transact(&[0x5F, 0x01, 0xFF, 0x04, 0x08, 0x00, 0xFD, 0xE8]), [0xDF, 0x80, 0xB2, 0x00]);
    assert_eq!(m.transact(&[0x5E, 0x00, 0xFF, 67]), [0xDE, 0x80, 0xB1, 0x00], "no room for 68 bytes");

    // MSAC_C2: its own call; I&M1 as written over C1.
    let sap = m.connect(10);
    assert_eq!(m.c2_transact(10, sap, &[0x5E, 0x00, 0xFF, 0xF0]), [0xDE, 0x80, 0xB5, 0x00]);
    assert_eq!(m.c2_transact(10, sap, &[0x5F, 0x00, 0xFF, 0x04, 0x08, 0x00, 0xFD, 0xE8]), [0x5F, 0x00, 0xFF, 0x04]);
    assert_eq!(m.c2_transact(10, sap, &[0x5E, 0x00, 0xFF, 0xF0]), read_answer);
    assert_eq!(m.c2_transact(10, sap, &[0x5F, 0x00, 0xFF, 0x04, 0x08, 0x00, 0xFD, 0xE9]), [0x5F, 0x00, 0xFF, 0x04]);
    let r = m.c2_transact(10, sap, &[0x5E, 0x00, 0xFF, 0xF0]);
    assert_eq!(&r[..8], &[0x5E, 0x00, 0xFF, 68, 0x08, 0x00, 0xFD, 0xE9]);
    assert_eq!(&r[18..], &im1[10..]);
    // Leaving data exchange ends the C1 relation: its call is forgotten.
    let prm = SetPrm::CARD.watchdog(10, 10).user([0x80, 0, 0, 0, 0]).pdu();
    assert_eq!(m.send(M1, Some(61), Some(62), &prm, true), Ans::Sc);
    assert_eq!(m.send(M1, Some(62), Some(62), card::MODULES[0].cfg, true), Ans::Sc);
    assert_eq!(m.transact(&[0x5E, 0x00, 0xFF, 0xF0]), [0xDE, 0x80, 0xB5, 0x00]);
}

/// Issue 12 items 2 and 3 on the bus: with DPV1_Enable and Enable_Diagnostic_Alarm a drive
/// fault becomes a diagnostic alarm (announced by DH, carried in Slave_Diag as
/// `06 01 00 <Seq_Nr|appears> <fault code>`), acknowledged by Alarm_Ack `5C 00 01 01` on
/// SAP 51; a wrong acknowledgement gets `DC 80 B5 00`; the status block follows.
#[test]
fn diagnostic_alarm_and_alarm_ack_on_sap_51() {
    let mut m = Master::new();
    let prm = SetPrm::CARD.watchdog(10, 10).user([0x80, 0x20, 0x00, 0, 0]).pdu();
    assert_eq!(m.send(M1, Some(61), Some(62), &prm, true), Ans::Sc);
    assert_eq!(m.send(M1, Some(62), Some(62), card::MODULES[0].cfg, true), Ans::Sc);
    assert_eq!(m.rig.node.slave().state(), DpState::DataExch);
    let diag = |m: &mut Master| match m.send(M1, Some(60), Some(62), &[], true) {
        Ans::Pdu(p) => p,
        other => panic!("diag {other:?}"),
    };
    assert_eq!(diag(&mut m)[6..], [] as [u8; 0]);
    // The drive faults (what the DPM link hands the slave).
    m.rig.node.slave_mut().set_ext_diag(&[0x03, 0x01, 0x01], true).unwrap();
    m.rig.node.slave_mut().set_drive_fault(0x2310);
    let f = m.rig.master.request(M1, None, None, &[0x04, 0x7E, 0, 0], true);
    m.rig.now = m.rig.now + Duration::from_micros(500);
    let r = testkit::feed(&mut m.rig.node, m.rig.now, &f).expect("Data_Exchange answered");
    assert_eq!(r[6], 0x0A, "DH: new diagnosis");
    let d = diag(&mut m);
    assert_eq!(d[0] & 0x08, 0x08, "Ext_Diag");
    assert_eq!(d[6..], [0x06, 0x01, 0x00, 0x01, 0x23, 0x10]);
    assert_eq!(diag(&mut m)[6..], [0x06, 0x81, 0x00, 0x00, 0x01, 0x01], "then the Status_Message");
    assert_eq!(m.transact(&[0x5C, 0x00, 0x01, 0x02]), [0xDC, 0x80, 0xB5, 0x00], "wrong specifier");
    assert_eq!(m.transact(&[0x5C, 0x00, 0x01, 0x01]), [0x5C, 0x00, 0x01, 0x01]);
    assert_eq!(m.transact(&[0x5C, 0x00, 0x01, 0x01]), [0xDC, 0x80, 0xB5, 0x00], "acknowledged once");
}

// ----- The data-record seam (node::DataRecords): a product's own records behind I&M -----

/// A product's record: slot 3 / index 9 holds 2 bytes; a DS_Write makes it busy until the next
/// DP-V1 pass (an asynchronous job); the node's context and ended relations are recorded.
#[derive(Default)]
struct OwnRecords {
    value: [u8; 2],
    busy: bool,
    begins: u32,
    station: Option<pbcard::node::StationInfo>,
    ended: Vec<u8>,
}

impl pbcard::dpv1::records::RecordHandler for OwnRecords {
    fn read(&mut self, _: Instant, slot: u8, index: u8, out: &mut [u8]) -> Result<usize, ErrorCode1> {
        match (slot, index) {
            (3, 9) if out.len() >= 2 => {
                out[..2].copy_from_slice(&self.value);
                Ok(2)
            }
            (3, 9) => Err(ErrorCode1::WRITE_LENGTH_ERROR),
            (3, _) => Err(ErrorCode1::INVALID_INDEX),
            _ => Err(ErrorCode1::INVALID_SLOT),
        }
    }
    fn write(&mut self, _: Instant, slot: u8, index: u8, data: &[u8]) -> Result<(), ErrorCode1> {
        if (slot, index) != (3, 9) {
            return Err(ErrorCode1::INVALID_SLOT);
        }
        self.value.copy_from_slice(data.get(..2).ok_or(ErrorCode1::WRITE_LENGTH_ERROR)?);
        self.busy = true;
        Ok(())
    }
}

impl pbcard::node::DataRecords for OwnRecords {
    fn begin(&mut self, _: Instant, station: &pbcard::node::StationInfo) {
        self.begins += 1;
        self.station = Some(*station);
    }
    fn end_relation(&mut self, relation: u8) {
        self.ended.push(relation);
    }
    fn is_busy(&self) -> bool {
        self.busy
    }
}

/// Request, one DP-V1 pass over `records`, poll: one MSAC_C1 exchange.
fn exchange(m: &mut Master, records: &mut impl pbcard::node::DataRecords, pdu: &[u8]) -> Vec<u8> {
    assert_eq!(m.c1(M1, pdu), Ans::Sc, "request acknowledged with SC");
    m.rig.node.process_acyclic(m.rig.now, records);
    match m.c1(M1, &[]) {
        Ans::Pdu(p) => p,
        other => panic!("poll after processing: {other:?}"),
    }
}

/// The node serves I&M itself and every other record from the records the application
/// passes in: their Error_Code_1 goes out as the DP-V1 error PDU (Error_Decode 0x80), a busy
/// job keeps the node's work flag up, the records learn the station's context and the end of
/// a relation; without records ([`NoRecords`]) every record but I&M is 0xB2 "invalid slot".
#[test]
fn a_products_own_data_records_behind_im() {
    use pbcard::dpv1::records::NoRecords;
    let mut m = Master::new();
    m.bring_up(0x80);
    let mut own = OwnRecords::default();
    let w = exchange(&mut m, &mut own, &[0x5F, 3, 9, 2, 0x12, 0x34]);
    assert_eq!(w, [0x5F, 3, 9, 2]);
    assert!(m.rig.node.has_acyclic_work(), "the records' job keeps the DP-V1 task running");
    own.busy = false;
    let r = exchange(&mut m, &mut own, &[0x5E, 3, 9, 240]);
    assert_eq!(r, [0x5E, 3, 9, 2, 0x12, 0x34]);
    assert!(!m.rig.node.has_acyclic_work());
    let e = exchange(&mut m, &mut own, &[0x5E, 3, 8, 240]);
    assert_eq!(e, [0xDE, 0x80, 0xB0, 0x00]);
    // I&M0 (slot 0 / index 255) is the node's: a call, then the read.
    let call = exchange(&mut m, &mut own, &[0x5F, 0, 255, 4, 0x08, 0x00, 0xFD, 0xE8]);
    assert_eq!(call, [0x5F, 0, 255, 4]);
    let im0 = exchange(&mut m, &mut own, &[0x5E, 0, 255, 240]);
    assert_eq!(im0[..4], [0x5E, 0, 255, 68], "I&M0: 4 header bytes and 64 bytes of record");
    assert_eq!(own.station.map(|s| s.address), Some(ME));
    assert_eq!(own.station.and_then(|s| s.module).map(|md| md.cfg), Some(card::MODULES[0].cfg));
    assert_eq!(own.begins, 5);
    // Without records.
    let e = exchange(&mut m, &mut NoRecords, &[0x5E, 0, 47, 240]);
    assert_eq!(e, [0xDE, 0x80, 0xB2, 0x00]);
    // MSAC_C1 ends with a new Set_Prm: the records hear of it at the next pass.
    m.bring_up(0x80);
    m.rig.node.process_acyclic(m.rig.now, &mut own);
    assert_eq!(own.ended, [pbcard::dpv1::records::RELATION_C1]);
}
