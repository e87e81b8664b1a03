//! The DPM transport on the STM32F411 reference board: SPI2 as SPI **slave** to the drive's
//! control board, both directions by DMA1, NSS as the transaction delimiter, and an IRQ
//! output to the host. The frame protocol (byte-level spec, checks, replies, events) is
//! `pbcard::dpm::spi`; this file only moves bytes (ARCHITECTURE §3).
//!
//! ## Pinout (connector to the drive's control board)
//!
//! | pin | function | direction (card) | note |
//! |---|---|---|---|
//! | PB12 | SPI2_NSS (AF5) + EXTI12 | in | hardware NSS: the SPI ignores SCK while high; its rising edge ends a transaction |
//! | PB13 | SPI2_SCK (AF5) | in | mode 0 (CPOL 0, CPHA 0), up to 12 MHz |
//! | PB14 | SPI2_MISO (AF5) | out | push-pull, very high speed |
//! | PB15 | SPI2_MOSI (AF5) | in | |
//! | PB0 | IRQ | out | active low, push-pull: low while the card has pending events |
//!
//! Nothing here touches the PROFIBUS side (USART1 on PA9 / PA10, DE on PA8, `f411.rs`) or
//! its DMA controller (USART1 is served by DMA2 only): this driver owns SPI2, DMA1 streams 3
//! and 4, EXTI line 12 and GPIOB pins 0 and 12..=15.
//!
//! ## DMA
//!
//! SPI2_RX = DMA1 stream 3 channel 0 (peripheral → memory, [`RX_LEN`] bytes), SPI2_TX = DMA1
//! stream 4 channel 0 (memory → peripheral, [`TX_LEN`] bytes). No DMA interrupt: the
//! transaction end is NSS rising.
//!
//! ## One transaction, and the reply pipeline
//!
//! NSS rising → EXTI15_10 → [`SpiPort::on_nss_rise`] (a few µs, never blocks on the
//! protocol): the received length is `RX_LEN - NDTR`; both streams stop; SPI2 is **reset
//! through RCC** and programmed again — the only way to drop the byte the TX DMA has already
//! preloaded into the data register (without it, the next reply would start with a stale
//! byte); RX is re-armed on a spare buffer, TX on nothing (MISO sends `0x00`, "no reply").
//! The received buffer goes to the frame task, which runs `dpm::spi::SpiSlave::handle`
//! against the image and hands the reply to [`SpiPort::reply_ready`]: if the next
//! transaction has not begun (NSS high, no byte received), SPI2 is re-programmed at once
//! with the TX DMA on the reply — it goes out in the **next** transaction (*k + 1*, the
//! protocol's pipeline, `pbcard::dpm::spi::ReplyPipeline`, the same state machine the
//! in-process `Loopback` runs); otherwise the reply is late and discarded, never sent in a
//! later transaction. (The first version armed the previous reply at each NSS rise: the
//! reply to *k* went out in *k + 2*, and the reference host never found it.)
//! [`SpiPort::refresh_ready`] re-arms a rebuilt CYCLIC reply the same way after each card
//! step. That is why the HAL's `SpiSlave` / `dma::Transfer` are not used: they cannot reset
//! and re-program SPI2 between transactions from the interrupt; GPIO, EXTI and RCC enable /
//! reset come from the HAL.
//!
//! Buffers: two RX and two TX buffers of about 1 KiB each (`cortex_m::singleton!`), owned
//! by whoever holds the `&'static mut` — the DMA only ever sees a buffer this port holds.
//! If the frame task still holds the spare RX buffer when a transaction ends (the master
//! was faster than [`pbcard::dpm::spi::T_READY_US`]), the transaction is dropped and
//! counted ([`PortStats::dropped`]); the master sees "no reply" and repeats.

use core::sync::atomic::{compiler_fence, Ordering};

use pbcard::dpm::spi::{PipelineStats, ReplyPipeline, SlavePort, SpiStats, WireImage, MAX_REPLY, MAX_TRANSACTION};
use pbcard::dpm::Dpm;
use rtic::Mutex;
use stm32f4xx_hal::gpio::{Alternate, Edge, ExtiPin, Output, PinState, PushPull, Speed, PB0, PB12, PB13, PB14, PB15};
use stm32f4xx_hal::pac::{DMA1, EXTI, SPI2, SYSCFG};
use stm32f4xx_hal::rcc::{Enable, Rcc, Reset};
use stm32f4xx_hal::syscfg::SysCfgExt;

/// RX buffer length: one byte more than the longest transaction, so that an overlong one is
/// seen (and refused) instead of cut to a valid length.
pub const RX_LEN: usize = MAX_TRANSACTION + 1;
/// TX buffer length: the longest reply; the bytes after a reply are `0x00`.
pub const TX_LEN: usize = MAX_REPLY;

/// A receive buffer.
pub type RxBuf = [u8; RX_LEN];
/// A transmit (reply) buffer.
pub type TxBuf = [u8; TX_LEN];

const RX_STREAM: usize = 3;
const TX_STREAM: usize = 4;

/// One received transaction, handed from the interrupt to the frame task (and back with
/// [`SpiPort::give_back`]).
pub struct Frame {
    buf: &'static mut RxBuf,
    len: usize,
}

impl AsRef<[u8]> for Frame {
    fn as_ref(&self) -> &[u8] {
        self.bytes()
    }
}

impl Frame {
    /// The MOSI bytes between NSS falling and rising.
    pub fn bytes(&self) -> &[u8] {
        &self.buf[..self.len]
    }
}

/// Counters of the port (the protocol's own are in `SpiSlave::stats`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, defmt::Format)]
pub struct PortStats {
    /// Transactions with at least one byte.
    pub transactions: u32,
    /// NSS pulses without a byte (ignored).
    pub empty: u32,
    /// Transactions dropped because the frame task had not returned the spare buffer.
    pub dropped: u32,
    /// The reply pipeline: replies armed in time, late (discarded), transactions without
    /// a reply, CYCLIC replies refreshed.
    pub pipeline: PipelineStats,
}

/// SPI2 slave + DMA1 + NSS EXTI + IRQ pin.
pub struct SpiPort {
    spi: SPI2,
    dma: DMA1,
    rcc: Rcc,
    nss: PB12<Alternate<5>>,
    _pins: (PB13<Alternate<5>>, PB14<Alternate<5>>, PB15<Alternate<5>>),
    irq: PB0<Output<PushPull>>,
    /// Armed for RX (the DMA writes it).
    rx: Option<&'static mut RxBuf>,
    rx_spare: Option<&'static mut RxBuf>,
    /// The reply buffers: which one the TX DMA reads (armed), which are free.
    tx: ReplyPipeline<&'static mut TxBuf>,
    stats: PortStats,
}

impl SpiPort {
    /// Whether no transaction has begun since the last NSS rise: NSS high and no byte
    /// received.
    fn idle(&self) -> bool {
        let remaining = usize::from(self.dma.st(RX_STREAM).ndtr().read().ndt().bits());
        self.nss.is_high() && remaining == RX_LEN
    }

    /// A CYCLIC reply rebuilt after a card step (`SpiSlave::refresh` on a copy of the armed
    /// one) replaces the armed reply, if no transaction has begun.
    pub fn refresh_ready(&mut self, buf: &'static mut TxBuf, len: usize) -> bool {
        self.reply_ready(buf, len)
    }

    /// The armed reply (to copy it for a refresh).
    pub fn armed(&self) -> Option<&TxBuf> {
        self.tx.armed().map(|b| &**b)
    }

    /// A reply buffer taken with [`Self::reply_buffer`] and not used.
    pub fn release(&mut self, buf: &'static mut TxBuf) {
        self.tx.release(buf);
    }

    /// Transactions ended so far (every NSS rise): unchanged = the armed reply still answers
    /// the request the frame task handled last.
    fn generation(&self) -> u32 {
        self.stats.transactions.wrapping_add(self.stats.empty)
    }

    /// The port's counters.
    pub fn stats(&self) -> PortStats {
        PortStats { pipeline: self.tx.stats(), ..self.stats }
    }

    /// Stop both streams and reset SPI2 (drops the preloaded TX byte and any overrun).
    #[inline(never)]
    fn stop(&mut self) {
        for s in [RX_STREAM, TX_STREAM] {
            let st = self.dma.st(s);
            st.cr().modify(|_, w| w.en().disabled());
            // EN reads 1 until the stream has finished its current beat (a few cycles).
            while st.cr().read().en().is_enabled() {}
        }
        // Clear every flag of streams 3 (LIFCR) and 4 (HIFCR).
        self.dma.lifcr().write(|w| {
            w.cfeif3().clear();
            w.cdmeif3().clear();
            w.cteif3().clear();
            w.chtif3().clear();
            w.ctcif3().clear()
        });
        self.dma.hifcr().write(|w| {
            w.cfeif4().clear();
            w.cdmeif4().clear();
            w.cteif4().clear();
            w.chtif4().clear();
            w.ctcif4().clear()
        });
        SPI2::reset(&mut self.rcc);
    }

    /// Program SPI2 and the streams for the next transaction (RM0383 §20.3.8 order: RXDMAEN,
    /// streams, TXDMAEN, SPE).
    #[inline(never)]
    fn start(&mut self) {
        // Slave, mode 0, 8 bit, MSB first, hardware NSS (SSM = 0).
        self.spi.cr1().write(|w| {
            w.mstr().clear_bit();
            w.cpol().clear_bit();
            w.cpha().clear_bit();
            w.dff().clear_bit();
            w.lsbfirst().clear_bit();
            w.ssm().clear_bit()
        });
        self.spi.cr2().write(|w| w.rxdmaen().set_bit());
        let dr = self.spi.dr().as_ptr() as u32;
        compiler_fence(Ordering::SeqCst);
        cortex_m::asm::dmb();
        if let Some(rx) = self.rx.as_deref_mut() {
            arm(&self.dma, RX_STREAM, dr, rx.as_mut_ptr() as u32, RX_LEN as u16, false);
        }
        if let Some(tx) = self.tx.armed().map(|b| &**b) {
            arm(&self.dma, TX_STREAM, dr, tx.as_ptr() as u32, TX_LEN as u16, true);
            self.spi.cr2().modify(|_, w| w.txdmaen().set_bit());
        }
        self.spi.cr1().modify(|_, w| w.spe().set_bit());
    }
}

/// Program and enable one stream: channel 0, byte transfers, memory increment.
fn arm(dma: &DMA1, stream: usize, periph: u32, mem: u32, n: u16, to_periph: bool) {
    let st = dma.st(stream);
    // SAFETY: `periph` is SPI2's data register, `mem` a buffer of at least `n` bytes that
    // the port owns (`&'static mut`) until the stream is stopped again in `stop`.
    st.par().write(|w| unsafe { w.pa().bits(periph) });
    st.m0ar().write(|w| unsafe { w.m0a().bits(mem) });
    st.ndtr().write(|w| w.ndt().set(n));
    st.fcr().reset(); // direct mode
    st.cr().write(|w| {
        w.chsel().set(0);
        if to_periph {
            w.dir().memory_to_peripheral();
        } else {
            w.dir().peripheral_to_memory();
        }
        w.minc().incremented();
        w.pinc().fixed();
        w.psize().bits8();
        w.msize().bits8();
        w.pl().high();
        w.en().enabled()
    });
}

/// The peripherals this port owns, handed over by the board's `init`
/// ([`super::f411::Board::spi`]): SPI2, DMA1, EXTI, SYSCFG, the pins PB0 and PB12..=PB15
/// (unconfigured), and RCC (the HAL's, after the clock tree is frozen), which the port keeps
/// to reset SPI2 after an aborted transaction; nothing else uses RCC after `init`.
pub struct SpiParts {
    /// The SPI in slave mode.
    pub spi: SPI2,
    /// Streams 3 (RX) and 4 (TX), channel 0.
    pub dma: DMA1,
    /// EXTI line 12 (NSS rising).
    pub exti: EXTI,
    /// The EXTI line 12 source selection (port B).
    pub syscfg: SYSCFG,
    /// The enable / reset bits of SPI2 and DMA1 (the frozen clock tree).
    pub rcc: Rcc,
    /// IRQ to the drive.
    pub irq: PB0,
    /// SPI2_NSS.
    pub nss: PB12,
    /// SPI2_SCK.
    pub sck: PB13,
    /// SPI2_MISO.
    pub miso: PB14,
    /// SPI2_MOSI.
    pub mosi: PB15,
}

/// The board contract's DPM transport (`pbcard::dpm::spi::SlavePort`): SPI2 slave + DMA1.
impl SlavePort for SpiPort {
    type Frame = Frame;
    type Reply = &'static mut TxBuf;

    /// Handle the end of a transaction (NSS rising; call from the EXTI15_10 interrupt):
    /// re-arm for the next one and return what was received, if the frame task can take it.
    fn on_nss_rise(&mut self) -> Option<Frame> {
        self.nss.clear_interrupt_pending_bit();
        let remaining = usize::from(self.dma.st(RX_STREAM).ndtr().read().ndt().bits());
        let len = RX_LEN.saturating_sub(remaining);
        self.stop();
        let mut frame = None;
        if len == 0 {
            self.stats.empty = self.stats.empty.wrapping_add(1);
        } else {
            self.stats.transactions = self.stats.transactions.wrapping_add(1);
            match (self.rx_spare.take(), self.rx.take()) {
                (Some(spare), Some(full)) => {
                    self.rx = Some(spare);
                    frame = Some(Frame { buf: full, len });
                }
                (spare, full) => {
                    // The frame task still holds the spare: drop this transaction.
                    self.rx_spare = spare;
                    self.rx = full;
                    self.stats.dropped = self.stats.dropped.wrapping_add(1);
                }
            }
        }
        self.tx.transaction_end();
        self.start();
        frame
    }

    /// A buffer for the next reply (`None` only if the frame task already holds both).
    fn reply_buffer(&mut self) -> Option<&'static mut TxBuf> {
        self.tx.buffer()
    }

    /// The reply in `buf` (its first `len` bytes; the rest is zeroed here) goes out in the
    /// next transaction if that has not begun yet; else it is late and discarded (the
    /// master sees `0x00` and repeats its request). Returns whether it was armed.
    fn reply_ready(&mut self, buf: &'static mut TxBuf, len: usize) -> bool {
        buf[len.min(TX_LEN)..].fill(0);
        let idle = self.idle();
        if self.tx.ready(buf, idle).is_none() {
            return false;
        }
        // Re-program SPI2 with the TX DMA on the armed reply (nothing was clocked yet).
        self.stop();
        self.start();
        true
    }

    /// The frame task is done with a received frame.
    fn give_back(&mut self, frame: Frame) {
        self.rx_spare = Some(frame.buf);
    }

    /// A received frame nobody could handle (the frame task was still running): count it
    /// dropped and take its buffer back.
    fn drop_frame(&mut self, frame: Frame) {
        self.stats.dropped = self.stats.dropped.wrapping_add(1);
        self.give_back(frame);
    }

    /// Drive the IRQ line: `true` = asserted (low).
    fn set_irq(&mut self, asserted: bool) {
        if asserted {
            self.irq.set_low();
        } else {
            self.irq.set_high();
        }
    }
}

/// Between two application steps (the 1 ms IRQ task, at the step's priority), with the
/// frame task's image (`WireImage`, issue 16 item 3): the hand-over with the application's
/// image `card` (`None`: a bench card whose simulated drive writes the host blocks in process:
/// nothing is handed over), then the armed CYCLIC reply rebuilt from the new image
/// (`docs/SPI.md` "One drive cycle": the drive gets the newest command) — armed only if no
/// transaction ended meanwhile, so a reply still goes out in *k + 1* or never — and the IRQ
/// line. The frame task waits only for the short copies under `wire`, never for the step.
/// Returns the port's and the protocol's counters.
pub fn after_step(
    port: &mut impl Mutex<T = SpiPort>,
    wire: &mut impl Mutex<T = WireImage>,
    card: Option<&mut Dpm>,
) -> (PortStats, SpiStats) {
    let (generation, buf) = port.lock(|p| (p.generation(), if p.armed().is_some() { p.reply_buffer() } else { None }));
    let (irq, proto, rebuilt) = wire.lock(|w| {
        if let Some(card) = card {
            w.hand_over(card);
        }
        let rebuilt = buf.map(|b| {
            let n = w.refresh(b);
            (b, n)
        });
        (w.irq(), w.stats(), rebuilt)
    });
    port.lock(|p| {
        if let Some((b, n)) = rebuilt {
            match n {
                Some(n) if p.generation() == generation && p.armed().is_some() => {
                    p.refresh_ready(b, n);
                }
                _ => p.release(b),
            }
        }
        p.set_irq(irq);
        (p.stats(), proto)
    })
}

/// Bring up SPI2 slave, DMA1, the NSS interrupt and the IRQ pin (released) on the
/// peripherals the board handed over. Call once from the RTIC `init`, after `f411::init`.
pub fn init(parts: SpiParts) -> SpiPort {
    let SpiParts { spi, dma, mut exti, syscfg, mut rcc, irq, nss, sck, miso, mosi } = parts;
    SPI2::enable(&mut rcc);
    SPI2::reset(&mut rcc);
    DMA1::enable(&mut rcc);
    DMA1::reset(&mut rcc);

    // Issue 11 3d: a card without a control board must not see transactions or EXTI12 edges
    // from floating inputs: NSS pulled up (deselected), SCK pulled down (mode 0 idle), MOSI
    // pulled up; IRQ is a push-pull output released (high) from here on (before this, during
    // reset, the control board's pull-up holds it released, docs/SPI.md).
    let irq = irq.into_push_pull_output_in_state(PinState::High);
    let mut nss = nss.into_alternate::<5>().internal_pull_up(true);
    let sck = sck.into_alternate::<5>().internal_pull_down(true);
    let miso = miso.into_alternate::<5>().speed(Speed::VeryHigh);
    let mosi = mosi.into_alternate::<5>().internal_pull_up(true);

    let mut syscfg = syscfg.constrain(&mut rcc);
    nss.make_interrupt_source(&mut syscfg);
    nss.trigger_on_edge(&mut exti, Edge::Rising);
    nss.enable_interrupt(&mut exti);

    let rx_a = cortex_m::singleton!(: RxBuf = [0; RX_LEN]);
    let rx_b = cortex_m::singleton!(: RxBuf = [0; RX_LEN]);
    let tx_a = cortex_m::singleton!(: TxBuf = [0; TX_LEN]);
    let tx_b = cortex_m::singleton!(: TxBuf = [0; TX_LEN]);
    let (Some(rx_a), Some(rx_b), Some(tx_a), Some(tx_b)) = (rx_a, rx_b, tx_a, tx_b) else {
        defmt::panic!("bsp::spi::init called twice");
    };

    let mut port = SpiPort {
        spi,
        dma,
        rcc,
        nss,
        _pins: (sck, miso, mosi),
        irq,
        rx: Some(rx_a),
        rx_spare: Some(rx_b),
        tx: ReplyPipeline::new(tx_a, tx_b),
        stats: PortStats::default(),
    };
    port.start();
    defmt::info!(
        "DPM SPI: SPI2 slave mode 0 (NSS PB12, SCK PB13, MISO PB14, MOSI PB15), IRQ PB0 active low, DMA1 streams 3/4"
    );
    port
}

/// `.uninit` RAM that survives a system reset (panic, HardFault, IWDG): the boot counter
/// behind `CARD.BOOT_ID` (issue 16), with a check word.
#[link_section = ".uninit.pbcard_boot"]
static mut BOOT_COUNTER: core::mem::MaybeUninit<[u32; 2]> = core::mem::MaybeUninit::uninit();

const BOOT_CHECK: u32 = 0xB007_1D00;

/// The boot identifier for `CARD.BOOT_ID`: a counter in RAM that survives resets, one more
/// on every start (after a power-up the RAM holds noise, which is as good a start value);
/// never 0. Call once from `init`, before interrupts are enabled.
pub fn boot_id() -> u16 {
    // SAFETY: called once from `init` with interrupts off; `[u32; 2]` has no invalid values.
    let count = unsafe {
        let p = core::ptr::addr_of_mut!(BOOT_COUNTER) as *mut [u32; 2];
        let [c, k] = core::ptr::read_volatile(p);
        let c = if k == BOOT_CHECK ^ c { c.wrapping_add(1) } else { c };
        core::ptr::write_volatile(p, [c, BOOT_CHECK ^ c]);
        c
    };
    (count as u16).max(1)
}
