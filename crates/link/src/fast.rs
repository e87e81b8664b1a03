//! The ASIC-style response path (issue 11 item 1): a [`FastPath`] that answers at the line
//! interrupt from frames the protocol core staged, and a [`CoreLink`] that runs the
//! [`Node`] behind it in a lower-priority task — the split of the SPC3 / VPC3+ ASICs, where
//! the chip answers at once from buffers the firmware prepared and the firmware judges
//! Set_Prm / Chk_Cfg afterwards.
//!
//! ```text
//!  line interrupt (top priority)                      core task (lower priority)
//!  ┌───────────────────────────┐  telegrams (spsc)   ┌──────────────────────────────┐
//!  │ FastPath                  │ ──────────────────▶ │ CoreLink                     │
//!  │  DA filter before a copy  │  seq, arrival time  │  Node::on_frame (FDL, DP,    │
//!  │  station filters, FCB     │                     │  DP-V1), Node::poll,         │
//!  │  answers from staging     │  deferred answers   │  Application through Node    │
//!  │                           │ ◀────────────────── │                              │
//!  │  reads  ◀── staging  ─────┼── triple buffer ────┼── writes (after every step)  │
//!  │  (outputs travel in the   │                     │  applies the outputs from    │
//!  │   queued Data_Exchange)   │                     │  the queued telegram         │
//!  └───────────────────────────┘                     └──────────────────────────────┘
//! ```
//!
//! **Joined only by two [`heapless::spsc`] queues and one [`TripleBuffer`]** of
//! [`AtomicU32`] words: no lock, no critical section, no `unsafe`. A triple buffer has one
//! writer and one reader; each owns one slot, the third is in the middle, and a publication
//! is one atomic swap of the middle index (the reader takes the middle with one swap too),
//! so the line always reads one complete staging — the old or the new, never half.
//!
//! **Every telegram addressed to the station** (DA = own address or broadcast, after the
//! filters of [`crate::fdl::station`]: SA 127, SA = own address, FC bit 7 → dropped and
//! counted, nothing queued) **is queued to the core in arrival order**, except FDL_Status
//! (answered by the line, no state) and frames the station ignores (responses, reserved
//! codes). The core therefore runs exactly the telegram sequence a core-alone card runs and
//! its state — one-shot diagnosis bits consumed by a diagnosis read, Prm_Fault / Cfg_Fault,
//! Not_Supported, the FCB memory, the watchdog — is the same; the line only *predicts* the
//! answer from the staging. The core republishes the staging after every step that can
//! change a staged answer ([`CoreLink::step`], [`CoreLink::poll`], [`CoreLink::publish`]
//! after the application changed the node).
//!
//! **What the line answers** (from the staging: state, locking master, image lengths, the
//! staged Data_Exchange and diagnosis frames, Real_Cfg, the outputs read-back):
//! Data_Exchange (DL / DH while new diagnosis is staged; RS for wrong state, master or
//! length; zero-length outputs answered as today, the core enters fail-safe Clear), Slave_Diag,
//! FDL_Status, Get_Cfg, Rd_Inp / Rd_Outp, Set_Prm / Chk_Cfg (SC at once), Set_Slave_Add (SC,
//! or RS when the staging shows it cannot be taken: wrong ident, frozen address, not
//! Wait_Prm), SDN (Global_Control) and broadcasts (queued, never answered), SDA / MSRD /
//! Ident / LSAP status (RS), and FCB/FCV retries byte for byte from its own stored last answer.
//!
//! **DP-V1 on the line** (`fast/dpv1.rs`): MSAC_C1 (SAP 51), the MSAC_C2 resource manager (SAP
//! 49) and the connection SAPs are answered from the staged relations (open or not, for
//! which master and SAPs, timers, the ready response frame; the RM's Poll_Timeout): a request
//! PDU → SC, a poll → the staged response or SC, an Initiate.req on SAP 49 → the RM PDU
//! naming the connection the core will reserve (or RR), refusals → RS, a slave-side abort →
//! the Abort PDU. A poll the line answered SC is queued with [`Queued::held`], and the core
//! hands out nothing on it ([`Node::on_frame_as`]): a response finished meanwhile stays
//! for the next poll — never lost, never delivered twice except as an FCB retry.
//!
//! **What still goes through the core**: [`Verdict::Core`] — the line waits for the core's
//! answer ([`FastPath::take_deferred`]), as the card did before the split — for SAP 51 in the
//! not-ready window (a queued Set_Prm / Chk_Cfg decides whether MSAC_C1 is open at all), for
//! an Initiate.req on SAP 49 while another MSAC_C2 frame is in flight (which connection the
//! RM names depends on states the line cannot see yet), and for any other SAP (the DP
//! slave's RS) or SAP combination the line does not stage. A retry of such a request also
//! goes to the core, whose station resends its stored answer.
//!
//! **DP-V1 "not ready yet"**: a relation with a queued frame the core has not judged yet is
//! *in flight*; the line answers further polls on it SC although the core alone (having run
//! the request at once) might already hand out the response — likewise a poll answered SC
//! because the core's newer staging (after `Node::process_acyclic`) was not published yet.
//! The response goes out on a later poll (`split_answers_equal_the_core` in `pbcard::fast::check`'s lag mode:
//! the next poll must deliver exactly the core alone's response). Timers are foreseen from
//! the staged deadlines; a core more than a Send_Timeout (≥ 1 s) behind the line is not.

//! **The not-ready window**: from a queued Set_Prm or Chk_Cfg until the core has judged it
//! (the staging carries the sequence number of the last telegram the core worked on), the
//! line answers Slave_Diag with the staged diagnosis and Station_Not_Ready (octet 1 bit 1)
//! set — never a stale "ready for data exchange" — and Data_Exchange, Rd_Inp, Rd_Outp with
//! RS (not ready yet; no outputs taken by the line). Outside the window the line's answer is
//! the core's answer byte for byte when the core has caught up; `split_answers_equal_the_core`
//! (`pbcard`'s `link_tests`) and the `fast_path` fuzz target check it (`pbcard::fast::check`, built
//! for pbcard's tests and its `test-support` feature).
//!
//! A Slave_Diag of the locking master that the line answered while new diagnosis was staged
//! also marks the staged DH as consumed until the core has worked on that read, so a
//! following Data_Exchange answers DL as the core alone would.
//!
//! **Streaming receive** (issue 11, [`crate::phy::stream::TelegramSink`]): the
//! physical layer hands a telegram's bytes to the fast path while they arrive (`begin`,
//! `bytes` in pieces of any size, `abort`) and asks for the decision with
//! [`FastPath::finish`] right after the last one. What grows with the telegram's length — the
//! destination filter, the FCS, the retry fingerprint, the copy into the core's queue slot,
//! the likely answer (the staged Data_Exchange response or diagnosis patched for this master,
//! or the DP-V1 decision with its answer: `dpv1`'s "Decided at the header") — is done per
//! piece; `finish` checks length, FCS, ED, state, window and retry and commits
//! in a time that does not grow with the length. [`FastPath::on_frame`] is `begin`, `bytes`
//! and `finish` of a whole telegram (`any_chunking_equals_on_frame`: every chunking gives its
//! verdicts). The line decides on the staging it had at `begin` (refreshed there once).

mod dpv1;
mod tick;

pub use dpv1::C2_CONNECTIONS;

pub use tick::{tick, CardApp};

use core::sync::atomic::{AtomicU32, Ordering};

use heapless::spsc::{Consumer, Producer, Queue};

use crate::dp::diag::{Status1, MAX_DIAG_DATA_LEN};
use crate::dp::slave_add::SetSlaveAdd;
use crate::dp::{sap, DpState, Events, SlaveConfig, MAX_OUTPUT_LEN};
use crate::fdl::telegram::{
    self, Decoded, FunctionCode, Header, RequestFunction, ResponseStatus, Telegram, MAX_FRAME_LEN,
};
use crate::node::Node;
use crate::phy::stream::TelegramSink;
use crate::time::Instant;

/// A triple buffer of `W` words (one writer, one reader), built from atomics only.
///
/// Slot ownership: the writer owns one slot (its back buffer), the reader one (its front
/// buffer), and the `middle` word names the third, with bit `FRESH` when the writer
/// published into it since the reader last took it. Publishing and taking are one
/// `swap` each, so the reader always holds a slot the writer completed and will not touch.
pub struct TripleBuffer<const W: usize> {
    slots: [[AtomicU32; W]; 3],
    middle: AtomicU32,
}

const FRESH: u32 = 1 << 2;
const INDEX: u32 = 3;

impl<const W: usize> Default for TripleBuffer<W> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const W: usize> TripleBuffer<W> {
    /// All slots zero; the middle is slot 0, the writer starts on slot 1, the reader on
    /// slot 2. Every word of a new buffer is zero, so a `static` of it (or of a
    /// [`Shared`]) is in `.bss`: no flash image, no start-up copy (issue 13 item 1).
    pub const fn new() -> Self {
        TripleBuffer { slots: [const { [const { AtomicU32::new(0) }; W] }; 3], middle: AtomicU32::new(0) }
    }

    /// The writing and the reading half, from the start layout (the middle slot 0, nothing
    /// fresh) whatever an earlier pair left, so the three indices are distinct.
    fn halves(&mut self) -> (TripleWriter<'_, W>, TripleReader<'_, W>) {
        *self.middle.get_mut() = 0;
        let tb = &*self;
        (TripleWriter { tb, back: 1 }, TripleReader { tb, front: 2 })
    }
}

/// The writing half of a [`TripleBuffer`].
pub struct TripleWriter<'a, const W: usize> {
    tb: &'a TripleBuffer<W>,
    back: u32,
}

impl<const W: usize> TripleWriter<'_, W> {
    /// Store `bytes` (little-endian packed) from word `at` on in the back slot.
    fn write(&mut self, at: usize, bytes: &[u8]) {
        let slot = &self.tb.slots[self.back as usize];
        store_words(slot.get(at..).unwrap_or(&[]), bytes);
    }

    /// Make the back slot the newest: one atomic swap.
    fn publish(&mut self) {
        let old = self.tb.middle.swap(self.back | FRESH, Ordering::AcqRel);
        self.back = old & INDEX;
    }
}

/// The reading half of a [`TripleBuffer`].
pub struct TripleReader<'a, const W: usize> {
    tb: &'a TripleBuffer<W>,
    front: u32,
}

impl<const W: usize> TripleReader<'_, W> {
    /// Take the newest publication, if there is one since the last call (one atomic swap).
    fn refresh(&mut self) -> bool {
        if self.tb.middle.load(Ordering::Acquire) & FRESH == 0 {
            return false;
        }
        let old = self.tb.middle.swap(self.front, Ordering::AcqRel);
        self.front = old & INDEX;
        true
    }

    fn word(&self, i: usize) -> u32 {
        self.tb.slots[self.front as usize].get(i).map_or(0, |w| w.load(Ordering::Relaxed))
    }

    /// Copy `dst.len()` bytes starting at byte `at` (a multiple of 4) of the front slot.
    fn read(&self, at: usize, dst: &mut [u8]) {
        let slot = &self.tb.slots[self.front as usize];
        load_words(slot.get(at / 4..).unwrap_or(&[]), dst);
    }
}

/// Store `bytes` little-endian packed into `words` (as many as there are).
fn store_words(words: &[AtomicU32], bytes: &[u8]) {
    let mut chunks = bytes.chunks_exact(4);
    let mut words = words.iter();
    for (c, w) in (&mut chunks).zip(&mut words) {
        w.store(u32::from_le_bytes([c[0], c[1], c[2], c[3]]), Ordering::Relaxed);
    }
    let rem = chunks.remainder();
    if let (false, Some(w)) = (rem.is_empty(), words.next()) {
        // 1 – 3 bytes, shifted in (no library copy for a partial word).
        let v = rem.iter().rev().fold(0u32, |v, &b| v << 8 | u32::from(b));
        w.store(v, Ordering::Relaxed);
    }
}

/// Load `dst.len()` bytes from `words` (zeros past their end).
fn load_words(words: &[AtomicU32], dst: &mut [u8]) {
    // The whole words first (no "past the end?" test per word), then the rest: the partial
    // last word (< 4 bytes), or zeros when the words ran out (a read past the slot's end).
    let n = (dst.len() / 4).min(words.len());
    let (head, tail) = dst.split_at_mut(n * 4);
    for (c, w) in head.chunks_exact_mut(4).zip(words) {
        c.copy_from_slice(&w.load(Ordering::Relaxed).to_le_bytes());
    }
    let w = words.get(n).map_or(0, |w| w.load(Ordering::Relaxed)).to_le_bytes();
    if tail.len() < 4 {
        for (d, s) in tail.iter_mut().zip(w) {
            *d = s;
        }
    } else {
        tail.fill(0);
    }
}

const fn round4(n: usize) -> usize {
    n.div_ceil(4) * 4
}

// Staging layout (bytes; every section starts on a word).
const ST_SEQ: usize = 0;
const ST_EPOCH: usize = 1;
/// Word 2: address, state, master (0xFF none), flags.
const ST_ID: usize = 2;
/// Word 3: input length, output length, Real_Cfg module index, diagnosis frame length.
const ST_LENS: usize = 3;
/// Word 4: Data_Exchange frame length (u16), min_TSDR in bit times (u16, upper half).
const ST_DXLEN: usize = 4;
const DX_AT: usize = 20;
/// The staged Slave_Diag frame: an SD2 frame of up to the DP slave's
/// [`MAX_DIAG_DATA_LEN`] octets (any product's `Max_Diag_Data_Len`, [`SlaveConfig::fits`]).
const DIAG_ROOM: usize = round4(MAX_DIAG_DATA_LEN + 11);
const DIAG_AT: usize = DX_AT + round4(MAX_FRAME_LEN);
const OUT_AT: usize = DIAG_AT + DIAG_ROOM;
/// The outputs read-back (Rd_Outp): up to the DP slave's [`MAX_OUTPUT_LEN`] octets (any
/// product's `Max_Output_Len`).
const OUT_ROOM: usize = round4(MAX_OUTPUT_LEN);
/// The DP-V1 relations ([`dpv1`]).
const DPV1_AT: usize = OUT_AT + OUT_ROOM;
const STAGE_BYTES: usize = DPV1_AT + dpv1::DPV1_BYTES;
/// Words of one staging.
pub const STAGE_WORDS: usize = STAGE_BYTES / 4;

const FLAG_DIAG_NEW: u8 = 1 << 0;
const FLAG_NO_ADD_CHG: u8 = 1 << 1;

/// Line → core queue depth (one slot of the ring stays free: `QUEUE_LEN - 1` = 5 telegrams;
/// the core task runs right after the line at the next priority, so it is at most a telegram
/// or two behind — six slots of 256 bytes keep the card-only build within its 32 KiB RAM).
pub const QUEUE_LEN: usize = 6;
/// Core → line queue depth (deferred answers).
pub const DEFERRED_LEN: usize = 2;

/// A telegram the line handed to the core: its bytes are in the slot `seq % QUEUE_LEN` of
/// [`Shared`], written (word by word, only its length) before the entry is queued; the core
/// copies them out before it dequeues the entry, so a slot is never written while read (the
/// ring holds at most `QUEUE_LEN - 1` entries).
#[derive(Debug, Clone, Copy)]
pub struct Queued {
    /// Sequence number (the line's count of queued telegrams).
    pub seq: u32,
    /// When the telegram was complete.
    pub at: Instant,
    /// The line did not answer: the core's answer goes back through the core → line queue.
    pub deferred: bool,
    /// The line answered this DP-V1 request or poll with SC: the core hands out no response
    /// on it ([`Node::on_frame_as`]), a ready one stays for the next poll.
    pub held: bool,
    len: u16,
}

/// Words of one telegram slot.
const SLOT_WORDS: usize = round4(MAX_FRAME_LEN) / 4;

type Slots = [[AtomicU32; SLOT_WORDS]; QUEUE_LEN];

fn slot_of(seq: u32) -> usize {
    seq as usize % QUEUE_LEN
}

/// The core's answer to a deferred request (`len` 0: no answer).
#[derive(Debug, Clone)]
pub struct Deferred {
    seq: u32,
    len: u16,
    bytes: [u8; MAX_FRAME_LEN],
}

/// What both halves share: the two queues and the staging's triple buffer. Put it in a `static`
/// place (RTIC `init` local) and [`split`](Self::split) it once.
pub struct Shared {
    to_core: Queue<Queued, QUEUE_LEN>,
    slots: Slots,
    to_line: Queue<Deferred, DEFERRED_LEN>,
    staging: TripleBuffer<STAGE_WORDS>,
    /// The line's copy of the telegram being received ([`TelegramSink`]).
    rx: [u8; MAX_FRAME_LEN],
}

impl Default for Shared {
    fn default() -> Self {
        Self::new()
    }
}

impl Shared {
    /// Empty queues, zero buffers.
    pub const fn new() -> Self {
        Shared {
            to_core: Queue::new(),
            slots: [const { [const { AtomicU32::new(0) }; SLOT_WORDS] }; QUEUE_LEN],
            to_line: Queue::new(),
            staging: TripleBuffer::new(),
            rx: [0; MAX_FRAME_LEN],
        }
    }

    /// The line half and the core half. The core half publishes the first staging from
    /// `node` at once, so the line answers from the node's state from the first telegram on.
    /// The line keeps the node's product configuration ([`crate::dp::DpSlave::config`]: the
    /// modules Get_Cfg answers from, the ident number Set_Slave_Add checks), which a node
    /// never changes.
    pub fn split<'a>(&'a mut self, node: &mut Node) -> (FastPath<'a>, CoreLink<'a>) {
        let config = node.slave().config();
        let Shared { to_core, slots, to_line, staging, rx } = self;
        let slots: &Slots = slots;
        let (qp, qc) = to_core.split();
        let (dp, dc) = to_line.split();
        let (sw, sr) = staging.halves();
        let mut core = CoreLink {
            from_line: qc,
            slots,
            frame: [0; MAX_FRAME_LEN],
            to_line: dp,
            staging: sw,
            done_seq: 0,
            epoch: 0,
            answer: [0; MAX_FRAME_LEN],
            stats: CoreStats::default(),
        };
        core.publish(node);
        let mut fast = FastPath {
            to_core: qp,
            slots,
            from_core: dc,
            staging: sr,
            config,
            st: Staged { address: config.default_address, ..Staged::EMPTY },
            seq: 0,
            judge_seq: 0,
            diag_consumed: None,
            rel: [dpv1::RelLine::IDLE; dpv1::RELS],
            last: None,
            bufs: [[0; MAX_FRAME_LEN]; 2],
            w: 0,
            rxb: &mut rx[..],
            rx: Rx::IDLE,
            prep: None,
            dprep: None,
            lean: None,
            given: Out::Silent,
            sd1: [0; 6],
            deferred: [0; MAX_FRAME_LEN],
            stats: FastStats::default(),
        };
        fast.refresh();
        (fast, core)
    }
}

/// The line's decision on one telegram.
#[derive(Debug, PartialEq, Eq)]
pub enum Verdict<'a> {
    /// No answer (another station, a broadcast, SDN, a filtered or ignored frame, queue full).
    Silent,
    /// These bytes go on the wire after min_TSDR.
    Answer(&'a [u8]),
    /// The core answers (DP-V1 and other SAPs the line does not stage): run the core, then
    /// [`FastPath::take_deferred`].
    Core,
}

/// Counters of the line half.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct FastStats {
    /// Frames for other stations, tokens, SC: dropped by DA before any copy.
    pub others: u32,
    /// Frames that failed to decode (or carried trailing bytes).
    pub invalid: u32,
    /// Requests from SA 127 or from the own address ([`crate::fdl::station::StationStats::bad_source`]).
    pub bad_source: u32,
    /// Frames with FC bit 7 set ([`crate::fdl::station::StationStats::reserved_fc`]).
    pub reserved_fc: u32,
    /// Frames to us the station ignores (responses, reserved codes, broadcast SRD).
    pub ignored: u32,
    /// Telegrams queued for the core.
    pub queued: u32,
    /// Telegrams dropped because the core queue was full (unanswered; the master retries).
    pub queue_full: u32,
    /// Answers the line gave itself.
    pub answered: u32,
    /// FCB retries answered from the stored answer.
    pub retries: u32,
    /// Requests left to the core ([`Verdict::Core`]).
    pub deferred: u32,
    /// Slave_Diag answered in the not-ready window.
    pub not_ready_diag: u32,
    /// DP-V1 frames (SAP 51, 49, connection SAPs) answered from the staging.
    pub dpv1: u32,
}

/// Counters of the core half.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct CoreStats {
    /// Telegrams worked on.
    pub steps: u32,
    /// Stagings published.
    pub publications: u32,
    /// Deferred answers the core → line queue had no room for.
    pub deferred_lost: u32,
}

/// The staging as the line decoded it (header words only; frames stay in the slot).
#[derive(Debug, Clone, Copy)]
struct Staged {
    done_seq: u32,
    epoch: u32,
    address: u8,
    state: u8,
    master: u8,
    flags: u8,
    in_len: u8,
    out_len: u8,
    module: u8,
    diag_len: u8,
    dx_len: u16,
    /// min_TSDR in force (bit times).
    min_tsdr: u16,
}

impl Staged {
    const EMPTY: Staged = Staged {
        done_seq: 0,
        epoch: 0,
        address: 0,
        state: 0,
        master: 0xFF,
        flags: 0,
        in_len: 0,
        out_len: 0,
        module: 0,
        diag_len: 0,
        dx_len: 0,
        min_tsdr: crate::time::BitTimes::MIN_TSDR_DEFAULT.0 as u16,
    };
    fn state(&self) -> DpState {
        match self.state {
            2 => DpState::DataExch,
            1 => DpState::WaitCfg,
            _ => DpState::WaitPrm,
        }
    }
    fn master(&self) -> Option<u8> {
        (self.master != 0xFF).then_some(self.master)
    }
}

fn state_code(s: DpState) -> u8 {
    match s {
        DpState::WaitPrm => 0,
        DpState::WaitCfg => 1,
        DpState::DataExch => 2,
    }
}

/// What the line stored for FCB retries (as [`crate::fdl::station`] does).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Last {
    sa: u8,
    fcb: bool,
    /// The request's [`fingerprint`].
    request: u32,
    own: u8,
    epoch: u32,
    /// `Some(n)`: the first `n` bytes of `buf` (0 = no answer); `None`: the core answered.
    answer: Option<u16>,
}

/// The station's retry fingerprint of a request — DSAP, SSAP, PDU length and the PDU's sum —
/// in one word: the SAPs are 6-bit values (0xFF for none) and a PDU is shorter than 256
/// octets, so two fingerprints are equal exactly when the four values are.
fn fingerprint(dsap: Option<u8>, ssap: Option<u8>, pdu_len: usize, sum: u8) -> u32 {
    u32::from_le_bytes([dsap.unwrap_or(0xFF), ssap.unwrap_or(0xFF), pdu_len as u8, sum])
}

/// `telegram::fcs` of the last `pdu_len` bytes before the FCS of a decoded (checksum-verified)
/// data frame, from its own FCS byte: the FCS minus the header bytes it covers (DA, SA, FC,
/// DAE, SAE) — the station's retry fingerprint without a pass over the PDU.
fn pdu_sum(frame: &[u8], pdu_len: usize) -> u8 {
    let n = frame.len();
    let start = if frame.first() == Some(&telegram::SD2) { 4 } else { 1 };
    let end = n.saturating_sub(2 + pdu_len).max(start);
    let fcs = frame.get(n.wrapping_sub(2)).copied().unwrap_or(0);
    fcs.wrapping_sub(telegram::fcs(frame.get(start..end).unwrap_or(&[])))
}

/// The SD1 frame without SAPs and PDU `[SD1, da, sa, fc, FCS, ED]` into `out` — what
/// [`telegram::emit`] lays out for that header (`header_sd1_equals_emit`), written directly:
/// every status answer of the line (FDL_Status, RS, RR, DH without inputs). Its length (6).
fn sd1_status(out: &mut [u8], da: u8, sa: u8, s: ResponseStatus) -> u16 {
    let fc = FunctionCode::response(s).0;
    if let Some(o) = out.get_mut(..6) {
        o.copy_from_slice(&[telegram::SD1, da, sa, fc, da.wrapping_add(sa).wrapping_add(fc), telegram::ED]);
        6
    } else {
        0
    }
}

/// How far the line got with the telegram being received ([`TelegramSink`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum RxState {
    /// No telegram begun (or it was finished / aborted).
    Idle,
    /// Begun, the destination address not in yet.
    Open,
    /// For another station (or no data frame): the rest is not looked at.
    Foreign,
    /// For this station (or broadcast), header valid so far: collected, summed, stored.
    Own,
    /// For this station but no telegram (a bad SD2 header, longer than its header says).
    Bad,
}

/// The telegram being received: what the line worked out while its bytes arrived.
#[derive(Debug, Clone, Copy)]
struct Rx {
    state: RxState,
    /// The station address at `begin` (the staging the decision uses).
    own: u8,
    /// Bytes so far (also those past the buffer).
    len: usize,
    /// The frame length the header announces (from the DA on).
    expect: usize,
    /// Where the bytes the FCS covers start ([`telegram::covered_start`]).
    start: usize,
    /// FCS of the covered bytes so far.
    sum: u8,
    /// Whole words stored into the core's slot so far.
    words: usize,
    /// The header (DA, SA, FC, DAE, SAE) was looked at for an answer to prepare.
    header_seen: bool,
    /// Once `header_seen`: [`telegram::fcs`] of the header bytes (DA, SA, FC, DAE, SAE), so
    /// that the retry fingerprint's PDU sum is the FCS byte minus this ([`pdu_sum`]).
    hsum: u8,
    /// The core's queue slot the bytes go to: that of sequence number `seq + 1`.
    slot: usize,
}

impl Rx {
    const IDLE: Rx = Rx {
        state: RxState::Idle,
        own: 0,
        len: 0,
        expect: 0,
        start: 1,
        sum: 0,
        words: 0,
        header_seen: false,
        hsum: 0,
        slot: 0,
    };
}

/// The arguments of a staged frame copied and patched into the answer buffer
/// ([`FastPath::patched`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Prep {
    at: usize,
    len: usize,
    da: u8,
    fc: u8,
    dsap: Option<u8>,
    status1: u8,
}

/// The whole decision on a request, made once its header was in ([`FastPath::prepare`]):
/// what [`FastPath::decide`] would conclude for these header bytes, this staging and this
/// retry memory — none of which changes while the rest of the telegram arrives —, so that
/// `finish` only checks the checksum and the end delimiter and commits it
/// ([`FastPath::decide_prepared`]; issue 11, the work left after the last byte). Made only
/// where the PDU cannot change the decision — every staged service but Set_Slave_Add (whose
/// PDU is judged): Data_Exchange and Slave_Diag ([`Prep`]), Set_Prm / Chk_Cfg (SC), Get_Cfg,
/// Rd_Inp / Rd_Outp and the status answers, built into `bufs[w]` with the header; and the
/// prepared DP-V1 decisions (`dpv1::Decided`, taken before its timer) — never for a request
/// that could be an FCB retry of the last one (its PDU decides), and never for a telegram
/// whose header arrived with its last byte (a DMA piece that holds the whole request: the
/// general decision is as fast then). The property `any_chunking_equals_on_frame` compares
/// it with the general decision of [`FastPath::on_frame`] in every chunking, and
/// `lean_dpv1_equals_on_frame` (`pbcard`'s `link_tests::fast_lean`) across the MSAC_C2 connections' timers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Lean {
    sa: u8,
    fc: u8,
    dsap: Option<u8>,
    ssap: Option<u8>,
    /// The PDU's length (the retry fingerprint).
    pdu_len: u8,
    what: LeanWhat,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum LeanWhat {
    /// A staged service's answer (`answer_srd`'s), `n` bytes already in `bufs[w]`: the
    /// prepared Data_Exchange or Slave_Diag frame ([`Prep`]), an SC, a status frame, Get_Cfg,
    /// Rd_Inp / Rd_Outp. `judge`: a Set_Prm / Chk_Cfg (it opens the not-ready window);
    /// `not_ready`: a Slave_Diag answered with Station_Not_Ready; `consume`: a Slave_Diag of
    /// the locking master that reads the staged DH.
    Staged { n: u16, judge: bool, not_ready: bool, consume: bool },
    /// The prepared DP-V1 decision (`dprep`).
    Dpv1,
}

/// Where a decision's answer is.
#[derive(Debug, Clone, Copy)]
enum Out {
    Silent,
    Core,
    /// `sd1[..n]`.
    Sd1(u16),
    /// `bufs[w ^ 1][..n]` (the stored answer).
    Stored(u16),
}

/// `a` is after `b` (sequence numbers, wrapping).
fn after(a: u32, b: u32) -> bool {
    (a.wrapping_sub(b) as i32) > 0
}

/// The line half: call [`on_frame`](Self::on_frame) at the line interrupt for every
/// telegram the receiver delimited.
pub struct FastPath<'a> {
    to_core: Producer<'a, Queued>,
    slots: &'a Slots,
    from_core: Consumer<'a, Deferred>,
    staging: TripleReader<'a, STAGE_WORDS>,
    /// The node's product configuration (Get_Cfg's modules, Set_Slave_Add's ident number).
    config: &'static SlaveConfig,
    st: Staged,
    seq: u32,
    /// Sequence number of the last queued Set_Prm / Chk_Cfg (the not-ready window).
    judge_seq: u32,
    /// The line answered the locking master's Slave_Diag while DH was staged (that read's
    /// sequence number): DH counts as consumed until the core worked on it.
    diag_consumed: Option<u32>,
    /// The DP-V1 relations' frames in flight ([`dpv1`]).
    rel: [dpv1::RelLine; dpv1::RELS],
    last: Option<Last>,
    /// Two answer buffers: `bufs[w]` is written (a new answer, or the one prepared while the
    /// request arrives), `bufs[w ^ 1]` holds the last answer given (what an FCB retry
    /// repeats). A new answer flips `w`.
    bufs: [[u8; MAX_FRAME_LEN]; 2],
    w: usize,
    /// The telegram being received (its bytes, [`Shared`]'s buffer) and what is known of it.
    rxb: &'a mut [u8],
    rx: Rx,
    /// The answer prepared into `bufs[w]` once the header was in: the arguments of
    /// [`FastPath::patched`] it was made with.
    prep: Option<Prep>,
    /// Or the DP-V1 decision whose answer was prepared into `bufs[w]` ([`dpv1`]).
    dprep: Option<dpv1::Decided>,
    /// The whole decision, when the prepared answer is certain to be it ([`Lean`]).
    lean: Option<Lean>,
    /// Where the last answer given is ([`FastPath::answer_given`]).
    given: Out,
    sd1: [u8; 6],
    deferred: [u8; MAX_FRAME_LEN],
    stats: FastStats,
}

const SC_FRAME: [u8; 1] = [telegram::SC];

impl core::fmt::Debug for FastPath<'_> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("FastPath").field("seq", &self.seq).field("stats", &self.stats).finish_non_exhaustive()
    }
}

impl core::fmt::Debug for CoreLink<'_> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("CoreLink").field("done_seq", &self.done_seq).field("stats", &self.stats).finish_non_exhaustive()
    }
}

impl<'a> FastPath<'a> {
    /// Counters.
    pub fn stats(&self) -> FastStats {
        self.stats
    }

    /// The station address of the newest staging.
    pub fn address(&mut self) -> u8 {
        self.refresh();
        self.st.address
    }

    /// min_TSDR of the newest staging (the node's [`Node::min_tsdr`] as of its last step):
    /// the line's wait after a request's last stop bit before an answer it sends now.
    pub fn min_tsdr(&mut self) -> crate::time::BitTimes {
        self.refresh();
        crate::time::BitTimes(u32::from(self.st.min_tsdr))
    }

    /// Whether a queued Set_Prm / Chk_Cfg waits for the core (the not-ready window).
    pub fn in_window(&mut self) -> bool {
        self.refresh();
        after(self.judge_seq, self.st.done_seq)
    }

    /// Whether the core has worked on every telegram the line queued (its newest staging
    /// says so).
    pub fn core_idle(&mut self) -> bool {
        self.refresh();
        !after(self.seq, self.st.done_seq)
    }

    /// Whether the telegram being received ([`TelegramSink`]) is addressed to the station
    /// (own address or broadcast; `Some(false)`: another station's, not looked at further),
    /// `None` while its destination is not in yet or no telegram is in progress.
    pub fn receiving_for_us(&self) -> Option<bool> {
        match self.rx.state {
            RxState::Own | RxState::Bad => Some(true),
            RxState::Foreign => Some(false),
            RxState::Idle | RxState::Open => None,
        }
    }

    /// Free places in the line → core queue.
    pub fn queue_free(&self) -> usize {
        self.to_core.capacity() - self.to_core.len()
    }

    fn refresh(&mut self) {
        // While a telegram arrives the line keeps the staging it had at its begin: the answer
        // prepared from it must stay the one the decision gives.
        if self.rx.state != RxState::Idle || !self.staging.refresh() {
            return;
        }
        let id = self.staging.word(ST_ID).to_le_bytes();
        let lens = self.staging.word(ST_LENS).to_le_bytes();
        self.st = Staged {
            done_seq: self.staging.word(ST_SEQ),
            epoch: self.staging.word(ST_EPOCH),
            address: id[0],
            state: id[1],
            master: id[2],
            flags: id[3],
            in_len: lens[0],
            out_len: lens[1],
            module: lens[2],
            diag_len: lens[3],
            dx_len: self.staging.word(ST_DXLEN) as u16,
            min_tsdr: (self.staging.word(ST_DXLEN) >> 16) as u16,
        };
        if self.diag_consumed.is_some_and(|s| !after(s, self.st.done_seq)) {
            self.diag_consumed = None;
        }
        // The window's mark follows the core once it has judged: sequence numbers compare by
        // wrapping distance, so a mark left 2^31 telegrams behind would read as "after" again
        // and reopen the not-ready window (≈ 12 days of a 1 ms bus cycle).
        if !after(self.judge_seq, self.st.done_seq) {
            self.judge_seq = self.st.done_seq;
        }
    }

    /// The core's answer to the oldest deferred request: `Some(bytes)` (empty = no answer),
    /// `None` while the core has not answered yet.
    pub fn take_deferred(&mut self) -> Option<&[u8]> {
        let d = self.from_core.dequeue()?;
        let n = d.len as usize;
        self.deferred[..n].copy_from_slice(&d.bytes[..n]);
        let _ = d.seq;
        Some(&self.deferred[..n])
    }

    fn queue(&mut self, now: Instant, len: usize, deferred: bool) -> Option<u32> {
        self.queue_as(now, len, deferred, false)
    }

    /// Commit the telegram of `len` bytes received into slot `seq + 1` (written while its
    /// bytes arrived, [`TelegramSink::bytes`]) as the next queue entry.
    fn queue_as(&mut self, now: Instant, len: usize, deferred: bool, held: bool) -> Option<u32> {
        let seq = self.seq.wrapping_add(1);
        if !self.to_core.ready() {
            self.stats.queue_full = self.stats.queue_full.wrapping_add(1);
            return None;
        }
        // The queue's index update is a release: the core sees the slot written.
        match self.to_core.enqueue(Queued { seq, at: now, deferred, held, len: len as u16 }) {
            Ok(()) => {
                self.seq = seq;
                self.stats.queued = self.stats.queued.wrapping_add(1);
                Some(seq)
            }
            Err(_) => {
                self.stats.queue_full = self.stats.queue_full.wrapping_add(1);
                None
            }
        }
    }

    /// One complete telegram from the line, at `now`: the answer (see the module docs). The
    /// same as [`begin`](TelegramSink::begin), [`bytes`](TelegramSink::bytes) of the whole
    /// frame and [`finish`](Self::finish) — which is what it does.
    pub fn on_frame(&mut self, now: Instant, frame: &[u8]) -> Verdict<'_> {
        self.begin();
        self.bytes(frame);
        self.finish(now)
    }

    /// The decision on the telegram whose last byte just went through
    /// [`bytes`](TelegramSink::bytes), at `now` (its arrival time): the same as
    /// [`on_frame`](Self::on_frame) of the whole telegram, in a time that does not grow with
    /// its length — the destination filter, the checksum, the retry fingerprint, the copy into
    /// the core's queue slot and the likely answer were done while the bytes arrived; here
    /// the length, FCS, ED, state, window and retry are checked and the telegram committed.
    pub fn finish(&mut self, now: Instant) -> Verdict<'_> {
        let rx = self.rx;
        // Idle: nothing reads the other fields until the next `begin` sets them all.
        self.rx.state = RxState::Idle;
        let out = match rx.state {
            RxState::Own => {
                // The partial last word into the slot (the whole words went in as they came).
                let rxb = core::mem::take(&mut self.rxb);
                let frame = &rxb[..rx.len.min(rxb.len())];
                let whole = frame.len() / 4 * 4;
                if whole < frame.len() {
                    store_words(&self.slots[rx.slot][whole / 4..], &frame[whole..]);
                }
                let n = frame.len();
                let lean = match self.lean {
                    Some(l) if n == rx.expect && frame[n - 2] == rx.sum && frame[n - 1] == telegram::ED => {
                        self.decide_prepared(now, n, l, frame[n - 2].wrapping_sub(rx.hsum), rx.own)
                    }
                    _ => None,
                };
                let out = match lean {
                    Some(out) => out,
                    None => match telegram::decode_summed(frame, rx.sum) {
                        Decoded::Frame(Telegram::Data(t), n) if n == frame.len() => {
                            // The retry fingerprint's PDU sum: from the header's sum taken while
                            // it arrived, else (no header seen: not reached for a decoded frame)
                            // over the header bytes now.
                            let sum = match rx.header_seen {
                                true => frame.get(frame.len().wrapping_sub(2)).map_or(0, |f| f.wrapping_sub(rx.hsum)),
                                false => pdu_sum(frame, t.pdu.len()),
                            };
                            // Checked in every test above the line side too (`pbcard`'s
                            // `link_tests`, `fast::check`, the fuzz targets: `test-support`).
                            #[cfg(any(test, feature = "test-support"))]
                            assert_eq!(sum, pdu_sum(frame, t.pdu.len()), "{frame:02x?}");
                            self.decide(now, frame, &t, rx.own, sum)
                        }
                        _ => {
                            self.stats.invalid = self.stats.invalid.wrapping_add(1);
                            Out::Silent
                        }
                    },
                };
                self.rxb = rxb;
                out
            }
            RxState::Bad => {
                self.stats.invalid = self.stats.invalid.wrapping_add(1);
                Out::Silent
            }
            // Other stations' traffic, tokens, SC, no destination (yet): dropped by DA.
            RxState::Idle | RxState::Open | RxState::Foreign => {
                self.stats.others = self.stats.others.wrapping_add(1);
                Out::Silent
            }
        };
        self.prep = None;
        self.dprep = None;
        self.lean = None;
        match out {
            Out::Silent => Verdict::Silent,
            Out::Core => Verdict::Core,
            Out::Sd1(_) | Out::Stored(_) => {
                self.given = out;
                Verdict::Answer(self.answer_given())
            }
        }
    }

    /// The bytes of the line's last [`Verdict::Answer`], for a port that transmits straight
    /// from the fast path instead of copying the answer: they stay as they are until the
    /// next [`finish`](Self::finish) that answers (the answer prepared while a request
    /// arrives goes into the other buffer).
    pub fn answer_given(&self) -> &[u8] {
        match self.given {
            Out::Sd1(n) => &self.sd1[..usize::from(n).min(self.sd1.len())],
            Out::Stored(n) => &self.bufs[self.w ^ 1][..usize::from(n).min(MAX_FRAME_LEN)],
            Out::Silent | Out::Core => &[],
        }
    }

    /// The decision on the decoded telegram `t` (`frame`: its bytes, already in the core's
    /// queue slot) to the station `own`; `psum`: its PDU's sum for the retry fingerprint
    /// ([`pdu_sum`]).
    fn decide(&mut self, now: Instant, frame: &[u8], t: &telegram::DataTelegram<'_>, own: u8, psum: u8) -> Out {
        let t = *t;
        if self.last.is_some_and(|l| l.own != own || l.epoch != self.st.epoch) {
            self.last = None;
        }
        if t.fc.0 & 0x80 != 0 {
            self.stats.reserved_fc = self.stats.reserved_fc.wrapping_add(1);
            return Out::Silent;
        }
        if !t.fc.is_request() {
            self.stats.ignored = self.stats.ignored.wrapping_add(1);
            return Out::Silent;
        }
        if t.sa == telegram::BROADCAST || t.sa == own {
            self.stats.bad_source = self.stats.bad_source.wrapping_add(1);
            return Out::Silent;
        }
        let function = t.fc.function();
        let sdn = matches!(function, RequestFunction::SdnLow | RequestFunction::SdnHigh);
        if t.da == telegram::BROADCAST {
            if sdn {
                self.queue(now, frame.len(), false);
            } else {
                self.stats.ignored = self.stats.ignored.wrapping_add(1);
            }
            return Out::Silent;
        }
        let fingerprint = fingerprint(t.dsap, t.ssap, t.pdu.len(), psum);
        let answer: Option<u16> = match function {
            RequestFunction::FdlStatus => {
                let n = sd1_status(&mut self.sd1, t.sa, own, ResponseStatus::Ok);
                self.stats.answered = self.stats.answered.wrapping_add(1);
                return Out::Sd1(n);
            }
            RequestFunction::SdnLow | RequestFunction::SdnHigh => {
                if let Some(seq) = self.queue(now, frame.len(), false) {
                    self.dpv1_sdn(now, seq, &t);
                }
                return Out::Silent;
            }
            RequestFunction::SrdLow | RequestFunction::SrdHigh => {
                if let Some(last) = self.last {
                    if t.fc.fcv() && last.sa == t.sa && last.fcb == t.fc.fcb() && last.request == fingerprint {
                        // A retry: the core keeps its watchdog and FCB memory in step.
                        if self.queue(now, frame.len(), last.answer.is_none()).is_none() {
                            return Out::Silent;
                        }
                        self.stats.retries = self.stats.retries.wrapping_add(1);
                        return match last.answer {
                            None => {
                                self.stats.deferred = self.stats.deferred.wrapping_add(1);
                                Out::Core
                            }
                            Some(0) => Out::Silent,
                            Some(n) => Out::Stored(n),
                        };
                    }
                }
                let staged = match (t.dsap, t.ssap) {
                    (None, None) => true,
                    (Some(d), Some(_)) => matches!(
                        d,
                        sap::SLAVE_DIAG
                            | sap::SET_PRM
                            | sap::CHK_CFG
                            | sap::GET_CFG
                            | sap::RD_INP
                            | sap::RD_OUTP
                            | sap::SET_SLAVE_ADD
                    ),
                    _ => false,
                };
                if !staged {
                    match self.dpv1(now, frame.len(), &t) {
                        dpv1::Dpv1::Core => {}
                        dpv1::Dpv1::QueueFull => return Out::Silent,
                        dpv1::Dpv1::Answer(n) => return self.answered(t.sa, t.fc, fingerprint, own, n),
                    }
                }
                let Some(seq) = self.queue(now, frame.len(), !staged) else {
                    return Out::Silent;
                };
                if !staged {
                    None
                } else {
                    if matches!(t.dsap, Some(sap::SET_PRM) | Some(sap::CHK_CFG)) {
                        self.judge_seq = seq;
                    }
                    Some(self.answer_srd(seq, &t))
                }
            }
            RequestFunction::SdaLow
            | RequestFunction::SdaHigh
            | RequestFunction::Msrd
            | RequestFunction::Ident
            | RequestFunction::LsapStatus => {
                // RS, as the station; queued so the core's FCB memory stays the line's.
                if self.queue(now, frame.len(), false).is_none() {
                    return Out::Silent;
                }
                Some(self.status(t.sa, ResponseStatus::Rs))
            }
            RequestFunction::TimeEvent | RequestFunction::Other(_) => {
                self.stats.ignored = self.stats.ignored.wrapping_add(1);
                return Out::Silent;
            }
        };
        let last = Last { sa: t.sa, fcb: t.fc.fcb(), request: fingerprint, own, epoch: self.st.epoch, answer };
        self.last = if t.fc.fcv() || t.fc.fcb() { Some(last) } else { None };
        match answer {
            None => {
                self.stats.deferred = self.stats.deferred.wrapping_add(1);
                Out::Core
            }
            Some(0) => Out::Silent,
            Some(n) => {
                self.stats.answered = self.stats.answered.wrapping_add(1);
                // The new answer becomes the stored one (what a retry repeats).
                self.w ^= 1;
                Out::Stored(n)
            }
        }
    }

    /// The line answered the request from `sa` with function code `fc` (its fingerprint
    /// `request`) with `buf[..n]`: remember it for FCB retries, hand it out.
    fn answered(&mut self, sa: u8, fc: FunctionCode, request: u32, own: u8, n: u16) -> Out {
        let last = Last { sa, fcb: fc.fcb(), request, own, epoch: self.st.epoch, answer: Some(n) };
        self.last = if fc.fcv() || fc.fcb() { Some(last) } else { None };
        if n == 0 {
            return Out::Silent;
        }
        self.stats.answered = self.stats.answered.wrapping_add(1);
        self.w ^= 1;
        Out::Stored(n)
    }

    /// [`decide`](Self::decide) for a telegram whose whole decision was made with its header
    /// ([`Lean`]): its checksum and end delimiter are right (the caller checked them, and the
    /// length), so it is committed — queued, its answer remembered for a retry — without
    /// decoding it again. `None` where the prepared DP-V1 decision's timer has passed: the
    /// general decision then.
    fn decide_prepared(&mut self, now: Instant, len: usize, l: Lean, psum: u8, own: u8) -> Option<Out> {
        if self.last.is_some_and(|x| x.own != own || x.epoch != self.st.epoch) {
            self.last = None;
        }
        let fc = FunctionCode(l.fc);
        let fp = fingerprint(l.dsap, l.ssap, usize::from(l.pdu_len), psum);
        let n = match l.what {
            LeanWhat::Dpv1 => match self.dpv1_prepared(now, len)? {
                dpv1::Dpv1::Answer(n) => n,
                dpv1::Dpv1::QueueFull => return Some(Out::Silent),
                dpv1::Dpv1::Core => return None,
            },
            LeanWhat::Staged { n, judge, not_ready, consume } => {
                let Some(seq) = self.queue(now, len, false) else { return Some(Out::Silent) };
                if judge {
                    self.judge_seq = seq;
                }
                if not_ready {
                    self.stats.not_ready_diag = self.stats.not_ready_diag.wrapping_add(1);
                }
                if consume {
                    self.diag_consumed = Some(seq);
                }
                n
            }
        };
        Some(self.answered(l.sa, fc, fp, own, n))
    }

    /// An SD1 status answer to `da` in `buf`; its length.
    fn status(&mut self, da: u8, s: ResponseStatus) -> u16 {
        sd1_status(&mut self.bufs[self.w], da, self.st.address, s)
    }

    fn sc(&mut self) -> u16 {
        self.bufs[self.w][0] = SC_FRAME[0];
        1
    }

    /// Copy the staged frame at `at` (`len` bytes) into `buf` and patch DA, FC and the DSAP
    /// with the FCS kept right (as `DpSlave::patch`); `status1` ORs bits into the first PDU
    /// octet (the not-ready diagnosis).
    fn patched(&mut self, at: usize, len: usize, da: u8, fc: u8, dsap: Option<u8>, status1: u8) -> u16 {
        let key = Prep { at, len, da, fc, dsap, status1 };
        if self.prep == Some(key) {
            // Prepared into `bufs[w]` while the request arrived, from this staging.
            return len as u16;
        }
        self.patch_into_scratch(key)
    }

    /// [`patched`](Self::patched)'s copy and patch into `bufs[w]`.
    fn patch_into_scratch(&mut self, key: Prep) -> u16 {
        let Prep { at, len, da, fc, dsap, status1 } = key;
        if !(6..=MAX_FRAME_LEN).contains(&len) {
            return 0;
        }
        let buf = &mut self.bufs[self.w][..len];
        self.staging.read(at, buf);
        let h = if buf[0] == telegram::SD2 { 4 } else { 1 };
        let mut fcs = buf[len - 2];
        let mut edits = [(h, (buf[h] & 0x80) | da), (h + 2, fc), (usize::MAX, 0), (usize::MAX, 0)];
        if let Some(d) = dsap {
            edits[2] = (h + 3, d & 0x3F);
            if status1 != 0 && h + 5 < len - 2 {
                edits[3] = (h + 5, buf[h + 5] | status1);
            }
        }
        for (i, v) in edits {
            if i < len - 2 {
                fcs = fcs.wrapping_sub(buf[i]).wrapping_add(v);
                buf[i] = v;
            }
        }
        buf[len - 2] = fcs;
        len as u16
    }

    /// A response with the DU read from the staging at `at` (`n` bytes), addressed as the
    /// answer to `t` (Rd_Inp / Rd_Outp).
    fn misc_from_staging(&mut self, t: &telegram::DataTelegram<'_>, at: usize, n: usize) -> u16 {
        let hdr = Header::response_to(t, ResponseStatus::Dl);
        let Ok(len) = telegram::emit_header(&mut self.bufs[self.w], &hdr, n) else {
            return self.status(t.sa, ResponseStatus::Rs);
        };
        let r = telegram::pdu_range(len, n);
        // The staged PDU sits at a word boundary only for the outputs; read through a bounce.
        let mut tmp = [0u8; MAX_FRAME_LEN + 4];
        let skew = at % 4;
        self.staging.read(at - skew, &mut tmp[..n + skew]);
        let buf = &mut self.bufs[self.w];
        buf[r].copy_from_slice(&tmp[skew..skew + n]);
        telegram::finish(buf, len);
        len as u16
    }

    /// The answer to a non-retry SRD of a staged service (`seq`: its queue number).
    fn answer_srd(&mut self, seq: u32, t: &telegram::DataTelegram<'_>) -> u16 {
        let st = self.st;
        let window = after(self.judge_seq, st.done_seq);
        let dx = st.state() == DpState::DataExch;
        match t.dsap {
            None => {
                // Data_Exchange.
                if window || !dx || st.master() != Some(t.sa) {
                    return self.status(t.sa, ResponseStatus::Rs);
                }
                let n_out = usize::from(st.out_len);
                if !t.pdu.is_empty() && t.pdu.len() != n_out {
                    return self.status(t.sa, ResponseStatus::Rs);
                }
                let dh = st.flags & FLAG_DIAG_NEW != 0 && self.diag_consumed.is_none();
                let s = if dh { ResponseStatus::Dh } else { ResponseStatus::Dl };
                if st.in_len == 0 {
                    return if dh { self.status(t.sa, s) } else { self.sc() };
                }
                self.patched(DX_AT, usize::from(st.dx_len), t.sa, s as u8, None, 0)
            }
            Some(sap::SLAVE_DIAG) => {
                let not_ready = if window {
                    self.stats.not_ready_diag = self.stats.not_ready_diag.wrapping_add(1);
                    Status1::STATION_NOT_READY.bits()
                } else {
                    0
                };
                if st.master() == Some(t.sa) && st.flags & FLAG_DIAG_NEW != 0 {
                    self.diag_consumed = Some(seq);
                }
                let dsap = t.ssap.unwrap_or(62);
                self.patched(DIAG_AT, usize::from(st.diag_len), t.sa, ResponseStatus::Dl as u8, Some(dsap), not_ready)
            }
            Some(sap::SET_PRM) | Some(sap::CHK_CFG) => self.sc(),
            Some(sap::SET_SLAVE_ADD) => {
                let ok = SetSlaveAdd::parse(t.pdu, self.config.ident_number).is_ok()
                    && st.flags & FLAG_NO_ADD_CHG == 0
                    && st.state() == DpState::WaitPrm;
                if ok {
                    self.sc()
                } else {
                    self.status(t.sa, ResponseStatus::Rs)
                }
            }
            Some(sap::GET_CFG) => self.get_cfg(t),
            Some(sap::RD_INP) | Some(sap::RD_OUTP) => self.read_back(t),
            // Not reached: `staged` lists the services above.
            Some(_) => self.status(t.sa, ResponseStatus::Rs),
        }
    }

    /// Get_Cfg's answer: the Real_Cfg of the staged module (the staged index is one of the
    /// configuration's modules, 0 when the slave's Real_Cfg is none of them). Out of line: one
    /// copy for `answer_srd` and `prepare` (a rare request).
    #[inline(never)]
    fn get_cfg(&mut self, t: &telegram::DataTelegram<'_>) -> u16 {
        let cfg = self.config.modules.get(usize::from(self.st.module)).map_or(&[][..], |m| m.cfg);
        let hdr = Header::response_to(t, ResponseStatus::Dl);
        match telegram::emit(&mut self.bufs[self.w], &hdr, cfg) {
            Ok(n) => n as u16,
            Err(_) => self.status(t.sa, ResponseStatus::Rs),
        }
    }

    /// Rd_Inp / Rd_Outp's answer (`t.dsap`): the staged inputs or outputs in data exchange
    /// outside the not-ready window, else RS. Out of line, as [`Self::get_cfg`].
    #[inline(never)]
    fn read_back(&mut self, t: &telegram::DataTelegram<'_>) -> u16 {
        let st = self.st;
        if after(self.judge_seq, st.done_seq) || st.state() != DpState::DataExch {
            return self.status(t.sa, ResponseStatus::Rs);
        }
        if t.dsap == Some(sap::RD_INP) {
            let n = usize::from(st.in_len);
            let len = usize::from(st.dx_len);
            if n == 0 || len < n + 2 {
                return self.misc_from_staging(t, DX_AT, 0);
            }
            self.misc_from_staging(t, DX_AT + telegram::pdu_range(len, n).start, n)
        } else {
            self.misc_from_staging(t, OUT_AT, usize::from(st.out_len))
        }
    }
}

/// The streaming receive seam (issue 11): the physical layer hands the telegram's bytes over
/// while they arrive, and calls [`FastPath::finish`] right after the last one.
///
/// What grows with the telegram's length is done here, per piece: the destination filter as
/// soon as DA is in (other stations' traffic: nothing more is looked at or copied, counted
/// as [`FastStats::others`] at `finish`), the FCS of the covered bytes, the copy into the
/// core's queue slot (word by word as the words fill), and — once DA, SA, FC and the SAPs are
/// in — the likely answer: the staged Data_Exchange response (or Slave_Diag) patched for
/// this master, copied into the answer buffer; `finish` then uses it if its decision is that
/// very answer (same staging, same arguments) and copies nothing.
///
/// **Why the slot is free before the telegram is committed**: the bytes go to the slot of
/// sequence number `seq + 1`, which is the slot of `seq + 1 - QUEUE_LEN`. The ring holds at
/// most `QUEUE_LEN - 1` entries, `seq - QUEUE_LEN + 2 ..= seq` at the most, so that older
/// telegram has been dequeued — and the core copies a slot out *before* it dequeues its entry
/// ([`CoreLink::step`]). Nothing reads the slot until the entry for `seq + 1` is enqueued
/// (its index update is the release), and a telegram that is not committed (foreign, invalid,
/// not queued, aborted) leaves bytes there that the next telegram overwrites.
impl TelegramSink for FastPath<'_> {
    fn begin(&mut self) {
        self.rx = Rx::IDLE;
        self.prep = None;
        self.dprep = None;
        self.lean = None;
        self.refresh();
        self.rx =
            Rx { state: RxState::Open, own: self.st.address, slot: slot_of(self.seq.wrapping_add(1)), ..Rx::IDLE };
    }

    fn bytes(&mut self, piece: &[u8]) {
        // One byte of a telegram for the station inside its length (a per-character
        // receiver): the general path below in a few instructions.
        if let ([b], RxState::Own) = (piece, self.rx.state) {
            let at = self.rx.len;
            if let (true, Some(d)) = (at < self.rx.expect, self.rxb.get_mut(at)) {
                *d = *b;
                self.rx.len = at + 1;
                if at >= self.rx.start && at + 2 < self.rx.expect {
                    self.rx.sum = self.rx.sum.wrapping_add(*b);
                }
                if at % 4 == 3 {
                    let w = at / 4;
                    if let (Some(word), Some(src)) = (self.slots[self.rx.slot].get(w), self.rxb.get(at - 3..=at)) {
                        word.store(u32::from_le_bytes([src[0], src[1], src[2], src[3]]), Ordering::Relaxed);
                    }
                    self.rx.words = w + 1;
                }
                if !self.rx.header_seen {
                    self.prepare(at + 1, self.rx.expect - 2);
                }
                return;
            }
        }
        if matches!(self.rx.state, RxState::Open | RxState::Own) {
            self.piece(piece);
        }
    }

    fn abort(&mut self) {
        self.rx = Rx::IDLE;
        self.prep = None;
        self.dprep = None;
        self.lean = None;
    }
}

impl FastPath<'_> {
    /// [`TelegramSink::bytes`] of any piece while the header is open or the telegram is the
    /// station's: kept out of line, so the single character's path stays small where it is
    /// inlined (the receiver's per-character handler).
    #[inline(never)]
    fn piece(&mut self, piece: &[u8]) {
        let at = self.rx.len;
        let n = piece.len().min(self.rxb.len().saturating_sub(at));
        let have = at + n;
        if let (Some(dst), Some(src)) = (self.rxb.get_mut(at..have), piece.get(..n)) {
            dst.copy_from_slice(src);
        }
        self.rx.len = at.saturating_add(piece.len());
        if self.rx.state == RxState::Open {
            // Destination first, before any copy to the core or sum: SD1 / SD3 carry DA at 1,
            // SD2 at 4; anything else (token, SC, garbage) is no telegram for the station.
            let da_at = match self.rxb.first() {
                _ if have == 0 => return,
                Some(&telegram::SD1) | Some(&telegram::SD3) => 1,
                Some(&telegram::SD2) => 4,
                _ => {
                    self.rx.state = RxState::Foreign;
                    return;
                }
            };
            let Some(&da) = self.rxb.get(da_at).filter(|_| have > da_at) else { return };
            let da = da & 0x7F;
            if da != self.rx.own && da != telegram::BROADCAST {
                self.rx.state = RxState::Foreign;
                return;
            }
            match telegram::frame_len(&self.rxb[..have]) {
                Ok(Some(len)) => self.rx.expect = len,
                _ => {
                    self.rx.state = RxState::Bad;
                    return;
                }
            }
            self.rx.start = telegram::covered_start(self.rxb[0]);
            self.rx.state = RxState::Own;
        }
        if self.rx.len > self.rx.expect {
            self.rx.state = RxState::Bad;
            return;
        }
        // The FCS over this piece's covered bytes (DA … last DU byte).
        let end = self.rx.expect - 2;
        let (from, to) = (at.max(self.rx.start), have.min(end));
        if from < to {
            self.rx.sum = self.rx.sum.wrapping_add(telegram::fcs(&self.rxb[from..to]));
        }
        // The words completed by this piece into the core's slot.
        let whole = have / 4;
        if whole > self.rx.words {
            store_words(&self.slots[self.rx.slot][self.rx.words..whole], &self.rxb[self.rx.words * 4..whole * 4]);
            self.rx.words = whole;
        }
        if !self.rx.header_seen && have < self.rx.expect {
            self.prepare(have, end);
        }
    }

    /// Once DA, SA, FC and the SAPs are in (`have` bytes, the covered bytes end at `end`;
    /// with both SAPs, also the first PDU octet): the answer the decision will likely give,
    /// prepared into `bufs[w]` — the staged Data_Exchange response for the locking master in
    /// data exchange, the staged diagnosis for a Slave_Diag, or a DP-V1 answer with the
    /// decision it comes from (`dpv1`'s `prepare_dpv1`). A guess: [`patched`](Self::patched)
    /// uses it only for exactly these arguments, the DP-V1 decision only for this request
    /// before the next timer of the relations it looked at.
    fn prepare(&mut self, have: usize, end: usize) {
        let s = self.rx.start;
        if have < s + 2 {
            return;
        }
        let b = &self.rxb;
        let (da_raw, sa_raw) = (b[s], b[s + 1]);
        let header = s + 3 + usize::from(da_raw >> 7) + usize::from(sa_raw >> 7);
        if have < header {
            return;
        }
        let ext = (da_raw & 0x80 != 0, sa_raw & 0x80 != 0);
        if ext == (true, true) && have == header && header < end {
            // A DP-V1 answer depends on the first PDU octet as well: wait for it.
            return;
        }
        self.rx.header_seen = true;
        self.rx.hsum = telegram::fcs(&b[s..header]);
        let fc = b[s + 2];
        let srd = fc & 0xC0 == 0x40 && matches!(fc & 0x0F, 0x0C | 0x0D);
        let (da, sa) = (da_raw & 0x7F, sa_raw & 0x7F);
        if !srd
            || header > end
            || da != self.rx.own
            || da == telegram::BROADCAST
            || sa == da
            || sa == telegram::BROADCAST
        {
            // (A broadcast is never answered, even by a station that had address 127.)
            return;
        }
        let st = self.st;
        let window = after(self.judge_seq, st.done_seq);
        // What `decide` needs beyond the header checks above to take the prepared answer as
        // the whole decision ([`Lean`]): the SAP octets as `telegram::decode` accepts them
        // (no region address, no chained extension), and no FCB retry of the last request
        // possible (`decide`'s retry test before its fingerprint; the retry memory is reset
        // there as here when the address or the epoch moved).
        let ext_ok = (!ext.0 || b[s + 3] & 0xC0 == 0) && (!ext.1 || b[s + 4] & 0xC0 == 0);
        let retry = fc & 0x10 != 0
            && self.last.is_some_and(|l| {
                l.own == self.rx.own && l.epoch == st.epoch && l.sa == sa && l.fcb == (fc & 0x20 != 0)
            });
        let (dsap, ssap) = (ext.0.then(|| b[s + 3] & 0x3F), ext.1.then(|| b[s + 4] & 0x3F));
        let first = (header < end).then(|| b[header]);
        let pdu_len = end - header;
        let lean =
            (ext_ok && !retry).then_some(Lean { sa, fc, dsap, ssap, pdu_len: pdu_len as u8, what: LeanWhat::Dpv1 });
        let staged = |n: u16| LeanWhat::Staged { n, judge: false, not_ready: false, consume: false };
        let dx = st.state() == DpState::DataExch;
        // The answer `answer_srd` gives, into `bufs[w]` now.
        let what = match (dsap, ssap) {
            (None, None) => {
                // Data_Exchange.
                if window || !dx || st.master() != Some(sa) || (pdu_len != 0 && pdu_len != usize::from(st.out_len)) {
                    staged(self.status(sa, ResponseStatus::Rs))
                } else {
                    let dh = st.flags & FLAG_DIAG_NEW != 0 && self.diag_consumed.is_none();
                    let status = if dh { ResponseStatus::Dh } else { ResponseStatus::Dl };
                    if st.in_len == 0 {
                        staged(if dh { self.status(sa, status) } else { self.sc() })
                    } else {
                        let key = Prep {
                            at: DX_AT,
                            len: usize::from(st.dx_len),
                            da: sa,
                            fc: status as u8,
                            dsap: None,
                            status1: 0,
                        };
                        let n = self.patch_into_scratch(key);
                        if n == 0 {
                            return;
                        }
                        self.prep = Some(key);
                        staged(n)
                    }
                }
            }
            (Some(sap::SLAVE_DIAG), Some(ssap)) => {
                let status1 = if window { Status1::STATION_NOT_READY.bits() } else { 0 };
                let key = Prep {
                    at: DIAG_AT,
                    len: usize::from(st.diag_len),
                    da: sa,
                    fc: ResponseStatus::Dl as u8,
                    dsap: Some(ssap),
                    status1,
                };
                let n = self.patch_into_scratch(key);
                if n == 0 {
                    return;
                }
                self.prep = Some(key);
                let consume = st.master() == Some(sa) && st.flags & FLAG_DIAG_NEW != 0;
                LeanWhat::Staged { n, judge: false, not_ready: window, consume }
            }
            (Some(sap::SET_PRM), Some(_)) | (Some(sap::CHK_CFG), Some(_)) => {
                LeanWhat::Staged { n: self.sc(), judge: true, not_ready: false, consume: false }
            }
            (Some(d @ (sap::GET_CFG | sap::RD_INP | sap::RD_OUTP)), Some(_)) => {
                let t = telegram::DataTelegram {
                    format: telegram::DataFormat::Sd2,
                    da,
                    sa,
                    fc: FunctionCode(fc),
                    dsap,
                    ssap,
                    pdu: &[],
                };
                staged(match d {
                    sap::GET_CFG => self.get_cfg(&t),
                    _ => self.read_back(&t),
                })
            }
            (Some(dsap), Some(ssap)) if dsap != sap::SET_SLAVE_ADD => {
                self.prepare_dpv1(sa, da, fc, dsap, ssap, first);
                if self.dprep.is_none() {
                    return;
                }
                LeanWhat::Dpv1
            }
            _ => return,
        };
        self.lean = lean.map(|l| Lean { what, ..l });
    }
}

/// One telegram on a single-threaded platform (the soft slave, the simulated-bus tests), where
/// the core runs right after the line instead of in a lower-priority task: the line's answer
/// or — for a request the line leaves to the core (DP-V1) — the core's answer at once, as the
/// firmware's core task pends the line; then the core works on everything queued. The answer
/// (never empty) is copied into `out`; its length. Not the firmware's path: there the line and
/// the core run at their own priorities (README "The response path").
pub fn single_threaded(
    fast: &mut FastPath<'_>,
    core: &mut CoreLink<'_>,
    node: &mut Node,
    now: Instant,
    frame: &[u8],
    out: &mut [u8],
) -> Option<usize> {
    let mut copy = |a: &[u8]| {
        let n = a.len().min(out.len());
        out[..n].copy_from_slice(&a[..n]);
        n
    };
    let answer = match fast.on_frame(now, frame) {
        Verdict::Silent => None,
        Verdict::Answer(a) => Some(copy(a)),
        Verdict::Core => {
            core.run(node);
            fast.take_deferred().filter(|a| !a.is_empty()).map(copy)
        }
    };
    core.run(node);
    answer
}

/// What one [`CoreLink::step`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Stepped {
    /// The telegram's sequence number.
    pub seq: u32,
    /// When it arrived.
    pub at: Instant,
    /// The line waited for this answer (it went into the core → line queue).
    pub deferred: bool,
    /// The core's own answer length (`None`: no answer), kept in [`CoreLink::answer`].
    pub answer_len: Option<usize>,
    /// A Data_Exchange the core applied (the drive may want to see the outputs now).
    pub data_exchange: bool,
    /// A DP-V1 request waits for `Node::process_acyclic`.
    pub acyclic_work: bool,
}

/// The core half: owns nothing of the node, is handed it at every call (the platform keeps
/// the node in its lower-priority task).
pub struct CoreLink<'a> {
    from_line: Consumer<'a, Queued>,
    slots: &'a Slots,
    /// The telegram being worked on, copied out of its slot.
    frame: [u8; MAX_FRAME_LEN],
    to_line: Producer<'a, Deferred>,
    staging: TripleWriter<'a, STAGE_WORDS>,
    done_seq: u32,
    epoch: u32,
    answer: [u8; MAX_FRAME_LEN],
    stats: CoreStats,
}

impl CoreLink<'_> {
    /// Counters.
    pub fn stats(&self) -> CoreStats {
        self.stats
    }

    /// Whether telegrams wait for [`step`](Self::step).
    pub fn pending(&self) -> bool {
        self.from_line.ready()
    }

    /// The core's answer of the last [`step`](Self::step) (what a core-alone card sent).
    pub fn answer(&self, len: usize) -> &[u8] {
        &self.answer[..len.min(MAX_FRAME_LEN)]
    }

    /// Work on the oldest queued telegram: `Node::on_frame` at its arrival time, the deferred
    /// answer back to the line, and a new staging. `None` when the queue is empty.
    pub fn step(&mut self, node: &mut Node) -> Option<Stepped> {
        // Copy the slot out before the entry is dequeued (then the line may reuse the slot).
        let q = *self.from_line.peek()?;
        let len = usize::from(q.len).min(MAX_FRAME_LEN);
        load_words(&self.slots[slot_of(q.seq)], &mut self.frame[..len]);
        let _ = self.from_line.dequeue();
        let dx_before = node.slave().stats().data_exchanges;
        let answer_len = node.on_frame_as(q.at, &self.frame[..len], !q.held).map(|a| {
            let n = a.len().min(MAX_FRAME_LEN);
            self.answer[..n].copy_from_slice(&a[..n]);
            n
        });
        if q.deferred {
            let n = answer_len.unwrap_or(0);
            let mut d = Deferred { seq: q.seq, len: n as u16, bytes: [0; MAX_FRAME_LEN] };
            d.bytes[..n].copy_from_slice(&self.answer[..n]);
            if self.to_line.enqueue(d).is_err() {
                self.stats.deferred_lost = self.stats.deferred_lost.wrapping_add(1);
            }
        }
        self.done_seq = q.seq;
        self.stats.steps = self.stats.steps.wrapping_add(1);
        self.publish(node);
        Some(Stepped {
            seq: q.seq,
            at: q.at,
            deferred: q.deferred,
            answer_len,
            data_exchange: node.slave().stats().data_exchanges != dx_before,
            acyclic_work: node.has_acyclic_work(),
        })
    }

    /// [`step`](Self::step) until the queue is empty; the number of telegrams.
    pub fn run(&mut self, node: &mut Node) -> usize {
        let mut n = 0;
        while self.step(node).is_some() {
            n += 1;
        }
        n
    }

    /// `Node::poll` (timers) and a new staging; returns the node's events.
    pub fn poll(&mut self, now: Instant, node: &mut Node) -> Events {
        let ev = node.poll(now);
        self.note_events(ev);
        self.publish(node);
        ev
    }

    /// Events the platform took from the node itself (e.g. through
    /// `Application::snapshot`, which polls the node): an address change reset the
    /// station's FCB memory, so the line forgets its own. Call [`publish`](Self::publish)
    /// afterwards.
    pub fn note_events(&mut self, ev: Events) {
        if ev.contains(Events::ADDRESS_CHANGED) {
            self.epoch = self.epoch.wrapping_add(1);
        }
    }

    /// Publish the staging from `node` (after anything changed the node: an application
    /// step, new inputs or diagnosis, the address).
    pub fn publish(&mut self, node: &mut Node) {
        // Straight into the back slot (no one sees it before `publish`), only what this
        // staging uses: the header words and the three frames.
        let diag = node.slave_mut().staged_diag_frame();
        let diag_len = diag.len().min(DIAG_ROOM);
        self.staging.write(DIAG_AT / 4, &diag[..diag_len]);
        let slave = node.slave();
        let dx = slave.staged_dx_frame();
        let dx_len = dx.len().min(MAX_FRAME_LEN);
        self.staging.write(DX_AT / 4, &dx[..dx_len]);
        let out = slave.outputs();
        let out_len = out.len().min(OUT_ROOM);
        self.staging.write(OUT_AT / 4, &out[..out_len]);
        let real = slave.real_cfg();
        let module = slave.config().modules.iter().position(|m| m.reference == real.reference).unwrap_or(0);
        let mut flags = 0;
        if slave.has_new_diag() {
            flags |= FLAG_DIAG_NEW;
        }
        if slave.no_add_chg() {
            flags |= FLAG_NO_ADD_CHG;
        }
        let mut h = [0u8; DX_AT];
        h[0..4].copy_from_slice(&self.done_seq.to_le_bytes());
        h[4..8].copy_from_slice(&self.epoch.to_le_bytes());
        h[8..12].copy_from_slice(&[
            slave.address(),
            state_code(slave.state()),
            slave.master_address().unwrap_or(0xFF),
            flags,
        ]);
        h[12..16].copy_from_slice(&[slave.input_len() as u8, out_len as u8, module as u8, diag_len as u8]);
        let min_tsdr = node.min_tsdr().0.min(u32::from(u16::MAX));
        h[16..20].copy_from_slice(&(dx_len as u32 | (min_tsdr << 16)).to_le_bytes());
        self.staging.write(0, &h);
        self.stage_dpv1(node);
        self.staging.publish();
        self.stats.publications = self.stats.publications.wrapping_add(1);
    }
}

/// What the differential tests above the line side look at inside the split (`pbcard`'s
/// `fast::check` and its unit tests, with the feature `test-support`); never in the firmware.
#[cfg(any(test, feature = "test-support"))]
#[doc(hidden)]
impl FastPath<'_> {
    /// The DP-V1 decision is prepared at the header (`dpv1`'s "Decided at the header").
    pub fn test_dpv1_prepared(&self) -> bool {
        self.dprep.is_some()
    }

    /// The lean (DP-V1 on the line) decision is prepared.
    pub fn test_lean_prepared(&self) -> bool {
        self.lean.is_some()
    }

    /// Advance the line's telegram sequence by `n`, as if `n` telegrams had been queued
    /// (the sequence-wrap tests).
    pub fn test_advance_seq(&mut self, n: u32) {
        self.seq = self.seq.wrapping_add(n);
    }
}

#[cfg(any(test, feature = "test-support"))]
#[doc(hidden)]
impl CoreLink<'_> {
    /// The next queued telegram's sequence, time, deferred and held flags and length.
    pub fn test_peek(&self) -> Option<(u32, Instant, bool, bool, u16)> {
        self.from_line.peek().map(|q| (q.seq, q.at, q.deferred, q.held, q.len))
    }

    /// The telegram the core link copied out of its slot last (its first `len` bytes).
    pub fn test_frame(&self, len: usize) -> &[u8] {
        &self.frame[..len.min(MAX_FRAME_LEN)]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A triple buffer hands out whole publications only.
    #[test]
    fn triple_buffer_is_never_torn() {
        let mut tb: TripleBuffer<4> = TripleBuffer::new();
        let (mut w, mut r) = tb.halves();
        assert!(!r.refresh(), "nothing published yet");
        w.write(0, &[7; 16]);
        w.publish();
        assert!(r.refresh(), "the first publication reaches the reader");
        let mut b = [0u8; 16];
        r.read(0, &mut b);
        assert_eq!(b, [7; 16]);
        for k in 0u8..50 {
            w.write(0, &[k; 16]);
            if k % 3 == 0 {
                w.publish();
            }
            if r.refresh() {
                let mut b = [0u8; 16];
                r.read(0, &mut b);
                assert!(b.iter().all(|&x| x == b[0]), "{b:?}");
            }
        }
    }

    #[test]
    fn fingerprints_differ_when_a_part_does() {
        let saps = [None, Some(0u8), Some(0x3F)];
        let mut seen = std::collections::HashSet::new();
        for d in saps {
            for s in saps {
                for len in [0usize, 1, 244, 246] {
                    for sum in [0u8, 0xFF] {
                        assert!(seen.insert(fingerprint(d, s, len, sum)), "{d:?} {s:?} {len} {sum}");
                    }
                }
            }
        }
    }

    #[test]
    fn header_sd1_equals_emit() {
        for (da, sa) in [(0u8, 0u8), (2, 8), (126, 125), (127, 3), (45, 126)] {
            for s in
                [ResponseStatus::Ok, ResponseStatus::Rs, ResponseStatus::Rr, ResponseStatus::Dh, ResponseStatus::Dl]
            {
                let hdr = Header { da, sa, fc: FunctionCode::response(s), dsap: None, ssap: None };
                let mut want = [0u8; 8];
                let n = telegram::emit(&mut want, &hdr, &[]).unwrap();
                let mut got = [0u8; 8];
                assert_eq!(usize::from(sd1_status(&mut got, da, sa, s)), n);
                assert_eq!(got[..n], want[..n]);
            }
        }
        assert_eq!(sd1_status(&mut [0u8; 5], 1, 2, ResponseStatus::Rs), 0);
    }

    /// `load_words` gives the packed bytes of the words, then zeros past their end, for every
    /// length (whole words, a partial last word, reads past the end).
    #[test]
    fn load_words_reads_packed_bytes_then_zeros() {
        let words = [AtomicU32::new(0x0403_0201), AtomicU32::new(0x0807_0605)];
        for n in 0..=13 {
            let mut dst = [0xEEu8; 13];
            load_words(&words, &mut dst[..n]);
            let want: std::vec::Vec<u8> = (1..=13u8).map(|b| if b <= 8 { b } else { 0 }).take(n).collect();
            assert_eq!(dst[..n], want[..], "{n} bytes");
            assert!(dst[n..].iter().all(|&b| b == 0xEE), "{n}: nothing written past dst");
        }
    }
}
