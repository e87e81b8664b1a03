//! The card firmware: one RTIC 2 application for every board.
//!
//! Wiring only, no protocol decisions (ARCHITECTURE §3): bytes from the PROFIBUS line go
//! into a [`pbcard::node::Node`] (framer → FDL station → DP slave); the response comes back
//! as bytes for the board's [`bsp::BusPort`].
//!
//! | priority | task | does |
//! |---|---|---|
//! | 16 (highest) | `usart1` (USART1 interrupt) | per character: `Node::on_byte` → response; the placeholder drive |
//! | 1 | `housekeeping` (async, every 1 ms) | `Node::poll` (watchdog), events, logs |
//! | – | `idle` | WFI |
//!
//! The board is chosen by cargo feature; only `bsp::board` differs between the builds:
//!
//! | feature | board | build |
//! |---|---|---|
//! | `board-f411` (default) | STM32F411 reference board (`bsp/f411.rs`), logs over RTT | `cargo build --release` |
//! | `qemu` | QEMU netduinoplus2 = STM32F405 (`bsp/qemu.rs`), defmt over semihosting | `cargo build --release --no-default-features --features qemu` |
//! | `bench` (+ `qemu`) | the same, logging TIM2 instruction counts per response | `... --features bench` |
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

#[cfg(all(target_os = "none", feature = "board-f411", feature = "qemu"))]
compile_error!(
    "features `board-f411` and `qemu` are exclusive: build QEMU with `--no-default-features --features qemu`"
);
#[cfg(all(target_os = "none", not(any(feature = "board-f411", feature = "qemu"))))]
compile_error!("choose a board: feature `board-f411` (default) or `qemu`");

#[cfg(all(target_os = "none", feature = "qemu"))]
use defmt_semihosting as _;
#[cfg(all(target_os = "none", feature = "board-f411"))]
use {defmt_rtt as _, panic_probe as _};

/// The PROFIBUS line rate until autobaud exists.
#[cfg(target_os = "none")]
const LINE_RATE: pbcard::time::Baudrate = pbcard::time::Baudrate::B1500k;

/// The station address until the address store exists (126 = the factory default of DP
/// slaves, changeable by Set_Slave_Add).
#[cfg(target_os = "none")]
const STATION_ADDRESS: u8 = 126;

/// **Placeholder** for the drive application (`src/drive`, in progress elsewhere): a loopback
/// "drive" that makes the cyclic data visibly alive and checkable from outside (the QEMU
/// end-to-end test models exactly this). It runs right after each new Data_Exchange; what it
/// stages is served with the next one (pre-staging, one cycle of lag).
///
/// On the first PZD words (offset 0, or 8 behind a PKW area — modules whose Cfg starts with
/// `F3`): STW1 → ZSW1, NSOLL_A → NIST_A ramping by [`Loopback::RAMP`] per Data_Exchange while
/// "operation enabled" (STW1 bits 0–3 set, bit 10 control by PLC), towards 0 otherwise. Every
/// other input byte echoes the output byte at the same position.
#[cfg(target_os = "none")]
#[derive(Debug, Default)]
pub struct Loopback {
    nist: i16,
}

#[cfg(target_os = "none")]
impl Loopback {
    /// NIST_A change per Data_Exchange.
    pub const RAMP: i32 = 0x0200;

    fn on_data_exchange(&mut self, slave: &mut pbcard::dp::DpSlave) {
        let mut buf = [0u8; pbcard::card::MAX_INPUT_LEN];
        let n = slave.input_len().min(buf.len());
        let out = slave.outputs();
        let m = out.len().min(n);
        buf[..m].copy_from_slice(&out[..m]);
        let pzd = if slave.module().is_some_and(|m| m.cfg.first() == Some(&0xF3)) { 8 } else { 0 };
        if out.len() >= pzd + 4 && n >= pzd + 4 {
            let stw1 = u16::from_be_bytes([out[pzd], out[pzd + 1]]);
            let nsoll = i16::from_be_bytes([out[pzd + 2], out[pzd + 3]]);
            let plc = stw1 & 0x0400 != 0;
            let enabled = plc && stw1 & 0x000F == 0x000F;
            let target = if enabled { i32::from(nsoll) } else { 0 };
            let nist = i32::from(self.nist);
            let step = (target - nist).clamp(-Self::RAMP, Self::RAMP);
            self.nist = (nist + step) as i16;
            let zsw1: u16 = if !plc {
                0x0040 // switching on inhibited
            } else {
                let bit = |on: bool, b: u16| if on { 1 << b } else { 0 };
                bit(stw1 & 1 != 0, 0)
                    | bit(stw1 & 0x0007 == 0x0007, 1)
                    | bit(enabled, 2)
                    | bit(stw1 & 0x0002 != 0, 4)
                    | bit(stw1 & 0x0004 != 0, 5)
                    | bit(true, 8)
                    | bit(true, 9)
                    | bit(enabled && i32::from(self.nist) == target, 10)
            };
            buf[pzd..pzd + 2].copy_from_slice(&zsw1.to_be_bytes());
            buf[pzd + 2..pzd + 4].copy_from_slice(&self.nist.to_be_bytes());
        }
        slave.set_inputs(&buf[..n]);
    }
}

#[cfg(target_os = "none")]
#[cfg_attr(feature = "board-f411", rtic::app(device = stm32f4xx_hal::pac, dispatchers = [SPI4, SPI5]))]
#[cfg_attr(feature = "qemu", rtic::app(device = stm32f4xx_hal::pac, dispatchers = [SPI2, SPI3]))]
mod app {
    use crate::bsp::board::{self, Port};
    use crate::bsp::clock::{Mono, SysTickClock};
    use crate::bsp::{BusPort, Clock, LineError, LineEvent, TxError};
    use crate::{Loopback, LINE_RATE, STATION_ADDRESS};

    use pbcard::dp::{DpSlave, Events};
    use pbcard::node::Node;
    use rtic_monotonics::systick::prelude::*;

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

    #[shared]
    struct Shared {
        node: Node,
        line: LineCounters,
    }

    #[local]
    struct Local {
        port: Port,
        clock: SysTickClock,
        drive: Loopback,
    }

    #[init]
    fn init(cx: init::Context) -> (Shared, Local) {
        let board::Board { port, clock } = board::init(cx.device, cx.core.SYST, LINE_RATE);
        defmt::info!("pbcard: station {=u8}, {=str}", STATION_ADDRESS, board::NAME);
        housekeeping::spawn().ok();
        (
            Shared { node: Node::new(DpSlave::new(STATION_ADDRESS)), line: LineCounters::default() },
            Local { port, clock, drive: Loopback::default() },
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
    #[task(binds = USART1, priority = 16, local = [port, drive], shared = [node, line])]
    fn usart1(cx: usart1::Context) {
        // Benchmark: instruction count at handler entry (then after each handled event).
        #[cfg(feature = "bench")]
        let mut entry = board::bench::count();
        let port = cx.local.port;
        let drive = cx.local.drive;
        // Top priority: these locks only mask interrupts (cpsid), which changes nothing here.
        (cx.shared.node, cx.shared.line).lock(|node, line| {
            while let Some(ev) = port.poll_event() {
                match ev {
                    LineEvent::Byte { byte, at, idle_before } => {
                        if idle_before.0 > 0 {
                            node.on_idle(idle_before);
                        }
                        // min_TSDR as it was before this request (a Set_Prm that changes it
                        // applies from the next response on).
                        let min_tsdr = node.min_tsdr();
                        let dx_before = node.slave().stats().data_exchanges;
                        if let Some(resp) = node.on_byte(at, byte) {
                            #[cfg(feature = "bench")]
                            let resp_len = resp.len();
                            let started = port.start_tx(resp, min_tsdr);
                            match started {
                                Ok(()) => line.responses = line.responses.wrapping_add(1),
                                Err(TxError::Busy) => line.tx_busy = line.tx_busy.wrapping_add(1),
                                Err(TxError::BadLength) => line.tx_bad_length = line.tx_bad_length.wrapping_add(1),
                            }
                            // After the measurement: request length, response length, instructions
                            // from the handler entry (of the request's last byte) to the first
                            // response byte written to DR.
                            #[cfg(feature = "bench")]
                            if started.is_ok() {
                                defmt::info!(
                                    "BENCH req {=usize} resp {=usize} instr {=u32}",
                                    node.framer().frame().len(),
                                    resp_len,
                                    port.tx_first_count().wrapping_sub(entry)
                                );
                            }
                        }
                        if node.slave().stats().data_exchanges != dx_before {
                            drive.on_data_exchange(node.slave_mut());
                        }
                    }
                    LineEvent::Error(e) => {
                        // The telegram this character belonged to is lost: the framer drops it
                        // and resynchronises on the next start delimiter.
                        line.count(e);
                        node.on_line_error();
                    }
                    LineEvent::TxDone => {}
                }
                #[cfg(feature = "bench")]
                {
                    entry = board::bench::count();
                }
            }
        });
    }

    /// Timers of the DP slave and the log, every millisecond.
    #[task(priority = 1, shared = [node, line], local = [clock])]
    async fn housekeeping(mut cx: housekeeping::Context) {
        const STATS_PERIOD_MS: u32 = 10_000;
        let clock = *cx.local.clock;
        let mut next = Mono::now();
        let mut ms: u32 = 0;
        let mut last_stats = None;
        let state = cx.shared.node.lock(|n| n.slave().state());
        defmt::info!("DP state {}", state);
        loop {
            next += 1.millis();
            Mono::delay_until(next).await;
            let now = clock.now();

            // Short lock: it masks the USART1 interrupt (ceiling = highest priority).
            let (events, state, master, address) = cx.shared.node.lock(|n| {
                let ev = n.poll(now);
                let s = n.slave();
                (ev, s.state(), s.master_address(), s.address())
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
                    // Node::poll has reset the FCB memory of the old address. Persisting the
                    // address is the address-store issue.
                    defmt::warn!("station address changed to {=u8} (not stored yet)", address);
                }
                defmt::debug!("DP events {=u16:#06x}", events.bits());
            }

            ms = ms.wrapping_add(1);
            if ms.is_multiple_of(STATS_PERIOD_MS) {
                let line = cx.shared.line.lock(|l| *l);
                let (framer, station, dp) =
                    cx.shared.node.lock(|n| (n.framer().stats(), n.station().stats(), n.slave().stats()));
                let stats = (line, framer, station, dp);
                if last_stats != Some(stats) {
                    defmt::info!("line {}, framer {}, station {}, dp {}", line, framer, station, dp);
                    last_stats = Some(stats);
                }
            }
        }
    }
}
