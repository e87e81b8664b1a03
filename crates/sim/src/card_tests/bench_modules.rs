//! The benchmark modules through the whole card (DP slave, node, DPM, simulated drive):
//! `cargo test -p pbcard-sim --lib --features bench --target x86_64-unknown-linux-gnu card_tests::bench_modules` (the other tests assume the GSD's modules).

use crate::bench::Application;
use crate::card::*;
use crate::dp::{cfg, DpSlave, DpState};
use crate::dpm::Telegram;
use crate::drive::DriveConfig;
use crate::fdl::telegram::{self, FunctionCode, Header};
use crate::node::Node;
use crate::time::{Duration, Instant};

const MASTER: u8 = 2;
const SLAVE: u8 = 5;

fn send(node: &mut Node, now: Instant, fcb: bool, dsap: Option<u8>, pdu: &[u8], srd: bool) -> Option<Vec<u8>> {
    let fc = if srd { FunctionCode::request(0xD, fcb, true) } else { FunctionCode::request(0x06, false, false) };
    let da = if srd { SLAVE } else { telegram::BROADCAST };
    let hdr = Header { da, sa: MASTER, fc, dsap, ssap: dsap.map(|_| 62) };
    let mut buf = [0u8; telegram::MAX_FRAME_LEN];
    let n = telegram::emit(&mut buf, &hdr, pdu).unwrap();
    let mut resp = None;
    for &b in &buf[..n] {
        if let Some(r) = node.on_byte(now, b) {
            resp = Some(r.to_vec());
        }
    }
    resp
}

#[test]
fn bench_modules_run_through_the_card() {
    assert_eq!((MAX_INPUT_LEN, MAX_OUTPUT_LEN), (244, 244));
    for m in [BENCH_32, BENCH_244] {
        let io = cfg::io_lengths(m.cfg).unwrap();
        assert_eq!((io.inputs, io.outputs), (m.inputs as usize, m.outputs as usize), "{}", m.name);
        assert_eq!(module_for_cfg(m.cfg), Some(&m));
        assert_eq!(Telegram::of_module(&m), None);

        let mut node = crate::card::node(DpSlave::new(&crate::card::SLAVE, SLAVE));
        let mut app = Application::new(DriveConfig::DEFAULT);
        let mut now = Instant::from_millis(0);
        let mut fcb = false;
        let mut srd = |node: &mut Node, now: Instant, dsap: Option<u8>, pdu: &[u8]| {
            fcb = !fcb;
            send(node, now, fcb, dsap, pdu, true).expect("answer")
        };
        // Set_Prm with Sync_Req and Freeze_Req, then Chk_Cfg.
        let mut prm = Vec::from([0xB8, 1, 100, 11, (IDENT_NUMBER >> 8) as u8, IDENT_NUMBER as u8, 0]);
        prm.extend_from_slice(&USER_PRM_DEFAULTS);
        assert_eq!(srd(&mut node, now, Some(61), &prm), [telegram::SC]);
        app.step(now, &mut node);
        assert_eq!(srd(&mut node, now, Some(62), m.cfg), [telegram::SC]);
        app.step(now, &mut node);
        assert_eq!(node.slave().state(), DpState::DataExch, "{}", m.name);
        let n = m.outputs as usize;
        for k in 0..5u8 {
            let out: Vec<u8> = (0..n).map(|i| (i as u8).wrapping_mul(7).wrapping_add(k) | 0x04).collect();
            let r = srd(&mut node, now, None, &out);
            assert_eq!(r.len(), m.inputs as usize + 9, "{}", m.name);
            assert_eq!(node.slave().outputs(), &out[..]);
            now = now + Duration::from_millis(2);
            app.step(now, &mut node);
            let dpm_out = app.dpm().outputs().unwrap();
            assert_eq!(dpm_out.bytes(), &out[..n.min(crate::dpm::layout::PD_CAPACITY)]);
            // Rd_Inp / Rd_Outp answer the whole images.
            let r = srd(&mut node, now, Some(57), &[]);
            assert_eq!(&r[telegram::pdu_range(r.len(), n)], &out[..], "{}", m.name);
            let r = srd(&mut node, now, Some(56), &[]);
            assert_eq!(r.len(), m.inputs as usize + 11, "{}", m.name);
        }
        // Sync, Freeze, Clear_Data, zero-length outputs, wrong length.
        for gc in [[0x20, 0], [0x08, 0], [0x02, 0], [0x14, 0], [0x00, 0]] {
            assert_eq!(send(&mut node, now, false, Some(58), &gc, false), None);
            let out: Vec<u8> = (0..n).map(|i| i as u8).collect();
            srd(&mut node, now, None, &out);
            now = now + Duration::from_millis(2);
            app.step(now, &mut node);
        }
        srd(&mut node, now, None, &[]);
        app.step(now, &mut node);
        srd(&mut node, now, None, &[1; 13]);
        assert!(node.slave().stats().wrong_output_len > 0);
        assert_eq!(node.slave().state(), DpState::WaitPrm, "{}: a wrong length ends data exchange", m.name);
    }
}
