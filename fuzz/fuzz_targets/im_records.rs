//! I&M (slot 0 / index 255, `pbcard::dpv1::im`) and the flash journal that keeps it
//! (`pbcard::store`) on untrusted bytes: the call parser, a write then a read through the I&M
//! function, and the journal's slot decoder with the record decoders. No panic, and what they
//! accept is consistent.
#![no_main]

use libfuzzer_sys::fuzz_target;
use pbcard::dpv1::im::ImData;
use pbcard::dpv1::im::{Call, Im, CALL_HEADER_LEN, RECORD_LEN};
use pbcard::store::{decode_slot, encode_slot, Record, Slot, StationAddress, HEADER_LEN, SLOT_SIZE};

fuzz_target!(|data: &[u8]| {
    if let Ok(c) = Call::parse(data) {
        assert!(data.len() == CALL_HEADER_LEN || data.len() == CALL_HEADER_LEN + RECORD_LEN);
        assert!((65000..=65004).contains(&c.fi_index));
    }
    let mut im = Im::new(&pbcard::card::IM);
    let slot = data.first().map_or(0, |b| b & 1);
    let mut out = [0u8; 240];
    match im.write(slot, data) {
        Ok(()) => {
            assert_eq!(im.read(0, &mut out), Ok(CALL_HEADER_LEN + RECORD_LEN));
            assert_eq!(&out[..CALL_HEADER_LEN], &data[..CALL_HEADER_LEN]);
        }
        Err(e) => {
            let _ = e.error_code1();
            assert!(im.read(0, &mut out).is_err());
            assert_eq!(im.take_changed(), None);
        }
    }
    if data.len() >= SLOT_SIZE {
        let mut b = [0u8; SLOT_SIZE];
        b.copy_from_slice(&data[..SLOT_SIZE]);
        if let Slot::Valid(h) = decode_slot(&b) {
            let payload = &b[HEADER_LEN..HEADER_LEN + h.len as usize];
            assert_eq!(encode_slot(h.seq, h.kind, payload), b);
            if payload.len() == StationAddress::LEN {
                if let Some(a) = StationAddress::decode(payload) {
                    assert!(a.address <= 126);
                }
            }
            if payload.len() == ImData::LEN {
                let d = <ImData as Record>::decode(payload).expect("any I&M bytes");
                assert_eq!(&d.encode()[..], payload);
            }
        }
    }
});
