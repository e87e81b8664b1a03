//! `telegram::decode` and `telegram::frame_len` on untrusted bytes: no panic, the two agree,
//! and a decoded data telegram re-emitted with `telegram::emit` decodes to the same fields
//! (byte for byte the same frame when the original used the format `emit` picks).
#![no_main]

use libfuzzer_sys::fuzz_target;
use pbcard::fdl::telegram::{self, DataFormat, Decoded, Header, Telegram, MAX_FRAME_LEN};

fuzz_target!(|data: &[u8]| {
    let announced = telegram::frame_len(data);
    match telegram::decode(data) {
        Decoded::Frame(t, n) => {
            assert!(n >= 1 && n <= data.len() && n <= MAX_FRAME_LEN, "frame length {n} of {}", data.len());
            assert_eq!(announced, Ok(Some(n)), "frame_len disagrees with decode");
            // Trailing bytes do not matter.
            assert_eq!(telegram::decode(&data[..n]), Decoded::Frame(t, n));
            if let Telegram::Data(d) = t {
                assert!(d.da < 128 && d.sa < 128);
                assert!(d.dsap.is_none_or(|s| s < 64) && d.ssap.is_none_or(|s| s < 64));
                let hdr = Header { da: d.da, sa: d.sa, fc: d.fc, dsap: d.dsap, ssap: d.ssap };
                let mut out = [0u8; MAX_FRAME_LEN];
                let m = telegram::emit(&mut out, &hdr, d.pdu).expect("a decoded telegram must be re-emittable");
                match telegram::decode(&out[..m]) {
                    Decoded::Frame(Telegram::Data(e), k) => {
                        assert_eq!(k, m);
                        assert_eq!((e.da, e.sa, e.fc, e.dsap, e.ssap), (d.da, d.sa, d.fc, d.dsap, d.ssap));
                        assert_eq!(e.pdu, d.pdu);
                        // emit picks SD1 for an empty DU, SD3 for 8 DU bytes, SD2 otherwise.
                        let du = d.dsap.is_some() as usize + d.ssap.is_some() as usize + d.pdu.len();
                        let canonical = match du {
                            0 => DataFormat::Sd1,
                            8 => DataFormat::Sd3,
                            _ => DataFormat::Sd2,
                        };
                        assert_eq!(e.format, canonical);
                        if d.format == canonical {
                            assert_eq!(&out[..m], &data[..n], "re-emitted frame differs");
                        }
                    }
                    other => panic!("re-emitted {:02x?} decodes as {other:?}", &out[..m]),
                }
            }
        }
        Decoded::Incomplete => match announced {
            Ok(None) => {}
            Ok(Some(n)) => assert!(n > data.len(), "Incomplete but {n} <= {}", data.len()),
            Err(e) => panic!("decode says Incomplete, frame_len says {e:?}"),
        },
        Decoded::Invalid(_) => {}
    }
});
