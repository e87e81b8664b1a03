//! The bus monitor's capture format on untrusted text: `capture::parse_line` never panics, a
//! chunk it reads writes back to a line that reads the same, and a whole replay of the text
//! (cutter, decoder, per-station bookkeeping) never panics.
#![no_main]

use libfuzzer_sys::fuzz_target;
use pbcard_monitor::capture::{parse_line, Record, Writer};
use pbcard_monitor::product::Product;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    for line in text.lines() {
        if let Ok(Record::Bytes { t_us, bytes }) = parse_line(line) {
            let mut w = Writer::new(Vec::new(), None).unwrap();
            w.bytes(t_us, &bytes).unwrap();
            let out = String::from_utf8(w.into_inner()).unwrap();
            let back = out.lines().nth(1).map(parse_line);
            assert_eq!(back, Some(Ok(Record::Bytes { t_us, bytes })), "{line:?}");
        }
    }
    let _ = pbcard_monitor::replay(Product::card(), &text, Some(10_000));
});
