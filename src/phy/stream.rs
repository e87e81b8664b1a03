//! The streaming receive seam (issue 11 items 1–2): telegrams handed to the line's decision
//! *while their bytes arrive*, so that the work left after the last byte does not grow with
//! the telegram's length — the way an SPC3 / VPC3+ checks DA and FCS on the fly and answers
//! within a few bit times of the end delimiter.
//!
//! The physical layer owns the cutting: it sees the bytes (one per receive interrupt on a
//! per-character port, or a piece of a DMA ring at each ring event), knows from the header
//! where a telegram ends (the length of SD1/SD3/SD4/SC, or LE + 6 for SD2, checked LE = LEr
//! and the repeated SD) and resynchronises after garbage, a character error or a gap. It
//! hands every telegram's bytes, in order and in pieces of any size, to a [`TelegramSink`]
//! — the protocol side (the fast path, `crate::fast`) implements it — and tells its driver
//! when the telegram's last byte went in, so the driver asks the sink for its decision at
//! once (end by length, not by an idle gap).
//!
//! Direction: this trait is defined here, in the lower layer, and implemented above
//! (ARCHITECTURE "data flows one way"); the physical layer never names the fast path.

/// The receiver of a telegram's bytes while they arrive.
///
/// Call order for one telegram: [`begin`](Self::begin), then [`bytes`](Self::bytes) as many
/// times as the pieces come (the first piece starts with the start delimiter; the pieces
/// together are exactly the telegram, by length), then either the driver's own "complete"
/// call on the implementing type (its decision) or [`abort`](Self::abort). A `begin` while
/// a telegram is in progress abandons that one as `abort` would.
pub trait TelegramSink {
    /// A new telegram starts: forget any partial state.
    fn begin(&mut self);
    /// The next bytes of the telegram in progress, in order (any split: one byte, a DMA
    /// half-ring, the two sides of a ring wrap).
    fn bytes(&mut self, bytes: &[u8]);
    /// The telegram in progress is lost (a character error, an idle gap inside it, a header
    /// that is no telegram): nothing of it may be answered or queued.
    fn abort(&mut self);
}
