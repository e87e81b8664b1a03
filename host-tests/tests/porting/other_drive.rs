//! **The product** of the worked example (docs/PORTING.md): what another drive maker writes to
//! run the protocol stack as *its* DP slave — the values its GSD file declares, its Chk_Cfg
//! rule, its I&M0 values and its drive interface. Nothing here names `pbcard::card` (this
//! card's own configuration): the stack takes every product value from these items.
//!
//! "ACME FC-20", a frequency converter: ident number 0x0C0B, three modules, three user
//! parameters, torque control only with the extended module.

use pbcard::dp::cfg::CfgError;
use pbcard::dp::prm::UserPrm;
use pbcard::dp::{AcceptAll, CfgPolicy, DpSlave, DpState, Module, SlaveConfig};
use pbcard::dpv1::im::ImDevice;

/// GSD `Ident_Number` (the PI assigns it to the manufacturer).
pub const IDENT_NUMBER: u16 = 0x0C0B;

/// GSD `Module = "Basic 2/2 words" 0xF1`: control word + speed setpoint out, status word +
/// actual speed in (2 words each way, consistent over the whole length).
pub const BASIC: Module = Module { name: "Basic 2/2 words", reference: 1, cfg: &[0xF1], inputs: 4, outputs: 4 };
/// GSD `Module = "Extended 4/4 words" 0xF3`: as [`BASIC`], plus torque setpoint / limit out,
/// actual torque / current in.
pub const EXTENDED: Module = Module { name: "Extended 4/4 words", reference: 2, cfg: &[0xF3], inputs: 8, outputs: 8 };
/// GSD `Module = "Monitor 6 words in" 0x55`: read-only monitoring (6 input words, no outputs).
pub const MONITOR: Module = Module { name: "Monitor 6 words in", reference: 3, cfg: &[0x55], inputs: 12, outputs: 0 };

/// GSD `ExtUserPrmData = 1 "Ramp time"` at octet 3: 0.1 s units, 1..=100, default 10.
pub const PRM_RAMP: UserPrm =
    UserPrm { reference: 1, offset: 3, name: "Ramp time (0.1 s)", default: 10, min: 1, max: 100 };
/// GSD `ExtUserPrmData = 2 "Speed limit"` at octet 4: percent of nominal, 10..=120, default 100.
pub const PRM_SPEED_LIMIT: UserPrm =
    UserPrm { reference: 2, offset: 4, name: "Speed limit (%)", default: 100, min: 10, max: 120 };
/// GSD `ExtUserPrmData = 3 "Control mode"` at octet 5: 0 = speed, 1 = torque.
pub const PRM_CONTROL_MODE: UserPrm =
    UserPrm { reference: 3, offset: 5, name: "Control mode", default: 0, min: 0, max: 1 };

/// GSD `Max_User_Prm_Data_Len`: the 3 DPV1_Status octets + the 3 user parameters.
pub const USER_PRM_LEN: usize = 6;
/// GSD `Ext_User_Prm_Data_Const(0)` with every default applied.
pub const USER_PRM_DEFAULTS: [u8; USER_PRM_LEN] =
    [0x00, 0x00, 0x00, PRM_RAMP.default, PRM_SPEED_LIMIT.default, PRM_CONTROL_MODE.default];

/// The product's Chk_Cfg rule: torque control (user parameter "Control mode" = 1) needs the
/// torque setpoint word, so only [`EXTENDED`] is accepted then (else Cfg_Fault).
#[derive(Debug, Clone, Copy, Default)]
pub struct TorqueNeedsExtended;

impl CfgPolicy for TorqueNeedsExtended {
    fn check_cfg(&self, module: &Module, user_prm: &[u8]) -> Result<(), CfgError> {
        let torque = user_prm.get(PRM_CONTROL_MODE.offset) == Some(&1);
        if torque && module.reference != EXTENDED.reference {
            return Err(CfgError::NotAllowedInOperateMode);
        }
        Ok(())
    }
}

/// The product as the DP slave checks it (`DpSlave::new(&OTHER, address)`).
pub const OTHER: SlaveConfig = SlaveConfig {
    ident_number: IDENT_NUMBER,
    default_address: 126,
    modules: &[BASIC, EXTENDED, MONITOR],
    user_prm_len: USER_PRM_LEN,
    user_prm_defaults: &USER_PRM_DEFAULTS,
    user_prms: &[PRM_RAMP, PRM_SPEED_LIMIT, PRM_CONTROL_MODE],
    freeze_mode_supp: false,
    sync_mode_supp: true,
    fail_safe: true,
    dpv1_slave: true,
    wd_base_1ms_supp: false,
    diagnostic_alarm_supp: false,
    max_diag_data_len: 16,
    cfg_policy: &TorqueNeedsExtended,
};
// The configuration fits the slave's compile-time buffers and is well formed.
const _: () = assert!(OTHER.fits());
// `AcceptAll` is the policy of a product without a Chk_Cfg rule.
#[allow(dead_code)]
const WITHOUT_RULE: SlaveConfig = SlaveConfig { cfg_policy: &AcceptAll, ..OTHER };

/// The product's I&M0 values (MSAC_C1 / MSAC_C2, slot 0 index 255): `Im::new(&OTHER_IM)`.
pub const OTHER_IM: ImDevice = ImDevice {
    manufacturer_id: 0x01A5,
    order_id: "FC-20-PB",
    hardware_revision: 3,
    software_revision: [b'V', 2, 4, 1],
    profile_id: pbcard::dpv1::im::PROFILE_ID_PROFIDRIVE,
};

/// The product's drive interface: its application reads the outputs from the DP slave and
/// writes the inputs into it (`DpSlave::outputs` / `set_inputs`, after every cycle; with the
/// fast-path split, `CoreLink::publish` afterwards so the line answers with them).
#[derive(Debug, Default)]
pub struct Fc20 {
    /// Control word as last received (bit 0 = run).
    pub control: u16,
    /// Speed setpoint (0x4000 = 100 %).
    pub setpoint: i16,
    /// Actual speed, following the setpoint by one step per cycle.
    pub speed: i16,
}

/// The product's application in the card's main loop (`fast::tick`): one drive cycle per
/// step, no data records of its own beyond I&M (the node serves slot 0 / index 255; a product
/// with records returns its `node::DataRecords` here).
impl pbcard::fast::CardApp for Fc20 {
    type Records<'a> = pbcard::dpv1::records::NoRecords;
    fn step(&mut self, _now: pbcard::time::Instant, node: &mut pbcard::node::Node) -> pbcard::dp::Events {
        self.cycle(node.slave_mut());
        pbcard::dp::Events::empty()
    }
    fn records(&mut self, _now: pbcard::time::Instant) -> Self::Records<'_> {
        pbcard::dpv1::records::NoRecords
    }
}

impl Fc20 {
    /// One drive cycle: outputs in, inputs out, as the module in force lays them out.
    pub fn cycle(&mut self, slave: &mut DpSlave) {
        if slave.state() != DpState::DataExch {
            return;
        }
        let out = slave.outputs();
        if out.len() >= 4 && !slave.is_clear() {
            self.control = u16::from_be_bytes([out[0], out[1]]);
            self.setpoint = i16::from_be_bytes([out[2], out[3]]);
        }
        let run = self.control & 1 != 0;
        self.speed = if run { self.setpoint } else { 0 };
        let status: u16 = if run { 0x0637 } else { 0x0631 };
        let mut inputs = [0u8; 12];
        inputs[0..2].copy_from_slice(&status.to_be_bytes());
        inputs[2..4].copy_from_slice(&self.speed.to_be_bytes());
        // Extended: actual torque and current; Monitor: those and two more words.
        inputs[4..6].copy_from_slice(&0x0100u16.to_be_bytes());
        inputs[6..8].copy_from_slice(&0x0042u16.to_be_bytes());
        slave.set_inputs(&inputs[..slave.input_len()]);
    }
}
