//! Test support shared by the crate's own tests, the workspace's test crates (`dpm-host`,
//! `softslave`, `host-tests`) and the fuzz targets: a scripted class-1 DP master that builds
//! the request telegrams of the bring-up (Set_Prm, Chk_Cfg) and of data exchange, with the
//! frame count bit per requester kept as a master does (reference §2.2 "FCB / FCV", §3.2
//! "Set_Prm", §3.3 "Chk_Cfg").
//!
//! Built only for `cfg(test)` or with the `test-support` feature; `no_std` and
//! allocation-free like the rest of the library, so every rig — a [`Node`] fed byte by byte,
//! a pseudo-terminal, a simulated line — uses the same request bytes.

use heapless::Vec;

mod card_rig;
pub use card_rig::{CardRig, NodeOnly, NodeRig};
/// The one fake drive parameter table and the mailbox around a table live in the profile layer
/// (`pbcard_profile::testkit`), re-exported here for the card's tests.
pub use pbcard_profile::testkit::{
    FakeDrive, Indirect, Mailbox, MailboxOp, Quirk, QuirkPnu, Refusal, Rule, LAST_PNU, PNUS,
};

use crate::card;
use crate::dp::DpState;
use crate::fdl::telegram::{self, EmitError, FunctionCode, Header, MAX_FRAME_LEN};
use crate::node::Node;
use crate::time::Instant;

/// One telegram (request or answer), at most [`MAX_FRAME_LEN`] bytes.
pub type Frame = Vec<u8, MAX_FRAME_LEN>;

/// The DSAP of Set_Prm (reference §3.2).
pub const SAP_SET_PRM: u8 = 61;
/// The DSAP of Chk_Cfg (reference §3.3).
pub const SAP_CHK_CFG: u8 = 62;
/// The SSAP a class-1 master uses for the DP services (reference §3.1).
pub const SAP_MASTER: u8 = 62;
/// Function bits of SRD with high priority (reference §2.2, FC table).
pub const SRD_HIGH: u8 = 0x0D;
/// Set_Prm Station_Status: Lock_Req (b7).
pub const LOCK_REQ: u8 = 0x80;
/// Set_Prm Station_Status: WD_On (b3).
pub const WD_ON: u8 = 0x08;

/// The Set_Prm parameters of a test master (reference §3.2: Station_Status, WD_Fact_1,
/// WD_Fact_2, min_TSDR, Ident_Number, Group_Ident, User_Prm_Data): any product's — its
/// User_Prm_Data of any length up to [`MAX_USER_PRM_LEN`] ([`SetPrm::user`]); this card's
/// ([`SetPrm::CARD`]) are [`card::USER_PRM_LEN`] octets, byte 0 is DPV1_Status_1.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SetPrm {
    /// Station_Status (Lock_Req, WD_On, ...).
    pub station_status: u8,
    /// WD_Fact_1.
    pub wd_fact_1: u8,
    /// WD_Fact_2.
    pub wd_fact_2: u8,
    /// min_TSDR in bit times.
    pub min_tsdr: u8,
    /// Ident_Number.
    pub ident: u16,
    /// Group_Ident.
    pub group: u8,
    /// User_Prm_Data (DPV1_Status_1..3, then the product's own octets): the first
    /// `user_len` octets.
    user: [u8; MAX_USER_PRM_LEN],
    user_len: u8,
}

impl SetPrm {
    /// What the pbcard tests send: Lock_Req + WD_On, watchdog 1 × 100 × 10 ms = 1 s,
    /// min_TSDR 11, the card's ident number, no group, the default User_Prm_Data.
    pub const CARD: SetPrm = SetPrm {
        station_status: LOCK_REQ | WD_ON,
        wd_fact_1: 1,
        wd_fact_2: 100,
        min_tsdr: 11,
        ident: card::IDENT_NUMBER,
        group: 0,
        user: pad(card::USER_PRM_DEFAULTS),
        user_len: card::USER_PRM_LEN as u8,
    };

    /// As [`Self::CARD`] for another product: its ident number and User_Prm_Data.
    pub const fn product<const N: usize>(ident: u16, user: [u8; N]) -> Self {
        Self::CARD.ident(ident).user(user)
    }

    /// With WD_On and the two watchdog factors.
    pub const fn watchdog(mut self, wd_fact_1: u8, wd_fact_2: u8) -> Self {
        self.station_status |= WD_ON;
        self.wd_fact_1 = wd_fact_1;
        self.wd_fact_2 = wd_fact_2;
        self
    }

    /// Without the watchdog (WD_On = 0, both factors 0).
    pub const fn no_watchdog(mut self) -> Self {
        self.station_status &= !WD_ON;
        self.wd_fact_1 = 0;
        self.wd_fact_2 = 0;
        self
    }

    /// With another Station_Status (the lock bits, WD_On, Sync_Req, Freeze_Req, Group), the
    /// watchdog factors kept.
    pub const fn station_status(mut self, status: u8) -> Self {
        self.station_status = status;
        self
    }

    /// With the two watchdog factors, Station_Status as it is (WD_On not touched).
    pub const fn wd_factors(mut self, wd_fact_1: u8, wd_fact_2: u8) -> Self {
        self.wd_fact_1 = wd_fact_1;
        self.wd_fact_2 = wd_fact_2;
        self
    }

    /// With another Group_Ident.
    pub const fn group(mut self, group: u8) -> Self {
        self.group = group;
        self
    }

    /// With another ident number.
    pub const fn ident(mut self, ident: u16) -> Self {
        self.ident = ident;
        self
    }

    /// With another min_TSDR.
    pub const fn min_tsdr(mut self, bits: u8) -> Self {
        self.min_tsdr = bits;
        self
    }

    /// With DPV1_Status_1 (User_Prm_Data byte 0; 0x80 = DPV1_Enable).
    pub const fn dpv1_status_1(mut self, status: u8) -> Self {
        self.user[0] = status;
        if self.user_len == 0 {
            self.user_len = 1;
        }
        self
    }

    /// With all of User_Prm_Data: `N` octets, any length up to [`MAX_USER_PRM_LEN`] (a
    /// longer one is a test script's mistake: a panic, at compile time in a `const`).
    pub const fn user<const N: usize>(mut self, user: [u8; N]) -> Self {
        assert!(N <= MAX_USER_PRM_LEN, "User_Prm_Data longer than a Set_Prm carries");
        self.user = pad(user);
        self.user_len = N as u8;
        self
    }

    /// With all of User_Prm_Data from a slice (cut at [`MAX_USER_PRM_LEN`]).
    pub fn user_bytes(mut self, user: &[u8]) -> Self {
        let n = user.len().min(MAX_USER_PRM_LEN);
        self.user = [0; MAX_USER_PRM_LEN];
        self.user[..n].copy_from_slice(&user[..n]);
        self.user_len = n as u8;
        self
    }

    /// The User_Prm_Data octets.
    pub fn user_prm(&self) -> &[u8] {
        &self.user[..usize::from(self.user_len)]
    }

    /// The Set_Prm PDU: the seven standard octets, then User_Prm_Data.
    pub fn pdu(&self) -> Vec<u8, { 7 + MAX_USER_PRM_LEN }> {
        let id = self.ident.to_be_bytes();
        let mut p = Vec::new();
        let head = [self.station_status, self.wd_fact_1, self.wd_fact_2, self.min_tsdr, id[0], id[1], self.group];
        // Both fit: 7 + at most MAX_USER_PRM_LEN octets.
        let _ = p.extend_from_slice(&head);
        let _ = p.extend_from_slice(self.user_prm());
        p
    }
}

/// The longest User_Prm_Data of a Set_Prm (a 244-octet PDU less the seven standard octets).
pub const MAX_USER_PRM_LEN: usize = crate::dp::prm::MAX_USER_PRM_LEN;

/// `user` in a [`MAX_USER_PRM_LEN`] array, zeros after it.
const fn pad<const N: usize>(user: [u8; N]) -> [u8; MAX_USER_PRM_LEN] {
    let mut out = [0u8; MAX_USER_PRM_LEN];
    let mut i = 0;
    while i < N && i < MAX_USER_PRM_LEN {
        out[i] = user[i];
        i += 1;
    }
    out
}

/// A scripted master: builds SRD requests to one slave and keeps the frame count bit of each
/// requesting address (several masters may share one script), as reference §2.2 asks: the
/// FCB toggles for every new request, a retry repeats it.
#[derive(Debug, Clone)]
pub struct ScriptedMaster {
    /// The requester of [`Self::srd`].
    pub master: u8,
    /// The addressed slave.
    pub slave: u8,
    fcb: [bool; 128],
}

impl ScriptedMaster {
    /// A master at `master` talking to station `slave`; every FCB starts at 0, so the first
    /// request carries FCB = 1.
    pub const fn new(master: u8, slave: u8) -> Self {
        ScriptedMaster { master, slave, fcb: [false; 128] }
    }

    /// The next SRD high request of [`Self::master`]: FCB toggled, FCV = 1, SSAP 62 when a
    /// DSAP is given (none for Data_Exchange).
    pub fn srd(&mut self, dsap: Option<u8>, pdu: &[u8]) -> Frame {
        self.request(self.master, dsap, dsap.map(|_| SAP_MASTER), pdu, true)
    }

    /// An SRD high request from `sa` (any address, the top bit ignored) with the given SAPs;
    /// `toggle` = false repeats the FCB of `sa`'s last request (a retry).
    /// Panics on a PDU too long for one telegram (a test script's mistake).
    pub fn request(&mut self, sa: u8, dsap: Option<u8>, ssap: Option<u8>, pdu: &[u8], toggle: bool) -> Frame {
        match self.try_request(sa, dsap, ssap, pdu, toggle) {
            Ok(f) => f,
            Err(e) => panic!("no telegram for a {}-byte PDU: {e:?}", pdu.len()),
        }
    }

    /// [`Self::request`] for a PDU that may not fit (fuzzed lengths): the FCB of `sa` toggles
    /// either way, as a master that tried to send.
    pub fn try_request(
        &mut self,
        sa: u8,
        dsap: Option<u8>,
        ssap: Option<u8>,
        pdu: &[u8],
        toggle: bool,
    ) -> Result<Frame, EmitError> {
        let sa = sa & 0x7F;
        let fcb = &mut self.fcb[usize::from(sa)];
        if toggle {
            *fcb = !*fcb;
        }
        let hdr = Header { da: self.slave, sa, fc: FunctionCode::request(SRD_HIGH, *fcb, true), dsap, ssap };
        try_frame(&hdr, pdu)
    }

    /// The FCB of `sa`'s last request.
    pub fn fcb(&self, sa: u8) -> bool {
        self.fcb[usize::from(sa & 0x7F)]
    }
}

/// The telegram of `hdr` with `pdu`. Panics on a PDU too long for one telegram (a test
/// script's mistake).
pub fn frame(hdr: &Header, pdu: &[u8]) -> Frame {
    match try_frame(hdr, pdu) {
        Ok(f) => f,
        Err(e) => panic!("no telegram for a {}-byte PDU: {e:?}", pdu.len()),
    }
}

/// The telegram of `hdr` with `pdu`, or why there is none.
pub fn try_frame(hdr: &Header, pdu: &[u8]) -> Result<Frame, EmitError> {
    let mut buf = [0u8; MAX_FRAME_LEN];
    let n = telegram::emit(&mut buf, hdr, pdu)?;
    let mut f = Frame::new();
    // `n` ≤ MAX_FRAME_LEN: `emit` wrote it into a buffer of that size.
    let _ = f.extend_from_slice(&buf[..n]);
    Ok(f)
}

/// Feed `frame` to `node` byte by byte (through its framer, as the UART does) at `now`;
/// the answer, if any.
pub fn feed(node: &mut Node, now: Instant, frame: &[u8]) -> Option<Frame> {
    let mut answer = None;
    for &b in frame {
        if let Some(r) = node.on_byte(now, b) {
            answer = Frame::from_slice(r).ok();
        }
    }
    answer
}

/// A card under test that a [`ScriptedMaster`] talks to: the shared bring-up and data
/// exchange of the rigs.
pub trait Rig {
    /// The master's script.
    fn master(&mut self) -> &mut ScriptedMaster;
    /// Deliver one request telegram to the card; its answer.
    fn deliver(&mut self, frame: &[u8]) -> Option<Frame>;
    /// Let the card run one cycle between two requests (timers, DPM, drive); default nothing.
    fn settle(&mut self) {}
    /// The DP state of the slave.
    fn dp_state(&self) -> DpState;
    /// The configured input length (the PDU length of a Data_Exchange answer).
    fn input_len(&self) -> usize;

    /// One SRD request of the master; panics without an answer.
    fn srd(&mut self, dsap: Option<u8>, pdu: &[u8]) -> Frame {
        let f = self.master().srd(dsap, pdu);
        match self.deliver(&f) {
            Some(r) => r,
            None => panic!("no answer to {:02x?}", f.as_slice()),
        }
    }

    /// Set_Prm with `prm`, Chk_Cfg with `cfg`, each acknowledged with SC and followed by one
    /// card cycle: the slave is in data exchange.
    fn bring_up(&mut self, prm: &SetPrm, cfg: &[u8]) {
        assert_eq!(self.srd(Some(SAP_SET_PRM), &prm.pdu()), [telegram::SC], "Set_Prm");
        self.settle();
        assert_eq!(self.srd(Some(SAP_CHK_CFG), cfg), [telegram::SC], "Chk_Cfg");
        self.settle();
        assert_eq!(self.dp_state(), DpState::DataExch);
    }

    /// One Data_Exchange with `outputs`; the input PDU of the answer.
    fn data_exchange(&mut self, outputs: &[u8]) -> Frame {
        let r = self.srd(None, outputs);
        let range = telegram::pdu_range(r.len(), self.input_len());
        let mut pdu = Frame::new();
        let _ = pdu.extend_from_slice(&r[range]);
        pdu
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fdl::telegram::{decode, Decoded, Telegram};

    #[test]
    fn set_prm_pdu_is_the_standard_octets_then_user_prm() {
        let id = card::IDENT_NUMBER.to_be_bytes();
        let mut want = [0x88, 1, 100, 11, id[0], id[1], 0, 0, 0, 0, 0, 0];
        want[7..].copy_from_slice(&card::USER_PRM_DEFAULTS);
        assert_eq!(SetPrm::CARD.pdu(), want);
        let p = SetPrm::CARD.no_watchdog().ident(0x1234).dpv1_status_1(0x80).pdu();
        assert_eq!(p[..8], [0x80, 0, 0, 11, 0x12, 0x34, 0, 0x80]);
    }

    /// Another product's Set_Prm: its ident and User_Prm_Data of its own length (none, six
    /// octets, the longest a PDU carries), the standard octets as this card's.
    #[test]
    fn set_prm_of_another_product_has_its_own_user_prm_length() {
        const OTHER: SetPrm = SetPrm::product(0x4711, [0x80, 0, 0, 1, 2, 3]);
        assert_eq!(OTHER.pdu(), [0x88, 1, 100, 11, 0x47, 0x11, 0, 0x80, 0, 0, 1, 2, 3]);
        assert_eq!(OTHER.user_prm(), [0x80, 0, 0, 1, 2, 3]);
        let none = SetPrm::CARD.user([]);
        assert_eq!(none.pdu().len(), 7);
        // DPV1_Status_1 gives an empty User_Prm_Data its first octet.
        assert_eq!(none.dpv1_status_1(0x80).user_prm(), [0x80]);
        let long = SetPrm::CARD.user_bytes(&[7; 300]);
        assert_eq!(long.pdu().len(), 244);
        let s = SetPrm::CARD.station_status(0x40).wd_factors(3, 4).group(0x81).min_tsdr(20).pdu();
        assert_eq!(s[..7], [0x40, 3, 4, 20, id_hi(), id_lo(), 0x81]);
    }

    fn id_hi() -> u8 {
        card::IDENT_NUMBER.to_be_bytes()[0]
    }

    fn id_lo() -> u8 {
        card::IDENT_NUMBER.to_be_bytes()[1]
    }

    #[test]
    fn requests_toggle_the_fcb_per_requester_and_retries_keep_it() {
        let mut m = ScriptedMaster::new(2, 5);
        let fc = |f: &Frame| match decode(f) {
            Decoded::Frame(Telegram::Data(t), n) if n == f.len() => (t.sa, t.da, t.fc, t.dsap, t.ssap),
            other => panic!("{other:?}"),
        };
        let (sa, da, fc1, dsap, ssap) = fc(&m.srd(Some(61), &[1, 2]));
        assert_eq!((sa, da, dsap, ssap), (2, 5, Some(61), Some(62)));
        assert!(fc1.fcb() && fc1.fcv() && fc1.is_request());
        assert!(!fc(&m.srd(None, &[])).2.fcb());
        assert!(fc(&m.request(3, None, None, &[], true)).2.fcb(), "another requester has its own FCB");
        assert!(!fc(&m.request(2, None, None, &[], false)).2.fcb(), "a retry repeats the FCB");
    }

    #[test]
    fn a_node_rig_reaches_data_exchange() {
        let mut r = NodeRig::node_only(2, 5);
        r.bring_up(&SetPrm::CARD, card::MODULES[0].cfg);
        assert_eq!(r.data_exchange(&[0, 0, 0, 0]).len(), r.input_len());
    }
}
