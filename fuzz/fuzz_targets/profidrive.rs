//! PROFIdrive parameter access (`profile::param`, record 47) and WEG's simple access
//! (`profile::weg48`, record 48) on arbitrary bytes (the whole input is the DS_Write data).
//!
//! Checks:
//! * `ParamRequest::parse`: no panic; an accepted request has the header fields of the input,
//!   yields `No_of_Parameters` parameters (with value blocks exactly for a change request), and
//!   re-emitted by the master's `emit_request` parses to the same parameters (pad bytes may
//!   differ; a 240-byte request without the optional last pad cannot be re-emitted padded).
//! * `respond` against the fake table of `pbcard::testkit::FakeDrive`, twice (the second run sees
//!   the first one's writes): 4..=240 bytes; `ParamResponse::parse` accepts it with reference,
//!   axis and No_of_Parameters mirrored and Response_ID = request ID | 0x80 exactly when a
//!   parameter failed; a positive change response is the header alone; otherwise one block
//!   per parameter (`40 00` or an error block in a negative change response, error blocks of
//!   one or two values).
//! * A refused request: `RequestError` mirrors the header bytes, and its `emit_response` is a
//!   parseable negative response (≤ 160 bytes) with one error block per parameter.
//! * weg48: `Request::parse` accepts exactly 2 and 4 bytes and round-trips; `SimpleAccess`
//!   write + reads (with 0..4 bytes of room) never panic, give one of WEG's seven codes, and a
//!   read returns 2 bytes only after a successful selection.
#![no_main]

use libfuzzer_sys::fuzz_target;
use pbcard::dpv1::pdu::EmitError;
use pbcard::profile::param::{
    emit_request, respond, Format, ParamRequest, ParamResponse, Parameter, RequestErrorKind, RequestId, ResponseId,
    HEADER_LEN, MAX_LEN, MAX_PARAMETERS,
};
use pbcard::profile::weg48::{self, SimpleAccess, Weg48Error};
use pbcard::testkit::FakeDrive;

fn check_response(req: &ParamRequest<'_>, out: &[u8; MAX_LEN], n: usize) {
    assert!((HEADER_LEN..=MAX_LEN).contains(&n), "response length {n}");
    let r =
        ParamResponse::parse(&out[..n]).unwrap_or_else(|e| panic!("response {:02x?} does not parse: {e:?}", &out[..n]));
    assert_eq!((r.reference, r.axis, r.count as usize), (req.reference, req.axis, req.len()), "not mirrored");
    let failed = r.id.0 & 0x80 != 0;
    assert_eq!(r.id.0 & 0x7F, req.id as u8, "Response_ID {:02x}", r.id.0);
    let blocks: Vec<_> = r.values().collect();
    let is_error = |b: &pbcard::profile::param::ValueBlock<'_>| b.format == Format::ERROR;
    for b in blocks.iter().filter(|b| is_error(b)) {
        assert!(matches!(b.count, 1 | 2) && b.error().is_some(), "error block {b:?}");
    }
    match (req.id, failed) {
        (RequestId::Change, false) => assert_eq!(n, HEADER_LEN, "positive change response {:02x?}", &out[..n]),
        (RequestId::Change, true) => {
            assert_eq!(blocks.len(), req.len());
            assert!(blocks.iter().all(|b| is_error(b) || (b.format == Format::ZERO && b.count == 0)), "{blocks:?}");
            assert!(blocks.iter().any(is_error));
        }
        (RequestId::Read, _) => {
            assert_eq!(blocks.len(), req.len(), "read response {:02x?}", &out[..n]);
            assert_eq!(blocks.iter().any(is_error), failed, "read response {:02x?}", &out[..n]);
        }
    }
}

fn check_param(data: &[u8], table: &mut FakeDrive) {
    let at = |i: usize| data.get(i).copied().unwrap_or(0);
    let req = match ParamRequest::parse(data) {
        Ok(req) => req,
        Err(e) => {
            assert_eq!((e.reference, e.request_id, e.axis, e.count), (at(0), at(1), at(2), at(3)));
            assert_eq!(e.error_code1().0, 0xB7);
            if let RequestErrorKind::IllegalFormat(f) = e.kind {
                assert!(Format(f).value_size().is_none());
            }
            let mut out = [0u8; MAX_LEN];
            let n = e.emit_response(&mut out);
            assert!((8..=160).contains(&n), "negative response length {n}");
            let r = ParamResponse::parse(&out[..n]).unwrap_or_else(|k| panic!("{:02x?}: {k:?}", &out[..n]));
            assert_eq!((r.reference, r.axis), (e.reference, e.axis));
            assert!(matches!(r.id, ResponseId::INVALID_REQUEST_ID | ResponseId::READ_ERROR | ResponseId::CHANGE_ERROR));
            let expected = if (1..=MAX_PARAMETERS).contains(&e.count) { e.count } else { 1 };
            assert_eq!(r.count, expected);
            let blocks: Vec<_> = r.values().collect();
            assert_eq!(blocks.len(), expected as usize);
            assert!(blocks.iter().all(|b| b.error().map(|x| x.value) == Some(e.error_value())));
            return;
        }
    };
    assert!(data.len() <= MAX_LEN);
    assert_eq!((req.reference, req.id as u8, req.axis, req.len()), (data[0], data[1], data[2], data[3] as usize));
    assert!(req.reference != 0 && (1..=MAX_PARAMETERS as usize).contains(&req.len()) && !req.is_empty());
    let params: Vec<Parameter<'_>> = req.parameters().collect();
    assert_eq!(params.len(), req.len());
    assert!(params.iter().all(|p| p.value.is_some() == (req.id == RequestId::Change)));

    // The master's side: emit the same request again.
    let mut buf = [0u8; 512];
    match emit_request(&mut buf, req.reference, req.id, req.axis, &params) {
        Ok(m) => {
            assert!(m == data.len() || m == data.len() + 1, "re-emitted {m} bytes of {}", data.len());
            let again =
                ParamRequest::parse(&buf[..m]).unwrap_or_else(|e| panic!("re-emitted {:02x?}: {e:?}", &buf[..m]));
            assert_eq!((again.reference, again.id, again.axis), (req.reference, req.id, req.axis));
            assert_eq!(again.parameters().collect::<Vec<_>>(), params);
        }
        Err(e) => {
            // Only the pad after the last odd value block (optional when parsing) can push it over.
            assert_eq!(e, EmitError::TooLong);
            assert_eq!(data.len(), MAX_LEN, "{data:02x?} not re-emittable");
        }
    }

    for _ in 0..2 {
        let mut out = [0u8; MAX_LEN];
        let n = respond(&req, table, &mut out);
        check_response(&req, &out, n);
    }
}

fn check_weg(data: &[u8], table: &mut FakeDrive) {
    match weg48::Request::parse(data) {
        Ok(r) => {
            assert!(matches!(data.len(), 2 | 4));
            let mut out = [0u8; 4];
            let n = r.emit(&mut out).expect("emit");
            assert_eq!(&out[..n], data);
            assert!(r.emit(&mut out[..n - 1]).is_err());
        }
        Err(e) => {
            assert!(!matches!(data.len(), 2 | 4));
            assert_eq!(e, Weg48Error::InvalidValues);
        }
    }
    let mut weg = SimpleAccess::new();
    let w = weg.on_write(data, 0, table);
    if let Err(e) = w {
        assert_eq!(Weg48Error::from_error_code1(e.error_code1()), Some(e));
    }
    match (w, data) {
        (Ok(()), &[a, b]) => assert_eq!(weg.selected(), Some(u16::from_be_bytes([a, b]))),
        _ => assert_eq!(weg.selected(), None),
    }
    for room in 0..=4 {
        let mut out = [0xEEu8; 4];
        match weg.on_read(0, table, &mut out[..room]) {
            Ok(n) => {
                assert!(weg.selected().is_some() && n == 2 && room >= 2);
                assert!(weg48::parse_read_data(&out[..n]).is_some());
            }
            Err(e) => {
                assert_eq!(Weg48Error::from_error_code1(e.error_code1()), Some(e));
                if weg.selected().is_none() {
                    assert_eq!(e, Weg48Error::ResponseNotAvailable);
                }
            }
        }
    }
    if let [a, b, ..] = *data {
        let _ = Weg48Error::from_error_value(pbcard::profile::param::ErrorValue(u16::from_be_bytes([a, b])));
    }
}

fuzz_target!(|data: &[u8]| {
    let mut table = FakeDrive::new();
    check_param(data, &mut table);
    check_weg(data, &mut table);
});
