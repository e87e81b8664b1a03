//! Test support of the profile layer (issue 13 item 5), for this crate's own tests and, with
//! the feature `test-support`, for the crates above it (`pbcard::testkit` re-exports it):
//!
//! * [`FakeDrive`] — the one fake drive parameter table of the workspace's tests;
//! * [`Mailbox`] — any table behind an asynchronous transport, as the drive sits behind the
//!   DPM parameter mailbox (`pbcard_dpm::params`): a value not answered yet is sent for and the
//!   table is [`ParameterAccess::pending`] until the test lets the drive answer.
//!
//! `no_std` and allocation-free like the rest of the crate.

mod fake_drive;

pub use fake_drive::{FakeDrive, Indirect, Quirk, QuirkPnu, Refusal, Rule, LAST_PNU, PNUS};

use heapless::Vec;

use crate::profile::param::{
    Attribute, ErrorValue, Format, ParamAddress, ParamError, ParameterAccess, ValueBlock, ValueWriter,
};

/// The most value bytes one mailbox operation carries (a whole parameter response's values).
pub const MAILBOX_VALUE_LEN: usize = 240;
/// The most answers a [`Mailbox`] keeps for one job: one for each parameter of the longest
/// request (39, reference §5.2) and one more. A job that asks more is answered 0x11 for the
/// rest (nothing is forgotten within a job, so no value is sent for twice).
pub const MAILBOX_ANSWERS: usize = 40;

/// One operation sent through a [`Mailbox`]: a read of the address's attribute (value,
/// description or text) or a change of its values, on the axis.
// A test double, allocation-free like the crate: the bytes stay inline (no `Box` in `no_std`).
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq)]
pub enum MailboxOp {
    /// Read the value(s), the description or the text at the address, on the axis.
    Read(u8, ParamAddress),
    /// Change the value(s) at the address, on the axis: the format, the number of values, the bytes.
    Write(u8, ParamAddress, Format, u8, Vec<u8, MAILBOX_VALUE_LEN>),
}

/// What the drive answered to a read: the format it gave, the number of values, their bytes.
#[derive(Debug, Clone, PartialEq)]
struct Reply {
    format: Option<Format>,
    count: u8,
    bytes: Vec<u8, MAILBOX_VALUE_LEN>,
}

type Answer = Result<Reply, ParamError>;

/// A table behind an asynchronous transport, like the drive behind the DPM parameter mailbox
/// (`pbcard_dpm::params`): a value, description or text not answered yet is sent for, one
/// operation at a time, and answered 0x11 "not executable" with
/// [`ParameterAccess::pending`] true while it is in flight; [`Mailbox::deliver`] lets the drive
/// answer it; the answers (with the drive's format and number of values) are kept for the job
/// and forgotten at [`ParameterAccess::start_job`]. A value missing from the answers is either
/// in flight or waits for the one in flight. The axes are the drive's ([`ParameterAccess::has_axis`]
/// is forwarded: the card knows them from the drive's identification).
#[derive(Debug, Clone)]
pub struct Mailbox<T> {
    /// The drive behind the transport.
    pub drive: T,
    inflight: Option<MailboxOp>,
    answers: Vec<(MailboxOp, Answer), MAILBOX_ANSWERS>,
    /// Operations the drive has answered.
    pub delivered: u32,
}

impl<T: ParameterAccess> Mailbox<T> {
    /// `drive` behind an idle mailbox.
    pub fn new(drive: T) -> Self {
        Mailbox { drive, inflight: None, answers: Vec::new(), delivered: 0 }
    }

    /// The operation in flight, if any.
    pub fn inflight(&self) -> Option<&MailboxOp> {
        self.inflight.as_ref()
    }

    /// The drive answers the operation in flight (nothing in flight: nothing happens).
    pub fn deliver(&mut self) {
        let Some(op) = self.inflight.take() else { return };
        let answer: Answer = match &op {
            MailboxOp::Read(axis, a) => {
                let mut buf = [0u8; MAILBOX_VALUE_LEN];
                let mut w = ValueWriter::new(&mut buf);
                let r = match a.attribute {
                    Attribute::Description => self.drive.read_description(*axis, a, &mut w),
                    Attribute::Text => self.drive.read_text(*axis, a, &mut w),
                    _ => self.drive.read_value(*axis, a, &mut w),
                };
                r.and_then(|()| {
                    let bytes =
                        Vec::from_slice(w.bytes()).map_err(|_| ParamError::from(ErrorValue::RESPONSE_TOO_LONG))?;
                    Ok(Reply { format: w.format(), count: w.count(), bytes })
                })
            }
            MailboxOp::Write(axis, a, format, count, bytes) => {
                let block = ValueBlock { format: *format, count: *count, bytes };
                self.drive.write_value(*axis, a, &block).map(|()| Reply { format: None, count: 0, bytes: Vec::new() })
            }
        };
        self.delivered += 1;
        // Room for every parameter of a request (`ask` sends nothing once it is full).
        let _ = self.answers.push((op, answer));
    }

    fn ask(&mut self, op: MailboxOp) -> Answer {
        if let Some((_, answer)) = self.answers.iter().find(|(o, _)| *o == op) {
            return answer.clone();
        }
        if !self.answers.is_full() {
            self.inflight.get_or_insert(op);
        }
        Err(ErrorValue::NOT_EXECUTABLE.into())
    }

    fn read(&mut self, axis: u8, a: &ParamAddress, out: &mut ValueWriter<'_>) -> Result<(), ParamError> {
        let r = self.ask(MailboxOp::Read(axis, *a))?;
        if let Some(f) = r.format {
            out.set_format(f);
        }
        let size = if r.count == 0 { 0 } else { r.bytes.len() / usize::from(r.count) };
        r.bytes.chunks(size.max(1)).try_for_each(|v| out.push_raw(v))
    }
}

impl<T: ParameterAccess> ParameterAccess for Mailbox<T> {
    fn has_axis(&self, axis: u8) -> bool {
        self.drive.has_axis(axis)
    }
    fn read_value(&mut self, axis: u8, a: &ParamAddress, out: &mut ValueWriter<'_>) -> Result<(), ParamError> {
        self.read(axis, a, out)
    }
    fn write_value(&mut self, axis: u8, a: &ParamAddress, v: &ValueBlock<'_>) -> Result<(), ParamError> {
        let bytes = Vec::from_slice(v.bytes).map_err(|_| ParamError::from(ErrorValue::VALUE_IMPERMISSIBLE))?;
        self.ask(MailboxOp::Write(axis, *a, v.format, v.count, bytes)).map(|_| ())
    }
    fn read_description(&mut self, axis: u8, a: &ParamAddress, out: &mut ValueWriter<'_>) -> Result<(), ParamError> {
        self.read(axis, a, out)
    }
    fn read_text(&mut self, axis: u8, a: &ParamAddress, out: &mut ValueWriter<'_>) -> Result<(), ParamError> {
        self.read(axis, a, out)
    }
    fn pending(&self) -> bool {
        self.inflight.is_some()
    }
    fn start_job(&mut self) {
        self.answers.clear();
        self.inflight = None;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::profile::param::{respond, ParamRequest, MAX_LEN};
    use crate::profile::table::{slots, ParamDef, Table, Type};

    fn value(pnu: u16, subindex: u16) -> ParamAddress {
        ParamAddress { attribute: Attribute::Value, elements: 1, pnu, subindex }
    }

    fn read(t: &mut impl ParameterAccess, axis: u8, a: &ParamAddress) -> Result<std::vec::Vec<u8>, ParamError> {
        let mut buf = [0u8; 64];
        let mut w = ValueWriter::new(&mut buf);
        t.read_value(axis, a, &mut w)?;
        Ok(w.bytes().to_vec())
    }

    fn word(x: u16) -> [u8; 2] {
        x.to_be_bytes()
    }

    const DEFS: &[ParamDef] = &[
        ParamDef::new(20, "Read only", Type::U16).read_only().with_default(7),
        ParamDef::new(101, "Min freq", Type::U16).limits(0, 32000),
        ParamDef::new(102, "Max freq", Type::U16).limits(0, 32000).with_default(5000),
    ];
    const N: usize = slots(DEFS);

    fn min_le_max(t: &Table<N>, pnu: u16, v: i64) -> Result<(), ErrorValue> {
        match pnu {
            101 if v > t.get(102, 0).unwrap_or(0) => Err(ErrorValue::LIMIT_EXCEEDED),
            102 if v < t.get(101, 0).unwrap_or(0) => Err(ErrorValue::LIMIT_EXCEEDED),
            _ => Ok(()),
        }
    }

    fn vacon_like() -> FakeDrive<N> {
        FakeDrive::with_table(Table::new(DEFS))
            .on_axis(1)
            .indirect(Indirect {
                pnu: 10001,
                not_found: ErrorValue::VACON_DRIVE_PARAMETER_NOT_FOUND,
                ids: 100..=199,
                ids_only: true,
            })
            .rule(min_le_max)
            .word_only()
            .without_descriptions()
    }

    #[test]
    fn the_standard_pnus_are_the_card_tests_table() {
        let mut d = FakeDrive::new();
        assert!(d.has_axis(0) && d.has_axis(1) && !d.has_axis(2));
        assert_eq!(read(&mut d, 0, &value(2, 0)), Ok(vec![0x12, 0x34]));
        assert_eq!(read(&mut d, 0, &value(999, 0)), Err(ErrorValue::IMPERMISSIBLE_PARAMETER_NUMBER.into()));
        let v = word(1001);
        let block = ValueBlock { format: Format::WORD, count: 1, bytes: &v };
        assert_eq!(d.write_value(0, &value(1, 0), &block), Err(ErrorValue::LIMIT_EXCEEDED.into()));
        let v = word(700);
        let block = ValueBlock { format: Format::WORD, count: 1, bytes: &v };
        assert_eq!(d.write_value(0, &value(1, 0), &block), Ok(()));
        assert_eq!((d.p1, d.writes, d.write_calls, d.read_calls), (700, 1, 2, 2));
        let mut buf = [0u8; 8];
        let mut w = ValueWriter::new(&mut buf);
        assert_eq!(d.read_text(0, &value(1, 2), &mut w), Ok(()));
        assert_eq!(w.bytes(), b"Auto");
        assert_eq!(d.read_text(0, &value(3, 0), &mut w), Err(ErrorValue::NO_TEXT_ARRAY.into()));
    }

    #[test]
    fn an_empty_drive_knows_no_pnu_on_any_axis() {
        let mut d = FakeDrive::empty();
        assert!(d.has_axis(0) && d.has_axis(7) && d.has_axis(255));
        for pnu in PNUS {
            assert_eq!(read(&mut d, 0, &value(pnu, 0)), Err(ErrorValue::IMPERMISSIBLE_PARAMETER_NUMBER.into()));
        }
    }

    #[test]
    fn the_indirect_pnu_reaches_drive_parameters_only_that_way() {
        let mut d = vacon_like();
        assert!(d.has_axis(1) && !d.has_axis(0));
        assert_eq!(read(&mut d, 1, &value(10001, 102)), Ok(word(5000).to_vec()));
        assert_eq!(read(&mut d, 1, &value(102, 0)), Err(ErrorValue::IMPERMISSIBLE_PARAMETER_NUMBER.into()));
        assert_eq!(read(&mut d, 1, &value(10001, 150)), Err(ErrorValue::VACON_DRIVE_PARAMETER_NOT_FOUND.into()));
        assert_eq!(read(&mut d, 1, &value(20, 0)), Ok(word(7).to_vec()), "outside the IDs: direct");
        // Two IDs in one request: 101, 102.
        let two = ParamAddress { elements: 2, ..value(10001, 101) };
        assert_eq!(read(&mut d, 1, &two), Ok([word(0), word(5000)].concat()));
    }

    #[test]
    fn rule_format_and_refusal_judge_a_change_before_the_table() {
        let mut d = vacon_like();
        let v = word(6000);
        let typed = ValueBlock { format: Format::UNSIGNED16, count: 1, bytes: &v };
        assert_eq!(d.write_value(1, &value(10001, 101), &typed), Err(ErrorValue::INCORRECT_DATA_TYPE.into()));
        let w = ValueBlock { format: Format::WORD, ..typed };
        assert_eq!(d.write_value(1, &value(10001, 101), &w), Err(ErrorValue::LIMIT_EXCEEDED.into()), "101 ≤ 102");
        let v = word(4000);
        let w = ValueBlock { format: Format::WORD, count: 1, bytes: &v };
        assert_eq!(d.write_value(1, &value(10001, 101), &w), Ok(()));
        assert_eq!(d.get(101, 0), Some(4000));
        assert_eq!(d.write_value(1, &value(20, 0), &w), Err(ErrorValue::VALUE_CANNOT_BE_CHANGED.into()));
        d.refuse = Some(Refusal { pnu: Some(10001), error: ErrorValue::NOT_EXECUTABLE });
        assert_eq!(d.write_value(1, &value(10001, 101), &w), Err(ErrorValue::NOT_EXECUTABLE.into()));
        assert_eq!((d.writes, d.write_calls), (1, 5));
        let mut buf = [0u8; 64];
        let mut out = ValueWriter::new(&mut buf);
        assert_eq!(d.read_description(1, &value(20, 1), &mut out), Err(ErrorValue::NO_DESCRIPTION.into()));
    }

    #[test]
    fn quirk_pnus_break_the_contract_and_the_encoder_still_answers() {
        const QUIRKS: &[QuirkPnu] = &[
            QuirkPnu { pnu: 1, read: Quirk::IgnoresFull, write: Ok(()) },
            QuirkPnu { pnu: 2, read: Quirk::Mixed, write: Ok(()) },
            QuirkPnu { pnu: 3, read: Quirk::Str(b"abc"), write: Ok(()) },
        ];
        let mut d = FakeDrive::empty().quirks(QUIRKS);
        // Read 100 × PNU 1 (overflows), 1 × PNU 2 (mixed), 1 × PNU 3.
        let req = [1, 1, 0, 3, 0x10, 100, 0, 1, 0, 0, 0x10, 1, 0, 2, 0, 0, 0x10, 1, 0, 3, 0, 0];
        let mut out = [0u8; MAX_LEN];
        let n = respond(&ParamRequest::parse(&req).unwrap(), &mut d, &mut out);
        assert_eq!(&out[..n], &[1, 0x81, 0, 3, 0x44, 1, 0, 0x15, 0x44, 1, 0, 0x05, 0x09, 3, b'a', b'b', b'c', 0]);
    }

    /// Through the mailbox a request is answered as the drive answers it directly: formats and
    /// numbers of values (words, a string, a float), descriptions, texts, the axes, a job of 39
    /// parameters (reference §5.2's longest request).
    #[test]
    fn the_mailbox_answers_as_the_drive_does() {
        let requests: [&[u8]; 3] = [
            // PNU 100 × 4, PNU 5 × 16 (VisibleString), PNU 7 (float), PNU 10 (Integer16).
            &[1, 1, 1, 4, 0x10, 4, 0, 100, 0, 0, 0x10, 16, 0, 5, 0, 0, 0x10, 1, 0, 7, 0, 0, 0x10, 1, 0, 10, 0, 0],
            // Description element 1 of PNU 2, text 2 of PNU 1, axis 7.
            &[2, 1, 1, 2, 0x20, 1, 0, 2, 0, 1, 0x30, 1, 0, 1, 0, 2],
            &[3, 1, 7, 1, 0x10, 1, 0, 2, 0, 0],
        ];
        // 39 different values: PNU 9, subindex 0 … 38.
        let many: std::vec::Vec<u8> =
            [4u8, 1, 0, 39].into_iter().chain((0..39u8).flat_map(|i| [0x10, 1, 0, 9, 0, i])).collect();
        for req in requests.iter().copied().chain([&many[..]]) {
            let req = ParamRequest::parse(req).unwrap();
            let (mut direct, mut out) = ([0u8; MAX_LEN], [0u8; MAX_LEN]);
            let n = respond(&req, &mut FakeDrive::new(), &mut direct);
            let mut m = Mailbox::new(FakeDrive::new());
            let mut passes = 0;
            m.start_job();
            let k = loop {
                let k = respond(&req, &mut m, &mut out);
                if !m.pending() {
                    break k;
                }
                m.deliver();
                passes += 1;
                assert!(passes < 100, "job never done");
            };
            assert_eq!(&out[..k], &direct[..n]);
            assert!(m.drive.read_calls <= 39, "a value sent for twice");
        }
    }

    #[test]
    fn the_mailbox_answers_after_the_drive_did() {
        let mut m = Mailbox::new(FakeDrive::new());
        let a = value(2, 0);
        assert_eq!(read(&mut m, 0, &a), Err(ErrorValue::NOT_EXECUTABLE.into()));
        assert!(m.pending());
        assert_eq!(m.inflight(), Some(&MailboxOp::Read(0, a)));
        assert_eq!(read(&mut m, 0, &value(101, 0)), Err(ErrorValue::NOT_EXECUTABLE.into()), "one at a time");
        m.deliver();
        assert!(!m.pending());
        assert_eq!(read(&mut m, 0, &a), Ok(vec![0x12, 0x34]));
        let v = word(7);
        let w = ValueBlock { format: Format::WORD, count: 1, bytes: &v };
        assert_eq!(m.write_value(0, &value(1, 0), &w), Err(ErrorValue::NOT_EXECUTABLE.into()));
        m.deliver();
        assert_eq!(m.write_value(0, &value(1, 0), &w), Ok(()));
        assert_eq!((m.drive.p1, m.delivered), (7, 2));
        m.start_job();
        assert_eq!(read(&mut m, 0, &a), Err(ErrorValue::NOT_EXECUTABLE.into()), "forgotten at the next job");
    }
}
