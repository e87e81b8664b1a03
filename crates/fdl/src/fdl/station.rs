//! The passive FDL station (a DP slave at layer 2; reference §2.4–2.5).
//!
//! The [`Station`] takes complete frames, filters them by address, answers FDL_Status
//! itself, applies the FCB/FCV retry rule, and hands every other request to the layer above
//! through [`FdlApplication`], the trait that layer implements.
//!
//! Answers to requests the slave does not support (reference §2.5; choices documented here
//! because the standard leaves the exact reaction to the implementation):
//!
//! | request function | answer |
//! |---|---|
//! | FDL_Status (9) | SD1, FC 0x00 (OK, station type "slave") |
//! | SRD low/high (0xC/0xD) | whatever the application answers |
//! | SDN low/high (4/6) | passed to the application; never answered |
//! | SDA low/high (3/5) | SD1 RS — DP uses no SDA service on any SAP |
//! | MSRD (7), Ident (0xE), LSAP status (0xF) | SD1 RS — not offered by a DP slave (as SPC3) |
//! | time event (0), reserved codes | no answer, counted |
//! | any response frame (b6 = 0), token, SC | no answer (a slave never initiates) |
//! | broadcast (DA 127) | SDN passed to the application, anything else ignored; never answered |
//! | SA 127 (broadcast) or SA = own address | no answer, not passed on, counted ([`StationStats::bad_source`]) |
//! | FC bit 7 set (reserved; DP-V2 time telegram) | no answer, not passed on, counted ([`StationStats::reserved_fc`]) |
//!
//! FCB/FCV (EN 50170, reference §2.4): only the last initiator (SA, FCB) is remembered. A
//! request with FCV = 1 from that initiator whose FCB did not toggle is a **retry**: the
//! stored response is sent again byte for byte and the application is not called.

use super::telegram::{self, DataTelegram, Decoded, FunctionCode, Header, RequestFunction, ResponseStatus, Telegram};
use crate::time::Instant;

/// What the application decided to answer. Frames the application built stay in the
/// application's own buffers ([`FdlApplication::frame`]); this keeps the decision path free
/// of copies.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum Reply {
    /// No answer at all (SDN, or a request that must stay unanswered).
    Silent,
    /// The short acknowledge SC (Set_Prm, Chk_Cfg, Set_Slave_Add … accepted for evaluation).
    ShortAck,
    /// An SD1 frame without data carrying this status (e.g. RS for a closed SAP).
    Status(ResponseStatus),
    /// The `len`-byte frame the application staged in its buffer `id`.
    Frame {
        /// buffer id, meaningful to the application only
        id: u8,
        /// frame length in bytes
        len: u16,
    },
}

/// A decided answer ([`Station::decide`]); [`Station::bytes`] gives its bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Tx {
    /// The short acknowledge SC.
    ShortAck,
    /// The station's own SD1 status frame.
    Sd1,
    /// An application frame.
    App {
        /// buffer id
        id: u8,
        /// length
        len: u16,
    },
}

/// The layer above FDL (the DP slave) implements this.
pub trait FdlApplication {
    /// The station's own address (0..=126).
    fn address(&self) -> u8;

    /// A request addressed to this station (or a broadcast SDN), which is **not** a retry.
    /// `now` is the time the frame was complete.
    ///
    /// A [`Reply::Frame`] buffer must stay byte-identical until the next call of
    /// `on_request`, because the station sends it again for an FCB retry.
    fn on_request(&mut self, now: Instant, req: &DataTelegram<'_>) -> Reply;

    /// A request that the station answered as a retry; lets the application keep its
    /// liveness supervision (the DP watchdog) running.
    fn on_retry(&mut self, now: Instant, req: &DataTelegram<'_>);

    /// The bytes of a frame staged by [`on_request`](Self::on_request).
    fn frame(&self, id: u8, len: u16) -> &[u8];
}

/// Counters of the station (the DPM status block shows them).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct StationStats {
    /// Requests addressed to us (incl. broadcast) handed to the application.
    pub requests: u32,
    /// FCB retries answered from the stored response.
    pub retries: u32,
    /// FDL_Status requests answered.
    pub fdl_status: u32,
    /// Requests answered RS because the function is not supported.
    pub unsupported: u32,
    /// Frames for other stations (or tokens / SC) seen and ignored.
    pub others: u32,
    /// Frames addressed to us that were ignored (responses, reserved codes, broadcast SRD).
    pub ignored: u32,
    /// Frames that failed to decode (corrupt; normally already dropped by the framer).
    pub invalid: u32,
    /// Requests to us with an impossible source (SA 127, the broadcast address, or SA = our
    /// own address): never answered.
    pub bad_source: u32,
    /// Frames to us with FC bit 7 set (reserved in DP-V0/V1; profirust's DP-V2 time telegram):
    /// no request of ours, never answered.
    pub reserved_fc: u32,
}

/// The last answer, remembered for FCB retries.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct LastReply {
    sa: u8,
    fcb: bool,
    /// Fingerprint of the request (DSAP, SSAP, PDU length, PDU sum): a real retry repeats
    /// the request byte for byte, so a request that differs is new even with the same FCB.
    /// This keeps a master that re-polls with an unchanged FCB (profirust after a slave went
    /// offline) from being served a stale answer forever.
    request: (Option<u8>, Option<u8>, usize, u8),
    reply: Reply,
    /// Header bytes of an SD1 status answer (da, sa).
    da: u8,
    own: u8,
}

/// The passive station.
#[derive(Debug, Clone)]
pub struct Station {
    last: Option<LastReply>,
    /// Small frames the station builds itself (SD1 status answers).
    sd1: [u8; 6],
    stats: StationStats,
}

impl Default for Station {
    fn default() -> Self {
        Self::new()
    }
}

const SC_FRAME: [u8; 1] = [telegram::SC];

fn fingerprint(t: &DataTelegram<'_>) -> (Option<u8>, Option<u8>, usize, u8) {
    (t.dsap, t.ssap, t.pdu.len(), telegram::fcs(t.pdu))
}

impl Station {
    /// A station that has answered nothing yet.
    pub const fn new() -> Self {
        Station {
            last: None,
            sd1: [0; 6],
            stats: StationStats {
                requests: 0,
                retries: 0,
                fdl_status: 0,
                unsupported: 0,
                others: 0,
                ignored: 0,
                invalid: 0,
                bad_source: 0,
                reserved_fc: 0,
            },
        }
    }

    /// Counters.
    pub fn stats(&self) -> StationStats {
        self.stats
    }

    /// Forget the FCB memory (after the address changed or the bus was lost).
    pub fn reset(&mut self) {
        self.last = None;
    }

    /// Handle one complete frame; returns the bytes to send after min_TSDR, if any.
    pub fn on_frame<'a, A: FdlApplication>(
        &'a mut self,
        now: Instant,
        frame: &[u8],
        app: &'a mut A,
    ) -> Option<&'a [u8]> {
        let tx = self.decide(now, frame, app)?;
        Some(self.bytes(tx, |id, len| app.frame(id, len)))
    }

    /// The bytes of a decided answer; `app_frame` resolves [`Tx::App`] (the application's
    /// [`FdlApplication::frame`]). Split from [`decide`](Self::decide) so that a caller that
    /// routes to several applications can lend them for the decision only.
    pub fn bytes<'a>(&'a self, tx: Tx, app_frame: impl FnOnce(u8, u16) -> &'a [u8]) -> &'a [u8] {
        match tx {
            Tx::ShortAck => &SC_FRAME,
            Tx::Sd1 => &self.sd1,
            Tx::App { id, len } => app_frame(id, len),
        }
    }

    /// Decide the answer to one complete frame (see the module table); `None` = no answer.
    pub fn decide<A: FdlApplication>(&mut self, now: Instant, frame: &[u8], app: &mut A) -> Option<Tx> {
        let t = match telegram::decode(frame) {
            // Exactly one telegram: trailing bytes mean the caller's framing is off.
            Decoded::Frame(_, n) if n != frame.len() => {
                self.stats.invalid = self.stats.invalid.wrapping_add(1);
                return None;
            }
            Decoded::Frame(Telegram::Data(t), _) => t,
            Decoded::Frame(..) => {
                self.stats.others = self.stats.others.wrapping_add(1);
                return None;
            }
            Decoded::Incomplete | Decoded::Invalid(_) => {
                self.stats.invalid = self.stats.invalid.wrapping_add(1);
                return None;
            }
        };
        let own = app.address();
        if self.last.is_some_and(|l| l.own != own) {
            // The address changed (Set_Slave_Add): frame counting starts afresh.
            self.last = None;
        }
        let broadcast = t.da == telegram::BROADCAST;
        if t.da != own && !broadcast {
            self.stats.others = self.stats.others.wrapping_add(1);
            return None;
        }
        if t.fc.0 & 0x80 != 0 {
            // FC b7 is reserved (0) in every request and response a DP-V1 slave takes part
            // in (reference §2.3): such a frame is not a request of ours.
            self.stats.reserved_fc = self.stats.reserved_fc.wrapping_add(1);
            return None;
        }
        if !t.fc.is_request() {
            self.stats.ignored = self.stats.ignored.wrapping_add(1);
            return None;
        }
        if t.sa == telegram::BROADCAST || t.sa == own {
            // No station sends from the broadcast address, and a frame "from us" is our own
            // echo or a duplicate address on the bus: answering either would put a frame to
            // DA 127 / to ourselves on the line (reference §2.2).
            self.stats.bad_source = self.stats.bad_source.wrapping_add(1);
            return None;
        }
        let function = t.fc.function();
        if broadcast {
            // Broadcasts are processed where DP allows (SDN: Global_Control) and never answered.
            if matches!(function, RequestFunction::SdnLow | RequestFunction::SdnHigh) {
                self.stats.requests = self.stats.requests.wrapping_add(1);
                let _ = app.on_request(now, &t);
            } else {
                self.stats.ignored = self.stats.ignored.wrapping_add(1);
            }
            return None;
        }
        let reply = match function {
            RequestFunction::FdlStatus => {
                self.stats.fdl_status = self.stats.fdl_status.wrapping_add(1);
                return self.sd1_status(&t, ResponseStatus::Ok);
            }
            RequestFunction::SdnLow | RequestFunction::SdnHigh => {
                self.stats.requests = self.stats.requests.wrapping_add(1);
                let _ = app.on_request(now, &t);
                return None;
            }
            RequestFunction::SrdLow | RequestFunction::SrdHigh => {
                if let Some(last) = self.last {
                    if t.fc.fcv() && last.sa == t.sa && last.fcb == t.fc.fcb() && last.request == fingerprint(&t) {
                        self.stats.retries = self.stats.retries.wrapping_add(1);
                        app.on_retry(now, &t);
                        return self.resend(last);
                    }
                }
                self.stats.requests = self.stats.requests.wrapping_add(1);
                app.on_request(now, &t)
            }
            RequestFunction::SdaLow
            | RequestFunction::SdaHigh
            | RequestFunction::Msrd
            | RequestFunction::Ident
            | RequestFunction::LsapStatus => {
                self.stats.unsupported = self.stats.unsupported.wrapping_add(1);
                Reply::Status(ResponseStatus::Rs)
            }
            RequestFunction::TimeEvent | RequestFunction::Other(_) => {
                self.stats.ignored = self.stats.ignored.wrapping_add(1);
                return None;
            }
        };
        // Remember (SA, FCB) for the retry rule: FCV = 1 or the "first cycle" FCV = 0, FCB = 1.
        let last = LastReply { sa: t.sa, fcb: t.fc.fcb(), request: fingerprint(&t), reply, da: t.sa, own };
        self.last = if t.fc.fcv() || t.fc.fcb() { Some(last) } else { None };
        self.resend(last)
    }

    fn resend(&mut self, last: LastReply) -> Option<Tx> {
        match last.reply {
            Reply::Silent => None,
            Reply::ShortAck => Some(Tx::ShortAck),
            Reply::Status(s) => {
                let hdr = Header { da: last.da, sa: last.own, fc: FunctionCode::response(s), dsap: None, ssap: None };
                telegram::emit(&mut self.sd1, &hdr, &[]).ok()?;
                Some(Tx::Sd1)
            }
            Reply::Frame { id, len } => Some(Tx::App { id, len }),
        }
    }

    fn sd1_status(&mut self, req: &DataTelegram<'_>, s: ResponseStatus) -> Option<Tx> {
        let hdr = Header { da: req.sa, sa: req.da, fc: FunctionCode::response(s), dsap: None, ssap: None };
        telegram::emit(&mut self.sd1, &hdr, &[]).ok()?;
        Some(Tx::Sd1)
    }
}
