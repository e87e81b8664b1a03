//! Scripted tests of the DP slave behind the FDL station: the services and failure cases a
//! peer master (profirust) never sends, byte for byte.

use crate::card;
use crate::dp::*;
use crate::fdl::station::Station;
use crate::fdl::telegram::{self, decode, Decoded, FunctionCode, Header, Telegram};
use crate::time::{BitTimes, Duration, Instant};

const ME: u8 = 8;
const M1: u8 = 2;
const M2: u8 = 3;
const ST1: &[u8] = &[0xC3, 0xC1, 0xC1, 0xFD, 0x00, 0x01];

struct Bus {
    station: Station,
    slave: DpSlave,
    fcb: [bool; 128],
    now: u64,
}

#[derive(Debug, PartialEq)]
enum Ans {
    None,
    Sc,
    Sd1(u8),
    Data { fc: u8, dsap: Option<u8>, ssap: Option<u8>, pdu: Vec<u8> },
}

impl Bus {
    fn new() -> Self {
        Bus { station: Station::new(), slave: DpSlave::new(&card::SLAVE, ME), fcb: [false; 128], now: 0 }
    }

    fn raw(&mut self, frame: &[u8]) -> Option<Vec<u8>> {
        self.now += 1000;
        self.slave.poll(Instant::from_micros(self.now));
        self.station.on_frame(Instant::from_micros(self.now), frame, &mut self.slave).map(|r| r.to_vec())
    }

    /// Build a request from master `sa` (FCB toggled per master, FCV = 1).
    fn frame(&mut self, sa: u8, da: u8, func: u8, dsap: Option<u8>, pdu: &[u8], toggle: bool) -> Vec<u8> {
        if toggle {
            self.fcb[sa as usize] = !self.fcb[sa as usize];
        }
        let fc = FunctionCode::request(func, self.fcb[sa as usize], true);
        let ssap = dsap.map(|_| 62);
        let hdr = Header { da, sa, fc, dsap, ssap };
        let mut out = [0u8; 256];
        let n = telegram::emit(&mut out, &hdr, pdu).unwrap();
        out[..n].to_vec()
    }

    fn req(&mut self, sa: u8, dsap: Option<u8>, pdu: &[u8]) -> Ans {
        let f = self.frame(sa, ME, 0x0D, dsap, pdu, true);
        parse(self.raw(&f))
    }

    fn sdn(&mut self, sa: u8, da: u8, dsap: u8, pdu: &[u8]) -> Option<Vec<u8>> {
        let hdr = Header { da, sa, fc: FunctionCode::request(0x06, false, false), dsap: Some(dsap), ssap: Some(62) };
        let mut out = [0u8; 64];
        let n = telegram::emit(&mut out, &hdr, pdu).unwrap();
        self.raw(&out[..n])
    }

    fn diag(&mut self, sa: u8) -> Vec<u8> {
        match self.req(sa, Some(60), &[]) {
            Ans::Data { fc: 0x08, dsap: Some(62), ssap: Some(60), pdu } => pdu,
            other => panic!("diag answer {other:?}"),
        }
    }

    fn set_prm(&mut self, sa: u8, status: u8, user: &[u8]) -> Ans {
        let p = crate::testkit::SetPrm::CARD.station_status(status).wd_factors(10, 10).group(0x01).user_bytes(user);
        self.req(sa, Some(61), &p.pdu())
    }

    fn bring_up(&mut self, status: u8) {
        assert_eq!(self.set_prm(M1, status, &card::USER_PRM_DEFAULTS), Ans::Sc);
        assert_eq!(self.req(M1, Some(62), ST1), Ans::Sc);
        assert_eq!(self.slave.state(), DpState::DataExch);
    }
}

fn parse(r: Option<Vec<u8>>) -> Ans {
    let Some(r) = r else { return Ans::None };
    match decode(&r) {
        Decoded::Frame(Telegram::ShortAck, 1) => Ans::Sc,
        Decoded::Frame(Telegram::Data(t), n) if n == r.len() => {
            assert_eq!((t.da, t.sa), (t.da, ME), "response from our address");
            if t.pdu.is_empty() && t.dsap.is_none() {
                Ans::Sd1(t.fc.0)
            } else {
                Ans::Data { fc: t.fc.0, dsap: t.dsap, ssap: t.ssap, pdu: t.pdu.to_vec() }
            }
        }
        other => panic!("slave sent an invalid frame {other:?} {r:02x?}"),
    }
}

fn id() -> [u8; 2] {
    card::IDENT_NUMBER.to_be_bytes()
}

#[test]
fn fdl_status_is_answered_with_sd1_ok() {
    let mut b = Bus::new();
    let r = b.raw(&[0x10, ME, M1, 0x49, (ME + M1 + 0x49), 0x16]).unwrap();
    assert_eq!(r, vec![0x10, M1, ME, 0x00, M1 + ME, 0x16]);
}

#[test]
fn diag_in_every_state() {
    let mut b = Bus::new();
    // Power on / Wait_Prm: Station_Not_Ready, Prm_Req, Master_Add 0xFF.
    assert_eq!(b.diag(M1), vec![0x02, 0x05, 0x00, 0xFF, id()[0], id()[1]]);
    // Wait_Cfg after Set_Prm with Lock + WD_On: Not_Ready, WD_On, locked by M1.
    assert_eq!(b.set_prm(M1, 0x88, &card::USER_PRM_DEFAULTS), Ans::Sc);
    assert_eq!(b.slave.state(), DpState::WaitCfg);
    assert_eq!(b.diag(M1), vec![0x02, 0x0C, 0x00, M1, id()[0], id()[1]]);
    // Data_Exch: all clear.
    assert_eq!(b.req(M1, Some(62), ST1), Ans::Sc);
    assert_eq!(b.diag(M1), vec![0x00, 0x0C, 0x00, M1, id()[0], id()[1]]);
    // Sync + Freeze requested: modes appear after the commands.
    let mut b = Bus::new();
    b.bring_up(0xB8);
    b.sdn(M1, 127, 58, &[0x28, 0x00]);
    assert_eq!(b.diag(M1)[1], 0x3C);
}

#[test]
fn prm_faults_and_recovery() {
    let mut b = Bus::new();
    // Wrong ident → Prm_Fault, Wait_Prm.
    let mut p = vec![0x88, 10, 10, 11, 0x12, 0x34, 0x00];
    p.extend_from_slice(&card::USER_PRM_DEFAULTS);
    assert_eq!(b.req(M1, Some(61), &p), Ans::Sc);
    assert_eq!(b.diag(M1)[..4], [0x42, 0x05, 0x00, 0xFF]);
    // Out-of-range user parameter (operate mode 9).
    assert_eq!(b.set_prm(M1, 0x88, &[0, 0, 0, 9, 0]), Ans::Sc);
    assert_eq!(b.diag(M1)[0], 0x42);
    // Publisher_Enable (DXB), which the card does not offer.
    assert_eq!(b.set_prm(M1, 0x88, &[0x20, 0, 0, 0, 0]), Ans::Sc);
    assert_eq!(b.diag(M1)[0], 0x42);
    // A good Set_Prm clears the fault.
    b.bring_up(0x88);
    assert_eq!(b.diag(M1)[0], 0x00);
    assert_eq!(b.slave.stats().prm_faults, 3);
}

#[test]
fn cfg_fault_goes_back_to_wait_prm() {
    let mut b = Bus::new();
    assert_eq!(b.set_prm(M1, 0x88, &card::USER_PRM_DEFAULTS), Ans::Sc);
    assert_eq!(b.req(M1, Some(62), &[0xF2]), Ans::Sc);
    assert_eq!(b.slave.state(), DpState::WaitPrm);
    assert_eq!(b.diag(M1)[..4], [0x06, 0x05, 0x00, 0xFF]);
    assert!(b.slave.take_events().contains(Events::CFG_FAULT));
    // Chk_Cfg in Wait_Prm → SC, not evaluated (profirust accepts only SC here).
    assert_eq!(b.req(M1, Some(62), ST1), Ans::Sc);
    assert_eq!(b.slave.state(), DpState::WaitPrm);
    assert_eq!(b.slave.stats().cfg_ignored, 1);
}

#[test]
fn get_cfg_rd_inp_rd_outp() {
    let mut b = Bus::new();
    // Before configuration Get_Cfg returns the default module; Rd_Inp is closed.
    assert_eq!(b.req(M2, Some(59), &[]), Ans::Data { fc: 0x08, dsap: Some(62), ssap: Some(59), pdu: ST1.to_vec() });
    assert_eq!(b.req(M2, Some(56), &[]), Ans::Sd1(0x03));
    b.bring_up(0x88);
    b.slave.set_inputs(&[1, 2, 3, 4]);
    assert_eq!(b.req(M1, None, &[9, 8, 7, 6]), Ans::Data { fc: 0x08, dsap: None, ssap: None, pdu: vec![1, 2, 3, 4] });
    assert_eq!(b.req(M2, Some(56), &[]), Ans::Data { fc: 0x08, dsap: Some(62), ssap: Some(56), pdu: vec![1, 2, 3, 4] });
    assert_eq!(b.req(M2, Some(57), &[]), Ans::Data { fc: 0x08, dsap: Some(62), ssap: Some(57), pdu: vec![9, 8, 7, 6] });
}

#[test]
fn data_exchange_lengths_and_clear() {
    let mut b = Bus::new();
    b.bring_up(0xC8 & 0x88);
    // Wrong length → RS, outputs not taken but zero: the slave leaves data exchange with
    // Cfg_Fault (issue 12 item 4l).
    assert_eq!(b.req(M1, None, &[1, 2, 3, 4]), Ans::Data { fc: 0x08, dsap: None, ssap: None, pdu: vec![0; 4] });
    assert_eq!(b.req(M1, None, &[5, 6]), Ans::Sd1(0x03));
    assert_eq!(b.slave.outputs(), &[0; 4]);
    assert_eq!(b.slave.stats().wrong_output_len, 1);
    assert_eq!(b.slave.state(), DpState::WaitPrm);
    assert_eq!(b.diag(M1)[..4], [0x06, 0x05, 0x00, 0xFF], "Not_Ready + Cfg_Fault, Prm_Req");
    b.bring_up(0x88);
    assert_eq!(b.diag(M1)[0], 0x00, "a new parameterization clears Cfg_Fault");
    assert!(matches!(b.req(M1, None, &[1, 2, 3, 4]), Ans::Data { .. }));
    // Zero-length outputs = fail-safe clear.
    b.slave.take_events();
    assert!(matches!(b.req(M1, None, &[]), Ans::Data { .. }));
    assert!(b.slave.is_clear());
    assert_eq!(b.slave.outputs(), &[0; 4]);
    assert!(b.slave.take_events().contains(Events::CLEAR_CHANGED | Events::OUTPUTS_UPDATED));
    assert!(matches!(b.req(M1, None, &[7, 7, 7, 7]), Ans::Data { .. }));
    assert!(!b.slave.is_clear());
    // Global_Control Clear_Data clears the outputs and enters Clear; a GC without it leaves.
    b.sdn(M1, 127, 58, &[0x02, 0x00]);
    assert!(b.slave.is_clear());
    assert_eq!(b.slave.outputs(), &[0; 4]);
    // In Clear, outputs stay zero whatever Data_Exchange carries.
    assert!(matches!(b.req(M1, None, &[9, 9, 9, 9]), Ans::Data { .. }));
    assert_eq!(b.slave.outputs(), &[0; 4]);
    b.sdn(M1, 127, 58, &[0x00, 0x00]);
    assert!(!b.slave.is_clear());
    assert!(matches!(b.req(M1, None, &[9, 9, 9, 9]), Ans::Data { .. }));
    assert_eq!(b.slave.outputs(), &[9; 4]);
}

#[test]
fn sync_and_freeze_semantics() {
    let mut b = Bus::new();
    b.bring_up(0xB8);
    b.slave.set_inputs(&[1, 1, 1, 1]);
    b.req(M1, None, &[1, 0, 0, 0]);
    assert_eq!(b.slave.outputs(), &[1, 0, 0, 0]);
    // Sync: outputs after it are held until the next Sync.
    b.sdn(M1, 127, 58, &[0x20, 0x00]);
    b.req(M1, None, &[2, 0, 0, 0]);
    assert_eq!(b.slave.outputs(), &[1, 0, 0, 0]);
    b.sdn(M1, 127, 58, &[0x20, 0x00]);
    assert_eq!(b.slave.outputs(), &[2, 0, 0, 0]);
    // Unsync applies what is pending and returns to direct outputs.
    b.req(M1, None, &[3, 0, 0, 0]);
    b.sdn(M1, 127, 58, &[0x30, 0x00]); // Sync + Unsync = Unsync
    assert!(!b.slave.is_sync());
    assert_eq!(b.slave.outputs(), &[3, 0, 0, 0]);
    b.req(M1, None, &[4, 0, 0, 0]);
    assert_eq!(b.slave.outputs(), &[4, 0, 0, 0]);
    // Freeze: inputs sampled now and held.
    b.sdn(M1, 127, 58, &[0x08, 0x00]);
    b.slave.set_inputs(&[2, 2, 2, 2]);
    assert!(matches!(b.req(M1, None, &[4, 0, 0, 0]), Ans::Data { pdu, .. } if pdu == [1, 1, 1, 1]));
    b.sdn(M1, 127, 58, &[0x08, 0x00]);
    b.slave.set_inputs(&[3, 3, 3, 3]);
    assert!(matches!(b.req(M1, None, &[4, 0, 0, 0]), Ans::Data { pdu, .. } if pdu == [2, 2, 2, 2]));
    b.sdn(M1, 127, 58, &[0x04, 0x00]); // Unfreeze
    assert!(matches!(b.req(M1, None, &[4, 0, 0, 0]), Ans::Data { pdu, .. } if pdu == [3, 3, 3, 3]));
    // Group select: GC for group 0x02 is ignored by a slave in group 0x01.
    b.sdn(M1, 127, 58, &[0x02, 0x02]);
    assert!(!b.slave.is_clear());
    b.sdn(M1, 127, 58, &[0x02, 0x01]);
    assert!(b.slave.is_clear());
}

/// Safety (issue 12 4a): Clear never applies what Sync held. The sequence: Set_Prm with
/// Sync_Req, DX `01 02 03 04`, GC Sync `20 00`, DX `05 06 07 08`, GC Clear+Sync `22 00` → outputs
/// zero (Rd_Outp too) and the held image discarded; the same for Clear+Unsync, Clear alone and
/// zero-length outputs, and nothing held comes back when Clear ends.
#[test]
fn clear_with_sync_never_applies_the_held_outputs() {
    // (command that enters Clear while outputs are held, via zero-length outputs?)
    for (gc, fs_clear) in [(0x22, false), (0x12, false), (0x02, false), (0x32, false), (0x00, true)] {
        let mut b = Bus::new();
        b.bring_up(0xB8);
        b.req(M1, None, &[1, 2, 3, 4]);
        assert_eq!(b.slave.outputs(), &[1, 2, 3, 4]);
        b.sdn(M1, 127, 58, &[0x20, 0x00]);
        b.req(M1, None, &[5, 6, 7, 8]);
        assert_eq!(b.slave.outputs(), &[1, 2, 3, 4], "held under Sync");
        if fs_clear {
            b.req(M1, None, &[]);
        } else {
            b.sdn(M1, 127, 58, &[gc, 0x00]);
        }
        assert!(b.slave.is_clear(), "GC {gc:02X}");
        assert_eq!(b.slave.outputs(), &[0; 4], "GC {gc:02X} fs {fs_clear}: zero, not the held image");
        let rd = b.req(M2, Some(57), &[]);
        assert!(matches!(rd, Ans::Data { ref pdu, .. } if pdu == &[0; 4]), "Rd_Outp {rd:?}");
        // While Clear lasts: Data_Exchange and further Syncs change nothing.
        if !fs_clear {
            for _ in 0..3 {
                b.req(M1, None, &[5, 6, 7, 8]);
                b.sdn(M1, 127, 58, &[0x22, 0x00]);
                assert_eq!(b.slave.outputs(), &[0; 4], "GC {gc:02X}: zero while Clear lasts");
            }
        }
        // Clear ends (operate, Sync or Unsync): the discarded image never comes back.
        b.sdn(M1, 127, 58, &[0x00, 0x00]);
        if fs_clear {
            // Leaving fail-safe Clear with fresh outputs of the right length.
            b.req(M1, None, &[9, 9, 9, 9]);
        }
        b.sdn(M1, 127, 58, &[0x10, 0x00]);
        assert!(!b.slave.is_clear());
        assert_ne!(b.slave.outputs(), &[5, 6, 7, 8], "GC {gc:02X} fs {fs_clear}: stale held outputs");
        // Live again: the newest outputs apply.
        b.req(M1, None, &[7, 7, 7, 7]);
        assert_eq!(b.slave.outputs(), &[7, 7, 7, 7]);
    }
}

/// Freeze_Mode (diagnosis octet 2 b4, issue 12 4d) follows Unfreeze at once: `04 00` and `0C 00`.
#[test]
fn freeze_mode_bit_clears_on_unfreeze() {
    for unfreeze in [0x04, 0x0C] {
        let mut b = Bus::new();
        b.bring_up(0xB8);
        b.req(M1, None, &[1, 0, 0, 0]);
        b.sdn(M1, 127, 58, &[0x08, 0x00]);
        assert!(b.slave.is_freeze());
        assert_eq!(b.diag(M1)[1] & 0x10, 0x10, "Freeze_Mode set");
        b.sdn(M1, 127, 58, &[unfreeze, 0x00]);
        assert!(!b.slave.is_freeze());
        assert_eq!(b.diag(M1)[1] & 0x10, 0, "GC {unfreeze:02X}: Freeze_Mode cleared");
    }
}

#[test]
fn sync_without_sync_req_is_not_supported() {
    let mut b = Bus::new();
    b.bring_up(0x88);
    b.req(M1, None, &[1, 0, 0, 0]);
    b.sdn(M1, 127, 58, &[0x20, 0x00]);
    assert!(!b.slave.is_sync());
    // Not_Supported is announced with DH and shown in the diagnosis.
    assert!(matches!(b.req(M1, None, &[2, 0, 0, 0]), Ans::Data { fc: 0x0A, .. }));
    assert_eq!(b.slave.outputs(), &[2, 0, 0, 0]);
    assert_eq!(b.diag(M1)[0], 0x10);
    assert!(matches!(b.req(M1, None, &[2, 0, 0, 0]), Ans::Data { fc: 0x08, .. }));
}

#[test]
fn global_control_only_from_locking_master() {
    let mut b = Bus::new();
    b.bring_up(0xB8);
    b.sdn(M2, 127, 58, &[0x02, 0x00]);
    assert!(!b.slave.is_clear());
    // Addressed to us directly works too, and is never answered.
    assert_eq!(b.sdn(M1, ME, 58, &[0x02, 0x00]), None);
    assert!(b.slave.is_clear());
}

#[test]
fn master_lock() {
    let mut b = Bus::new();
    b.bring_up(0x88);
    // A second master cannot parameterize, configure or write outputs; it reads diagnosis.
    assert_eq!(b.set_prm(M2, 0x88, &card::USER_PRM_DEFAULTS), Ans::Sc);
    assert_eq!(b.slave.master_address(), Some(M1));
    assert_eq!(b.req(M2, Some(62), &[0xF5]), Ans::Sc);
    assert_eq!(b.slave.module(), Some(&card::MODULES[0]));
    assert_eq!(b.req(M2, None, &[1, 2, 3, 4]), Ans::Sd1(0x03));
    assert_eq!(b.slave.outputs(), &[0; 4]);
    assert_eq!(b.diag(M2)[3], M1);
    assert_eq!(b.slave.state(), DpState::DataExch);
    // Unlock by the owner releases the slave; then M2 may take it.
    assert_eq!(b.set_prm(M1, 0x40, &[]), Ans::Sc);
    assert_eq!(b.slave.master_address(), None);
    assert_eq!(b.set_prm(M2, 0x88, &card::USER_PRM_DEFAULTS), Ans::Sc);
    assert_eq!(b.slave.master_address(), Some(M2));
}

#[test]
fn lock0_unlock0_only_takes_min_tsdr() {
    let mut b = Bus::new();
    let mut p = vec![0x00, 10, 10, 40, id()[0], id()[1], 0];
    p.extend_from_slice(&card::USER_PRM_DEFAULTS);
    assert_eq!(b.req(M1, Some(61), &p), Ans::Sc);
    assert_eq!(b.slave.min_tsdr(), BitTimes(40));
    assert_eq!(b.slave.state(), DpState::WaitPrm);
}

#[test]
fn watchdog_expiry_leaves_data_exchange() {
    let mut b = Bus::new();
    b.bring_up(0x88); // WD 10 × 10 × 10 ms = 1 s
    assert_eq!(b.slave.watchdog_time(), Some(Duration::from_millis(1000)));
    b.req(M1, None, &[1, 2, 3, 4]);
    b.slave.take_events();
    b.slave.poll(Instant::from_micros(b.now + 999_000));
    assert_eq!(b.slave.state(), DpState::DataExch);
    b.slave.poll(Instant::from_micros(b.now + 1_000_000));
    assert_eq!(b.slave.state(), DpState::WaitPrm);
    assert_eq!(b.slave.outputs(), &[0; 4]);
    assert!(b
        .slave
        .take_events()
        .contains(Events::WATCHDOG_EXPIRED | Events::LEFT_DATA_EXCHANGE | Events::OUTPUTS_UPDATED));
    assert_eq!(b.diag(M1)[..4], [0x02, 0x05, 0x00, 0xFF]);
    // WD base 1 ms.
    let mut b = Bus::new();
    assert_eq!(b.set_prm(M1, 0x88, &[0x04, 0, 0, 0, 0]), Ans::Sc);
    assert_eq!(b.slave.watchdog_time(), Some(Duration::from_millis(100)));
}

#[test]
fn fcb_retry_resends_without_executing() {
    let mut b = Bus::new();
    b.bring_up(0xB8);
    b.sdn(M1, 127, 58, &[0x20, 0x00]); // Sync mode: outputs pend
    b.slave.set_inputs(&[1, 2, 3, 4]);
    let f = b.frame(M1, ME, 0x0D, None, &[5, 5, 5, 5], true);
    let first = b.raw(&f).unwrap();
    let count = b.slave.stats().data_exchanges;
    // The application changes its inputs; the retry still gets the first answer.
    b.slave.set_inputs(&[9, 9, 9, 9]);
    let again = b.raw(&f).unwrap();
    assert_eq!(first, again);
    assert_eq!(b.slave.stats().data_exchanges, count);
    assert_eq!(b.station.stats().retries, 1);
    // A new request (FCB toggled) gets the new inputs.
    assert!(matches!(b.req(M1, None, &[5, 5, 5, 5]), Ans::Data { pdu, .. } if pdu == [9, 9, 9, 9]));
    // A retried Set_Prm after a reply is not evaluated again.
    let mut p = vec![0x88, 1, 1, 11, id()[0], id()[1], 0];
    p.extend_from_slice(&card::USER_PRM_DEFAULTS);
    let f = b.frame(M1, ME, 0x0D, Some(61), &p, true);
    assert_eq!(b.raw(&f).unwrap(), vec![0xE5]);
    assert!(b.slave.take_events().contains(Events::PRM_ACCEPTED));
    assert_eq!(b.raw(&f).unwrap(), vec![0xE5]);
    assert!(b.slave.take_events().is_empty(), "retry must not re-parameterize");
    assert_eq!(b.station.stats().retries, 2);
}

#[test]
fn set_slave_add() {
    let mut b = Bus::new();
    let i = id();
    // Wrong ident → RS.
    assert_eq!(b.req(M2, Some(55), &[20, 0, 0, 0]), Ans::Sd1(0x03));
    // Too short → RS.
    assert_eq!(b.req(M2, Some(55), &[20]), Ans::Sd1(0x03));
    // Address 126 is not allowed as a new address.
    assert_eq!(b.req(M2, Some(55), &[126, i[0], i[1], 0]), Ans::Sd1(0x03));
    // Accepted, and frozen with No_Add_Chg.
    assert_eq!(b.req(M2, Some(55), &[20, i[0], i[1], 1]), Ans::Sc);
    assert_eq!((b.slave.address(), b.slave.no_add_chg()), (20, true));
    assert!(b.slave.take_events().contains(Events::ADDRESS_CHANGED));
    // The old address is dead; the new one answers; a further change is refused.
    let f = b.frame(M2, ME, 0x0D, Some(60), &[], true);
    assert_eq!(b.raw(&f), None);
    let f = b.frame(M2, 20, 0x0D, Some(55), &[30, i[0], i[1], 0], true);
    assert!(matches!(parse_from(b.raw(&f), 20), Some(0x03)));
    // Only before parameterization.
    let mut b = Bus::new();
    b.bring_up(0x88);
    assert_eq!(b.req(M2, Some(55), &[20, i[0], i[1], 0]), Ans::Sd1(0x03));
}

/// The drive's station address (DPM CONFIG): outside data exchange like Set_Slave_Add,
/// refused in data exchange and once No_Add_Chg froze the address.
#[test]
fn set_address_from_the_drive() {
    use slave_add::SlaveAddError;
    let mut b = Bus::new();
    assert_eq!(b.slave.set_address(126), Err(SlaveAddError::Address(126)));
    assert_eq!(b.slave.set_address(ME), Ok(false), "the same address is no change");
    assert!(!b.slave.take_events().contains(Events::ADDRESS_CHANGED));
    assert_eq!(b.slave.set_address(20), Ok(true));
    assert!(b.slave.take_events().contains(Events::ADDRESS_CHANGED));
    // The old address is dead, the new one answers.
    let f = b.frame(M1, ME, 0x0D, Some(60), &[], true);
    assert_eq!(b.raw(&f), None);
    let f = b.frame(M1, 20, 0x0D, Some(60), &[], true);
    assert!(b.raw(&f).is_some());
    // In data exchange: refused, nothing changes.
    let mut b = Bus::new();
    b.bring_up(0x88);
    assert_eq!(b.slave.set_address(21), Err(SlaveAddError::State));
    assert_eq!((b.slave.address(), b.slave.state()), (ME, DpState::DataExch));
    // In Wait_Cfg: taken, the parameterization (for the old address) is gone.
    let mut b = Bus::new();
    assert_eq!(b.set_prm(M1, 0x88, &card::USER_PRM_DEFAULTS), Ans::Sc);
    assert_eq!(b.slave.state(), DpState::WaitCfg);
    assert_eq!(b.slave.set_address(22), Ok(true));
    assert_eq!((b.slave.state(), b.slave.master_address()), (DpState::WaitPrm, None));
    // Frozen by a Set_Slave_Add with No_Add_Chg: refused (the same address still passes).
    let mut b = Bus::new();
    let i = id();
    assert_eq!(b.req(M2, Some(55), &[30, i[0], i[1], 1]), Ans::Sc);
    assert_eq!(b.slave.set_address(31), Err(SlaveAddError::Frozen));
    assert_eq!(b.slave.set_address(30), Ok(false));
    assert_eq!(b.slave.address(), 30);
}

/// The drive selected a telegram: Chk_Cfg with another (valid) module is a Cfg_Fault; its
/// own module is accepted; lifting the restriction accepts any module again.
#[test]
fn chk_cfg_restricted_to_the_drives_module() {
    let st1 = &card::MODULES[0];
    let other = card::MODULES.iter().find(|m| m.reference != st1.reference).unwrap();
    let mut b = Bus::new();
    b.slave.require_module(Some(other));
    assert_eq!(b.slave.required_module().map(|m| m.reference), Some(other.reference));
    assert_eq!(b.set_prm(M1, 0x88, &card::USER_PRM_DEFAULTS), Ans::Sc);
    assert_eq!(b.req(M1, Some(62), ST1), Ans::Sc, "Chk_Cfg is always acknowledged");
    assert_eq!(b.slave.state(), DpState::WaitPrm);
    assert_eq!(b.slave.stats().cfg_faults, 1);
    assert_eq!(b.diag(M1)[0] & 0x04, 0x04, "Cfg_Fault in Status1");
    assert_eq!(b.set_prm(M1, 0x88, &card::USER_PRM_DEFAULTS), Ans::Sc);
    assert_eq!(b.req(M1, Some(62), other.cfg), Ans::Sc);
    assert_eq!(b.slave.state(), DpState::DataExch);
    assert_eq!(b.slave.module().map(|m| m.reference), Some(other.reference));
    let mut b = Bus::new();
    b.slave.require_module(Some(st1));
    b.slave.require_module(None);
    b.bring_up(0x88);
}

fn parse_from(r: Option<Vec<u8>>, sa: u8) -> Option<u8> {
    let r = r?;
    match decode(&r) {
        Decoded::Frame(Telegram::Data(t), _) if t.sa == sa => Some(t.fc.0),
        _ => None,
    }
}

#[test]
fn ext_diag_announced_by_dh() {
    let mut b = Bus::new();
    b.bring_up(0x88);
    assert!(matches!(b.req(M1, None, &[0; 4]), Ans::Data { fc: 0x08, .. }));
    let blocks = [0x04, 0x01, 0x00, 0x00, 0x81, 0x41, 0x25];
    b.slave.set_ext_diag(&blocks, true).unwrap();
    assert!(matches!(b.req(M1, None, &[0; 4]), Ans::Data { fc: 0x0A, .. }));
    let d = b.diag(M1);
    assert_eq!(d[0], 0x08);
    assert_eq!(&d[6..], &blocks);
    assert!(matches!(b.req(M1, None, &[0; 4]), Ans::Data { fc: 0x08, .. }));
    // Malformed blocks are refused and change nothing.
    assert!(b.slave.set_ext_diag(&[0x00], true).is_err());
    assert_eq!(&b.diag(M1)[6..], &blocks);
}

#[test]
fn unsupported_requests() {
    let mut b = Bus::new();
    // Unknown SAP → RS; SDA → RS; Ident → RS; LSAP status → RS.
    assert_eq!(b.req(M1, Some(20), &[]), Ans::Sd1(0x03));
    for func in [0x03, 0x0E, 0x0F] {
        let f = b.frame(M1, ME, func, Some(60), &[], false);
        assert_eq!(parse(b.raw(&f)), Ans::Sd1(0x03), "function {func:x}");
    }
    // Broadcast SRD: ignored, never answered.
    let f = b.frame(M1, 127, 0x0D, Some(60), &[], true);
    assert_eq!(b.raw(&f), None);
    // Other station, token, SC: ignored.
    let f = b.frame(M1, 9, 0x0D, Some(60), &[], true);
    assert_eq!(b.raw(&f), None);
    assert_eq!(b.raw(&[0xDC, ME, M1]), None);
    assert_eq!(b.raw(&[0xE5]), None);
    // A response frame addressed to us is ignored.
    assert_eq!(b.raw(&[0x10, ME, M1, 0x08, ME + M1 + 0x08, 0x16]), None);
    // Trailing bytes after a telegram → no answer.
    assert_eq!(b.raw(&[0x10, ME, M1, 0x49, ME + M1 + 0x49, 0x16, 0x00]), None);
    // Corrupt frame → no answer.
    assert_eq!(b.raw(&[0x10, ME, M1, 0x49, 0x00, 0x16]), None);
}

proptest::proptest! {
    /// Random requests (valid frames with random contents) never panic, every answer is a
    /// valid frame from our address, and the images keep their configured lengths.
    #[test]
    fn random_requests_keep_invariants(reqs in proptest::collection::vec(
        (proptest::option::of(proptest::sample::select(vec![55u8, 56, 57, 58, 59, 60, 61, 62, 51, 0])),
         proptest::sample::select(vec![0x03u8, 0x04, 0x06, 0x09, 0x0C, 0x0D, 0x0E]),
         proptest::collection::vec(proptest::num::u8::ANY, 0..20), proptest::bool::ANY), 1..60)) {
        let mut b = Bus::new();
        b.bring_up(0xB8);
        for (dsap, func, pdu, toggle) in reqs {
            let f = b.frame(M1, ME, func, dsap, &pdu, toggle);
            if let Some(r) = b.raw(&f) {
                match decode(&r) {
                    Decoded::Frame(Telegram::ShortAck, 1) => {}
                    Decoded::Frame(Telegram::Data(t), n) => {
                        proptest::prop_assert_eq!(n, r.len());
                        proptest::prop_assert_eq!(t.sa, b.slave.address());
                    }
                    other => proptest::prop_assert!(false, "{:?}", other),
                }
            }
            proptest::prop_assert_eq!(b.slave.outputs().len(), b.slave.output_len());
            proptest::prop_assert_eq!(b.slave.inputs().len(), b.slave.input_len());
        }
    }
}
