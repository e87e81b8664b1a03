//! The card firmware: an RTIC 2 application on the STM32F411 reference board.
//!
//! Wiring only, no protocol decisions (ARCHITECTURE §3): bytes from the PROFIBUS line go
//! through [`pbcard::fdl::framer::Framer`] into [`pbcard::fdl::station::Station`] and the
//! [`pbcard::dp::DpSlave`]; the response comes back as bytes for the [`bsp::BusPort`].
//!
//! | priority | task | does |
//! |---|---|---|
//! | 16 (highest) | `usart1` (USART1 interrupt) | per character: framer → station → DP slave → response |
//! | 1 | `housekeeping` (async, every 1 ms) | `DpSlave::poll` (watchdog), events, logs |
//! | – | `idle` | WFI |
//!
//! This edition is interrupt-per-character at a fixed rate ([`LINE_RATE`]); DMA, the bit
//! timer and autobaud come with the board-support issue (see `bsp/f411.rs` for the
//! shortcuts this implies, notably min_TSDR by busy-waiting).
//!
//! On the host this file compiles to an empty `main` (the bin target is firmware only).
#![cfg_attr(target_os = "none", no_std)]
#![cfg_attr(target_os = "none", no_main)]

#[cfg(not(target_os = "none"))]
fn main() {}

#[cfg(target_os = "none")]
mod bsp;

#[cfg(target_os = "none")]
use {defmt_rtt as _, panic_probe as _};

/// The PROFIBUS line rate until autobaud exists.
#[cfg(target_os = "none")]
const LINE_RATE: pbcard::time::Baudrate = pbcard::time::Baudrate::B1500k;

/// The station address until the address store exists (126 = the factory default of DP
/// slaves, changeable by Set_Slave_Add).
#[cfg(target_os = "none")]
const STATION_ADDRESS: u8 = 126;

/// Crystal and clock tree of the reference board (ARCHITECTURE §2).
#[cfg(target_os = "none")]
mod clocks {
    pub const HSE_HZ: u32 = 25_000_000;
    pub const SYSCLK_HZ: u32 = 96_000_000;
    /// APB2 (USART1) at the full 96 MHz: 12 Mbit/s divides exactly (OVER8, BRR 1.0).
    pub const PCLK2_HZ: u32 = 96_000_000;
}

#[cfg(target_os = "none")]
#[rtic::app(device = stm32f4xx_hal::pac, dispatchers = [SPI4, SPI5])]
mod app {
    use crate::bsp::clock::{self, Mono, SysTickClock};
    use crate::bsp::divisor;
    use crate::bsp::f411::{DePin, Usart1Port};
    use crate::bsp::{BusPort, Clock, LineError, LineEvent, TxError};
    use crate::{clocks, LINE_RATE, STATION_ADDRESS};

    use pbcard::dp::{DpSlave, Events};
    use pbcard::fdl::framer::{Framer, Push};
    use pbcard::fdl::station::Station;
    use pbcard::time::BitTimes;
    use rtic_monotonics::systick::prelude::*;
    use stm32f4xx_hal::gpio::{GpioExt, PinState, Speed};
    use stm32f4xx_hal::rcc::{self, RccExt};
    use stm32f4xx_hal::time::Hertz;

    type Port = Usart1Port<DePin, SysTickClock>;

    /// Line-level counters (shown in the log; later in the DPM status block).
    #[derive(Debug, Clone, Copy, Default, PartialEq, Eq, defmt::Format)]
    pub struct LineCounters {
        pub parity: u32,
        pub framing: u32,
        pub noise: u32,
        pub overrun: u32,
        /// A response was due while the previous one was still being sent.
        pub tx_busy: u32,
        /// The station returned a response the port could not take (length).
        pub tx_bad_length: u32,
        pub responses: u32,
    }

    impl LineCounters {
        fn count(&mut self, e: LineError) {
            let inc = |c: &mut u32, on: bool| *c = c.wrapping_add(u32::from(on));
            inc(&mut self.parity, e.parity);
            inc(&mut self.framing, e.framing);
            inc(&mut self.noise, e.noise);
            inc(&mut self.overrun, e.overrun);
        }
    }

    /// The layer-2 machinery driven by the USART interrupt.
    pub struct Link {
        framer: Framer,
        station: Station,
        line: LineCounters,
    }

    #[shared]
    struct Shared {
        slave: DpSlave,
        link: Link,
    }

    #[local]
    struct Local {
        port: Port,
        clock: SysTickClock,
    }

    #[init]
    fn init(cx: init::Context) -> (Shared, Local) {
        let dp = cx.device;
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

        let clock = clock::start(cx.core.SYST, sysclk);

        let gpioa = dp.GPIOA.split(&mut rcc);
        let de = gpioa.pa8.into_push_pull_output_in_state(PinState::Low).speed(Speed::VeryHigh);
        let tx = gpioa.pa9.into_alternate::<7>().speed(Speed::VeryHigh);
        // Pull-up: the transceiver's RO may float while its receiver is disabled.
        let rx = gpioa.pa10.into_alternate::<7>().internal_pull_up(true);

        let port = match Usart1Port::new(dp.USART1, (tx, rx), DePin(de), clock, pclk2, LINE_RATE, &mut rcc) {
            Ok(p) => p,
            Err(e) => defmt::panic!("line rate {} not reachable at PCLK2 {=u32} Hz", e.0, pclk2),
        };

        let rate = port.baud();
        let (over8, brr) = divisor::usart_brr(pclk2, rate.bits_per_second()).unwrap_or((false, 0));
        defmt::info!(
            "pbcard: station {=u8}, USART1 {} = {=u32} bit/s (OVER8 {=bool}, BRR {=u16:#x}), SYSCLK {=u32} Hz",
            STATION_ADDRESS,
            rate,
            divisor::actual_baud(pclk2, over8, brr),
            over8,
            brr,
            sysclk
        );

        housekeeping::spawn().ok();

        (
            Shared {
                slave: DpSlave::new(STATION_ADDRESS),
                link: Link { framer: Framer::new(), station: Station::new(), line: LineCounters::default() },
            },
            Local { port, clock },
        )
    }

    #[idle]
    fn idle(_: idle::Context) -> ! {
        loop {
            // The default RTIC idle spins; sleep instead (also keeps QEMU `-icount` fast).
            cortex_m::asm::wfi();
        }
    }

    /// The PROFIBUS line, one interrupt per character (and per TXE/TC while responding).
    #[task(binds = USART1, priority = 16, local = [port], shared = [slave, link])]
    fn usart1(cx: usart1::Context) {
        let port = cx.local.port;
        // Top priority: these locks only mask interrupts (cpsid), which changes nothing here.
        (cx.shared.slave, cx.shared.link).lock(|slave, link| {
            while let Some(ev) = port.poll_event() {
                match ev {
                    LineEvent::Byte { byte, at, idle_before } => {
                        if idle_before.0 > 0 {
                            link.framer.idle(idle_before);
                        }
                        if let Push::Frame(_) = link.framer.push(byte) {
                            // min_TSDR as it was before this request (a Set_Prm that
                            // changes it applies from the next response on).
                            let min_tsdr = slave.min_tsdr();
                            if let Some(resp) = link.station.on_frame(at, link.framer.frame(), slave) {
                                match port.start_tx(resp, min_tsdr) {
                                    Ok(()) => link.line.responses = link.line.responses.wrapping_add(1),
                                    Err(TxError::Busy) => link.line.tx_busy = link.line.tx_busy.wrapping_add(1),
                                    Err(TxError::BadLength) => {
                                        link.line.tx_bad_length = link.line.tx_bad_length.wrapping_add(1)
                                    }
                                }
                            }
                        }
                    }
                    LineEvent::Error(e) => {
                        // The telegram this character belonged to is lost: drop what the
                        // framer holds (it resynchronises on the next start delimiter).
                        link.line.count(e);
                        link.framer.idle(BitTimes(0));
                    }
                    LineEvent::TxDone => {}
                }
            }
        });
    }

    /// Timers of the DP slave and the log, every millisecond.
    #[task(priority = 1, shared = [slave, link], local = [clock])]
    async fn housekeeping(mut cx: housekeeping::Context) {
        const STATS_PERIOD_MS: u32 = 10_000;
        let clock = *cx.local.clock;
        let mut next = Mono::now();
        let mut ms: u32 = 0;
        let mut last_stats = None;
        let state = cx.shared.slave.lock(|s| s.state());
        defmt::info!("DP state {}", state);
        loop {
            next += 1.millis();
            Mono::delay_until(next).await;
            let now = clock.now();

            // Short lock: it masks the USART1 interrupt (ceiling = highest priority).
            let (events, state, master, address) = cx.shared.slave.lock(|s| {
                s.poll(now);
                (s.take_events(), s.state(), s.master_address(), s.address())
            });
            if !events.is_empty() {
                if events.contains(Events::STATE_CHANGED) {
                    match master {
                        Some(m) => defmt::info!("DP state {}, master {=u8}", state, m),
                        None => defmt::info!("DP state {}", state),
                    }
                }
                if events.contains(Events::WATCHDOG_EXPIRED) {
                    defmt::warn!("DP watchdog expired: outputs cleared");
                }
                if events.contains(Events::ADDRESS_CHANGED) {
                    // The FCB memory belongs to the old address (Station::reset). Persisting
                    // the address is the address-store issue.
                    cx.shared.link.lock(|l| l.station.reset());
                    defmt::warn!("station address changed to {=u8} (not stored yet)", address);
                }
                defmt::debug!("DP events {=u16:#06x}", events.bits());
            }

            ms = ms.wrapping_add(1);
            if ms.is_multiple_of(STATS_PERIOD_MS) {
                let link = cx.shared.link.lock(|l| (l.line, l.framer.stats(), l.station.stats()));
                let dp = cx.shared.slave.lock(|s| s.stats());
                let stats = (link, dp);
                if last_stats != Some(stats) {
                    defmt::info!("line {}, framer {}, station {}, dp {}", link.0, link.1, link.2, dp);
                    last_stats = Some(stats);
                }
            }
        }
    }
}
