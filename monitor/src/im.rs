//! I&M records on the bus (reference §4.7; PROFIBUS Profile Guidelines Part 1
//! "Identification & Maintenance Functions"): the call header `08 00 FI_Index` of a DS_Write
//! (or Data_Transport) to slot 0 / index 255, and the records I&M0 … I&M4 that follow it.
//!
//! Every record is 64 bytes: a 10-byte manufacturer-specific header, then the fields (the
//! layout of `pbcard::dpv1::im`, the card's implementation):
//!
//! | record | fields (bytes after the header) |
//! |---|---|
//! | I&M0 (65000) | MANUFACTURER_ID 2, ORDER_ID 20, SERIAL_NUMBER 16, HARDWARE_REVISION 2, SOFTWARE_REVISION 4, REV_COUNTER 2, PROFILE_ID 2, PROFILE_SPECIFIC_TYPE 2, IM_VERSION 2, IM_SUPPORTED 2 |
//! | I&M1 (65001) | TAG_FUNCTION 32, TAG_LOCATION 22 (visible strings) |
//! | I&M2 (65002) | INSTALLATION_DATE 16 ("YYYY-MM-DD hh:mm"), reserved 38 |
//! | I&M3 (65003) | DESCRIPTOR 54 |
//! | I&M4 (65004) | SIGNATURE 54 (octets) |
//!
//! A DS_Read of index 255 answers the call header of the selected record, then the record
//! (4 + 64 bytes). Which record a read returns is the last call *on that relation* (MSAC_C1, or
//! one MSAC_C2 connection); the monitor tracks it ([`crate::Monitor`]) so that a device that
//! answers the bare 64-byte record is decoded as the right one too.

use std::fmt::Write as _;

use pbcard::dpv1::im::{CALL, CALL_HEADER_LEN, FI_IM0, HEADER_LEN, RECORD_LEN};

use pbcard_softslave::hex;

/// The record index of the I&M call (slot 0).
pub const INDEX: u8 = pbcard::dpv1::im::INDEX;

/// `I&M0` … `I&M15` for FI_Index 65000 … 65015 (the guideline's range), else `None`.
pub fn name(fi_index: u16) -> Option<String> {
    let k = fi_index.checked_sub(FI_IM0)?;
    (k <= 15).then(|| format!("I&M{k}"))
}

/// The FI_Index of a call header `08 00 FI_Index` at the start of `data`.
pub fn call_index(data: &[u8]) -> Option<u16> {
    match data {
        [CALL, 0, hi, lo, ..] => Some(u16::from_be_bytes([*hi, *lo])),
        _ => None,
    }
}

/// A visible string field: printable ASCII, others as `.`, trailing blanks and NULs cut.
pub fn visible(field: &[u8]) -> String {
    let end = field.iter().rposition(|&c| c != b' ' && c != 0).map_or(0, |i| i + 1);
    field[..end].iter().map(|&c| if (0x20..0x7F).contains(&c) { c as char } else { '.' }).collect()
}

/// One record (64 bytes: header and fields) of `fi_index`, field by field:
/// `I&M1: TAG_FUNCTION "…", TAG_LOCATION "…"`. Other lengths and records beyond I&M4 are shown
/// as bytes.
pub fn record(fi_index: u16, r: &[u8]) -> String {
    let Some(n) = name(fi_index) else { return format!("not an I&M record (IM_Index {fi_index}): {}", hex(r)) };
    if r.len() != RECORD_LEN {
        return format!("{n}: {} bytes, a record has {RECORD_LEN}: {}", r.len(), hex(r));
    }
    let (header, b) = r.split_at(HEADER_LEN);
    let w = |i: usize| u16::from_be_bytes([b[i], b[i + 1]]);
    let mut s = match fi_index - FI_IM0 {
        0 => format!(
            "I&M0: MANUFACTURER_ID {}, ORDER_ID \"{}\", SERIAL_NUMBER \"{}\", HARDWARE_REVISION {}, SOFTWARE_REVISION {}{}.{}.{}, REV_COUNTER {}, PROFILE_ID 0x{:04X}, PROFILE_SPECIFIC_TYPE {}, IM_VERSION {}.{}, IM_SUPPORTED 0x{:04X}",
            w(0),
            visible(&b[2..22]),
            visible(&b[22..38]),
            w(38),
            if b[40].is_ascii_graphic() { b[40] as char } else { '?' },
            b[41],
            b[42],
            b[43],
            w(44),
            w(46),
            w(48),
            b[50],
            b[51],
            w(52)
        ),
        1 => format!("I&M1: TAG_FUNCTION \"{}\", TAG_LOCATION \"{}\"", visible(&b[..32]), visible(&b[32..])),
        2 => {
            let mut s = format!("I&M2: INSTALLATION_DATE \"{}\"", visible(&b[..16]));
            let reserved = &b[16..];
            if reserved.iter().any(|&c| c != b' ' && c != 0) {
                let _ = write!(s, ", reserved {}", hex(reserved));
            }
            s
        }
        3 => format!("I&M3: DESCRIPTOR \"{}\"", visible(b)),
        4 => match b.iter().rposition(|&c| c != 0) {
            None => "I&M4: SIGNATURE none (54 zero bytes)".to_string(),
            Some(last) if last + 1 < b.len() => {
                format!("I&M4: SIGNATURE {} (then {} zero bytes)", hex(&b[..=last]), b.len() - last - 1)
            }
            Some(_) => format!("I&M4: SIGNATURE {}", hex(b)),
        },
        _ => format!("{n}: {}", hex(b)),
    };
    if header.iter().any(|&c| c != 0) {
        let _ = write!(s, ", manufacturer header {}", hex(header));
    }
    s
}

/// The data of a DS_Write / Data_Transport request to index 255: the call, and the record it
/// writes: `I&M function call, IM_Index 65001: I&M1: TAG_FUNCTION "…", TAG_LOCATION "…"`.
pub fn call(data: &[u8]) -> String {
    if data.len() < CALL_HEADER_LEN {
        return format!("I&M call too short ({} bytes, the header has {CALL_HEADER_LEN}): {}", data.len(), hex(data));
    }
    let Some(fi) = call_index(data) else {
        return format!(
            "not an I&M call (Extended_Function_Num {:02X}, reserved {:02X}; the call is 08 00): {}",
            data[0],
            data[1],
            hex(data)
        );
    };
    let n = name(fi).unwrap_or_else(|| "no I&M record".to_string());
    let body = &data[CALL_HEADER_LEN..];
    if body.is_empty() {
        format!("I&M function call, IM_Index {fi} ({n}): selected for the next read")
    } else {
        format!("I&M function call, IM_Index {fi}: {}", record(fi, body))
    }
}

/// The data of a DS_Read / Data_Transport response of index 255. With the call header, the
/// record it names (`IM_Index 65001: I&M1: …`), flagged when it is not what the relation's last
/// call (`selected`) asked for; a bare 64-byte record is taken as the selected one (I&M0
/// without a call).
pub fn response(data: &[u8], selected: Option<u16>) -> String {
    if let Some(fi) = call_index(data) {
        let mut s = format!("IM_Index {fi}: {}", record(fi, &data[CALL_HEADER_LEN..]));
        match selected {
            Some(sel) if sel != fi => {
                let _ = write!(s, " (NOT the record the call on this relation selected, IM_Index {sel})");
            }
            None => s.push_str(" (no call seen on this relation)"),
            Some(_) => {}
        }
        return s;
    }
    if data.len() == RECORD_LEN {
        return match selected {
            Some(fi) => format!("IM_Index {fi} (the call on this relation), without call header: {}", record(fi, data)),
            None => format!("no call seen on this relation, read as I&M0: {}", record(FI_IM0, data)),
        };
    }
    format!("I&M: {} bytes, neither call header + record nor a {RECORD_LEN}-byte record: {}", data.len(), hex(data))
}

#[cfg(test)]
mod tests {
    use super::*;
    use pbcard::dpv1::im::{DeviceIdent, Im, CONTENT_LEN, FI_IM4};
    use proptest::prelude::*;

    /// `08 00 FI_Index` + a 64-byte record with `content` (blank-padded) after a zero header.
    fn write_call(fi: u16, content: &[u8]) -> Vec<u8> {
        let mut d = vec![CALL, 0];
        d.extend_from_slice(&fi.to_be_bytes());
        d.extend_from_slice(&[0; HEADER_LEN]);
        let mut c = content.to_vec();
        c.resize(CONTENT_LEN, b' ');
        d.extend_from_slice(&c);
        d
    }

    /// What the card answers to a DS_Read after `call` (written on relation 0).
    fn card_read(im: &mut Im, call: &[u8]) -> Vec<u8> {
        im.write(0, call).expect("the card accepts the call");
        let mut out = [0u8; 240];
        let n = im.read(0, &mut out).expect("the card answers the read");
        out[..n].to_vec()
    }

    fn padded(fields: &[(&str, usize)]) -> Vec<u8> {
        let mut v = Vec::new();
        for (t, len) in fields {
            let mut f = t.as_bytes().to_vec();
            f.resize(*len, b' ');
            v.extend_from_slice(&f);
        }
        v
    }

    #[test]
    fn im1_tag_function_and_tag_location_field_by_field() {
        let w = write_call(65001, &padded(&[("Pump 3 main drive", 32), ("Hall B, rack 7", 22)]));
        assert_eq!(
            call(&w),
            "I&M function call, IM_Index 65001: I&M1: TAG_FUNCTION \"Pump 3 main drive\", TAG_LOCATION \"Hall B, rack 7\""
        );
        let r = card_read(&mut Im::new(&pbcard::card::IM), &w);
        assert_eq!(r.len(), 68);
        assert_eq!(
            response(&r, Some(65001)),
            "IM_Index 65001: I&M1: TAG_FUNCTION \"Pump 3 main drive\", TAG_LOCATION \"Hall B, rack 7\""
        );
        // A full 32-character TAG_FUNCTION ends exactly at TAG_LOCATION.
        let w = write_call(65001, &padded(&[("ABCDEFGHIJKLMNOPQRSTUVWXYZ012345", 32), ("L", 22)]));
        assert!(call(&w).ends_with("TAG_FUNCTION \"ABCDEFGHIJKLMNOPQRSTUVWXYZ012345\", TAG_LOCATION \"L\""));
        // As shipped (blanks): empty fields.
        let r = card_read(&mut Im::new(&pbcard::card::IM), &[CALL, 0, 0xFD, 0xE9]);
        assert_eq!(response(&r, Some(65001)), "IM_Index 65001: I&M1: TAG_FUNCTION \"\", TAG_LOCATION \"\"");
    }

    #[test]
    fn im2_installation_date_field_by_field() {
        let w = write_call(65002, b"2026-12-01 22:40");
        assert_eq!(call(&w), "I&M function call, IM_Index 65002: I&M2: INSTALLATION_DATE \"2026-12-01 22:40\"");
        let r = card_read(&mut Im::new(&pbcard::card::IM), &w);
        assert_eq!(response(&r, Some(65002)), "IM_Index 65002: I&M2: INSTALLATION_DATE \"2026-12-01 22:40\"");
        // Something in the 38 reserved bytes is shown.
        let mut c = b"2026-12-01 22:40".to_vec();
        c.resize(CONTENT_LEN, b' ');
        c[20] = 0x7F;
        assert!(call(&write_call(65002, &c)).ends_with(&format!("\"2026-12-01 22:40\", reserved {}", {
            let mut r = vec![b' '; 38];
            r[4] = 0x7F;
            hex(&r)
        })));
    }

    #[test]
    fn im3_descriptor_field_by_field() {
        let text = "Main pump drive, replaced bearing 2026-11, see log 17."; // 54 characters
        assert_eq!(text.len(), 54);
        let w = write_call(65003, text.as_bytes());
        let r = card_read(&mut Im::new(&pbcard::card::IM), &w);
        assert_eq!(response(&r, Some(65003)), format!("IM_Index 65003: I&M3: DESCRIPTOR \"{text}\""));
        // Not printable: shown as dots, and the trailing blanks are cut.
        let w = write_call(65003, b"a\x01b\xFFc");
        assert_eq!(call(&w), "I&M function call, IM_Index 65003: I&M3: DESCRIPTOR \"a.b.c\"");
    }

    #[test]
    fn im4_signature_field_by_field() {
        let mut sig = [0u8; CONTENT_LEN];
        sig[..4].copy_from_slice(&[0xDE, 0xAD, 0xBE, 0xEF]);
        let r = card_read(&mut Im::new(&pbcard::card::IM), &write_call(65004, &sig));
        assert_eq!(response(&r, Some(65004)), "IM_Index 65004: I&M4: SIGNATURE DE AD BE EF (then 50 zero bytes)");
        // As shipped: zeros.
        let r = card_read(&mut Im::new(&pbcard::card::IM), &[CALL, 0, 0xFD, 0xEC]);
        assert_eq!(response(&r, Some(65004)), "IM_Index 65004: I&M4: SIGNATURE none (54 zero bytes)");
        let full = [0xA5u8; CONTENT_LEN];
        let r = card_read(&mut Im::new(&pbcard::card::IM), &write_call(65004, &full));
        assert_eq!(response(&r, Some(65004)), format!("IM_Index 65004: I&M4: SIGNATURE {}", hex(&full)));
    }

    #[test]
    fn im0_of_the_card_and_the_call_header() {
        let mut im = Im::new(&pbcard::card::IM);
        let mut serial = [b' '; 16];
        serial[..6].copy_from_slice(b"SN-001");
        im.set_ident(DeviceIdent { serial_number: serial, hardware_revision: 2 });
        assert_eq!(
            call(&[CALL, 0, 0xFD, 0xE8]),
            "I&M function call, IM_Index 65000 (I&M0): selected for the next read"
        );
        let r = card_read(&mut im, &[CALL, 0, 0xFD, 0xE8]);
        let t = response(&r, Some(65000));
        assert!(
            t.starts_with(&format!(
                "IM_Index 65000: I&M0: MANUFACTURER_ID {}, ORDER_ID \"{}\", SERIAL_NUMBER \"SN-001\", HARDWARE_REVISION 2, SOFTWARE_REVISION V",
                pbcard::card::IM_MANUFACTURER_ID,
                pbcard::card::IM_ORDER_ID
            )),
            "{t}"
        );
        assert!(
            t.ends_with(
                "REV_COUNTER 0, PROFILE_ID 0x3A00, PROFILE_SPECIFIC_TYPE 0, IM_VERSION 1.1, IM_SUPPORTED 0x000F"
            ),
            "{t}"
        );
        // The bare record (a device without the header in its answer) and no call.
        assert!(
            response(&r[4..], None).starts_with("no call seen on this relation, read as I&M0: I&M0: MANUFACTURER_ID")
        );
    }

    #[test]
    fn the_relation_and_malformed_calls() {
        let r = card_read(&mut Im::new(&pbcard::card::IM), &[CALL, 0, 0xFD, 0xE9]);
        assert!(
            response(&r, Some(65000)).ends_with("(NOT the record the call on this relation selected, IM_Index 65000)")
        );
        assert!(response(&r, None).ends_with("(no call seen on this relation)"));
        assert!(response(&r[4..], Some(65001))
            .starts_with("IM_Index 65001 (the call on this relation), without call header: I&M1: "));
        assert_eq!(call(&[CALL, 0]), "I&M call too short (2 bytes, the header has 4): 08 00");
        assert_eq!(
            call(&[0x09, 0, 0xFD, 0xE8]),
            "not an I&M call (Extended_Function_Num 09, reserved 00; the call is 08 00): 09 00 FD E8"
        );
        assert_eq!(
            call(&[CALL, 0, 0x00, 0x01]),
            "I&M function call, IM_Index 1 (no I&M record): selected for the next read"
        );
        assert_eq!(
            call(&[CALL, 0, 0xFD, 0xE9, 1, 2]),
            "I&M function call, IM_Index 65001: I&M1: 2 bytes, a record has 64: 01 02"
        );
        assert!(response(&[1, 2, 3], None).starts_with("I&M: 3 bytes"));
        let mut rec = vec![1u8; RECORD_LEN];
        rec[HEADER_LEN..].fill(b' ');
        assert!(record(65003, &rec).ends_with(", manufacturer header 01 01 01 01 01 01 01 01 01 01"));
    }

    proptest! {
        /// The I&M decoders take any bytes and any selection without a panic.
        #[test]
        fn any_bytes_decode(data in proptest::collection::vec(any::<u8>(), 0..240), sel in any::<Option<u16>>()) {
            let _ = call(&data);
            let _ = response(&data, sel);
            let fi = call_index(&data).unwrap_or(FI_IM0);
            let _ = record(fi, &data);
        }

        /// The record decoder of DS_Write / DS_Read and Data_Transport takes any index and data.
        #[test]
        fn any_record_data_decodes(
            index in prop_oneof![Just(47u8), Just(INDEX), any::<u8>()],
            data in proptest::collection::vec(any::<u8>(), 0..240),
            pnus in proptest::collection::vec(any::<u16>(), 0..4),
            sel in any::<Option<u16>>(),
        ) {
            let _ = crate::decode::record_write(index, &data);
            let _ = crate::decode::record_read(index, &data, &pnus, sel);
        }

        /// What the card encodes comes back field by field: I&M1–3 texts (printable, as a
        /// master writes them) written through the card's I&M function and read back are the
        /// decoded fields; an I&M4 signature its bytes.
        #[test]
        fn card_records_round_trip(
            k in 1u16..=4,
            a in "[ -~]{0,32}",
            b in "[ -~]{0,22}",
            sig in proptest::collection::vec(any::<u8>(), CONTENT_LEN),
        ) {
            let fi = FI_IM0 + k;
            let content = match k {
                1 => padded(&[(&a, 32), (&b, 22)]),
                2 => padded(&[(&a[..a.len().min(16)], 16), ("", 38)]),
                3 => padded(&[(&format!("{a}{b}"), CONTENT_LEN)]),
                _ => sig.clone(),
            };
            let w = write_call(fi, &content);
            let r = card_read(&mut Im::new(&pbcard::card::IM), &w);
            prop_assert_eq!(&r[..4], &w[..4]);
            let text = response(&r, Some(fi));
            let want = match k {
                1 => format!("I&M1: TAG_FUNCTION \"{}\", TAG_LOCATION \"{}\"", a.trim_end(), b.trim_end()),
                2 => format!("I&M2: INSTALLATION_DATE \"{}\"", a[..a.len().min(16)].trim_end()),
                3 => format!("I&M3: DESCRIPTOR \"{}\"", format!("{a}{b}").trim_end()),
                _ => record(FI_IM4, &r[4..]),
            };
            prop_assert_eq!(&text, &format!("IM_Index {fi}: {want}"));
            prop_assert_eq!(call(&w), format!("I&M function call, IM_Index {fi}: {want}"));
            if k == 4 {
                // The signature's bytes are in the text, in order.
                let last = sig.iter().rposition(|&c| c != 0);
                if let Some(l) = last {
                    prop_assert!(text.contains(&hex(&sig[..=l])));
                }
            }
        }
    }
}
