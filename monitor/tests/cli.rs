//! The `pbcard-monitor` binary: a capture file, raw hex on standard input, JSON lines, a bad
//! command line, and live input on a pseudo-terminal (listen only) recorded with `--record`
//! and replayed.

use std::io::{BufRead, BufReader, Write};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const BIN: &str = env!("CARGO_BIN_EXE_pbcard-monitor");

/// FDL_Status to 5, its answer, Set_Prm (SD2) and its SC, garbage, Slave_Diag to 5.
const CAPTURE: &str = "# pbcard-monitor capture 1
rate 19200
0.000000 10 05 02 49 50 16
0.004011 10 02 05 00 07 16
0.042504 68 11 11 68 85 82 5D 3D 3E 88 01 64 0B 0F 11 00 80 00 00 00 00 77 16
0.043650 E5
0.050000 00 FF
0.060000 68 05 05 68 85 82 7D 3C 3E FE 16
";

fn tmp(name: &str) -> std::path::PathBuf {
    std::env::temp_dir().join(format!("pbcard-monitor-{}-{name}", std::process::id()))
}

#[test]
fn a_capture_file_is_decoded_with_the_summary() {
    let path = tmp("cap.txt");
    std::fs::write(&path, CAPTURE).unwrap();
    let out = Command::new(BIN).args(["--input", path.to_str().unwrap()]).output().unwrap();
    assert!(out.status.success(), "{out:?}");
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("Response(FDL_Status)   station type: slave [TSDR 11 bit]"), "{text}");
    assert!(text.contains("Set_Prm                Station_Status 88 (Lock_Req WD_On)"), "{text}");
    assert!(text.contains("2 bytes: no start delimiter"), "{text}");
    assert!(text.contains("NO ANSWER to Slave_Diag"), "{text}");
    assert!(text.contains("summary: 5 telegrams, 1 garbage runs, 19200 bit/s"), "{text}");
    let row = text.lines().find(|l| l.trim_start().starts_with("5 ")).unwrap();
    assert!(row.contains("Wait_Cfg"), "{row}");

    let out = Command::new(BIN).args(["--summary", "--input", path.to_str().unwrap()]).output().unwrap();
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.starts_with("summary: 5 telegrams") && !text.contains("Set_Prm"), "only the table: {text}");

    let out = Command::new(BIN).args(["--json", "--input", path.to_str().unwrap()]).output().unwrap();
    let text = String::from_utf8(out.stdout).unwrap();
    let first: serde_json::Value = serde_json::from_str(text.lines().next().unwrap()).unwrap();
    assert_eq!(first["service"], "FDL_Status");
    assert_eq!((first["sd"].as_str(), first["da"].as_u64(), first["sa"].as_u64()), (Some("SD1"), Some(5), Some(2)));
    assert_eq!(first["t"].as_f64(), Some(0.0));
    assert!(String::from_utf8(out.stderr).unwrap().contains("summary:"), "the summary goes to stderr with --json");
    let _ = std::fs::remove_file(path);
}

#[test]
fn hex_on_stdin_and_bad_command_lines() {
    let mut child =
        Command::new(BIN).args(["--input", "-", "--hex"]).stdin(Stdio::piped()).stdout(Stdio::piped()).spawn().unwrap();
    child.stdin.take().unwrap().write_all(b"10 05 02 49 50 16\n10 02 05 00 07 16\n").unwrap();
    let out = child.wait_with_output().unwrap();
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("Response(FDL_Status)"), "{text}");
    assert!(!text.contains("[TSDR"), "no times, no timing: {text}");
    for args in [&["--frob"][..], &[][..], &["--device", "/dev/null"][..], &["--input", "x", "--baud", "115200"][..]] {
        let out = Command::new(BIN).args(args).output().unwrap();
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        assert_eq!(String::from_utf8(out.stderr).unwrap().lines().count(), 2, "{args:?}: one error line + the hint");
    }
}

#[test]
fn live_pty_input_is_decoded_recorded_and_replayed() {
    let rec = tmp("live.txt");
    let mut child = Command::new(BIN)
        .args(["--device", "pty", "--baud", "19200", "--record", rec.to_str().unwrap()])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut err = BufReader::new(child.stderr.take().unwrap());
    let mut l = String::new();
    err.read_line(&mut l).unwrap();
    let path = l.split_whitespace().find(|w| w.starts_with("/dev/pts/")).expect("the pty path").to_string();
    let mut tty = std::fs::OpenOptions::new().write(true).open(&path).unwrap();
    // A request, then (a bus later) its answer, then garbage.
    tty.write_all(&[0x10, 0x05, 0x02, 0x49, 0x50, 0x16]).unwrap();
    std::thread::sleep(Duration::from_millis(50));
    tty.write_all(&[0x10, 0x02, 0x05, 0x00, 0x07, 0x16, 0x33]).unwrap();
    let end = Instant::now() + Duration::from_secs(20);
    while Instant::now() < end && std::fs::read_to_string(&rec).map_or(true, |t| !t.contains(" 33")) {
        std::thread::sleep(Duration::from_millis(20));
    }
    std::thread::sleep(Duration::from_millis(100));
    // SAFETY: signalling our own child.
    assert_eq!(unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGINT) }, 0);
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success(), "{out:?}");
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("FDL_Status") && text.contains("Response(FDL_Status)   station type: slave"), "{text}");
    assert!(text.contains("1 bytes: truncated telegram") || text.contains("1 bytes: no start delimiter"), "{text}");
    let capture = std::fs::read_to_string(&rec).unwrap();
    assert!(capture.starts_with("# pbcard-monitor capture 1\nrate 19200\n"), "{capture}");
    let out = Command::new(BIN).args(["--input", rec.to_str().unwrap()]).output().unwrap();
    let replayed = String::from_utf8(out.stdout).unwrap();
    assert!(replayed.contains("Response(FDL_Status)   station type: slave [TSDR"), "{replayed}");
    let _ = std::fs::remove_file(rec);
}

#[test]
fn names_from_a_gsd_file() {
    let path = tmp("gsd-cap.txt");
    std::fs::write(&path, CAPTURE).unwrap();
    let gsd = concat!(env!("CARGO_MANIFEST_DIR"), "/../gsd/ODCP0F11.gsd");
    let out = Command::new(BIN).args(["--gsd", gsd, "--input", path.to_str().unwrap()]).output().unwrap();
    assert!(out.status.success(), "{out:?}");
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("names from ") && text.contains("ODCP0F11.gsd"), "{text}");
    let prm = text.lines().find(|l| l.contains("Set_Prm ")).unwrap();
    assert!(prm.contains("Ident_Number 0x0F11, Group_Ident 0x00") && !prm.contains("≠ GSD"), "{prm}");
    let out =
        Command::new(BIN).args(["--gsd", "/nonexistent.gsd", "--input", path.to_str().unwrap()]).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    let _ = std::fs::remove_file(path);
}
