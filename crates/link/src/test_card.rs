//! A stand-in product for the unit tests of this crate that need a station, not the card: one
//! module, no user parameters, no Chk_Cfg rule, and the telegram builder of the tests. The
//! tests that run this card's whole configuration, records and scripted master are in
//! `pbcard` (`src/link_tests/`), where the product is.

use heapless::Vec;

use crate::dp::{AcceptAll, DpSlave, Module, SlaveConfig};
use crate::dpv1::im::ImDevice;
use crate::fdl::telegram::{self, Header, MAX_FRAME_LEN};
use crate::node::Node;

/// A DP-V1 slave with one 4-byte module (`pbcard::card`'s ident number, so the FDL and DP
/// answers look like the card's).
pub static SLAVE: SlaveConfig = SlaveConfig {
    ident_number: pbcard_dp::test_card::IDENT_NUMBER,
    default_address: 126,
    modules: &[Module { name: "4 bytes in/out", reference: 1, cfg: &[0xF1], inputs: 4, outputs: 4 }],
    user_prm_len: 3,
    user_prm_defaults: &[0, 0, 0],
    user_prms: &[],
    freeze_mode_supp: true,
    sync_mode_supp: true,
    fail_safe: true,
    dpv1_slave: true,
    wd_base_1ms_supp: true,
    diagnostic_alarm_supp: false,
    max_diag_data_len: 32,
    cfg_policy: &AcceptAll,
};

/// The telegram of `hdr` with `pdu` (as `pbcard::testkit::frame`).
pub fn frame(hdr: &Header, pdu: &[u8]) -> Vec<u8, MAX_FRAME_LEN> {
    let mut buf = [0u8; MAX_FRAME_LEN];
    let n = telegram::emit(&mut buf, hdr, pdu).expect("a PDU that fits a telegram");
    let mut f = Vec::new();
    let _ = f.extend_from_slice(&buf[..n]);
    f
}

/// The I&M0 values of the stand-in (`pbcard::card::IM`'s): the DP layers' stand-in.
pub static IM: ImDevice = pbcard_dp::test_card::IM;

/// A node of the stand-in over `slave` (as `pbcard::card::node`).
pub fn node(slave: DpSlave) -> Node {
    Node::with_device(slave, &IM, pbcard_dp::test_card::PROFILE_IDENT_NUMBER)
}
