//! # pbcard-softslave — the card's PROFIBUS DP slave and a simulated drive on a serial port
//!
//! The same sans-IO stack as the firmware ([`pbcard::node::Node`]) and the same simulated
//! drive behind the same DPM image ([`pbcard_sim::bench::Application`]), driven by a host loop:
//!
//! * bytes are read non-blocking and fed to [`Node::on_byte`](pbcard::node::Node::on_byte) with their arrival time;
//!   telegrams are found by their length, parity/framing errors (8E1 with `PARMRK`) go to
//!   [`Node::on_line_error`](pbcard::node::Node::on_line_error), silence of at least the idle threshold to [`Node::on_idle`](pbcard::node::Node::on_idle);
//! * a response is written once min_TSDR has passed since the request was read (spinning for
//!   the last stretch) — unless a character arrived after the request before the answer went
//!   out (in the same read, or any time up to the write): a request must be followed by an
//!   idle line (reference §1.4, T_SYN), so one followed without a gap by more bytes is not
//!   answered ([`Summary::dropped_line_active`]). The telegram itself still reached its station,
//!   as on the F411, whose `pbcard::phy::line::tx_plan` drops the response for the same reason
//!   (`TxDrop::LineActive`) after the receiver has handed the telegram on;
//! * [`Application::step`](pbcard_sim::bench::Application::step) runs every 2 ms and after every received chunk;
//! * [`run`] returns when `stop` is set (the binary sets it on Ctrl-C).
//!
//! A pseudo-terminal has no parity and no line timing: bytes pass, and the DP master at the
//! other end must use generous slot times.

pub mod args;
mod monitor;
pub mod parmrk;
pub mod serial;
pub mod state;
pub mod station;

use std::io;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant as StdInstant};

use pbcard::card;

use pbcard::time::{BitTimes, Instant};

pub use args::{parse_args, ArgError, Command, Options, USAGE};
pub use monitor::hex;
use pbcard::phy::port::{CharReceiver, LineEvent, Transmitter};
use serial::Port;
pub use station::{ConfigError, Station, StationConfig};

/// How often the application (DPM, simulated drive, timers) runs when no telegram arrives.
const STEP_EVERY: Duration = Duration::from_millis(2);
/// Waits for min_TSDR shorter than this are spun, not slept.
const SPIN_BELOW: Duration = Duration::from_millis(2);

/// Counters at the end of a run (summed over the stations).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Summary {
    /// Run time.
    pub elapsed: Duration,
    /// Requests the FDL stations handled.
    pub requests: u32,
    /// FCB retries answered from the stored response.
    pub retries: u32,
    /// Data_Exchange requests answered.
    pub data_exchanges: u32,
    /// Corrupt telegrams (as the first station's framer counted them).
    pub corrupt: u32,
    /// Responses written.
    pub responses: u32,
    /// Responses not written because characters followed the request before the answer was
    /// due (no idle line after the request: the F411's `TxDrop::LineActive`).
    pub dropped_line_active: u32,
    /// Per station: address and its Data_Exchange count.
    pub stations: Vec<(u8, u32)>,
}

/// Open the device and run the stations until `stop` is set. Every log line (already
/// timestamped, seconds since start; a station's lines prefixed `#address`) goes to `log`.
///
/// Several stations share the line: every received byte goes to every station's [`Node`](pbcard::node::Node),
/// whose framer and FDL station keep only the telegrams addressed to it (destination address,
/// or broadcast), so each card answers its own requests as it would alone on the bus.
pub fn run(opts: &Options, stop: &AtomicBool, log: &mut dyn FnMut(&str)) -> io::Result<Summary> {
    let t0 = StdInstant::now();
    let mut emit = |msg: String| log(&format!("[{:>9.3}] {msg}", t0.elapsed().as_secs_f64()));
    let rate = opts.baud;
    // The stations first: a bad configuration stops here, before the device is opened.
    let configs = opts.stations().map_err(|e| io::Error::new(io::ErrorKind::InvalidInput, e.to_string()))?;
    let mut stations = Vec::with_capacity(configs.len());
    for c in &configs {
        stations.push(Station::new(c).map_err(|e| io::Error::new(io::ErrorKind::InvalidInput, e.to_string()))?);
    }
    // --state: the stored address and I&M1-4 into each station before the line opens.
    let (mut states, restored) = state::open_all(opts, &mut stations)?;
    let mut port = if opts.device == "pty" { Port::create_pty(rate)? } else { Port::open(&opts.device, rate)? };

    let addresses: Vec<String> = configs.iter().map(|c| c.address.to_string()).collect();
    emit(format!(
        "pbcard soft slave {}: station{} {}, ident 0x{:04X}, {} bit/s on {}",
        env!("CARGO_PKG_VERSION"),
        if configs.len() > 1 { "s" } else { "" },
        addresses.join(", "),
        card::IDENT_NUMBER,
        rate.bits_per_second(),
        port.path()
    ));
    if opts.device == "pty" {
        emit(format!("created a pseudo-terminal: point the DP master program at {}", port.path()));
    }
    emit(match (port.parity(), port.is_pty()) {
        (true, _) => "line: 8E1 (11-bit characters), parity and framing errors detected".into(),
        (false, true) => "line: 8N1 — a pseudo-terminal cannot do parity; bytes pass unchanged, no line timing".into(),
        (false, false) => "WARNING: the device refused even parity, running 8N1: a PROFIBUS master sends 8E1, \
                           expect garbled telegrams on a real line"
            .into(),
    });
    if !port.is_pty() && port.speed() != rate.bits_per_second() {
        emit(format!("WARNING: the device reports {} bit/s", port.speed()));
    }
    let modules: Vec<String> = card::MODULES.iter().map(|m| format!("{} ({})", m.name, hex(m.cfg))).collect();
    emit(format!("modules (the master's Chk_Cfg picks one): {}", modules.join(", ")));
    for st in &mut stations {
        let c = &st.config;
        let prefix = st.prefix();
        let module = c.module.map_or("any module".to_string(), |m| format!("only {} ({})", m.name, hex(m.cfg)));
        let params: Vec<String> = c.params.iter().map(|(p, v)| format!("P{p} = {v}")).collect();
        emit(format!(
            "{prefix} simulated drive: PROFIdrive STW1/ZSW1, 0x4000 = 100 %, ramp 0 → 100 % in {} ms; 0x047E → ready, 0x047F → run; {module}{}",
            c.ramp.as_millis(),
            if params.is_empty() { String::new() } else { format!("; {}", params.join(", ")) }
        ));
        st.app.set_baudrate(Some(rate));
    }
    restored.into_iter().for_each(&mut emit);
    emit("waiting for a DP master (Ctrl-C stops)".into());

    // The port's bit timer and its characters' times count from the run's start.
    port.set_epoch(t0);
    let to_us = |d: pbcard::time::Duration| Duration::from_micros(d.as_micros());
    let idle =
        opts.idle.unwrap_or_else(|| to_us(rate.bits_to_duration(BitTimes::TSYN.0)).max(Duration::from_millis(10)));
    let now_pb = |t: StdInstant| Instant::from_micros(t.duration_since(t0).as_micros() as u64);

    let mut last_activity = t0;
    let mut idle_reported = true;
    let mut tx: Option<(StdInstant, Vec<u8>)> = None;
    // The station whose answer `tx` is.
    let mut tx_station = 0usize;
    let mut last_step = t0;
    let mut last_pd = t0;
    let mut responses = 0u32;
    let mut dropped_line_active = 0u32;

    while !stop.load(Ordering::Relaxed) {
        let now = StdInstant::now();
        let mut timeout = STEP_EVERY.saturating_sub(now - last_step);
        if let Some((at, _)) = &tx {
            timeout = timeout.min(at.saturating_duration_since(now).saturating_sub(SPIN_BELOW));
        }
        if !idle_reported {
            timeout = timeout.min((last_activity + idle).saturating_duration_since(now));
        }
        let mut got = false;
        if port.wait_readable(timeout)? {
            // The line contract's receiver (`pbcard::phy::port::CharReceiver`): every
            // character of one read with the read's time; a read error ends the events.
            while let Some(rx) = port.poll_event() {
                let (now, t) = match rx {
                    LineEvent::Byte { at, .. } => (at, t0 + Duration::from_micros(at.as_micros())),
                    _ => {
                        let t = StdInstant::now();
                        (now_pb(t), t)
                    }
                };
                got = true;
                last_activity = t;
                idle_reported = false;
                {
                    // A character after the request and before its answer: the line was not
                    // idle after the request, so it is not answered (module documentation).
                    if let Some((_, r)) = tx.take() {
                        dropped_line_active = dropped_line_active.wrapping_add(1);
                        if let Some(st) = stations.get(tx_station).filter(|st| st.config.verbose) {
                            emit(format!(
                                "{} answer {} dropped: characters followed the request without an idle line",
                                st.prefix(),
                                hex(&r)
                            ));
                        }
                    }
                    match rx {
                        LineEvent::Byte { byte: b, .. } => {
                            for (i, st) in stations.iter_mut().enumerate() {
                                let frames = st.framer.stats().frames;
                                let response = st.on_byte(now, b);
                                if let Some(r) = response {
                                    let wait = to_us(rate.bits_to_duration(st.node.min_tsdr().0));
                                    tx = Some((t + wait, r));
                                    tx_station = i;
                                }
                                if st.framer.stats().frames != frames {
                                    let prefix = format!("#{}", st.node.slave().address());
                                    st.monitor
                                        .on_frame(st.framer.frame(), &st.node, &mut |m| emit(format!("{prefix} {m}")));
                                }
                            }
                        }
                        LineEvent::Error(_) => stations.iter_mut().for_each(|st| st.framer.line_error()),
                        LineEvent::TxDone => {}
                    }
                }
            }
            port.take_error()?;
        }
        let now = StdInstant::now();
        if !got && !idle_reported && now.saturating_duration_since(last_activity) >= idle {
            let bits = rate.duration_to_bits(pbcard::time::Duration::from_micros(
                now.saturating_duration_since(last_activity).as_micros() as u64,
            ));
            for st in stations.iter_mut() {
                if st.config.verbose && !st.framer.pending().is_empty() {
                    emit(format!(
                        "{} partial telegram dropped after idle line: {}",
                        st.prefix(),
                        hex(st.framer.pending())
                    ));
                }
                st.framer.idle(BitTimes(bits.min(u32::MAX as u64) as u32));
            }
            idle_reported = true;
        }
        if let Some((at, _)) = &tx {
            if at.saturating_duration_since(now) < SPIN_BELOW {
                let at = *at;
                while StdInstant::now() < at {
                    std::hint::spin_loop();
                }
                // Characters waiting to be read arrived before the answer: the next round reads
                // them and drops it.
                if port.wait_readable(Duration::ZERO)? {
                    continue;
                }
                let (_, bytes) = tx.take().unwrap_or((at, Vec::new()));
                let sent = StdInstant::now();
                // Due now: the contract's transmitter writes at once (`at` has passed).
                if port.start_tx(&bytes, port.ticks_at(at)).is_err() {
                    port.take_error()?;
                }
                responses = responses.wrapping_add(1);
                let late = (sent - at).as_micros() as u64;
                if let Some(st) = stations.get_mut(tx_station) {
                    let prefix = st.prefix();
                    st.monitor
                        .on_response(&bytes, (late > 100).then_some(late), &mut |m| emit(format!("{prefix} {m}")));
                }
                // The line is busy while our answer goes out.
                last_activity = sent + to_us(rate.bits_to_duration(11 * bytes.len() as u32));
                idle_reported = false;
            }
        }
        if got || now - last_step >= STEP_EVERY {
            last_step = now;
            for (i, st) in stations.iter_mut().enumerate() {
                // The main loop's step (`pbcard::fast::tick`): the application with the
                // configured module kept, DP-V1 data records at slot 0 over the card's PNUs and
                // the simulated drive's parameters through the DPM mailbox (a job waiting for
                // the drive is retried here every step; the master's next poll fetches the
                // response), and the staging republished: the fast path answers from the node
                // as it is now.
                let mut app = station::Configured { app: &mut st.app, module: st.config.module };
                let events = pbcard::fast::tick(now_pb(now), &mut st.node, &mut st.core, &mut app);
                let prefix = st.prefix();
                st.monitor.on_step(events, &st.node, &st.app, &mut |m| emit(format!("{prefix} {m}")));
                if let Some(file) = states.get_mut(i) {
                    file.persist(&mut st.node).into_iter().for_each(|m| emit(format!("{prefix} {m}")));
                }
            }
        }
        if let Some(every) = opts.pd_every {
            if now - last_pd >= every {
                for st in stations.iter_mut() {
                    let prefix = st.prefix();
                    st.monitor.process_data((now - last_pd).as_secs_f64(), &st.node, &st.app, &mut |m| {
                        emit(format!("{prefix} {m}"))
                    });
                }
                last_pd = now;
            }
        }
    }

    let mut summary = Summary { elapsed: t0.elapsed(), responses, dropped_line_active, ..Default::default() };
    for st in &stations {
        let s = st.node.station().stats();
        let dx = st.node.slave().stats().data_exchanges;
        summary.requests += s.requests;
        summary.retries += s.retries;
        summary.data_exchanges += dx;
        summary.stations.push((st.node.slave().address(), dx));
    }
    summary.corrupt = stations.first().map_or(0, |st| st.framer.stats().corrupt);
    emit(format!(
        "stopped after {:.1} s: {} requests, {} Data_Exchange, {} FCB retries, {} corrupt telegrams, {} responses, \
         {} not sent (line active after the request)",
        summary.elapsed.as_secs_f64(),
        summary.requests,
        summary.data_exchanges,
        summary.retries,
        summary.corrupt,
        summary.responses,
        summary.dropped_line_active
    ));
    Ok(summary)
}
