//! QEMU's `netduinoplus2` machine (STM32F405): the same firmware without real hardware
//! timing, for the end-to-end test, the demo and the instruction-count benchmark.
//!
//! What QEMU 7.2 models, and what this board module does about it
//! (`/work/shared/reference/toolchain.md`, QEMU section):
//!
//! * **No RCC model** (reads 0): no HSE, no PLL — the reset HSI clock is kept
//!   ([`Config::hsi`](stm32f4xx_hal::rcc::Config::hsi) waits for nothing). The SysTick runs at a
//!   fixed [`SYSTICK_HZ`] = 168 MHz whatever RCC says, so the monotonic is started with that.
//! * **USART1 carries data only** (`-serial` #0): RXNE/TXE/TC interrupts per byte, baud rate,
//!   parity and word length ignored, no IDLE flag, no DMA. [`QemuUsart1`] is therefore a
//!   per-byte interrupt driver that finds frame ends by length alone (the framer does that):
//!   it reports no idle gaps — the bytes of one telegram may reach QEMU's socket milliseconds
//!   apart on a busy host, so a gap measured here would cut telegrams — and it does not wait
//!   for min_TSDR before answering (the emulated line has no bit time; the peer is a host
//!   program). QEMU holds back the next received byte until DR has been read (no overrun),
//!   and bytes sent before the receiver is enabled are dropped (the host waits for a first
//!   answer before it starts its master).
//! * **An idle line after each request** (reference §1.4: a telegram is valid only when the
//!   line stays idle for T_SYN after it; issue 12 item 4e, line part). QEMU has no bit time,
//!   and QEMU's UART hands over the bytes the host wrote back to back one at a time, each
//!   after DR was read — so "more bytes follow" cannot be seen at the last byte's interrupt.
//!   Every answer (fast path or core) is therefore staged in the port's buffer
//!   ([`QemuUsart1::stage_tx`]) and starts only after a quiet window of [`QUIET_US`] (5 ms of
//!   the SysTick clock; 50 µs of emulated time in the `bench` build, whose `-icount` clock
//!   only advances with instructions or by jumping to the next timer while the CPU sleeps)
//!   from the request's last byte; any character arriving in that window — or while the core
//!   works on a DP-V1 request — drops the answer and counts it
//!   ([`LineStats::dropped_line_active`], the F411's `TxDrop::LineActive`). The telegram
//!   itself has reached the fast path / core, as on the F411. No timer is used: the
//!   housekeeping task (every millisecond) pends USART1 while an answer waits
//!   ([`answer_waiting`]), and the interrupt starts it once the window has passed, so an
//!   answer leaves 5–6 ms after its request (the e2e master's slot time is 160 ms). The
//!   benchmark's instruction count ends when the answer is staged, not at its start.
//! * **No GPIO, no DE pin**: nothing to switch; the pin multiplexer is not programmed.
//! * **Logs**: defmt over semihosting (`defmt-semihosting`); QEMU's stdout carries the defmt
//!   frames, decoded with `defmt-print -e <elf>`.
//! * **Exit codes**: a panic or a HardFault ends QEMU through semihosting with exit code 1
//!   (`-semihosting-config enable=on,target=native`), so a broken firmware fails a run instead
//!   of hanging it.
//! * **Benchmark** (feature `bench`): TIM2 with PSC = 0 counts one per executed instruction
//!   under `-icount shift=0,align=off,sleep=off` (see [`bench`]).

use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use cortex_m::peripheral::SYST;
use pbcard::fdl::framer::{Cut, Framer, FramerStats};
use pbcard::fdl::telegram::MAX_FRAME_LEN;
use pbcard::phy::stream::TelegramSink;
use pbcard::time::{Baudrate, BitTimes, Instant};
use stm32f4xx_hal::pac::{self, RCC, USART1};
use stm32f4xx_hal::rcc::{self, Enable, RccExt, Reset};

use super::clock::{self, SysTickClock};
use super::divisor::usart_brr;
use pbcard::phy::line::BitClock;

use super::{
    BitTimer, CharReceiver, Clock, DriverEnable, LineError, LineEvent, LineRate, Transmitter, TxError, UnsupportedRate,
};

/// Board name for the boot log.
pub const NAME: &str = "QEMU netduinoplus2 (STM32F405), USART1 per byte, no line timing";

/// QEMU's SysTick frequency on netduinoplus2 (fixed, independent of RCC).
pub const SYSTICK_HZ: u32 = 168_000_000;

/// The line port of this board.
pub type Port = QemuUsart1<SysTickClock>;
/// The line of this board: only the line interrupt uses it (the lower tasks read
/// [`LineView`]).
pub type Line = QemuLine;
/// The rate control of this board (fixed).
pub type Baud = FixedRate;

/// What [`init`] hands to the application.
pub struct Board {
    /// USART1, receiving, with its framer; the fast path is attached in `init`.
    pub line: QemuLine,
    /// The microsecond clock (SysTick monotonic).
    pub clock: SysTickClock,
}

/// Clocks (reset HSI), SysTick monotonic at 168 MHz, USART1 at `rate` (receiving); with the
/// `bench` feature also TIM2 as the instruction counter.
pub fn init(dp: pac::Peripherals, syst: SYST, rate: Baudrate) -> Board {
    let mut rcc = dp.RCC.freeze(rcc::Config::hsi());
    let pclk2 = rcc.clocks.pclk2().raw();
    let clock = clock::start(syst, SYSTICK_HZ);
    #[cfg(feature = "bench")]
    bench::start(dp.TIM2, &mut rcc);
    let port = QemuUsart1::new(dp.USART1, clock, pclk2, rate, &mut rcc);
    defmt::info!("USART1 {} (QEMU ignores the rate), HSI {=u32} Hz, SysTick {=u32} Hz", port.rate(), pclk2, SYSTICK_HZ);
    Board { line: QemuLine::new(port), clock }
}

/// The line's counters for the lower tasks, published by the line interrupt after each
/// interrupt (plain atomic stores; the lower tasks only load).
static LINE_STATS: [AtomicU32; 9] = [const { AtomicU32::new(0) }; 9];
/// An answer waits for its quiet window ([`QUIET_US`]): the housekeeping task pends the line
/// interrupt every millisecond while this is set ([`answer_waiting`]).
static ANSWER_WAITING: AtomicBool = AtomicBool::new(false);

/// The quiet window after a request before its answer starts (microseconds of the SysTick
/// clock; see the module documentation): 5 ms, in the benchmark build 50 µs of emulated time.
pub const QUIET_US: u64 = if cfg!(feature = "bench") { 50 } else { 5_000 };

/// Whether an answer waits for its quiet window (the housekeeping task pends USART1 then).
pub fn answer_waiting() -> bool {
    ANSWER_WAITING.load(Ordering::Relaxed)
}
static RX_STATS: [AtomicU32; 4] = [const { AtomicU32::new(0) }; 4];
/// The lower tasks' view of the QEMU line: no lock shared with the line interrupt.
pub struct LineView;

impl LineView {
    /// Counters (as of the line's last interrupt).
    pub fn stats(&self) -> LineStats {
        let l = |i: usize| LINE_STATS[i].load(Ordering::Relaxed);
        LineStats {
            parity: l(0),
            framing: l(1),
            noise: l(2),
            overrun: l(3),
            queue_full: l(4),
            tx_busy: l(5),
            tx_bad_length: l(6),
            responses: l(7),
            dropped_line_active: l(8),
        }
    }

    /// The framer's counters.
    pub fn rx_stats(&self) -> FramerStats {
        let r = |i: usize| RX_STATS[i].load(Ordering::Relaxed);
        FramerStats { frames: r(0), corrupt: r(1), truncated: r(2), skipped_bytes: r(3) }
    }

    /// Telegrams lost on the line (STATUS.CORRUPT_FRAMES): the framer's invalid telegrams and
    /// those cut off.
    pub fn corrupt_frames(&self) -> u32 {
        let f = self.rx_stats();
        f.corrupt.wrapping_add(f.truncated)
    }
}

/// What the line keeps with each telegram.
#[derive(Debug, Clone, Copy)]
pub struct FrameMeta {
    /// TIM2 at the entry of the interrupt that took the last byte (benchmark build).
    #[cfg(feature = "bench")]
    entry: u32,
    /// The telegram's length (benchmark log).
    #[cfg(feature = "bench")]
    len: usize,
}

/// Line-level counters of the per-byte port (shown in the log).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, defmt::Format)]
pub struct LineStats {
    pub parity: u32,
    pub framing: u32,
    pub noise: u32,
    pub overrun: u32,
    /// Telegrams dropped because the decision task had not taken the older ones.
    pub queue_full: u32,
    /// A response was due while the previous one was still being sent.
    pub tx_busy: u32,
    /// The station returned a response the port could not take (length).
    pub tx_bad_length: u32,
    pub responses: u32,
    /// Answers not sent because a character arrived after the request within the quiet
    /// window (no idle line after the request: the F411's `TxDrop::LineActive`).
    pub dropped_line_active: u32,
}

/// The QEMU line with the same shape as the F411's `DmaLine`: the per-byte interrupt feeds a
/// [`Framer`] (frame ends by length; QEMU reports no gaps), complete telegrams go into a queue
/// for the core; the fast path's (or the core's) answer starts after the quiet window
/// ([`QUIET_US`]: no line timing under QEMU).
///
/// `repr(C)`, the fast path first and the held characters (8 KiB) last: every field the
/// per-character path touches stays within an immediate load offset of the line's base
/// (the compiler's own field order can put the fast path behind the held characters, which
/// costs an extra instruction per field access on the response path).
#[repr(C)]
pub struct QemuLine {
    /// The line half of the split (`pbcard::fast`), attached once in `init`.
    fast: Option<pbcard::fast::FastPath<'static>>,
    port: Port,
    framer: Framer,
    stats: LineStats,
    /// A request the fast path left to the core: its data, until the core's answer is back.
    awaiting: Option<FrameMeta>,
    /// An answer in the port's buffer, waiting for its quiet window: since when, for which
    /// request, through the core.
    staged: Option<(Instant, FrameMeta, bool)>,
    /// Characters are held until the core has caught up (see [`take`]).
    hold: bool,
    /// A character arrived while the core worked on the request in `awaiting`.
    active_while_awaiting: bool,
    /// The F411's DMA receive, emulated (feature `bench-dma`; zero-sized otherwise).
    emu: DmaEmu,
    /// The held characters and their arrival times.
    held: heapless::Deque<(u8, Instant), HELD>,
}

/// Characters the line holds at most while the core catches up (two longest telegrams).
const HELD: usize = 2 * MAX_FRAME_LEN;

impl QemuLine {
    fn new(port: Port) -> Self {
        QemuLine {
            port,
            framer: Framer::new(),
            stats: LineStats::default(),
            awaiting: None,
            fast: None,
            hold: false,
            held: heapless::Deque::new(),
            staged: None,
            active_while_awaiting: false,
            emu: DmaEmu::new(),
        }
    }

    /// Give the line its fast path (from `init`, after the split).
    pub fn attach(&mut self, fast: pbcard::fast::FastPath<'static>) {
        self.fast = Some(fast);
    }

    /// The USART1 interrupt with the ASIC-style split (`pbcard::fast`): every character into
    /// the framer, every telegram into the fast path, which answers at once from the staged
    /// frames (the response's first character goes into DR in this interrupt) or leaves it to
    /// the core (DP-V1): then the core's answer is sent when the core task pends this
    /// interrupt again. Returns `true` when telegrams were queued for the core.
    pub fn on_usart_fast(&mut self) -> bool {
        #[cfg(feature = "bench")]
        let mut entry = bench::count();
        #[cfg(not(feature = "bench"))]
        let entry = 0u32;
        let Some(fast) = self.fast.as_mut() else {
            return false;
        };
        let queued_before = fast.stats().queued;
        if let Some(meta) = self.awaiting {
            if let Some(answer) = fast.take_deferred() {
                self.awaiting = None;
                if core::mem::take(&mut self.active_while_awaiting) {
                    self.stats.dropped_line_active = self.stats.dropped_line_active.wrapping_add(1);
                } else if !answer.is_empty() {
                    let now = self.port.clock.now();
                    stage(&mut self.port, &mut self.stats, &mut self.staged, meta, answer, true, now);
                }
            }
        }
        // The core has caught up: the held characters first, in order.
        if self.hold && fast.core_idle() {
            self.hold = false;
        }
        while !self.hold {
            let Some((byte, at)) = self.held.pop_front() else { break };
            self.hold = take(
                &mut self.port,
                &mut self.stats,
                &mut self.framer,
                fast,
                &mut self.awaiting,
                &mut self.staged,
                &mut self.emu,
                byte,
                at,
                entry,
            );
        }
        while let Some(ev) = self.port.poll_event_from(|| fast.answer_given()) {
            if !matches!(ev, LineEvent::TxDone) {
                // A character after the request: the line was not idle after it, so its
                // answer is not sent (module documentation).
                if self.staged.take().is_some() {
                    self.port.abort_tx();
                    self.stats.dropped_line_active = self.stats.dropped_line_active.wrapping_add(1);
                }
                if self.awaiting.is_some() {
                    self.active_while_awaiting = true;
                }
            }
            match ev {
                LineEvent::Byte { byte, at, .. } => {
                    if self.hold {
                        // DR is read (QEMU keeps its interrupt line up otherwise); the
                        // character waits here until the core has caught up.
                        if self.held.push_back((byte, at)).is_err() {
                            self.stats.queue_full = self.stats.queue_full.wrapping_add(1);
                        }
                    } else {
                        self.hold = take(
                            &mut self.port,
                            &mut self.stats,
                            &mut self.framer,
                            fast,
                            &mut self.awaiting,
                            &mut self.staged,
                            &mut self.emu,
                            byte,
                            at,
                            entry,
                        );
                        // The character's cost: its event (SR, DR, clock) through the cut,
                        // the sink and — at the last — the decision (benchmark build).
                        #[cfg(feature = "bench")]
                        bench::char_cost(bench::count().wrapping_sub(entry));
                    }
                }
                LineEvent::Error(e) => {
                    let inc = |c: &mut u32, on: bool| *c = c.wrapping_add(u32::from(on));
                    inc(&mut self.stats.parity, e.parity);
                    inc(&mut self.stats.framing, e.framing);
                    inc(&mut self.stats.noise, e.noise);
                    inc(&mut self.stats.overrun, e.overrun);
                    self.framer.line_error();
                    self.emu.line_error(fast);
                    fast.abort();
                }
                LineEvent::TxDone => {}
            }
            #[cfg(feature = "bench")]
            {
                entry = bench::count();
            }
        }
        // The quiet window has passed without a character: the answer starts.
        if let Some((since, meta, through_core)) = self.staged {
            let now = self.port.clock.now();
            if now.saturating_since(since).as_micros() >= QUIET_US {
                self.staged = None;
                self.port.start_staged(fast.answer_given());
                self.stats.responses = self.stats.responses.wrapping_add(1);
                #[cfg(feature = "bench")]
                defmt::info!(
                    "BENCH req {=usize} resp {=usize} instr {=u32} {=str}",
                    meta.len,
                    self.port.tx_len,
                    self.port.tx_first_count().wrapping_sub(meta.entry),
                    if through_core { "core" } else { "fast" }
                );
                let _ = (meta, through_core);
            }
        }
        ANSWER_WAITING.store(self.staged.is_some(), Ordering::Relaxed);
        publish_stats(&self.stats, &self.framer, fast.stats().invalid);
        fast.stats().queued != queued_before
    }
}

/// One character into the framer, which cuts the stream by the headers' lengths
/// ([`Framer::cut`], no decoding), and straight on into the fast path's
/// [`TelegramSink`] (`begin` at a start delimiter, `bytes` for every character, `abort` for
/// a bad header): the destination filter, the checksum, the copy into the core's queue slot
/// and the likely answer are done character by character, so at the telegram's last
/// character only [`FastPath::finish`](pbcard::fast::FastPath::finish) runs, whose time does
/// not grow with the telegram. Its answer goes onto the line. Returns whether the fast path
/// queued the telegram for the core: then the
/// line holds the characters that follow until the core has caught up (QEMU's master is a
/// host program that sends the next request the moment it has the answer — sooner, in
/// emulated time, than a real master's turnaround — and would otherwise keep this
/// interrupt busy so that the core never ran between two requests; the answer itself waits
/// only for its quiet window, [`QUIET_US`]). The F411's DMA receiver needs nothing of the kind.
#[allow(clippy::too_many_arguments)]
#[cfg(not(feature = "bench-dma"))]
fn take(
    port: &mut Port,
    stats: &mut LineStats,
    framer: &mut Framer,
    fast: &mut pbcard::fast::FastPath<'static>,
    awaiting: &mut Option<FrameMeta>,
    staged: &mut Option<(Instant, FrameMeta, bool)>,
    _emu: &mut DmaEmu,
    byte: u8,
    at: Instant,
    entry: u32,
) -> bool {
    #[cfg(feature = "bench")]
    let sink_start = bench::count();
    match framer.cut(byte) {
        Cut::Skip => return false,
        Cut::Dropped(_) => {
            fast.abort();
            return false;
        }
        Cut::Byte { first, last } => {
            if first {
                fast.begin();
            }
            fast.bytes(&[byte]);
            if !last {
                #[cfg(feature = "bench")]
                bench::char_in(
                    framer.telegram_len(),
                    false,
                    fast.receiving_for_us(),
                    bench::count().wrapping_sub(sink_start),
                );
                return false;
            }
        }
    }
    // The benchmark's bookkeeping of the last character comes after the answer is staged
    // (below): it is not the line's work and stays out of the measured response path.
    #[cfg(feature = "bench")]
    let bench_us = fast.receiving_for_us();
    let _ = entry;
    let meta = FrameMeta {
        #[cfg(feature = "bench")]
        entry,
        #[cfg(feature = "bench")]
        len: framer.telegram_len(),
    };
    let queued = finish(port, stats, fast, awaiting, staged, meta, at);
    #[cfg(feature = "bench")]
    bench::char_in(framer.telegram_len(), true, bench_us, 0);
    queued
}

/// [`take`] of the `bench-dma` build: the character into [`DmaEmu`].
#[allow(clippy::too_many_arguments)]
#[cfg(feature = "bench-dma")]
fn take(
    port: &mut Port,
    stats: &mut LineStats,
    framer: &mut Framer,
    fast: &mut pbcard::fast::FastPath<'static>,
    awaiting: &mut Option<FrameMeta>,
    staged: &mut Option<(Instant, FrameMeta, bool)>,
    emu: &mut DmaEmu,
    byte: u8,
    at: Instant,
    _entry: u32,
) -> bool {
    emu.take(port, stats, framer, fast, awaiting, staged, byte, at)
}

/// The fast path's decision at the end of a telegram and its answer staged (or the telegram
/// left to the core): whether the fast path queued it. Both receives' [`take`] end here.
#[inline(always)]
fn finish(
    port: &mut Port,
    stats: &mut LineStats,
    fast: &mut pbcard::fast::FastPath<'static>,
    awaiting: &mut Option<FrameMeta>,
    staged: &mut Option<(Instant, FrameMeta, bool)>,
    meta: FrameMeta,
    at: Instant,
) -> bool {
    let before = fast.stats().queued;
    match fast.finish(at) {
        pbcard::fast::Verdict::Answer(bytes) => stage(port, stats, staged, meta, bytes, false, at),
        pbcard::fast::Verdict::Core => *awaiting = Some(meta),
        pbcard::fast::Verdict::Silent => {}
    }
    fast.stats().queued != before
}

/// The F411's DMA receive (≥ 3 Mbit/s, `bsp::f411::DmaLine::walk_ring`) emulated on QEMU's
/// per-byte USART for the benchmark (feature `bench-dma`; a zero-sized stand-in otherwise):
/// every character goes into a 16-byte chunk as the DMA would put it into the ring, not into
/// the stream. At every 16th character of the line (the ring's half- and full-transfer
/// points, which do not follow the telegrams) the chunk goes through `Stream::piece` into the
/// fast path's sink — the HT/TC interrupt's work, counted per chunk (`CHUNK` log lines), with
/// the F411's destination filter (`Stream::set_filter`, other stations' telegrams skipped by
/// length). At a
/// telegram's last character — where on the F411 the USART's IDLE interrupt comes one
/// character later — the count starts (`entry`: the IDLE handler's entry), the remainder of
/// 1 … 16 characters goes through `Stream::piece` and `FastPath::finish` decides: the window
/// the F411's IDLE handler runs between the line going quiet and its answer's DMA start,
/// without the handler's own register work (SR, NDTR, the ring walk, the T_SYN compare:
/// estimated from the source, `card::F411_IDLE_ENTRY_INSTRUCTIONS`). The end is known here from
/// a shadow [`Framer::cut`] of every character, outside the count (the F411 learns it from
/// the IDLE flag).
#[cfg(feature = "bench-dma")]
pub struct DmaEmu {
    stream: pbcard::phy::stream::Stream,
    chunk: [u8; 16],
    n: usize,
    /// Characters of the line so far, modulo 16 (the ring's half).
    pos: u8,
    /// The cost of the telegram's first chunk (its start delimiter and header: the sink's
    /// `begin`, the destination filter) and the largest of its later chunks.
    chunk_first: Option<u32>,
    chunk_max: u32,
    /// The smallest of its later chunks (a chunk the SysTick interrupt did not preempt).
    chunk_min: u32,
}

/// The zero-sized stand-in of every build but `bench-dma`.
#[cfg(not(feature = "bench-dma"))]
pub struct DmaEmu;

#[cfg(not(feature = "bench-dma"))]
impl DmaEmu {
    const fn new() -> Self {
        DmaEmu
    }
    #[inline(always)]
    fn line_error(&mut self, _fast: &mut pbcard::fast::FastPath<'static>) {}
}

#[cfg(feature = "bench-dma")]
impl DmaEmu {
    const fn new() -> Self {
        DmaEmu {
            stream: pbcard::phy::stream::Stream::new(pbcard::phy::stream::Resync::Hunt),
            chunk: [0; 16],
            n: 0,
            pos: 0,
            chunk_first: None,
            chunk_max: 0,
            chunk_min: u32::MAX,
        }
    }

    /// A character error: the telegram in progress and the unfed chunk are dropped.
    fn line_error(&mut self, fast: &mut pbcard::fast::FastPath<'static>) {
        self.n = 0;
        self.stream.error(fast);
    }

    /// One received character (see the type's documentation).
    #[allow(clippy::too_many_arguments)]
    fn take(
        &mut self,
        port: &mut Port,
        stats: &mut LineStats,
        framer: &mut Framer,
        fast: &mut pbcard::fast::FastPath<'static>,
        awaiting: &mut Option<FrameMeta>,
        staged: &mut Option<(Instant, FrameMeta, bool)>,
        byte: u8,
        at: Instant,
    ) -> bool {
        use pbcard::phy::stream::Step;
        let last = matches!(framer.cut(byte), Cut::Byte { last: true, .. });
        self.chunk[self.n] = byte;
        self.n += 1;
        self.pos = (self.pos + 1) % 16;
        if !last {
            if self.pos == 0 {
                // The half- or full-transfer interrupt: the chunk into the stream.
                let t0 = bench::count();
                let (_, step) = self.stream.piece(&self.chunk[..self.n], fast);
                let cost = bench::count().wrapping_sub(t0);
                match self.chunk_first {
                    None => self.chunk_first = Some(cost),
                    Some(_) => {
                        self.chunk_max = self.chunk_max.max(cost);
                        self.chunk_min = self.chunk_min.min(cost);
                    }
                }
                self.n = 0;
                if step == Step::Complete {
                    // The stream found an end the shadow cut did not: not a telegram here.
                    fast.abort();
                }
            }
            return false;
        }
        // The IDLE interrupt: the remainder, then the decision.
        let entry = bench::count();
        let (_, step) = self.stream.piece(&self.chunk[..self.n], fast);
        self.n = 0;
        let len = framer.telegram_len();
        // Another station's telegram skipped by the filter ends `Skipped` (its sink aborted at DA).
        let who = match (step, fast.receiving_for_us()) {
            (Step::Skipped, _) | (_, Some(false)) => "other",
            (_, Some(true)) => "us",
            _ => "unknown",
        };
        let queued =
            step == Step::Complete && finish(port, stats, fast, awaiting, staged, FrameMeta { entry, len }, at);
        // After the count of the answer (it ended at the answer's staging): this telegram's
        // largest chunk and its IDLE handler's part (remainder + `finish`).
        let end = bench::count().wrapping_sub(entry);
        if let Some(first) = self.chunk_first {
            defmt::info!(
                "CHUNK {=str} len {=usize} first {=u32} chunk {=u32} low {=u32} end {=u32}",
                who,
                len,
                first,
                self.chunk_max,
                self.chunk_min,
                end
            );
        }
        self.chunk_first = None;
        self.chunk_max = 0;
        self.chunk_min = u32::MAX;
        // As the F411 after every decision with its rate locked (QEMU's is fixed): other
        // stations' telegrams are skipped by length, their bytes not read.
        self.stream.set_filter(Some(fast.address()));
        queued
    }
}

/// Put a response into the port's buffer to start once the line has been quiet for
/// [`QUIET_US`] after `since` (the request's last character; see the module documentation).
fn stage(
    port: &mut Port,
    stats: &mut LineStats,
    staged: &mut Option<(Instant, FrameMeta, bool)>,
    request: FrameMeta,
    bytes: &[u8],
    through_core: bool,
    since: Instant,
) {
    // The line's own answers are sent from the fast path's answer buffer
    // (`FastPath::answer_given`) without a copy; the core's are copied into the port's.
    let r = if through_core { port.stage_tx(bytes) } else { port.stage_line(bytes.len()) };
    match r {
        Ok(()) => *staged = Some((since, request, through_core)),
        Err(TxError::Busy) => stats.tx_busy = stats.tx_busy.wrapping_add(1),
        Err(TxError::BadLength) => stats.tx_bad_length = stats.tx_bad_length.wrapping_add(1),
    }
}

/// The counters into the atomics [`LineView`] reads.
/// `invalid`: the fast path's telegrams to the station that failed to decode (the checksum is
/// the fast path's since the framer only cuts), counted with the framer's corrupt headers.
fn publish_stats(stats: &LineStats, framer: &Framer, invalid: u32) {
    {
        let l = *stats;
        for (i, v) in [
            l.parity,
            l.framing,
            l.noise,
            l.overrun,
            l.queue_full,
            l.tx_busy,
            l.tx_bad_length,
            l.responses,
            l.dropped_line_active,
        ]
        .into_iter()
        .enumerate()
        {
            LINE_STATS[i].store(v, Ordering::Relaxed);
        }
        let f = framer.stats();
        for (i, v) in [f.frames, f.corrupt.wrapping_add(invalid), f.truncated, f.skipped_bytes].into_iter().enumerate()
        {
            RX_STATS[i].store(v, Ordering::Relaxed);
        }
    }
}

/// The line's rate is its port's (QEMU ignores it; the QEMU build runs at a fixed rate,
/// `FixedRate`).
impl LineRate for QemuLine {
    fn rate(&self) -> Baudrate {
        self.port.rate()
    }

    fn set_rate(&mut self, rate: Baudrate) -> Result<(), UnsupportedRate> {
        self.port.set_rate(rate)
    }
}

impl QemuLine {
    /// Counters.
    pub fn stats(&self) -> LineStats {
        self.stats
    }

    /// The framer's counters.
    pub fn rx_stats(&self) -> FramerStats {
        self.framer.stats()
    }

    /// Telegrams lost on the line (STATUS.CORRUPT_FRAMES): the framer's bad headers (a
    /// character error inside a telegram included, `Framer::line_error`), those cut off, and
    /// the telegrams to the station the fast path found invalid (checksum, ED, length).
    pub fn corrupt_frames(&self) -> u32 {
        let f = self.framer.stats();
        let invalid = self.fast.as_ref().map_or(0, |fast| fast.stats().invalid);
        f.corrupt.wrapping_add(f.truncated).wrapping_add(invalid)
    }

    /// Always: QEMU has no line hardware to supervise.
    pub fn is_healthy(&self) -> bool {
        true
    }

    /// Nothing to restart under QEMU.
    pub fn restart_rx(&mut self) {}
}

/// The QEMU board's rate control: the fixed rate (QEMU's line has no bit time to search), with
/// the calls the F411's `pbcard::phy::autobaud::Autobaud` takes.
#[derive(Debug, Clone, Copy)]
pub struct FixedRate(pub Baudrate);

impl pbcard::phy::line::RateControl for FixedRate {
    fn on_frame(&mut self, _now: Instant, _ok: bool, _to_us: bool) {}
    fn on_garbage(&mut self, _now: Instant) {}
    fn detected(&self) -> Option<Baudrate> {
        Some(self.0)
    }
}

impl FixedRate {
    /// Nothing to supervise.
    pub fn dp_watchdog_active(&mut self, _now: Instant, _active: bool) {}
    /// Never a new rate.
    pub fn poll(&mut self, _now: Instant) -> Option<Baudrate> {
        None
    }
    /// The fixed rate.
    pub fn detected(&self) -> Option<Baudrate> {
        Some(self.0)
    }
    /// The fixed rate (the log's "rate" field).
    pub fn stats(&self) -> Baudrate {
        self.0
    }
}

/// The rate never changes under QEMU: nothing to switch (`FixedRate::poll` never asks).
pub fn switch_rate(_rate: Baudrate) -> bool {
    true
}

/// The QEMU board's supervision: nothing (no LED pins, no flash journal, no watchdog).
pub struct Supervisor;

impl Supervisor {
    /// No LEDs, no journal, no IWDG.
    pub fn tick(&mut self, _now: Instant, _leds: Option<pbcard::led::Leds>, _address: (u8, bool), _alive: bool) {}
}

/// No fault path to register with: a panic ends QEMU.
pub fn register_application(_app: &mut pbcard_sim::bench::Application) {}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Tx {
    /// Receiving.
    Idle,
    /// A response in the buffer, not started ([`QemuUsart1::stage_tx`]).
    Staged,
    /// Characters left to hand to the data register (TXE interrupt enabled).
    Sending,
    /// All characters handed over; waiting for TC (TC interrupt enabled).
    Draining,
}

/// USART1 under QEMU: one interrupt per character, no timing — the board contract's
/// [`LineRate`], [`CharReceiver`] and [`Transmitter`], with the fallbacks of a port without a
/// bit timer ([`BitTimer`]: the protocol clock's microseconds) and without DE
/// ([`DriverEnable`]: no-ops).
pub struct QemuUsart1<C: Clock> {
    usart: USART1,
    clock: C,
    pclk_hz: u32,
    rate: Baudrate,
    tx: Tx,
    tx_buf: [u8; MAX_FRAME_LEN],
    tx_len: usize,
    tx_pos: usize,
    /// The response in progress is the caller's ([`QemuUsart1::stage_line`]), not `tx_buf`.
    tx_from_line: bool,
    /// TIM2 when the first response character was written to DR (benchmark build).
    #[cfg(feature = "bench")]
    tx_first_count: u32,
}

impl<C: Clock> QemuUsart1<C> {
    /// Take USART1 (clock enabled and reset — no-ops under QEMU, kept for the real F405), program
    /// 8 data bits + even parity and start receiving with the RXNE interrupt. The NVIC line is
    /// unmasked by RTIC for the task bound to USART1.
    pub fn new(usart: USART1, clock: C, pclk_hz: u32, rate: Baudrate, rcc: &mut RCC) -> Self {
        USART1::enable(rcc);
        USART1::reset(rcc);
        let mut port = QemuUsart1 {
            usart,
            clock,
            pclk_hz,
            rate,
            tx: Tx::Idle,
            tx_buf: [0; MAX_FRAME_LEN],
            tx_len: 0,
            tx_pos: 0,
            tx_from_line: false,
            #[cfg(feature = "bench")]
            tx_first_count: 0,
        };
        port.usart.cr2().write(|w| w.stop().stop1());
        port.usart.cr3().reset();
        // Every rate is "supported": QEMU ignores the divisor.
        let _ = port.set_rate(rate);
        port
    }

    /// TIM2 count at the write of the first character of the last response started.
    #[cfg(feature = "bench")]
    pub fn tx_first_count(&self) -> u32 {
        self.tx_first_count
    }

    /// Put a response into the buffer without starting it ([`QemuUsart1::start_staged`]
    /// starts it, [`QemuUsart1::abort_tx`] drops it). In the benchmark build the instruction
    /// count is taken here: the quiet window that follows is the line's rule, not work.
    pub fn stage_tx(&mut self, bytes: &[u8]) -> Result<(), TxError> {
        if self.tx != Tx::Idle {
            return Err(TxError::Busy);
        }
        if bytes.is_empty() || bytes.len() > self.tx_buf.len() {
            return Err(TxError::BadLength);
        }
        self.tx_buf[..bytes.len()].copy_from_slice(bytes);
        self.tx_len = bytes.len();
        self.tx_from_line = false;
        self.tx = Tx::Staged;
        #[cfg(feature = "bench")]
        {
            self.tx_first_count = bench::count();
        }
        Ok(())
    }

    /// Stage a response of `len` bytes that the caller keeps and hands to every
    /// [`start_staged`](Self::start_staged) / [`poll_event_from`](Self::poll_event_from)
    /// until it is sent (the fast path's answer buffer, `FastPath::answer_given`): no copy.
    pub fn stage_line(&mut self, len: usize) -> Result<(), TxError> {
        if self.tx != Tx::Idle {
            return Err(TxError::Busy);
        }
        if len == 0 || len > MAX_FRAME_LEN {
            return Err(TxError::BadLength);
        }
        self.tx_len = len;
        self.tx_from_line = true;
        self.tx = Tx::Staged;
        #[cfg(feature = "bench")]
        {
            self.tx_first_count = bench::count();
        }
        Ok(())
    }

    /// The `i`-th character of the response in progress: from the caller's `line` bytes
    /// ([`stage_line`](Self::stage_line)) or the port's buffer ([`stage_tx`](Self::stage_tx)).
    fn tx_byte(&self, line: &[u8], i: usize) -> u8 {
        let src = if self.tx_from_line { line } else { &self.tx_buf[..] };
        src.get(i).copied().unwrap_or(0)
    }

    /// Start the staged response: its first character into DR (`line`: the caller's bytes
    /// after [`stage_line`](Self::stage_line), ignored after [`stage_tx`](Self::stage_tx)).
    pub fn start_staged(&mut self, line: &[u8]) {
        if self.tx != Tx::Staged {
            return;
        }
        let _ = self.usart.sr().read();
        let b = self.tx_byte(line, 0);
        self.usart.dr().write(|w| w.dr().set(u16::from(b)));
        self.tx_pos = 1;
        if self.tx_pos < self.tx_len {
            self.tx = Tx::Sending;
            self.usart.cr1().modify(|_, w| w.txeie().enabled());
        } else {
            self.tx = Tx::Draining;
            self.usart.cr1().modify(|_, w| w.tcie().enabled());
        }
    }

    fn abort_tx(&mut self) {
        self.usart.cr1().modify(|_, w| w.txeie().clear_bit().tcie().clear_bit());
        self.tx = Tx::Idle;
        self.tx_len = 0;
        self.tx_pos = 0;
    }
}

impl<C: Clock> LineRate for QemuUsart1<C> {
    /// QEMU ignores the divisor: every rate is accepted.
    fn set_rate(&mut self, rate: Baudrate) -> Result<(), UnsupportedRate> {
        self.abort_tx();
        self.usart.cr1().write(|w| w.ue().clear_bit());
        // QEMU ignores BRR; program the nearest divisor the HSI clock allows, for a real F405.
        if let Some((over8, brr)) = usart_brr(self.pclk_hz, rate.bits_per_second()) {
            self.usart.brr().write(|w| w.div_mantissa().set(brr >> 4).div_fraction().set((brr & 0xF) as u8));
            self.usart.cr1().write(|w| w.over8().bit(over8));
        }
        self.usart.cr1().modify(|_, w| {
            w.m().m9(); // 9-bit word: 8 data bits + the parity bit
            w.pce().enabled().ps().even();
            w.rxneie().enabled();
            w.te().enabled().re().enabled();
            w.ue().enabled()
        });
        let _ = self.usart.sr().read();
        let _ = self.usart.dr().read();
        self.rate = rate;
        Ok(())
    }

    fn rate(&self) -> Baudrate {
        self.rate
    }
}

/// Fallback: QEMU has no bit timer (and no line timing to keep): the counter is the protocol
/// clock's microseconds ([`Clock::now`], truncated to 32 bits), 1 MHz.
impl<C: Clock> BitTimer for QemuUsart1<C> {
    fn clock(&self) -> BitClock {
        BitClock { hz: 1_000_000 }
    }

    fn ticks(&self) -> u32 {
        self.clock.now().as_micros() as u32
    }
}

/// Fallback: QEMU's netduinoplus2 has no transceiver: DE is a no-op.
impl<C: Clock> DriverEnable for QemuUsart1<C> {
    fn enable(&mut self) {}
    fn disable(&mut self) {}
}

impl<C: Clock> Transmitter for QemuUsart1<C> {
    /// Fallback: starts at once, whatever `not_before` says — there is no compare to wait for
    /// and no line timing to keep under QEMU (the module comment); `QemuLine` stages its
    /// answers for a quiet window instead ([`QemuUsart1::stage_tx`]).
    fn start_tx(&mut self, bytes: &[u8], _not_before: u32) -> Result<(), TxError> {
        self.stage_tx(bytes)?;
        self.start_staged(&[]);
        Ok(())
    }

    fn tx_busy(&self) -> bool {
        self.tx != Tx::Idle
    }
}

impl<C: Clock> CharReceiver for QemuUsart1<C> {
    /// Order matters under QEMU, where TC is set the moment the last character is written and
    /// the host may have sent the next request before this handler gets to it: the end of our
    /// response is reported before received characters (so a request that arrives meanwhile
    /// never finds the port still busy), and a received character is taken before the next
    /// response character is written (QEMU's DR write clears RXNE).
    fn poll_event(&mut self) -> Option<LineEvent> {
        self.poll_event_from(|| &[])
    }
}

impl<C: Clock> QemuUsart1<C> {
    /// [`CharReceiver::poll_event`] with the caller's bytes of a response staged by
    /// [`stage_line`](Self::stage_line) (see there).
    /// `line` is asked for the bytes only when a response character is due (not on the
    /// receive path: the last request character's turn does not pay for it).
    pub fn poll_event_from<'l>(&mut self, line: impl Fn() -> &'l [u8]) -> Option<LineEvent> {
        loop {
            let sr = self.usart.sr().read();
            if self.tx == Tx::Draining && sr.tc().bit_is_set() {
                self.usart.cr1().modify(|_, w| w.tcie().disabled());
                self.tx = Tx::Idle;
                self.tx_len = 0;
                self.tx_pos = 0;
                return Some(LineEvent::TxDone);
            }
            if sr.rxne().bit_is_set() || sr.ore().bit_is_set() {
                let at = self.clock.now();
                let word = self.usart.dr().read().dr().bits();
                let err = LineError {
                    parity: sr.pe().bit_is_set(),
                    framing: sr.fe().bit_is_set(),
                    noise: sr.nf().bit_is_set(),
                    overrun: sr.ore().bit_is_set(),
                };
                if err != LineError::default() {
                    return Some(LineEvent::Error(err));
                }
                // Frames end by length: no idle gaps are reported (module comment).
                return Some(LineEvent::Byte { byte: word as u8, at, idle_before: BitTimes(0) });
            }
            if self.tx == Tx::Sending && sr.txe().bit_is_set() {
                let b = self.tx_byte(line(), self.tx_pos);
                self.usart.dr().write(|w| w.dr().set(u16::from(b)));
                self.tx_pos += 1;
                if self.tx_pos >= self.tx_len {
                    self.tx = Tx::Draining;
                    self.usart.cr1().modify(|_, w| w.txeie().disabled().tcie().enabled());
                }
                continue;
            }
            return None;
        }
    }
}

/// End QEMU through semihosting: exit code 0 (`success`) or 1.
pub fn exit(success: bool) -> ! {
    use cortex_m_semihosting::debug;
    debug::exit(if success { debug::EXIT_SUCCESS } else { debug::EXIT_FAILURE });
    // Only reached when semihosting is off (`-semihosting-config` missing): stop here.
    loop {
        cortex_m::asm::wfi();
    }
}

static PANICKING: AtomicBool = AtomicBool::new(false);

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    cortex_m::interrupt::disable();
    // A panic inside the logger must not recurse: log once, then exit.
    if !PANICKING.swap(true, Ordering::Relaxed) {
        defmt::error!("panic: {}", defmt::Display2Format(info));
    }
    exit(false)
}

#[defmt::panic_handler]
fn defmt_panic() -> ! {
    // `defmt::panic!` / `defmt::assert!` have logged already.
    cortex_m::interrupt::disable();
    exit(false)
}

#[cortex_m_rt::exception]
unsafe fn HardFault(ef: &cortex_m_rt::ExceptionFrame) -> ! {
    if !PANICKING.swap(true, Ordering::Relaxed) {
        defmt::error!("HardFault at pc {=u32:#010x}", ef.pc());
    }
    exit(false)
}

/// The instruction counter of the benchmark build: TIM2, prescaler 0, which QEMU advances by
/// one per executed instruction under `-icount shift=0,align=off,sleep=off` (1 GHz timer
/// clock, 1 ns per instruction). Its counter does not wrap at ARR under QEMU; differences are
/// taken with wrapping arithmetic anyway.
#[cfg(feature = "bench")]
pub mod bench {
    use stm32f4xx_hal::pac::{RCC, TIM2};
    use stm32f4xx_hal::rcc::{Enable, Reset};

    /// Start TIM2 as a free-running counter (PSC = 0, ARR = max).
    pub fn start(tim: TIM2, rcc: &mut RCC) {
        TIM2::enable(rcc);
        TIM2::reset(rcc);
        tim.psc().write(|w| w.psc().set(0));
        tim.arr().write(|w| unsafe { w.bits(u32::MAX) });
        tim.egr().write(|w| w.ug().set_bit());
        tim.cr1().modify(|_, w| w.cen().set_bit());
        // From here on only `count()` reads the counter; the handle itself is not needed.
    }

    use core::sync::atomic::{AtomicU32, Ordering};

    /// The character the line took last: its index in its telegram (bits 0..15), bit 16 = it
    /// was the last, bits 17..18 = addressed to us (1), another station (2), not known (0).
    static CUR: AtomicU32 = AtomicU32::new(0);
    /// The telegram's largest handler counts: characters 1..=16 (the header and with it the
    /// prepared answer), characters after 16 (the streaming cost per character).
    static HEAD_MAX: AtomicU32 = AtomicU32::new(0);
    static CHAR_MAX: AtomicU32 = AtomicU32::new(0);
    /// The telegram's largest count of the cut and the sink alone (`Framer::cut` +
    /// `TelegramSink::bytes`) for a character after 16.
    static SINK_MAX: AtomicU32 = AtomicU32::new(0);

    /// The line took character `len - 1` of a telegram (`last`: its last by length; `us`:
    /// [`FastPath::receiving_for_us`](pbcard::fast::FastPath::receiving_for_us)).
    #[cfg_attr(feature = "bench-dma", allow(dead_code))]
    pub fn char_in(len: usize, last: bool, us: Option<bool>, sink: u32) {
        let who = match us {
            Some(true) => 1,
            Some(false) => 2,
            None => 0,
        };
        let i = (len.saturating_sub(1)).min(0xFFFF) as u32;
        if i == 0 {
            HEAD_MAX.store(0, Ordering::Relaxed);
            CHAR_MAX.store(0, Ordering::Relaxed);
            SINK_MAX.store(0, Ordering::Relaxed);
        }
        if i > 16 && !last {
            SINK_MAX.fetch_max(sink, Ordering::Relaxed);
        }
        CUR.store(i | u32::from(last) << 16 | who << 17, Ordering::Relaxed);
    }

    /// The character the line took last cost `n` instructions (from its event on). At a
    /// telegram's last character of 32 bytes or more, its maxima go into the log:
    /// `STREAM <us|other|unknown> len <n> head <instructions> char <instructions> sink
    /// <instructions> end <instructions>` (sink: the cut and `TelegramSink::bytes` of one
    /// character after 16; end: the handler of the last character, `FastPath::finish` in it).
    pub fn char_cost(n: u32) {
        let cur = CUR.swap(0, Ordering::Relaxed);
        let (i, last, who) = (cur & 0xFFFF, cur >> 16 & 1 != 0, cur >> 17 & 3);
        if !last {
            let m = if i <= 16 { &HEAD_MAX } else { &CHAR_MAX };
            m.fetch_max(n, Ordering::Relaxed);
            return;
        }
        let (head, char) = (HEAD_MAX.swap(0, Ordering::Relaxed), CHAR_MAX.swap(0, Ordering::Relaxed));
        let sink = SINK_MAX.swap(0, Ordering::Relaxed);
        if i + 1 >= 32 {
            let who = match who {
                1 => "us",
                2 => "other",
                _ => "unknown",
            };
            defmt::info!(
                "STREAM {=str} len {=u32} head {=u32} char {=u32} sink {=u32} end {=u32}",
                who,
                i + 1,
                head,
                char,
                sink,
                n
            );
        }
    }

    /// The counter now.
    #[inline(always)]
    pub fn count() -> u32 {
        // SAFETY: a read of TIM2's counter register, which `start` configured and which
        // nothing writes afterwards; reading it has no side effect.
        unsafe { (*TIM2::ptr()).cnt().read().bits() }
    }
}
