//! The CYCLIC exchange (protocol version 2, issue 16 item 2): one CRC-checked request per
//! drive cycle carries the drive's heartbeat, its drive-neutral status and actual values
//! (DRIVE_STATE, sized to the telegram's words) and a mailbox fragment; its reply, clocked
//! out in the next transaction — normally the next cycle's CYCLIC request — carries the
//! pending events, the card's heartbeat, flags, communication state, boot id and event
//! counters, the drive-neutral command and setpoints (DRIVE_CMD, sized to the telegram) and
//! a mailbox fragment. The card **refreshes** an armed CYCLIC reply after each of its steps
//! (`SpiSlave::refresh`), so the command the drive receives is the newest, not the one of
//! the moment of the request (the VPC3+'s buffer switch in SPI terms).
//!
//! Request DATA (after the common header, `ADDR` = 0, `LEN` = n):
//!
//! | byte | field | meaning |
//! |---|---|---|
//! | 0..2 | HEARTBEAT | the drive's heartbeat (`DRIVE.HEARTBEAT`) |
//! | 2..4 | DRIVE_SEQ | new `DRIVE` counter (the card writes HEARTBEAT under it, the rest of DRIVE as the host last wrote it); 0 = DRIVE untouched |
//! | 4..6 | STATE_SEQ | new `DRIVE_STATE` counter; 0 = DRIVE_STATE untouched |
//! | 6 | STATE_LEN | s = bytes of DRIVE_STATE from its FLAGS field (16: through NAMUR; 20 + 2·words with INPUTS_SEQ, EXTRA_COUNT and EXTRA words); the rest of the block is written 0 |
//! | 7 | RSP_OFF | mailbox fragment host → card: offset in MBX_RSP |
//! | 8 | RSP_LEN | r = its bytes (0 = none) |
//! | 9 | REQ_OFF | mailbox fragment card → host wanted: offset in MBX_REQ |
//! | 10 | REQ_LEN | bytes wanted (0 = none) |
//! | 11..11+s | STATE | DRIVE_STATE bytes from FLAGS |
//! | 11+s..11+s+r | RSP | MBX_RSP bytes from RSP_OFF |
//!
//! Reply DATA (RESULT OK; `ADDR` 0):
//!
//! | byte | field | meaning |
//! |---|---|---|
//! | 0..2 | EVENTS | the pending-events bitmap (as in STATUS) |
//! | 2..4 | CARD_HEARTBEAT | `CARD.HEARTBEAT` |
//! | 4 | CARD_FLAGS | `CARD.FLAGS` |
//! | 5 | COMM_STATE | `STATUS.COMM_STATE` (P0740 coding) |
//! | 6..8 | BOOT_ID | `CARD.BOOT_ID` |
//! | 8..16 | CARD_EVENTS | `CARD.EVENTS` counters |
//! | 16..18 | CMD_SEQ | `DRIVE_CMD.SEQ_HEAD`; 0 = no consistent command (keep the last one) |
//! | 18 | CMD_LEN | c = bytes of DRIVE_CMD from FLAGS (12 + 2·EXTRA_COUNT; 0 with CMD_SEQ 0) |
//! | 19 | REQ_LEN | q = bytes of the MBX_REQ fragment (0: not asked, or the block is being written) |
//! | 20..20+c | CMD | DRIVE_CMD bytes from FLAGS |
//! | 20+c..20+c+q | REQ | MBX_REQ bytes from REQ_OFF |
//!
//! Checks on top of the common ones (refused with BAD_LENGTH): LEN ≠ 11 + s + r, s beyond
//! DRIVE_STATE's payload, a fragment beyond its block. The values are all card-side copies
//! of consistent blocks, made in one go, so the reply is one consistent card cycle.

use super::{get16, put16, REPLY_HEADER};
use crate::dpm::layout::{card, drive, drive_cmd, drive_state, mbx_req, mbx_rsp, status};
use crate::dpm::Dpm;

/// Offsets in the request DATA (the table of the module docs).
pub mod req {
    /// u16 the drive's heartbeat.
    pub const HEARTBEAT: usize = 0;
    /// u16 new DRIVE counter (0 = DRIVE untouched).
    pub const DRIVE_SEQ: usize = 2;
    /// u16 new DRIVE_STATE counter (0 = DRIVE_STATE untouched).
    pub const STATE_SEQ: usize = 4;
    /// u8 bytes of DRIVE_STATE from its FLAGS field.
    pub const STATE_LEN: usize = 6;
    /// u8 MBX_RSP fragment: offset.
    pub const RSP_OFF: usize = 7;
    /// u8 MBX_RSP fragment: bytes.
    pub const RSP_LEN: usize = 8;
    /// u8 MBX_REQ fragment wanted: offset.
    pub const REQ_OFF: usize = 9;
    /// u8 MBX_REQ fragment wanted: bytes.
    pub const REQ_LEN: usize = 10;
    /// DRIVE_STATE bytes, then the MBX_RSP fragment.
    pub const STATE: usize = 11;
}

/// Offsets in the reply DATA (the table of the module docs).
pub mod rep {
    /// u16 the pending-events bitmap.
    pub const EVENTS: usize = 0;
    /// u16 `CARD.HEARTBEAT`.
    pub const CARD_HEARTBEAT: usize = 2;
    /// u8 `CARD.FLAGS`.
    pub const CARD_FLAGS: usize = 4;
    /// u8 `STATUS.COMM_STATE`.
    pub const COMM_STATE: usize = 5;
    /// u16 `CARD.BOOT_ID`.
    pub const BOOT_ID: usize = 6;
    /// u8 × 8 `CARD.EVENTS`.
    pub const CARD_EVENTS: usize = 8;
    /// u16 `DRIVE_CMD.SEQ_HEAD` (0 = no consistent command).
    pub const CMD_SEQ: usize = 16;
    /// u8 bytes of DRIVE_CMD from FLAGS.
    pub const CMD_LEN: usize = 18;
    /// u8 bytes of the MBX_REQ fragment.
    pub const REQ_LEN: usize = 19;
    /// DRIVE_CMD bytes, then the MBX_REQ fragment.
    pub const CMD: usize = 20;
}

/// Request DATA before STATE.
pub const REQUEST_FIXED: usize = req::STATE;
/// Reply DATA before CMD.
pub const REPLY_FIXED: usize = rep::CMD;
/// Bytes of DRIVE_STATE payload (from FLAGS to the tail).
pub const STATE_PAYLOAD: usize = drive_state::SEQ_TAIL - drive_state::FLAGS;
/// Bytes of DRIVE_STATE without the extra words: FLAGS through NAMUR.
pub const STATE_BASE: usize = drive_state::INPUTS_SEQ - drive_state::FLAGS;
/// Bytes of DRIVE_CMD from FLAGS to the extra words.
pub const CMD_BASE: usize = drive_cmd::EXTRA - drive_cmd::FLAGS;
/// Most bytes of a mailbox fragment.
pub const MAX_FRAGMENT: usize = 32;
/// Fewest bytes of a mailbox fragment the reference hosts use (a telegram that leaves less of
/// the transaction budget gets this many: the cycle is that much longer).
pub const MIN_FRAGMENT: usize = 4;
/// The longest CYCLIC request DATA.
pub const MAX_REQUEST_DATA: usize = REQUEST_FIXED + STATE_PAYLOAD + MAX_FRAGMENT;
/// The longest CYCLIC reply DATA.
pub const MAX_REPLY_DATA: usize = REPLY_FIXED + (drive_cmd::SEQ_TAIL - drive_cmd::FLAGS) + MAX_FRAGMENT;

/// A CYCLIC request that passed its own checks (the common header and CRC are checked by
/// `parse_request`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CyclicRequest<'a> {
    /// The drive's heartbeat.
    pub heartbeat: u16,
    /// New DRIVE counter (0 = untouched).
    pub drive_seq: u16,
    /// New DRIVE_STATE counter (0 = untouched).
    pub state_seq: u16,
    /// DRIVE_STATE bytes from FLAGS.
    pub state: &'a [u8],
    /// MBX_RSP fragment: offset and bytes.
    pub rsp: (u8, &'a [u8]),
    /// MBX_REQ fragment wanted: offset and length.
    pub req: (u8, u8),
}

impl<'a> CyclicRequest<'a> {
    /// Check the DATA of a CYCLIC request: the grammar of the module docs. `None` = BAD_LENGTH.
    pub fn parse(d: &'a [u8]) -> Option<CyclicRequest<'a>> {
        if d.len() < REQUEST_FIXED {
            return None;
        }
        let (s, r) = (usize::from(d[req::STATE_LEN]), usize::from(d[req::RSP_LEN]));
        let (rsp_off, req_off, req_len) = (d[req::RSP_OFF], d[req::REQ_OFF], d[req::REQ_LEN]);
        let fits = |off: u8, len: usize, block: usize| len <= MAX_FRAGMENT && usize::from(off) + len <= block;
        if d.len() != REQUEST_FIXED + s + r
            || s > STATE_PAYLOAD
            || !fits(rsp_off, r, mbx_rsp::LEN)
            || !fits(req_off, usize::from(req_len), mbx_req::LEN)
        {
            return None;
        }
        Some(CyclicRequest {
            heartbeat: get16(d, req::HEARTBEAT),
            drive_seq: get16(d, req::DRIVE_SEQ),
            state_seq: get16(d, req::STATE_SEQ),
            state: &d[REQUEST_FIXED..REQUEST_FIXED + s],
            rsp: (rsp_off, &d[REQUEST_FIXED + s..]),
            req: (req_off, req_len),
        })
    }

    /// Encode the DATA into `out` (at least [`Self::len`] bytes); returns its length.
    pub fn encode(&self, out: &mut [u8]) -> usize {
        let (s, r) = (self.state.len(), self.rsp.1.len());
        put16(out, req::HEARTBEAT, self.heartbeat);
        put16(out, req::DRIVE_SEQ, self.drive_seq);
        put16(out, req::STATE_SEQ, self.state_seq);
        out[req::STATE_LEN] = s as u8;
        out[req::RSP_OFF] = self.rsp.0;
        out[req::RSP_LEN] = r as u8;
        out[req::REQ_OFF] = self.req.0;
        out[req::REQ_LEN] = self.req.1;
        out[REQUEST_FIXED..REQUEST_FIXED + s].copy_from_slice(self.state);
        out[REQUEST_FIXED + s..REQUEST_FIXED + s + r].copy_from_slice(self.rsp.1);
        REQUEST_FIXED + s + r
    }

    /// Bytes of its DATA.
    pub fn len(&self) -> usize {
        REQUEST_FIXED + self.state.len() + self.rsp.1.len()
    }

    /// Never empty (the fixed part).
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Apply the host's part to the image: DRIVE's heartbeat under DRIVE_SEQ, DRIVE_STATE
    /// under STATE_SEQ (tail, payload, head: each block consistent when done), the MBX_RSP
    /// fragment as bytes.
    pub fn apply(&self, dpm: &mut Dpm) {
        let img = dpm.as_bytes_mut();
        if self.drive_seq != 0 {
            let b = &mut img[drive::START..drive::START + drive::LEN];
            put16(b, drive::SEQ_TAIL, self.drive_seq);
            put16(b, drive::HEARTBEAT, self.heartbeat);
            put16(b, drive::SEQ_HEAD, self.drive_seq);
        }
        if self.state_seq != 0 {
            let b = &mut img[drive_state::START..drive_state::START + drive_state::LEN];
            put16(b, drive_state::SEQ_TAIL, self.state_seq);
            let p = &mut b[drive_state::FLAGS..drive_state::SEQ_TAIL];
            p[..self.state.len()].copy_from_slice(self.state);
            p[self.state.len()..].fill(0);
            put16(b, drive_state::SEQ_HEAD, self.state_seq);
        }
        let (off, bytes) = self.rsp;
        let at = mbx_rsp::START + usize::from(off);
        img[at..at + bytes.len()].copy_from_slice(bytes);
    }
}

/// Build the CYCLIC reply DATA into `out` (`reply[REPLY_HEADER..]`) from the image as it is
/// now; returns its length. `events` is the pending-events bitmap; `req` the MBX_REQ
/// fragment wanted.
pub fn build_reply(dpm: &Dpm, events: u16, req: (u8, u8), out: &mut [u8]) -> usize {
    let img = dpm.as_bytes();
    let consistent = |start: usize, len: usize| {
        let h = get16(img, start);
        h != 0 && h == get16(img, start + len - 2)
    };
    put16(out, rep::EVENTS, events);
    let c = &img[card::START..card::START + card::LEN];
    out[rep::CARD_HEARTBEAT..rep::CARD_HEARTBEAT + 2].copy_from_slice(&c[card::HEARTBEAT..card::HEARTBEAT + 2]);
    out[rep::CARD_FLAGS] = c[card::FLAGS];
    out[rep::COMM_STATE] = img[status::START + status::COMM_STATE];
    out[rep::BOOT_ID..rep::BOOT_ID + 2].copy_from_slice(&c[card::BOOT_ID..card::BOOT_ID + 2]);
    out[rep::CARD_EVENTS..rep::CMD_SEQ].copy_from_slice(&c[card::EVENTS..card::EVENTS + 8]);
    let mut n = REPLY_FIXED;
    if consistent(drive_cmd::START, drive_cmd::LEN) {
        let b = &img[drive_cmd::START..drive_cmd::START + drive_cmd::LEN];
        let words = usize::from(b[drive_cmd::EXTRA_COUNT]).min((drive_cmd::SEQ_TAIL - drive_cmd::EXTRA) / 2);
        let len = CMD_BASE + 2 * words;
        out[rep::CMD_SEQ..rep::CMD_SEQ + 2].copy_from_slice(&b[..2]);
        out[rep::CMD_LEN] = len as u8;
        out[n..n + len].copy_from_slice(&b[drive_cmd::FLAGS..drive_cmd::FLAGS + len]);
        n += len;
    } else {
        put16(out, rep::CMD_SEQ, 0);
        out[rep::CMD_LEN] = 0;
    }
    let (off, len) = (usize::from(req.0), usize::from(req.1));
    if len > 0 && consistent(mbx_req::START, mbx_req::LEN) {
        let at = mbx_req::START + off;
        out[n..n + len].copy_from_slice(&img[at..at + len]);
        out[rep::REQ_LEN] = len as u8;
        n += len;
    } else {
        out[rep::REQ_LEN] = 0;
    }
    n
}

/// A decoded CYCLIC reply DATA.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CyclicReply<'a> {
    /// The pending-events bitmap.
    pub events: u16,
    /// `CARD.HEARTBEAT`.
    pub card_heartbeat: u16,
    /// `CARD.FLAGS`.
    pub card_flags: u8,
    /// `STATUS.COMM_STATE`.
    pub comm_state: u8,
    /// `CARD.BOOT_ID`.
    pub boot_id: u16,
    /// `CARD.EVENTS`.
    pub card_events: [u8; 8],
    /// `DRIVE_CMD.SEQ_HEAD` (0 = no consistent command).
    pub command_seq: u16,
    /// DRIVE_CMD bytes from FLAGS.
    pub command: &'a [u8],
    /// The MBX_REQ fragment.
    pub request: &'a [u8],
}

impl<'a> CyclicReply<'a> {
    /// Decode reply DATA (`None`: lengths inconsistent).
    pub fn decode(d: &'a [u8]) -> Option<CyclicReply<'a>> {
        if d.len() < REPLY_FIXED {
            return None;
        }
        let (c, q) = (usize::from(d[rep::CMD_LEN]), usize::from(d[rep::REQ_LEN]));
        if d.len() != REPLY_FIXED + c + q || c > drive_cmd::SEQ_TAIL - drive_cmd::FLAGS {
            return None;
        }
        let mut card_events = [0u8; 8];
        card_events.copy_from_slice(&d[rep::CARD_EVENTS..rep::CMD_SEQ]);
        Some(CyclicReply {
            events: get16(d, rep::EVENTS),
            card_heartbeat: get16(d, rep::CARD_HEARTBEAT),
            card_flags: d[rep::CARD_FLAGS],
            comm_state: d[rep::COMM_STATE],
            boot_id: get16(d, rep::BOOT_ID),
            card_events,
            command_seq: get16(d, rep::CMD_SEQ),
            command: &d[REPLY_FIXED..REPLY_FIXED + c],
            request: &d[REPLY_FIXED + c..],
        })
    }
}

const _: () = {
    assert!(REPLY_HEADER + MAX_REPLY_DATA + 2 <= super::MAX_REPLY);
    assert!(rep::CMD_SEQ - rep::CARD_EVENTS == crate::dpm::layout::CARD_EVENT_COUNT);
};
