//! The shipped card on the simulated line: [`CardEndpoint`] runs what the firmware runs — the
//! ASIC-style split (`pbcard::fast`: the line's [`FastPath`] answers from the staged frames,
//! [`CoreLink`] works the queued telegrams through the [`Node`]) and the card's
//! [`Application`] (DPM image, profile runtime, the simulated drive behind the DPM) — so that
//! profirust's master judges the card, not its parts (issue 13 item 5, issue 11 item 5).
//!
//! Per simulation step: the characters that completed go through the line's framer; each
//! telegram into [`FastPath::on_frame`] (the answer is decided there, from the staging as it
//! was before the telegram; a DP-V1 request the line leaves to the core gets the core's answer
//! at once, as QEMU's core task pends the line); the core then works everything queued; the
//! answer goes out min_TSDR after the request (the value in force before the request: a
//! Set_Prm that changes it applies from the next answer on), checked against
//! `card::max_tsdr` by [`SimLine`]. Every millisecond, and right after a Data_Exchange, the
//! application steps, the DP-V1 work runs over the DPM-backed parameters, and the staging is
//! republished — the soft slave's main loop.

use super::*;
use pbcard::fast::{single_threaded, CoreLink, FastPath, Shared};
use pbcard::node::Node;
use pbcard_sim::bench::Application;
use pbcard_sim::drive::DriveConfig;

/// How often the application steps (the firmware's housekeeping period).
const STEP_US: u64 = 1000;

/// The shipped card on one end of the simulated line.
pub struct CardEndpoint {
    /// Its end of the line (answers, timing, trace).
    pub line: SimLine,
    framer: Framer,
    fast: FastPath<'static>,
    core: CoreLink<'static>,
    /// The protocol core.
    pub node: Node,
    /// The card's application: DPM image, profile runtime, simulated drive.
    pub app: Application,
    next_step_us: u64,
    step_now: bool,
    /// OR of every event so far.
    pub events_seen: Events,
    last_state: DpState,
}

impl CardEndpoint {
    /// The card at the end of `line` (station address `address`) with the simulated drive
    /// `drive`.
    pub fn new(line: SimLine, address: u8, drive: DriveConfig) -> Self {
        let mut node = pbcard::card::node(DpSlave::new(&card::SLAVE, address));
        let app = Application::new(drive);
        // One split per card for the life of the test.
        let shared: &'static mut Shared = Box::leak(Box::new(Shared::new()));
        let (fast, core) = shared.split(&mut node);
        let last_state = node.slave().state();
        CardEndpoint {
            line,
            framer: Framer::new(),
            fast,
            core,
            node,
            app,
            next_step_us: 0,
            step_now: false,
            events_seen: Events::empty(),
            last_state,
        }
    }

    /// Install a fault hook on its line (replaces any previous one).
    pub fn set_fault_hook(&mut self, hook: impl FnMut(Dir, u64, &[u8]) -> Fault + 'static) {
        self.line.fault = Some(Box::new(hook));
    }

    fn on_frame(&mut self, now_us: u64, mut frame: Vec<u8>) {
        let now = Instant::from_micros(now_us);
        let own = self.node.slave().address();
        let mine = addressed_to(&frame, own);
        if mine {
            self.line.note(now_us, format!("rx  {}", hex(&frame)));
        }
        if !self.line.rx_fault(now_us, &mut frame) {
            return;
        }
        // min_TSDR in force before this request, from the staging (as the F411 line reads it).
        let min_tsdr = self.fast.min_tsdr();
        let dx_before = self.node.slave().stats().data_exchanges;
        let mut out = [0u8; telegram::MAX_FRAME_LEN];
        let answer = single_threaded(&mut self.fast, &mut self.core, &mut self.node, now, &frame, &mut out)
            .map(|n| out[..n].to_vec());
        if self.node.slave().stats().data_exchanges != dx_before {
            // New outputs: the drive sees them now (the firmware's app_step).
            self.step_now = true;
        }
        match answer {
            Some(a) if !mine => panic!(
                "card #{own} answered a frame not addressed to it: {} -> {}\n{}",
                hex(&frame),
                hex(&a),
                self.line.dump_trace_last(TRACE_DUMP)
            ),
            Some(a) => self.line.answer(now_us, a, min_tsdr),
            None => {}
        }
    }
}

impl Endpoint for CardEndpoint {
    fn address(&self) -> u8 {
        self.node.slave().address()
    }

    fn poll(&mut self, now_us: u64) -> Events {
        match self.line.receive(now_us) {
            Rx::Nothing => {}
            Rx::Idle(bits) => self.framer.idle(bits),
            Rx::Bytes(rx) => {
                for &b in &rx {
                    match self.framer.push(b) {
                        Push::Pending => {}
                        Push::Dropped(e) => self.line.note(now_us, format!("framer dropped bytes: {e:?}")),
                        Push::Frame(_) => {
                            let frame = self.framer.frame().to_vec();
                            self.on_frame(now_us, frame);
                        }
                    }
                }
                self.line.rx_scratch = rx;
            }
        }
        self.line.send_due(now_us);
        let mut ev = Events::empty();
        if self.step_now || now_us >= self.next_step_us {
            self.step_now = false;
            self.next_step_us = now_us + STEP_US;
            let now = Instant::from_micros(now_us);
            // The main loop's step: the application, DP-V1 work, the staging republished so
            // the fast path answers from the node as it is now.
            ev = pbcard::fast::tick(now, &mut self.node, &mut self.core, &mut self.app);
        }
        if !ev.is_empty() {
            self.events_seen |= ev;
            self.line.note(now_us, format!("card events {ev:?}"));
        }
        let st = self.node.slave().state();
        if st != self.last_state {
            self.line.note(now_us, format!("slave state {:?} -> {:?}", self.last_state, st));
            self.last_state = st;
        }
        ev
    }

    fn dp_state(&self) -> DpState {
        self.node.slave().state()
    }

    fn note(&mut self, t_us: u64, what: String) {
        self.line.note(t_us, what);
    }

    fn report(&self) -> String {
        format!(
            "card #{}: state {:?}, master {:?}, events seen {:?}, fast {:?}, core {:?}, dp {:?}\n--- trace of #{} ---\n{}",
            self.address(),
            self.node.slave().state(),
            self.node.slave().master_address(),
            self.events_seen,
            self.fast.stats(),
            self.core.stats(),
            self.node.slave().stats(),
            self.address(),
            self.line.dump_trace_last(TRACE_DUMP)
        )
    }
}

impl SimBus<CardEndpoint> {
    /// The line with profirust's master and one shipped card per `(address, drive)`.
    pub fn cards(master: MasterConfig, peripherals: &[PeripheralConfig], cards: &[(u8, DriveConfig)]) -> Self {
        let addresses: Vec<u8> = cards.iter().map(|(a, _)| *a).collect();
        SimBus::with_endpoints(master, peripherals, &addresses, |line, addr| {
            let drive = cards.iter().find(|(a, _)| *a == addr).map(|(_, d)| *d).expect("a drive per card");
            CardEndpoint::new(line, addr, drive)
        })
    }
}
