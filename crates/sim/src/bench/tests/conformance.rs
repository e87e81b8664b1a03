//! Issue 12 item 4: conformance defects found when the card was tested as a PLC test lab
//! would, each fed as request bytes through the shipped card (`Node` + `Application`) and
//! judged by the answer bytes.

use super::*;
use crate::testkit::SetPrm;

/// A PROFIdrive parameter request (record 47) for one value: reference §5.1.
fn read_request(reference: u8, pnu: u16, subindex: u16, elements: u8) -> Vec<u8> {
    let p = pnu.to_be_bytes();
    let s = subindex.to_be_bytes();
    vec![reference, 0x01, 0x01, 0x01, 0x10, elements, p[0], p[1], s[0], s[1]]
}

/// Item b: PNU 944 (fault message counter) and PNU 947 (fault numbers) read over DP-V1 show
/// the profile layer's fault buffer while the drive is in fault (OPTE3/E5 §6.4.6).
#[test]
fn b_pnu_944_947_show_the_fault_buffer() {
    let mut b = Bench::new();
    b.bring_up_with(&card::MODULES[0], 0x80);
    for cw in [0x047E, 0x047F] {
        b.cycle(&[(cw >> 8) as u8, cw as u8, 0x20, 0x00], 5);
    }
    // No fault yet: counter 0, active situation empty.
    b.write47(&read_request(1, 944, 0, 1));
    assert_eq!(b.read47(), [1, 1, 1, 1, 0x42, 1, 0, 0]);
    b.app.drive_mut().inject_fault(0x2310, 0);
    for _ in 0..5 {
        b.cycle(&[0x04, 0x7F, 0x20, 0x00], 5);
    }
    assert_eq!(b.app.runtime().faults().numbers()[0], 0x2310, "the profile layer saw the fault");
    let counter = b.app.runtime().faults().counter();
    assert!(counter > 0);
    b.write47(&read_request(2, 944, 0, 1));
    let c = counter.to_be_bytes();
    assert_eq!(b.read47(), [2, 1, 1, 1, 0x42, 1, c[0], c[1]]);
    // PNU 947 elements 0..2: the active fault, then nothing.
    b.write47(&read_request(3, 947, 0, 2));
    assert_eq!(b.read47(), [3, 1, 1, 1, 0x42, 2, 0x23, 0x10, 0, 0]);
}

/// The PDU of a data answer (SD2 or SD3, after the SAP bytes).
fn sd2_pdu(r: &[u8]) -> Vec<u8> {
    match telegram::decode(r) {
        telegram::Decoded::Frame(telegram::Telegram::Data(t), n) if n == r.len() => t.pdu.to_vec(),
        other => panic!("no data answer: {r:02X?} ({other:?})"),
    }
}

/// Item i: Get_Cfg answers Real_Cfg_Data, the configuration in force — the drive's selected
/// telegram before Chk_Cfg, the accepted module in data exchange (reference §3.4).
#[test]
fn i_get_cfg_answers_the_drives_selected_telegram() {
    use crate::dpm::HostConfig;
    let st1 = &card::MODULES[0];
    let st20 = card::MODULES.iter().find(|m| Telegram::of_module(m) == Some(Telegram::Standard(20))).unwrap();
    let mut b = Bench::new();
    assert_eq!(sd2_pdu(&b.srd(Some(59), &[])), st1.cfg, "no selection, no Chk_Cfg: the first GSD module");
    b.app.host_mut().write_config(&HostConfig { telegram: Telegram::Standard(20), ..HostConfig::DEFAULT }).unwrap();
    b.step(1);
    b.step(1);
    assert_eq!(b.node.slave().required_module().map(|m| m.reference), Some(st20.reference));
    assert_eq!(sd2_pdu(&b.srd(Some(59), &[])), st20.cfg, "the drive's telegram 20");
    b.bring_up(st20);
    assert_eq!(sd2_pdu(&b.srd(Some(59), &[])), st20.cfg);
    // In data exchange a new selection waits (pending) and Get_Cfg keeps the module in force.
    b.app.host_mut().write_config(&HostConfig { telegram: Telegram::Standard(1), ..HostConfig::DEFAULT }).unwrap();
    b.step(1);
    b.step(1);
    assert_eq!(sd2_pdu(&b.srd(Some(59), &[])), st20.cfg, "in data exchange: the accepted module");
}

/// Runs the ST1 drive at 50 % (047E, then 047F) for a few cycles.
fn run_st1(b: &mut Bench) {
    for cw in [0x047E_u16, 0x047F, 0x047F, 0x047F] {
        b.cycle(&[(cw >> 8) as u8, cw as u8, 0x20, 0x00], 5);
    }
    assert_eq!(b.app.profidrive_state(), Some(DriveState::Operation));
}

/// A Set_Prm PDU with Station_Status `status`, min_TSDR `min_tsdr`, ident `ident` and the
/// default User_Prm_Data.
fn set_prm_pdu(status: u8, min_tsdr: u8, ident: u16) -> Vec<u8> {
    SetPrm::CARD.station_status(status).min_tsdr(min_tsdr).ident(ident).pdu().to_vec()
}

/// Item c: a Set_Prm from the locking master with Lock_Req = 0, Unlock_Req = 0 takes over
/// min_TSDR only — not validated, no Prm_Fault even with a foreign ident, the outputs and the
/// running drive untouched (EN 50170 lock table, reference §3.3). Unlock_Req with a foreign
/// ident releases the slave without Prm_Fault.
#[test]
fn c_lock0_unlock0_takes_min_tsdr_only_and_unlock_is_not_validated() {
    let mut b = Bench::new();
    b.bring_up(&card::MODULES[0]);
    run_st1(&mut b);
    assert_eq!(b.srd(Some(61), &set_prm_pdu(0x00, 37, 0x1234)), [telegram::SC]);
    b.step(1);
    assert_eq!(b.node.slave().state(), DpState::DataExch);
    assert_eq!(b.node.min_tsdr(), crate::time::BitTimes(37), "min_TSDR taken over");
    let diag = sd2_pdu(&b.srd(Some(60), &[]));
    assert_eq!(diag[0] & 0x40, 0, "no Prm_Fault: {diag:02X?}");
    assert_eq!(diag[3], MASTER, "still locked");
    assert_eq!(b.node.slave().outputs(), &[0x04, 0x7F, 0x20, 0x00], "outputs kept");
    b.cycle(&[0x04, 0x7F, 0x20, 0x00], 5);
    assert_eq!(b.app.profidrive_state(), Some(DriveState::Operation), "the drive keeps running");
    assert_eq!(b.node.slave().stats().prm_min_tsdr_only, 1);
    assert_eq!(b.node.slave().stats().prm_faults, 0);
    // min_TSDR 0 = keep.
    assert_eq!(b.srd(Some(61), &set_prm_pdu(0x00, 0, 0x1234)), [telegram::SC]);
    assert_eq!(b.node.min_tsdr(), crate::time::BitTimes(37));
    // Unlock with a foreign ident: released, no Prm_Fault, Master_Add 0xFF.
    assert_eq!(b.srd(Some(61), &set_prm_pdu(0x40, 11, 0x1234)), [telegram::SC]);
    b.step(1);
    assert_eq!(b.node.slave().state(), DpState::WaitPrm);
    let diag = sd2_pdu(&b.srd(Some(60), &[]));
    assert_eq!((diag[0] & 0x40, diag[1] & 0x01, diag[3]), (0, 0x01, 0xFF), "released: {diag:02X?}");
    assert_eq!(b.node.slave().stats().prm_unlocks, 1);
    assert!(b.node.slave().outputs().iter().all(|&x| x == 0), "outputs cleared");
}

/// Item g: a Set_Prm with fewer User_Prm_Data octets than the GSD's `Max_User_Prm_Data_Len`
/// (here: only the three DPV1_Status bytes, as a DP-V0 tool without the GSD's
/// ExtUserPrmData would send) is a Prm_Fault, not padded with defaults.
#[test]
fn g_short_set_prm_is_a_prm_fault() {
    let mut b = Bench::new();
    let short = &set_prm_pdu(0x88, 11, card::IDENT_NUMBER)[..10];
    assert_eq!(b.srd(Some(61), short), [telegram::SC]);
    b.step(1);
    assert_eq!(b.node.slave().state(), DpState::WaitPrm);
    let diag = sd2_pdu(&b.srd(Some(60), &[]));
    assert_eq!(diag[..4], [0x42, 0x05, 0x00, 0xFF], "Station_Not_Ready + Prm_Fault, Prm_Req: {diag:02X?}");
    assert_eq!(b.srd(Some(62), card::MODULES[0].cfg), [telegram::SC]);
    assert_eq!(b.node.slave().state(), DpState::WaitPrm, "Chk_Cfg not evaluated");
    // The full length is accepted; a short one in data exchange ends it (outputs zero).
    b.bring_up(&card::MODULES[0]);
    run_st1(&mut b);
    assert_eq!(b.srd(Some(61), &set_prm_pdu(0x88, 11, card::IDENT_NUMBER)[..11]), [telegram::SC]);
    b.step(1);
    assert_eq!(b.node.slave().state(), DpState::WaitPrm);
    assert!(b.node.slave().outputs().iter().all(|&x| x == 0));
    assert_eq!(b.node.slave().stats().prm_faults, 2);
}

/// MSAC_C2 Initiate.req (reference §4.5): Send_Timeout `send_timeout` × 10 ms, Read/Write,
/// Profile_Ident 0, S and D type 0 with 2-byte blocks.
fn initiate_req(send_timeout: u16) -> Vec<u8> {
    let t = send_timeout.to_be_bytes();
    vec![0x57, 0, 0, 0, t[0], t[1], 0x01, 0x00, 0, 0, 0, 0, 0, 2, 0, 2, 0, 0, 0, 0]
}

impl Bench {
    /// Open an MSAC_C2 connection from this master's SAP 50: Initiate.req on the resource
    /// manager (SAP 49), then on the server SAP, then a poll; returns the server SAP and the
    /// Initiate.res PDU.
    fn c2_connect(&mut self, send_timeout: u16) -> (u8, Vec<u8>) {
        let rm = sd2_pdu(&self.send(Some(49), Some(50), &initiate_req(send_timeout)));
        assert_eq!(rm[0], 0x56, "RM PDU {rm:02X?}");
        let sap = rm[1];
        assert_eq!(self.send(Some(sap), Some(50), &initiate_req(send_timeout)), [telegram::SC]);
        (sap, sd2_pdu(&self.send(Some(sap), Some(50), &[])))
    }

    /// [`Bench::c1`] for any answer frame (SD3 for a PDU of six octets).
    fn c1_pdu(&mut self, pdu: &[u8]) -> Vec<u8> {
        assert_eq!(self.send(Some(51), Some(51), pdu), [telegram::SC], "request acknowledged");
        self.acyclic();
        sd2_pdu(&self.send(Some(51), Some(51), &[]))
    }

    /// One MSAC_C2 request on `sap`, the DP-V1 task, one poll: the response PDU.
    fn c2(&mut self, sap: u8, pdu: &[u8]) -> Vec<u8> {
        assert_eq!(self.send(Some(sap), Some(50), pdu), [telegram::SC], "request acknowledged");
        self.acyclic();
        sd2_pdu(&self.send(Some(sap), Some(50), &[]))
    }
}

/// Item k: the MSAC_C2 Initiate.res carries Profile_Ident_Number 0x3A00, the PROFIdrive
/// profile the GSD states (`card::PROFILE_IDENT_NUMBER`), although the master sent 0.
#[test]
fn k_initiate_res_carries_the_profidrive_profile_ident() {
    let mut b = Bench::new();
    let (_, res) = b.c2_connect(300);
    // 57 | Max_Len_Data_Unit 240 | Features 01 00 | Profile_Features 00 00 | Profile_Ident 3A 00 |
    // S_Type 0 S_Len 2 D_Type 0 D_Len 2 | the request's D block, then its S block.
    assert_eq!(res, [0x57, 0xF0, 0x01, 0x00, 0x00, 0x00, 0x3A, 0x00, 0, 2, 0, 2, 0, 0, 0, 0]);
}

/// Item f: PNU 965 is one OctetString2 value `03 29` (PROFIdrive 4.1); PNU 975 has the eight
/// elements PROFIdrive defines; the number list 980 … lists the card's PNUs and then the
/// drive's parameters (P100, P101, …, read from the drive through the mailbox), zero-terminated,
/// and continues in 981.
#[test]
fn f_pnu_965_975_980_as_profidrive_defines_them() {
    use crate::profile::pnu::{CARD_PNUS, LIST_LEN};
    let mut b = Bench::new();
    b.bring_up_with(&card::MODULES[0], 0x80);
    b.write47(&read_request(1, 965, 0, 1));
    assert_eq!(b.read47(), [1, 1, 1, 1, 0x42, 1, 0x03, 0x29], "one OctetString2 value");
    b.write47(&read_request(2, 975, 0, 8));
    let r = b.read47();
    assert_eq!(r[..6], [2, 1, 1, 1, 0x42, 8], "{r:02X?}");
    assert_eq!(words(&r[6..]), [0, 1, 1, 2026, 2211, 1, 1, 1]);
    // PNU 980 / 981: the card's PNUs, the drive's (its table, through the mailbox), the end
    // mark, zeros.
    let mut all = CARD_PNUS.to_vec();
    all.extend(crate::drive::params::DRIVE_PARAMS.iter().map(|d| d.pnu));
    all.push(0);
    assert!(all.len() <= 2 * LIST_LEN);
    all.resize(2 * LIST_LEN, 0);
    b.write47(&read_request(3, 980, 0, 40));
    assert_eq!(b.read47(), [0xDE, 0x80, 0xB5, 0x00], "the drive's part comes through the mailbox");
    b.step(1);
    let r = b.read47();
    assert_eq!(r[..6], [3, 1, 1, 1, 0x42, 40], "{r:02X?}");
    assert_eq!(words(&r[6..]), all[..40]);
    // Subindex access and the continuation: 980 has 64 elements, 981 the next 64; element 64
    // does not exist.
    b.write47(&read_request(4, 980, 20, 4));
    b.step(1);
    assert_eq!(words(&b.read47()[6..]), all[20..24]);
    b.write47(&read_request(5, 981, 0, LIST_LEN as u8));
    b.step(1);
    let r = b.read47();
    assert_eq!(r[..6], [5, 1, 1, 1, 0x42, 64]);
    assert_eq!(words(&r[6..]), all[LIST_LEN..]);
    b.write47(&read_request(6, 980, LIST_LEN as u16, 1));
    b.step(1);
    assert_eq!(b.read47(), [6, 0x81, 1, 1, 0x44, 1, 0, 0x03], "invalid subindex");
}

/// Item h: record-47 state does not survive the end of its relation. MSAC_C1: a response
/// waiting when data exchange is left is not handed to the next relation; an orphaned job
/// (the drive never answered) does not block MSAC_C2 with 0xC2. MSAC_C2: a response waiting
/// when the connection is aborted (by the master or by Send_Timeout) is gone for the next
/// connection on the same SAP.
#[test]
fn h_record_47_state_ends_with_its_relation() {
    const STATE_CONFLICT: [u8; 4] = [0xDE, 0x80, 0xB5, 0x00];
    let p100 = read_request(1, 100, 0, 1);
    let write = |req: &[u8]| [&[0x5F, 0, 47, req.len() as u8][..], req].concat();
    let mut b = Bench::new();
    // C1: a response is ready, then data exchange is left and entered again.
    b.bring_up_with(&card::MODULES[0], 0x80);
    b.write47(&p100);
    b.step(1);
    b.acyclic();
    b.bring_up_with(&card::MODULES[0], 0x80);
    assert_eq!(b.read47(), STATE_CONFLICT, "no stale response for the new MSAC_C1 relation");
    // C1: an orphaned job (the drive does not answer), then data exchange ends.
    b.app.set_serve_parameters(false);
    b.write47(&p100);
    assert!(b.node.has_acyclic_work());
    assert_eq!(b.srd(Some(61), &set_prm_pdu(0x40, 11, card::IDENT_NUMBER)), [telegram::SC], "Unlock");
    b.step(1);
    b.app.set_serve_parameters(true);
    let (sap, _) = b.c2_connect(300);
    let mut req = read_request(2, 101, 0, 1);
    assert_eq!(b.c2(sap, &write(&req)), [0x5F, 0, 47, 10], "not blocked by the dead relation's job (0xC2)");
    b.step(1);
    b.acyclic();
    // C2: the response is waiting; the master aborts; a new connection gets none of it.
    assert_eq!(b.send(Some(sap), Some(50), &[0x58, 0x00, 0x20, 0x00]), [telegram::SC], "master Abort");
    let (sap2, _) = b.c2_connect(300);
    assert_eq!(sap2, sap, "the same SAP again");
    assert_eq!(b.c2(sap, &[0x5E, 0, 47, 240]), STATE_CONFLICT, "no stale response after an abort");
    // C2: a response is waiting; the connection times out (3 s); the next one reads nothing.
    req[0] = 3;
    assert_eq!(b.c2(sap, &write(&req)), [0x5F, 0, 47, 10]);
    b.step(1);
    b.acyclic();
    b.step(3100);
    assert_eq!(sd2_pdu(&b.send(Some(sap), Some(50), &[])), [0x58, 0x00, 0x13, 0x00], "timeout Abort");
    let (sap3, _) = b.c2_connect(300);
    assert_eq!(sap3, sap);
    assert_eq!(b.c2(sap, &[0x5E, 0, 47, 240]), STATE_CONFLICT, "no stale response after a timeout");
}

/// Item j: records 47 and 48 also answer at slot 1, the drive module's slot the GSD declares
/// (`SlotDefinition`, `card::RECORD_SLOTS`), as SINAMICS / ABB-style masters address them;
/// other slots stay 0xB2. Over MSAC_C1 and MSAC_C2.
#[test]
fn j_records_answer_at_the_drive_modules_slot() {
    let mut b = Bench::new();
    b.bring_up_with(&card::MODULES[0], 0x80);
    let req = read_request(9, 918, 0, 1);
    let mut write = vec![0x5F, card::DRIVE_MODULE_SLOT, 47, req.len() as u8];
    write.extend_from_slice(&req);
    assert_eq!(b.c1(&write), [0x5F, 1, 47, 10]);
    assert_eq!(b.c1(&[0x5E, 1, 47, 240]), [0x5E, 1, 47, 8, 9, 1, 1, 1, 0x42, 1, 0, SLAVE]);
    // WEG simple access (record 48) at slot 1: select P100, read it.
    assert_eq!(b.c1(&[0x5F, 1, 48, 2, 0, 100]), [0xDF, 0x80, 0xC2, 0x00], "the value comes from the drive");
    b.step(1);
    assert_eq!(b.c1(&[0x5F, 1, 48, 2, 0, 100]), [0x5F, 1, 48, 2], "repeated");
    if b.c1_pdu(&[0x5E, 1, 48, 2]) == [0xDE, 0x80, 0xC2, 0x00] {
        b.step(1);
    }
    assert_eq!(b.c1_pdu(&[0x5E, 1, 48, 2]), [0x5E, 1, 48, 2, 0, 50]);
    // Slot 2 is no slot of this device.
    write[1] = 2;
    assert_eq!(b.c1(&write), [0xDF, 0x80, 0xB2, 0x00]);
    assert_eq!(b.c1(&[0x5E, 2, 47, 240]), [0xDE, 0x80, 0xB2, 0x00]);
    // MSAC_C2 at slot 1.
    let (sap, _) = b.c2_connect(300);
    write[1] = 1;
    assert_eq!(b.c2(sap, &write), [0x5F, 1, 47, 10]);
    assert_eq!(b.c2(sap, &[0x5E, 1, 47, 240]), [0x5E, 1, 47, 8, 9, 1, 1, 1, 0x42, 1, 0, SLAVE]);
}

/// Item l: a Data_Exchange with a wrong non-zero output length is answered RS, its outputs
/// are not taken, and the slave leaves data exchange (outputs zero, the drive sees the master
/// gone; Wait_Prm with Cfg_Fault) instead of running on stale outputs that every such request
/// would keep alive by retriggering the watchdog.
#[test]
fn l_wrong_output_length_ends_data_exchange() {
    let mut b = Bench::new();
    b.bring_up(&card::MODULES[0]);
    run_st1(&mut b);
    let r = b.srd(None, &[0x04, 0x7F, 0x20, 0x00, 0x99, 0x99]);
    assert_eq!(r, [0x10, MASTER, SLAVE, 0x03, MASTER + SLAVE + 0x03, 0x16], "SD1 RS");
    b.step(1);
    assert_eq!(b.node.slave().state(), DpState::WaitPrm);
    assert!(b.node.slave().outputs().iter().all(|&x| x == 0), "outputs zero, not 99 99");
    let diag = sd2_pdu(&b.srd(Some(60), &[]));
    assert_eq!(diag[..4], [0x06, 0x05, 0x00, 0xFF], "Station_Not_Ready + Cfg_Fault, Prm_Req: {diag:02X?}");
    b.step(5);
    assert_ne!(b.app.profidrive_state(), Some(DriveState::Operation), "the drive does not run on stale outputs");
    assert_eq!(b.node.slave().stats().wrong_output_len, 1);
    // The master parameterizes again and the drive can be switched on.
    b.bring_up(&card::MODULES[0]);
    assert_eq!(sd2_pdu(&b.srd(Some(60), &[]))[0] & 0x46, 0x00, "no Cfg_Fault / Prm_Fault / Not_Ready");
}

/// Item e (station part): requests from SA 127, from the card's own address, or with FC
/// bit 7 set are never answered and never reach the DP slave (counted), whatever the service;
/// the same requests from the master are answered.
#[test]
fn e_impossible_sources_and_reserved_fc_are_never_answered() {
    let mut b = Bench::new();
    b.bring_up(&card::MODULES[0]);
    let sd1 = |sa: u8, fc: u8| vec![0x10, SLAVE, sa, fc, SLAVE.wrapping_add(sa).wrapping_add(fc), 0x16];
    let sd2 = |sa: u8, fc: u8, dsap: Option<u8>, pdu: &[u8]| {
        let hdr = Header { da: SLAVE, sa, fc: FunctionCode(fc), dsap, ssap: dsap.map(|_| 62) };
        let mut out = [0u8; telegram::MAX_FRAME_LEN];
        let n = telegram::emit(&mut out, &hdr, pdu).unwrap();
        out[..n].to_vec()
    };
    let outputs = [0x04, 0x7E, 0x11, 0x11];
    let frames = [
        sd1(127, 0x49),
        sd1(SLAVE, 0x49),
        sd1(MASTER, 0xC9),
        sd2(127, 0x6D, Some(60), &[]),
        sd2(SLAVE, 0x6D, Some(60), &[]),
        sd2(MASTER, 0xED, Some(60), &[]),
        sd2(127, 0x7D, None, &outputs),
        sd2(SLAVE, 0x7D, None, &outputs),
        sd2(MASTER, 0xFD, None, &outputs),
        // Set_Prm with a foreign ident from SA 127 / own address / FC b7: never evaluated.
        sd2(127, 0x6D, Some(61), &set_prm_pdu(0x88, 11, 0x1234)),
        sd2(SLAVE, 0x6D, Some(61), &set_prm_pdu(0x88, 11, 0x1234)),
        sd2(MASTER, 0xED, Some(61), &set_prm_pdu(0x88, 11, 0x1234)),
    ];
    let before = b.node.station().stats();
    for f in &frames {
        for &x in f {
            assert!(b.node.on_byte(b.now, x).is_none(), "answered: {f:02X?}");
        }
    }
    let after = b.node.station().stats();
    assert_eq!(after.bad_source - before.bad_source, 8);
    assert_eq!(after.reserved_fc - before.reserved_fc, 4);
    assert_eq!(after.requests, before.requests, "nothing reached the DP slave");
    assert_eq!(b.node.slave().state(), DpState::DataExch);
    assert_eq!(b.node.slave().stats().prm_faults, 0);
    assert!(b.node.slave().outputs().iter().all(|&x| x == 0), "no outputs taken");
    // From the master: answered.
    let mut r = None;
    for &x in &sd1(MASTER, 0x49) {
        r = b.node.on_byte(b.now, x).map(|r| r.to_vec());
    }
    assert_eq!(r.unwrap(), [0x10, MASTER, SLAVE, 0x00, MASTER + SLAVE, 0x16], "FDL_Status from the master");
    assert!(sd2_pdu(&b.srd(Some(60), &[])).len() >= 6, "Slave_Diag from the master");
}
