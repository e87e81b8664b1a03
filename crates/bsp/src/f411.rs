//! The STM32F411 reference board, DMA edition: USART1 on PA9 (TX) / PA10 (RX) with DMA2, the
//! RS485 driver enable on PA8, TIM5 as the bit timer (ARCHITECTURE §2, §4).
//!
//! USART1 is programmed through the PAC directly: 9-bit word with parity (= 8 data bits +
//! even parity, PROFIBUS's 11-bit character), 1 stop bit, at the rate the autobaud search asks
//! for ([`DmaLine::set_rate`], divisors from `pbcard::phy::divisor`).
//!
//! **Receive** (issue 11 item 2; README "The response path"). Every received byte goes
//! through one streaming framer, [`pbcard::phy::stream::Stream`] (gap resync: after a
//! character error, garbage or a gap inside a telegram only an idle ≥ T_SYN makes a start
//! delimiter trustworthy), which cuts telegrams by their header's length (SD1 6, SD3 14, SD4
//! 3, SC 1, SD2 LE + 6) and hands their bytes to the line's sink as they arrive — no segment
//! copy. Two modes, chosen per rate by [`RxMode::for_rate`] in [`DmaLine::set_rate`]:
//! * **Per character, ≤ 1.5 Mbit/s** (≥ 704 cycles per character): the receive DMA is off and
//!   the CPU owns the receiver, so it reads DR (issue 11 item 3f allows it only then). One
//!   USART interrupt per character (RXNEIE, IDLEIE, PEIE, EIE on): SR, then DR once (which
//!   also clears IDLE and the error flags), the TIM5 timestamp, the character through the
//!   stream. At the telegram's **last character** ([`Step::Complete`], by length) the fast
//!   path decides at once: the request's end is that character's stop bit
//!   ([`LineTicks::end_at_last_char`]) — no IDLE wait. IDLE (one idle character) inside a
//!   telegram drops it, and arms the T_SYN proof. PE / FE / NF / ORE abort the telegram.
//!   Race left open: a character whose RXNE lands between the SR and the DR read of an
//!   IDLE-only interrupt is lost (two instructions; a character needs ≥ 704 cycles).
//! * **DMA, ≥ 3 Mbit/s**: DMA2 stream 2 channel 4 writes a circular [`RX_RING`] = 32-byte
//!   ring; its half/full-transfer interrupt ([`DmaLine::on_dma`], every 16 characters) hands
//!   the new ring bytes — at most two pieces at a wrap — in place to `Stream::piece`
//!   ([`pbcard::phy::ring::RingWalker`]: HT/TC flags read and cleared first, then NDTR; a
//!   flag the position does not explain, or both flags at once, is an **overrun** — the DMA
//!   lapped the reader —, counted `ring_overrun`, the telegram dropped). The USART interrupt
//!   comes for the first RXNE of a segment, for IDLE and for errors ([`RxIrqGate`]: SR only,
//!   never DR — the DMA owns DR). **IDLE** hands over the remainder: the request's end is
//!   found by IDLE (11 + 1 bit times after its last stop bit, [`LineTicks::end_at_idle`]) and
//!   the fast path decides then. A telegram the stream completes inside a piece (characters
//!   follow) is decided as "not last" (never answered, queued if for the core); one completed
//!   at the ring's last byte waits for the IDLE. An error hands the ring's bytes so far to the
//!   stream and drops the telegram in progress.
//!
//! While the rate is locked, other stations' telegrams are **skipped by length** after their
//! DA (`Stream::set_filter`): the sink is not called, and in DMA mode their bytes beyond the
//! header are never read — the ring walker only moves its position.
//!
//! **The CPU never reads USART_DR while the DMA owns the receiver** (issue 11 item 3f). IDLE
//! and the error flags clear only by "a read of USART_SR followed by a read of USART_DR"
//! (RM0383 §19.6.1); a CPU read of DR could take a character from under the DMA. In DMA mode
//! the interrupt reads SR only; the DMA's own read of DR for the next character completes the
//! sequence. Until then the flag stays set, so its interrupt is switched off and the next
//! segment's first RXNE switches it on again ([`RxIrqGate`], host-tested in
//! `pbcard::phy::timing`). In per-character mode the DMA is stopped and DR is the CPU's.
//!
//! At each IDLE the TIM5 compare 2 is armed **first** — before the ring or the stream is
//! touched — at [`LineTicks::tsyn_check_at`] (the per-rate tick tables are computed once in
//! [`DmaLine::new`] and picked at [`DmaLine::set_rate`]: one addition, no division), with the
//! receive mark (DMA: the ring position; per character: the character count): if the mark
//! has not moved by then, the line has been idle for at least T_SYN (33 bit times) and the
//! stream accepts start delimiters again. A compare that has already passed when it is armed
//! ([`compare_passed`]) is fired at once by a software event (TIM5_EGR.CC2G), not 44.7 s
//! later at the counter's wrap (issue 11 item 2). After our own response the proof runs from
//! the last stop bit (TC): T_SYN + one character.
//!
//! **The split** (issue 11 item 1, as on QEMU; README "The response path"). The line owns
//! the [`FastPath`] half of `pbcard::fast` ([`DmaLine::attach`]): each telegram the stream
//! completes goes to the fast path here: the stream hands its bytes to the fast path as they
//! arrive (`Tee`: `FastPath` is a `TelegramSink`, and to the line's copy for the rate control)
//! and `DmaLine::decide` asks for `FastPath::finish` at its end, in the USART1 (or DMA) interrupt, at the protocol clock's time
//! ([`SysTickClock::line_now`], lock-free). An answer from the staging goes to the transmitter
//! at once (min_TSDR from the staging, `FastPath::min_tsdr`); a request the fast path leaves
//! to the core ([`Verdict::Core`]: DP-V1 cases, other SAPs) waits in `awaiting` until the
//! core task (priority 15) pends USART1 with its answer (`FastPath::take_deferred`), which is
//! then sent under the same rules (min_TSDR, max_TSDR, the line quiet since the request).
//! Every telegram is then classified (`pbcard::phy::line::classify`, after the response is
//! on its way) and accounted to the rate control's line half (`pbcard::phy::rate_link::RateTap`):
//! the autobaud machine runs in the housekeeping task, which asks for rate switches through
//! the same link; the TIM5 interrupt carries them out ([`DmaLine::on_command`]). An answer
//! goes out only while the link's gate is open (`RateTap::may_answer`: the rate locked, or
//! about to lock on this very request).
//!
//! **Transmit.** The fast path's (or the core's) answer goes to the transmitter (`Sender`,
//! the transmitting fields of [`DmaLine`]) with min_TSDR. [`pbcard::phy::line::tx_plan`] decides: drop it (characters arrived since
//! the request — the master moved on —, later than the GSD's max_TSDR, or still sending), start
//! at once, or arm TIM5 compare 1 at min_TSDR after the request's last stop bit. The start
//! (here or in the TIM5 interrupt) sets DE (PA8) and then enables the USART's transmit DMA
//! (DMA2 stream 7 channel 4), so the driver is on just before the first start bit. The
//! receiver is off while we drive the line (no echo). The USART TC interrupt (last stop bit
//! sent) releases DE and switches the receiver back on. Nothing here busy-waits.
//!
//! The line interrupts (USART1, TIM5) run at the highest priority and share nothing with the
//! lower tasks: no task below 16 locks this [`DmaLine`] (the counters are atomics,
//! [`monitor`]; silence, restart and rate switches go through the command mailbox,
//! [`control`], and `pbcard::phy::rate_link`; the core through the split's queues and triple
//! buffer). A lower task holding the `Node` delays only the core task (DP-V1 answers, the
//! staging's refresh), never an answer from the staging, the DE release or the receiver.
//!
//! **In RAM** (issue 11 item 2). [`DmaLine::on_usart`] (the per-character path and the DMA
//! mode's IDLE, with the receive gate, the T_SYN compare and TC inlined), `feed` (the
//! streaming framer, `Stream::piece`, one copy for both modes), `DmaLine::decide` (with
//! `FastPath::finish`'s own body, `tx_plan` and the response start inlined) — ≈ 5.7 KiB — are linked into
//! `.data.pbcard_line` ([`DmaLine::on_timer`], the TIM5 compares, runs from flash: its
//! response start is for an answer that was ready before min_TSDR, its T_SYN proof only
//! re-synchronises the receiver; neither is bounded by MaxTsdr) (the fast path's
//! larger callees — `answer_srd`, the DP-V1 planner, the queue — stay in flash behind
//! long-branch thunks): cortex-m-rt 0.7 puts every `.data.*` input section into `.data`, which
//! its reset code copies from flash to RAM, so they run from SRAM without flash wait states or
//! ART cache misses (lld inserts the long-branch thunks between the two regions). Still in
//! flash: the RTIC vector stubs, `memcpy` (compiler_builtins) of the assembled telegram and
//! the queue copies, the DMA mode's ring walk (`walk_ring`, `on_dma`: ≈ 0.9 KiB that the
//! 32 KiB RAM budget does not hold; it runs through the ART accelerator's instruction cache,
//! and only its pieces' bytes go through `feed` in RAM), the core's answers
//! (`take_deferred`), the rate control's classification after the answer started, the
//! silence, the panic paths, and `set_rate` (the restart command). A flash stall is not
//! bridged by this — the vector table is in flash — which is why the line is silenced around
//! flash writes.
//!
//! **One buffer** (RAM budget). The request being assembled for the fast path and the
//! response being sent share 255 bytes (`LINE_BUF`): a response is copied in
//! only while the line is quiet since its request (no telegram in progress), reception is off
//! while it is sent, and a character before an armed start drops the start (`rx_quiet`)
//! before the stream's next bytes can land there (the handlers share one priority).
//!
//! **Flash stalls** (issue 11 item 3b). Programming or erasing the address journal (low
//! priority, only after a Set_Slave_Add) stalls instruction fetch from flash — every
//! interrupt with it — for the whole operation (up to ≈ 0.5 s for a 16 KiB erase): a response
//! in flight would keep DE on, the DMA ring would be overrun, and afterwards the pending IDLE
//! would cut stale ring contents with a fresh timestamp and answer them. So the housekeeping
//! task first **silences** the line ([`control::silence`]: the TIM5 interrupt, pended, aborts
//! a response — DE low, transmit DMA off —, switches the receiver and its interrupts off and
//! stops the receive DMA and both compares), writes the flash, and then **restarts** it
//! ([`control::restart`]: USART reprogrammed, ring flushed — the DMA restarts at index 0 —, the
//! stream reset,
//! no earlier request answerable any more, the receiver waits for T_SYN, proven by a compare
//! armed from now; core answers that come back meanwhile are dropped). The
//! commands go through an atomic mailbox executed at the line's own priority, so no lower task
//! touches the line's registers or takes its lock. If the line cannot confirm the silence (its
//! interrupt masked), the write is postponed to the next millisecond.

use core::ptr::addr_of_mut;
use core::sync::atomic::{AtomicU32, AtomicU8, Ordering};

use pbcard::fast::{FastPath, Verdict};
use pbcard::fdl::telegram::MAX_FRAME_LEN;
use pbcard::phy::line::{self, classify, BitClock, FrameClass, RxStats, TxDrop, TxPlan};
use pbcard::phy::rate_link::RateTap;
use pbcard::phy::ring::RingWalker;
use pbcard::phy::stream::{Resync, Step, Stream, TelegramSink};
use pbcard::phy::timing::{compare_passed, LineTicks, RequestEnd, RxEnables, RxFlags, RxIrqGate, RxMode};
use pbcard::time::{Baudrate, BitTimes, Instant};
use stm32f4xx_hal::gpio::{Output, PushPull, PA10, PA8, PA9, PB6, PB7, PB8};
use stm32f4xx_hal::pac::{DMA2, IWDG, RCC, TIM5, USART1};
use stm32f4xx_hal::rcc::{Enable, Reset};

use super::clock::SysTickClock;
use super::divisor::usart_brr;
use super::{BitTimer, DriverEnable, LineRate, Transmitter, TxError, UnsupportedRate};

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

/// Bytes of the circular receive buffer of the DMA mode (≥ 3 Mbit/s): half/full-transfer
/// interrupts every 16 characters hand its new bytes to the streaming framer in place
/// (`pbcard::phy::ring::RingWalker`), so it never holds a whole telegram.
pub const RX_RING: usize = 32;

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
/// Half / full transfer interrupt enables (SxCR HTIE, TCIE) and stream 2's flags in LISR.
const DMA_HTIE: u32 = 1 << 3;
const DMA_TCIE: u32 = 1 << 4;
const DMA_S2_HT: u32 = 1 << 20;
const DMA_S2_TC: u32 = 1 << 21;

// USART SR bits (RM0383 §19.6.1).
const SR_PE: u16 = 1 << 0;
const SR_FE: u16 = 1 << 1;
const SR_NF: u16 = 1 << 2;
const SR_ORE: u16 = 1 << 3;
const SR_IDLE: u16 = 1 << 4;
const SR_RXNE: u16 = 1 << 5;
const SR_TC: u16 = 1 << 6;

// TIM5 bits (RM0383 §13.4).
const TIM_CC1: u32 = 1 << 1;
const TIM_CC2: u32 = 1 << 2;

/// What the line keeps with each telegram it cut.
#[derive(Debug, Clone, Copy)]
pub struct FrameMeta {
    /// No character followed the request when it was decided (otherwise it is never
    /// answered: the line is busy again).
    last_of_segment: bool,
    /// The receive mark at the request's end ([`DmaLine::rx_mark`]: the ring position in DMA
    /// mode, the character count per character).
    seg_end: u16,
    /// Segment number (DMA mode: counts IDLE events and restarts; per character: restarts).
    seg: u32,
    /// Where the request's last stop bit is on TIM5 (from its last character's RXNE or its
    /// IDLE).
    end: RequestEnd,
}

/// The line's copy of the telegram in progress, made while its bytes arrive (the ring itself
/// is never copied): what the rate control classifies after the answer has started; the
/// fast path takes the same bytes itself ([`Tee`]).
struct Assemble {
    buf: Option<&'static mut [u8; MAX_FRAME_LEN]>,
    len: usize,
    open: bool,
}

impl TelegramSink for Assemble {
    #[inline(always)]
    fn begin(&mut self) {
        self.len = 0;
        self.open = true;
    }
    #[inline(always)]
    fn bytes(&mut self, bytes: &[u8]) {
        let Some(buf) = self.buf.as_deref_mut() else { return };
        let end = self.len + bytes.len();
        if self.open && end <= buf.len() {
            buf[self.len..end].copy_from_slice(bytes);
            self.len = end;
        } else {
            self.open = false;
        }
    }
    #[inline(always)]
    fn abort(&mut self) {
        self.open = false;
    }
}

/// The streaming framer's sink: every telegram's bytes to the fast path as they arrive
/// (`FastPath` is a `TelegramSink`: destination filter, FCS, the core's queue slot and the
/// likely answer per piece, so `FastPath::finish` at the end is constant in the telegram's
/// length, issue 11) and to [`Assemble`], the line's copy the rate control classifies
/// (`phy::line::classify`, after the answer has started, off the response path).
struct Tee<'a> {
    fast: Option<&'a mut FastPath<'static>>,
    asm: &'a mut Assemble,
}

impl TelegramSink for Tee<'_> {
    #[inline(always)]
    fn begin(&mut self) {
        if let Some(f) = self.fast.as_deref_mut() {
            f.begin();
        }
        self.asm.begin();
    }
    #[inline(always)]
    fn bytes(&mut self, bytes: &[u8]) {
        if let Some(f) = self.fast.as_deref_mut() {
            f.bytes(bytes);
        }
        self.asm.bytes(bytes);
    }
    #[inline(always)]
    fn abort(&mut self) {
        if let Some(f) = self.fast.as_deref_mut() {
            f.abort();
        }
        self.asm.abort();
    }
}

/// Why a telegram was lost before the decision, and what the transmitter did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, defmt::Format)]
pub struct LineStats {
    pub parity: u32,
    pub framing: u32,
    pub noise: u32,
    pub overrun: u32,
    /// The receive DMA lapped the ring reader (a handler more than half a ring late): the
    /// telegram in progress was dropped.
    pub ring_overrun: u32,
    /// Telegrams dropped because the core had not taken the older ones (the fast path's
    /// `FastStats::queue_full`).
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
    /// Waiting for TIM5 compare 1; the receive mark when armed.
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
    /// The tick table of `rate` (taken from `tables` at `set_rate`).
    table: LineTicks,
    /// The tick tables of every rate, computed once in `new` (the line's only divisions —
    /// 64-bit ones — happen there, never in a line interrupt).
    tables: [LineTicks; Baudrate::ALL.len()],
    /// The USART divisor of every rate (OVER8, BRR), computed once in `new`.
    divisors: [Option<(bool, u16)>; Baudrate::ALL.len()],
    rate: Baudrate,
    ring: &'static mut [u8; RX_RING],
    /// How the USART receives at `rate` ([`RxMode::for_rate`]).
    mode: RxMode,
    /// The ring's read side in DMA mode (the first byte not yet handed to `stream`).
    walker: RingWalker<RX_RING>,
    /// Characters received in per-character mode (the receive mark, wrapping).
    chars: u16,
    /// DMA mode: a telegram the stream completed at the last ring byte of an HT/TC event,
    /// decided at the IDLE (or as "not last" when more bytes come first).
    pending: Option<FrameMeta>,
    /// Which receive interrupts are on in DMA mode ([`RxIrqGate`]).
    gate: RxIrqGate,
    /// The enables last programmed (written only when they change).
    enabled: Option<RxEnables>,
    /// The streaming framer: every character (per character) or ring piece (DMA) through it.
    stream: Stream,
    /// Its sink (until the fast path is one itself).
    asm: Assemble,
    /// The line half of the split (`pbcard::fast`), attached once in `init`.
    fast: Option<FastPath<'static>>,
    /// The line half of the rate control (`pbcard::phy::rate_link`), attached with it.
    rate_tap: Option<RateTap<'static>>,
    /// Requests the fast path left to the core ([`Verdict::Core`]), oldest first, until
    /// their answers are back.
    awaiting: heapless::Deque<FrameMeta, { pbcard::fast::QUEUE_LEN }>,
    /// The protocol clock, read lock-free ([`SysTickClock::line_now`]), and its last reading.
    time: SysTickClock,
    last_now: Instant,
    segments: u32,
    /// Ring position the T_SYN check compares with.
    tsyn_pos: Option<u16>,
    tx: Tx,
    /// The bit rate is trustworthy (crystal running): responses may go out. `false` after a
    /// crystal failure: listen only, DE never set.
    transmit: bool,
    /// Silenced for a flash operation ([`control::silence`]): receiver, transmitter and
    /// compares off until [`control::restart`].
    silent: bool,
}

// Every field of the line within the 12-bit immediate offset of Thumb-2 loads and stores
// (`LDR rt, [rn, #imm12]`): no field access on the response path needs a second instruction
// for its offset, the cost `QemuLine` had before it became `repr(C)` (its 8 KiB of held
// characters in front of the fast path). A compile-time check of the F411 build.
const _: () = assert!(core::mem::size_of::<DmaLine>() < 4096, "DmaLine outgrew the 12-bit load offsets");

static mut RX_RING_BUF: [u8; RX_RING] = [0; RX_RING];
/// The line's one telegram buffer: the request being assembled ([`Assemble`]) and the
/// response being sent (`Sender`). Never both: a response is copied in only while the line
/// is quiet since its request (no telegram in progress), reception is off while it is sent,
/// and a character arriving before an armed start drops the start (`rx_quiet`) before the
/// stream's next bytes can land here — the handlers run at one priority, one at a time.
static mut LINE_BUF: [u8; MAX_FRAME_LEN] = [0; MAX_FRAME_LEN];

/// The transmitter's parts of a [`DmaLine`], borrowed field by field ([`sender!`]) so that a
/// response can be started while the fast path's answer (a borrow of `DmaLine::fast`) is held.
struct Sender<'l> {
    usart: &'l USART1,
    dma: &'l DMA2,
    tim: &'l TIM5,
    de: &'l mut DePin,
    buf: &'l mut [u8; MAX_FRAME_LEN],
    tx: &'l mut Tx,
    table: &'l LineTicks,
    transmit: bool,
}

/// The [`Sender`] of a `DmaLine` expression (field borrows only).
macro_rules! sender {
    ($l:expr, $buf:expr) => {
        Sender {
            usart: &$l.usart,
            dma: &$l.dma,
            tim: &$l.tim,
            de: &mut $l.de,
            buf: $buf,
            tx: &mut $l.tx,
            table: &$l.table,
            transmit: $l.transmit,
        }
    };
}

impl DmaLine {
    /// Take USART1, DMA2 and TIM5 (clocks enabled and reset here), start TIM5 free-running at
    /// `timclk_hz`, program 11-bit characters at `rate` and start the receive DMA. Call once
    /// (it owns the static DMA buffers). The NVIC lines are unmasked by RTIC. `transmit`:
    /// the bit rate comes from the crystal; `false` = listen only (no response, DE never on).
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
        transmit: bool,
        time: SysTickClock,
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
        let (ring, buf) = unsafe { (&mut *addr_of_mut!(RX_RING_BUF), &mut *addr_of_mut!(LINE_BUF)) };

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
            table: LineTicks::new(BitClock { hz: timclk_hz }, rate),
            tables: Baudrate::ALL.map(|r| LineTicks::new(BitClock { hz: timclk_hz }, r)),
            divisors: Baudrate::ALL.map(|r| usart_brr(pclk_hz, r.bits_per_second())),
            rate,
            ring,
            mode: RxMode::for_rate(rate),
            walker: RingWalker::new(),
            chars: 0,
            pending: None,
            gate: RxIrqGate::new(),
            enabled: None,
            stream: Stream::new(Resync::Gap),
            asm: Assemble { buf: Some(buf), len: 0, open: false },
            fast: None,
            rate_tap: None,
            awaiting: heapless::Deque::new(),
            time,
            last_now: Instant::from_micros(0),
            segments: 0,
            tsyn_pos: None,
            tx: Tx::Idle,
            transmit,
            silent: false,
        };
        line.usart.cr2().write(|w| w.stop().stop1());
        line.set_rate(rate)?;
        Ok(line)
    }

    /// Give the line its fast path and its half of the rate control (from `init`, after the
    /// splits): from here on every telegram is answered here ([`DmaLine::on_usart`]).
    pub fn attach(&mut self, fast: FastPath<'static>, rate: RateTap<'static>) {
        self.fast = Some(fast);
        self.rate_tap = Some(rate);
    }

    /// The APB2 clock the divisors are computed from.
    pub fn pclk_hz(&self) -> u32 {
        self.pclk_hz
    }

    /// Counters (the published atomics, [`monitor::stats`]).
    pub fn stats(&self) -> LineStats {
        monitor::stats().0
    }

    /// The telegram cutter's counters.
    pub fn rx_stats(&self) -> RxStats {
        self.stream.stats()
    }

    /// Telegrams lost on the line (STATUS.CORRUPT_FRAMES): [`RxStats::lost_frames`].
    pub fn corrupt_frames(&self) -> u32 {
        self.stream.stats().lost_frames()
    }

    /// Publish the cutter's counters for the lower tasks ([`monitor`]).
    #[inline(always)]
    fn publish_rx(&self) {
        let r = self.stream.stats();
        for (i, v) in [r.frames, r.corrupt, r.truncated, r.garbage, r.unsynced, r.tsyn].into_iter().enumerate() {
            COUNTERS[RX_BASE + i].store(v, Ordering::Relaxed);
        }
    }

    /// Whether the receive DMA and the USART are running as programmed (supervision: the
    /// housekeeping task feeds the IWDG only then).
    pub fn is_healthy(&self) -> bool {
        let rx_on = self.dma.st(RX_STREAM).cr().read().bits() & DMA_EN != 0 || self.mode == RxMode::PerChar;
        let ue = self.usart.cr1().read().ue().bit_is_set();
        let tim_on = self.tim.cr1().read().bits() & 1 != 0;
        rx_on && ue && tim_on
    }

    /// Ring write position of the receive DMA.
    #[inline(always)]
    fn ring_pos(&self) -> usize {
        ring_pos(&self.dma)
    }

    /// The receive mark: how far the receiver has got (DMA mode: the ring position; per
    /// character: the characters counted). A response armed or deferred at one mark goes out
    /// only while the mark has not moved ([`DmaLine::rx_quiet`]).
    #[inline(always)]
    fn rx_mark(&self) -> u16 {
        match self.mode {
            RxMode::Dma => self.ring_pos() as u16,
            RxMode::PerChar => self.chars,
        }
    }

    /// No character since the mark `mark` ([`rx_quiet`]).
    #[inline(always)]
    fn rx_quiet(&self, mark: u16) -> bool {
        rx_quiet(self.mode, &self.dma, &self.usart, self.chars, mark)
    }

    fn stop_rx_dma(&mut self) {
        let st = self.dma.st(RX_STREAM);
        st.cr().modify(|r, w| unsafe { w.bits(r.bits() & !DMA_EN) });
        while st.cr().read().bits() & DMA_EN != 0 {}
        self.dma.lifcr().write(|w| unsafe { w.bits(DMA_S2_FLAGS) });
    }

    /// Restart the receiver in the current mode: DMA mode the circular ring with its HT/TC
    /// interrupts from index 0; per character nothing to start (RXNEIE). Whatever was
    /// received before is forgotten and the stream waits for T_SYN.
    fn start_rx(&mut self) {
        if self.mode == RxMode::Dma {
            let st = self.dma.st(RX_STREAM);
            st.par().write(|w| unsafe { w.bits(self.usart.dr().as_ptr() as u32) });
            st.m0ar().write(|w| unsafe { w.bits(self.ring.as_ptr() as u32) });
            st.ndtr().write(|w| unsafe { w.bits(RX_RING as u32) });
            st.fcr().write(|w| unsafe { w.bits(0) }); // direct mode
            st.cr().write(|w| unsafe {
                w.bits(DMA_CHSEL_USART1 | DMA_PL_VERY_HIGH | DMA_MINC | DMA_CIRC | DMA_HTIE | DMA_TCIE)
            });
            st.cr().modify(|r, w| unsafe { w.bits(r.bits() | DMA_EN) });
        }
        self.walker.restart();
        self.chars = 0;
        self.drop_pending();
        self.gate.restart();
        self.enabled = None;
        self.apply_gate();
        // No telegram before the restart may be answered any more (`quiet_since`).
        self.segments = self.segments.wrapping_add(1);
        self.tsyn_pos = None;
        self.stream.reset(&mut Tee { fast: self.fast.as_mut(), asm: &mut self.asm });
        // Every telegram to the sink until the rate is locked again (`decide`).
        self.stream.set_filter(None);
    }

    /// A telegram the stream completed but that is not decided after all (a character error
    /// or an overrun before its IDLE, a restart): the sinks forget it. The stream has
    /// finished with it (it hands no `abort` for a complete telegram), so without this the
    /// fast path would stay in the station's telegram — its staging not refreshed, its
    /// address and window as of then — until the next telegram to the station.
    #[inline(always)]
    fn drop_pending(&mut self) {
        if self.pending.take().is_some() {
            Tee { fast: self.fast.as_mut(), asm: &mut self.asm }.abort();
        }
    }

    /// Drop whatever the ring holds and wait for T_SYN again: the full restart of
    /// [`control::restart`] (USART reprogrammed at the current rate, ring flushed, T_SYN
    /// proof armed from now).
    pub fn restart_rx(&mut self) {
        self.silent = false;
        let _ = self.set_rate(self.rate);
    }

    /// The telegram the stream completed to the fast path's decision (`FastPath::finish`;
    /// `meta` = where it ended and whether the line was quiet after it).
    // One copy, in RAM (called from every receive path).
    #[inline(never)]
    #[link_section = ".data.pbcard_line"]
    fn decide(&mut self, meta: FrameMeta) {
        if !self.asm.open {
            return;
        }
        self.asm.open = false;
        let Some(buf) = self.asm.buf.take() else { return };
        let n = self.asm.len;
        self.on_telegram(&mut *buf, n, meta);
        self.asm.buf = Some(buf);
        // Other stations' telegrams are skipped by length while the rate is locked (the
        // search needs every valid telegram to lock; `Stream::set_filter`).
        let filter = match (self.fast.as_mut(), self.rate_tap.as_ref()) {
            (Some(f), Some(t)) if t.may_answer(false) => Some(f.address()),
            _ => None,
        };
        self.stream.set_filter(filter);
    }

    /// The line silent for a flash operation: a response in flight aborted (DE low, transmit
    /// DMA off), the receiver and its interrupts off, the receive DMA stopped, both compares
    /// off. Only [`DmaLine::restart_rx`] (or `set_rate`) brings it back.
    // Cold: in flash (module documentation "In RAM").
    #[inline(never)]
    fn silence(&mut self) {
        self.abort_tx();
        self.usart.cr1().modify(|_, w| w.re().disabled().rxneie().disabled().idleie().disabled().peie().disabled());
        self.usart.cr3().modify(|_, w| w.eie().disabled());
        self.enabled = None;
        self.stop_rx_dma();
        self.tim.dier().modify(|r, w| unsafe { w.bits(r.bits() & !(TIM_CC1 | TIM_CC2)) });
        self.tsyn_pos = None;
        self.silent = true;
    }

    /// A command from a lower task ([`control`]), executed in the TIM5 interrupt: the
    /// mailbox, then a rate switch the rate keeper asked for (`RateTap::take_switch`; not
    /// while silenced — it is carried out after the restart).
    fn on_command(&mut self) {
        match COMMAND.swap(control::NONE, Ordering::AcqRel) {
            control::SILENCE => self.silence(),
            control::RESTART => self.restart_rx(),
            _ => {}
        }
        if !self.silent {
            if let Some(rate) = self.rate_tap.as_mut().and_then(|t| t.take_switch()) {
                // Every rate has a divisor at the board's PCLK2 (`new` computed them; the
                // keeper's caller logs an unreachable one): an error leaves the old rate.
                let _ = self.set_rate(rate);
            }
        }
    }

    /// One telegram the receiver cut, in the USART1 interrupt: the fast path decides
    /// (`FastPath::finish`); its answer goes out at min_TSDR of the staging while the rate
    /// control's gate is open (`RateTap::may_answer`); a request left to the core waits in
    /// `awaiting`; then the telegram is accounted to the rate control
    /// (`pbcard::phy::line::classify`: after the response is on its way, off its path).
    #[inline(always)]
    fn on_telegram(&mut self, buf: &mut [u8; MAX_FRAME_LEN], n: usize, meta: FrameMeta) {
        let now = self.time.line_now(self.last_now);
        self.last_now = now;
        let (Some(fast), Some(tap)) = (self.fast.as_mut(), self.rate_tap.as_mut()) else { return };
        let own = fast.address();
        // min_TSDR as the core last published it (a Set_Prm that changes it applies from the
        // next response on, as in the single-task decision).
        let min_tsdr = fast.min_tsdr();
        let max_tsdr = BitTimes(u32::from(pbcard::card::max_tsdr(self.rate)));
        let quiet = meta.last_of_segment
            && meta.seg == self.segments
            && rx_quiet(self.mode, &self.dma, &self.usart, self.chars, meta.seg_end);
        // The fast path took the telegram's bytes as they arrived ([`Tee`]): its decision now,
        // in a time that does not grow with the telegram's length.
        match fast.finish(now) {
            Verdict::Answer(bytes) => {
                let open = tap.may_answer(true);
                // An answered request is an error-free SD1/SD2/SD3 telegram to us (the fast
                // path decoded it): accounted without the bytes, which the answer overwrites.
                tap.account(FrameClass { ok_sd123: true, to_us: true, invalid: false });
                if open {
                    sender!(self, buf).respond(&meta, bytes, min_tsdr, max_tsdr, quiet);
                }
            }
            Verdict::Core => {
                // At most `QUEUE_LEN − 1` requests are with the core: never full.
                let _ = self.awaiting.push_back(meta);
                account(tap, &buf[..n], own);
            }
            Verdict::Silent => account(tap, &buf[..n], own),
        }
    }

    /// The core's answers to requests in `awaiting` (the core task pends USART1 after each):
    /// sent as `respond` decides (min_TSDR, max_TSDR, the line quiet since the request); none
    /// while silenced or while the rate control's gate is shut.
    // In flash: the core's answers are not on the fast path's response path.
    #[inline(never)]
    fn take_deferred(&mut self) {
        loop {
            let Some(fast) = self.fast.as_mut() else { return };
            let min_tsdr = fast.min_tsdr();
            let Some(bytes) = fast.take_deferred() else { return };
            let Some(meta) = self.awaiting.pop_front() else { continue };
            let open = self.rate_tap.as_ref().is_some_and(|t| t.may_answer(false));
            if self.silent || bytes.is_empty() || !open {
                continue;
            }
            let max_tsdr = BitTimes(u32::from(pbcard::card::max_tsdr(self.rate)));
            let quiet = meta.last_of_segment
                && meta.seg == self.segments
                && rx_quiet(self.mode, &self.dma, &self.usart, self.chars, meta.seg_end);
            let Some(buf) = self.asm.buf.as_deref_mut() else { return };
            sender!(self, buf).respond(&meta, bytes, min_tsdr, max_tsdr, quiet);
        }
    }

    /// The USART1 interrupt: the received characters (per character) or the ring's remainder
    /// at IDLE (DMA mode) through the streaming framer, the fast path's decision at a
    /// telegram's end, character errors, TC, the core's answers. Returns `true` when
    /// telegrams were queued for the core.
    // In RAM (module documentation "In RAM").
    #[inline(never)]
    #[link_section = ".data.pbcard_line"]
    pub fn on_usart(&mut self) -> bool {
        let queued_before = self.fast.as_ref().map_or(0, |f| f.stats().queued);
        let sr = self.usart.sr().read().bits();
        if self.silent {
            // Pended before the silence: nothing is received, nothing to release; a core
            // answer that came back meanwhile is dropped.
            self.take_deferred();
            return false;
        }
        match self.mode {
            RxMode::PerChar => self.on_char(sr),
            RxMode::Dma => self.on_usart_dma(sr),
        }
        if sr & SR_TC != 0 && self.tx == Tx::Sending && self.dma.st(TX_STREAM).ndtr().read().bits() == 0 {
            // The last stop bit is out: release the bus and listen again.
            self.de.disable();
            self.usart.cr3().modify(|_, w| w.dmat().disabled());
            self.usart.cr1().modify(|_, w| w.tcie().disabled().re().enabled());
            self.tx = Tx::Idle;
            // The receiver restarts: wait for the first character of the next segment.
            self.gate.restart();
            // The master waits T_ID ≥ T_SYN after our response: T_SYN + one character from our
            // last stop bit (at or before now) proves it.
            let now = self.ticks();
            self.arm_tsyn_check(self.table.tsyn_check_after_stop(now), self.rx_mark());
        }
        // After the received characters (whose telegrams come first), the core's answers: one
        // to a request before them is dropped then (the line was not quiet).
        self.take_deferred();
        self.apply_gate();
        if !self.stream.in_telegram() {
            self.publish_rx();
        }
        let Some(fast) = self.fast.as_ref() else { return false };
        let stats = fast.stats();
        COUNTERS[QUEUE_FULL].store(stats.queue_full, Ordering::Relaxed);
        stats.queued != queued_before
    }

    /// Per-character mode (≤ 1.5 Mbit/s): the CPU owns the receiver (receive DMA off, issue
    /// 11 item 3f), reads DR once per interrupt (which also clears IDLE and the error flags
    /// after the SR read) and pushes the character into the stream. At its telegram's last
    /// character ([`Step::Complete`], by the header's length) the fast path decides at once.
    #[inline(always)]
    fn on_char(&mut self, sr: u16) {
        if sr & (SR_RXNE | SR_IDLE | SR_PE | SR_FE | SR_NF | SR_ORE) == 0 {
            return;
        }
        let dr = self.usart.dr().read().bits();
        // IDLE and a character in one SR read (the interrupt came late): outside a telegram
        // the gap came first (it changes nothing then, and the T_SYN proof it arms fails on
        // the character); inside one, the character may be its last, so it goes first.
        let idle_first = sr & SR_IDLE != 0 && !self.stream.in_telegram();
        if idle_first {
            self.on_char_idle();
        }
        if sr & (SR_PE | SR_FE | SR_NF | SR_ORE) != 0 {
            self.count_errors(sr);
            self.chars = self.chars.wrapping_add(1);
            self.stream.error(&mut Tee { fast: self.fast.as_mut(), asm: &mut self.asm });
        } else if sr & SR_RXNE != 0 {
            // The timer first: the request's end is this character's stop bit.
            let seen = self.ticks();
            self.chars = self.chars.wrapping_add(1);
            match feed(
                &mut self.stream,
                core::slice::from_ref(&(dr as u8)),
                &mut Tee { fast: self.fast.as_mut(), asm: &mut self.asm },
            )
            .1
            {
                Step::Complete => {
                    let meta = FrameMeta {
                        last_of_segment: true,
                        seg_end: self.chars,
                        seg: self.segments,
                        end: self.table.end_at_last_char(seen),
                    };
                    self.decide(meta);
                }
                Step::Skipped | Step::Garbage | Step::Pending => {}
            }
        }
        if sr & SR_IDLE != 0 && !idle_first {
            self.on_char_idle();
        }
    }

    /// Per-character mode, IDLE (one idle character): inside a telegram a gap that drops it;
    /// the T_SYN proof runs from here (armed first, from the tick table). In flash: per
    /// character the request's end is found by length, so IDLE is off the response path.
    #[inline(never)]
    fn on_char_idle(&mut self) {
        let idle_seen = self.ticks();
        self.arm_tsyn_check(self.table.tsyn_check_at(idle_seen), self.chars);
        self.stream.idle(BitTimes::CHAR, &mut Tee { fast: self.fast.as_mut(), asm: &mut self.asm });
    }

    /// DMA mode (≥ 3 Mbit/s), the USART side: the receive gate ([`RxIrqGate`]: SR only, never
    /// DR); a character error hands the ring's bytes so far to the stream and drops the
    /// telegram in progress; IDLE hands over the remainder — the request's end — and the fast
    /// path decides.
    #[inline(always)]
    fn on_usart_dma(&mut self, sr: u16) {
        let irq = self.gate.on_interrupt(rx_flags(sr));
        if irq.error {
            self.count_errors(sr);
            self.walk_ring(None);
            // A completion at the ring's end may be the corrupt character itself.
            self.drop_pending();
            self.stream.error(&mut Tee { fast: self.fast.as_mut(), asm: &mut self.asm });
        }
        if irq.segment_end {
            // First the timestamp and the T_SYN compare (from the tick table), then the ring.
            let idle_seen = self.ticks();
            let write = self.ring_pos();
            self.arm_tsyn_check(self.table.tsyn_check_at(idle_seen), write as u16);
            self.segments = self.segments.wrapping_add(1);
            self.walk_ring(Some(self.table.end_at_idle(idle_seen)));
            // A telegram still incomplete at IDLE had a gap inside: dropped.
            self.stream.idle(BitTimes::CHAR, &mut Tee { fast: self.fast.as_mut(), asm: &mut self.asm });
            // The next segment may have begun meanwhile (its RXNE already passed).
            let moved = self.ring_pos() != write;
            let sr_now = self.usart.sr().read().bits();
            self.gate.after_segment(moved, rx_flags(sr_now));
        }
    }

    /// The receive DMA's half/full-transfer interrupt (DMA2 stream 2, DMA mode): the ring's
    /// new bytes through the stream. Returns `true` when telegrams were queued for the core.
    // In flash (RAM budget; module documentation "In RAM").
    #[inline(never)]
    pub fn on_dma(&mut self) -> bool {
        let queued_before = self.fast.as_ref().map_or(0, |f| f.stats().queued);
        if self.silent || self.mode != RxMode::Dma {
            self.dma.lifcr().write(|w| unsafe { w.bits(DMA_S2_FLAGS) });
            return false;
        }
        self.walk_ring(None);
        self.publish_rx();
        self.fast.as_ref().is_some_and(|f| f.stats().queued != queued_before)
    }

    /// DMA mode: the pending HT/TC flags (read and cleared first), then the DMA position; the
    /// new ring bytes (≤ 2 pieces) through `Stream::piece` in place. A telegram completed
    /// inside the bytes is decided at once as "not last" (characters follow: never answered,
    /// but queued if it is for the core); one completed at the last byte waits for the IDLE
    /// (`at_idle`: its end) to be decided with its timing. An overrun (the DMA lapped the
    /// reader) drops the telegram in progress and waits for T_SYN.
    // In flash (RAM budget; the pieces' bytes go through `feed`, in RAM).
    #[inline(never)]
    fn walk_ring(&mut self, at_idle: Option<RequestEnd>) {
        let flags = self.dma.lisr().read().bits() & (DMA_S2_HT | DMA_S2_TC);
        self.dma.lifcr().write(|w| unsafe { w.bits(flags) });
        let write = self.ring_pos();
        let walk = self.walker.walk(flags & DMA_S2_HT != 0, flags & DMA_S2_TC != 0, write);
        if walk.overrun {
            add(RING_OVERRUN, 1);
            self.drop_pending();
            self.stream.error(&mut Tee { fast: self.fast.as_mut(), asm: &mut self.asm });
            return;
        }
        let fresh = !walk.first.is_empty();
        if let Some(mut meta) = self.pending.take() {
            if fresh {
                meta.last_of_segment = false;
                self.decide(meta);
            } else {
                self.pending = Some(meta);
            }
        }
        for (range, last_piece) in [(walk.first, walk.second.is_empty()), (walk.second, true)] {
            let (mut at, end) = (range.start, range.end);
            while at < end {
                let (used, step) = feed(
                    &mut self.stream,
                    &self.ring[at..end],
                    &mut Tee { fast: self.fast.as_mut(), asm: &mut self.asm },
                );
                at += used;
                if step == Step::Complete {
                    let more = at < end || !last_piece;
                    let meta = FrameMeta {
                        last_of_segment: !more,
                        seg_end: write as u16,
                        seg: self.segments,
                        end: RequestEnd { stop_latest: 0, stop_earliest: 0 },
                    };
                    if more {
                        self.decide(meta);
                    } else {
                        self.pending = Some(meta);
                    }
                }
            }
            if last_piece {
                break;
            }
        }
        if let Some(end) = at_idle {
            if let Some(mut meta) = self.pending.take() {
                meta.end = end;
                meta.seg = self.segments;
                meta.seg_end = write as u16;
                self.decide(meta);
            }
        }
    }

    /// Count a character error's kinds.
    #[inline(always)]
    fn count_errors(&self, sr: u16) {
        add(PARITY, u32::from(sr & SR_PE != 0));
        add(FRAMING, u32::from(sr & SR_FE != 0));
        add(NOISE, u32::from(sr & SR_NF != 0));
        add(OVERRUN, u32::from(sr & SR_ORE != 0));
    }

    /// Program RXNEIE, IDLEIE, PEIE (CR1) and EIE (CR3): per character all of them; DMA mode
    /// as the gate says, when they changed.
    fn apply_gate(&mut self) {
        let e = match self.mode {
            RxMode::PerChar => RxEnables { rxne: true, idle: true, errors: true },
            RxMode::Dma => self.gate.enables(),
        };
        if self.enabled == Some(e) {
            return;
        }
        self.usart.cr1().modify(|_, w| w.rxneie().bit(e.rxne).idleie().bit(e.idle).peie().bit(e.errors));
        self.usart.cr3().modify(|_, w| w.eie().bit(e.errors));
        self.enabled = Some(e);
    }

    /// Arm TIM5 compare 2 for the T_SYN proof at `at`, against the ring position `pos` (the
    /// end of the last segment, or of our response): the proof holds if the DMA has not moved
    /// from it when the compare fires. Already passed → the event is generated at once
    /// (TIM5_EGR.CC2G sets CC2IF; the TIM5 interrupt runs right after this one).
    fn arm_tsyn_check(&mut self, at: u32, pos: u16) {
        self.tsyn_pos = Some(pos);
        self.tim.ccr(1).write(|w| unsafe { w.bits(at) });
        self.tim.sr().write(|w| unsafe { w.bits(!TIM_CC2) });
        self.tim.dier().modify(|r, w| unsafe { w.bits(r.bits() | TIM_CC2) });
        if compare_passed(self.ticks(), at) {
            self.tim.egr().write(|w| unsafe { w.bits(TIM_CC2) });
        }
    }

    /// The TIM5 interrupt: the T_SYN check (compare 2) and the delayed response start
    /// (compare 1).
    // In flash (ART cache), not RAM: compare 1 starts a response that was ready *before*
    // min_TSDR (the answer waits for the line's rule, not for this code), and the T_SYN proof
    // only re-synchronises the receiver — neither is on the path that MaxTsdr bounds. Keeps
    // the card-only build within its 32 KiB RAM (issue 13).
    #[inline(never)]
    pub fn on_timer(&mut self) {
        self.on_command();
        if self.silent {
            return;
        }
        let sr = self.tim.sr().read().bits();
        let dier = self.tim.dier().read().bits();
        if sr & dier & TIM_CC2 != 0 {
            self.tim.sr().write(|w| unsafe { w.bits(!TIM_CC2) });
            self.tim.dier().modify(|r, w| unsafe { w.bits(r.bits() & !TIM_CC2) });
            if let Some(pos) = self.tsyn_pos.take() {
                if self.rx_quiet(pos) {
                    self.stream.idle(BitTimes::TSYN, &mut Tee { fast: self.fast.as_mut(), asm: &mut self.asm });
                    self.publish_rx();
                }
            }
        }
        if sr & dier & TIM_CC1 != 0 {
            self.tim.sr().write(|w| unsafe { w.bits(!TIM_CC1) });
            self.tim.dier().modify(|r, w| unsafe { w.bits(r.bits() & !TIM_CC1) });
            if let Tx::Armed { ring_pos } = self.tx {
                if let (true, Some(buf)) = (self.rx_quiet(ring_pos), self.asm.buf.as_deref_mut()) {
                    add(DELAYED_STARTS, 1);
                    sender!(self, buf).start_now();
                } else {
                    self.tx = Tx::Idle;
                    add(DROPPED_LINE_ACTIVE, 1);
                }
            }
        }
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

impl LineRate for DmaLine {
    fn rate(&self) -> Baudrate {
        self.rate
    }

    /// Abort a response, reprogram the divisor, restart the receiver (whatever was received
    /// is dropped; T_SYN is awaited again, proven by a compare armed from now).
    fn set_rate(&mut self, rate: Baudrate) -> Result<(), UnsupportedRate> {
        // Divisor and tick table from the tables computed in `new` (no division here, so no
        // line interrupt ever reaches a 64-bit division, not even the restart after a flash
        // write).
        let i = Baudrate::ALL.iter().position(|&r| r == rate).ok_or(UnsupportedRate(rate))?;
        let (over8, brr) = self.divisors[i].ok_or(UnsupportedRate(rate))?;
        self.abort_tx();
        self.stop_rx_dma();
        // OVER8 may only change while UE = 0 (RM0383 §19.6.4): disable, program, enable.
        self.usart.cr1().write(|w| w.ue().clear_bit());
        self.usart.cr3().reset();
        self.usart.brr().write(|w| w.div_mantissa().set(brr >> 4).div_fraction().set((brr & 0xF) as u8));
        // The receive interrupts (RXNEIE, IDLEIE, PEIE, EIE) are the gate's ([`RxIrqGate`]).
        self.usart.cr1().write(|w| {
            w.over8().bit(over8);
            w.m().m9(); // 9-bit word: 8 data bits + the parity bit
            w.pce().enabled().ps().even();
            w.te().enabled().re().enabled();
            w.ue().enabled()
        });
        // Receive by DMA at ≥ 3 Mbit/s; per character (the CPU reads DR) below.
        let mode = RxMode::for_rate(rate);
        self.usart.cr3().write(|w| w.dmar().bit(mode == RxMode::Dma));
        // The receive DMA is stopped: the CPU owns the receiver, so this DR read (clearing
        // stale IDLE / error flags) takes nothing from the DMA.
        let _ = self.usart.sr().read();
        let _ = self.usart.dr().read();
        self.rate = rate;
        self.mode = mode;
        self.table = self.tables[i];
        self.start_rx();
        // Resynchronise: T_SYN + one character of quiet from now proves T_SYN.
        let now = self.ticks();
        self.arm_tsyn_check(self.table.tsyn_check_after_stop(now), 0);
        Ok(())
    }
}

/// TIM5, free-running at the timer clock (96 MHz): compare 1 starts a delayed response,
/// compare 2 proves T_SYN (module documentation).
impl BitTimer for DmaLine {
    fn clock(&self) -> BitClock {
        self.clock
    }

    #[inline(always)]
    fn ticks(&self) -> u32 {
        self.tim.cnt().read().bits()
    }
}

/// The DMA transmitter (DMA2 stream 7, DE on PA8, TC releases it). The line's own answers go
/// through `Sender::respond` (`pbcard::phy::line::tx_plan` first: line active, max_TSDR),
/// which starts them the same way.
impl Transmitter for DmaLine {
    /// A line that may not transmit (after a crystal failure: listen only) or is silenced for
    /// a flash write refuses with [`TxError::Busy`]. A delayed start is dropped if a character
    /// arrives before it.
    fn start_tx(&mut self, bytes: &[u8], not_before: u32) -> Result<(), TxError> {
        if self.tx != Tx::Idle || !self.transmit || self.silent {
            return Err(TxError::Busy);
        }
        if bytes.is_empty() || bytes.len() > MAX_FRAME_LEN {
            return Err(TxError::BadLength);
        }
        let at = (!compare_passed(self.ticks(), not_before)).then_some(not_before);
        let ring_pos = self.rx_mark();
        let Some(buf) = self.asm.buf.as_deref_mut() else { return Err(TxError::Busy) };
        sender!(self, buf).send(bytes, at, ring_pos);
        Ok(())
    }

    fn tx_busy(&self) -> bool {
        self.tx != Tx::Idle
    }
}

impl Sender<'_> {
    /// Send `bytes` as the response to `request` (the fast path's or the core's answer), no earlier
    /// than `min_tsdr` after its last stop bit and no later than `max_tsdr` — or not at all
    /// ([`line::tx_plan`]). Returns what was done.
    fn respond(
        &mut self,
        request: &FrameMeta,
        bytes: &[u8],
        min_tsdr: BitTimes,
        max_tsdr: BitTimes,
        quiet: bool,
    ) -> TxPlan {
        if !self.transmit || bytes.is_empty() || bytes.len() > self.buf.len() {
            add(DROPPED_BAD_LENGTH, 1);
            return TxPlan::Drop(TxDrop::Busy);
        }
        // From the tick table: additions and one multiply, no division.
        let not_before = self.table.not_before(request.end, min_tsdr);
        let latest = self.table.latest(request.end, max_tsdr);
        let plan = line::tx_plan(self.tim.cnt().read().bits(), not_before, latest, quiet, *self.tx != Tx::Idle);
        match plan {
            TxPlan::Drop(TxDrop::LineActive) => add(DROPPED_LINE_ACTIVE, 1),
            TxPlan::Drop(TxDrop::TooLate) => add(DROPPED_TOO_LATE, 1),
            TxPlan::Drop(TxDrop::Busy) => add(DROPPED_BUSY, 1),
            TxPlan::Now => self.send(bytes, None, request.seg_end),
            TxPlan::At(t) => self.send(bytes, Some(t), request.seg_end),
        }
        plan
    }

    /// Copy `bytes` (checked: 1..=MAX_FRAME_LEN) into the transmit buffer and start them now
    /// (`at` = `None`) or arm TIM5 compare 1 at `at`; the armed start is dropped when the ring
    /// has moved from `ring_pos` by then (`DmaLine::on_timer`).
    #[inline(always)]
    fn send(&mut self, bytes: &[u8], at: Option<u32>, ring_pos: u16) {
        self.buf[..bytes.len()].copy_from_slice(bytes);
        let st = self.dma.st(TX_STREAM);
        st.ndtr().write(|w| unsafe { w.bits(bytes.len() as u32) });
        if let Some(t) = at {
            *self.tx = Tx::Armed { ring_pos };
            self.tim.ccr(0).write(|w| unsafe { w.bits(t) });
            self.tim.sr().write(|w| unsafe { w.bits(!TIM_CC1) });
            self.tim.dier().modify(|r, w| unsafe { w.bits(r.bits() | TIM_CC1) });
            // The compare may have passed while it was being armed.
            if compare_passed(self.tim.cnt().read().bits(), t) {
                self.tim.dier().modify(|r, w| unsafe { w.bits(r.bits() & !TIM_CC1) });
                self.start_now();
            }
        } else {
            self.start_now();
        }
    }

    /// Drive the bus and start the transmit DMA (NDTR already set, data in `tx_buf`).
    fn start_now(&mut self) {
        let st = self.dma.st(TX_STREAM);
        self.usart.cr1().modify(|_, w| w.re().disabled());
        self.dma.hifcr().write(|w| unsafe { w.bits(DMA_S7_FLAGS) });
        st.par().write(|w| unsafe { w.bits(self.usart.dr().as_ptr() as u32) });
        st.m0ar().write(|w| unsafe { w.bits(self.buf.as_ptr() as u32) });
        st.fcr().write(|w| unsafe { w.bits(0) });
        st.cr().write(|w| unsafe { w.bits(DMA_CHSEL_USART1 | DMA_PL_VERY_HIGH | DMA_MINC | DMA_DIR_M2P) });
        // TC is rc_w0: writing 0 clears it, the other bits written 1 are unaffected.
        self.usart.sr().write(|w| unsafe { w.bits(!SR_TC) });
        st.cr().modify(|r, w| unsafe { w.bits(r.bits() | DMA_EN) });
        self.de.enable();
        self.usart.cr3().modify(|_, w| w.dmat().enabled());
        self.usart.cr1().modify(|_, w| w.tcie().enabled());
        *self.tx = Tx::Sending;
        add(RESPONSES, 1);
    }
}

/// Ring write position of the receive DMA.
#[inline(always)]
fn ring_pos(dma: &DMA2) -> usize {
    let ndtr = dma.st(RX_STREAM).ndtr().read().bits() as usize;
    // NDTR counts down from RX_RING and reloads at 0 (circular mode).
    (RX_RING - ndtr.min(RX_RING)) % RX_RING
}

/// The streaming framer's one copy in RAM (`Stream::piece`, generic, instantiated here): the
/// per-character path passes one-byte pieces, the DMA path the ring's pieces.
#[inline(never)]
#[link_section = ".data.pbcard_line"]
fn feed(stream: &mut Stream, bytes: &[u8], sink: &mut Tee<'_>) -> (usize, Step) {
    stream.piece(bytes, sink)
}

/// The telegram accounted to the rate control (`pbcard::phy::line::classify` decodes it
/// whole): after the response is on its way, in flash (off the response path, not worth RAM).
#[inline(never)]
fn account(tap: &mut RateTap<'static>, frame: &[u8], own: u8) {
    tap.account(classify(frame, own));
}

/// No character since the receive mark `mark`: DMA mode the ring position has not moved; per
/// character the count has not moved and none waits in DR (RXNE).
#[inline(always)]
fn rx_quiet(mode: RxMode, dma: &DMA2, usart: &USART1, chars: u16, mark: u16) -> bool {
    match mode {
        RxMode::Dma => ring_pos(dma) as u16 == mark,
        RxMode::PerChar => chars == mark && usart.sr().read().bits() & SR_RXNE == 0,
    }
}

// The line's counters (issue 11 item 3c): written only by the line interrupts (USART1, TIM5,
// both at priority 16: one writer at a time, so a load and a store, no read-modify-write
// race) and read by any task without a lock.
const PARITY: usize = 0;
const FRAMING: usize = 1;
const NOISE: usize = 2;
const OVERRUN: usize = 3;
const QUEUE_FULL: usize = 4;
const RESPONSES: usize = 5;
const DELAYED_STARTS: usize = 6;
const DROPPED_LINE_ACTIVE: usize = 7;
const DROPPED_TOO_LATE: usize = 8;
const DROPPED_BUSY: usize = 9;
const DROPPED_BAD_LENGTH: usize = 10;
const RING_OVERRUN: usize = 11;
/// [`RxStats`] in field order from here (published after each receive event and T_SYN).
const RX_BASE: usize = 12;
const COUNTER_COUNT: usize = RX_BASE + 6;

#[allow(clippy::declare_interior_mutable_const)]
const ZERO: AtomicU32 = AtomicU32::new(0);
static COUNTERS: [AtomicU32; COUNTER_COUNT] = [ZERO; COUNTER_COUNT];

/// Count `n` more on counter `i` (with the line's exclusive access only).
#[inline(always)]
fn add(i: usize, n: u32) {
    let c = &COUNTERS[i];
    c.store(c.load(Ordering::Relaxed).wrapping_add(n), Ordering::Relaxed);
}

/// The line's counters and health for the lower tasks, lock-free: atomics the line interrupts
/// publish, and read-only register reads (issue 11 item 3c).
pub mod monitor {
    use core::sync::atomic::Ordering;

    use pbcard::phy::line::RxStats;
    use stm32f4xx_hal::pac::{DMA2, TIM5, USART1};

    use super::*;

    fn get(i: usize) -> u32 {
        COUNTERS[i].load(Ordering::Relaxed)
    }

    /// The line's counters and the telegram cutter's (each value consistent; the set may be
    /// one event apart).
    pub fn stats() -> (LineStats, RxStats) {
        let line = LineStats {
            parity: get(PARITY),
            framing: get(FRAMING),
            noise: get(NOISE),
            overrun: get(OVERRUN),
            ring_overrun: get(RING_OVERRUN),
            queue_full: get(QUEUE_FULL),
            responses: get(RESPONSES),
            delayed_starts: get(DELAYED_STARTS),
            dropped_line_active: get(DROPPED_LINE_ACTIVE),
            dropped_too_late: get(DROPPED_TOO_LATE),
            dropped_busy: get(DROPPED_BUSY),
            dropped_bad_length: get(DROPPED_BAD_LENGTH),
        };
        let rx = RxStats {
            frames: get(RX_BASE),
            corrupt: get(RX_BASE + 1),
            truncated: get(RX_BASE + 2),
            garbage: get(RX_BASE + 3),
            unsynced: get(RX_BASE + 4),
            tsyn: get(RX_BASE + 5),
        };
        (line, rx)
    }

    /// Telegrams lost on the line (STATUS.CORRUPT_FRAMES): [`RxStats::lost_frames`].
    pub fn corrupt_frames() -> u32 {
        stats().1.lost_frames()
    }

    /// Whether the receive DMA, the USART and TIM5 run as programmed ([`super::DmaLine::is_healthy`]),
    /// from read-only register reads.
    pub fn is_healthy() -> bool {
        // SAFETY: reads of control registers, no side effects; the line owns the writes.
        let (dma, usart, tim) = unsafe { (&*DMA2::ptr(), &*USART1::ptr(), &*TIM5::ptr()) };
        // Per character (≤ 1.5 Mbit/s) the receive DMA is off and RXNEIE on.
        let rx_on = dma.st(RX_STREAM).cr().read().bits() & DMA_EN != 0 || usart.cr1().read().rxneie().bit_is_set();
        rx_on && usart.cr1().read().ue().bit_is_set() && tim.cr1().read().bits() & 1 != 0
    }
}

/// The mailbox of [`control`]: one command at a time, taken by the TIM5 interrupt.
static COMMAND: AtomicU8 = AtomicU8::new(control::NONE);

/// Commands to the line from lower-priority tasks, without its lock (issue 11 item 3b/3c): the
/// command goes into an atomic mailbox and the TIM5 interrupt — the line's own priority, above
/// every caller — is pended and executes it before `command` returns.
pub mod control {
    use core::sync::atomic::Ordering;

    use stm32f4xx_hal::pac::Interrupt;

    use super::COMMAND;

    pub(super) const NONE: u8 = 0;
    pub(super) const SILENCE: u8 = 1;
    pub(super) const RESTART: u8 = 2;

    /// Hand `cmd` to the line; `true` when it was executed (the TIM5 interrupt ran). `false`
    /// only if interrupts are masked here (called inside a critical section): the command is
    /// withdrawn.
    fn command(cmd: u8) -> bool {
        COMMAND.store(cmd, Ordering::Release);
        cortex_m::peripheral::NVIC::pend(Interrupt::TIM5);
        cortex_m::asm::dsb();
        cortex_m::asm::isb();
        // The interrupt has preempted us between the pend and here, unless it is masked.
        COMMAND.compare_exchange(cmd, NONE, Ordering::AcqRel, Ordering::Acquire).is_err()
    }

    /// Silence the line before a flash operation (module documentation "Flash stalls"):
    /// `true` once DE is low and receiver, DMA and compares are off.
    pub fn silence() -> bool {
        command(SILENCE)
    }

    /// Restart the line fully after a flash operation: USART reprogrammed, ring flushed, the
    /// receiver waits for T_SYN (proven from now).
    pub fn restart() -> bool {
        command(RESTART)
    }

    /// Pend the TIM5 interrupt without a command: it carries out a rate switch the rate
    /// keeper asked for (`pbcard::phy::rate_link`).
    pub fn kick() {
        cortex_m::peripheral::NVIC::pend(Interrupt::TIM5);
        cortex_m::asm::dsb();
        cortex_m::asm::isb();
    }
}

/// The receive gate's view of USART_SR.
#[inline(always)]
fn rx_flags(sr: u16) -> RxFlags {
    RxFlags { idle: sr & SR_IDLE != 0, error: sr & (SR_PE | SR_FE | SR_NF | SR_ORE) != 0 }
}

/// The safe state of the line from a panic or HardFault handler, without the `DmaLine`
/// (whose owner may be the one that failed): stop the transmit DMA, release DE (PA8).
///
/// # Safety
/// Only from the fault path: it writes GPIOA, DMA2 and USART1 registers behind the owners'
/// backs, which is fine only because nothing runs afterwards but a reset.
pub unsafe fn line_safe_state() {
    let dp = stm32f4xx_hal::pac::Peripherals::steal();
    // DE first: one store, whatever state the rest is in.
    dp.GPIOA.bsrr().write(|w| w.br8().set_bit());
    dp.USART1.cr3().modify(|_, w| w.dmat().disabled());
    dp.DMA2.st(TX_STREAM).cr().modify(|r, w| w.bits(r.bits() & !DMA_EN));
    dp.USART1.cr1().modify(|_, w| w.te().disabled().tcie().disabled());
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
/// The rate control of this board: the ASIC-style search and supervision
/// (`pbcard::phy::autobaud::Autobaud`) in the keeper half of `pbcard::phy::rate_link`; the
/// line interrupt holds the other half.
pub type Baud = pbcard::phy::rate_link::RateKeeper<'static>;

/// Make the line take the rate switch the keeper has just asked for (`RateKeeper::poll`
/// returned `rate`): the TIM5 interrupt, pended, carries it out before this returns
/// (`DmaLine::on_command`). `false` when the rate has no USART divisor at PCLK2 (the line
/// then stays at the old rate).
pub fn switch_rate(rate: Baudrate) -> bool {
    if usart_brr(clocks::PCLK2_HZ, rate.bits_per_second()).is_none() {
        return false;
    }
    control::kick();
    true
}
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
    /// it differs from the stored pair (Set_Slave_Add) and the I&M1–4 of [`Self::store_im`] (the
    /// flash stalls the CPU meanwhile, so the line is silenced before and restarted after —
    /// module documentation "Flash stalls": both through the line's command mailbox, no lock);
    /// start the IWDG at the first call and feed it only when `alive` (the line
    /// hardware runs and the protocol tasks make progress).
    pub fn tick(
        &mut self,
        now: pbcard::time::Instant,
        leds: Option<pbcard::led::Leds>,
        address: (u8, bool),
        alive: bool,
    ) {
        if let Some(l) = leds {
            self.leds.show(now, l);
        }
        if self.iwdg.is_none() {
            if let Some(p) = self.iwdg_periph.take() {
                self.iwdg = Some(Iwdg::start(p));
            }
        }
        if address != self.stored || self.im.is_some() {
            if let Some(w) = self.iwdg.as_mut() {
                w.feed();
            }
            // Silence first (DE low, receiver and DMA off); if the line cannot confirm it, the
            // write waits for the next millisecond (nothing is taken from the queue before).
            if control::silence() {
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
                if let Some(d) = self.im.take() {
                    match self.store.save(&d) {
                        Ok(written) => defmt::info!("I&M1-4 stored (written {=bool})", written),
                        Err(e) => defmt::error!("storing I&M1-4 failed: {}", e),
                    }
                }
                // Restart fully: ring flushed, T_SYN awaited (nothing stale is answered).
                control::restart();
            }
        }
        if alive {
            if let Some(w) = self.iwdg.as_mut() {
                w.feed();
            }
        }
    }
}

/// SysTick's hardware priority: RTIC logical priority 2 of 16 (`(16 − 2) << 4`), above the
/// priority-1 tasks that await it, below everything else (the line is logical 16 = 0x00).
pub const SYSTICK_PRIORITY_HW: u8 = (16 - 2) << 4;

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

    // Issue 11 3d: DE (PA8) low before anything else. `__pre_init` (below) has driven it low
    // before RAM initialisation; the HAL's `split` resets GPIOA (PA8 floats for a few cycles,
    // held low by the board's external pull-down) and the pin is an output at low again at
    // once, before the clock tree is touched.
    let mut rcc_regs = dp.RCC;
    let gpioa = dp.GPIOA.split(&mut rcc_regs);
    let de = gpioa.pa8.into_push_pull_output_in_state(PinState::Low).speed(Speed::VeryHigh);

    // Keep the debug clock running in WFI, so probe-rs / RTT keep working in idle; stop the
    // IWDG while the core is halted by a debugger.
    dp.DBGMCU.cr().modify(|_, w| w.dbg_sleep().set_bit());
    dp.DBGMCU.apb1_fz().modify(|_, w| w.dbg_iwdg_stop().set_bit());

    // Issue 11 3a: the regulator at scale 1 before the PLL runs at 96 MHz (PWR_CR.VOS = 0b11,
    // "scale 1, HCLK ≤ 100 MHz"; the reset value 0b10 is scale 2, rated ≤ 84 MHz, and
    // stm32f4xx-hal's `freeze` leaves it). RM0383 §5.4.1: VOS can be modified only while the
    // PLL is off and takes effect when it is switched on; PWR_CSR.VOSRDY then says the
    // regulator has reached the level.
    scale1_before_pll(&rcc_regs, &dp.PWR);
    // Issue 11 3g: the crystal is started here with a timeout (the HAL's `freeze` waits for
    // HSERDY forever). Without it the card runs from HSI (same 96 MHz tree) but never drives
    // the bus: HSI's tolerance (±1 % at 25 °C, more over temperature, DS10314) is far outside
    // PROFIBUS's ±0.3 % — a defined fault, logged, with the DPM side still running.
    let crystal = start_hse(&rcc_regs);
    let config = if crystal { rcc::Config::hse(Hertz::from_raw(clocks::HSE_HZ)) } else { rcc::Config::hsi() };
    let mut rcc = rcc_regs.freeze(
        config
            .sysclk(Hertz::from_raw(clocks::SYSCLK_HZ))
            .pclk1(Hertz::from_raw(clocks::PCLK1_HZ))
            .pclk2(Hertz::from_raw(clocks::PCLK2_HZ)),
    );
    let vos_ready = wait_vos_ready(&dp.PWR);
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

    defmt::info!(
        "regulator: PWR_CR.VOS = {=u8:#04b} (scale 1), VOSRDY {=bool}",
        dp.PWR.cr().read().vos().bits(),
        vos_ready
    );

    if !crystal {
        defmt::error!(
            "HSE ({=u32} Hz crystal) did not start within {=u32} ms: running from HSI, the PROFIBUS line stays silent",
            clocks::HSE_HZ,
            HSE_TIMEOUT_MS
        );
    }
    brown_out_level(&dp.FLASH);

    let clock = super::clock::start(syst, sysclk);
    // Issue 11 3c: SysTick (the RTIC monotonic's tick; its reset priority 0 is the line's own)
    // below every task but the priority-1 ones, so its handler never delays the line.
    // SAFETY: `init` runs with interrupts disabled; only SysTick's priority changes.
    unsafe {
        cortex_m::Peripherals::steal()
            .SCB
            .set_priority(cortex_m::peripheral::scb::SystemHandler::SysTick, SYSTICK_PRIORITY_HW)
    };

    let tx = gpioa.pa9.into_alternate::<7>().speed(Speed::VeryHigh);
    // Pull-up: the transceiver's RO may float while its receiver is disabled.
    let rx = gpioa.pa10.into_alternate::<7>().internal_pull_up(true);

    let gpiob = dp.GPIOB.split(&mut rcc);
    let leds = LedPins {
        ps: gpiob.pb6.into_push_pull_output_in_state(PinState::Low),
        bs: gpiob.pb7.into_push_pull_output_in_state(PinState::Low),
        fs: gpiob.pb8.into_push_pull_output_in_state(PinState::Low),
    };

    let line = match DmaLine::new(
        dp.USART1,
        dp.DMA2,
        dp.TIM5,
        (tx, rx),
        DePin(de),
        pclk2,
        timclk1,
        rate,
        crystal,
        clock,
        &mut rcc,
    ) {
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

/// PWR_CR.VOS = scale 1 (0b11) with the PLL off (RM0383 §5.4.1). After a reset the PLL is
/// off; should anything have left it on (a debugger script), the system clock goes back to
/// HSI and the PLL is stopped first, which `freeze` then programs and starts again.
fn scale1_before_pll(rcc: &stm32f4xx_hal::pac::RCC, pwr: &stm32f4xx_hal::pac::PWR) {
    if rcc.cr().read().pllon().bit_is_set() {
        rcc.cfgr().modify(|_, w| w.sw().hsi());
        while !rcc.cfgr().read().sws().is_hsi() {}
        rcc.cr().modify(|_, w| w.pllon().clear_bit());
        while rcc.cr().read().pllrdy().bit_is_set() {}
    }
    rcc.apb1enr().modify(|_, w| w.pwren().set_bit());
    // A peripheral clock is on only a few AHB cycles after its enable bit (the F4 errata's
    // "delay after an RCC peripheral clock enabling"): a read-back and a DSB before the access.
    let _ = rcc.apb1enr().read();
    cortex_m::asm::dsb();
    pwr.cr().modify(|_, w| w.vos().scale1());
}

/// Wait (bounded: ≈ 1 ms at 96 MHz) until PWR_CSR.VOSRDY says the regulator is at the VOS
/// level; `false` if it did not come (logged; the card runs on, as it did before this check).
fn wait_vos_ready(pwr: &stm32f4xx_hal::pac::PWR) -> bool {
    for _ in 0..1000 {
        if pwr.csr().read().vosrdy().bit_is_set() {
            return true;
        }
        cortex_m::asm::delay(96);
    }
    false
}

/// How long the crystal may take to start (HSE_STARTUP_TIMEOUT of ST's own drivers: 100 ms;
/// a 25 MHz crystal typically needs 2 ms, DS10314 t_SU(HSE)).
pub const HSE_TIMEOUT_MS: u32 = 100;

/// Switch the crystal oscillator on and wait for RCC_CR.HSERDY at most [`HSE_TIMEOUT_MS`]
/// (counted in HSI cycles: the core runs from the 16 MHz HSI after reset). `false`: HSEON
/// is cleared again and the clock tree is built on HSI.
fn start_hse(rcc: &stm32f4xx_hal::pac::RCC) -> bool {
    rcc.cr().modify(|_, w| w.hseon().set_bit());
    // Polled every 1 600 cycles = 100 µs at 16 MHz.
    for _ in 0..HSE_TIMEOUT_MS * 10 {
        if rcc.cr().read().hserdy().bit_is_set() {
            return true;
        }
        cortex_m::asm::delay(1_600);
    }
    rcc.cr().modify(|_, w| w.hseon().clear_bit());
    false
}

/// FLASH_OPTCR.BOR_LEV for brown-out level 3 (RM0383 §3.8.6: 00 = VBOR3 ≈ 2.7 V, 01 = VBOR2,
/// 10 = VBOR1, 11 = off — the factory value; the stm32f4 PAC's enumeration of this field names
/// 0 "off", so the raw bits are used here).
const BOR_LEV_LEVEL3: u32 = 0b00;
const OPTCR_BOR_LEV_SHIFT: u32 = 2;
const OPTCR_BOR_LEV_MASK: u32 = 0b11 << OPTCR_BOR_LEV_SHIFT;
const OPTCR_OPTLOCK: u32 = 1 << 0;
const OPTCR_OPTSTRT: u32 = 1 << 1;
const OPTKEY1: u32 = 0x0819_2A3B;
const OPTKEY2: u32 = 0x4C5D_6E7F;
const FLASH_SR_BSY: u32 = 1 << 16;

/// Issue 11 3g: the brown-out reset at level 3 (≈ 2.7 V), the lowest supply at which 3 flash
/// wait states are rated at 96 MHz (RM0383 Table 5: 2.7–3.6 V). The option byte is written
/// **only when it differs** — once, at the first boot of a new card — never on every boot
/// (option-byte programming wears the option sector and a power loss during it is the one
/// risky moment): the read-modify-write keeps RDP, nWRP and the user bits as they are. The
/// line is not running yet (DE low), so the stall of the write costs nothing.
fn brown_out_level(flash: &stm32f4xx_hal::pac::FLASH) {
    let optcr = flash.optcr().read().bits();
    let level = (optcr & OPTCR_BOR_LEV_MASK) >> OPTCR_BOR_LEV_SHIFT;
    if level == BOR_LEV_LEVEL3 {
        defmt::info!("brown-out reset: level 3 (option byte BOR_LEV = 0b00)");
        return;
    }
    while flash.sr().read().bits() & FLASH_SR_BSY != 0 {}
    flash.optkeyr().write(|w| unsafe { w.bits(OPTKEY1) });
    flash.optkeyr().write(|w| unsafe { w.bits(OPTKEY2) });
    let new = (optcr & !(OPTCR_BOR_LEV_MASK | OPTCR_OPTLOCK | OPTCR_OPTSTRT)) | (BOR_LEV_LEVEL3 << OPTCR_BOR_LEV_SHIFT);
    flash.optcr().write(|w| unsafe { w.bits(new) });
    flash.optcr().write(|w| unsafe { w.bits(new | OPTCR_OPTSTRT) });
    while flash.sr().read().bits() & FLASH_SR_BSY != 0 {}
    flash.optcr().modify(|r, w| unsafe { w.bits(r.bits() | OPTCR_OPTLOCK) });
    let now = (flash.optcr().read().bits() & OPTCR_BOR_LEV_MASK) >> OPTCR_BOR_LEV_SHIFT;
    defmt::warn!("brown-out reset: BOR_LEV {=u32:#04b} -> {=u32:#04b} (level 3, written once)", level, now);
}

// Issue 11 3d: the RS485 driver enable low as the very first thing after reset, before the
// RAM is initialised and long before the clocks (cortex-m-rt calls `__pre_init` from the
// reset handler; written in assembly because no Rust may run before RAM initialisation,
// cortex-m-rt's documentation of `pre_init`). RCC_AHB1ENR.GPIOAEN (0x4002_3830 bit 0), a
// read-back for the clock-enable delay, GPIOA_BSRR.BR8 (0x4002_0018 bit 24: ODR8 = 0), then
// GPIOA_MODER.MODER8 = 0b01 (0x4002_0000 bits 17:16: output; the other pins, SWD on PA13 /
// PA14 included, keep their mode). Until then (reset, the first few cycles) the transceiver's
// DE is held low by the external pull-down on PA8 (README "Hardware").
core::arch::global_asm!(
    ".section .text.__pre_init,\"ax\",%progbits",
    ".global __pre_init",
    ".type __pre_init,%function",
    ".thumb_func",
    "__pre_init:",
    "    ldr r0, =0x40023830",
    "    ldr r1, [r0]",
    "    orr r1, r1, #1",
    "    str r1, [r0]",
    "    ldr r1, [r0]",
    "    dsb",
    "    ldr r0, =0x40020018",
    "    mov r1, #0x01000000",
    "    str r1, [r0]",
    "    ldr r0, =0x40020000",
    "    ldr r1, [r0]",
    "    bic r1, r1, #0x00030000",
    "    orr r1, r1, #0x00010000",
    "    str r1, [r0]",
    "    bx lr",
    ".ltorg",
    ".size __pre_init, . - __pre_init",
);
