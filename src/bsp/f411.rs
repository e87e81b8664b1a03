//! The STM32F411 reference board, interrupt-per-byte edition: USART1 on PA9 (TX) / PA10 (RX),
//! RS485 driver enable on PA8 (ARCHITECTURE §2).
//!
//! USART1 is programmed through the PAC directly (the HAL's serial driver hides the status
//! flags that must be read together with each character): 9-bit word with parity enabled
//! (= 8 data bits + even parity, PROFIBUS's 11-bit character), 1 stop bit, receiver
//! interrupt per character (RXNEIE), transmitter by TXE then TC interrupt.
//!
//! Shortcuts of this edition (the board-support issue replaces them by DMA2 + a bit timer):
//! * **min_TSDR** is kept by busy-waiting in [`BusPort::start_tx`] on the [`Clock`] until
//!   `min_gap + 1` bit times (+ 1 µs of timestamp truncation) have passed since the
//!   interrupt that took the request's last character (RXNE is raised about half a stop bit
//!   before the line is idle, hence the extra bit). At 1.5 Mbit/s the decision path alone takes longer than 11 bit times (7.3 µs), so
//!   the wait is usually zero; a master-set min_TSDR of 255 bit times busy-waits at most
//!   170 µs in the highest-priority handler (the bus is silent meanwhile: the master waits
//!   for us). At 9.6 kbit/s the same wait would be 26 ms: not acceptable beyond this issue.
//! * **Gaps** are measured between interrupt timestamps; only gaps ≥ T_SYN + one character
//!   are reported (interrupt latency cannot fake those without also overrunning the USART).
//! * **Echo**: the receiver is switched off (CR1.RE = 0) while we drive the bus, so a
//!   transceiver whose receiver stays on does not feed our own response back.
//! * 12 Mbit/s (and in practice 6/3 Mbit/s) cannot work per byte: 0.9 µs per character.
//! * **Masked receiver**: the lower-priority tasks lock the `Node`, which masks USART1, for one
//!   `Application::step` (up to about 6500 instructions, ≈ 68 µs at 96 MHz) or one
//!   `Node::process_acyclic` (README "Benchmark"). With one character of buffering, a request
//!   arriving meanwhile at 1.5 Mbit/s (7.3 µs per character) overruns: the telegram is lost
//!   (counted, resynchronised) and the master repeats it. The DMA receiver does not lose it.

use pbcard::fdl::telegram::MAX_FRAME_LEN;
use pbcard::time::{Baudrate, BitTimes, Duration, Instant};
use stm32f4xx_hal::gpio::{Output, PushPull, PA10, PA8, PA9};
use stm32f4xx_hal::pac::{RCC, USART1};
use stm32f4xx_hal::rcc::{Enable, Reset};

use super::divisor::usart_brr;
use super::{BusPort, Clock, DriverEnable, LineError, LineEvent, TxError, UnsupportedRate};

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

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Tx {
    /// Receiving.
    Idle,
    /// Characters left to hand to the data register (TXE interrupt enabled).
    Sending,
    /// All characters handed over; waiting for the last stop bit (TC interrupt enabled).
    Draining,
}

/// USART1 as a [`BusPort`], one interrupt per character.
pub struct Usart1Port<DE: DriverEnable, C: Clock> {
    usart: USART1,
    _pins: (TxPin, RxPin),
    de: DE,
    clock: C,
    pclk_hz: u32,
    rate: Baudrate,
    tx: Tx,
    tx_buf: [u8; MAX_FRAME_LEN],
    tx_len: usize,
    tx_pos: usize,
    /// Time of the last line activity we know of: a received character (ours or not) or
    /// the end of our own response.
    last_activity: Option<Instant>,
}

impl<DE: DriverEnable, C: Clock> Usart1Port<DE, C> {
    /// Take USART1 (clock enabled and reset here), program 11-bit characters at `rate` and
    /// start receiving with the RXNE interrupt enabled. `pclk_hz` is the APB2 clock.
    /// The NVIC line is unmasked by RTIC for the task bound to USART1.
    pub fn new(
        usart: USART1,
        pins: (TxPin, RxPin),
        mut de: DE,
        clock: C,
        pclk_hz: u32,
        rate: Baudrate,
        rcc: &mut RCC,
    ) -> Result<Self, UnsupportedRate> {
        de.disable();
        USART1::enable(rcc);
        USART1::reset(rcc);
        let mut port = Usart1Port {
            usart,
            _pins: pins,
            de,
            clock,
            pclk_hz,
            rate,
            tx: Tx::Idle,
            tx_buf: [0; MAX_FRAME_LEN],
            tx_len: 0,
            tx_pos: 0,
            last_activity: None,
        };
        // CR2: 1 stop bit, no clock output, no LIN. CR3: no DMA, no flow control, no
        // half-duplex (DE is a GPIO, RX and TX are separate pins on the transceiver).
        port.usart.cr2().write(|w| w.stop().stop1());
        port.usart.cr3().reset();
        port.set_baud(rate)?;
        Ok(port)
    }

    /// The APB2 clock the divisors are computed from.
    pub fn pclk_hz(&self) -> u32 {
        self.pclk_hz
    }

    /// Stop any transmission and put the driver in receive.
    fn abort_tx(&mut self) {
        self.usart.cr1().modify(|_, w| w.txeie().clear_bit().tcie().clear_bit());
        self.de.disable();
        self.tx = Tx::Idle;
        self.tx_len = 0;
        self.tx_pos = 0;
    }

    /// Bit times of idle line between `last_activity` and the character taken at `at`.
    fn idle_before(&self, at: Instant) -> BitTimes {
        let Some(prev) = self.last_activity else {
            return BitTimes(0);
        };
        let bits = self.rate.duration_to_bits(at.saturating_since(prev));
        // Between two interrupt timestamps lies one character (11 bits) plus the gap.
        let threshold = u64::from(BitTimes::TSYN.0 + 2 * BitTimes::CHAR.0);
        if bits >= threshold {
            BitTimes(u32::try_from(bits - u64::from(BitTimes::CHAR.0)).unwrap_or(u32::MAX))
        } else {
            BitTimes(0)
        }
    }
}

impl<DE: DriverEnable, C: Clock> BusPort for Usart1Port<DE, C> {
    fn set_baud(&mut self, rate: Baudrate) -> Result<(), UnsupportedRate> {
        let (over8, brr) = usart_brr(self.pclk_hz, rate.bits_per_second()).ok_or(UnsupportedRate(rate))?;
        self.abort_tx();
        // OVER8 may only change while UE = 0 (RM0383 §19.6.4): disable, program, enable.
        self.usart.cr1().write(|w| w.ue().clear_bit());
        self.usart.brr().write(|w| w.div_mantissa().set(brr >> 4).div_fraction().set((brr & 0xF) as u8));
        self.usart.cr1().write(|w| {
            w.over8().bit(over8);
            w.m().m9(); // 9-bit word: 8 data bits + the parity bit
            w.pce().enabled().ps().even();
            w.rxneie().enabled(); // RXNE and ORE
            w.te().enabled().re().enabled();
            w.ue().enabled()
        });
        // Drop whatever the old rate left in the receiver: read SR then DR clears
        // RXNE/PE/FE/NF/ORE.
        let _ = self.usart.sr().read();
        let _ = self.usart.dr().read();
        self.rate = rate;
        self.last_activity = None;
        Ok(())
    }

    fn baud(&self) -> Baudrate {
        self.rate
    }

    fn start_tx(&mut self, bytes: &[u8], min_gap: BitTimes) -> Result<(), TxError> {
        if self.tx != Tx::Idle {
            return Err(TxError::Busy);
        }
        if bytes.is_empty() || bytes.len() > self.tx_buf.len() {
            return Err(TxError::BadLength);
        }
        self.tx_buf[..bytes.len()].copy_from_slice(bytes);
        self.tx_len = bytes.len();

        // min_TSDR by busy-waiting (shortcut of this edition, see the module comment).
        if let Some(last) = self.last_activity {
            // + 1 bit: RXNE comes about half a stop bit before the line is idle;
            // + 1 µs: `last` and `now()` are both truncated to whole microseconds.
            let not_before = last + self.rate.bits_to_duration(min_gap.0 + 1) + Duration::from_micros(1);
            while self.clock.now() < not_before {}
        }

        // Receiver off while we drive the line (no echo of our own response).
        self.usart.cr1().modify(|_, w| w.re().disabled());
        self.de.enable();
        // Reading SR then writing DR clears a stale TC flag of the previous response.
        let _ = self.usart.sr().read();
        self.usart.dr().write(|w| w.dr().set(u16::from(self.tx_buf[0])));
        self.tx_pos = 1;
        if self.tx_pos < self.tx_len {
            self.tx = Tx::Sending;
            self.usart.cr1().modify(|_, w| w.txeie().enabled());
        } else {
            self.tx = Tx::Draining;
            self.usart.cr1().modify(|_, w| w.tcie().enabled());
        }
        Ok(())
    }

    fn tx_busy(&self) -> bool {
        self.tx != Tx::Idle
    }

    fn poll_event(&mut self) -> Option<LineEvent> {
        loop {
            let sr = self.usart.sr().read();

            // Receiver: RXNE, or ORE without RXNE (both raise the RXNEIE interrupt).
            // Reading DR after SR clears RXNE, PE, FE, NF and ORE.
            if sr.rxne().bit_is_set() || sr.ore().bit_is_set() {
                let at = self.clock.now();
                let word = self.usart.dr().read().dr().bits();
                let err = LineError {
                    parity: sr.pe().bit_is_set(),
                    framing: sr.fe().bit_is_set(),
                    noise: sr.nf().bit_is_set(),
                    overrun: sr.ore().bit_is_set(),
                };
                let idle_before = self.idle_before(at);
                self.last_activity = Some(at);
                if err != LineError::default() {
                    return Some(LineEvent::Error(err));
                }
                // With M = 1 and PCE = 1, bit 8 is the parity bit: strip it.
                return Some(LineEvent::Byte { byte: word as u8, at, idle_before });
            }

            match self.tx {
                Tx::Sending if sr.txe().bit_is_set() => {
                    self.usart.dr().write(|w| w.dr().set(u16::from(self.tx_buf[self.tx_pos])));
                    self.tx_pos += 1;
                    if self.tx_pos >= self.tx_len {
                        // Last character is in the data register: wait for its stop bit.
                        self.tx = Tx::Draining;
                        self.usart.cr1().modify(|_, w| w.txeie().disabled().tcie().enabled());
                    }
                    continue;
                }
                Tx::Draining if sr.tc().bit_is_set() => {
                    // Last stop bit is out: release the bus and listen again.
                    self.de.disable();
                    self.usart.cr1().modify(|_, w| w.tcie().disabled().re().enabled());
                    self.tx = Tx::Idle;
                    self.tx_len = 0;
                    self.tx_pos = 0;
                    self.last_activity = Some(self.clock.now());
                    return Some(LineEvent::TxDone);
                }
                _ => return None,
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Board bring-up (called from the RTIC `init`; the QEMU board has the same shape in `qemu.rs`)
// ---------------------------------------------------------------------------------------------

/// Board name for the boot log.
pub const NAME: &str = "STM32F411 reference board, USART1 per byte";

/// Crystal and clock tree of the reference board (ARCHITECTURE §2).
pub mod clocks {
    /// The crystal.
    pub const HSE_HZ: u32 = 25_000_000;
    /// Core clock.
    pub const SYSCLK_HZ: u32 = 96_000_000;
    /// APB2 (USART1) at the full 96 MHz: 12 Mbit/s divides exactly (OVER8, BRR 1.0).
    pub const PCLK2_HZ: u32 = 96_000_000;
}

/// The line port of this board.
pub type Port = Usart1Port<DePin, super::clock::SysTickClock>;

/// What [`init`] hands to the application.
pub struct Board {
    /// USART1 with the DE pin, receiving.
    pub port: Port,
    /// The microsecond clock (SysTick monotonic).
    pub clock: super::clock::SysTickClock,
}

/// Clock tree (25 MHz HSE → 96 MHz), SysTick monotonic, PA8 DE / PA9 TX / PA10 RX, USART1
/// at `rate` (receiving).
pub fn init(dp: stm32f4xx_hal::pac::Peripherals, syst: cortex_m::peripheral::SYST, rate: Baudrate) -> Board {
    use stm32f4xx_hal::gpio::{GpioExt, PinState, Speed};
    use stm32f4xx_hal::rcc::{self, RccExt};
    use stm32f4xx_hal::time::Hertz;

    // Keep the debug clock running in WFI, so probe-rs / RTT keep working in idle.
    dp.DBGMCU.cr().modify(|_, w| w.dbg_sleep().set_bit());

    let mut rcc = dp.RCC.freeze(
        rcc::Config::hse(Hertz::from_raw(clocks::HSE_HZ))
            .sysclk(Hertz::from_raw(clocks::SYSCLK_HZ))
            .pclk2(Hertz::from_raw(clocks::PCLK2_HZ)),
    );
    let sysclk = rcc.clocks.sysclk().raw();
    let pclk2 = rcc.clocks.pclk2().raw();
    defmt::assert_eq!(sysclk, clocks::SYSCLK_HZ);
    defmt::assert_eq!(pclk2, clocks::PCLK2_HZ);

    let clock = super::clock::start(syst, sysclk);

    let gpioa = dp.GPIOA.split(&mut rcc);
    let de = gpioa.pa8.into_push_pull_output_in_state(PinState::Low).speed(Speed::VeryHigh);
    let tx = gpioa.pa9.into_alternate::<7>().speed(Speed::VeryHigh);
    // Pull-up: the transceiver's RO may float while its receiver is disabled.
    let rx = gpioa.pa10.into_alternate::<7>().internal_pull_up(true);

    let port = match Usart1Port::new(dp.USART1, (tx, rx), DePin(de), clock, pclk2, rate, &mut rcc) {
        Ok(p) => p,
        Err(e) => defmt::panic!("line rate {} not reachable at PCLK2 {=u32} Hz", e.0, pclk2),
    };

    let rate = port.baud();
    let (over8, brr) = usart_brr(pclk2, rate.bits_per_second()).unwrap_or((false, 0));
    defmt::info!(
        "USART1 {} = {=u32} bit/s (OVER8 {=bool}, BRR {=u16:#x}), SYSCLK {=u32} Hz",
        rate,
        super::divisor::actual_baud(pclk2, over8, brr),
        over8,
        brr,
        sysclk
    );
    Board { port, clock }
}
