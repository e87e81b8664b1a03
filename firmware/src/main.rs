//! The card firmware: one RTIC 2 application for every board.
//!
//! Wiring only, no protocol decisions (ARCHITECTURE §3): bytes from the PROFIBUS line go
//! into a [`pbcard::node::Node`] (framer → FDL station → DP slave, DP-V1); the response comes
//! back as bytes for the board's line port (the board contract `pbcard::phy::port`, README
//! "Hardware"). Behind the node sits the card ([`CardApp`]): the F411 build without `sim-drive` runs [`pbcard::app::Card`] alone (the
//! DPM image, the card-side link, the profile layer; the drive's control board is the SPI
//! master and writes the host blocks, block "DPM SPI transport" below; nothing of
//! `pbcard_sim::drive` is linked, `scripts/footprint.sh`). QEMU and the F411 with the `sim-drive`
//! feature run the bench [`pbcard_sim::bench::Application`]: the same card with the simulated
//! drive (`pbcard_sim::drive::SimDrive`, PROFIdrive state machine and ramp) over the in-process
//! SPI frames — the same application as the soft slave's.
//!
//! | priority | task | does |
//! |---|---|---|
//! | 16 (highest) | F411: `usart1` (USART1: IDLE, PE/FE/NF/ORE, TC; pended by `core_step` for a deferred answer), `tim5` (TIM5 compares: T_SYN proof, delayed response start; the command mailbox: flash silence / restart, rate switch) | the DMA line (`crates/bsp/src/f411.rs`) with the fast path (`pbcard::fast::FastPath`): every telegram cut at IDLE through `FastPath::on_frame`, its answer by `respond` (min_TSDR from the staging, min/max_TSDR by TIM5), a deferred one when the core has it; each telegram classified for the rate control (`phy::rate_link`: the line's gate, counts, switches); release DE on TC; never touches the `Node` |
//! | 16 | QEMU: `usart1` (USART1 interrupt per character) | the per-byte line with the same fast path (`crates/bsp/src/qemu.rs` `on_usart_fast`) → response after the quiet window |
//! | 15 | both: `core_step` (bound to the unused I2C1_EV interrupt, pended by `usart1` and by every task that changed the node) | `CoreLink`: republish the staging, `Node::on_frame` for every queued telegram, the staging after each; a deferred (DP-V1) answer back to the line (pends USART1); after a Data_Exchange spawns `app_step`, after a DP-V1 request `acyclic` |
//! | 11 | F411: `spi_frame` (software task, spawned by `spi_nss` at 12 on NSS rising) | one DPM SPI transaction against its own image (`dpm::spi::WireImage`), the reply armed for the next one |
//! | 8 | `acyclic` (software task) | `Node::process_acyclic`: DP-V1 records at slot 0, PROFIdrive parameter access (the application's `Application::records`: card PNUs, then the drive's through the DPM parameter mailbox, `Application::parameters`; a job waiting for the drive is retried on the next spawn) |
//! | 1 | `housekeeping` (async, every 1 ms) | the application step with two short Node locks (`Application::snapshot`: node timers + a copy; unlocked: DPM publish, drive, profile cycle, PKW, DRIVE_CMD; `Application::apply`: diagnosis + input image), then pends `core_step` (staging); STATUS.CORRUPT_FRAMES from the line's atomics, events, logs; F411: the autobaud machine (`RateKeeper::poll`: the line's counts, the timers, the gate's verdict; a rate switch asked of the line through `board::switch_rate`, no lock), LEDs, IWDG, address journal (line silence / restart through the mailbox) |
//! | 1 | `app_step` (software task) | one application step (as above) right after a Data_Exchange (the drive sees new outputs at once) |
//! | – | `idle` | WFI |
//!
//! The `Node` is shared by all of them but the line interrupts (ceiling 15: a lock masks the
//! core task, never the line); the lower tasks lock it only to copy (`Application::snapshot`
//! and `Application::apply` around the unlocked DPM, drive, profile and PKW work) or for one
//! `Node::process_acyclic` call (README "Benchmark"). No task below 16 shares `line` on
//! either board (README "The response path").
//!
//! The board is chosen by cargo feature; only `bsp::board` and the line block below differ:
//!
//! | feature | board | build |
//! |---|---|---|
//! | `board-f411` (default) | STM32F411 reference board (`crates/bsp/src/f411.rs`): DMA line with the fast path, autobaud, address journal in flash, LEDs, IWDG, own panic path; logs over RTT | `cargo build --release` |
//! | `qemu` | QEMU netduinoplus2 = STM32F405 (`crates/bsp/src/qemu.rs`), per-byte line at a fixed rate, defmt over semihosting | `DEFMT_LOG=info cargo build --release --no-default-features --features qemu` (`bash scripts/qemu.sh build`; the F411's default level `warn` would drop the QEMU tests' info logs) |
//! | `bench` (+ `qemu`) | the same, logging TIM2 instruction counts per response and under the Node lock | `DEFMT_LOG=info ... --features bench` (the counts are info logs) |
//!
//! On the host this file compiles to an empty `main` (the bin target is firmware only).
#![cfg_attr(target_os = "none", no_std)]
#![cfg_attr(target_os = "none", no_main)]

#[cfg(not(target_os = "none"))]
fn main() {}

#[cfg(target_os = "none")]
use pbcard_bsp as bsp;

#[cfg(all(target_os = "none", feature = "board-f411", feature = "qemu"))]
compile_error!(
    "features `board-f411` and `qemu` are exclusive: build QEMU with `--no-default-features --features qemu`"
);
#[cfg(all(target_os = "none", not(any(feature = "board-f411", feature = "qemu"))))]
compile_error!("choose a board: feature `board-f411` (default) or `qemu`");

#[cfg(all(target_os = "none", feature = "board-f411"))]
use defmt_rtt as _;
#[cfg(all(target_os = "none", feature = "qemu"))]
use defmt_semihosting as _;

/// What runs behind the node (`pbcard_bsp::CardApp`: the card alone, or the bench with the
/// simulated drive on QEMU and on the F411 with `sim-drive`).
#[cfg(target_os = "none")]
use bsp::CardApp;

/// The PROFIBUS line rate of the QEMU board (also shown as P0963 / PNU 963); the F411
/// searches it (autobaud).
#[cfg(all(target_os = "none", feature = "qemu"))]
const LINE_RATE: pbcard::time::Baudrate = pbcard::time::Baudrate::B1500k;

/// The station address of a card whose address journal is empty (126 = the factory default
/// of DP slaves, changeable at run time by Set_Slave_Add, which the F411 stores in flash; the
/// QEMU board has no store). A build can choose another one:
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
#[cfg_attr(feature = "board-f411", rtic::app(device = stm32f4xx_hal::pac, dispatchers = [SPI4, SPI5, SPI3]))]
#[cfg_attr(feature = "qemu", rtic::app(device = stm32f4xx_hal::pac, dispatchers = [SPI2, SPI3, SPI1]))]
mod app {
    use crate::bsp::board;
    use crate::bsp::clock::{Mono, SysTickClock};
    use crate::bsp::Clock;
    use crate::STATION_ADDRESS;

    use crate::CardApp;
    use pbcard::dp::{DpSlave, DpState, Events};
    use pbcard::dpm::spi::SlavePort;
    use pbcard::dpm::CommState;
    use pbcard::led::{LedInputs, Leds};
    use pbcard::node::Node;
    use pbcard::profile::profidrive::State as DriveState;
    #[cfg(any(feature = "qemu", feature = "sim-drive"))]
    use pbcard_sim::drive::DriveConfig;
    use rtic::Mutex;
    use rtic_monotonics::systick::prelude::*;

    #[cfg(feature = "qemu")]
    use crate::LINE_RATE;
    #[cfg(feature = "board-f411")]
    use pbcard::phy::autobaud::Autobaud;
    #[cfg(feature = "board-f411")]
    use pbcard::phy::rate_link::RateLink;

    /// What the log reports after a step, read while the node was locked.
    struct NodeView {
        events: Events,
        state: DpState,
        master: Option<u8>,
        address: u8,
        no_add_chg: bool,
        acyclic_work: bool,
        /// Requests addressed to us so far (FDL station counter).
        requests: u32,
        watchdog: Option<pbcard::time::Duration>,
    }

    impl NodeView {
        /// The DP watchdog supervises the master (autobaud's DP_Control).
        fn dp_watchdog_active(&self) -> bool {
            self.watchdog.is_some() && self.state != DpState::WaitPrm
        }
    }

    /// The card behind the DPM (image, link, profile layer; QEMU and `sim-drive`: with the
    /// simulated drive) and what the log has shown of it.
    pub struct Drive {
        app: CardApp,
        clock: SysTickClock,
        comm: Option<CommState>,
        state: DriveState,
        led_requests: u32,
        led_last_frame: Option<pbcard::time::Instant>,
        led_was_dx: bool,
        led_shown: Option<Leds>,
        /// The last reset came from the fault path: BS shows "card fault" until data exchange.
        card_fault: bool,
        /// The pattern for the LED pins.
        leds: Option<Leds>,
        /// Largest instruction counts of the parts of a step: `snapshot` and `apply` (under
        /// the Node lock), publish + drive + collect (unlocked).
        #[cfg(feature = "bench")]
        max_step: [u32; 3],
    }

    impl Drive {
        fn new(clock: SysTickClock, rate: Option<pbcard::time::Baudrate>) -> Self {
            // QEMU and a bench board without a drive (`sim-drive`): the simulated drive runs
            // over the in-process SPI frames. The F411 with a drive: the card alone, the
            // drive's control board writes the host blocks through SPI (`spi_frame`).
            #[cfg(any(feature = "qemu", feature = "sim-drive"))]
            let mut app = CardApp::new(DriveConfig::DEFAULT);
            #[cfg(not(any(feature = "qemu", feature = "sim-drive")))]
            let mut app = CardApp::new();
            // Issue 16: CARD.BOOT_ID, another value on every start of the board.
            #[cfg(feature = "board-f411")]
            app.link_mut().set_boot_id(crate::bsp::spi::boot_id());
            app.set_baudrate(rate);
            let state = app.profidrive_state().unwrap_or(DriveState::SwitchingOnInhibited);
            Drive {
                app,
                clock,
                comm: None,
                state,
                led_requests: 0,
                led_last_frame: None,
                led_was_dx: false,
                led_shown: None,
                card_fault: false,
                leds: None,
                #[cfg(feature = "bench")]
                max_step: [0; 3],
            }
        }

        /// One application step now, the node locked only to copy: `Application::snapshot`
        /// (node timers, a copy of state, outputs and Set_Prm user bytes) and
        /// `Application::apply` (the drive's diagnosis and the new input image into the
        /// slave). The DPM writes (`publish`), the simulated drive, the profile cycle, the
        /// PKW service and DRIVE_CMD (`collect`) run between them, unlocked. `line_errors`:
        /// the line's count of corrupt telegrams (STATUS.CORRUPT_FRAMES).
        fn step(&mut self, node: &mut impl Mutex<T = Node>, line_errors: u32) -> NodeView {
            let now = self.clock.now();
            let app = &mut self.app;
            app.link_mut().set_line_errors(line_errors);
            #[cfg(feature = "bench")]
            let mut instr = [0u32; 3];
            let snap = node.lock(|n| {
                let (snap, _n) = measured(|| app.snapshot(now, n));
                #[cfg(feature = "bench")]
                {
                    instr[0] = _n;
                }
                snap
            });
            #[cfg(feature = "bench")]
            let t_free = board::bench::count();
            app.publish(&snap);
            #[cfg(any(feature = "qemu", feature = "sim-drive"))]
            app.step_drive(now);
            let update = app.collect(now, &snap);
            #[cfg(feature = "bench")]
            {
                instr[2] = board::bench::count().wrapping_sub(t_free);
            }
            let mut v = node.lock(|n| {
                let ((), _n) = measured(|| app.apply(n, &update));
                #[cfg(feature = "bench")]
                {
                    instr[1] = _n;
                }
                let s = n.slave();
                NodeView {
                    events: Events::empty(),
                    state: s.state(),
                    master: s.master_address(),
                    address: s.address(),
                    no_add_chg: s.no_add_chg(),
                    acyclic_work: n.has_acyclic_work(),
                    requests: n.station().stats().requests,
                    watchdog: s.watchdog_time(),
                }
            });
            let events = snap.events;
            v.events = events;
            // The node changed (timers, diagnosis, inputs): the core task republishes the fast
            // path's staging now.
            if events.contains(Events::ADDRESS_CHANGED) {
                ADDRESS_CHANGES.fetch_add(1, core::sync::atomic::Ordering::Relaxed);
            }
            rtic::pend(CORE_IRQ);
            #[cfg(feature = "bench")]
            {
                // Each part's own maximum: the two locked parts and the unlocked middle.
                const PARTS: [&str; 3] = ["LOCK app.snapshot", "LOCK app.apply", "UNLOCKED app.step"];
                for (k, what) in PARTS.iter().enumerate() {
                    if instr[k] > self.max_step[k] {
                        self.max_step[k] = instr[k];
                        defmt::info!("{=str} {=u32} instructions (new maximum)", what, instr[k]);
                    }
                }
            }
            // The line spawns the DP-V1 task; this catches a request that arrived while the
            // task was finishing (its spawn failed then).
            if v.acyclic_work {
                acyclic::spawn().ok();
            }
            self.log(&v);
            self.leds(now, &v);
            v
        }

        /// The card's image for the SPI frame task's hand-over (`bsp::spi::after_step`): the
        /// card alone hands it over; with `sim-drive` the simulated drive writes the host
        /// blocks through its in-process frames and nothing is handed over.
        #[cfg(feature = "board-f411")]
        fn wire_card(&mut self) -> Option<&mut pbcard::dpm::Dpm> {
            #[cfg(feature = "sim-drive")]
            {
                None
            }
            #[cfg(not(feature = "sim-drive"))]
            {
                Some(self.app.dpm_mut())
            }
        }

        /// The PS / BS / FS LED pattern (OPTE3/E5 §4.3, `pbcard::led`); logged when it
        /// changes, shown on the pins by the F411.
        fn leds(&mut self, now: pbcard::time::Instant, v: &NodeView) {
            if v.requests != self.led_requests {
                self.led_requests = v.requests;
                self.led_last_frame = Some(now);
            }
            let dx = v.state == DpState::DataExch;
            if dx {
                self.led_was_dx = true;
                self.card_fault = false;
            }
            let inputs = LedInputs {
                data_exchange: dx,
                // The simulated drive is part of the firmware: always there.
                drive_active: true,
                card_fault: self.card_fault,
                last_frame_for_us: self.led_last_frame,
                watchdog: v.watchdog,
                lost_after_data_exchange: self.led_was_dx && !dx,
            };
            let leds = pbcard::led::indicate(now, &inputs);
            if self.led_shown != Some(leds) {
                defmt::info!("LEDs: PS {} BS {} FS {}", leds.ps, leds.bs, leds.fs);
                self.led_shown = Some(leds);
            }
            self.leds = Some(leds);
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
                // Node::poll has reset the FCB memory of the old address; the F411's
                // housekeeping stores it.
                defmt::warn!("station address changed to {=u8}", v.address);
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
            // The card's PROFIdrive state of the drive (S1 before a profile is selected).
            let state = self.app.profidrive_state().unwrap_or(DriveState::SwitchingOnInhibited);
            #[cfg(not(any(feature = "qemu", feature = "sim-drive")))]
            if state != self.state {
                defmt::info!("drive: {=str} -> {=str}", self.state.name(), state.name());
                self.state = state;
            }
            #[cfg(any(feature = "qemu", feature = "sim-drive"))]
            if state != self.state {
                let drive = self.app.drive();
                defmt::info!(
                    "drive: {=str} -> {=str} (command {=u16:#06x}, setpoint {=i16}, status {=u16:#06x}, speed {=i16})",
                    self.state.name(),
                    state.name(),
                    drive.command().flags.bits(),
                    drive.command().speed_setpoint,
                    drive.status().flags.bits(),
                    drive.actual_speed()
                );
                self.state = state;
            }
        }
    }

    /// Run `f`, work done under the Node lock. The bench build (QEMU) counts its
    /// instructions; it does not mask interrupts for it (that would be a critical section
    /// over the fast path), so a line interrupt that lands in it is counted too — the
    /// benchmark sends one request at a time and waits for the answer, so this is rare and
    /// only ever raises the figure. Other builds just run it (count 0).
    #[inline(always)]
    fn measured<R>(f: impl FnOnce() -> R) -> (R, u32) {
        #[cfg(feature = "bench")]
        {
            let t0 = board::bench::count();
            let r = f();
            (r, board::bench::count().wrapping_sub(t0))
        }
        #[cfg(not(feature = "bench"))]
        {
            (f(), 0)
        }
    }

    /// Runs of the DP-V1 task (its liveness for the IWDG).
    static ACYCLIC_RUNS: core::sync::atomic::AtomicU32 = core::sync::atomic::AtomicU32::new(0);

    #[shared]
    struct Shared {
        node: Node,
        drive: Drive,
        /// The PROFIBUS line (F411: USART1 + DMA2 + TIM5; QEMU: USART1 per byte + framer).
        line: board::Line,
        /// The rate control (F411: autobaud, the keeper half of `pbcard::phy::rate_link`, used by
        /// the housekeeping task alone; QEMU: fixed).
        baud: board::Baud,
        // DPM SPI transport: see the block "DPM SPI transport" below.
        spi: DpmSpiPort,
        /// The frame task's own image (`pbcard::dpm::spi::WireImage`), handed over with the
        /// application's after each step.
        spi_wire: pbcard::dpm::spi::WireImage,
    }

    #[local]
    struct Local {
        /// The core half of the split, in the core task.
        core_link: pbcard::fast::CoreLink<'static>,
        acyclic_clock: SysTickClock,
        supervisor: board::Supervisor,
    }

    /// The split's queues and triple buffers (`pbcard::fast::Shared`) and, on the F411, the
    /// autobaud's rate link are `init`'s local resources: statics with an all-zero `const`
    /// initialiser, so they are in `.bss` and no start-up code builds or copies them (a
    /// `cortex_m::singleton!` built the 7 KiB value on the stack and copied it, issue 13
    /// item 1). `init` runs once, so each is handed out once, for the life of the firmware.
    #[init(local = [
        split: pbcard::fast::Shared = pbcard::fast::Shared::new(),
        #[cfg(feature = "board-f411")]
        rate_link: RateLink = RateLink::new(),
    ])]
    fn init(cx: init::Context) -> (Shared, Local) {
        init_board(cx.device, cx.core.SYST, cx.local)
    }

    #[cfg(feature = "qemu")]
    fn init_board(
        device: stm32f4xx_hal::pac::Peripherals,
        syst: cortex_m::peripheral::SYST,
        local: init::LocalResources<'_>,
    ) -> (Shared, Local) {
        let board::Board { mut line, clock } = board::init(device, syst, LINE_RATE);
        defmt::info!("pbcard: station {=u8}, {=str}", STATION_ADDRESS, board::NAME);
        log_drive();
        let mut node = pbcard::card::node(DpSlave::new(&pbcard::card::SLAVE, STATION_ADDRESS));
        node.set_baudrate(Some(LINE_RATE));
        // The split's queues and triple buffers (`init`'s local), for the life of the firmware.
        let (fast, core_link) = local.split.split(&mut node);
        // The line half goes to the line interrupt, which alone uses `line` on QEMU.
        line.attach(fast);
        housekeeping::spawn().ok();
        (
            Shared {
                node,
                line,
                baud: board::FixedRate(LINE_RATE),
                drive: Drive::new(clock, Some(LINE_RATE)),
                spi: start_dpm_spi(),
                spi_wire: pbcard::dpm::spi::WireImage::new(),
            },
            Local { core_link, acyclic_clock: clock, supervisor: board::Supervisor },
        )
    }

    #[cfg(feature = "board-f411")]
    fn init_board(
        device: stm32f4xx_hal::pac::Peripherals,
        syst: cortex_m::peripheral::SYST,
        local: init::LocalResources<'_>,
    ) -> (Shared, Local) {
        use pbcard::store::Flash as _;
        let recovered = crate::bsp::fault::take_recovered_fault();
        // Autobaud from power-up: listen at the first search rate (12 Mbit/s).
        let baud = Autobaud::new(pbcard::time::Instant::from_micros(0));
        let b = board::init(device, syst, baud.rate());
        let store = pbcard::store::Journal::new(b.flash);
        let stored = store.load::<pbcard::store::StationAddress>();
        let (address, no_add_chg) = stored.map_or((STATION_ADDRESS, false), |r| (r.address, r.no_add_chg));
        defmt::info!(
            "pbcard: station {=u8} ({=str}, No_Add_Chg {=bool}), {=str}",
            address,
            if stored.is_some() { "stored" } else { "default" },
            no_add_chg,
            board::NAME
        );
        defmt::info!(
            "journal (station address, I&M1-4): {=u32} slots of {=usize} bytes in 2 × {=u32} bytes at {=u32:#010x}",
            pbcard::store::Journal::<crate::bsp::flash::JournalFlash>::SLOTS,
            pbcard::store::SLOT_SIZE,
            crate::bsp::flash::JournalFlash::SECTOR_SIZE,
            crate::bsp::flash::JOURNAL_BASE
        );
        let im = store.load::<pbcard::dpv1::im::ImData>();
        defmt::info!("I&M1-4: {=str}", if im.is_some() { "stored" } else { "as shipped" });
        if recovered {
            defmt::error!("restarted after a card fault (panic or HardFault)");
        }
        #[cfg(feature = "sim-drive")]
        {
            log_drive();
            defmt::warn!("drive: simulated (feature sim-drive): no drive may be connected to the DPM SPI port");
        }
        #[cfg(not(feature = "sim-drive"))]
        defmt::info!("drive: the control board behind the DPM SPI port (SPI2 slave, card only)");
        let mut node = pbcard::card::node(DpSlave::with_address_lock(&pbcard::card::SLAVE, address, no_add_chg));
        node.set_baudrate(None);
        // I&M1-4 as stored, before the line starts.
        if let Some(d) = im {
            node.im_mut().set_data(d);
        }
        let mut drive = Drive::new(b.clock, None);
        drive.card_fault = recovered;
        if recovered {
            drive.app.report_recovered_fault();
        }
        // The split's queues and triple buffers (`init`'s local), for the life of the firmware.
        let (fast, core_link) = local.split.split(&mut node);
        // The Baud_Search starts now (the SysTick clock starts at 0 in `board::init`); the
        // line classifies and gates, housekeeping searches and switches (`phy::rate_link`).
        let (rate_tap, baud) = local.rate_link.split(Autobaud::new(b.clock.now()));
        let mut line = b.line;
        // The line halves go to the line interrupts, which alone use `line`.
        line.attach(fast, rate_tap);
        housekeeping::spawn().ok();
        (
            Shared { node, drive, line, baud, spi: start_dpm_spi(b.spi), spi_wire: pbcard::dpm::spi::WireImage::new() },
            Local {
                core_link,
                acyclic_clock: b.clock,
                supervisor: board::Supervisor::new(b.leds, store, b.iwdg, (address, no_add_chg)),
            },
        )
    }

    #[cfg(any(feature = "qemu", feature = "sim-drive"))]
    fn log_drive() {
        defmt::info!(
            "drive: simulated behind the DPM (PROFIdrive STW1/ZSW1, NSOLL_A/NIST_A 0x4000 = 100 %, ramp {=u64} ms)",
            DriveConfig::DEFAULT.ramp_time.as_millis()
        );
    }

    #[idle]
    fn idle(_: idle::Context) -> ! {
        loop {
            // The default RTIC idle spins; sleep instead (also keeps QEMU `-icount` fast).
            cortex_m::asm::wfi();
        }
    }

    // =========================================================================================
    // The line: the interrupt(s) at the top priority with the fast path, the core one below
    // =========================================================================================

    /// USART1. F411: IDLE (a segment is complete → its telegrams through the fast path),
    /// character errors, TC (DE off). QEMU: one interrupt per character into the framer, and
    /// the response's next character. Never touches the `Node`.
    ///
    /// Both boards: the fast path (`pbcard::fast::FastPath`, owned by the line): every
    /// telegram into the fast path, which answers from the staged frames at once or leaves it
    /// to the core (DP-V1: the core task pends this interrupt when its answer is back); the
    /// core task is pended when telegrams were queued. No task below 16 locks `line` (they
    /// read the line's atomics: F411 `board::monitor`, QEMU `board::LineView`; the F411's
    /// rate switches and flash silences go through its command mailbox, `board::control`),
    /// so this lock is free and nothing masks the fast path; the core is reached through the
    /// split's queues and triple buffers only, the rate control through `phy::rate_link`.
    #[task(binds = USART1, priority = 16, shared = [line])]
    fn usart1(mut cx: usart1::Context) {
        #[cfg(feature = "board-f411")]
        if cx.shared.line.lock(|l| l.on_usart()) {
            rtic::pend(CORE_IRQ);
        }
        #[cfg(feature = "qemu")]
        if cx.shared.line.lock(|l| l.on_usart_fast()) {
            rtic::pend(CORE_IRQ);
        }
    }

    /// The interrupt the core task is bound to (I2C1 event: unused by the card on both boards,
    /// and no device of QEMU's netduinoplus2 drives it — an EXTI line is driven by QEMU's EXTI
    /// model and its software pend was not taken under `-icount`).
    const CORE_IRQ: stm32f4xx_hal::pac::Interrupt = stm32f4xx_hal::pac::Interrupt::I2C1_EV;

    /// Address changes the housekeeping step saw (`Node::poll` reset the station's FCB
    /// memory): the core task tells the fast path (`CoreLink::note_events`).
    static ADDRESS_CHANGES: core::sync::atomic::AtomicU32 = core::sync::atomic::AtomicU32::new(0);

    /// The protocol core behind the fast path, both boards (bound to I2C1_EV, pended by
    /// `usart1` and by every lower task that changed the node): republish the staging, then
    /// every queued telegram through `Node::on_frame` (`CoreLink::step`), the staging
    /// republished after each; a deferred (DP-V1) answer goes back to the line by pending
    /// USART1 (F411: `DmaLine::on_usart` sends it as `respond` decides, min_TSDR / max_TSDR by
    /// TIM5).
    #[task(binds = I2C1_EV, priority = 15, shared = [node], local = [core_link, seen_address_changes: u32 = 0])]
    fn core_step(mut cx: core_step::Context) {
        let link = cx.local.core_link;
        let changes = ADDRESS_CHANGES.load(core::sync::atomic::Ordering::Relaxed);
        if changes != *cx.local.seen_address_changes {
            *cx.local.seen_address_changes = changes;
            link.note_events(Events::ADDRESS_CHANGED);
        }
        loop {
            cx.shared.node.lock(|n| {
                link.publish(n);
                #[cfg(feature = "bench")]
                let mut t0 = board::bench::count();
                while let Some(step) = link.step(n) {
                    #[cfg(feature = "bench")]
                    {
                        let instr = board::bench::count().wrapping_sub(t0);
                        let len = step.answer_len.unwrap_or(0);
                        defmt::info!("CORE step {=u32} instructions (answer {=usize})", instr, len);
                    }
                    if step.deferred {
                        rtic::pend(stm32f4xx_hal::pac::Interrupt::USART1);
                    }
                    if step.acyclic_work {
                        acyclic::spawn().ok();
                    }
                    if step.data_exchange {
                        app_step::spawn().ok();
                    }
                    #[cfg(feature = "bench")]
                    {
                        t0 = board::bench::count();
                    }
                }
            });
            // QEMU: the line takes the characters it held once the core has caught up (QEMU's
            // line holds them, `bsp::qemu`): USART1 preempts here, and what it queued
            // meanwhile is worked on in this activation. (The F411's DMA line holds nothing.)
            #[cfg(feature = "qemu")]
            {
                rtic::pend(stm32f4xx_hal::pac::Interrupt::USART1);
                cortex_m::asm::dsb();
                cortex_m::asm::isb();
            }
            if !link.pending() {
                break;
            }
        }
    }

    /// F411 receive DMA (≥ 3 Mbit/s): the ring's half/full-transfer events hand its new bytes
    /// to the streaming framer (`board::DmaLine::on_dma`); same priority as USART1.
    #[cfg(feature = "board-f411")]
    #[task(binds = DMA2_STREAM2, priority = 16, shared = [line])]
    fn dma2_stream2(mut cx: dma2_stream2::Context) {
        if cx.shared.line.lock(|l| l.on_dma()) {
            rtic::pend(CORE_IRQ);
        }
    }

    /// F411 TIM5 compares: the T_SYN proof and the response start at min_TSDR.
    #[cfg(feature = "board-f411")]
    #[task(binds = TIM5, priority = 16, shared = [line])]
    fn tim5(mut cx: tim5::Context) {
        cx.shared.line.lock(|l| l.on_timer());
    }

    // =========================================================================================
    // Shared above the line
    // =========================================================================================

    /// DP-V1: data records at slot 0 (PROFIdrive parameter access, WEG record 48) for MSAC_C1
    /// and MSAC_C2. The master polls until the response is there ("not ready" meanwhile). The
    /// card's records (`Application::records`, owned by the application) reach the drive's
    /// parameters through the DPM parameter mailbox (`Application::parameters`);
    /// a job still waiting for the drive keeps `Node::has_acyclic_work` true, so the
    /// housekeeping step spawns this task again.
    #[task(priority = 8, shared = [node, drive], local = [acyclic_clock])]
    async fn acyclic(cx: acyclic::Context) {
        let now = cx.local.acyclic_clock.now();
        let acyclic::SharedResources { mut node, mut drive, .. } = cx.shared;
        #[cfg(feature = "bench")]
        let mut instr = 0u32;
        // The application (priority ceiling 8) for the DPM mailbox, the node (masks the
        // core task, not the line) for one pass over the waiting requests.
        drive.lock(|d| {
            let mut records = d.app.records(now);
            node.lock(|n| {
                let ((), _n) = measured(|| n.process_acyclic(now, &mut records));
                #[cfg(feature = "bench")]
                {
                    instr = _n;
                }
            });
        });
        ACYCLIC_RUNS.fetch_add(1, core::sync::atomic::Ordering::Relaxed);
        // Republish the staging (the DP-V1 work may change the node's answers).
        rtic::pend(CORE_IRQ);
        #[cfg(feature = "bench")]
        defmt::info!("LOCK process_acyclic {=u32} instructions", instr);
    }

    /// One application step right after a Data_Exchange.
    #[task(priority = 1, shared = [node, drive])]
    async fn app_step(cx: app_step::Context) {
        let app_step::SharedResources { mut node, mut drive, .. } = cx.shared;
        let line_errors = line_errors();
        // Same priority as housekeeping: this lock costs nothing.
        drive.lock(|d| {
            d.step(&mut node, line_errors);
        });
    }

    // The line's counters for the lower tasks, never under a lock shared with the line
    // interrupts (issue 11 3c): F411, the atomics its line interrupts publish and read-only
    // register reads (`board::monitor`); QEMU, the atomics the fast path's interrupt
    // publishes (`board::LineView`). No task below 16 shares `line`.
    /// The line's lost-telegram count (STATUS.CORRUPT_FRAMES).
    #[cfg(feature = "board-f411")]
    fn line_errors() -> u32 {
        board::monitor::corrupt_frames()
    }
    /// The line hardware runs (IWDG supervision).
    #[cfg(feature = "board-f411")]
    fn line_healthy() -> bool {
        board::monitor::is_healthy()
    }
    /// The line's statistics for the log.
    #[cfg(feature = "board-f411")]
    fn line_stats() -> (board::LineStats, pbcard::phy::line::RxStats) {
        board::monitor::stats()
    }
    #[cfg(feature = "qemu")]
    fn line_errors() -> u32 {
        board::LineView.corrupt_frames()
    }
    #[cfg(feature = "qemu")]
    fn line_healthy() -> bool {
        true
    }
    #[cfg(feature = "qemu")]
    fn line_stats() -> (board::LineStats, pbcard::fdl::framer::FramerStats) {
        (board::LineView.stats(), board::LineView.rx_stats())
    }

    const STATS_PERIOD_MS: u32 = 10_000;

    /// Every millisecond: the application step and the node's timers, the rate control's
    /// timers (F411: search step → new divisor, Baud_Control / DP_Control; P0963), the
    /// board's supervision (F411: LED pins, the address journal after a Set_Slave_Add, the
    /// IWDG), and the log.
    #[task(priority = 1, shared = [node, drive, baud], local = [supervisor])]
    async fn housekeeping(cx: housekeeping::Context) {
        let housekeeping::SharedResources { mut node, mut drive, mut baud, .. } = cx.shared;
        let sup = cx.local.supervisor;
        let mut next = Mono::now();
        let mut ms: u32 = 0;
        let mut last_stats = None;
        let mut shown_rate = baud.lock(|b| b.detected());
        let mut acyclic_wait: Option<(u32, pbcard::time::Instant)> = None;
        let state = node.lock(|n| n.slave().state());
        defmt::info!("DP state {}", state);
        // The application is in its final place now: the fault path may write its DPM.
        drive.lock(|d| board::register_application(&mut d.app));
        // The bench build: the critical sections every lower task still takes (they mask the
        // fast path too), measured once.
        #[cfg(feature = "bench")]
        {
            let clock = drive.lock(|d| d.clock);
            let t0 = board::bench::count();
            let _ = clock.now();
            let n_now = board::bench::count().wrapping_sub(t0);
            let t0 = board::bench::count();
            defmt::info!("CS probe");
            let n_log = board::bench::count().wrapping_sub(t0);
            defmt::info!("CS clock.now {=u32} instructions", n_now);
            defmt::info!("CS defmt {=u32} instructions", n_log);
        }
        loop {
            next += 1.millis();
            Mono::delay_until(next).await;
            // QEMU: an answer waits for its quiet window; the line interrupt starts it (or has
            // dropped it when a character came meanwhile, `bsp::qemu`).
            #[cfg(feature = "qemu")]
            if board::answer_waiting() {
                rtic::pend(stm32f4xx_hal::pac::Interrupt::USART1);
            }
            let line_errors = line_errors();
            let (v, now, leds) = drive.lock(|d| {
                let v = d.step(&mut node, line_errors);
                (v, d.clock.now(), d.leds)
            });

            // Rate control: the DP watchdog state, the line's telegrams since the last step
            // (F411: `phy::rate_link`), the timers, a new rate — which the line interrupt
            // carries out (`board::switch_rate`: no lock of the line).
            let (switch, detected) = baud.lock(|b| {
                b.dp_watchdog_active(now, v.dp_watchdog_active());
                (b.poll(now), b.detected())
            });
            if let Some(rate) = switch {
                if !board::switch_rate(rate) {
                    defmt::error!("rate {} not reachable", rate);
                }
            }
            if detected != shown_rate {
                shown_rate = detected;
                match detected {
                    Some(r) => defmt::info!("baud rate locked: {} (P0963 = {=u8})", r, r.p0963_code()),
                    None => defmt::warn!("baud rate search (P0963 = 5)"),
                }
                node.lock(|n| n.set_baudrate(detected));
                drive.lock(|d| d.app.set_baudrate(detected));
            }

            // Supervision: alive = the line hardware runs and the DP-V1 task does not leave
            // work waiting for more than 100 ms.
            let runs = ACYCLIC_RUNS.load(core::sync::atomic::Ordering::Relaxed);
            acyclic_wait = match (v.acyclic_work, acyclic_wait) {
                (false, _) => None,
                (true, Some((r, since))) if r == runs => Some((r, since)),
                (true, _) => Some((runs, now)),
            };
            let acyclic_alive = acyclic_wait
                .is_none_or(|(_, since)| now.saturating_since(since) < pbcard::time::Duration::from_millis(100));
            let alive = acyclic_alive && line_healthy();
            // I&M1-4 a master wrote go into the journal with the address (QEMU: RAM only).
            #[cfg(feature = "board-f411")]
            if let Some(d) = node.lock(|n| n.im_mut().take_changed()) {
                sup.store_im(d);
            }
            // F411: a journal write silences and restarts the line through its command mailbox.
            sup.tick(now, leds, (v.address, v.no_add_chg), alive);

            ms = ms.wrapping_add(1);
            if ms.is_multiple_of(STATS_PERIOD_MS) {
                let (ls, rx) = line_stats();
                let ab = baud.lock(|b| b.stats());
                let (station, dp) = node.lock(|n| (n.station().stats(), n.slave().stats()));
                let link = drive.lock(|d| d.app.link().stats());
                let stats = (ls, rx, ab, station, dp, link);
                if last_stats != Some(stats) {
                    defmt::info!(
                        "line {}, rx {}, rate {}, station {}, dp {}, dpm link {}",
                        ls,
                        rx,
                        ab,
                        station,
                        dp,
                        link
                    );
                    last_stats = Some(stats);
                }
            }
        }
    }

    // ---------------------------------------------------------------------------------------
    // DPM SPI transport (issue 7 item 4; board-f411 only). The drive's control board is SPI
    // master; `crates/bsp/src/spi.rs` moves the bytes, `pbcard::dpm::spi::SpiSlave` decides. NSS rising
    // (EXTI15_10, short, priority 12 — below USART1) re-arms the DMA and hands the received
    // frame to `spi_frame` (priority 11, above the step and the DP-V1 task), which applies it
    // to its own image (`WireImage`) and stages the reply for the next transaction.
    // `spi_irq` hands the images over after each step (`bsp::spi::after_step`: a short copy
    // under the frame task's lock), refreshes an armed CYCLIC reply and keeps the IRQ line in
    // step with the card's writes. The F411 build runs `Application::card_only()`:
    // the housekeeping step publishes and collects, its drive part does nothing, so the host
    // blocks are written by the control board's frames alone. With the `sim-drive` feature
    // (a bench card without a drive) the simulated drive writes them through its in-process
    // SPI frames instead, and no control board may be connected.
    // ---------------------------------------------------------------------------------------

    /// The SPI port (QEMU: none; its transport is in-process, `pbcard::dpm::spi::Loopback`).
    #[cfg(feature = "board-f411")]
    type DpmSpiPort = crate::bsp::spi::SpiPort;
    /// The SPI port (QEMU: none; its transport is in-process, `pbcard::dpm::spi::Loopback`).
    #[cfg(not(feature = "board-f411"))]
    type DpmSpiPort = NoSpiPort;
    /// QEMU has no SPI port: its DPM transport is in process (`pbcard::dpm::spi::Loopback`
    /// inside `pbcard_sim::bench::Application`).
    #[cfg(not(feature = "board-f411"))]
    pub struct NoSpiPort;
    /// No transaction and no reply buffer ever exists on a board without an SPI port.
    #[cfg(not(feature = "board-f411"))]
    pub enum NoSpiFrame {}
    #[cfg(not(feature = "board-f411"))]
    impl AsRef<[u8]> for NoSpiFrame {
        fn as_ref(&self) -> &[u8] {
            match *self {}
        }
    }
    #[cfg(not(feature = "board-f411"))]
    impl AsMut<[u8]> for NoSpiFrame {
        fn as_mut(&mut self) -> &mut [u8] {
            match *self {}
        }
    }
    /// The board contract's DPM transport on a board without one (the documented fallback):
    /// no transaction ever ends, no reply buffer, no IRQ line.
    #[cfg(not(feature = "board-f411"))]
    impl SlavePort for NoSpiPort {
        type Frame = NoSpiFrame;
        type Reply = NoSpiFrame;
        fn on_nss_rise(&mut self) -> Option<NoSpiFrame> {
            None
        }
        fn reply_buffer(&mut self) -> Option<NoSpiFrame> {
            None
        }
        fn reply_ready(&mut self, buf: NoSpiFrame, _len: usize) -> bool {
            match buf {}
        }
        fn give_back(&mut self, frame: NoSpiFrame) {
            match frame {}
        }
        fn drop_frame(&mut self, frame: NoSpiFrame) {
            match frame {}
        }
        fn set_irq(&mut self, _asserted: bool) {}
    }
    /// A received SPI frame (QEMU: none).
    #[cfg_attr(not(feature = "board-f411"), allow(dead_code))]
    type DpmSpiFrame = <DpmSpiPort as SlavePort>::Frame;

    /// Bring up the SPI port on the peripherals the board handed over and start the IRQ
    /// task (from `init`).
    #[cfg(feature = "board-f411")]
    fn start_dpm_spi(parts: crate::bsp::spi::SpiParts) -> DpmSpiPort {
        spi_irq::spawn().ok();
        crate::bsp::spi::init(parts)
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
    #[task(priority = 11, shared = [spi, spi_wire])]
    async fn spi_frame(cx: spi_frame::Context, frame: DpmSpiFrame) {
        let spi_frame::SharedResources { mut spi, mut spi_wire, .. } = cx.shared;
        let Some(reply) = spi.lock(|p| p.reply_buffer()) else {
            spi.lock(|p| p.drop_frame(frame));
            return;
        };
        // Its own image: never behind the application step (issue 16 item 3).
        let (len, irq) = spi_wire.lock(|w| (w.handle(frame.bytes(), reply), w.irq()));
        spi.lock(|p| {
            p.reply_ready(reply, len);
            p.give_back(frame);
            p.set_irq(irq);
        });
    }

    /// The IRQ line to the drive every millisecond (the card writes its blocks in the
    /// housekeeping step), and the transport's counters in the log when they change.
    #[cfg(feature = "board-f411")]
    #[task(priority = 1, shared = [spi, spi_wire, drive])]
    async fn spi_irq(cx: spi_irq::Context) {
        let spi_irq::SharedResources { mut spi, mut spi_wire, mut drive, .. } = cx.shared;
        let mut ms: u32 = 0;
        let mut shown = None;
        loop {
            Mono::delay(1.millis()).await;
            // Between two steps (same priority as housekeeping): the hand-over, the armed
            // CYCLIC reply refreshed, the IRQ line.
            let (port, proto) = drive.lock(|d| {
                let card = d.wire_card();
                crate::bsp::spi::after_step(&mut spi, &mut spi_wire, card)
            });
            ms = ms.wrapping_add(1);
            if ms.is_multiple_of(10_000) && shown != Some((port, proto)) {
                defmt::info!("dpm spi port {}, protocol {}", port, proto);
                shown = Some((port, proto));
            }
        }
    }
}
