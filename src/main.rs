//! The card firmware: one RTIC 2 application for every board.
//!
//! Wiring only, no protocol decisions (ARCHITECTURE §3): bytes from the PROFIBUS line go
//! into a [`pbcard::node::Node`] (framer → FDL station → DP slave, DP-V1); the response comes
//! back as bytes for the board's [`bsp::BusPort`]. Behind the node sits
//! [`pbcard::app::Application`]: the first DPM image, the card-side link and the simulated
//! drive (`pbcard::drive::SimDrive`, PROFIdrive state machine and ramp) — the same
//! application as the soft slave's. On the F411 the simulated drive is a placeholder until
//! the SPI transport of the DPM to the drive's control board exists (issue 7): then the
//! housekeeping task runs `Node::poll`, `Link::publish`, the transfer and `Link::collect`
//! instead of `Application::step`.
//!
//! | priority | task | does |
//! |---|---|---|
//! | 16 (highest) | `usart1` (USART1 interrupt) | per character: `Node::on_byte` → response; after a Data_Exchange spawns `app_step`, after a DP-V1 request `acyclic` |
//! | 8 | `acyclic` (software task) | `Node::process_acyclic`: DP-V1 records at slot 0, PROFIdrive parameter access (card PNUs, then the drive's through the DPM parameter mailbox, `Application::parameters`; a job waiting for the drive is retried on the next spawn) |
//! | 1 | `housekeeping` (async, every 1 ms) | `Application::step` (node timers, DPM status/outputs, drive, inputs), events, logs |
//! | 1 | `app_step` (software task) | one `Application::step` right after a Data_Exchange (the drive sees new outputs at once) |
//! | – | `idle` | WFI |
//!
//! The `Node` is shared by all of them; the lower tasks lock it (which masks USART1) only for
//! one `Application::step` or one `Node::process_acyclic` call — still up to ≈ 68 µs at
//! 96 MHz for the step (the `bench` build logs the counts, README "Benchmark"), longer than
//! the per-character receiver of this edition can bridge at 1.5 Mbit/s (`bsp/f411.rs`).
//!
//! The board is chosen by cargo feature; only `bsp::board` differs between the builds:
//!
//! | feature | board | build |
//! |---|---|---|
//! | `board-f411` (default) | STM32F411 reference board (`bsp/f411.rs`), logs over RTT | `cargo build --release` |
//! | `qemu` | QEMU netduinoplus2 = STM32F405 (`bsp/qemu.rs`), defmt over semihosting | `cargo build --release --no-default-features --features qemu` |
//! | `bench` (+ `qemu`) | the same, logging TIM2 instruction counts per response and under the Node lock | `... --features bench` |
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

/// The PROFIBUS line rate until autobaud exists (also shown as P0963 / PNU 963).
#[cfg(target_os = "none")]
const LINE_RATE: pbcard::time::Baudrate = pbcard::time::Baudrate::B1500k;

/// The station address until the address store is wired (126 = the factory default of DP
/// slaves, changeable at run time by Set_Slave_Add). A build can choose another one:
/// `PBCARD_STATION_ADDRESS=5 bash scripts/qemu.sh build` (0..=125; anything else → 126).
#[cfg(target_os = "none")]
const STATION_ADDRESS: u8 = station_address(option_env!("PBCARD_STATION_ADDRESS"));

/// Parse a decimal station address at compile time; 126 when absent or invalid.
#[cfg(target_os = "none")]
const fn station_address(s: Option<&str>) -> u8 {
    let Some(s) = s else { return pbcard::card::DEFAULT_ADDRESS };
    let b = s.as_bytes();
    if b.is_empty() || b.len() > 3 {
        return pbcard::card::DEFAULT_ADDRESS;
    }
    let mut v: u32 = 0;
    let mut i = 0;
    while i < b.len() {
        if !b[i].is_ascii_digit() {
            return pbcard::card::DEFAULT_ADDRESS;
        }
        v = v * 10 + (b[i] - b'0') as u32;
        i += 1;
    }
    if v > 125 {
        pbcard::card::DEFAULT_ADDRESS
    } else {
        v as u8
    }
}

#[cfg(target_os = "none")]
#[cfg_attr(feature = "board-f411", rtic::app(device = stm32f4xx_hal::pac, dispatchers = [SPI4, SPI5]))]
#[cfg_attr(feature = "qemu", rtic::app(device = stm32f4xx_hal::pac, dispatchers = [SPI2, SPI3]))]
mod app {
    use crate::bsp::board::{self, Port};
    use crate::bsp::clock::{Mono, SysTickClock};
    use crate::bsp::{BusPort, Clock, LineError, LineEvent, TxError};
    use crate::{LINE_RATE, STATION_ADDRESS};

    use pbcard::app::Application;
    use pbcard::dp::{DpSlave, DpState, Events};
    use pbcard::dpm::CommState;
    use pbcard::drive::profidrive::DriveState;
    use pbcard::drive::DriveConfig;
    use pbcard::led::{LedInputs, Leds};
    use pbcard::node::Node;
    use rtic::Mutex;
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

    /// What the log reports after a step, read while the node was locked.
    struct NodeView {
        events: Events,
        state: DpState,
        master: Option<u8>,
        address: u8,
        acyclic_work: bool,
        /// Requests addressed to us so far (FDL station counter).
        requests: u32,
        watchdog: Option<pbcard::time::Duration>,
    }

    /// The application behind the DPM (image, link, simulated drive) and what the log has
    /// shown of it.
    pub struct Drive {
        app: Application,
        clock: SysTickClock,
        comm: Option<CommState>,
        state: DriveState,
        led_requests: u32,
        led_last_frame: Option<pbcard::time::Instant>,
        led_was_dx: bool,
        led_shown: Option<Leds>,
        /// Largest instruction count of one `Application::step` under the Node lock.
        #[cfg(feature = "bench")]
        max_step: u32,
    }

    impl Drive {
        fn new(clock: SysTickClock) -> Self {
            let mut app = Application::new(DriveConfig::DEFAULT);
            app.set_baudrate(Some(LINE_RATE));
            let state = app.drive().state();
            Drive {
                app,
                clock,
                comm: None,
                state,
                led_requests: 0,
                led_last_frame: None,
                led_was_dx: false,
                led_shown: None,
                #[cfg(feature = "bench")]
                max_step: 0,
            }
        }

        /// One [`Application::step`] now (node timers, DPM, drive, inputs), the node locked
        /// for just that call; then the log of what changed.
        fn step(&mut self, node: &mut impl Mutex<T = Node>) {
            let now = self.clock.now();
            let app = &mut self.app;
            #[cfg(feature = "bench")]
            let mut instr = 0u32;
            // Masks the USART1 interrupt (ceiling = highest priority) for one step.
            let v = node.lock(|n| {
                #[cfg(feature = "bench")]
                let t0 = board::bench::count();
                let events = app.step(now, n);
                #[cfg(feature = "bench")]
                {
                    instr = board::bench::count().wrapping_sub(t0);
                }
                let s = n.slave();
                NodeView {
                    events,
                    state: s.state(),
                    master: s.master_address(),
                    address: s.address(),
                    acyclic_work: n.has_acyclic_work(),
                    requests: n.station().stats().requests,
                    watchdog: s.watchdog_time(),
                }
            });
            #[cfg(feature = "bench")]
            if instr > self.max_step {
                self.max_step = instr;
                defmt::info!("LOCK app.step {=u32} instructions (new maximum)", instr);
            }
            // The ISR spawns the DP-V1 task; this catches a request that arrived while the
            // task was finishing (its spawn failed then).
            if v.acyclic_work {
                acyclic::spawn().ok();
            }
            self.log(&v);
            self.leds(now, &v);
        }

        /// The PS / BS / FS LED pattern (OPTE3/E5 §4.3, `pbcard::led`); logged when it
        /// changes. Driving the board's LED pins is the board-support issue's.
        fn leds(&mut self, now: pbcard::time::Instant, v: &NodeView) {
            if v.requests != self.led_requests {
                self.led_requests = v.requests;
                self.led_last_frame = Some(now);
            }
            let dx = v.state == DpState::DataExch;
            if dx {
                self.led_was_dx = true;
            }
            let inputs = LedInputs {
                data_exchange: dx,
                // The simulated drive is part of the firmware: always there.
                drive_active: true,
                card_fault: false,
                last_frame_for_us: self.led_last_frame,
                watchdog: v.watchdog,
                lost_after_data_exchange: self.led_was_dx && !dx,
            };
            let leds = pbcard::led::indicate(now, &inputs);
            if self.led_shown != Some(leds) {
                defmt::info!("LEDs: PS {} BS {} FS {}", leds.ps, leds.bs, leds.fs);
                self.led_shown = Some(leds);
            }
        }

        fn log(&mut self, v: &NodeView) {
            let events = v.events;
            if events.contains(Events::STATE_CHANGED) {
                match v.master {
                    Some(m) => defmt::info!("DP state {}, master {=u8}", v.state, m),
                    None => defmt::info!("DP state {}", v.state),
                }
            }
            if events.contains(Events::WATCHDOG_EXPIRED) {
                defmt::warn!("DP watchdog expired: outputs cleared");
            }
            if events.contains(Events::ADDRESS_CHANGED) {
                // Node::poll has reset the FCB memory of the old address. Persisting the
                // address is the address-store issue.
                defmt::warn!("station address changed to {=u8} (not stored yet)", v.address);
            }
            if !events.is_empty() {
                defmt::debug!("DP events {=u16:#06x}", events.bits());
            }
            // What the drive sees: P0740 in the DPM status block, its own state.
            if let Ok(status) = self.app.dpm().status() {
                if self.comm != Some(status.comm) {
                    defmt::info!("P0740 = {=u8} ({})", status.comm.code(), status.comm);
                    self.comm = Some(status.comm);
                }
            }
            let drive = self.app.drive();
            if drive.state() != self.state {
                defmt::info!(
                    "drive: {=str} -> {=str} (STW1 {=u16:#06x}, ZSW1 {=u16:#06x}, NSOLL_A {=i16}, NIST_A {=i16})",
                    self.state.name(),
                    drive.state().name(),
                    drive.control_word(),
                    drive.status_word(),
                    drive.setpoint(),
                    drive.actual_speed()
                );
                self.state = drive.state();
            }
        }
    }

    #[shared]
    struct Shared {
        node: Node,
        line: LineCounters,
        drive: Drive,
        // DPM SPI transport: see the block "DPM SPI transport" below.
        spi: DpmSpiPort,
        spi_slave: pbcard::dpm::spi::SpiSlave,
    }

    #[local]
    struct Local {
        port: Port,
        acyclic_clock: SysTickClock,
    }

    #[init]
    fn init(cx: init::Context) -> (Shared, Local) {
        let board::Board { port, clock } = board::init(cx.device, cx.core.SYST, LINE_RATE);
        defmt::info!("pbcard: station {=u8}, {=str}", STATION_ADDRESS, board::NAME);
        defmt::info!(
            "drive: simulated behind the DPM (PROFIdrive STW1/ZSW1, NSOLL_A/NIST_A 0x4000 = 100 %, ramp {=u64} ms)",
            DriveConfig::DEFAULT.ramp_time.as_millis()
        );
        #[cfg(feature = "board-f411")]
        defmt::warn!("drive: the simulated drive stands in for the DPM transport to the drive (issue 7)");
        let mut node = Node::new(DpSlave::new(STATION_ADDRESS));
        node.set_baudrate(Some(LINE_RATE));
        housekeeping::spawn().ok();
        let spi = start_dpm_spi();
        (
            Shared {
                node,
                line: LineCounters::default(),
                drive: Drive::new(clock),
                spi,
                spi_slave: pbcard::dpm::spi::SpiSlave::new(),
            },
            Local { port, acyclic_clock: clock },
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
    #[task(binds = USART1, priority = 16, local = [port], shared = [node, line])]
    fn usart1(cx: usart1::Context) {
        // Benchmark: instruction count at handler entry (then after each handled event).
        #[cfg(feature = "bench")]
        let mut entry = board::bench::count();
        let port = cx.local.port;
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
                            // A DP-V1 request was acknowledged; the middle-priority task works
                            // on it (if it is still running, the spawn fails and the next
                            // housekeeping step spawns it again).
                            if node.has_acyclic_work() {
                                acyclic::spawn().ok();
                            }
                        }
                        if node.slave().stats().data_exchanges != dx_before {
                            // New outputs: the drive sees them now, not at the next millisecond.
                            app_step::spawn().ok();
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

    /// DP-V1: data records at slot 0 (PROFIdrive parameter access, WEG record 48) for MSAC_C1
    /// and MSAC_C2. The master polls until the response is there ("not ready" meanwhile). The
    /// drive's parameters go through the DPM parameter mailbox (`Application::parameters`);
    /// a job still waiting for the drive keeps `Node::has_acyclic_work` true, so the
    /// housekeeping step spawns this task again.
    #[task(priority = 8, shared = [node, drive], local = [acyclic_clock])]
    async fn acyclic(cx: acyclic::Context) {
        let now = cx.local.acyclic_clock.now();
        let acyclic::SharedResources { mut node, mut drive, .. } = cx.shared;
        #[cfg(feature = "bench")]
        let mut instr = 0u32;
        // The application (priority ceiling 8) for the DPM mailbox, the node (masks the
        // USART1 interrupt) for one pass over the waiting requests.
        drive.lock(|d| {
            let mut params = d.app.parameters(now);
            node.lock(|n| {
                #[cfg(feature = "bench")]
                let t0 = board::bench::count();
                n.process_acyclic(now, &mut params);
                #[cfg(feature = "bench")]
                {
                    instr = board::bench::count().wrapping_sub(t0);
                }
            });
        });
        #[cfg(feature = "bench")]
        defmt::info!("LOCK process_acyclic {=u32} instructions", instr);
    }

    /// One application step right after a Data_Exchange.
    #[task(priority = 1, shared = [node, drive])]
    async fn app_step(cx: app_step::Context) {
        let app_step::SharedResources { mut node, mut drive, .. } = cx.shared;
        // Same priority as housekeeping: this lock costs nothing.
        drive.lock(|d| d.step(&mut node));
    }

    /// The application and the node's timers every millisecond, and the log.
    #[task(priority = 1, shared = [node, line, drive])]
    async fn housekeeping(cx: housekeeping::Context) {
        const STATS_PERIOD_MS: u32 = 10_000;
        let housekeeping::SharedResources { mut node, mut line, mut drive, .. } = cx.shared;
        let mut next = Mono::now();
        let mut ms: u32 = 0;
        let mut last_stats = None;
        let state = node.lock(|n| n.slave().state());
        defmt::info!("DP state {}", state);
        loop {
            next += 1.millis();
            Mono::delay_until(next).await;
            drive.lock(|d| d.step(&mut node));

            ms = ms.wrapping_add(1);
            if ms.is_multiple_of(STATS_PERIOD_MS) {
                let line = line.lock(|l| *l);
                let (framer, station, dp) = node.lock(|n| (n.framer().stats(), n.station().stats(), n.slave().stats()));
                let link = drive.lock(|d| d.app.link().stats());
                let stats = (line, framer, station, dp, link);
                if last_stats != Some(stats) {
                    defmt::info!("line {}, framer {}, station {}, dp {}, dpm link {}", line, framer, station, dp, link);
                    last_stats = Some(stats);
                }
            }
        }
    }

    // ---------------------------------------------------------------------------------------
    // DPM SPI transport (issue 7 item 4; board-f411 only). The drive's control board is SPI
    // master; `bsp/spi.rs` moves the bytes, `pbcard::dpm::spi::SpiSlave` decides. NSS rising
    // (EXTI15_10, short, priority 12 — below USART1) re-arms the DMA and hands the received
    // frame to `spi_frame` (priority 1), which applies it to the application's image under
    // the `drive` lock and stages the reply for the next transaction. `spi_irq` keeps the IRQ
    // line in step with the card's writes. While the simulated drive still stands in for the
    // control board (`Application::step`), it writes the host blocks too: switching the
    // housekeeping step to publish / collect only is the lead's wiring step.
    // ---------------------------------------------------------------------------------------

    /// The SPI port (QEMU: none; its transport is in-process, `pbcard::dpm::spi::Loopback`).
    #[cfg(feature = "board-f411")]
    type DpmSpiPort = crate::bsp::spi::SpiPort;
    /// The SPI port (QEMU: none; its transport is in-process, `pbcard::dpm::spi::Loopback`).
    #[cfg(not(feature = "board-f411"))]
    type DpmSpiPort = NoSpiPort;
    /// QEMU has no SPI port.
    #[cfg(not(feature = "board-f411"))]
    pub struct NoSpiPort;
    /// A received SPI frame (QEMU: none).
    #[cfg(feature = "board-f411")]
    type DpmSpiFrame = crate::bsp::spi::Frame;
    /// A received SPI frame (QEMU: none).
    #[cfg(not(feature = "board-f411"))]
    type DpmSpiFrame = ();

    /// Bring up the SPI port and start the IRQ task (from `init`).
    #[cfg(feature = "board-f411")]
    fn start_dpm_spi() -> DpmSpiPort {
        spi_irq::spawn().ok();
        crate::bsp::spi::init()
    }
    #[cfg(not(feature = "board-f411"))]
    fn start_dpm_spi() -> DpmSpiPort {
        NoSpiPort
    }

    /// NSS rising: the end of one SPI transaction.
    #[cfg(feature = "board-f411")]
    #[task(binds = EXTI15_10, priority = 12, shared = [spi])]
    fn spi_nss(mut cx: spi_nss::Context) {
        if let Some(frame) = cx.shared.spi.lock(|p| p.on_nss_rise()) {
            if let Err(frame) = spi_frame::spawn(frame) {
                cx.shared.spi.lock(|p| p.drop_frame(frame));
            }
        }
    }

    /// One received SPI frame against the DPM image; the reply goes out in the next
    /// transaction.
    #[cfg(feature = "board-f411")]
    #[task(priority = 1, shared = [spi, spi_slave, drive])]
    async fn spi_frame(cx: spi_frame::Context, frame: DpmSpiFrame) {
        let spi_frame::SharedResources { mut spi, mut spi_slave, mut drive, .. } = cx.shared;
        let Some(reply) = spi.lock(|p| p.reply_buffer()) else {
            spi.lock(|p| p.drop_frame(frame));
            return;
        };
        // The image is locked for one `handle` (masks the DP-V1 task, not USART1).
        let (len, irq) = (&mut spi_slave, &mut drive).lock(|slave, d| {
            let dpm = d.app.dpm_mut();
            let len = slave.handle(frame.bytes(), dpm, reply);
            (len, slave.irq(dpm))
        });
        spi.lock(|p| {
            p.reply_ready(reply, len);
            p.give_back(frame);
            p.set_irq(irq);
        });
    }

    /// The IRQ line to the drive every millisecond (the card writes its blocks in the
    /// housekeeping step), and the transport's counters in the log when they change.
    #[cfg(feature = "board-f411")]
    #[task(priority = 1, shared = [spi, spi_slave, drive])]
    async fn spi_irq(cx: spi_irq::Context) {
        let spi_irq::SharedResources { mut spi, mut spi_slave, mut drive, .. } = cx.shared;
        let mut ms: u32 = 0;
        let mut shown = None;
        loop {
            Mono::delay(1.millis()).await;
            let (irq, proto) = (&mut spi_slave, &mut drive).lock(|s, d| (s.irq(d.app.dpm()), s.stats()));
            let port = spi.lock(|p| {
                p.set_irq(irq);
                p.stats()
            });
            ms = ms.wrapping_add(1);
            if ms.is_multiple_of(10_000) && shown != Some((port, proto)) {
                defmt::info!("dpm spi port {}, protocol {}", port, proto);
                shown = Some((port, proto));
            }
        }
    }
}
