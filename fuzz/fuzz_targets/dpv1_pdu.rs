//! The DP-V1 PDU codec (`dpv1::pdu`) and the record service (`dpv1::channel::serve_records`) on
//! arbitrary bytes (the whole input is one PDU).
//!
//! Checks:
//! * `pdu::parse`: no panic; an accepted request re-emits (`Request::emit`) to `buffer_len()`
//!   bytes that parse to the same request — byte for byte the input when it was in canonical
//!   form (Abort and Idle have a short form, Initiate's reserved bytes are sent as 0); a buffer
//!   one byte short is refused with `BufferTooSmall`; the error helpers do not panic.
//! * `Response::parse`: no panic; an accepted response re-emits and re-parses equal (Abort
//!   without detail comes back with detail 0).
//! * `serve_records` (with and without Data_Transport) over a fake [`RecordHandler`]: no
//!   panic; a PDU of 4..=244 bytes that `Response::parse` accepts, or the 4-byte error PDU
//!   `req[0] | 0x80, 0x80, ec1, 0` (for a first byte that is no function); the response
//!   mirrors the request (function, slot, index, write length, read data ≤ the length asked)
//!   and carries the handler's error code; the handler is only called for valid requests
//!   and sees exactly the room the request allows.
#![no_main]

use libfuzzer_sys::fuzz_target;
use pbcard::dpv1::channel::serve_records;
use pbcard::dpv1::pdu::{
    self, EmitError, ErrorCode1, Function, InitiateResponse, Request, Response, ERROR_BIT, ERROR_DECODE_DPV1,
    MAX_DATA_LEN, MAX_PDU_LEN,
};
use pbcard::dpv1::records::RecordHandler;
use pbcard::time::Instant;

const RECORDS: usize = 8;
const RECORD_LEN: usize = 64;

/// A record handler whose behaviour the request's slot selects:
/// * slot 0: a store of 8 records (index 0..8) of up to 64 bytes (longer writes 0xB1, other
///   indices 0xB0);
/// * slot 1: every access fails with Error_Code_1 = the index byte (any value, also ones
///   outside the DP-V1 table);
/// * slot 2: a read fills all the room it is given, a write succeeds;
/// * slot 3: a read returns no bytes, a write succeeds;
/// * any other slot: 0xB2 invalid slot.
struct Fake {
    rec: [[u8; RECORD_LEN]; RECORDS],
    len: [usize; RECORDS],
    reads: u32,
    writes: u32,
    /// The room (`out.len()`) of the last read.
    read_room: usize,
    /// What the last successful read returned.
    read_data: Vec<u8>,
}

impl Fake {
    fn new() -> Self {
        let mut f = Fake {
            rec: [[0; RECORD_LEN]; RECORDS],
            len: [0; RECORDS],
            reads: 0,
            writes: 0,
            read_room: 0,
            read_data: vec![],
        };
        for (i, r) in f.rec.iter_mut().enumerate() {
            for (j, b) in r.iter_mut().enumerate() {
                *b = (i * 16 + j) as u8;
            }
            f.len[i] = i * 9; // 0, 9, 18 … 63
        }
        f
    }
}

impl RecordHandler for Fake {
    fn read(&mut self, _: Instant, slot: u8, index: u8, out: &mut [u8]) -> Result<usize, ErrorCode1> {
        self.reads += 1;
        self.read_room = out.len();
        let n = match slot {
            0 => {
                let i = index as usize;
                if i >= RECORDS {
                    return Err(ErrorCode1::INVALID_INDEX);
                }
                let n = self.len[i].min(out.len());
                out[..n].copy_from_slice(&self.rec[i][..n]);
                n
            }
            1 => return Err(ErrorCode1(index)),
            2 => {
                for (k, b) in out.iter_mut().enumerate() {
                    *b = k as u8 ^ index;
                }
                out.len()
            }
            3 => 0,
            _ => return Err(ErrorCode1::INVALID_SLOT),
        };
        self.read_data = out[..n].to_vec();
        Ok(n)
    }

    fn write(&mut self, _: Instant, slot: u8, index: u8, data: &[u8]) -> Result<(), ErrorCode1> {
        self.writes += 1;
        match slot {
            0 => {
                let i = index as usize;
                if i >= RECORDS {
                    return Err(ErrorCode1::INVALID_INDEX);
                }
                if data.len() > RECORD_LEN {
                    return Err(ErrorCode1::WRITE_LENGTH_ERROR);
                }
                self.rec[i][..data.len()].copy_from_slice(data);
                self.len[i] = data.len();
                Ok(())
            }
            1 => Err(ErrorCode1(index)),
            2 | 3 => Ok(()),
            _ => Err(ErrorCode1::INVALID_SLOT),
        }
    }
}

fn check_request(data: &[u8]) {
    let parsed = pdu::parse(data);
    if let Err(e) = &parsed {
        let _ = (e.error_code1(), e.abort_reason(), e.function());
        return;
    }
    let r = parsed.unwrap();
    assert!(r.function().code() == data[0], "{r:?} from first byte {:02x}", data[0]);
    let n = r.buffer_len();
    match r {
        Request::Abort(a) if a.detail.is_none() => assert_eq!(n, data.len() + 1),
        Request::Idle if data.len() == 1 => assert_eq!(n, 2),
        _ => assert_eq!(n, data.len(), "buffer_len of {r:?}"),
    }
    let mut out = [0u8; 600];
    let emitted = r.emit(&mut out);
    if data.len() > MAX_PDU_LEN {
        // Only an Initiate is accepted beyond the 244-byte PDU (its address blocks are only
        // checked to fill the PDU); it cannot be re-emitted. FDL never delivers such a PDU.
        assert!(matches!(r, Request::Initiate(_)), "{r:?}: {} bytes accepted", data.len());
        assert_eq!(emitted, Err(EmitError::TooLong));
        return;
    }
    let m = emitted.unwrap_or_else(|e| panic!("{r:?} parsed from {data:02x?} does not re-emit: {e:?}"));
    assert_eq!(m, n);
    // Abort: the short form comes back with detail 0.
    let normal = match r {
        Request::Abort(a) if a.detail.is_none() => Request::Abort(pdu::Abort { detail: Some(0), ..a }),
        _ => r,
    };
    assert_eq!(pdu::parse(&out[..m]), Ok(normal), "re-emitted {:02x?}", &out[..m]);
    // Bytes the codec does not keep: Abort's Instance/Reason b7..b6, Idle's reserved byte,
    // Initiate's reserved bytes 1..3.
    let canonical = match r {
        Request::Abort(_) => data.len() == 4 && data[2] & 0xC0 == 0,
        Request::Idle => data == [0x48, 0],
        Request::Initiate(_) => data[1..4] == [0, 0, 0],
        _ => true,
    };
    if canonical {
        assert_eq!(&out[..m], data, "re-emitted request differs");
    }
    assert_eq!(r.emit(&mut out[..m - 1]), Err(EmitError::BufferTooSmall { needed: m }));
    // An Initiate.req is answered with the S and D blocks swapped; that response round-trips.
    if let Request::Initiate(init) = r {
        let resp = Response::Initiate(InitiateResponse::answering(&init, 240, [1, 0], [0, 0], 0));
        let k = resp.emit(&mut out).expect("Initiate.res to a ≤ 244-byte Initiate.req");
        assert_eq!(k, m - 4);
        assert_eq!(Response::parse(&out[..k]), Ok(resp));
    }
}

fn check_response_codec(data: &[u8]) {
    let Ok(resp) = Response::parse(data) else { return };
    let mut out = [0u8; 600];
    match resp.emit(&mut out) {
        Ok(m) => {
            assert_eq!(m, resp.buffer_len());
            let again = Response::parse(&out[..m])
                .unwrap_or_else(|e| panic!("{resp:?} re-emitted as {:02x?}: {e:?}", &out[..m]));
            match (resp, again) {
                (Response::Abort(a), Response::Abort(b)) if a.detail.is_none() => {
                    assert_eq!(b, pdu::Abort { detail: Some(0), ..a })
                }
                _ => assert_eq!(again, resp),
            }
        }
        Err(e) => {
            // Only an Initiate.res can be accepted longer than a PDU may be.
            assert!(matches!(resp, Response::Initiate(_)) && data.len() > MAX_PDU_LEN, "{resp:?}: {e:?}");
        }
    }
}

fn check_serve(data: &[u8], allow_transport: bool) {
    let mut h = Fake::new();
    let before = h.rec;
    // The channel's buffer: exactly one PDU, prefilled with garbage.
    let mut out = [0xEEu8; MAX_PDU_LEN];
    let n = serve_records(Instant::from_micros(1), data, &mut out, &mut h, allow_transport);
    assert!((4..=MAX_PDU_LEN).contains(&n), "serve_records returned {n} for {data:02x?}");
    let resp = &out[..n];
    let parsed_req = pdu::parse(data);
    let parsed = Response::parse(resp);
    let err_pdu = |ec1: u8| [data.first().copied().unwrap_or(0) | ERROR_BIT, ERROR_DECODE_DPV1, ec1, 0];
    let req = match parsed_req {
        Err(e) => {
            assert_eq!((h.reads, h.writes), (0, 0), "handler called for the malformed {data:02x?}");
            let ec1 = e.error_code1().unwrap_or(ErrorCode1::FEATURE_NOT_SUPPORTED);
            assert_eq!(resp, err_pdu(ec1.0), "answer to malformed {data:02x?} ({e:?})");
            if parsed.is_err() {
                assert!(Function::from_code(data.first().copied().unwrap_or(0) & !ERROR_BIT).is_none());
            }
            return;
        }
        Ok(r) => r,
    };
    let resp = parsed.unwrap_or_else(|e| panic!("serve_records answered {data:02x?} with {resp:02x?}: {e:?}"));
    let error_of = |resp: Response<'_>, f: Function| match resp {
        Response::Error { function, decode, code1, code2 } => {
            assert_eq!((function, decode, code2), (f, ERROR_DECODE_DPV1, 0), "{resp:?} to {req:?}");
            Some(code1)
        }
        _ => None,
    };
    match req {
        Request::Read(r) => {
            assert_eq!((h.reads, h.writes), (1, 0));
            assert_eq!(h.read_room, (r.length as usize).min(MAX_DATA_LEN), "room offered for {r:?}");
            match resp {
                Response::Read(d) => {
                    assert_eq!((d.slot, d.index), (r.slot, r.index));
                    assert!(d.data.len() <= r.length as usize);
                    assert_eq!(d.data, &h.read_data[..]);
                }
                other => assert!(error_of(other, Function::Read).is_some(), "{other:?} to {r:?}"),
            }
        }
        Request::Write(w) => {
            assert_eq!((h.reads, h.writes), (0, 1));
            match resp {
                Response::Write { slot, index, length } => {
                    assert_eq!((slot, index, length as usize), (w.slot, w.index, w.data.len()));
                    if w.slot == 0 {
                        assert_eq!(&h.rec[w.index as usize][..w.data.len()], w.data);
                    }
                }
                other => assert!(error_of(other, Function::Write).is_some(), "{other:?} to {w:?}"),
            }
        }
        Request::DataTransport(d) if allow_transport => match resp {
            Response::DataTransport(r) => {
                assert_eq!((h.reads, h.writes), (1, 1));
                assert_eq!(h.read_room, MAX_DATA_LEN);
                assert_eq!((r.slot, r.index, r.data), (d.slot, d.index, &h.read_data[..]));
            }
            other => assert!(error_of(other, Function::DataTransport).is_some(), "{other:?} to {d:?}"),
        },
        Request::AlarmAck(_) => {
            assert_eq!(error_of(resp, Function::AlarmAck), Some(ErrorCode1::STATE_CONFLICT));
        }
        other => {
            assert_eq!((h.reads, h.writes), (0, 0));
            assert_eq!(error_of(resp, other.function()), Some(ErrorCode1::FEATURE_NOT_SUPPORTED), "{other:?}");
            assert_eq!(h.rec, before);
        }
    }
}

fuzz_target!(|data: &[u8]| {
    check_request(data);
    check_response_codec(data);
    check_serve(data, false);
    check_serve(data, true);
});
