//! The card's side of the DPM exchange: node → image (status, outputs) and image → node
//! (inputs).

use super::{CardSide, CommState, Dpm, PdFlags, ProcessData, Status, StatusFlags, Telegram};
use crate::dp::{DpState, Events};
use crate::node::Node;
use crate::time::Baudrate;

/// Counters of the [`Link`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct LinkStats {
    /// INPUTS reads that saw a write in progress (retried next time).
    pub torn_reads: u32,
    /// INPUTS written for another telegram than the active one (not served to the master).
    pub stale_telegram: u32,
    /// INPUTS images handed to the DP slave.
    pub inputs_taken: u32,
    /// OUTPUTS writes.
    pub outputs_written: u32,
    /// STATUS writes.
    pub status_written: u32,
}

/// Moves data between a [`Node`] and a [`Dpm`], on the card's side.
///
/// Call [`Link::publish`] after [`Node::poll`] (it writes STATUS when it changed and OUTPUTS
/// whenever a Data_Exchange delivered outputs or their meaning changed), let the host work on
/// the image, then [`Link::collect`] (it hands a new INPUTS image written for the active
/// telegram to the DP slave; the master receives it with its next Data_Exchange).
#[derive(Debug, Clone)]
pub struct Link {
    baud: Option<Baudrate>,
    init_error: bool,
    telegram: Telegram,
    last_status: Option<Status>,
    last_outputs: Option<ProcessData>,
    inputs_seq: u16,
    stats: LinkStats,
}

impl Default for Link {
    fn default() -> Self {
        Self::new()
    }
}

impl Link {
    /// A link with no baud rate detected yet.
    pub const fn new() -> Self {
        Link {
            baud: None,
            init_error: false,
            telegram: Telegram::None,
            last_status: None,
            last_outputs: None,
            inputs_seq: 0,
            stats: LinkStats {
                torn_reads: 0,
                stale_telegram: 0,
                inputs_taken: 0,
                outputs_written: 0,
                status_written: 0,
            },
        }
    }

    /// The rate the platform listens at (`None` while the autobaud search runs); shown as
    /// P0963 in the status block.
    pub fn set_baudrate(&mut self, rate: Option<Baudrate>) {
        self.baud = rate;
    }

    /// The platform could not start the PROFIBUS interface: the status block shows P0740
    /// "initialization error" until cleared.
    pub fn set_init_error(&mut self, failed: bool) {
        self.init_error = failed;
    }

    /// Counters.
    pub fn stats(&self) -> LinkStats {
        self.stats
    }

    /// The status block's content for `node` as it is now.
    pub fn status_of(&self, node: &Node) -> Status {
        let slave = node.slave();
        let st = slave.stats();
        let mut flags = StatusFlags::empty();
        flags.set(StatusFlags::CLEAR, slave.is_clear());
        flags.set(StatusFlags::SYNC, slave.is_sync());
        flags.set(StatusFlags::FREEZE, slave.is_freeze());
        flags.set(StatusFlags::WATCHDOG_ON, slave.watchdog_time().is_some() && slave.state() != DpState::WaitPrm);
        flags.set(StatusFlags::ADDRESS_LOCKED, slave.no_add_chg());
        Status {
            comm: if self.init_error { CommState::InitError } else { CommState::of(slave) },
            baud: super::p0963(self.baud),
            station_address: slave.address(),
            master_address: slave.master_address(),
            telegram: active_telegram(node),
            dp_state: slave.state(),
            flags,
            watchdog_ms: slave.watchdog_time().map_or(0, |t| t.as_millis().min(u16::MAX as u64) as u16),
            data_exchanges: st.data_exchanges,
            prm_faults: st.prm_faults as u16,
            cfg_faults: st.cfg_faults as u16,
            watchdog_expiries: st.watchdog_expiries as u16,
            corrupt_frames: node.framer().stats().corrupt as u16,
        }
    }

    /// Write STATUS (when changed) and OUTPUTS (on new outputs or a changed meaning). A change
    /// of the active telegram also clears the input image until the host answers for the new
    /// one.
    pub fn publish(&mut self, node: &mut Node, events: Events, dpm: &mut Dpm) {
        let telegram = active_telegram(node);
        if telegram != self.telegram {
            self.telegram = telegram;
            self.inputs_seq = 0;
            node.slave_mut().set_inputs(&[]);
        }
        let mut card = dpm.card();
        self.write_status(node, &mut card);

        let slave = node.slave();
        let mut flags = PdFlags::empty();
        flags.set(PdFlags::DATA_EXCHANGE, slave.state() == DpState::DataExch);
        flags.set(PdFlags::CLEAR, slave.is_clear());
        let pd = ProcessData::new(telegram, flags, slave.outputs());
        if events.contains(Events::OUTPUTS_UPDATED) || self.last_outputs.as_ref() != Some(&pd) {
            card.write_outputs(&pd);
            self.last_outputs = Some(pd);
            self.stats.outputs_written = self.stats.outputs_written.wrapping_add(1);
        }
    }

    /// Take a new INPUTS image written for the active telegram.
    pub fn collect(&mut self, node: &mut Node, dpm: &Dpm) {
        match dpm.inputs() {
            Err(_) => self.stats.torn_reads = self.stats.torn_reads.wrapping_add(1),
            Ok(pd) if pd.seq != self.inputs_seq => {
                self.inputs_seq = pd.seq;
                if pd.telegram == self.telegram && self.telegram != Telegram::None {
                    node.slave_mut().set_inputs(pd.bytes());
                    self.stats.inputs_taken = self.stats.inputs_taken.wrapping_add(1);
                } else {
                    self.stats.stale_telegram = self.stats.stale_telegram.wrapping_add(1);
                }
            }
            Ok(_) => {}
        }
    }

    fn write_status(&mut self, node: &Node, card: &mut CardSide<'_>) {
        let s = self.status_of(node);
        if self.last_status != Some(s) {
            card.write_status(&s);
            self.last_status = Some(s);
            self.stats.status_written = self.stats.status_written.wrapping_add(1);
        }
    }
}

/// The telegram of the module the last Chk_Cfg selected.
fn active_telegram(node: &Node) -> Telegram {
    node.slave().module().and_then(Telegram::of_module).unwrap_or(Telegram::None)
}
