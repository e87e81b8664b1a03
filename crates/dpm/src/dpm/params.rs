//! The drive's parameters through the DPM parameter mailbox, as a
//! [`ParameterAccess`] table: what the card's PROFIdrive parameter access (record 47, WEG
//! record 48) reaches behind the card's own PNUs.
//!
//! The mailbox answers later, so [`MailboxParams`] never waits: a value it has not got yet
//! is sent for (one request at a time) and the table reports [`ParameterAccess::pending`];
//! the answer — the drive's values or error, or the mailbox's timeout error 0x11 / 0xDD01 —
//! lands in a small [`ParamCache`] and the next build of the same job takes it from there.
//! A write therefore reaches the drive once per job however often the response is built; the
//! cache is emptied when a new job starts ([`ParameterAccess::start_job`]). An answer to a
//! request of an earlier job is dropped.

use super::{Dpm, Link, MailboxRequest, ParamValues, RequestKind};
use crate::profile::param::{
    Attribute, ErrorValue, ParamAddress, ParamError, ParameterAccess, ValueBlock, ValueWriter,
};
use crate::time::Instant;

/// Answers one job can keep (parameters of one request that go to the drive).
pub const CACHE_ENTRIES: usize = 8;

/// `ERROR_INFO` of a parameter beyond the [`CACHE_ENTRIES`] drive parameters one job can ask.
pub const CACHE_FULL_INFO: u16 = 0xDD03;

/// The answer to a drive parameter beyond [`CACHE_ENTRIES`] in one request: 0x11 with
/// [`CACHE_FULL_INFO`].
pub const CACHE_FULL_ERROR: ParamError =
    ParamError { value: ErrorValue::NOT_EXECUTABLE, additional_info: Some(CACHE_FULL_INFO) };

/// Placeholder answer while a value is pending (the response is not sent).
const PENDING: ParamError = ParamError { value: ErrorValue::NOT_EXECUTABLE, additional_info: None };

/// What identifies an answer within one job: kind, axis, PNU, subindex, count.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Key {
    kind: RequestKind,
    axis: u8,
    pnu: u16,
    subindex: u16,
    count: u8,
}

impl Key {
    fn of(req: &MailboxRequest) -> Key {
        Key { kind: req.kind, axis: req.axis, pnu: req.pnu, subindex: req.subindex, count: req.count }
    }
}

#[derive(Debug, Clone)]
struct Entry {
    key: Key,
    outcome: Result<ParamValues, ParamError>,
}

/// The answers of the current job and the request in flight for it.
#[derive(Debug, Clone, Default)]
pub struct ParamCache {
    entries: heapless::Vec<Entry, CACHE_ENTRIES>,
    inflight: Option<(u16, Key)>,
}

impl ParamCache {
    /// Empty.
    pub const fn new() -> Self {
        ParamCache { entries: heapless::Vec::new(), inflight: None }
    }

    /// Forget every answer and the request in flight (its answer will be dropped: the claim
    /// on it is given up).
    pub fn clear(&mut self, link: &mut Link) {
        self.entries.clear();
        if self.inflight.take().is_some() {
            link.claim_parameter(0);
        }
    }

    /// Poll the mailbox and keep the answer to the request in flight (only that one: an
    /// answer another cache claimed stays for it).
    ///
    /// Out of line: the step and the DP-V1 task both call it (footprint, issue 13 item 1).
    #[inline(never)]
    pub fn collect(&mut self, now: Instant, link: &mut Link, dpm: &Dpm) {
        link.poll_parameter(now, dpm);
        let mine = self.inflight.map(|(id, _)| id);
        if let Some((_, outcome)) = link.take_parameter_answer(mine) {
            if let Some((_, key)) = self.inflight.take() {
                // Room was reserved when the request was sent.
                let _ = self.entries.push(Entry { key, outcome });
            }
        }
    }

    /// Whether a request of this cache is in flight (its answer is claimed for it: take it
    /// with [`Self::collect`], or no other request can be sent).
    pub fn waiting(&self) -> bool {
        self.inflight.is_some()
    }

    fn find(&self, key: Key) -> Option<Result<ParamValues, ParamError>> {
        self.entries.iter().find(|e| e.key == key).map(|e| e.outcome)
    }
}

/// The drive's parameters through the mailbox, for one pass of
/// [`Node::process_acyclic`](crate::node::Node::process_acyclic).
#[derive(Debug)]
pub struct MailboxParams<'a> {
    now: Instant,
    link: &'a mut Link,
    dpm: &'a mut Dpm,
    cache: &'a mut ParamCache,
    pending: bool,
}

impl<'a> MailboxParams<'a> {
    /// The table at `now` (takes an answer that arrived meanwhile into `cache`).
    ///
    /// Out of line: the step and the DP-V1 task both call it (footprint, issue 13 item 1).
    #[inline(never)]
    pub fn new(now: Instant, link: &'a mut Link, dpm: &'a mut Dpm, cache: &'a mut ParamCache) -> Self {
        cache.collect(now, link, dpm);
        MailboxParams { now, link, dpm, cache, pending: false }
    }

    /// The answer to `req`: from the cache, or sent for (then pending).
    fn ask(&mut self, req: MailboxRequest) -> Result<ParamValues, ParamError> {
        let key = Key::of(&req);
        if let Some(outcome) = self.cache.find(key) {
            return outcome;
        }
        let cache = &mut *self.cache;
        if cache.entries.len() + usize::from(cache.inflight.is_some()) >= CACHE_ENTRIES {
            return Err(CACHE_FULL_ERROR);
        }
        if cache.inflight.is_none() {
            // A busy mailbox (an earlier job's request) is tried again on the next pass.
            if let Ok(id) = self.link.submit_parameter(self.now, &req, self.dpm) {
                cache.inflight = Some((id, key));
                self.link.claim_parameter(id);
            }
        }
        self.pending = true;
        Err(PENDING)
    }
}

impl ParameterAccess for MailboxParams<'_> {
    /// Every axis: the drive answers 0x19 for one it does not have.
    fn has_axis(&self, _axis: u8) -> bool {
        true
    }

    #[inline(never)]
    fn read_value(&mut self, axis: u8, addr: &ParamAddress, out: &mut ValueWriter<'_>) -> Result<(), ParamError> {
        let values = self.ask(MailboxRequest::read(axis, addr.pnu, addr.subindex, addr.elements))?;
        put(&values, out)
    }

    fn write_value(&mut self, axis: u8, addr: &ParamAddress, values: &ValueBlock<'_>) -> Result<(), ParamError> {
        let v = ParamValues::new(values.format, values.count, values.bytes)
            .ok_or(ParamError::from(ErrorValue::NOT_EXECUTABLE))?;
        let req = MailboxRequest { count: addr.elements, ..MailboxRequest::write(axis, addr.pnu, addr.subindex, v) };
        self.ask(req).map(|_| ())
    }

    #[inline(never)]
    fn read_description(&mut self, axis: u8, addr: &ParamAddress, out: &mut ValueWriter<'_>) -> Result<(), ParamError> {
        debug_assert_eq!(addr.attribute, Attribute::Description);
        let values = self.ask(MailboxRequest::read_description(axis, addr.pnu, addr.subindex))?;
        put(&values, out)
    }

    fn pending(&self) -> bool {
        self.pending
    }

    fn start_job(&mut self) {
        self.cache.clear(self.link);
        self.pending = false;
    }
}

/// Copy the drive's values into `out`, value by value.
fn put(values: &ParamValues, out: &mut ValueWriter<'_>) -> Result<(), ParamError> {
    out.set_format(values.format);
    let bytes = values.bytes();
    match values.format.value_size() {
        Some(size) if size > 0 && size * values.count as usize == bytes.len() => {
            bytes.chunks(size).try_for_each(|v| out.push_raw(v))
        }
        // Sizes that do not add up: the response builder reports 0x05.
        _ => out.push_raw(bytes),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dpm::MailboxServer;
    use crate::profile::param::Format;
    use crate::time::Duration;

    /// The drive: answers every read with 0x0042 (PNU 100) or an error.
    fn drive(server: &mut MailboxServer, dpm: &mut Dpm) -> Option<u16> {
        let req = server.fetch(&dpm.host())?;
        let outcome = if req.pnu == 100 {
            Ok(ParamValues::new(Format::WORD, 1, &[0, 0x42]).unwrap())
        } else {
            Err(ParamError::from(ErrorValue::IMPERMISSIBLE_PARAMETER_NUMBER))
        };
        MailboxServer::respond(&mut dpm.host(), req.id, outcome);
        Some(req.id)
    }

    /// Issue 16 (d): the record-47 cache and the PKW cache share the mailbox; the one that
    /// looks first never takes (and drops) the other's answer, and an answer whose job ended
    /// does not keep the mailbox busy.
    #[test]
    fn the_record_47_and_pkw_caches_never_take_each_others_answers() {
        let (mut link, mut dpm, mut server) =
            (Link::new(pbcard_link::test_card::SLAVE.modules), Dpm::new(), MailboxServer::new());
        let (mut rec47, mut pkw) = (ParamCache::new(), ParamCache::new());
        let mut now = Instant::from_millis(0);
        let req = MailboxRequest::read(1, 100, 0, 1);
        {
            let mut t = MailboxParams::new(now, &mut link, &mut dpm, &mut rec47);
            assert_eq!(t.ask(req), Err(PENDING));
        }
        assert!(drive(&mut server, &mut dpm).is_some());
        now = now + Duration::from_millis(1);
        // The PKW cache looks first: the answer is not its own, it stays.
        {
            let t = MailboxParams::new(now, &mut link, &mut dpm, &mut pkw);
            assert!(!t.pending());
        }
        assert!(pkw.entries.is_empty());
        assert!(link.mailbox().is_busy(), "the record-47 answer still waits");
        {
            let mut t = MailboxParams::new(now, &mut link, &mut dpm, &mut rec47);
            assert_eq!(t.ask(req), Ok(ParamValues::new(Format::WORD, 1, &[0, 0x42]).unwrap()));
        }
        assert!(!link.mailbox().is_busy());

        // A job that ends with its request in flight: the answer is dropped by whoever looks
        // next, and the mailbox is free for the other cache.
        let other = MailboxRequest::read(1, 200, 0, 1);
        {
            let mut t = MailboxParams::new(now, &mut link, &mut dpm, &mut pkw);
            assert_eq!(t.ask(other), Err(PENDING));
            t.start_job();
        }
        assert!(drive(&mut server, &mut dpm).is_some());
        now = now + Duration::from_millis(1);
        {
            let mut t = MailboxParams::new(now, &mut link, &mut dpm, &mut rec47);
            t.start_job();
            assert_eq!(t.ask(req), Err(PENDING), "sent: the orphan answer did not block the mailbox");
        }
        assert!(rec47.inflight.is_some());

        // A claimant that never comes back (its job stopped without a new one): after the
        // mailbox timeout its answer no longer blocks the other cache.
        let (mut link, mut dpm) = (Link::new(pbcard_link::test_card::SLAVE.modules), Dpm::new());
        let mut server = MailboxServer::new();
        let (mut rec47, mut pkw) = (ParamCache::new(), ParamCache::new());
        {
            let mut t = MailboxParams::new(now, &mut link, &mut dpm, &mut pkw);
            assert_eq!(t.ask(other), Err(PENDING));
        }
        assert!(drive(&mut server, &mut dpm).is_some());
        // (Seen first at +300 ms, given up at +900 ms: more than the 500 ms mailbox timeout.)
        for _ in 0..3 {
            now = now + Duration::from_millis(300);
            let mut t = MailboxParams::new(now, &mut link, &mut dpm, &mut rec47);
            t.start_job();
            let _ = t.ask(req);
        }
        assert!(rec47.inflight.is_some(), "the stale claim was given up and the read sent");
    }
}
