//! DP-V1 on the line (issue 11 item 1): MSAC_C1 (SAP 51), the MSAC_C2 resource manager
//! (SAP 49) and the connection SAPs answered from staged state, the core judging afterwards.
//!
//! DP-V1 is built for this split (reference §4.3): a request PDU is acknowledged with SC at
//! once and worked on later; the master polls (SRD without data) and gets SC until the
//! response is there. The staging ([`CoreLink::publish`](super::CoreLink::publish)) therefore carries, per relation
//! (MSAC_C1 and each of the node's [`C2_CONNECTIONS`] MSAC_C2 connections), whether it
//! is open, for which master and SAP, its timer and its ready response frame; and the RM's
//! Poll_Timeout. The line answers:
//!
//! | frame | line's answer |
//! |---|---|
//! | SAP 51, C1 closed, not the locking master, SSAP ≠ 51 | RS (as `C1::on_request`) |
//! | SAP 51, request PDU | SC |
//! | SAP 51 / connection SAP, poll, response staged | the staged response frame |
//! | SAP 51 / connection SAP, poll, nothing staged | SC ("not ready") |
//! | SAP 49, not an Initiate.req or no SSAP | RS |
//! | SAP 49, Initiate.req | the RM PDU naming the connection the core will reserve, or RR |
//! | connection SAP, closed or another master / SSAP | RS |
//! | connection SAP, the master's Abort PDU | SC |
//! | connection SAP, aborted by the slave | the Abort PDU (built from the staged reason) |
//! | connection SAP, any other request PDU | SC |
//!
//! Timers are foreseen: a staged connection whose reservation, Send_Timeout or pending Abort
//! expired by the frame's arrival is treated as `C2` will treat it at that frame
//! (`C2::expire`).
//!
//! **Frames in flight.** The staging shows the core after the last telegram it worked on.
//! A relation with a queued, not yet judged frame that changes its state (a request PDU, an
//! RM reservation, a fetched response, an Abort) is *in flight*: the line knows only that it
//! is open for that master (or closed, after an Abort) and answers every further frame on it
//! with SC — "not ready yet" — until the core has caught up. A poll answered SC travels to
//! the core with [`Queued::held`](super::Queued::held): the core then hands out nothing on it
//! ([`Node::on_frame_as`](crate::node::Node::on_frame_as)) — a response the core finished meanwhile (or a pending Abort
//! PDU) stays for the next poll, so a response is never lost and never delivered twice
//! (except as the FCB retry the station and the line both repeat byte for byte).
//!
//! **Decided at the header** ([`FastPath::prepare_dpv1`], issue 11): the decision depends only
//! on the header (SA, the SAPs), whether the PDU is empty and its first octet, the staging
//! and the line's relation view (neither changes while a telegram arrives) and the time. So
//! once the first PDU octet is in, the line plans at the earliest time, builds the answer
//! into its free answer buffer and keeps the plan with the earliest timer of the relations it
//! looked at ([`Decided`]); at the last character `finish` takes it when the telegram decoded
//! (FCS, ED, extensions), SA and DSAP match and the arrival is before that timer — otherwise
//! it plans again as before. A connection SAP's Abort PDU is not prepared (its full parse
//! decides).
//!
//! **Deferred to the core** ([`Verdict::Core`](super::Verdict::Core), the line waits as before the split):
//! * SAP 51 in the not-ready window (a queued Set_Prm / Chk_Cfg decides whether MSAC_C1 is
//!   open at all);
//! * SAP 49 while any MSAC_C2 connection is in flight: which connection the RM names (or
//!   whether it answers RR) depends on states the line cannot see yet — an honest immediate
//!   answer is impossible there. A class-2 master opens one connection at a time, so this is
//!   a second master's Initiate racing the first one's.

use super::{after, round4, CoreLink, FastPath, DPV1_AT, QUEUE_LEN};
use crate::dpv1::c1;
use crate::dpv1::c2::{self, ConnectionState};
use crate::dpv1::pdu::{Abort, AbortReason, Function, Instance, Response, Subnet};
use crate::fdl::telegram::{DataFormat, DataTelegram, FunctionCode, ResponseStatus, MAX_FRAME_LEN};
use crate::node::Node;
use crate::time::Instant;

/// The MSAC_C2 connections of the node (`N` of its [`C2<N>`](c2::C2), [`Node::c2`]): read off
/// the node's type, so the line stages as many as the core runs without naming the product.
pub const C2_CONNECTIONS: usize = connections(Node::c2);

const fn connections<const N: usize>(_: for<'a> fn(&'a Node) -> &'a c2::C2<N>) -> usize {
    N
}

/// Relations: MSAC_C1, then the MSAC_C2 connections (connection `i` = relation `1 + i`).
pub(super) const RELS: usize = 1 + C2_CONNECTIONS;
/// Per relation: `[kind, master, master SAP, abort reason]`, `[frame length u16, Send_Timeout
/// u16]`, the timer's deadline (µs, u64), then the ready response frame.
const REL_HDR: usize = 16;
const REL_ROOM: usize = REL_HDR + round4(MAX_FRAME_LEN);
/// Bytes of the DP-V1 staging: the RM word (Poll_Timeout u16) and the relations.
pub(super) const DPV1_BYTES: usize = 4 + RELS * REL_ROOM;

const fn rel_at(r: usize) -> usize {
    DPV1_AT + 4 + r * REL_ROOM
}

const K_CLOSED: u8 = 0;
const K_RESERVED: u8 = 1;
const K_OPEN: u8 = 2;
const K_ABORTING: u8 = 3;
/// The line's own view: a frame in flight, the relation open for its master.
const K_FLIGHT: u8 = 4;

/// The line's knowledge of one relation beyond the staging.
#[derive(Debug, Clone, Copy)]
pub(super) struct RelLine {
    /// The last queued frame that changes the relation's state.
    seq: u32,
    /// Whether `seq` was ever set.
    set: bool,
    /// After it: open for (master, master SAP), or closed.
    open: Option<(u8, u8)>,
}

impl RelLine {
    pub(super) const IDLE: RelLine = RelLine { seq: 0, set: false, open: None };
}

/// One relation as the line sees it at a frame's arrival.
#[derive(Debug, Clone, Copy)]
struct View {
    kind: u8,
    master: u8,
    ssap: u8,
    reason: u8,
    frame_len: u16,
}

/// What the line answers (built into `buf` once the frame is queued).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Plan {
    Status(ResponseStatus),
    /// SC; the core hands out nothing on this frame.
    Sc,
    /// The staged response frame of relation `r`, its length (the view's at the plan's time).
    Ready(u8, u16),
    /// The RM PDU naming connection `i`.
    Rm(u8),
    /// The Abort PDU of connection `i` (reason code).
    Abort(u8, u8),
}

/// The relation a frame puts in flight, with its view after the frame (open for master and
/// master SAP, or closed).
type Flight = Option<(u8, Option<(u8, u8)>)>;

/// A DP-V1 decision made while the request's header arrived ([`FastPath::prepare_dpv1`]),
/// its answer in `bufs[w]`: the decision at the last character is this one as long as the
/// telegram is the one it was made for (SA, DSAP; the rest of the header and the first PDU
/// octet are the same received bytes) and `now` is before `until` — the earliest timer
/// (reservation, Send_Timeout, pending Abort) of the staged relations it looked at, after
/// which [`FastPath::plan`] could see another state. The staging and the line's own
/// relation view do not change while a telegram arrives.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Decided {
    /// `until` in µs, low and high word (no u64 alignment: the fast path's RAM is tight).
    until: [u32; 2],
    plan: Plan,
    flight: Flight,
    /// The answer's length in `bufs[w]` (0: none).
    n: u16,
    sa: u8,
    dsap: u8,
}

impl Decided {
    fn until(&self) -> u64 {
        u64::from(self.until[0]) | u64::from(self.until[1]) << 32
    }
}

/// A timer of a staged relation runs in this state (`staged_view` moves it on).
fn timed(kind: u8) -> bool {
    matches!(kind, K_RESERVED | K_OPEN | K_ABORTING)
}

/// The line's decision on a DP-V1 SRD.
pub(super) enum Dpv1 {
    /// Not DP-V1, or deferred: the core answers.
    Core,
    /// The core queue is full: no answer (the master retries).
    QueueFull,
    /// `buf[..n]` is the answer (0: none).
    Answer(u16),
}

/// Connection index of a connection SAP (48, 47, …).
fn conn_of(sap: u8) -> Option<usize> {
    let i = usize::from(c2::HIGHEST_SAP.checked_sub(sap)?);
    (i < C2_CONNECTIONS).then_some(i)
}

impl FastPath<'_> {
    /// Relation `r` has a frame the core has not judged yet (the core is at most
    /// [`QUEUE_LEN`] telegrams behind the line, so an older one is judged: no wrap-around).
    fn in_flight(&self, r: usize) -> bool {
        let l = self.rel[r];
        l.set && self.seq.wrapping_sub(l.seq) < QUEUE_LEN as u32 && after(l.seq, self.st.done_seq)
    }

    /// Relation `r` from the staging, its timer run up to `now` (µs) as `C2::expire` would;
    /// `until` is lowered to the next deadline that would change the view after `now`.
    fn staged_view(&self, r: usize, now: u64, until: &mut u64) -> View {
        let w = rel_at(r) / 4;
        let [kind, master, ssap, reason] = self.staging.word(w).to_le_bytes();
        let lens = self.staging.word(w + 1);
        let mut v = View { kind, master, ssap, reason, frame_len: lens as u16 };
        let send_timeout = u64::from(lens >> 16) * 10_000;
        let mut deadline = u64::from(self.staging.word(w + 2)) | u64::from(self.staging.word(w + 3)) << 32;
        if r > 0 {
            loop {
                if now < deadline {
                    if timed(v.kind) {
                        *until = (*until).min(deadline);
                    }
                    break;
                }
                v.kind = match v.kind {
                    K_RESERVED | K_ABORTING => K_CLOSED,
                    K_OPEN => {
                        v.reason = AbortReason::Timeout.bits();
                        v.frame_len = 0;
                        deadline = deadline.saturating_add(send_timeout);
                        K_ABORTING
                    }
                    _ => break,
                };
            }
        }
        v
    }

    /// Relation `r` at `now`: the line's own view while in flight, else the staging's.
    fn view(&self, r: usize, now: u64, until: &mut u64) -> View {
        if self.in_flight(r) {
            let (kind, (master, ssap)) = match self.rel[r].open {
                Some(o) => (K_FLIGHT, o),
                None => (K_CLOSED, (0, 0)),
            };
            return View { kind, master, ssap, reason: 0, frame_len: 0 };
        }
        self.staged_view(r, now, until)
    }

    /// The plan for a DP-V1 SRD at `now` (µs), and the relation it puts in flight (with its
    /// view after the frame). `None`: not DP-V1, or the core must answer. The plan stays the
    /// same for any later time before `until` (lowered to the next timer it depends on).
    fn plan(&self, now: u64, until: &mut u64, t: &DataTelegram<'_>) -> Option<(Plan, Flight)> {
        let dsap = t.dsap?;
        let poll = t.pdu.is_empty();
        if dsap == c1::SAP {
            if after(self.judge_seq, self.st.done_seq) {
                return None;
            }
            let v = self.staged_view(0, now, until);
            if v.kind != K_OPEN || v.master != t.sa || t.ssap != Some(c1::SAP) {
                return Some((Plan::Status(ResponseStatus::Rs), None));
            }
            let open = Some((0, Some((t.sa, c1::SAP))));
            let ready = poll && v.frame_len > 0 && !self.in_flight(0);
            return Some((if ready { Plan::Ready(0, v.frame_len) } else { Plan::Sc }, open));
        }
        if dsap == c2::RM_SAP {
            let initiate = t.pdu.first() == Some(&Function::Initiate.code());
            let (true, Some(ssap)) = (initiate, t.ssap) else {
                return Some((Plan::Status(ResponseStatus::Rs), None));
            };
            if (1..RELS).any(|r| self.in_flight(r)) {
                return None;
            }
            let mut same = None;
            let mut free = None;
            for i in 0..C2_CONNECTIONS {
                let v = self.staged_view(1 + i, now, until);
                if v.kind == K_CLOSED {
                    free = free.or(Some(i));
                } else if (v.master, v.ssap) == (t.sa, ssap) {
                    same = same.or(Some(i));
                }
            }
            return Some(match same.or(free) {
                Some(i) => (Plan::Rm(i as u8), Some((1 + i as u8, Some((t.sa, ssap))))),
                None => (Plan::Status(ResponseStatus::Rr), None),
            });
        }
        let i = conn_of(dsap)?;
        let r = 1 + i;
        let v = self.view(r, now, until);
        if v.kind == K_CLOSED || v.master != t.sa || t.ssap != Some(v.ssap) {
            return Some((Plan::Status(ResponseStatus::Rs), None));
        }
        let (i, r) = (i as u8, r as u8);
        let open = Some((r, Some((t.sa, v.ssap))));
        if t.pdu.first() == Some(&Function::Abort.code())
            && matches!(crate::dpv1::pdu::parse(t.pdu), Ok(crate::dpv1::pdu::Request::Abort(_)))
        {
            return Some((Plan::Sc, Some((r, None))));
        }
        // Every frame from the master restarts the connection's timer: in flight.
        Some(match v.kind {
            K_ABORTING => (Plan::Abort(i, v.reason), Some((r, None))),
            K_OPEN if poll && v.frame_len > 0 => (Plan::Ready(r, v.frame_len), open),
            _ => (Plan::Sc, open),
        })
    }

    /// A DP-V1 SRD (SAP 51, 49, a connection SAP): answered from the staging and queued, or
    /// left to the core (see the module docs). The decision and its answer prepared while
    /// the header arrived ([`Decided`]) are taken when they are still this telegram's.
    pub(super) fn dpv1(&mut self, at: Instant, len: usize, t: &DataTelegram<'_>) -> Dpv1 {
        let now = at.as_micros();
        let (plan, flight, built) = match self.dprep {
            Some(p) if p.sa == t.sa && Some(p.dsap) == t.dsap && now < p.until() => (p.plan, p.flight, Some(p.n)),
            _ => {
                let Some((plan, flight)) = self.plan(now, &mut { u64::MAX }, t) else { return Dpv1::Core };
                (plan, flight, None)
            }
        };
        let Some(()) = self.dpv1_commit(at, len, plan, flight) else { return Dpv1::QueueFull };
        let n = match built {
            Some(n) => n,
            None => self.build(plan, t),
        };
        Dpv1::Answer(n)
    }

    /// [`dpv1`](Self::dpv1) with the decision prepared while the header arrived, for a
    /// telegram that is the one it was made for ([`super::Lean`]): `None` when its timer has
    /// passed (the general decision plans again).
    pub(super) fn dpv1_prepared(&mut self, at: Instant, len: usize) -> Option<Dpv1> {
        let p = self.dprep.filter(|p| at.as_micros() < p.until())?;
        Some(match self.dpv1_commit(at, len, p.plan, p.flight) {
            Some(()) => Dpv1::Answer(p.n),
            None => Dpv1::QueueFull,
        })
    }

    /// The DP-V1 decision `plan` committed: the telegram queued (held for the core when the
    /// answer is SC), the relation it puts in flight noted. `None`: the queue is full.
    fn dpv1_commit(&mut self, at: Instant, len: usize, plan: Plan, flight: Flight) -> Option<()> {
        let held = matches!(plan, Plan::Sc);
        let seq = self.queue_as(at, len, false, held)?;
        if let Some((r, open)) = flight {
            self.rel[usize::from(r)] = RelLine { seq, set: true, open };
        }
        self.stats.dpv1 = self.stats.dpv1.wrapping_add(1);
        Some(())
    }

    /// The answer of `plan` to `t` into `bufs[w]`; its length.
    fn build(&mut self, plan: Plan, t: &DataTelegram<'_>) -> u16 {
        let own = self.st.address;
        match plan {
            Plan::Status(s) => self.status(t.sa, s),
            Plan::Sc => self.sc(),
            Plan::Ready(r, len) => {
                let len = usize::from(len).min(MAX_FRAME_LEN);
                self.staging.read(rel_at(usize::from(r)) + REL_HDR, &mut self.bufs[self.w][..len]);
                len as u16
            }
            Plan::Rm(i) => {
                let poll_timeout = self.staging.word(DPV1_AT / 4) as u16;
                let rm = Response::ResourceManager { server_sap: c2::HIGHEST_SAP - i, poll_timeout };
                self.pdu_frame(t, own, c2::RM_SAP, &rm)
            }
            Plan::Abort(i, reason) => {
                let a = Abort {
                    subnet: Subnet::None,
                    instance: Instance::MsacC2,
                    reason: AbortReason::from_bits(reason),
                    detail: Some(0),
                };
                self.pdu_frame(t, own, c2::HIGHEST_SAP - i, &Response::Abort(a))
            }
        }
    }

    /// While an SRD's header arrives (SA `sa` to `da` with FC `fc`, both SAPs, `first`: the
    /// first PDU octet, `None` for a poll): the DP-V1 decision and its answer, into
    /// `bufs[w]` and `dprep` — as [`plan`](Self::plan) at the earliest time,
    /// valid up to the relations' next timer ([`Decided`]). Nothing for another SAP, a frame
    /// the core answers, and a connection SAP's Abort PDU (its full parse decides).
    pub(super) fn prepare_dpv1(&mut self, sa: u8, da: u8, fc: u8, dsap: u8, ssap: u8, first: Option<u8>) {
        if dsap != c1::SAP && dsap != c2::RM_SAP && conn_of(dsap).is_none() {
            return;
        }
        if conn_of(dsap).is_some() && first == Some(Function::Abort.code()) {
            return;
        }
        let one = [first.unwrap_or(0)];
        let pdu = if first.is_some() { &one[..] } else { &[] };
        let t = DataTelegram {
            format: DataFormat::Sd2,
            da,
            sa,
            fc: FunctionCode(fc),
            dsap: Some(dsap),
            ssap: Some(ssap),
            pdu,
        };
        let mut until = u64::MAX;
        let Some((plan, flight)) = self.plan(0, &mut until, &t) else { return };
        let n = self.build(plan, &t);
        let until = [until as u32, (until >> 32) as u32];
        self.dprep = Some(Decided { until, plan, flight, n, sa, dsap });
    }

    /// A queued SDN (`seq`): the master's Abort PDU on its connection SAP closes the
    /// connection (unanswered), so the relation is in flight, closed.
    pub(super) fn dpv1_sdn(&mut self, now: Instant, seq: u32, t: &DataTelegram<'_>) {
        let Some(r) = t.dsap.and_then(conn_of).map(|i| 1 + i) else { return };
        let v = self.view(r, now.as_micros(), &mut { u64::MAX });
        let mine = v.kind != K_CLOSED && v.master == t.sa && t.ssap == Some(v.ssap);
        if mine && matches!(crate::dpv1::pdu::parse(t.pdu), Ok(crate::dpv1::pdu::Request::Abort(_))) {
            self.rel[r] = RelLine { seq, set: true, open: None };
        }
    }

    /// A 4-byte response PDU to `t` from `our_sap` in `buf` (as `C2::emit_scratch`).
    fn pdu_frame(&mut self, t: &DataTelegram<'_>, own: u8, our_sap: u8, resp: &Response<'_>) -> u16 {
        match c2::emit_short_response(&mut self.bufs[self.w], own, t, our_sap, resp) {
            Some(len) => len as u16,
            None => self.status(t.sa, ResponseStatus::Rr),
        }
    }
}

impl CoreLink<'_> {
    /// Stage the DP-V1 relations of `node` into the scratch and the back slot (part of
    /// [`CoreLink::publish`]).
    pub(super) fn stage_dpv1(&mut self, node: &Node) {
        self.staging.write(DPV1_AT / 4, &u32::from(node.c2().min_send_timeout()).to_le_bytes());
        let slave = node.slave();
        for r in 0..RELS {
            let (kind, master, ssap, reason, send_timeout, deadline, frame) = if r == 0 {
                let open = c1::C1::is_open(slave);
                let kind = if open { K_OPEN } else { K_CLOSED };
                let frame = node.c1().ready_frame().filter(|_| open);
                (kind, slave.master_address().unwrap_or(0xFF), c1::SAP, 0, 0, 0, frame)
            } else {
                let i = r - 1;
                let Some(c) = node.c2().connection(i) else { continue };
                let (kind, reason) = match c.state {
                    ConnectionState::Closed => (K_CLOSED, 0),
                    ConnectionState::Reserved => (K_RESERVED, 0),
                    ConnectionState::Open => (K_OPEN, 0),
                    ConnectionState::Aborting(why) => (K_ABORTING, why.bits()),
                };
                let deadline = node.c2().deadline(i).map_or(0, Instant::as_micros);
                (kind, c.master, c.master_sap, reason, c.send_timeout, deadline, node.c2().ready_frame(i))
            };
            let at = rel_at(r);
            let frame = frame.unwrap_or(&[]);
            let n = frame.len().min(MAX_FRAME_LEN);
            let mut h = [0u8; REL_HDR];
            h[0..4].copy_from_slice(&[kind, master, ssap, reason]);
            h[4..6].copy_from_slice(&(n as u16).to_le_bytes());
            h[6..8].copy_from_slice(&send_timeout.to_le_bytes());
            h[8..16].copy_from_slice(&deadline.to_le_bytes());
            self.staging.write(at / 4, &h);
            self.staging.write((at + REL_HDR) / 4, &frame[..n]);
        }
    }
}
