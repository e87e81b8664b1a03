//! The card's reply pipeline (docs/SPI.md "Pipelining"), one state machine for the board
//! driver (`crates/bsp/src/spi.rs`, buffers `&'static mut`) and the in-process [`super::Loopback`]
//! (buffer indices), so that both clock a reply out in the same transaction.
//!
//! The rule: the reply to the request of transaction *k* is **armed** (the TX DMA points at
//! it) as soon as the card has built it, provided transaction *k + 1* has not begun yet; it
//! is then clocked out during *k + 1* and never again. A reply built after *k + 1* began is
//! **late** and discarded, so a reply can never appear in *k + 2* or later (the earlier board
//! driver armed the previous reply at each NSS rise: the reply to *k* went out in *k + 2*,
//! and the reference host, which fetches in *k + 1*, never saw one).

/// The reply buffers of the card side and which one is armed. `B` is the buffer handle
/// (the board: `&'static mut TxBuf`; the loopback: an index).
#[derive(Debug, Clone)]
pub struct ReplyPipeline<B> {
    armed: Option<B>,
    free: [Option<B>; 2],
    stats: PipelineStats,
}

/// Counters of the pipeline (all wrap).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct PipelineStats {
    /// Replies armed in time.
    pub armed: u32,
    /// Replies built after the next transaction had begun (discarded).
    pub late: u32,
    /// Transactions that ended without an armed reply (MISO `0x00`).
    pub no_reply: u32,
    /// Armed replies rebuilt with newer data before they went out (CYCLIC refresh).
    pub refreshed: u32,
}

impl<B> ReplyPipeline<B> {
    /// Two free buffers, nothing armed.
    pub const fn new(a: B, b: B) -> Self {
        ReplyPipeline {
            armed: None,
            free: [Some(a), Some(b)],
            stats: PipelineStats { armed: 0, late: 0, no_reply: 0, refreshed: 0 },
        }
    }

    /// NSS rose: the armed reply (if any) has been clocked out; its buffer is free again.
    /// Returns whether a reply went out in this transaction.
    pub fn transaction_end(&mut self) -> bool {
        match self.armed.take() {
            Some(b) => {
                self.put_free(b);
                true
            }
            None => {
                self.stats.no_reply = self.stats.no_reply.wrapping_add(1);
                false
            }
        }
    }

    /// A buffer to build the next reply in (`None` only while the frame task holds both).
    pub fn buffer(&mut self) -> Option<B> {
        let [a, b] = &mut self.free;
        a.take().or_else(|| b.take())
    }

    /// The reply in `buf` is built. `idle`: no transaction has begun since the one it answers
    /// ended (board: NSS high and no byte received). Idle: `buf` is armed and returned for the
    /// TX DMA; else the reply is late: discarded, its buffer free again, `None`.
    pub fn ready(&mut self, buf: B, idle: bool) -> Option<&B> {
        if !idle {
            self.stats.late = self.stats.late.wrapping_add(1);
            self.put_free(buf);
            return None;
        }
        self.stats.armed = self.stats.armed.wrapping_add(1);
        if let Some(old) = self.armed.replace(buf) {
            // A refresh replaced an armed reply that had not gone out.
            self.stats.refreshed = self.stats.refreshed.wrapping_add(1);
            self.put_free(old);
        }
        self.armed.as_ref()
    }

    /// The armed reply, if any.
    pub fn armed(&self) -> Option<&B> {
        self.armed.as_ref()
    }

    /// Disarm without sending (the card dropped the transaction the reply would go out in:
    /// the reply is lost like a late one).
    pub fn discard(&mut self) {
        if let Some(b) = self.armed.take() {
            self.stats.late = self.stats.late.wrapping_add(1);
            self.put_free(b);
        }
    }

    /// A buffer taken with [`Self::buffer`] and not used (a refresh that came too late).
    pub fn release(&mut self, buf: B) {
        self.put_free(buf);
    }

    /// The counters.
    pub fn stats(&self) -> PipelineStats {
        self.stats
    }

    fn put_free(&mut self, buf: B) {
        let slot = if self.free[0].is_none() { 0 } else { 1 };
        self.free[slot] = Some(buf);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_reply_goes_out_in_the_next_transaction_or_never() {
        let mut p = ReplyPipeline::new(0u8, 1u8);
        // Transaction 0 ends: nothing was armed.
        assert!(!p.transaction_end());
        let b = p.buffer().unwrap();
        assert_eq!(p.ready(b, true), Some(&b));
        // Transaction 1 carries it.
        assert!(p.transaction_end());
        // The reply to 1 is late (transaction 2 began): discarded, 2 carries nothing.
        let b = p.buffer().unwrap();
        assert_eq!(p.ready(b, false), None);
        assert!(!p.transaction_end());
        assert_eq!(p.stats(), PipelineStats { armed: 1, late: 1, no_reply: 2, refreshed: 0 });
        // Both buffers are free again.
        assert!(p.buffer().is_some() && p.buffer().is_some() && p.buffer().is_none());
    }

    #[test]
    fn a_refresh_replaces_the_armed_reply() {
        let mut p = ReplyPipeline::new(0u8, 1u8);
        let a = p.buffer().unwrap();
        p.ready(a, true);
        let b = p.buffer().unwrap();
        assert_eq!(p.ready(b, true), Some(&b));
        assert_eq!(p.stats().refreshed, 1);
        assert!(p.transaction_end());
        assert!(p.buffer().is_some() && p.buffer().is_some());
    }
}
