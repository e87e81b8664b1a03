//! DP-V1 diagnosis blocks and diagnostic alarms (reference §3.5 "DP-V1 alarm / status block",
//! §4.4 "MSAC_C1 alarms"; the profichip VPC3+ alarm state machine as the model).
//!
//! **Diagnosis format.** With DPV1_Enable (Set_Prm DPV1_Status_1 b7) the device-related block
//! of the extended diagnosis is a DP-V1 PDU: `header (00 + length incl. header), type, slot,
//! specifier, data` ([`device_block`]):
//!
//! * a **diagnostic alarm** (Alarm_Type 1) while one waits to be delivered, data = the drive's
//!   fault code (u16 BE; 0 in a "disappears" alarm for a cleared fault: the code that cleared);
//! * otherwise each device-related block of the drive (DPM `DRIVE.EXT_DIAG`, the vendor data)
//!   as a **Status_Message** (Status_Type 0x81), slot 0, specifier 0, data = the drive's block
//!   without its header.
//!
//! Identifier- and channel-related blocks pass unchanged. Without DPV1_Enable the drive's
//! blocks go out as they are (the DP-V0 vendor block).
//!
//! **Diagnostic alarms** (the only alarm type this card offers; process, pull/plug, status,
//! update and manufacturer alarms are not offered: a Set_Prm enabling one is a Prm_Fault, and
//! status information travels in the Status_Message block, which needs no acknowledgement):
//! enabled by DPV1_Status_2 b5 Enable_Diagnostic_Alarm. While in data exchange, a change of the
//! drive's fault code makes an alarm — 0 → x "appears" (specifier 01, slot disturbed), x → 0
//! "disappears" (10), x → y "appears" with the new code — with the next sequence number
//! (0..=31, specifier b7..b3). At most [`Alarms::limit`] alarms are outstanding (waiting or
//! delivered, not yet acknowledged): DPV1_Status_3 Alarm_Mode 0 = one per type (one here),
//! 1..7 = 2, 4, 8, 12, 16, 24, 32 in total, capped at [`MAX_OUTSTANDING`]
//! (GSD `Alarm_Sequence_Mode_Count`). While the limit is reached no alarm is made; the fault
//! state is compared again after every acknowledgement, so the last change is never lost.
//!
//! An alarm is announced by DH in Data_Exchange and carried in the next Slave_Diag; once the
//! locking master read it, it counts as delivered and the next waiting one is staged (DH
//! again). The master acknowledges with Alarm_Ack `5C slot type specifier` on MSAC_C1 (SAP 51;
//! no Extra_Alarm_SAP): it must name a delivered alarm by slot 0, type 1 and its sequence
//! number (specifier b7..b3 and the appears/disappears bits as sent), else the answer is the
//! DP-V1 error PDU `DC 80 B5 00` (state conflict: no such alarm outstanding; `DC 80 B2 00` for
//! another slot). Leaving data exchange drops every alarm and restarts the numbering.
//! UNVERIFIED: the error codes for a refused Alarm_Ack are our choice — the reference
//! (`profibus-dp-slave.md`) names 0xB5 only for a busy record-47 read and gives no code for
//! an Alarm_Ack that matches no outstanding alarm.

/// Why an Alarm_Ack was refused (MSAC_C1 answers the DP-V1 error PDU: [`AckError::Slot`] →
/// 0xB2 invalid slot, the others → 0xB5 state conflict).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[non_exhaustive]
pub enum AckError {
    /// A slot other than 0 (alarms of this card are all slot 0).
    Slot(u8),
    /// No delivered alarm with this type, sequence number and specifier is outstanding.
    NoSuchAlarm,
    /// Not in data exchange (no alarm relation).
    State,
}

/// An Alarm_Ack's fields (`5C slot alarm_type specifier`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Ack {
    /// Slot_Number.
    pub slot: u8,
    /// Alarm_Type.
    pub alarm_type: u8,
    /// Specifier: Seq_Nr b7..b3, Add_Ack b2, appears / disappears b1..b0.
    pub specifier: u8,
}

/// Alarm_Type of a diagnostic alarm.
pub const ALARM_TYPE_DIAGNOSTIC: u8 = 1;
/// Status_Type Status_Message (b7 set = a status PDU).
pub const STATUS_TYPE_STATUS_MESSAGE: u8 = 0x81;
/// Specifier b1..b0: the error appears (slot disturbed).
pub const SPECIFIER_APPEARS: u8 = 0b01;
/// Specifier b1..b0: the error disappears (slot ok).
pub const SPECIFIER_DISAPPEARS: u8 = 0b10;
/// The most alarms outstanding at once (GSD `Alarm_Sequence_Mode_Count`).
pub const MAX_OUTSTANDING: usize = 8;
/// Bytes of a diagnostic alarm block: 4-byte header + the fault code.
pub const ALARM_BLOCK_LEN: usize = 6;

/// DPV1_Status_2 b5 Enable_Diagnostic_Alarm.
pub const ENABLE_DIAGNOSTIC_ALARM: u8 = 0x20;

/// Outstanding alarms for DPV1_Status_3 `mode` (b2..b0): 0 = one per type (type mode), then
/// 2, 4, 8, 12, 16, 24, 32 in total, capped at [`MAX_OUTSTANDING`].
pub const fn limit_of(mode: u8) -> usize {
    let n = match mode & 0x07 {
        0 => 1,
        1 => 2,
        2 => 4,
        3 => 8,
        4 => 12,
        5 => 16,
        6 => 24,
        _ => 32,
    };
    if n > MAX_OUTSTANDING {
        MAX_OUTSTANDING
    } else {
        n
    }
}

/// One alarm.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Alarm {
    /// Sequence number 0..=31.
    pub seq: u8,
    /// [`SPECIFIER_APPEARS`] or [`SPECIFIER_DISAPPEARS`].
    pub kind: u8,
    /// The drive's fault code it reports.
    pub fault_code: u16,
    /// Read by the locking master in a Slave_Diag (waiting for its Alarm_Ack).
    pub delivered: bool,
}

impl Alarm {
    /// The specifier byte: Seq_Nr in b7..b3, appears / disappears in b1..b0, no Add_Ack.
    pub const fn specifier(&self) -> u8 {
        (self.seq << 3) | self.kind
    }

    /// The device-related block `06 01 00 specifier code_hi code_lo`.
    pub fn block(&self) -> [u8; ALARM_BLOCK_LEN] {
        let c = self.fault_code.to_be_bytes();
        [ALARM_BLOCK_LEN as u8, ALARM_TYPE_DIAGNOSTIC, 0, self.specifier(), c[0], c[1]]
    }
}

/// Counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct AlarmStats {
    /// Alarms made.
    pub raised: u32,
    /// Alarms acknowledged.
    pub acknowledged: u32,
    /// Alarm_Ack refused (no such alarm outstanding, wrong slot / type / sequence number).
    pub bad_acks: u32,
    /// Alarms dropped unacknowledged when data exchange was left.
    pub dropped: u32,
    /// Fault changes that waited because the outstanding limit was reached.
    pub held_back: u32,
}

/// The diagnostic alarm state machine (module docs).
#[derive(Debug, Clone)]
pub struct Alarms {
    enabled: bool,
    limit: usize,
    /// Outstanding alarms, oldest first.
    queue: heapless::Vec<Alarm, MAX_OUTSTANDING>,
    next_seq: u8,
    /// The fault code the last alarm reported (the baseline at the start of data exchange).
    reported: u16,
    /// The drive's fault code now.
    fault: u16,
    stats: AlarmStats,
}

impl Default for Alarms {
    fn default() -> Self {
        Self::new()
    }
}

impl Alarms {
    /// Disabled, nothing outstanding.
    pub const fn new() -> Self {
        Alarms {
            enabled: false,
            limit: 1,
            queue: heapless::Vec::new(),
            next_seq: 0,
            reported: 0,
            fault: 0,
            stats: AlarmStats { raised: 0, acknowledged: 0, bad_acks: 0, dropped: 0, held_back: 0 },
        }
    }

    /// After an accepted Set_Prm: enabled (DPV1_Enable and Enable_Diagnostic_Alarm) and the
    /// Alarm_Mode of DPV1_Status_3.
    pub fn configure(&mut self, enabled: bool, alarm_mode: u8) {
        self.enabled = enabled;
        self.limit = limit_of(alarm_mode);
    }

    /// Whether diagnostic alarms are enabled.
    pub fn enabled(&self) -> bool {
        self.enabled
    }
    /// Outstanding alarms at most.
    pub fn limit(&self) -> usize {
        self.limit
    }
    /// Counters.
    pub fn stats(&self) -> AlarmStats {
        self.stats
    }
    /// Outstanding alarms, oldest first.
    pub fn outstanding(&self) -> &[Alarm] {
        &self.queue
    }

    /// Data exchange begins: the fault present now is the baseline (it shows in the status
    /// block; only changes make alarms).
    pub fn start(&mut self) {
        self.reported = self.fault;
    }

    /// Data exchange ends: every alarm is dropped, the numbering restarts.
    pub fn stop(&mut self) {
        self.stats.dropped = self.stats.dropped.wrapping_add(self.queue.len() as u32);
        self.queue.clear();
        self.next_seq = 0;
        self.reported = self.fault;
    }

    /// The drive's fault code (0 = none). Returns whether a new alarm was made (`in_dx`:
    /// alarms are made only in data exchange).
    pub fn set_fault(&mut self, code: u16, in_dx: bool) -> bool {
        self.fault = code;
        if !in_dx {
            self.reported = code;
            return false;
        }
        self.raise()
    }

    #[inline(never)]
    fn raise(&mut self) -> bool {
        if !self.enabled || self.fault == self.reported {
            return false;
        }
        if self.queue.len() >= self.limit {
            self.stats.held_back = self.stats.held_back.wrapping_add(1);
            return false;
        }
        let (kind, code) =
            if self.fault == 0 { (SPECIFIER_DISAPPEARS, self.reported) } else { (SPECIFIER_APPEARS, self.fault) };
        let a = Alarm { seq: self.next_seq, kind, fault_code: code, delivered: false };
        // Cannot fail: the length was checked against the limit (≤ capacity).
        let _ = self.queue.push(a);
        self.next_seq = (self.next_seq + 1) % 32;
        self.reported = self.fault;
        self.stats.raised = self.stats.raised.wrapping_add(1);
        true
    }

    /// The alarm the next Slave_Diag carries: the oldest one not delivered yet.
    #[inline(never)]
    pub fn to_deliver(&self) -> Option<&Alarm> {
        self.queue.iter().find(|a| !a.delivered)
    }

    /// The locking master read a Slave_Diag carrying [`Self::to_deliver`]. Returns whether
    /// another alarm waits (the diagnosis changes again: DH).
    pub fn delivered(&mut self) -> bool {
        if let Some(a) = self.queue.iter_mut().find(|a| !a.delivered) {
            a.delivered = true;
        }
        self.to_deliver().is_some()
    }

    /// Alarm_Ack from the locking master (module docs). On success the alarm is gone and the
    /// fault state is compared again (returns whether that made a new alarm).
    pub fn acknowledge(&mut self, ack: &Ack) -> Result<bool, AckError> {
        if ack.slot != 0 {
            self.stats.bad_acks = self.stats.bad_acks.wrapping_add(1);
            return Err(AckError::Slot(ack.slot));
        }
        let pos = self.queue.iter().position(|a| {
            a.delivered && ack.alarm_type == ALARM_TYPE_DIAGNOSTIC && ack.specifier & 0xFB == a.specifier()
        });
        let Some(i) = pos else {
            self.stats.bad_acks = self.stats.bad_acks.wrapping_add(1);
            return Err(AckError::NoSuchAlarm);
        };
        // The others keep their order: the alarm moves to the end by swaps and goes, not
        // `Vec::remove` (its `memmove` was one of the firmware's two, 1.5 KiB of flash;
        // footprint, issue 13 item 1).
        for k in i + 1..self.queue.len() {
            self.queue.swap(k - 1, k);
        }
        self.queue.pop();
        self.stats.acknowledged = self.stats.acknowledged.wrapping_add(1);
        Ok(self.raise())
    }
}

/// Build the extended diagnosis from the drive's `blocks` into `out`: as they are without
/// DP-V1, else in the DP-V1 format with `alarm` as the device-related block when given
/// (module docs). Returns the length; blocks that would not fit are left out.
pub fn device_block(blocks: &[u8], dpv1: bool, alarm: Option<&Alarm>, out: &mut [u8]) -> usize {
    if !dpv1 {
        let n = blocks.len().min(out.len());
        out[..n].copy_from_slice(&blocks[..n]);
        return n;
    }
    let mut n = 0;
    if let Some(a) = alarm {
        if out.len() >= ALARM_BLOCK_LEN {
            out[..ALARM_BLOCK_LEN].copy_from_slice(&a.block());
            n = ALARM_BLOCK_LEN;
        }
    }
    let mut i = 0;
    while i < blocks.len() {
        let h = blocks[i];
        let len = match h >> 6 {
            0b10 => 3,
            _ => ((h & 0x3F) as usize).max(1),
        };
        let end = (i + len).min(blocks.len());
        let block = &blocks[i..end];
        if h >> 6 == 0b00 {
            // A device-related vendor block: a Status_Message, unless the alarm takes its place.
            let data = &block[1..];
            let total = 4 + data.len();
            if alarm.is_none() && total <= 63 && n + total <= out.len() {
                out[n..n + 4].copy_from_slice(&[total as u8, STATUS_TYPE_STATUS_MESSAGE, 0, 0]);
                out[n + 4..n + total].copy_from_slice(data);
                n += total;
            }
        } else if n + block.len() <= out.len() {
            out[n..n + block.len()].copy_from_slice(block);
            n += block.len();
        }
        i = end;
    }
    n
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The card's limit.
    fn validate_ext_diag(blocks: &[u8]) -> Result<(), crate::dp::diag::DiagError> {
        crate::dp::diag::validate_ext_diag(blocks, crate::test_card::MAX_EXT_DIAG_LEN)
    }

    fn ack(a: &Alarm) -> Ack {
        Ack { slot: 0, alarm_type: ALARM_TYPE_DIAGNOSTIC, specifier: a.specifier() }
    }

    #[test]
    fn blocks_in_both_formats() {
        let mut out = [0u8; 58];
        let drive = [0x03, 0x01, 0x02, 0x42, 0x01];
        let n = device_block(&drive, false, None, &mut out);
        assert_eq!(&out[..n], &drive, "DP-V0: the vendor block");
        let n = device_block(&drive, true, None, &mut out);
        assert_eq!(&out[..n], &[0x06, 0x81, 0x00, 0x00, 0x01, 0x02, 0x42, 0x01], "Status_Message + identifier block");
        let a = Alarm { seq: 5, kind: SPECIFIER_APPEARS, fault_code: 0x2310, delivered: false };
        let n = device_block(&drive, true, Some(&a), &mut out);
        assert_eq!(&out[..n], &[0x06, 0x01, 0x00, 0x29, 0x23, 0x10, 0x42, 0x01], "alarm, Seq_Nr 5 appears");
        assert_eq!(validate_ext_diag(&out[..n]), Ok(()));
        assert_eq!(device_block(&[], true, None, &mut out), 0);
    }

    #[test]
    fn appears_disappears_ack_and_limit() {
        let mut al = Alarms::new();
        al.configure(true, 0); // type mode: one outstanding
        al.start();
        assert!(al.set_fault(0x2310, true));
        let a = *al.to_deliver().unwrap();
        assert_eq!((a.seq, a.kind, a.fault_code), (0, SPECIFIER_APPEARS, 0x2310));
        // The fault clears before the ack: held back (limit 1).
        assert!(!al.set_fault(0, true));
        assert_eq!(al.stats().held_back, 1);
        // Not delivered yet: an ack is refused.
        assert_eq!(al.acknowledge(&ack(&a)), Err(AckError::NoSuchAlarm));
        assert!(!al.delivered());
        // Wrong sequence number, wrong type, wrong slot.
        let mut bad = ack(&a);
        bad.specifier = 1 << 3 | 1;
        assert_eq!(al.acknowledge(&bad), Err(AckError::NoSuchAlarm));
        assert_eq!(al.acknowledge(&Ack { alarm_type: 2, ..ack(&a) }), Err(AckError::NoSuchAlarm));
        assert_eq!(al.acknowledge(&Ack { slot: 1, ..ack(&a) }), Err(AckError::Slot(1)));
        // The right ack: the held-back change becomes the next alarm (disappears, seq 1).
        assert_eq!(al.acknowledge(&ack(&a)), Ok(true));
        let b = *al.to_deliver().unwrap();
        assert_eq!((b.seq, b.kind, b.fault_code), (1, SPECIFIER_DISAPPEARS, 0x2310));
        assert_eq!(al.stats().bad_acks, 4);
        // Leaving data exchange drops it.
        al.stop();
        assert!(al.outstanding().is_empty());
        assert_eq!(al.stats().dropped, 1);
    }

    #[test]
    fn sequence_numbers_wrap_at_32_and_the_mode_limits() {
        assert_eq!([0, 1, 2, 3, 4, 7].map(limit_of), [1, 2, 4, 8, 8, 8]);
        let mut al = Alarms::new();
        al.configure(true, 2); // 4 outstanding
        al.start();
        for i in 0..4u16 {
            assert!(al.set_fault(0x1000 + i, true));
        }
        assert!(!al.set_fault(0x2000, true), "limit reached");
        for i in 0..40u32 {
            let a = *al.to_deliver().or(al.outstanding().first()).unwrap();
            if !a.delivered {
                al.delivered();
            }
            let a = *al.outstanding().iter().find(|a| a.delivered).unwrap();
            assert_eq!(u32::from(a.seq), i % 32);
            al.acknowledge(&ack(&a)).unwrap();
            al.set_fault(0x3000 + (i as u16 % 2), true);
        }
    }

    #[test]
    fn disabled_or_outside_data_exchange_makes_no_alarm() {
        let mut al = Alarms::new();
        assert!(!al.set_fault(1, true), "disabled");
        al.configure(true, 3);
        assert!(!al.set_fault(2, false), "not in data exchange");
        al.start();
        assert!(!al.set_fault(2, true), "baseline: the fault at the start");
        assert!(al.set_fault(0, true));
    }

    proptest::proptest! {
        /// Any drive blocks: never a panic, and what DP-V1 makes of well-formed blocks is
        /// well-formed again.
        #[test]
        fn any_blocks(blocks in proptest::collection::vec(proptest::num::u8::ANY, 0..40), dpv1 in proptest::bool::ANY,
                      alarm in proptest::option::of((0u8..32, 1u8..3, proptest::num::u16::ANY))) {
            let a = alarm.map(|(seq, kind, fault_code)| Alarm { seq, kind, fault_code, delivered: false });
            let mut out = [0u8; 58];
            let n = device_block(&blocks, dpv1, a.as_ref(), &mut out);
            proptest::prop_assert!(n <= out.len());
            if validate_ext_diag(&blocks).is_ok() && blocks.len() <= 32 {
                proptest::prop_assert_eq!(validate_ext_diag(&out[..n]), Ok(()));
            }
        }

        /// Any sequence of fault codes and acks: outstanding never above the limit, sequence
        /// numbers of outstanding alarms distinct.
        #[test]
        fn any_history(ops in proptest::collection::vec((proptest::num::u16::ANY, proptest::num::u8::ANY), 0..60), mode in 0u8..8) {
            let mut al = Alarms::new();
            al.configure(true, mode);
            al.start();
            for (code, op) in ops {
                match op % 4 {
                    0 => { al.set_fault(code % 3, true); }
                    1 => { al.delivered(); }
                    2 => { let _ = al.acknowledge(&Ack { slot: 0, alarm_type: 1, specifier: op }); }
                    _ => if let Some(a) = al.outstanding().iter().find(|a| a.delivered).copied() { let _ = al.acknowledge(&ack(&a)); },
                }
                proptest::prop_assert!(al.outstanding().len() <= al.limit());
                let mut seqs: Vec<u8> = al.outstanding().iter().map(|a| a.seq).collect();
                seqs.dedup();
                proptest::prop_assert_eq!(seqs.len(), al.outstanding().len());
            }
        }
    }
}
