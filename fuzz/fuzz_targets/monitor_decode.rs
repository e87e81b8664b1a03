//! The bus monitor's decoder on arbitrary line bytes, cut into arbitrary chunks with arbitrary
//! times (first byte: chunk length seed): never panics, and the cutter loses no byte — the
//! telegrams and garbage runs it reports add up to the input. The same bytes as record data
//! (DS_Write / DS_Read / Data_Transport of record 47 and I&M, `decode::record_write`,
//! `decode::record_read`, `im::*`) never panic either.
#![no_main]

use libfuzzer_sys::fuzz_target;
use pbcard_monitor::cut::{Cut, Cutter};
use pbcard_monitor::product::Product;
use pbcard_monitor::Monitor;
use pbcard_monitor::{decode, im};

fuzz_target!(|data: &[u8]| {
    let Some((&seed, bytes)) = data.split_first() else { return };
    for index in [47, im::INDEX, seed] {
        let _ = decode::record_write(index, bytes);
        let _ = decode::record_read(index, bytes, &[918, 10001], Some(65000 + u16::from(seed % 20)));
    }
    let _ = im::response(bytes, None);
    let _ = im::record(65000 + u16::from(seed % 20), bytes);
    let step = usize::from(seed % 17) + 1;
    let mut cutter = Cutter::new();
    let mut mon = Monitor::new(Product::card(), Some(pbcard::time::Baudrate::ALL[usize::from(seed % 10)]));
    let mut cuts = Vec::new();
    for (i, chunk) in bytes.chunks(step).enumerate() {
        let t = (i as u64) * u64::from(seed) * 37;
        if seed & 0x80 != 0 && i % 5 == 4 {
            cutter.gap(&mut cuts);
        }
        cutter.push(Some(t), chunk, &mut cuts);
    }
    cutter.finish(&mut cuts);
    let mut total = 0;
    for c in &cuts {
        total += match c {
            Cut::Frame { bytes, .. } | Cut::Garbage { bytes, .. } => bytes.len(),
        };
        for l in mon.on_cut(c) {
            let _ = l.text_line();
            let _ = l.json();
        }
    }
    let _ = mon.finish();
    let _ = mon.summary();
    assert_eq!(total, bytes.len(), "the cutter lost or invented bytes");
});
