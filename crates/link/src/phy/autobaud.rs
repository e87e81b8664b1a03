//! Automatic baud-rate detection and supervision, as the SPC3/VPC3 ASICs do it (reference
//! §1.6), as a sans-IO state machine.
//!
//! ```text
//! power-up
//!    │
//!    ▼
//! Baud_Search ───── SD1/SD2/SD3 ok, any DA ─────▶ Baud_Control ──── DP watchdog active ────▶ DP_Control
//!  12M → 9.6k, wrap                                retriggered by own                     DpSlave::poll
//!  dwell(rate) each ◀─── no own frame for T_bc ─── frames only  ◀── DP watchdog inactive ── supervises
//! ```
//!
//! **Baud_Search.** From power-up the receiver listens at 12 Mbit/s and steps down through
//! [`Baudrate::ALL`] (wrapping after 9.6 kbit/s), staying [`dwell`]`(rate)` at each rate. One
//! complete, error-free SD1, SD2 or SD3 telegram to *any* address locks the rate; SD4 tokens and
//! SC short acknowledges do not count (three random bytes starting with 0xDC, or one 0xE5, are
//! too easy to see at a wrong rate), and neither does anything the caller reports as
//! [`Autobaud::on_garbage`].
//!
//! **Dwell.** Neither Siemens nor profichip publish theirs (reference §1.6, §9 item 8). Ours is
//! [`DWELL_BITS`] = 2 × 2805 + 2000 = 7610 bit times, at least [`DWELL_FLOOR`] (10 ms):
//! enough for the tail of a longest telegram (255 bytes × 11 bits) that was already on the
//! line when the receiver switched, up to 2000 bit times of idle line, tokens, SC and slot-time
//! waits for silent stations, and then one complete longest telegram. So any bus whose
//! SD1/SD2/SD3 frames follow each other that closely locks on the *first* visit of its rate,
//! whatever the phase. The floor covers masters with idle time between cycles at the high
//! rates (2000 bit times are only 0.17 ms at 12 Mbit/s).
//!
//! | rate | 12M | 6M | 3M | 1.5M | 500k | 187.5k | 93.75k | 45.45k | 19.2k | 9.6k |
//! |---|---|---|---|---|---|---|---|---|---|---|
//! | dwell (ms) | 10 | 10 | 10 | 10 | 15.2 | 40.6 | 81.2 | 167.4 | 396.4 | 792.7 |
//!
//! A full scan takes [`full_scan`] = 1.533 s. The worst-case time to lock from power-up at
//! rate R is the sum of the dwells down to and including R's: 10 ms at 12 Mbit/s … 1.533 s at
//! 9.6 kbit/s (the simulated-bus tests below assert it; measured worst cases with longest
//! telegrams only: 0.5 ms at 12 Mbit/s, 51 ms at 500 kbit/s, 1.32 s at 9.6 kbit/s). A dwell of
//! "tens of ms" at 9.6 kbit/s is not possible: one longest telegram alone lasts 292 ms there.
//!
//! **Baud_Control.** Once locked, the rate is kept while error-free telegrams *addressed to
//! this station* keep coming; when none arrives for [`Config::baud_control`] (the ASICs'
//! `WD_Baud_Control_Val² × 10 ms`, default 0x10 → 2.56 s, see [`Config::from_wd_baud_control_val`])
//! the search starts again — at the rate that was locked (a master that stopped is most likely
//! to come back at the same rate), then downward as usual. The DP state machine is *not*
//! reset by this (ASIC behaviour, reference §1.6).
//!
//! Consequence, documented ASIC behaviour (reference §9 item 8): on a bus whose traffic is all
//! for *other* stations (our station is not configured in the master), the card locks, loses
//! the lock after T_bc, relocks within one dwell, and so on: P0963 alternates between the rate
//! and 5 ("not detected") with a period of about T_bc. Broadcasts (DA 127) do not count as
//! addressed to us.
//!
//! **DP_Control.** While the DP watchdog runs (a Set_Prm with WD_On = 1 was accepted and the
//! slave is not in Wait_Prm) the DP slave supervises the master itself: [`DpSlave::poll`]
//! leaves data exchange when no Data_Exchange arrives within the watchdog time. Baud_Control is
//! suspended meanwhile — the rate is held however long the line stays quiet. The integration
//! reports the watchdog state after every frame the slave handled and every `DpSlave::poll`:
//!
//! ```text
//! autobaud.dp_watchdog_active(now, slave.watchdog_time().is_some() && slave.state() != DpState::WaitPrm);
//! ```
//!
//! When it turns inactive (the DP watchdog expired and the slave went to Wait_Prm, or a new
//! Set_Prm switched WD_On off) this machine returns to Baud_Control with a fresh T_bc. So after
//! a rate change in data exchange the search begins T_wd + T_bc after the last good frame.
//!
//! **Caller's contract.** Program the USART with [`divisor_for`](super::divisor::divisor_for)
//! `(`[`Autobaud::rate`]`)` at start and whenever [`Autobaud::poll`] returns a rate, and then
//! discard whatever was received and restart the framer. Call `poll` at least every
//! millisecond or at [`Autobaud::next_deadline`]. Report every complete telegram with
//! [`Autobaud::on_frame`] and every parity/framing/overrun error or invalid telegram with
//! [`Autobaud::on_garbage`]. Respond to requests only while [`Autobaud::detected`] is `Some`.
//!
//! [`DpSlave::poll`]: crate::dp::DpSlave::poll

use crate::fdl::telegram::MAX_FRAME_LEN;
use crate::time::{Baudrate, BitTimes, Duration, Instant};

/// Bit times of the longest telegram (255 characters of 11 bits).
pub const LONGEST_FRAME_BITS: u32 = MAX_FRAME_LEN as u32 * BitTimes::CHAR.0;

/// Idle/token/slot-time budget between two counting telegrams, in bit times.
pub const GAP_BUDGET_BITS: u32 = 2000;

/// The search dwell in bit times: the tail of a longest telegram, the gap budget, and one
/// complete longest telegram.
pub const DWELL_BITS: u32 = 2 * LONGEST_FRAME_BITS + GAP_BUDGET_BITS;

/// The shortest dwell at any rate.
pub const DWELL_FLOOR: Duration = Duration::from_millis(10);

/// How long the search listens at `rate` before stepping down: [`DWELL_BITS`] at that rate,
/// at least [`DWELL_FLOOR`].
pub const fn dwell(rate: Baudrate) -> Duration {
    let d = rate.bits_to_duration(DWELL_BITS);
    if d.as_micros() < DWELL_FLOOR.as_micros() {
        DWELL_FLOOR
    } else {
        d
    }
}

/// One complete pass over all ten rates.
pub const fn full_scan() -> Duration {
    let mut sum = 0;
    let mut i = 0;
    while i < Baudrate::ALL.len() {
        sum += dwell(Baudrate::ALL[i]).as_micros();
        i += 1;
    }
    Duration::from_micros(sum)
}

/// P0963 value "baud rate not detected".
pub const P0963_NOT_DETECTED: u8 = 5;

/// Settings of the supervision.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct Config {
    /// The Baud_Control time T_bc: how long the locked rate is kept without a telegram
    /// addressed to this station (outside DP_Control).
    pub baud_control: Duration,
}

impl Config {
    /// The ASICs' default register value `WD_Baud_Control_Val` (profichip driver).
    pub const DEFAULT_WD_BAUD_CONTROL_VAL: u8 = 0x10;

    /// T_bc from the ASIC register value: `val² × 10 ms` (reference §1.6; the square is
    /// inferred from the "root value" wording, §9 item 5). 0 is taken as 1 (10 ms).
    pub const fn from_wd_baud_control_val(val: u8) -> Config {
        let v = if val == 0 { 1 } else { val as u64 };
        Config { baud_control: Duration::from_millis(v * v * 10) }
    }
}

impl Default for Config {
    /// `WD_Baud_Control_Val` = 0x10 → T_bc = 2.56 s.
    fn default() -> Self {
        Config::from_wd_baud_control_val(Config::DEFAULT_WD_BAUD_CONTROL_VAL)
    }
}

/// The supervision state (reference §1.6, watchdog state machine).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum Supervision {
    /// Searching: the rate is not known.
    BaudSearch,
    /// Locked; kept alive by telegrams addressed to this station.
    BaudControl,
    /// Locked; the DP watchdog of the slave supervises the master.
    DpControl,
}

/// Counters (diagnosis / DPM status block).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct AutobaudStats {
    /// Times a rate was locked.
    pub locks: u32,
    /// Times Baud_Control expired (lock lost).
    pub baud_control_expiries: u32,
    /// Rate switches during the search.
    pub search_steps: u32,
    /// Errors reported through [`Autobaud::on_garbage`].
    pub garbage: u32,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum State {
    Search { until: Instant },
    Control { until: Instant },
    DpControl,
}

/// The baud-rate search and supervision state machine (see the module documentation).
#[derive(Debug, Clone)]
pub struct Autobaud {
    cfg: Config,
    /// Index into [`Baudrate::ALL`] of the rate the receiver listens at.
    index: usize,
    state: State,
    /// The last value given to [`dp_watchdog_active`](Self::dp_watchdog_active).
    dp_watchdog: bool,
    stats: AutobaudStats,
}

impl Autobaud {
    /// Power-up: searching, listening at 12 Mbit/s, default [`Config`].
    pub fn new(now: Instant) -> Self {
        Self::with_config(now, Config::default())
    }

    /// Power-up with explicit settings.
    pub fn with_config(now: Instant, cfg: Config) -> Self {
        Autobaud {
            cfg,
            index: 0,
            state: State::Search { until: now + dwell(Baudrate::ALL[0]) },
            dp_watchdog: false,
            stats: AutobaudStats::default(),
        }
    }

    /// The settings.
    pub fn config(&self) -> Config {
        self.cfg
    }

    /// The rate the UART must listen (and answer) at.
    pub fn rate(&self) -> Baudrate {
        Baudrate::ALL[self.index]
    }

    /// The supervision state.
    pub fn state(&self) -> Supervision {
        match self.state {
            State::Search { .. } => Supervision::BaudSearch,
            State::Control { .. } => Supervision::BaudControl,
            State::DpControl => Supervision::DpControl,
        }
    }

    /// The locked rate, `None` while searching.
    pub fn detected(&self) -> Option<Baudrate> {
        match self.state {
            State::Search { .. } => None,
            State::Control { .. } | State::DpControl => Some(self.rate()),
        }
    }

    /// The detected rate in P0963 coding ([`Baudrate::p0963_code`]), 5 = not detected.
    pub fn p0963(&self) -> u8 {
        match self.detected() {
            Some(r) => r.p0963_code(),
            None => P0963_NOT_DETECTED,
        }
    }

    /// Counters.
    pub fn stats(&self) -> AutobaudStats {
        self.stats
    }

    /// When [`poll`](Self::poll) next has something to do (end of the dwell, Baud_Control
    /// expiry); `None` in DP_Control.
    pub fn next_deadline(&self) -> Option<Instant> {
        match self.state {
            State::Search { until } | State::Control { until } => Some(until),
            State::DpControl => None,
        }
    }

    /// A complete telegram was received at [`rate`](Self::rate). `frame_ok_for_anyone`: it is
    /// an error-free SD1/SD2/SD3 telegram (any address; `false` for SD4, SC and anything with
    /// a character error); `addressed_to_us`: it is such a telegram with DA = our station
    /// address (not the broadcast 127). Telegrams that are not OK are ignored here.
    pub fn on_frame(&mut self, now: Instant, frame_ok_for_anyone: bool, addressed_to_us: bool) {
        if !frame_ok_for_anyone {
            return;
        }
        match self.state {
            State::Search { .. } => {
                self.stats.locks = self.stats.locks.wrapping_add(1);
                self.state = self.locked_state(now);
            }
            State::Control { .. } => {
                if addressed_to_us {
                    self.state = State::Control { until: now + self.cfg.baud_control };
                }
            }
            State::DpControl => {}
        }
    }

    /// A parity, framing or overrun error, or an invalid telegram, at the current rate. Only
    /// counted: the search does not leave a rate early (one disturbed character at the right
    /// rate would cost a whole scan), and errors never retrigger Baud_Control.
    pub fn on_garbage(&mut self, _now: Instant) {
        self.stats.garbage = self.stats.garbage.wrapping_add(1);
    }

    /// Whether the DP slave's own watchdog is running (see the module documentation for the
    /// expression). Active → DP_Control; inactive again → Baud_Control with a fresh T_bc.
    /// While searching the value is only remembered.
    pub fn dp_watchdog_active(&mut self, now: Instant, active: bool) {
        self.dp_watchdog = active;
        match (self.state, active) {
            (State::Control { .. }, true) => self.state = State::DpControl,
            (State::DpControl, false) => self.state = State::Control { until: now + self.cfg.baud_control },
            _ => {}
        }
    }

    /// Run the timers. Returns the new rate when the UART must be reprogrammed (the search
    /// stepped down); Baud_Control expiry returns `None` (the rate stays, the search resumes
    /// here) but [`detected`](Self::detected) becomes `None`. A late call advances one rate
    /// only and gives the new rate a full dwell from `now`.
    pub fn poll(&mut self, now: Instant) -> Option<Baudrate> {
        match self.state {
            State::Search { until } if now >= until => {
                self.index = (self.index + 1) % Baudrate::ALL.len();
                self.stats.search_steps = self.stats.search_steps.wrapping_add(1);
                self.state = State::Search { until: now + dwell(self.rate()) };
                Some(self.rate())
            }
            State::Control { until } if now >= until => {
                self.stats.baud_control_expiries = self.stats.baud_control_expiries.wrapping_add(1);
                self.state = State::Search { until: now + dwell(self.rate()) };
                None
            }
            _ => None,
        }
    }

    fn locked_state(&self, now: Instant) -> State {
        if self.dp_watchdog {
            State::DpControl
        } else {
            State::Control { until: now + self.cfg.baud_control }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fdl::framer::{Framer, Push};
    use crate::fdl::telegram::{decode, emit, Decoded, FunctionCode, Header, Telegram};
    use std::collections::VecDeque;
    use std::vec::Vec;

    const OUR: u8 = 5;
    const MASTER: u8 = 2;
    const NS: u64 = 1_000_000_000;

    fn inst(ns: u64) -> Instant {
        Instant::from_micros(ns / 1000)
    }

    fn bits_ns(rate: Baudrate, bits: u64) -> u64 {
        bits * NS / rate.bits_per_second() as u64
    }

    /// Default slot times (reference §1.2; 45.45k: a typical GSD-derived value).
    fn slot_bits(rate: Baudrate) -> u64 {
        match rate {
            Baudrate::B12M => 1000,
            Baudrate::B6M => 600,
            Baudrate::B3M => 400,
            Baudrate::B1500k => 300,
            Baudrate::B500k => 200,
            Baudrate::B45450 => 640,
            _ => 100,
        }
    }

    fn frame(header: Header, pdu: &[u8]) -> Vec<u8> {
        let mut out = [0u8; MAX_FRAME_LEN];
        let n = emit(&mut out, &header, pdu).unwrap();
        out[..n].to_vec()
    }

    // ------------------------------------------------------------------------------------
    // The simulated bus: one master polling slaves with Data_Exchange (SRD high), asking one
    // GAP address for FDL_Status per cycle and passing the token to itself.
    // ------------------------------------------------------------------------------------

    #[derive(Clone, Debug)]
    struct Traffic {
        /// (station, responds) polled with Data_Exchange every cycle.
        polled: Vec<(u8, bool)>,
        /// Data_Exchange PDU length (246 = longest telegram, 255 bytes).
        pdu_len: usize,
        /// GAP addresses asked for FDL_Status, one per cycle (none answers).
        gap: Option<(u8, u8)>,
        /// Extra idle bit times after each cycle.
        cycle_idle_bits: u64,
    }

    impl Traffic {
        /// Our station and two others in data exchange, short telegrams, GAP polling 3..=30.
        fn normal() -> Self {
            Traffic {
                polled: vec![(3, true), (OUR, false), (4, true)],
                pdu_len: 10,
                gap: Some((6, 30)),
                cycle_idle_bits: 0,
            }
        }
        /// Only longest telegrams (the dwell's design case).
        fn heavy() -> Self {
            Traffic { polled: vec![(OUR, false), (3, true)], pdu_len: 246, gap: None, cycle_idle_bits: 0 }
        }
        /// Traffic for other stations only (our station is not configured in the master).
        fn others_only() -> Self {
            Traffic { polled: vec![(3, true), (4, true)], pdu_len: 4, gap: Some((10, 20)), cycle_idle_bits: 0 }
        }
    }

    #[derive(Debug)]
    struct Tx {
        start: u64,
        end: u64,
        rate: Baudrate,
        bytes: Vec<u8>,
    }

    struct Bus {
        /// (from ns, what the bus carries from then on; None = silent).
        segments: Vec<(u64, Option<(Baudrate, Traffic)>)>,
        seg: usize,
        t: u64,
        items: VecDeque<(u64, Vec<u8>)>,
        next_idle: u64,
        fcb: bool,
        gap_next: u8,
        cycle: u8,
    }

    impl Bus {
        fn new(segments: Vec<(u64, Option<(Baudrate, Traffic)>)>) -> Self {
            let t = segments[0].0;
            Bus { segments, seg: 0, t, items: VecDeque::new(), next_idle: 33, fcb: false, gap_next: 0, cycle: 0 }
        }

        fn build_cycle(&mut self, rate: Baudrate, tr: &Traffic) {
            let slot = slot_bits(rate);
            let mut pending = self.next_idle;
            self.cycle = self.cycle.wrapping_add(1);
            for &(addr, responds) in &tr.polled {
                let pdu: Vec<u8> =
                    (0..tr.pdu_len).map(|i| (i as u8).wrapping_mul(37).wrapping_add(self.cycle ^ addr)).collect();
                let fc = FunctionCode::request(0xD, self.fcb, true);
                let req = frame(Header { da: addr, sa: MASTER, fc, dsap: None, ssap: None }, &pdu);
                self.items.push_back((pending, req));
                if responds {
                    let fc = FunctionCode(0x08);
                    let rsp = frame(Header { da: MASTER, sa: addr, fc, dsap: None, ssap: None }, &pdu);
                    self.items.push_back((30, rsp));
                    pending = 33;
                } else {
                    pending = slot + 33;
                }
            }
            self.fcb = !self.fcb;
            if let Some((lo, hi)) = tr.gap {
                let span = hi - lo + 1;
                let da = lo + self.gap_next % span;
                self.gap_next = self.gap_next.wrapping_add(1);
                let fc = FunctionCode::request(0x9, false, false);
                self.items.push_back((pending, frame(Header { da, sa: MASTER, fc, dsap: None, ssap: None }, &[])));
                pending = slot + 33;
            }
            self.items.push_back((pending, vec![0xDC, MASTER, MASTER]));
            self.next_idle = 33 + tr.cycle_idle_bits;
        }

        fn next(&mut self) -> Option<Tx> {
            loop {
                let seg_end = self.segments.get(self.seg + 1).map_or(u64::MAX, |s| s.0);
                let Some((rate, tr)) = self.segments[self.seg].1.clone() else {
                    if seg_end == u64::MAX {
                        return None;
                    }
                    self.switch();
                    continue;
                };
                if self.items.is_empty() {
                    self.build_cycle(rate, &tr);
                }
                let (idle, bytes) = self.items.pop_front().unwrap();
                let start = self.t + bits_ns(rate, idle);
                let end = start + bits_ns(rate, 11 * bytes.len() as u64);
                if end > seg_end {
                    self.switch();
                    continue;
                }
                self.t = end;
                return Some(Tx { start, end, rate, bytes });
            }
        }

        fn switch(&mut self) {
            self.seg += 1;
            self.t = self.segments[self.seg].0;
            self.items.clear();
            self.next_idle = 33;
        }
    }

    // ------------------------------------------------------------------------------------
    // The listener: a UART at the rate Autobaud asks for, a Framer, and the board's glue.
    // ------------------------------------------------------------------------------------

    struct Listener {
        ab: Autobaud,
        framer: Framer,
        listen: Baudrate,
        /// Power-up / last UART reprogramming (ns): nothing before it is received.
        reprog: u64,
        last_end: u64,
        rng: u64,
        /// Poll period (ns); `None` = poll exactly at `next_deadline`.
        tick: Option<u64>,
        next_tick: u64,
        /// A modelled DP slave watchdog: (T_wd, deadline).
        dp_wd: Option<(u64, Option<u64>)>,
        detected: Option<Baudrate>,
        /// Detection changes (ns, detected).
        log: Vec<(u64, Option<Baudrate>)>,
        /// UART reprogramming (ns, rate).
        rates: Vec<(u64, Baudrate)>,
        /// SD1/SD2/SD3 frames accepted while listening at a wrong rate.
        false_frames: u32,
        /// Last frame addressed to us (ns).
        last_own: u64,
    }

    impl Listener {
        fn new(t0: u64, cfg: Config, tick: Option<u64>) -> Self {
            let ab = Autobaud::with_config(inst(t0), cfg);
            Listener {
                listen: ab.rate(),
                ab,
                framer: Framer::new(),
                reprog: t0,
                last_end: t0,
                rng: 0x9E37_79B9_7F4A_7C15 ^ t0,
                tick,
                next_tick: t0,
                dp_wd: None,
                detected: None,
                log: Vec::new(),
                rates: Vec::new(),
                false_frames: 0,
                last_own: 0,
            }
        }

        fn rand(&mut self) -> u64 {
            // xorshift64*
            self.rng ^= self.rng >> 12;
            self.rng ^= self.rng << 25;
            self.rng ^= self.rng >> 27;
            self.rng.wrapping_mul(0x2545_F491_4F6C_DD1D)
        }

        fn note(&mut self, t: u64) {
            let d = self.ab.detected();
            if d != self.detected {
                self.detected = d;
                self.log.push((t, d));
            }
            assert_eq!(self.ab.rate(), self.listen);
            assert_eq!(self.ab.p0963(), d.map_or(5, |r| r.p0963_code()));
        }

        /// Run timers up to `t` (ns).
        fn advance_to(&mut self, t: u64) {
            loop {
                let poll_at = match self.tick {
                    None => self.ab.next_deadline().map(|d| d.as_micros() * 1000),
                    Some(_) => Some(self.next_tick),
                };
                let dp_at = self.dp_wd.and_then(|(_, d)| d);
                let next = match (poll_at, dp_at) {
                    (Some(a), Some(b)) => a.min(b),
                    (a, b) => match a.or(b) {
                        Some(x) => x,
                        None => break,
                    },
                };
                if next > t {
                    break;
                }
                if dp_at == Some(next) {
                    // The DP slave's watchdog expired: Wait_Prm, watchdog off.
                    self.dp_wd = self.dp_wd.map(|(w, _)| (w, None));
                    self.ab.dp_watchdog_active(inst(next), false);
                }
                if poll_at == Some(next) {
                    if let Some(p) = self.tick {
                        self.next_tick += p;
                    }
                    if let Some(r) = self.ab.poll(inst(next)) {
                        self.listen = r;
                        self.reprog = next;
                        self.framer = Framer::new();
                        self.rates.push((next, r));
                    }
                }
                self.note(next);
            }
        }

        fn push(&mut self, now: u64, byte: u8, right_rate: bool) {
            match self.framer.push(byte) {
                Push::Frame(_) => match decode(self.framer.frame()) {
                    Decoded::Frame(Telegram::Data(d), _) => {
                        if !right_rate {
                            self.false_frames += 1;
                        }
                        let to_us = d.da == OUR;
                        if to_us {
                            self.last_own = now;
                        }
                        self.ab.on_frame(inst(now), true, to_us);
                        // The modelled DP slave: a telegram for us while locked (re)starts its
                        // watchdog (as Set_Prm/Data_Exchange would).
                        if to_us && self.ab.detected().is_some() {
                            if let Some((w, _)) = self.dp_wd {
                                self.dp_wd = Some((w, Some(now + w)));
                                self.ab.dp_watchdog_active(inst(now), true);
                            }
                        }
                    }
                    _ => self.ab.on_frame(inst(now), false, false),
                },
                Push::Dropped(_) => self.ab.on_garbage(inst(now)),
                Push::Pending => {}
            }
        }

        fn deliver(&mut self, tx: &Tx) {
            self.advance_to(tx.end);
            let eff = tx.start.max(self.reprog);
            if eff < tx.end {
                let gap_from = self.last_end.max(self.reprog);
                let l = self.listen;
                if eff > gap_from {
                    let bits = l.duration_to_bits(Duration::from_micros((eff - gap_from) / 1000));
                    if bits >= 11 {
                        self.framer.idle(BitTimes(bits as u32));
                    }
                }
                if l == tx.rate {
                    // Exact bytes: those whose start bit comes after the reprogramming.
                    let skip = (0..tx.bytes.len())
                        .find(|&i| tx.start + bits_ns(l, 11 * i as u64) >= eff)
                        .unwrap_or(tx.bytes.len());
                    for i in skip..tx.bytes.len() {
                        self.push(tx.end, tx.bytes[i], true);
                    }
                } else {
                    // Wrong rate: pseudo-random characters, three in four with a framing or
                    // parity error (the board then drops the partial frame).
                    let n = ((tx.end - eff) * l.bits_per_second() as u64 / (11 * NS)).clamp(1, 300);
                    for _ in 0..n {
                        let r = self.rand();
                        if r & 3 != 0 {
                            self.ab.on_garbage(inst(tx.end));
                            self.framer.idle(BitTimes(0));
                        } else {
                            self.push(tx.end, (r >> 32) as u8, false);
                        }
                    }
                }
            }
            self.last_end = tx.end;
            self.note(tx.end);
        }
    }

    struct Sim {
        bus: Bus,
        l: Listener,
        pending: Option<Tx>,
    }

    impl Sim {
        fn new(segments: Vec<(u64, Option<(Baudrate, Traffic)>)>, t0: u64, cfg: Config, tick: Option<u64>) -> Self {
            Sim { bus: Bus::new(segments), l: Listener::new(t0, cfg, tick), pending: None }
        }

        /// Run until `t` (ns), or until `stop` holds after a step.
        fn run_until(&mut self, t: u64, mut stop: impl FnMut(&Listener) -> bool) {
            loop {
                if self.pending.is_none() {
                    self.pending = self.bus.next();
                }
                match &self.pending {
                    Some(tx) if tx.end <= t => {
                        let tx = self.pending.take().unwrap();
                        if tx.end > self.l.reprog {
                            self.l.deliver(&tx);
                        }
                    }
                    _ => {
                        self.l.advance_to(t);
                        return;
                    }
                }
                if stop(&self.l) {
                    return;
                }
            }
        }
    }

    fn first_lock(l: &Listener) -> Option<(u64, Baudrate)> {
        l.log.iter().find_map(|&(t, d)| d.map(|r| (t, r)))
    }

    /// Sum of dwells from 12M down to and including `rate`: the first-visit lock bound.
    fn first_visit_bound(rate: Baudrate) -> u64 {
        Baudrate::ALL.iter().take_while(|&&r| r != rate).map(|&r| dwell(r).as_micros()).sum::<u64>()
            + dwell(rate).as_micros()
    }

    fn ms(ns: u64) -> f64 {
        ns as f64 / 1e6
    }

    // ------------------------------------------------------------------------------------
    // Unit tests of the machine.
    // ------------------------------------------------------------------------------------

    #[test]
    fn dwell_table_and_scan_time() {
        let expect_us = [10_000, 10_000, 10_000, 10_000, 15_220, 40_587, 81_174, 167_437, 396_355, 792_709];
        for (r, us) in Baudrate::ALL.iter().zip(expect_us) {
            assert_eq!(dwell(*r).as_micros(), us, "{r:?}");
            // Dwell ≥ two longest telegrams + gap budget at every rate.
            assert!(r.duration_to_bits(dwell(*r)) >= DWELL_BITS as u64 - 1);
        }
        assert_eq!(full_scan().as_micros(), 1_533_482);
        assert!(full_scan() < Duration::from_millis(2000));
    }

    #[test]
    fn config_from_register_value() {
        assert_eq!(Config::default().baud_control, Duration::from_millis(2560));
        assert_eq!(Config::from_wd_baud_control_val(1).baud_control, Duration::from_millis(10));
        assert_eq!(Config::from_wd_baud_control_val(0).baud_control, Duration::from_millis(10));
        assert_eq!(Config::from_wd_baud_control_val(255).baud_control, Duration::from_millis(650_250));
    }

    #[test]
    fn power_up_state() {
        let ab = Autobaud::new(Instant::from_millis(5));
        assert_eq!(ab.rate(), Baudrate::B12M);
        assert_eq!(ab.state(), Supervision::BaudSearch);
        assert_eq!(ab.detected(), None);
        assert_eq!(ab.p0963(), 5);
        assert_eq!(ab.next_deadline(), Some(Instant::from_millis(15)));
    }

    #[test]
    fn tokens_sc_and_garbage_do_not_lock() {
        let mut ab = Autobaud::new(Instant::from_millis(0));
        for i in 0..100 {
            ab.on_frame(Instant::from_micros(i * 50), false, false);
            ab.on_garbage(Instant::from_micros(i * 50 + 10));
        }
        assert_eq!(ab.detected(), None);
        assert_eq!(ab.stats().garbage, 100);
        assert_eq!(ab.poll(Instant::from_millis(10)), Some(Baudrate::B6M));
    }

    #[test]
    fn baud_control_retriggered_only_by_own_frames() {
        let t = Instant::from_millis;
        let mut ab = Autobaud::new(t(0));
        ab.on_frame(t(1), true, false);
        assert_eq!(ab.detected(), Some(Baudrate::B12M));
        assert_eq!(ab.p0963(), 9);
        assert_eq!(ab.next_deadline(), Some(t(2561)));
        ab.on_frame(t(2000), true, false); // others: no retrigger
        assert_eq!(ab.poll(t(2560)), None);
        assert_eq!(ab.state(), Supervision::BaudControl);
        ab.on_frame(t(2560), true, true); // ours: retrigger
        assert_eq!(ab.next_deadline(), Some(t(5120)));
        assert_eq!(ab.poll(t(5120)), None);
        assert_eq!(ab.state(), Supervision::BaudSearch);
        assert_eq!(ab.stats().baud_control_expiries, 1);
        // The search resumes at the locked rate for one dwell.
        assert_eq!(ab.rate(), Baudrate::B12M);
        assert_eq!(ab.poll(t(5129)), None);
        assert_eq!(ab.poll(t(5130)), Some(Baudrate::B6M));
    }

    #[test]
    fn dp_control_suspends_baud_control() {
        let t = Instant::from_millis;
        let mut ab = Autobaud::new(t(0));
        ab.dp_watchdog_active(t(0), true); // while searching: remembered only
        assert_eq!(ab.state(), Supervision::BaudSearch);
        ab.dp_watchdog_active(t(0), false);
        ab.on_frame(t(1), true, true);
        ab.dp_watchdog_active(t(2), true);
        assert_eq!(ab.state(), Supervision::DpControl);
        assert_eq!(ab.next_deadline(), None);
        assert_eq!(ab.poll(t(100_000)), None);
        assert_eq!(ab.detected(), Some(Baudrate::B12M));
        ab.dp_watchdog_active(t(100_000), false); // DP watchdog expired
        assert_eq!(ab.state(), Supervision::BaudControl);
        assert_eq!(ab.next_deadline(), Some(t(102_560)));
        assert_eq!(ab.poll(t(102_560)), None);
        assert_eq!(ab.state(), Supervision::BaudSearch);
        // Locking while the DP watchdog is reported active goes straight to DP_Control.
        ab.dp_watchdog_active(t(102_561), true);
        ab.on_frame(t(102_562), true, false);
        assert_eq!(ab.state(), Supervision::DpControl);
    }

    #[test]
    fn late_poll_advances_one_rate() {
        let mut ab = Autobaud::new(Instant::from_millis(0));
        assert_eq!(ab.poll(Instant::from_millis(10_000)), Some(Baudrate::B6M));
        assert_eq!(ab.next_deadline(), Some(Instant::from_millis(10_010)));
    }

    #[derive(Debug, Clone)]
    enum Op {
        Frame { ok: bool, ours: bool },
        Garbage,
        Poll,
        Dp(bool),
    }

    fn op() -> impl proptest::strategy::Strategy<Value = (u64, Op)> {
        use proptest::prelude::*;
        let op = prop_oneof![
            (any::<bool>(), any::<bool>()).prop_map(|(ok, ours)| Op::Frame { ok, ours }),
            Just(Op::Garbage),
            Just(Op::Poll),
            Just(Op::Poll),
            any::<bool>().prop_map(Op::Dp),
        ];
        (prop_oneof![0u64..2_000, 0u64..50_000, 0u64..3_000_000], op)
    }

    proptest::proptest! {
        /// Any input sequence: the invariants of the state machine hold.
        #[test]
        fn invariants(val in 1u8..40, ops in proptest::collection::vec(op(), 0..300)) {
            use proptest::prop_assert_eq as eq;
            use proptest::prop_assert as check;
            let cfg = Config::from_wd_baud_control_val(val);
            let mut now = Instant::from_micros(1);
            let mut ab = Autobaud::with_config(now, cfg);
            let mut dwell_start = now;
            let mut retrigger = now; // start of the running T_bc
            let mut dp = false;
            for (dt, op) in ops {
                now = now + Duration::from_micros(dt);
                let (before_state, before_rate) = (ab.state(), ab.rate());
                match op {
                    Op::Frame { ok, ours } => {
                        ab.on_frame(now, ok, ours);
                        match (before_state, ok) {
                            (Supervision::BaudSearch, true) => {
                                eq!(ab.state(), if dp { Supervision::DpControl } else { Supervision::BaudControl });
                                retrigger = now;
                            }
                            (Supervision::BaudControl, true) if ours => retrigger = now,
                            _ => eq!(ab.state(), before_state),
                        }
                    }
                    Op::Garbage => {
                        ab.on_garbage(now);
                        eq!(ab.state(), before_state);
                    }
                    Op::Dp(a) => {
                        dp = a;
                        ab.dp_watchdog_active(now, a);
                        match (before_state, a) {
                            (Supervision::BaudControl, true) => eq!(ab.state(), Supervision::DpControl),
                            (Supervision::DpControl, false) => {
                                eq!(ab.state(), Supervision::BaudControl);
                                retrigger = now;
                            }
                            _ => eq!(ab.state(), before_state),
                        }
                    }
                    Op::Poll => {
                        let r = ab.poll(now);
                        match before_state {
                            Supervision::BaudSearch => {
                                let due = now >= dwell_start + dwell(before_rate);
                                eq!(r.is_some(), due);
                                if let Some(r) = r {
                                    eq!(r, ab.rate());
                                    let i = Baudrate::ALL.iter().position(|&x| x == before_rate).unwrap();
                                    eq!(r, Baudrate::ALL[(i + 1) % 10]);
                                    dwell_start = now;
                                }
                            }
                            Supervision::BaudControl => {
                                eq!(r, None);
                                let expired = now >= retrigger + cfg.baud_control;
                                eq!(ab.state() == Supervision::BaudSearch, expired);
                                if expired {
                                    dwell_start = now;
                                }
                            }
                            Supervision::DpControl => {
                                eq!(r, None);
                                eq!(ab.state(), Supervision::DpControl);
                            }
                        }
                    }
                }
                if !matches!(op, Op::Poll) {
                    eq!(ab.rate(), before_rate);
                }
                eq!(ab.detected().is_some(), ab.state() != Supervision::BaudSearch);
                eq!(ab.p0963() == 5, ab.detected().is_none());
                if let Some(r) = ab.detected() {
                    eq!(r, ab.rate());
                }
                check!(ab.next_deadline().is_none() == (ab.state() == Supervision::DpControl));
            }
        }
    }

    // ------------------------------------------------------------------------------------
    // Simulated bus.
    // ------------------------------------------------------------------------------------

    /// From power-up at an arbitrary phase of the traffic, every rate locks on the first visit:
    /// within the sum of the dwells down to it. Prints the worst case per rate.
    #[test]
    fn detection_at_all_rates_from_power_up() {
        std::println!("rate      dwell ms  bound ms  worst lock ms (normal / heavy traffic)");
        for rate in Baudrate::ALL {
            let mut worst = [0u64; 2];
            for (k, traffic) in [Traffic::normal(), Traffic::heavy()].into_iter().enumerate() {
                for phase in 0..12u64 {
                    // Power-up somewhere in the first few thousand bit times of the traffic.
                    let t0 = bits_ns(rate, 20_000) + bits_ns(rate, phase * 613);
                    let mut sim = Sim::new(vec![(0, Some((rate, traffic.clone())))], t0, Config::default(), None);
                    let limit = t0 + 3 * full_scan().as_micros() * 1000;
                    sim.run_until(limit, |l| l.detected.is_some());
                    let (t, r) = first_lock(&sim.l).unwrap_or_else(|| panic!("{rate:?} phase {phase}: no lock"));
                    assert_eq!(r, rate, "phase {phase}");
                    assert_eq!(sim.l.false_frames, 0);
                    assert_eq!(sim.l.ab.p0963(), rate.p0963_code());
                    let lock = t - t0;
                    assert!(
                        lock <= first_visit_bound(rate) * 1000,
                        "{rate:?} {k} phase {phase}: {} ms > {} ms",
                        ms(lock),
                        first_visit_bound(rate) as f64 / 1e3
                    );
                    worst[k] = worst[k].max(lock);
                }
            }
            std::println!(
                "{:<9} {:>8.1} {:>9.1} {:>9.2} / {:.2}",
                std::format!("{rate:?}"),
                dwell(rate).as_micros() as f64 / 1e3,
                first_visit_bound(rate) as f64 / 1e3,
                ms(worst[0]),
                ms(worst[1])
            );
        }
    }

    /// The board polls on a 1 ms tick instead of at the exact deadlines: same result, each
    /// dwell up to one tick longer.
    #[test]
    fn detection_with_coarse_polling() {
        for rate in Baudrate::ALL {
            let t0 = 1_234_567;
            let mut sim = Sim::new(vec![(0, Some((rate, Traffic::normal())))], t0, Config::default(), Some(1_000_000));
            sim.run_until(t0 + 3 * full_scan().as_micros() * 1000, |l| l.detected.is_some());
            let (t, r) = first_lock(&sim.l).unwrap();
            assert_eq!(r, rate);
            let idx = Baudrate::ALL.iter().position(|&x| x == rate).unwrap() as u64;
            assert!(t - t0 <= (first_visit_bound(rate) + (idx + 1) * 1000) * 1000);
        }
    }

    /// A silent bus: the search cycles through all ten rates, highest first, forever; each rate
    /// for exactly its dwell; P0963 stays 5.
    #[test]
    fn silent_bus_keeps_searching() {
        let mut sim = Sim::new(vec![(0, None)], 0, Config::default(), None);
        let end = 3 * full_scan().as_micros() * 1000 + 1;
        sim.run_until(end, |_| false);
        assert!(sim.l.log.is_empty());
        assert_eq!(sim.l.ab.p0963(), 5);
        assert_eq!(sim.l.rates.len(), 30);
        let mut prev = (0u64, Baudrate::B12M);
        for (i, &(t, r)) in sim.l.rates.iter().enumerate() {
            assert_eq!(r, Baudrate::ALL[(i + 1) % 10]);
            assert_eq!(t - prev.0, dwell(prev.1).as_micros() * 1000);
            prev = (t, r);
        }
        assert_eq!(sim.l.rates[9].0, full_scan().as_micros() * 1000);
        assert_eq!(sim.l.ab.stats().search_steps, 30);
    }

    /// The master changes the rate while we are locked: Baud_Control runs out T_bc after the
    /// last telegram for us, the search starts at the old rate and finds the new one within
    /// one full scan.
    #[test]
    fn rate_change_while_running() {
        let pairs = [
            (Baudrate::B12M, Baudrate::B9600),
            (Baudrate::B9600, Baudrate::B12M),
            (Baudrate::B1500k, Baudrate::B500k),
            (Baudrate::B500k, Baudrate::B1500k),
            (Baudrate::B187500, Baudrate::B45450),
            (Baudrate::B19200, Baudrate::B93750),
            (Baudrate::B6M, Baudrate::B3M),
        ];
        let tbc = Config::default().baud_control.as_micros() * 1000;
        for (r1, r2) in pairs {
            let change = 4 * NS;
            let segments = vec![(0, Some((r1, Traffic::normal()))), (change, Some((r2, Traffic::normal())))];
            let mut sim = Sim::new(segments, 0, Config::default(), None);
            sim.run_until(change, |_| false);
            assert_eq!(sim.l.log.len(), 1, "{r1:?}: locked once, held by own frames");
            assert_eq!(sim.l.log[0].1, Some(r1));
            let last_own = sim.l.last_own;
            sim.run_until(change + tbc + 2 * full_scan().as_micros() * 1000, |l| l.log.len() >= 3);
            let log = &sim.l.log;
            assert_eq!(log.len(), 3, "{r1:?} → {r2:?}: {log:?}");
            assert_eq!(log[1], (last_own / 1000 * 1000 + tbc, None), "{r1:?} → {r2:?}");
            assert_eq!(log[2].1, Some(r2));
            let relock = log[2].0 - log[1].0;
            assert!(relock <= full_scan().as_micros() * 1000, "{r1:?} → {r2:?}: relock {} ms", ms(relock));
            assert_eq!(sim.l.false_frames, 0);
            std::println!(
                "{r1:?} → {r2:?}: lost {:.1} ms after the change, relocked {:.1} ms later",
                ms(log[1].0 - change),
                ms(relock)
            );
        }
    }

    /// Traffic only for other stations: the rate locks (any address counts for the search)
    /// but nothing retriggers Baud_Control, so the lock is lost every T_bc and found again
    /// within one dwell (the search resumes at the same rate) — reference §9 item 8.
    #[test]
    fn traffic_for_others_only_loses_lock_every_baud_control_time() {
        let tbc = Config::default().baud_control.as_micros() * 1000;
        for rate in [Baudrate::B12M, Baudrate::B500k, Baudrate::B19200] {
            let mut sim = Sim::new(vec![(0, Some((rate, Traffic::others_only())))], 0, Config::default(), None);
            sim.run_until(3 * tbc + NS, |_| false);
            let log = &sim.l.log;
            assert!(log.len() >= 6, "{rate:?}: {log:?}");
            for pair in log.windows(2) {
                match (pair[0], pair[1]) {
                    ((t_lock, Some(r)), (t_lost, None)) => {
                        assert_eq!(r, rate);
                        assert_eq!(t_lost, t_lock / 1000 * 1000 + tbc);
                    }
                    ((t_lost, None), (t_lock, Some(r))) => {
                        assert_eq!(r, rate);
                        assert!(t_lock - t_lost <= dwell(rate).as_micros() * 1000);
                    }
                    other => panic!("{other:?}"),
                }
            }
            assert_eq!(sim.l.ab.stats().baud_control_expiries as usize, log.len() / 2);
            assert_eq!(sim.l.rates.len(), Baudrate::ALL.iter().position(|&r| r == rate).unwrap());
        }
    }

    /// DP_Control: with the DP watchdog running, a quiet line longer than T_bc keeps the rate;
    /// after a rate change the DP watchdog expires first, then Baud_Control, then the search.
    #[test]
    fn dp_watchdog_interplay() {
        let tbc = Config::default().baud_control.as_micros() * 1000;
        let twd = 200_000_000; // 200 ms DP watchdog
        let r = Baudrate::B1500k;
        // Quiet line for 6 s (> T_bc) in the middle: the lock holds while the DP watchdog
        // is long enough (modelled as 10 s here).
        let segments = vec![(0, Some((r, Traffic::normal()))), (NS, None), (7 * NS, Some((r, Traffic::normal())))];
        let mut sim = Sim::new(segments, 0, Config::default(), None);
        sim.l.dp_wd = Some((10 * NS, None));
        sim.run_until(9 * NS, |_| false);
        assert_eq!(sim.l.log.len(), 1, "{:?}", sim.l.log);
        assert_eq!(sim.l.ab.state(), Supervision::DpControl);

        // Rate change with a 200 ms DP watchdog: lost at last own frame + T_wd + T_bc.
        let change = 2 * NS;
        let r2 = Baudrate::B93750;
        let segments = vec![(0, Some((r, Traffic::normal()))), (change, Some((r2, Traffic::normal())))];
        let mut sim = Sim::new(segments, 0, Config::default(), None);
        sim.l.dp_wd = Some((twd, None));
        sim.run_until(change, |_| false);
        let last_own = sim.l.last_own;
        assert_eq!(sim.l.ab.state(), Supervision::DpControl);
        sim.run_until(change + twd + tbc + 2 * full_scan().as_micros() * 1000, |l| l.log.len() >= 3);
        let log = &sim.l.log;
        assert_eq!(log.len(), 3, "{log:?}");
        assert_eq!(log[1], ((last_own + twd) / 1000 * 1000 + tbc, None));
        assert_eq!(log[2].1, Some(r2));
    }
}
