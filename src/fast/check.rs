//! The equivalence check of the split (issue 11 item 5): one byte string drives two cards —
//! a core alone ([`Node::on_frame`], the card before the split) and the split
//! ([`FastPath`] + [`CoreLink`] + a second [`Node`]) — through the same telegram sequence,
//! and every answer on the line is compared. Used by the proptest
//! `split_answers_equal_the_core` and the `fast_path` fuzz target; built only for
//! `cfg(test)` or the `test-support` feature.
//!
//! The sequence: two masters (2 and 3) and a third requester (5), Set_Prm in many forms (the
//! lock table, short, wrong ident, Sync/Freeze requests, DP-V1 status), Chk_Cfg (every
//! module, mangled), Data_Exchange of any length, Slave_Diag, Get_Cfg, Rd_Inp / Rd_Outp,
//! Global_Control (Clear / Sync / Unsync / Freeze / Unfreeze, to us or broadcast),
//! Set_Slave_Add, FDL_Status, SDA and other function codes, DP-V1 (below),
//! FCB retries, other stations' traffic, mangled sources (SA 127, SA = own address, FC bit
//! 7), raw bytes, time steps (the watchdog) and application changes (inputs, extended
//! diagnosis, Stat_Diag, drive fault, the start-up gate).
//!
//! **How the not-ready window is treated** ([`Mode`]):
//! * [`Mode::Sync`] — the core runs to completion after every telegram (as it does on an idle
//!   card between a master's requests). Every answer must equal the core alone's, byte for
//!   byte; no window ever opens.
//! * [`Mode::Lag`] — after a Set_Prm or Chk_Cfg the core stays behind while the master sends
//!   what a master sends while it waits for a slave to become ready (Slave_Diag, FDL_Status,
//!   other stations' traffic, mangled frames); before anything else the core catches up. In
//!   the window a Slave_Diag answer may differ from the core alone's only in being the older
//!   staged diagnosis with Station_Not_Ready set (a valid diagnosis answer to the requester
//!   with octet 1 bit 1); every other answer must be equal. An FCB retry must repeat the
//!   split's own earlier answer byte for byte (equal to the core alone's outside the window).
//!   DP-V1: after a request PDU the core may stay behind while the master polls, and a run
//!   of the DP-V1 task may find the split's core behind; a poll the split answers SC where
//!   the core alone delivered a response (or an Abort PDU) is the documented "not ready yet"
//!   difference — the master's next poll (after the core caught up) must then deliver
//!   exactly the core alone's frame, so a response is neither lost nor doubled.
//!
//! The DP-V1 operations: the DP-V1 start-up (Set_Prm with DPV1_Enable, Chk_Cfg), MSAC_C1
//! Read / Write / Data_Transport / Alarm_Ack / raw PDUs and polls (right and wrong SSAP, any
//! master), MSAC_C2 RM Initiate.req (good, malformed, no SSAP) followed by the Initiate.req on
//! the granted SAP, requests / Idle / Abort / polls on the connection SAPs, a second master,
//! and runs of `Node::process_acyclic` over the tests' fake drive table (`testkit::FakeDrive`).

use heapless::Vec;

use super::{CoreLink, FastPath, Shared, Verdict, C2_CONNECTIONS};
use crate::dp::{DpSlave, SlaveConfig};
use crate::dpv1::c1;
use crate::dpv1::c2::{self, ConnectionState};
use crate::dpv1::pdu::{AddressBlock, InitiateRequest};
use crate::fdl::telegram::{
    self, Decoded, FunctionCode, Header, RequestFunction, ResponseStatus, Telegram, MAX_FRAME_LEN,
};
use crate::node::Node;
use crate::phy::stream::TelegramSink;
use crate::profile::records::CardRecords;
use crate::testkit::FakeDrive;
use crate::testkit::{Frame, SetPrm};
use crate::time::Instant;

/// The product both cards run (the operation mix's Set_Prm is the card's, [`SetPrm::CARD`]).
const CARD: &SlaveConfig = &crate::card::SLAVE;

/// The station address of both cards.
pub const ME: u8 = 8;
const MASTERS: [u8; 3] = [2, 3, 5];
/// Another slave on the bus.
const OTHER: u8 = 9;

/// How the core is scheduled against the line (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// The core catches up after every telegram: answers equal.
    Sync,
    /// The core stays behind in the not-ready window.
    Lag,
}

/// The first difference found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Mismatch {
    /// Operation number.
    pub step: usize,
    /// The request.
    pub request: Frame,
    /// The core alone's answer.
    pub alone: Option<Frame>,
    /// The split's answer.
    pub split: Option<Frame>,
    /// Which rule failed.
    pub why: &'static str,
}

/// Reads the input front to back; zeros once it is used up.
struct Src<'a>(&'a [u8]);

impl<'a> Src<'a> {
    fn u8(&mut self) -> u8 {
        match self.0.split_first() {
            Some((&b, rest)) => {
                self.0 = rest;
                b
            }
            None => 0,
        }
    }
    fn bytes(&mut self, n: usize) -> &'a [u8] {
        let n = n.min(self.0.len());
        let (a, b) = self.0.split_at(n);
        self.0 = b;
        a
    }
}

fn frame_of(bytes: &[u8]) -> Frame {
    let mut f = Frame::new();
    let _ = f.extend_from_slice(&bytes[..bytes.len().min(MAX_FRAME_LEN)]);
    f
}

/// What an operation does.
enum Action {
    /// A telegram on the line; `holdable`: the core may stay behind for it in [`Mode::Lag`];
    /// `lag`: in [`Mode::Lag`] the core may stay behind after it (a DP-V1 request PDU).
    Telegram { frame: Frame, holdable: bool, diag: bool, lag: bool },
    /// `Node::process_acyclic` on both cards (DP-V1 responses); `split_behind`: in
    /// [`Mode::Lag`] the split's core does not catch up first.
    Process { split_behind: bool },
    /// Time passes: both nodes' timers.
    Tick(u64),
    /// An application change, applied to both nodes.
    App(u8, Vec<u8, 64>),
}

struct Rig {
    fcb: [bool; 128],
    next: Option<Frame>,
    last: Option<Frame>,
    /// After an RM request: the Initiate.req on the granted SAP (master, its SAP, the PDU).
    initiate: Option<(u8, u8, Vec<u8, 64>)>,
}

impl Rig {
    fn request(&mut self, da: u8, sa: u8, dsap: Option<u8>, ssap: Option<u8>, pdu: &[u8], function: u8) -> Frame {
        let fcb = &mut self.fcb[usize::from(sa & 0x7F)];
        *fcb = !*fcb;
        let hdr = Header { da, sa, fc: FunctionCode::request(function, *fcb, true), dsap, ssap };
        match crate::testkit::try_frame(&hdr, pdu) {
            Ok(f) => f,
            Err(_) => Frame::new(),
        }
    }
}

fn set_prm(src: &mut Src<'_>) -> Vec<u8, 64> {
    let v = src.u8();
    let mut p = SetPrm::CARD;
    match v % 12 {
        1 => p = p.no_watchdog(),
        2 => p.station_status = src.u8(),
        4 => p = p.ident(u16::from(src.u8()) << 8 | u16::from(src.u8())),
        5 => p.station_status |= src.u8() & 0x30,
        6 => p.group = src.u8(),
        7 => p = p.dpv1_status_1(src.u8()),
        _ => {}
    }
    let pdu = p.pdu();
    let mut out = Vec::new();
    let n = if v % 12 == 3 { usize::from(src.u8()) % (pdu.len() + 1) } else { pdu.len() };
    let _ = out.extend_from_slice(&pdu[..n.min(64)]);
    out
}

fn next_action(src: &mut Src<'_>, rig: &mut Rig, alone: &Node) -> Action {
    if let Some(f) = rig.next.take() {
        rig.last = Some(f.clone());
        let holdable = poll_of(&f);
        return Action::Telegram { frame: f, holdable, diag: false, lag: false };
    }
    if let Some((m, ssap, init)) = rig.initiate.take() {
        // The Initiate.req on the SAP the RM named (as the core alone reserved it).
        let sap = conn_of(alone, m).map_or(c2::HIGHEST_SAP, |(sap, _)| sap);
        let f = rig.request(alone.slave().address(), m, Some(sap), Some(ssap), &init, 0x0D);
        rig.next = Some(rig.request(alone.slave().address(), m, Some(sap), Some(ssap), &[], 0x0D));
        rig.last = Some(f.clone());
        return Action::Telegram { frame: f, holdable: false, diag: false, lag: true };
    }
    let op = src.u8();
    let da = alone.slave().address();
    // Mostly the first master, so that sequences reach data exchange.
    let m = match src.u8() {
        0..=169 => MASTERS[0],
        170..=229 => MASTERS[1],
        _ => MASTERS[2],
    };
    let srd = 0x0D;
    let f = match op % 19 {
        18 => {
            // The start-up pair at once: Set_Prm (the card's) then Chk_Cfg (module 0) — the
            // second telegram follows as the next operation through `rig.next`.
            let pdu = SetPrm::CARD.pdu();
            let cfg = rig.request(da, m, Some(62), Some(62), CARD.modules[0].cfg, srd);
            rig.next = Some(cfg);
            rig.request(da, m, Some(61), Some(62), &pdu, srd)
        }
        0 => {
            let pdu = set_prm(src);
            rig.request(da, m, Some(61), Some(62), &pdu, srd)
        }
        1 => {
            let module = &CARD.modules[usize::from(src.u8()) % CARD.modules.len()];
            let mut cfg: Vec<u8, 32> = Vec::new();
            let _ = cfg.extend_from_slice(module.cfg);
            let mangle = src.u8();
            if mangle & 0xC0 == 0xC0 && !cfg.is_empty() {
                let i = usize::from(mangle) % cfg.len();
                cfg[i] = src.u8();
            }
            rig.request(da, m, Some(62), Some(62), &cfg, srd)
        }
        2 => {
            let n = match src.u8() % 4 {
                0 | 1 => alone.slave().output_len(),
                2 => 0,
                _ => usize::from(src.u8()) % 40,
            };
            let pdu = src.bytes(n);
            // Room for the largest module's outputs (244 bytes in the bench build).
            let mut out = [0u8; 256];
            out[..pdu.len()].copy_from_slice(pdu);
            rig.request(da, m, None, None, &out[..n], srd)
        }
        3 => {
            let diag = rig.request(da, m, Some(60), Some(62), &[], srd);
            return Action::Telegram { frame: diag, holdable: true, diag: true, lag: false };
        }
        4 => rig.request(da, m, Some(59), Some(62), &[], srd),
        5 => {
            let d = if src.u8() & 1 == 0 { 56 } else { 57 };
            rig.request(da, m, Some(d), Some(62), &[], srd)
        }
        6 => {
            let to = if src.u8() & 1 == 0 { telegram::BROADCAST } else { da };
            let cmd = src.u8();
            let group = src.u8() & 0x03;
            let hdr =
                Header { da: to, sa: m, fc: FunctionCode::request(0x06, false, false), dsap: Some(58), ssap: Some(62) };
            crate::testkit::frame(&hdr, &[cmd, group])
        }
        7 => match rig.last.clone() {
            Some(l) => {
                let diag = matches!(telegram::decode(&l), Decoded::Frame(Telegram::Data(t), _) if t.dsap == Some(60));
                return Action::Telegram { frame: l, holdable: diag, diag, lag: false };
            }
            None => Frame::new(),
        },
        8 => {
            let to = if da == OTHER { OTHER + 1 } else { OTHER };
            let other = rig.request(to, m, None, None, src.bytes(4), srd);
            return Action::Telegram { frame: other, holdable: true, diag: false, lag: false };
        }
        9 => {
            let how = src.u8() % 3;
            let sa = match how {
                0 => telegram::BROADCAST,
                1 => da,
                _ => m,
            };
            let mut f = rig.request(da, sa, Some(60), Some(62), &[], srd);
            if how == 2 && f.len() > 6 {
                // FC bit 7 (SD3 diagnosis request: FC at 3).
                let at = if f[0] == telegram::SD2 { 6 } else { 3 };
                f[at] |= 0x80;
                let n = f.len();
                let start = if f[0] == telegram::SD2 { 4 } else { 1 };
                f[n - 2] = telegram::fcs(&f[start..n - 2]);
            }
            return Action::Telegram { frame: f, holdable: true, diag: false, lag: false };
        }
        10 => {
            let hdr = Header { da, sa: m, fc: FunctionCode::request(0x09, false, false), dsap: None, ssap: None };
            let f = crate::testkit::frame(&hdr, &[]);
            return Action::Telegram { frame: f, holdable: true, diag: false, lag: false };
        }
        11 => {
            let new = src.u8() % 130;
            let ident = if src.u8() & 0x80 == 0 { CARD.ident_number } else { 0x1234 };
            let lock = src.u8() & 1;
            let [hi, lo] = ident.to_be_bytes();
            rig.request(da, m, Some(55), Some(62), &[new, hi, lo, lock], srd)
        }
        12 => return Action::Tick(u64::from(src.u8()) * 20_000),
        13 => {
            let what = src.u8();
            let n = usize::from(src.u8()) % 40;
            let mut data = Vec::new();
            let _ = data.extend_from_slice(src.bytes(n));
            return Action::App(what, data);
        }
        14 => {
            let n = usize::from(src.u8()) % 24;
            let mut f = frame_of(src.bytes(n));
            if let Ok(Some(len)) = telegram::frame_len(&f) {
                if len <= f.len() && len >= 6 {
                    f.truncate(len);
                    let start = if f[0] == telegram::SD2 { 4 } else { 1 };
                    f[len - 2] = telegram::fcs(&f[start..len - 2]);
                    f[len - 1] = telegram::ED;
                }
            }
            f
        }
        15 => return dpv1_action(src, rig, alone, da, m),
        16 => {
            let function = src.u8() & 0x0F;
            rig.request(da, m, Some(60), Some(62), &[], function)
        }
        _ => {
            // A new request with the FCB not toggled (a master that re-polls).
            rig.fcb[usize::from(m)] = !rig.fcb[usize::from(m)];
            rig.request(da, m, None, None, src.bytes(alone.slave().output_len()), srd)
        }
    };
    rig.last = Some(f.clone());
    Action::Telegram { frame: f, holdable: false, diag: false, lag: false }
}

/// A DP-V1 poll (SRD without data on SAP 51 or a connection SAP).
fn poll_of(f: &[u8]) -> bool {
    matches!(telegram::decode(f), Decoded::Frame(Telegram::Data(t), _)
        if t.pdu.is_empty() && t.dsap.is_some_and(|d| d == c1::SAP || (c2::HIGHEST_SAP + 1 - C2_CONNECTIONS as u8..=c2::HIGHEST_SAP).contains(&d)))
}

/// The connection SAP and master SAP the core alone holds for master `m`.
fn conn_of(alone: &Node, m: u8) -> Option<(u8, u8)> {
    (0..C2_CONNECTIONS)
        .filter_map(|i| alone.c2().connection(i))
        .find(|c| c.state != ConnectionState::Closed && c.master == m)
        .map(|c| (c.sap, c.master_sap))
}

/// An MSAC_C2 Initiate.req PDU (S and D address blocks of type 0).
fn initiate(send_timeout: u16, s_len: u8, api: u8) -> Vec<u8, 64> {
    let mut v = initiate_pdu(send_timeout, api);
    if let Some(b) = v.get_mut(13) {
        *b = s_len;
    }
    v
}

/// An MSAC_C2 Initiate.req PDU with `send_timeout` and the destination API `api`, as
/// `InitiateRequest::emit` builds it (also the lean-path tests, `link_tests::fast_lean`).
pub(crate) fn initiate_pdu(send_timeout: u16, api: u8) -> Vec<u8, 64> {
    let req = InitiateRequest {
        send_timeout,
        features_supported: [1, 0],
        profile_features_supported: [0, 0],
        profile_ident_number: 0,
        source: AddressBlock { kind: 0, bytes: &[0, 0] },
        destination: AddressBlock { kind: 0, bytes: &[api, 0] },
    };
    let mut out = [0u8; 64];
    let n = req.emit(&mut out).unwrap_or(0);
    let mut v = Vec::new();
    let _ = v.extend_from_slice(&out[..n]);
    v
}

/// A DP-V1 data PDU: Read / Write / Data_Transport of a record at slot 0 (PROFIdrive 47,
/// WEG 48, I&M 255, a missing one), Idle, Abort, Alarm_Ack, or raw bytes.
fn dpv1_pdu(src: &mut Src<'_>) -> Vec<u8, 64> {
    let mut v: Vec<u8, 64> = Vec::new();
    let index = [47u8, 48, 255, 1][usize::from(src.u8() % 4)];
    match src.u8() % 9 {
        0 | 1 => {
            let _ = v.extend_from_slice(&[0x5E, 0, index, src.u8() % 250]);
        }
        2 | 3 => {
            let n = usize::from(src.u8()) % 24;
            let data = src.bytes(n);
            let _ = v.extend_from_slice(&[0x5F, 0, index, data.len() as u8]);
            let _ = v.extend_from_slice(data);
        }
        4 => {
            let n = 1 + usize::from(src.u8()) % 12;
            let data = src.bytes(n);
            let _ = v.extend_from_slice(&[0x51, 0, index, data.len() as u8]);
            let _ = v.extend_from_slice(data);
        }
        5 => {
            let _ = v.extend_from_slice(&[0x48, 0]);
        }
        6 => {
            let _ = v.extend_from_slice(&[0x58, 0, 0x20, 0]);
        }
        7 => {
            let _ = v.extend_from_slice(&[0x5C, 1, 1, 0]);
        }
        _ => {
            let n = usize::from(src.u8()) % 12;
            let _ = v.extend_from_slice(src.bytes(n));
        }
    }
    v
}

/// A DP-V1 operation: the DP-V1 start-up, MSAC_C1 requests and polls, MSAC_C2 RM /
/// Initiate / requests / polls / Abort, or a run of the DP-V1 task.
fn dpv1_action(src: &mut Src<'_>, rig: &mut Rig, alone: &Node, da: u8, m: u8) -> Action {
    let srd = 0x0D;
    let f = match src.u8() % 10 {
        0 => {
            // Set_Prm with DPV1_Enable, then Chk_Cfg: MSAC_C1 opens.
            let pdu = SetPrm::CARD.dpv1_status_1(0x80).pdu();
            rig.next = Some(rig.request(da, m, Some(62), Some(62), CARD.modules[0].cfg, srd));
            rig.request(da, m, Some(61), Some(62), &pdu, srd)
        }
        1..=3 => {
            let ssap = if src.u8() < 240 { c1::SAP } else { 50 };
            let pdu = if src.u8() & 1 == 0 { dpv1_pdu(src) } else { Vec::new() };
            let f = rig.request(da, m, Some(c1::SAP), Some(ssap), &pdu, srd);
            if !pdu.is_empty() {
                rig.next = Some(rig.request(da, m, Some(c1::SAP), Some(ssap), &[], srd));
                rig.last = Some(f.clone());
                return Action::Telegram { frame: f, holdable: false, diag: false, lag: true };
            }
            rig.last = Some(f.clone());
            return Action::Telegram { frame: f, holdable: true, diag: false, lag: false };
        }
        4 => {
            let ssap = 40 + (src.u8() & 1);
            let st = u16::from(src.u8()) * 2;
            let how = src.u8();
            let init = match how % 8 {
                0 => initiate(st, 3, 0),
                1 => initiate(st, 2, 1),
                2 => {
                    let mut v = Vec::new();
                    let _ = v.extend_from_slice(&[0x57, 0]);
                    v
                }
                _ => initiate(st, 2, 0),
            };
            let ssap_field = if how & 0xF0 == 0xF0 { None } else { Some(ssap) };
            if how & 0x08 == 0 {
                rig.initiate = Some((m, ssap, init.clone()));
            }
            rig.request(da, m, Some(c2::RM_SAP), ssap_field, &init, srd)
        }
        5..=8 => {
            let (sap, ssap) = conn_of(alone, m).unwrap_or((c2::HIGHEST_SAP - (src.u8() & 1), 40 + (src.u8() & 1)));
            let ssap = if src.u8() < 240 { ssap } else { ssap ^ 1 };
            let pdu = match src.u8() % 4 {
                0 => Vec::new(),
                1 => initiate(u16::from(src.u8()), 2, 0),
                _ => dpv1_pdu(src),
            };
            let function = if src.u8() < 24 { 0x06 } else { srd };
            let f = rig.request(da, m, Some(sap), Some(ssap), &pdu, function);
            if !pdu.is_empty() {
                rig.next = Some(rig.request(da, m, Some(sap), Some(ssap), &[], srd));
                rig.last = Some(f.clone());
                return Action::Telegram { frame: f, holdable: false, diag: false, lag: true };
            }
            rig.last = Some(f.clone());
            return Action::Telegram { frame: f, holdable: true, diag: false, lag: false };
        }
        _ => return Action::Process { split_behind: src.u8() & 1 == 0 },
    };
    rig.last = Some(f.clone());
    Action::Telegram { frame: f, holdable: false, diag: false, lag: false }
}

fn apply(node: &mut Node, what: u8, data: &[u8]) {
    let s = node.slave_mut();
    match what % 6 {
        0 | 1 => s.set_inputs(data),
        2 => {
            let _ = s.set_ext_diag(data, what & 0x80 != 0);
        }
        3 => s.set_stat_diag(what & 0x80 != 0),
        4 => s.set_drive_fault(u16::from(what >> 4)),
        _ => s.set_ready(what & 0x80 == 0),
    }
}

/// A valid Slave_Diag answer from `own` to `to` with Station_Not_Ready set.
fn not_ready_diag(answer: &[u8], own: u8, to: u8) -> bool {
    match telegram::decode(answer) {
        Decoded::Frame(Telegram::Data(t), n) => {
            n == answer.len()
                && t.sa == own
                && t.da == to
                && t.fc == FunctionCode::response(ResponseStatus::Dl)
                && t.pdu.len() >= 6
                && t.pdu[0] & 0x02 != 0
        }
        _ => false,
    }
}

/// How the split's line gets a telegram: whole ([`FastPath::on_frame`]), or — when `cuts`
/// is not empty — through the [`TelegramSink`] in pieces whose sizes cycle through `cuts`
/// (`c % 40 + 1` bytes each: single bytes, DMA chunks, the rest at once), then
/// [`FastPath::finish`].
struct Pieces<'c> {
    cuts: &'c [u8],
    next: usize,
}

impl Pieces<'_> {
    fn verdict<'f>(&mut self, fast: &'f mut FastPath<'_>, now: Instant, f: &[u8]) -> Verdict<'f> {
        if self.cuts.is_empty() {
            return fast.on_frame(now, f);
        }
        fast.begin();
        let mut rest = f;
        while !rest.is_empty() {
            let c = self.cuts[self.next % self.cuts.len()];
            self.next = self.next.wrapping_add(1);
            let (piece, tail) = rest.split_at((usize::from(c) % 40 + 1).min(rest.len()));
            fast.bytes(piece);
            rest = tail;
        }
        fast.finish(now)
    }
}

fn split_answer(
    fast: &mut FastPath<'_>,
    core: &mut CoreLink<'_>,
    split: &mut Node,
    now: Instant,
    f: &[u8],
    pieces: &mut Pieces<'_>,
) -> Option<Frame> {
    match pieces.verdict(fast, now, f) {
        Verdict::Silent => None,
        Verdict::Answer(a) => Some(frame_of(a)),
        Verdict::Core => {
            core.run(split);
            match fast.take_deferred() {
                Some([]) | None => None,
                Some(a) => Some(frame_of(a)),
            }
        }
    }
}

#[cfg(test)]
std::thread_local! {
    /// Print every telegram (tests only).
    pub static TRACE: core::cell::Cell<bool> = const { core::cell::Cell::new(false) };
}

/// What a run reached (to see that the generator gets somewhere).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Coverage {
    /// Operations run.
    pub ops: usize,
    /// Data_Exchange answered with data by the core alone.
    pub data_exchanges: u32,
    /// Slave_Diag answered by the line in the not-ready window.
    pub not_ready_diags: u32,
    /// Requests the line left to the core.
    pub deferred: u32,
    /// FCB retries the line answered.
    pub retries: u32,
    /// DP-V1 frames the line answered from the staging.
    pub dpv1_line: u32,
    /// DP-V1 polls answered with a response frame by the split.
    pub dpv1_responses: u32,
    /// Polls the split answered "not ready" while the core alone delivered, delivered on the
    /// next poll ([`Mode::Lag`]).
    pub held_repolls: u32,
}

/// Run the operations `data` encodes (at most `max_ops`) on both cards; what was reached,
/// or the first difference.
// A test helper without a heap (no_std): the mismatch is returned by value.
#[allow(clippy::result_large_err)]
pub fn run(data: &[u8], mode: Mode, max_ops: usize) -> Result<Coverage, Mismatch> {
    run_in_pieces(data, mode, max_ops, &[])
}

/// [`run`] with the split's line fed through the [`TelegramSink`] in pieces whose sizes cycle
/// through `cuts` (`c % 40 + 1` bytes; empty: whole telegrams through
/// [`FastPath::on_frame`]).
// A test helper without a heap (no_std): the mismatch is returned by value.
#[allow(clippy::result_large_err)]
pub fn run_in_pieces(data: &[u8], mode: Mode, max_ops: usize, cuts: &[u8]) -> Result<Coverage, Mismatch> {
    let mut pieces = Pieces { cuts, next: 0 };
    let mut src = Src(data);
    let mut alone = crate::card::node(DpSlave::new(CARD, ME));
    let mut split = crate::card::node(DpSlave::new(CARD, ME));
    let mut shared = Shared::new();
    let (mut fast, mut core) = shared.split(&mut split);
    let mut rig = Rig { fcb: [false; 128], next: None, last: None, initiate: None };
    let mut now = 0u64;
    // The split's answer to the request the station stored last (what a retry repeats).
    let mut stored: Option<Option<Frame>> = None;
    // The DP-V1 task's parameters of each card (the tests' one fake drive table).
    let mut pa_alone = FakeDrive::new();
    let mut pa_split = FakeDrive::new();
    // Each card's data records (records 47 / 48), owned by the application.
    let mut rec_alone = CardRecords::new(&crate::card::RECORDS);
    let mut rec_split = CardRecords::new(&crate::card::RECORDS);
    // A DP-V1 poll the split answered "not ready" while the core alone delivered: the core
    // alone's answer and the master's next poll, which must deliver exactly that.
    let mut owed: Option<(Frame, Frame)> = None;
    let mut cov = Coverage::default();
    let mut step = 0;
    while !src.0.is_empty() && step < max_ops {
        step += 1;
        if let Some((want, req)) = owed.take() {
            // The master polls again once the card had time: the held response goes out now.
            core.run(&mut split);
            let t = Instant::from_micros(now);
            alone.process_acyclic(t, &mut rec_alone.with(&mut pa_alone));
            split.process_acyclic(t, &mut rec_split.with(&mut pa_split));
            core.publish(&mut split);
            now += 150;
            let t = Instant::from_micros(now);
            let _ = alone.on_frame(t, &req);
            let s = split_answer(&mut fast, &mut core, &mut split, t, &req, &mut pieces);
            core.run(&mut split);
            if s.as_ref() != Some(&want) {
                return Err(Mismatch {
                    step,
                    request: req,
                    alone: Some(want),
                    split: s,
                    why: "a DP-V1 response the line answered \"not ready\" did not come on the next poll",
                });
            }
            cov.held_repolls += 1;
            stored = Some(s);
            rig.last = Some(req);
            continue;
        }
        let mut lag_after = false;
        match next_action(&mut src, &mut rig, &alone) {
            Action::Process { split_behind } => {
                let t = Instant::from_micros(now);
                alone.process_acyclic(t, &mut rec_alone.with(&mut pa_alone));
                // The split's DP-V1 task may overtake its core only for the DP-V1 requests
                // themselves (their polls are answered "not ready" meanwhile, checked below), not
                // for a queued Set_Prm / Chk_Cfg: with it unjudged the task would work on a
                // state the card alone never had (it judged the Set_Prm / Chk_Cfg first), and
                // either order is the slave's to choose — the firmware's core task runs above
                // the DP-V1 task, so this order needs a Set_Prm / Chk_Cfg arriving while the
                // task holds the node; the comparison cannot follow it.
                if mode == Mode::Sync || !split_behind || fast.in_window() {
                    core.run(&mut split);
                }
                split.process_acyclic(t, &mut rec_split.with(&mut pa_split));
                core.publish(&mut split);
            }
            Action::Tick(us) => {
                core.run(&mut split);
                now += us;
                let t = Instant::from_micros(now);
                alone.poll(t);
                core.poll(t, &mut split);
            }
            Action::App(what, data) => {
                core.run(&mut split);
                apply(&mut alone, what, &data);
                apply(&mut split, what, &data);
                core.publish(&mut split);
            }
            Action::Telegram { frame, holdable, diag, lag } => {
                lag_after = lag && mode == Mode::Lag;
                if mode == Mode::Sync || !holdable || fast.queue_free() < 2 {
                    core.run(&mut split);
                }
                now += 150;
                let t = Instant::from_micros(now);
                let before = alone.station().stats();
                let a = alone.on_frame(t, &frame).map(frame_of);
                let after = alone.station().stats();
                let window = fast.in_window();
                let own = alone.slave().address();
                let s = split_answer(&mut fast, &mut core, &mut split, t, &frame, &mut pieces);
                if mode == Mode::Sync {
                    core.run(&mut split);
                }
                #[cfg(test)]
                if TRACE.with(|t| t.get()) {
                    std::eprintln!("{step} {frame:02x?} alone {a:02x?} split {s:02x?} win {window} alone {:?} split {:?} fast {:?}", alone.station().stats(), split.station().stats(), fast.stats());
                }
                let mismatch = |why| Mismatch { step, request: frame.clone(), alone: a.clone(), split: s.clone(), why };
                if after.retries != before.retries {
                    if stored.as_ref() != Some(&s) {
                        return Err(mismatch("a retry did not repeat the split's own answer"));
                    }
                } else {
                    let srd = matches!(telegram::decode(&frame), Decoded::Frame(Telegram::Data(t), _)
                        if matches!(t.fc.function(), RequestFunction::SrdLow | RequestFunction::SrdHigh));
                    if (srd && after.requests != before.requests) || after.unsupported != before.unsupported {
                        stored = Some(s.clone());
                    }
                    if window && diag && a.is_some() {
                        let sa = match telegram::decode(&frame) {
                            Decoded::Frame(Telegram::Data(t), _) => t.sa,
                            _ => 0xFF,
                        };
                        if !s.as_deref().is_some_and(|b| not_ready_diag(b, own, sa)) {
                            return Err(mismatch("not-ready window: not a Station_Not_Ready diagnosis"));
                        }
                    } else if mode == Mode::Lag
                        && poll_of(&frame)
                        && s.as_deref() == Some(&[telegram::SC][..])
                        && a.as_ref().is_some_and(|a| a.len() > 1)
                    {
                        // The core was behind: "not ready yet"; the next poll must deliver.
                        let Decoded::Frame(Telegram::Data(t), _) = telegram::decode(&frame) else {
                            return Err(mismatch("a poll that does not decode"));
                        };
                        let (sa, dsap, ssap) = (t.sa, t.dsap, t.ssap);
                        let again = rig.request(own, sa, dsap, ssap, &[], 0x0D);
                        owed = a.clone().map(|a| (a, again));
                    } else if a != s {
                        return Err(mismatch("the split answered differently"));
                    }
                    if poll_of(&frame) && s.as_ref().is_some_and(|s| s.len() > 1) {
                        cov.dpv1_responses += 1;
                    }
                }
            }
        }
        // The node states never differ: the core sees every telegram in order.
        if mode == Mode::Sync || (!fast.in_window() && !lag_after) {
            core.run(&mut split);
            if alone.slave().state() != split.slave().state() || alone.slave().outputs() != split.slave().outputs() {
                return Err(Mismatch {
                    step,
                    request: Frame::new(),
                    alone: None,
                    split: None,
                    why: "the split's core state differs from the core alone's",
                });
            }
        }
    }
    let fs = fast.stats();
    Ok(Coverage {
        ops: step,
        data_exchanges: alone.slave().stats().data_exchanges,
        not_ready_diags: fs.not_ready_diag,
        deferred: fs.deferred,
        retries: fs.retries,
        dpv1_line: fs.dpv1,
        ..cov
    })
}
