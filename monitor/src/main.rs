//! `pbcard-monitor`: see `--help` and the README section "Bus monitor".
#![forbid(unsafe_code)]

use std::fs::File;
use std::io::{self, BufWriter, Read, Write};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use pbcard::time::Baudrate;
use pbcard_monitor::capture::{self, Writer};
use pbcard_monitor::cut::{Cut, Cutter};
use pbcard_monitor::product::Product;
use pbcard_monitor::{Line, Monitor};
use pbcard_softslave::args::parse_baud;
use pbcard_softslave::parmrk::{Parmrk, Rx};
use pbcard_softslave::serial::Port;

const USAGE: &str = "\
pbcard-monitor — a listen-only PROFIBUS bus monitor: FDL, DP, DP-V1 and PROFIdrive decoded with
the pbcard parsers; per station request → response matching, response time against MaxTsdr,
retries, missing answers, cycle time.

USAGE:
    pbcard-monitor --device PATH --baud N [options]     a serial device (never transmits), or
                                                         `pty` to create a pseudo-terminal
    pbcard-monitor --input FILE|- [--baud N] [options]   a capture file (its first line is
                                                         `# pbcard-monitor capture 1`), or raw
                                                         bus bytes (cut by syntax); - = stdin

OPTIONS:
    -d, --device PATH   serial device (8E1 when the device can; a pty is 8N1)
    -i, --input FILE    capture or raw bytes; `--hex` reads hex text instead of raw bytes
    -b, --baud N        rate (9600 … 12M, 19.2k, 1.5M …): for the device, and for judging the
                        times of raw input; a capture names its own rate
        --record FILE   write what is read as a capture (with times from a device)
        --gsd FILE      names of modules and user parameters, MaxTsdr, from a GSD file
                        (default: the pbcard card, gsd/ODCP0F11.gsd)
        --json          one JSON object per telegram instead of the readable line
        --summary       the per-station summary instead of the telegram lines (live: every
                        2 s; always at the end)
        --gap-us N      silence that ends a partial telegram (device input; default 33 bit
                        times, at least 10000 µs)
        --hex           --input is hex text (\"10 05 02 49 50 16 …\")
    -h, --help          this text

Stop a live monitor with Ctrl-C (the summary is printed).
";

#[derive(Debug, Default)]
struct Opts {
    device: Option<String>,
    input: Option<String>,
    baud: Option<Baudrate>,
    record: Option<PathBuf>,
    gsd: Option<PathBuf>,
    json: bool,
    summary: bool,
    gap_us: Option<u64>,
    hex: bool,
}

fn parse(args: impl Iterator<Item = String>) -> Result<Option<Opts>, String> {
    let mut o = Opts::default();
    let mut it = args;
    while let Some(a) = it.next() {
        let (name, inline) = match a.split_once('=') {
            Some((n, v)) if n.starts_with("--") => (n.to_string(), Some(v.to_string())),
            _ => (a.clone(), None),
        };
        let mut value = |flag: &str| inline.clone().or_else(|| it.next()).ok_or(format!("{flag} needs a value"));
        match name.as_str() {
            "-h" | "--help" => return Ok(None),
            "--json" => o.json = true,
            "--summary" => o.summary = true,
            "--hex" => o.hex = true,
            "-d" | "--device" => o.device = Some(value("--device")?),
            "-i" | "--input" => o.input = Some(value("--input")?),
            "-b" | "--baud" => {
                let v = value("--baud")?;
                o.baud = Some(parse_baud(&v).ok_or(format!("--baud '{v}': not a PROFIBUS rate"))?);
            }
            "--record" => o.record = Some(value("--record")?.into()),
            "--gsd" => o.gsd = Some(value("--gsd")?.into()),
            "--gap-us" => {
                let v = value("--gap-us")?;
                o.gap_us = Some(v.parse().map_err(|_| format!("--gap-us '{v}': expected µs"))?);
            }
            _ => return Err(format!("unknown argument '{a}'")),
        }
    }
    match (&o.device, &o.input) {
        (None, None) => return Err("--device PATH or --input FILE|- is required".into()),
        (Some(_), Some(_)) => return Err("--device and --input exclude each other".into()),
        (Some(_), None) if o.baud.is_none() => return Err("--device needs --baud".into()),
        _ => {}
    }
    Ok(Some(o))
}

/// Where lines go.
struct Out {
    json: bool,
    summary: bool,
    stdout: io::StdoutLock<'static>,
}

impl Out {
    fn lines(&mut self, lines: &[Line]) -> io::Result<()> {
        if self.summary {
            return Ok(());
        }
        for l in lines {
            if self.json {
                writeln!(self.stdout, "{}", l.json())?;
            } else {
                writeln!(self.stdout, "{}", l.text_line())?;
            }
        }
        Ok(())
    }

    fn summary(&mut self, m: &Monitor) -> io::Result<()> {
        if self.json {
            eprint!("{}", m.summary());
            Ok(())
        } else {
            write!(self.stdout, "{}", m.summary())
        }
    }
}

fn hex_text(text: &str) -> Result<Vec<u8>, String> {
    text.split(|c: char| c.is_ascii_whitespace() || c == ',')
        .filter(|s| !s.is_empty())
        .map(|s| {
            let s = s.trim_start_matches("0x");
            u8::from_str_radix(s, 16).map_err(|_| format!("'{s}' is not a hex byte"))
        })
        .collect()
}

fn run_input(o: &Opts, product: Product, out: &mut Out) -> Result<(), String> {
    let path = o.input.as_deref().unwrap_or("-");
    let mut data = Vec::new();
    if path == "-" {
        io::stdin().read_to_end(&mut data).map_err(|e| format!("stdin: {e}"))?;
    } else {
        data = std::fs::read(path).map_err(|e| format!("cannot read {path}: {e}"))?;
    }
    let is_capture = data.starts_with(capture::HEADER.as_bytes());
    let (lines, mon) = if is_capture {
        let text = String::from_utf8_lossy(&data);
        let (lines, mut mon) = pbcard_monitor::replay(product, &text, o.gap_us);
        if let (None, Some(b)) = (mon.rate(), o.baud) {
            mon.set_rate(b);
        }
        (lines, mon)
    } else {
        let bytes = if o.hex { hex_text(&String::from_utf8_lossy(&data))? } else { data };
        if let Some(rec) = &o.record {
            let f = File::create(rec).map_err(|e| format!("cannot create {}: {e}", rec.display()))?;
            let mut w = Writer::new(BufWriter::new(f), o.baud).map_err(|e| e.to_string())?;
            w.bytes(None, &bytes).and_then(|_| w.flush()).map_err(|e| e.to_string())?;
        }
        pbcard_monitor::decode_raw(product, o.baud, &bytes)
    };
    out.lines(&lines).map_err(|e| e.to_string())?;
    out.summary(&mon).map_err(|e| e.to_string())
}

fn run_device(o: &Opts, product: Product, out: &mut Out, stop: &AtomicBool) -> Result<(), String> {
    let rate = o.baud.unwrap_or(Baudrate::B19200);
    let device = o.device.as_deref().unwrap_or("");
    let port = if device == "pty" { Port::create_pty(rate) } else { Port::open(device, rate) };
    let mut port = port.map_err(|e| e.to_string())?;
    eprintln!(
        "pbcard-monitor: listening on {} at {} bit/s ({}), never transmitting; names from {}",
        port.path(),
        rate.bits_per_second(),
        if port.parity() { "8E1, character errors detected" } else { "8N1, no parity check" },
        product.source
    );
    let mut rec = match &o.record {
        Some(p) => {
            let f = File::create(p).map_err(|e| format!("cannot create {}: {e}", p.display()))?;
            Some(Writer::new(BufWriter::new(f), Some(rate)).map_err(|e| e.to_string())?)
        }
        None => None,
    };
    let gap_us = o.gap_us.unwrap_or_else(|| rate.bits_to_duration(33).as_micros().max(10_000));
    let mut mon = Monitor::new(product, Some(rate));
    let mut cutter = Cutter::new();
    let mut decoder = Parmrk::new(port.parity());
    let t0 = Instant::now();
    let mut last_rx = t0;
    let mut last_summary = t0;
    let mut buf = [0u8; 1024];
    while !stop.load(Ordering::Relaxed) {
        let readable = port.wait_readable(Duration::from_millis(50)).map_err(|e| e.to_string())?;
        let mut cuts: Vec<Cut> = Vec::new();
        let now = Instant::now();
        if !readable && cutter.pending() > 0 && now.duration_since(last_rx).as_micros() as u64 > gap_us {
            cutter.gap(&mut cuts);
        }
        if readable {
            let n = port.read(&mut buf).map_err(|e| e.to_string())?;
            let t = Instant::now();
            let t_us = t.duration_since(t0).as_micros() as u64;
            if t.duration_since(last_rx).as_micros() as u64 > gap_us && cutter.pending() > 0 {
                cutter.gap(&mut cuts);
            }
            last_rx = t;
            let mut chunk = Vec::with_capacity(n);
            decoder.feed(&buf[..n], |rx| match rx {
                Rx::Byte(b) => chunk.push(b),
                Rx::Error => {
                    cutter.push(Some(t_us), &chunk, &mut cuts);
                    if let Some(w) = rec.as_mut() {
                        let _ = w.bytes(Some(t_us), &chunk).and_then(|_| w.line_error(Some(t_us)));
                    }
                    chunk.clear();
                    cutter.line_error(Some(t_us), &mut cuts);
                }
            });
            cutter.push(Some(t_us), &chunk, &mut cuts);
            if let Some(w) = rec.as_mut() {
                w.bytes(Some(t_us), &chunk).and_then(|_| w.flush()).map_err(|e| e.to_string())?;
            }
        }
        for c in &cuts {
            let lines = mon.on_cut(c);
            out.lines(&lines).map_err(|e| e.to_string())?;
        }
        if out.summary && now.duration_since(last_summary) >= Duration::from_secs(2) {
            last_summary = now;
            out.summary(&mon).map_err(|e| e.to_string())?;
        }
    }
    let mut cuts = Vec::new();
    cutter.finish(&mut cuts);
    for c in &cuts {
        let lines = mon.on_cut(c);
        out.lines(&lines).map_err(|e| e.to_string())?;
    }
    let lines = mon.finish();
    out.lines(&lines).map_err(|e| e.to_string())?;
    if let Some(w) = rec.as_mut() {
        w.flush().map_err(|e| e.to_string())?;
    }
    out.summary(&mon).map_err(|e| e.to_string())
}

fn main() -> ExitCode {
    let o = match parse(std::env::args().skip(1)) {
        Ok(Some(o)) => o,
        Ok(None) => {
            print!("{USAGE}");
            return ExitCode::SUCCESS;
        }
        Err(e) => {
            eprintln!("pbcard-monitor: {e}\n(try --help)");
            return ExitCode::from(2);
        }
    };
    let product = match &o.gsd {
        Some(p) => match Product::from_gsd(p) {
            Ok(p) => p,
            Err(e) => {
                eprintln!("pbcard-monitor: {e}");
                return ExitCode::from(2);
            }
        },
        None => Product::card(),
    };
    let mut out = Out { json: o.json, summary: o.summary, stdout: io::stdout().lock() };
    let result = if o.device.is_some() {
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        if let Err(e) = ctrlc::set_handler(move || flag.store(true, Ordering::Relaxed)) {
            eprintln!("pbcard-monitor: cannot install the Ctrl-C handler: {e}");
            return ExitCode::FAILURE;
        }
        run_device(&o, product, &mut out, &stop)
    } else {
        run_input(&o, product, &mut out)
    };
    let _ = out.stdout.flush();
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("pbcard-monitor: {e}");
            ExitCode::FAILURE
        }
    }
}
