//! The worked example of docs/PORTING.md (issue 13, "One card, many hosts"): another drive
//! maker's product ([`other_drive`]: its own ident number 0x0C0B, modules, User_Prm_Data,
//! Chk_Cfg rule, I&M0 values and drive interface) configures the protocol stack —
//! `DpSlave::new(&OTHER, address)`, `Node`, the fast-path split `fast::Shared::split` — and a
//! scripted class-1 master drives it bytes in, bytes out: Set_Prm (its ident accepted, this
//! card's refused with Prm_Fault), Chk_Cfg (its modules, its rule), Data_Exchange through its
//! drive interface, Slave_Diag (its ident), Get_Cfg, and its I&M0 over MSAC_C1 — and the same
//! session on the tests' one card rig (`testkit::CardRig::with_node`) answered byte for byte
//! alike.
//!
//! Run: `cargo test -p host-tests --target x86_64-unknown-linux-gnu --test porting`.

#[path = "porting/other_drive.rs"]
mod other_drive;

use other_drive::{Fc20, BASIC, EXTENDED, IDENT_NUMBER, MONITOR, OTHER, OTHER_IM, USER_PRM_DEFAULTS};
use pbcard::dp::diag::Status1;
use pbcard::dp::{DpSlave, DpState};
use pbcard::dpv1::im::Im;
use pbcard::fast::{self, CoreLink, FastPath, Shared};
use pbcard::fdl::telegram::{self, Decoded, ResponseStatus, Telegram};
use pbcard::node::Node;
use pbcard::testkit::{ScriptedMaster, SetPrm};
use pbcard::time::Instant;

const ME: u8 = 7;
const MASTER: u8 = 2;

/// The product's firmware as a platform runs it: the line half answers at the "interrupt",
/// the core half and the application run after every telegram.
struct Product {
    node: Node,
    fast: FastPath<'static>,
    core: CoreLink<'static>,
    drive: Fc20,
    master: ScriptedMaster,
    now: u64,
}

impl Product {
    fn new() -> Self {
        let mut node = pbcard::card::node(DpSlave::new(&OTHER, ME));
        *node.im_mut() = Im::new(&OTHER_IM);
        let shared: &'static mut Shared = Box::leak(Box::new(Shared::new()));
        let (fast, core) = shared.split(&mut node);
        Product { node, fast, core, drive: Fc20::default(), master: ScriptedMaster::new(MASTER, ME), now: 0 }
    }

    /// One request of the master on `dsap` / `ssap`; the answer's bytes.
    fn send(&mut self, dsap: Option<u8>, ssap: Option<u8>, pdu: &[u8]) -> Option<Vec<u8>> {
        let f = self.master.request(MASTER, dsap, ssap, pdu, true);
        self.now += 1000;
        let now = Instant::from_micros(self.now);
        self.core.poll(now, &mut self.node);
        // The line's answer; the core judges what was queued (a single-threaded platform).
        let mut out = [0u8; pbcard::fdl::telegram::MAX_FRAME_LEN];
        let answer = fast::single_threaded(&mut self.fast, &mut self.core, &mut self.node, now, &f, &mut out)
            .map(|n| out[..n].to_vec());
        // The lower-priority tasks: the drive's cycle, DP-V1 work, the staging republished
        // (the main loop's step, `fast::tick`, with the product's `CardApp`).
        fast::tick(now, &mut self.node, &mut self.core, &mut self.drive);
        answer
    }

    fn srd(&mut self, dsap: Option<u8>, pdu: &[u8]) -> Option<Vec<u8>> {
        self.send(dsap, dsap.map(|_| 62), pdu)
    }

    /// A request the slave acknowledges with SC (Set_Prm, Chk_Cfg).
    fn sc(&mut self, dsap: u8, pdu: &[u8]) {
        assert_eq!(self.srd(Some(dsap), pdu), Some(vec![telegram::SC]), "SAP {dsap} {pdu:02x?}");
    }

    /// The PDU of a data answer.
    fn pdu(&mut self, dsap: Option<u8>, pdu: &[u8]) -> Vec<u8> {
        let a = self.srd(dsap, pdu).expect("an answer");
        pdu_of(&a).unwrap_or_else(|| panic!("no data answer: {a:02x?}"))
    }

    fn diag(&mut self) -> Vec<u8> {
        self.pdu(Some(60), &[])
    }

    /// An MSAC_C1 request (SAP 51): SC, then polls until the response.
    fn c1(&mut self, pdu: &[u8]) -> Vec<u8> {
        assert_eq!(self.send(Some(51), Some(51), pdu), Some(vec![telegram::SC]));
        for _ in 0..8 {
            let a = self.send(Some(51), Some(51), &[]).expect("an answer to the poll");
            if let Some(p) = pdu_of(&a) {
                return p;
            }
        }
        panic!("no MSAC_C1 response to {pdu:02x?}");
    }
}

fn pdu_of(frame: &[u8]) -> Option<Vec<u8>> {
    match telegram::decode(frame) {
        Decoded::Frame(Telegram::Data(t), _) if t.fc.0 & 0x0F != ResponseStatus::Rs as u8 => Some(t.pdu.to_vec()),
        _ => None,
    }
}

/// Set_Prm of the product: Lock_Req + WD_On, 1 s watchdog, min_TSDR 11, `ident`, no group,
/// `user` (DPV1_Status_1..3 and the product's user parameters).
fn set_prm(ident: u16, user: &[u8]) -> Vec<u8> {
    SetPrm::CARD.ident(ident).user_bytes(user).pdu().to_vec()
}

/// The product's User_Prm_Data with DPV1_Enable and `control_mode`.
fn user(control_mode: u8) -> [u8; 6] {
    let mut u = USER_PRM_DEFAULTS;
    u[0] = 0x80; // DPV1_Status_1: DPV1_Enable
    u[5] = control_mode;
    u
}

#[test]
fn another_drive_runs_the_stack_with_its_own_configuration() {
    let mut p = Product::new();
    // Slave_Diag before parameterization: its ident number, Prm_Req.
    let d = p.diag();
    assert_eq!(d[4..6], IDENT_NUMBER.to_be_bytes(), "its ident in the diagnosis");
    assert_eq!(d.len(), 6);
    // Get_Cfg before Chk_Cfg: Real_Cfg = its first module.
    assert_eq!(p.pdu(Some(59), &[]), BASIC.cfg);

    // Set_Prm: this card's (ident 0x0F11, its User_Prm_Data) and ours with another ident are
    // refused with Prm_Fault; a user parameter out of its range too.
    p.sc(61, &SetPrm::CARD.pdu());
    assert_ne!(p.diag()[0] & Status1::PRM_FAULT.bits(), 0, "this card's Set_Prm: Prm_Fault");
    p.sc(61, &set_prm(pbcard::card::IDENT_NUMBER, &user(0)));
    assert_ne!(p.diag()[0] & Status1::PRM_FAULT.bits(), 0, "the card's ident: Prm_Fault");
    let mut bad = user(0);
    bad[4] = 121; // speed limit above 120 %
    p.sc(61, &set_prm(IDENT_NUMBER, &bad));
    assert_ne!(p.diag()[0] & Status1::PRM_FAULT.bits(), 0, "out of range: Prm_Fault");
    assert_eq!(p.node.slave().state(), DpState::WaitPrm);

    // Its own Set_Prm with torque control: accepted.
    p.sc(61, &set_prm(IDENT_NUMBER, &user(1)));
    assert_eq!(p.diag()[0] & Status1::PRM_FAULT.bits(), 0);
    assert_eq!(p.node.slave().state(), DpState::WaitCfg);
    // Chk_Cfg: the card's Standard Telegram 1 is no module of this product; Basic is one, but
    // its rule refuses it in torque control: Cfg_Fault, back to Wait_Prm.
    p.sc(62, pbcard::card::MODULES[0].cfg);
    assert_ne!(p.diag()[0] & Status1::CFG_FAULT.bits(), 0, "not its module: Cfg_Fault");
    p.sc(61, &set_prm(IDENT_NUMBER, &user(1)));
    p.sc(62, BASIC.cfg);
    assert_ne!(p.diag()[0] & Status1::CFG_FAULT.bits(), 0, "its rule: Cfg_Fault");
    assert_eq!(p.node.slave().state(), DpState::WaitPrm);
    // Extended in torque control: data exchange.
    p.sc(61, &set_prm(IDENT_NUMBER, &user(1)));
    p.sc(62, EXTENDED.cfg);
    assert_eq!(p.node.slave().state(), DpState::DataExch);
    let d = p.diag();
    assert_eq!(d[0] & (Status1::CFG_FAULT | Status1::PRM_FAULT | Status1::STATION_NOT_READY).bits(), 0);
    assert_eq!(d[3], MASTER);
    assert_eq!(d[4..6], IDENT_NUMBER.to_be_bytes());
    assert_eq!(p.pdu(Some(59), &[]), EXTENDED.cfg, "Get_Cfg: the module in force");

    // Data_Exchange through its drive interface: run at 50 %.
    let out = [0x04, 0x7F, 0x20, 0x00, 0, 0, 0, 0];
    p.pdu(None, &out);
    assert_eq!(p.drive.setpoint, 0x2000);
    assert_eq!(p.node.slave().outputs(), out);
    let inputs = p.pdu(None, &out);
    assert_eq!(inputs, [0x06, 0x37, 0x20, 0x00, 0x01, 0x00, 0x00, 0x42]);
    // Rd_Outp (answered by the line from the staging).
    assert_eq!(p.pdu(Some(57), &[]), out);

    // Its I&M0 over MSAC_C1: the call header `08 00 FD E8`, then the 64-byte record.
    assert_eq!(p.c1(&[0x5F, 0x00, 0xFF, 0x04, 0x08, 0x00, 0xFD, 0xE8]), [0x5F, 0x00, 0xFF, 0x04]);
    let r = p.c1(&[0x5E, 0x00, 0xFF, 0xF0]);
    assert_eq!(r[..8], [0x5E, 0x00, 0xFF, 68, 0x08, 0x00, 0xFD, 0xE8]);
    let im0 = &r[8..];
    assert_eq!(im0[10..12], OTHER_IM.manufacturer_id.to_be_bytes());
    assert_eq!(&im0[12..32], b"FC-20-PB            ");
    assert_eq!(im0[48..50], OTHER_IM.hardware_revision.to_be_bytes());
    assert_eq!(im0[50..54], [b'V', 2, 4, 1]);
}

/// Speed control accepts every module of the product, the monitor one without outputs too.
#[test]
fn every_module_of_the_product_in_speed_control() {
    for m in [BASIC, EXTENDED, MONITOR] {
        let mut p = Product::new();
        p.sc(61, &set_prm(IDENT_NUMBER, &user(0)));
        p.sc(62, m.cfg);
        assert_eq!(p.node.slave().state(), DpState::DataExch, "{}", m.name);
        assert_eq!(p.pdu(Some(59), &[]), m.cfg);
        let out = vec![0; usize::from(m.outputs)];
        p.srd(None, &out);
        let inputs = p.pdu(None, &out);
        assert_eq!(inputs.len(), usize::from(m.inputs), "{}: {inputs:02x?}", m.name);
        assert_eq!(inputs[..4], [0x06, 0x31, 0x00, 0x00], "{}: stopped", m.name);
    }
}

/// The one card rig of the tests runs another product as well (`CardRig::with_node`: its node,
/// its application): every answer of a whole session — diagnosis, Get_Cfg, its Set_Prm and
/// Chk_Cfg, Data_Exchange, Rd_Outp, a wrong-length Data_Exchange, its I&M0 over MSAC_C1 with
/// the polls — is byte for byte the one the product's platform split (`Product`: line half,
/// core half, main-loop step) gives.
#[test]
fn the_card_rig_runs_the_product_as_its_platform_does() {
    use pbcard::testkit::{CardRig, Rig};
    let mut node = pbcard::card::node(DpSlave::new(&OTHER, ME));
    *node.im_mut() = Im::new(&OTHER_IM);
    let mut rig = CardRig::with_node(node, Fc20::default(), MASTER);
    let mut p = Product::new();
    let run = [0x04, 0x7F, 0x20, 0x00, 0, 0, 0, 0];
    let script: Vec<(Option<u8>, Option<u8>, Vec<u8>)> = vec![
        (Some(60), Some(62), vec![]),
        (Some(59), Some(62), vec![]),
        (Some(61), Some(62), set_prm(IDENT_NUMBER, &user(1))),
        (Some(62), Some(62), EXTENDED.cfg.to_vec()),
        (Some(60), Some(62), vec![]),
        (None, None, run.to_vec()),
        (None, None, run.to_vec()),
        (Some(57), Some(62), vec![]),
        (Some(51), Some(51), vec![0x5F, 0x00, 0xFF, 0x04, 0x08, 0x00, 0xFD, 0xE8]),
        (Some(51), Some(51), vec![]),
        (Some(51), Some(51), vec![]),
        (Some(51), Some(51), vec![0x5E, 0x00, 0xFF, 0xF0]),
        (Some(51), Some(51), vec![]),
        (Some(51), Some(51), vec![]),
        (None, None, run.to_vec()),
        // Outputs of the wrong length: RS, the slave leaves data exchange (Cfg_Fault).
        (None, None, vec![0; 3]),
        (Some(60), Some(62), vec![]),
    ];
    for (i, (dsap, ssap, pdu)) in script.iter().enumerate() {
        let f = rig.master.request(MASTER, *dsap, *ssap, pdu, true);
        let on_rig = rig.deliver(&f).map(|a| a.to_vec());
        rig.step(1);
        rig.acyclic();
        let on_platform = p.send(*dsap, *ssap, pdu);
        assert_eq!(on_rig, on_platform, "request {i} {f:02x?}");
        assert!(on_rig.is_some(), "request {i} answered");
        assert_eq!(rig.dp_state(), p.node.slave().state(), "request {i}");
        if i == 5 {
            assert_eq!(rig.dp_state(), DpState::DataExch);
        }
    }
    assert_eq!(rig.app.setpoint, 0x2000);
    assert_eq!((rig.app.control, rig.app.setpoint), (p.drive.control, p.drive.setpoint));
    assert_eq!(rig.dp_state(), DpState::WaitPrm, "after the wrong-length outputs");
}
