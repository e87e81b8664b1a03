//! The STM32F411 reference board, DMA edition: USART1 on PA9 (TX) / PA10 (RX) with DMA2, the
//! RS485 driver enable on PA8, TIM5 as the bit timer (ARCHITECTURE §2, §4).
//!
//! USART1 is programmed through the PAC directly: 9-bit word with parity (= 8 data bits +
//! even parity, PROFIBUS's 11-bit character), 1 stop bit, at the rate the autobaud search asks
//! for ([`DmaLine::set_baud`], divisors from `pbcard::phy::divisor`).
//!
//! **Receive.** DMA2 stream 2 channel 4 copies every character into a circular
//! [`RX_RING`]-byte buffer and never stops, whatever the CPU does (a masked interrupt, a flash
//! operation stalling instruction fetch). The USART interrupt comes only for
//! * **IDLE** — one idle character after a stop bit: the bytes since the last IDLE (one
//!   *segment*) go through [`pbcard::phy::line::Receiver`], which cuts them into telegrams by
//!   their header length ([`pbcard::phy::line::expected_len`]) and hands every telegram on —
//!   requests for us, for other stations, tokens, other slaves' responses — into a queue for
//!   the decision task; the TIM5 timestamp of the IDLE gives the last stop bit;
//! * **PE / FE / NF / ORE** (PEIE, EIE) — the segment in progress is marked corrupt and
//!   dropped at its IDLE; the receiver then waits for T_SYN;
//! * **TC** — the end of our response (below).
//!
//! After each IDLE the TIM5 compare 2 is armed at [`BitClock::tsyn_check_at`]: if the DMA
//! position has not moved by then, the line has been idle for at least T_SYN (33 bit times)
//! and the receiver accepts start delimiters again ([`Receiver::on_tsyn`]).
//!
//! **Transmit.** The decision task hands the pre-staged response to [`DmaLine::respond`]
//! with min_TSDR. [`pbcard::phy::line::tx_plan`] decides: drop it (characters arrived since
//! the request — the master moved on —, later than the GSD's max_TSDR, or still sending), start
//! at once, or arm TIM5 compare 1 at min_TSDR after the request's last stop bit. The start
//! (here or in the TIM5 interrupt) sets DE (PA8) and then enables the USART's transmit DMA
//! (DMA2 stream 7 channel 4), so the driver is on just before the first start bit. The
//! receiver is off while we drive the line (no echo). The USART TC interrupt (last stop bit
//! sent) releases DE and switches the receiver back on. Nothing here busy-waits.
//!
//! The line interrupts (USART1, TIM5) run at the highest priority and share nothing with the
//! lower tasks but this [`DmaLine`]; the FDL/DP decision runs one priority below, so a lower
//! task holding the `Node` delays a decision (the response may then be dropped as too late:
//! the master repeats it) but never the DE release or the receiver.
//!
//! **Flash stalls.** Programming or erasing the address journal (low priority, only after a
//! Set_Slave_Add) stalls instruction fetch from flash for the whole operation (up to ~0.5 s
//! for a 16 KiB erase); the DMA keeps receiving meanwhile but the ring may be overrun, so the
//! housekeeping task calls [`DmaLine::restart_rx`] afterwards.

use core::ptr::addr_of_mut;

use pbcard::fdl::telegram::MAX_FRAME_LEN;
use pbcard::phy::line::{self, BitClock, Receiver, RxStats, TxDrop, TxPlan};
use pbcard::time::{Baudrate, BitTimes};
use stm32f4xx_hal::gpio::{Output, PushPull, PA10, PA8, PA9, PB6, PB7, PB8};
use stm32f4xx_hal::pac::{DMA2, IWDG, RCC, TIM5, USART1};
use stm32f4xx_hal::rcc::{Enable, Reset};

use super::divisor::usart_brr;
use super::{DriverEnable, FrameQueue, UnsupportedRate};

/// USART1 TX pin (AF7).
pub type TxPin = PA9<stm32f4xx_hal::gpio::Alternate<7>>;
/// USART1 RX pin (AF7).
pub type RxPin = PA10<stm32f4xx_hal::gpio::Alternate<7>>;

/// The RS485 driver-enable GPIO (PA8, push-pull, high = drive the bus).
pub struct DePin(pub PA8<Output<PushPull>>);

impl DriverEnable for DePin {
    #[inline(always)]
    fn enable(&mut self) {
        self.0.set_high();
    }
    #[inline(always)]
    fn disable(&mut self) {
        self.0.set_low();
    }
}

/// Bytes of the circular receive buffer: two longest telegrams, so a segment is never
/// overwritten before its IDLE is handled.
pub const RX_RING: usize = 512;

/// DMA2 stream / channel numbers (RM0383 Table 28: USART1_RX on stream 2 or 5, USART1_TX on
/// stream 7, channel 4).
const RX_STREAM: usize = 2;
const TX_STREAM: usize = 7;
const USART1_CHANNEL: u32 = 4;

// DMA SxCR bits (RM0383 §9.5.5).
const DMA_EN: u32 = 1 << 0;
const DMA_DIR_M2P: u32 = 0b01 << 6;
const DMA_CIRC: u32 = 1 << 8;
const DMA_MINC: u32 = 1 << 10;
const DMA_PL_VERY_HIGH: u32 = 0b11 << 16;
const DMA_CHSEL_USART1: u32 = USART1_CHANNEL << 25;
/// All interrupt flags of stream 2 (LIFCR bits 16..21) and stream 7 (HIFCR bits 22..27).
const DMA_S2_FLAGS: u32 = 0b11_1101 << 16;
const DMA_S7_FLAGS: u32 = 0b11_1101 << 22;

// USART SR bits (RM0383 §19.6.1).
const SR_PE: u16 = 1 << 0;
const SR_FE: u16 = 1 << 1;
const SR_NF: u16 = 1 << 2;
const SR_ORE: u16 = 1 << 3;
const SR_IDLE: u16 = 1 << 4;
const SR_TC: u16 = 1 << 6;

// TIM5 bits (RM0383 §13.4).
const TIM_CC1: u32 = 1 << 1;
const TIM_CC2: u32 = 1 << 2;

/// What the line keeps with each telegram it cut from the ring.
#[derive(Debug, Clone, Copy)]
pub struct FrameMeta {
    /// The request ends with its segment: characters after it mean the line is busy again.
    last_of_segment: bool,
    /// Ring write position at the segment's IDLE.
    seg_end: u16,
    /// Segment number (counts IDLE events).
    seg: u32,
    /// TIM5 value read after the IDLE flag.
    idle_seen: u32,
}

/// Why a telegram was lost before the decision, and what the transmitter did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, defmt::Format)]
pub struct LineStats {
    pub parity: u32,
    pub framing: u32,
    pub noise: u32,
    pub overrun: u32,
    /// Telegrams dropped because the decision task had not taken the older ones.
    pub queue_full: u32,
    pub responses: u32,
    /// Responses started by the TIM5 compare (min_TSDR not yet over when they were ready).
    pub delayed_starts: u32,
    pub dropped_line_active: u32,
    pub dropped_too_late: u32,
    pub dropped_busy: u32,
    pub dropped_bad_length: u32,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Tx {
    Idle,
    /// Waiting for TIM5 compare 1; the ring position when armed.
    Armed {
        ring_pos: u16,
    },
    /// DMA running / last character draining; DE on.
    Sending,
}

/// USART1 + DMA2 + TIM5: the PROFIBUS line of the reference board (module documentation).
pub struct DmaLine {
    usart: USART1,
    dma: DMA2,
    tim: TIM5,
    _pins: (TxPin, RxPin),
    de: DePin,
    pclk_hz: u32,
    clock: BitClock,
    rate: Baudrate,
    ring: &'static mut [u8; RX_RING],
    tx_buf: &'static mut [u8; MAX_FRAME_LEN],
    /// Ring index of the first byte not yet cut.
    read: usize,
    seg_buf: [u8; MAX_FRAME_LEN],
    /// A character error since the last IDLE.
    corrupt: bool,
    receiver: Receiver,
    queue: FrameQueue<FrameMeta>,
    segments: u32,
    /// Ring position the T_SYN check compares with.
    tsyn_pos: Option<u16>,
    tx: Tx,
    stats: LineStats,
}

static mut RX_RING_BUF: [u8; RX_RING] = [0; RX_RING];
static mut TX_BUF: [u8; MAX_FRAME_LEN] = [0; MAX_FRAME_LEN];

impl DmaLine {
    /// Take USART1, DMA2 and TIM5 (clocks enabled and reset here), start TIM5 free-running at
    /// `timclk_hz`, program 11-bit characters at `rate` and start the receive DMA. Call once
    /// (it owns the static DMA buffers). The NVIC lines are unmasked by RTIC.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        usart: USART1,
        dma: DMA2,
        tim: TIM5,
        pins: (TxPin, RxPin),
        mut de: DePin,
        pclk_hz: u32,
        timclk_hz: u32,
        rate: Baudrate,
        rcc: &mut RCC,
    ) -> Result<Self, UnsupportedRate> {
        de.disable();
        USART1::enable(rcc);
        USART1::reset(rcc);
        DMA2::enable(rcc);
        TIM5::enable(rcc);
        TIM5::reset(rcc);
        // SAFETY: `new` is called once from `init`; the buffers are handed to the DMA and to
        // this struct only.
        let (ring, tx_buf) = unsafe { (&mut *addr_of_mut!(RX_RING_BUF), &mut *addr_of_mut!(TX_BUF)) };

        // TIM5: 32-bit up-counter, prescaler 0, wraps at 2^32 (44.7 s at 96 MHz).
        tim.psc().write(|w| unsafe { w.bits(0) });
        tim.arr().write(|w| unsafe { w.bits(u32::MAX) });
        tim.egr().write(|w| unsafe { w.bits(1) }); // UG: load PSC
        tim.sr().write(|w| unsafe { w.bits(0) });
        tim.cr1().write(|w| unsafe { w.bits(1) }); // CEN

        let mut line = DmaLine {
            usart,
            dma,
            tim,
            _pins: pins,
            de,
            pclk_hz,
            clock: BitClock { hz: timclk_hz },
            rate,
            ring,
            tx_buf,
            read: 0,
            seg_buf: [0; MAX_FRAME_LEN],
            corrupt: false,
            receiver: Receiver::new(),
            queue: FrameQueue::new(),
            segments: 0,
            tsyn_pos: None,
            tx: Tx::Idle,
            stats: LineStats::default(),
        };
        line.usart.cr2().write(|w| w.stop().stop1());
        line.set_baud(rate)?;
        Ok(line)
    }

    /// The APB2 clock the divisors are computed from.
    pub fn pclk_hz(&self) -> u32 {
        self.pclk_hz
    }

    /// The bit timer.
    pub fn bit_clock(&self) -> BitClock {
        self.clock
    }

    /// The current line rate.
    pub fn baud(&self) -> Baudrate {
        self.rate
    }

    /// Counters.
    pub fn stats(&self) -> LineStats {
        self.stats
    }

    /// The telegram cutter's counters.
    pub fn rx_stats(&self) -> RxStats {
        self.receiver.stats()
    }

    /// Telegrams lost on the line (STATUS.CORRUPT_FRAMES): [`RxStats::lost_frames`].
    pub fn corrupt_frames(&self) -> u32 {
        self.receiver.stats().lost_frames()
    }

    /// TIM5 now.
    #[inline(always)]
    pub fn ticks(&self) -> u32 {
        self.tim.cnt().read().bits()
    }

    /// Whether the receive DMA and the USART are running as programmed (supervision: the
    /// housekeeping task feeds the IWDG only then).
    pub fn is_healthy(&self) -> bool {
        let rx_on = self.dma.st(RX_STREAM).cr().read().bits() & DMA_EN != 0;
        let ue = self.usart.cr1().read().ue().bit_is_set();
        let tim_on = self.tim.cr1().read().bits() & 1 != 0;
        rx_on && ue && tim_on
    }

    /// Ring write position of the receive DMA.
    #[inline(always)]
    fn ring_pos(&self) -> usize {
        let ndtr = self.dma.st(RX_STREAM).ndtr().read().bits() as usize;
        // NDTR counts down from RX_RING and reloads at 0 (circular mode).
        (RX_RING - ndtr.min(RX_RING)) % RX_RING
    }

    /// Switch the line to `rate`: abort a response, reprogram the divisor, restart the
    /// receiver (whatever was received is dropped; T_SYN is awaited again).
    pub fn set_baud(&mut self, rate: Baudrate) -> Result<(), UnsupportedRate> {
        let (over8, brr) = usart_brr(self.pclk_hz, rate.bits_per_second()).ok_or(UnsupportedRate(rate))?;
        self.abort_tx();
        self.stop_rx_dma();
        // OVER8 may only change while UE = 0 (RM0383 §19.6.4): disable, program, enable.
        self.usart.cr1().write(|w| w.ue().clear_bit());
        self.usart.cr3().reset();
        self.usart.brr().write(|w| w.div_mantissa().set(brr >> 4).div_fraction().set((brr & 0xF) as u8));
        self.usart.cr1().write(|w| {
            w.over8().bit(over8);
            w.m().m9(); // 9-bit word: 8 data bits + the parity bit
            w.pce().enabled().ps().even();
            w.peie().enabled(); // parity errors
            w.idleie().enabled(); // telegram boundaries
            w.te().enabled().re().enabled();
            w.ue().enabled()
        });
        // Errors (FE, NF, ORE) interrupt with DMA reception (EIE); receive by DMA.
        self.usart.cr3().write(|w| w.eie().enabled().dmar().enabled());
        let _ = self.usart.sr().read();
        let _ = self.usart.dr().read();
        self.rate = rate;
        self.start_rx_dma();
        Ok(())
    }

    fn stop_rx_dma(&mut self) {
        let st = self.dma.st(RX_STREAM);
        st.cr().modify(|r, w| unsafe { w.bits(r.bits() & !DMA_EN) });
        while st.cr().read().bits() & DMA_EN != 0 {}
        self.dma.lifcr().write(|w| unsafe { w.bits(DMA_S2_FLAGS) });
    }

    fn start_rx_dma(&mut self) {
        let st = self.dma.st(RX_STREAM);
        st.par().write(|w| unsafe { w.bits(self.usart.dr().as_ptr() as u32) });
        st.m0ar().write(|w| unsafe { w.bits(self.ring.as_ptr() as u32) });
        st.ndtr().write(|w| unsafe { w.bits(RX_RING as u32) });
        st.fcr().write(|w| unsafe { w.bits(0) }); // direct mode
        st.cr().write(|w| unsafe { w.bits(DMA_CHSEL_USART1 | DMA_PL_VERY_HIGH | DMA_MINC | DMA_CIRC) });
        st.cr().modify(|r, w| unsafe { w.bits(r.bits() | DMA_EN) });
        self.read = 0;
        self.corrupt = false;
        self.queue.clear();
        self.tsyn_pos = None;
        self.receiver.reset();
    }

    /// Drop whatever the ring holds and wait for T_SYN again (after a flash operation that may
    /// have stalled the CPU longer than the ring lasts).
    pub fn restart_rx(&mut self) {
        if self.tx == Tx::Idle {
            self.stop_rx_dma();
            self.start_rx_dma();
        }
    }

    /// The next telegram for the decision task: its bytes into `buf`, its length and data.
    pub fn take_frame(&mut self, buf: &mut [u8; MAX_FRAME_LEN]) -> Option<(usize, FrameMeta)> {
        self.queue.pop_into(buf)
    }

    /// Whether no character has arrived since `frame`'s IDLE (its response may still go out).
    fn quiet_since(&self, frame: &FrameMeta) -> bool {
        frame.last_of_segment && frame.seg == self.segments && self.ring_pos() == usize::from(frame.seg_end)
    }

    /// The USART1 interrupt: errors, IDLE, TC. Returns `true` when telegrams were queued for
    /// the decision task.
    pub fn on_usart(&mut self) -> bool {
        let sr = self.usart.sr().read().bits();
        let mut queued = false;
        if sr & (SR_PE | SR_FE | SR_NF | SR_ORE) != 0 {
            let inc = |c: &mut u32, bit: u16| *c = c.wrapping_add(u32::from(sr & bit != 0));
            inc(&mut self.stats.parity, SR_PE);
            inc(&mut self.stats.framing, SR_FE);
            inc(&mut self.stats.noise, SR_NF);
            inc(&mut self.stats.overrun, SR_ORE);
            self.corrupt = true;
            // SR then DR clears the flags (this DR read may take a character from the DMA: the
            // segment is dropped anyway).
            let _ = self.usart.dr().read();
        }
        if sr & SR_IDLE != 0 {
            let idle_seen = self.ticks();
            let _ = self.usart.dr().read(); // SR then DR clears IDLE
            queued = self.on_idle(idle_seen);
        }
        if sr & SR_TC != 0 && self.tx == Tx::Sending && self.dma.st(TX_STREAM).ndtr().read().bits() == 0 {
            // The last stop bit is out: release the bus and listen again.
            self.de.disable();
            self.usart.cr3().modify(|_, w| w.dmat().disabled());
            self.usart.cr1().modify(|_, w| w.tcie().disabled().re().enabled());
            self.tx = Tx::Idle;
            // The master waits T_ID ≥ T_SYN after our response: prove it like after an IDLE.
            self.arm_tsyn_check(self.ticks());
        }
        queued
    }

    fn on_idle(&mut self, idle_seen: u32) -> bool {
        let write = self.ring_pos();
        let n = (write + RX_RING - self.read) % RX_RING;
        let take = n.min(self.seg_buf.len());
        for i in 0..take {
            self.seg_buf[i] = self.ring[(self.read + i) % RX_RING];
        }
        self.read = write;
        // A segment longer than a telegram cannot be one: dropped like a corrupt one.
        let corrupt = core::mem::take(&mut self.corrupt) || n > take;
        self.segments = self.segments.wrapping_add(1);
        let seg = self.segments;
        let seg_end = write as u16;
        let (queue, stats, seg_buf) = (&mut self.queue, &mut self.stats, &self.seg_buf);
        let mut queued = 0usize;
        let meta = FrameMeta { last_of_segment: false, seg_end, seg, idle_seen };
        self.receiver.segment(&seg_buf[..take], corrupt, |f| {
            if !queue.push(f, meta) {
                stats.queue_full = stats.queue_full.wrapping_add(1);
            }
            queued += 1;
        });
        if queued > 0 {
            if let Some(m) = self.queue.back_meta_mut() {
                m.last_of_segment = true;
            }
        }
        self.arm_tsyn_check(idle_seen);
        queued > 0
    }

    fn arm_tsyn_check(&mut self, from: u32) {
        let at = self.clock.tsyn_check_at(self.rate, from);
        self.tsyn_pos = Some(self.ring_pos() as u16);
        self.tim.ccr(1).write(|w| unsafe { w.bits(at) });
        self.tim.sr().write(|w| unsafe { w.bits(!TIM_CC2) });
        self.tim.dier().modify(|r, w| unsafe { w.bits(r.bits() | TIM_CC2) });
    }

    /// The TIM5 interrupt: the T_SYN check (compare 2) and the delayed response start
    /// (compare 1).
    pub fn on_timer(&mut self) {
        let sr = self.tim.sr().read().bits();
        let dier = self.tim.dier().read().bits();
        if sr & dier & TIM_CC2 != 0 {
            self.tim.sr().write(|w| unsafe { w.bits(!TIM_CC2) });
            self.tim.dier().modify(|r, w| unsafe { w.bits(r.bits() & !TIM_CC2) });
            if self.tsyn_pos.take() == Some(self.ring_pos() as u16) && !self.corrupt {
                self.receiver.on_tsyn();
            }
        }
        if sr & dier & TIM_CC1 != 0 {
            self.tim.sr().write(|w| unsafe { w.bits(!TIM_CC1) });
            self.tim.dier().modify(|r, w| unsafe { w.bits(r.bits() & !TIM_CC1) });
            if let Tx::Armed { ring_pos } = self.tx {
                if usize::from(ring_pos) == self.ring_pos() {
                    self.stats.delayed_starts = self.stats.delayed_starts.wrapping_add(1);
                    self.start_now();
                } else {
                    self.tx = Tx::Idle;
                    self.stats.dropped_line_active = self.stats.dropped_line_active.wrapping_add(1);
                }
            }
        }
    }

    /// Send `bytes` as the response to `request` (the decision task's answer), no earlier
    /// than `min_tsdr` after its last stop bit and no later than `max_tsdr` — or not at all
    /// ([`line::tx_plan`]). Returns what was done.
    pub fn respond(&mut self, request: &FrameMeta, bytes: &[u8], min_tsdr: BitTimes, max_tsdr: BitTimes) -> TxPlan {
        if bytes.is_empty() || bytes.len() > self.tx_buf.len() {
            self.stats.dropped_bad_length = self.stats.dropped_bad_length.wrapping_add(1);
            return TxPlan::Drop(TxDrop::Busy);
        }
        let not_before = self.clock.response_not_before(self.rate, request.idle_seen, min_tsdr);
        let latest = self.clock.response_latest(self.rate, request.idle_seen, max_tsdr);
        let plan = line::tx_plan(self.ticks(), not_before, latest, self.quiet_since(request), self.tx != Tx::Idle);
        match plan {
            TxPlan::Drop(TxDrop::LineActive) => {
                self.stats.dropped_line_active = self.stats.dropped_line_active.wrapping_add(1)
            }
            TxPlan::Drop(TxDrop::TooLate) => self.stats.dropped_too_late = self.stats.dropped_too_late.wrapping_add(1),
            TxPlan::Drop(TxDrop::Busy) => self.stats.dropped_busy = self.stats.dropped_busy.wrapping_add(1),
            TxPlan::Now | TxPlan::At(_) => {
                self.tx_buf[..bytes.len()].copy_from_slice(bytes);
                let st = self.dma.st(TX_STREAM);
                st.ndtr().write(|w| unsafe { w.bits(bytes.len() as u32) });
                if let TxPlan::At(t) = plan {
                    self.tx = Tx::Armed { ring_pos: request.seg_end };
                    self.tim.ccr(0).write(|w| unsafe { w.bits(t) });
                    self.tim.sr().write(|w| unsafe { w.bits(!TIM_CC1) });
                    self.tim.dier().modify(|r, w| unsafe { w.bits(r.bits() | TIM_CC1) });
                    // The compare may have passed while it was being armed.
                    if line::reached(self.ticks(), t) {
                        self.tim.dier().modify(|r, w| unsafe { w.bits(r.bits() & !TIM_CC1) });
                        self.start_now();
                    }
                } else {
                    self.start_now();
                }
            }
        }
        plan
    }

    /// Drive the bus and start the transmit DMA (NDTR already set, data in `tx_buf`).
    fn start_now(&mut self) {
        let st = self.dma.st(TX_STREAM);
        self.usart.cr1().modify(|_, w| w.re().disabled());
        self.dma.hifcr().write(|w| unsafe { w.bits(DMA_S7_FLAGS) });
        st.par().write(|w| unsafe { w.bits(self.usart.dr().as_ptr() as u32) });
        st.m0ar().write(|w| unsafe { w.bits(self.tx_buf.as_ptr() as u32) });
        st.fcr().write(|w| unsafe { w.bits(0) });
        st.cr().write(|w| unsafe { w.bits(DMA_CHSEL_USART1 | DMA_PL_VERY_HIGH | DMA_MINC | DMA_DIR_M2P) });
        // TC is rc_w0: writing 0 clears it, the other bits written 1 are unaffected.
        self.usart.sr().write(|w| unsafe { w.bits(!SR_TC) });
        st.cr().modify(|r, w| unsafe { w.bits(r.bits() | DMA_EN) });
        self.de.enable();
        self.usart.cr3().modify(|_, w| w.dmat().enabled());
        self.usart.cr1().modify(|_, w| w.tcie().enabled());
        self.tx = Tx::Sending;
        self.stats.responses = self.stats.responses.wrapping_add(1);
    }

    fn abort_tx(&mut self) {
        self.tim.dier().modify(|r, w| unsafe { w.bits(r.bits() & !TIM_CC1) });
        self.usart.cr1().modify(|_, w| w.tcie().disabled());
        self.usart.cr3().modify(|_, w| w.dmat().disabled());
        let st = self.dma.st(TX_STREAM);
        st.cr().modify(|r, w| unsafe { w.bits(r.bits() & !DMA_EN) });
        while st.cr().read().bits() & DMA_EN != 0 {}
        self.de.disable();
        self.tx = Tx::Idle;
    }
}

/// The safe state of the line from a panic or HardFault handler, without the `DmaLine`
/// (whose owner may be the one that failed): stop the transmit DMA, release DE (PA8).
///
/// # Safety
/// Only from the fault path: it writes GPIOA, DMA2 and USART1 registers behind the owners'
/// backs, which is fine only because nothing runs afterwards but a reset.
pub unsafe fn line_safe_state() {
    let dp = stm32f4xx_hal::pac::Peripherals::steal();
    dp.GPIOA.bsrr().write(|w| w.br8().set_bit());
    dp.USART1.cr3().modify(|_, w| w.dmat().disabled());
    dp.DMA2.st(TX_STREAM).cr().modify(|r, w| w.bits(r.bits() & !DMA_EN));
    dp.USART1.cr1().modify(|_, w| w.te().disabled());
}

// ---------------------------------------------------------------------------------------------
// LEDs and IWDG
// ---------------------------------------------------------------------------------------------

/// The three LEDs of the card (OPTE3/E5 §4.3), active high with a series resistor each:
/// PS red on PB6, BS yellow on PB7, FS green on PB8 (PB12..PB15 are the DPM SPI2, `bsp::spi`) (README "Hardware").
pub struct LedPins {
    ps: PB6<Output<PushPull>>,
    bs: PB7<Output<PushPull>>,
    fs: PB8<Output<PushPull>>,
}

impl LedPins {
    /// Show the pattern `leds` at `now` (called every millisecond: blinking is computed by
    /// `pbcard::led`).
    pub fn show(&mut self, now: pbcard::time::Instant, leds: pbcard::led::Leds) {
        self.ps.set_state(leds.ps.is_lit(now).into());
        self.bs.set_state(leds.bs.is_lit(now).into());
        self.fs.set_state(leds.fs.is_lit(now).into());
    }
}

/// The independent watchdog: LSI (≈ 32 kHz) / 64, reload [`Iwdg::RELOAD`] → ≈ 2 s, longer
/// than the worst flash sector erase of the card's journal (16 KiB: 0.5 s max, DS10314).
pub struct Iwdg(IWDG);

impl Iwdg {
    /// Reload value (12 bits): 1000 × 2 ms.
    pub const RELOAD: u16 = 1000;

    /// Start the watchdog (it cannot be stopped again until reset).
    pub fn start(iwdg: IWDG) -> Self {
        // RM0383 §17.3: start (also starts the LSI), unlock PR/RLR, program, wait until both
        // are taken over in the LSI domain, reload.
        iwdg.kr().write(|w| unsafe { w.bits(0xCCCC) });
        iwdg.kr().write(|w| unsafe { w.bits(0x5555) });
        iwdg.pr().write(|w| unsafe { w.bits(0b100) }); // /64
        iwdg.rlr().write(|w| unsafe { w.bits(Self::RELOAD) });
        while iwdg.sr().read().bits() != 0 {}
        iwdg.kr().write(|w| unsafe { w.bits(0xAAAA) });
        Iwdg(iwdg)
    }

    /// Reload the counter.
    pub fn feed(&mut self) {
        self.0.kr().write(|w| unsafe { w.bits(0xAAAA) });
    }
}

// ---------------------------------------------------------------------------------------------
// Board bring-up (called from the RTIC `init`; the QEMU board has the same shape in `qemu.rs`)
// ---------------------------------------------------------------------------------------------

/// Board name for the boot log.
pub const NAME: &str = "STM32F411 reference board, USART1 + DMA2, TIM5 bit timer, autobaud";

/// The line of this board.
pub type Line = DmaLine;
/// The rate control of this board: the ASIC-style search and supervision.
pub type Baud = pbcard::phy::autobaud::Autobaud;
pub use super::fault::register_application;

/// The low-priority board work (housekeeping task): LED pins, the card's journal (station
/// address, I&M1–4), the IWDG.
pub struct Supervisor {
    leds: LedPins,
    store: pbcard::store::Journal<super::flash::JournalFlash>,
    iwdg: Option<Iwdg>,
    iwdg_periph: Option<IWDG>,
    /// What is stored (address, No_Add_Chg).
    stored: (u8, bool),
    /// I&M1–4 a master wrote, not stored yet ([`Self::store_im`]).
    im: Option<pbcard::dpv1::im::ImData>,
}

impl Supervisor {
    /// The supervisor over the board's LEDs, journal (holding `stored`) and watchdog.
    pub fn new(
        leds: LedPins,
        store: pbcard::store::Journal<super::flash::JournalFlash>,
        iwdg: IWDG,
        stored: (u8, bool),
    ) -> Self {
        Supervisor { leds, store, iwdg: None, iwdg_periph: Some(iwdg), stored, im: None }
    }

    /// I&M1–4 to store at the next [`Self::tick`] (`Im::take_changed`).
    pub fn store_im(&mut self, data: pbcard::dpv1::im::ImData) {
        self.im = Some(data);
    }

    /// Once per millisecond: show `leds`; store `address` (station address, No_Add_Chg) when
    /// it differs from the stored pair (Set_Slave_Add) and the I&M1–4 of [`Self::store_im`]
    /// (the flash stalls the CPU meanwhile — returns `true`: restart the receiver); start the
    /// IWDG at the first call and feed it only when `alive` (the line hardware runs and the
    /// protocol tasks make progress).
    pub fn tick(
        &mut self,
        now: pbcard::time::Instant,
        leds: Option<pbcard::led::Leds>,
        address: (u8, bool),
        alive: bool,
    ) -> bool {
        if let Some(l) = leds {
            self.leds.show(now, l);
        }
        if self.iwdg.is_none() {
            if let Some(p) = self.iwdg_periph.take() {
                self.iwdg = Some(Iwdg::start(p));
            }
        }
        let mut restart = false;
        let im = self.im.take();
        if address != self.stored || im.is_some() {
            if let Some(w) = self.iwdg.as_mut() {
                w.feed();
            }
            if address != self.stored {
                let record = pbcard::store::StationAddress { address: address.0, no_add_chg: address.1 };
                match self.store.save(&record) {
                    Ok(written) => {
                        defmt::info!("station address {} stored (written {=bool})", record, written);
                    }
                    Err(e) => defmt::error!("storing the station address failed: {}", e),
                }
                // On an error: retried at the next change only (no flash wear loop).
                self.stored = address;
            }
            if let Some(d) = im {
                match self.store.save(&d) {
                    Ok(written) => defmt::info!("I&M1-4 stored (written {=bool})", written),
                    Err(e) => defmt::error!("storing I&M1-4 failed: {}", e),
                }
            }
            restart = true;
        }
        if alive {
            if let Some(w) = self.iwdg.as_mut() {
                w.feed();
            }
        }
        restart
    }
}

/// Crystal and clock tree of the reference board (ARCHITECTURE §2).
pub mod clocks {
    /// The crystal.
    pub const HSE_HZ: u32 = 25_000_000;
    /// Core clock.
    pub const SYSCLK_HZ: u32 = 96_000_000;
    /// APB2 (USART1) at the full 96 MHz: 12 Mbit/s divides exactly (OVER8, BRR 1.0).
    pub const PCLK2_HZ: u32 = 96_000_000;
    /// APB1 at 48 MHz (its maximum is 50 MHz): the timers on it (TIM5) count at twice that.
    pub const PCLK1_HZ: u32 = 48_000_000;
    /// TIM5's counting clock (APB1 prescaler ≠ 1 → ×2).
    pub const TIMCLK1_HZ: u32 = 96_000_000;
}

/// What [`init`] hands to the application.
pub struct Board {
    /// The line (listening at the first search rate).
    pub line: DmaLine,
    /// The microsecond clock (SysTick monotonic).
    pub clock: super::clock::SysTickClock,
    /// The LEDs (all off).
    pub leds: LedPins,
    /// The journal's flash sectors (station address, I&M1–4).
    pub flash: super::flash::JournalFlash,
    /// The independent watchdog, not started (the application starts it when its tasks run).
    pub iwdg: IWDG,
    /// The DPM SPI transport's peripherals and pins, for [`super::spi::init`].
    pub spi: super::spi::SpiParts,
}

/// Clock tree (25 MHz HSE → 96 MHz, 3 flash wait states, ART on), SysTick monotonic, PA8 DE /
/// PA9 TX / PA10 RX, PB6..8 LEDs, TIM5, USART1 + DMA2 at `rate` (receiving); the DPM SPI
/// transport's peripherals handed over unconfigured in [`Board::spi`].
pub fn init(dp: stm32f4xx_hal::pac::Peripherals, syst: cortex_m::peripheral::SYST, rate: Baudrate) -> Board {
    use stm32f4xx_hal::gpio::{GpioExt, PinState, Speed};
    use stm32f4xx_hal::rcc::{self, RccExt};
    use stm32f4xx_hal::time::Hertz;

    // Keep the debug clock running in WFI, so probe-rs / RTT keep working in idle; stop the
    // IWDG while the core is halted by a debugger.
    dp.DBGMCU.cr().modify(|_, w| w.dbg_sleep().set_bit());
    dp.DBGMCU.apb1_fz().modify(|_, w| w.dbg_iwdg_stop().set_bit());

    let mut rcc = dp.RCC.freeze(
        rcc::Config::hse(Hertz::from_raw(clocks::HSE_HZ))
            .sysclk(Hertz::from_raw(clocks::SYSCLK_HZ))
            .pclk1(Hertz::from_raw(clocks::PCLK1_HZ))
            .pclk2(Hertz::from_raw(clocks::PCLK2_HZ)),
    );
    let sysclk = rcc.clocks.sysclk().raw();
    let pclk2 = rcc.clocks.pclk2().raw();
    let timclk1 = rcc.clocks.timclk1().raw();
    defmt::assert_eq!(sysclk, clocks::SYSCLK_HZ);
    defmt::assert_eq!(pclk2, clocks::PCLK2_HZ);
    defmt::assert_eq!(timclk1, clocks::TIMCLK1_HZ);
    // The HAL sets LATENCY = (sysclk − 1) / 30 MHz = 3 wait states, prefetch, I- and D-cache
    // (RM0383 Table 5: 3 WS for 90 < HCLK ≤ 100 MHz at 2.7–3.6 V).
    let acr = dp.FLASH.acr().read();
    defmt::info!(
        "flash: {=u8} wait states, prefetch {=bool}, I-cache {=bool}, D-cache {=bool}",
        acr.latency().bits(),
        acr.prften().bit_is_set(),
        acr.icen().bit_is_set(),
        acr.dcen().bit_is_set()
    );

    let clock = super::clock::start(syst, sysclk);

    let gpioa = dp.GPIOA.split(&mut rcc);
    let de = gpioa.pa8.into_push_pull_output_in_state(PinState::Low).speed(Speed::VeryHigh);
    let tx = gpioa.pa9.into_alternate::<7>().speed(Speed::VeryHigh);
    // Pull-up: the transceiver's RO may float while its receiver is disabled.
    let rx = gpioa.pa10.into_alternate::<7>().internal_pull_up(true);

    let gpiob = dp.GPIOB.split(&mut rcc);
    let leds = LedPins {
        ps: gpiob.pb6.into_push_pull_output_in_state(PinState::Low),
        bs: gpiob.pb7.into_push_pull_output_in_state(PinState::Low),
        fs: gpiob.pb8.into_push_pull_output_in_state(PinState::Low),
    };

    let line = match DmaLine::new(dp.USART1, dp.DMA2, dp.TIM5, (tx, rx), DePin(de), pclk2, timclk1, rate, &mut rcc) {
        Ok(l) => l,
        Err(e) => defmt::panic!("line rate {} not reachable at PCLK2 {=u32} Hz", e.0, pclk2),
    };
    let (over8, brr) = usart_brr(pclk2, rate.bits_per_second()).unwrap_or((false, 0));
    defmt::info!(
        "USART1 {} = {=u32} bit/s (OVER8 {=bool}, BRR {=u16:#x}), SYSCLK {=u32} Hz, TIM5 {=u32} Hz",
        rate,
        super::divisor::actual_baud(pclk2, over8, brr),
        over8,
        brr,
        sysclk,
        timclk1
    );
    let spi = super::spi::SpiParts {
        spi: dp.SPI2,
        dma: dp.DMA1,
        exti: dp.EXTI,
        syscfg: dp.SYSCFG,
        rcc,
        irq: gpiob.pb0,
        nss: gpiob.pb12,
        sck: gpiob.pb13,
        miso: gpiob.pb14,
        mosi: gpiob.pb15,
    };
    Board { line, clock, leds, flash: super::flash::JournalFlash::new(dp.FLASH), iwdg: dp.IWDG, spi }
}
