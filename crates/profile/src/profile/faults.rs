//! The PROFIdrive fault buffer (VACON OPTE3/E5 §6.4.6, Table 112; reference §5.2), read through
//! the card's PNUs ([`super::pnu`]):
//!
//! | PNU | content (Table 112) |
//! |---|---|
//! | 944 | fault message counter: incremented each time the fault buffer changes (UINT16) |
//! | 947 | fault numbers, UINT16\[32\]: [`SITUATIONS`] fault situations × [`MESSAGES`] messages |
//! | 950 | scaling of the fault buffer, UINT16\[2\]: number of fault situations (4), messages per situation (8) |
//!
//! Elements 0..8 of PNU 947 are the *active* fault situation: the drive's faults in the order
//! they arose ("If no fault is active, the active fault situation (first fault situation) is
//! zero", §6.4.6). When the drive clears its faults (a fault reset), the active situation is
//! closed and becomes the most recent acknowledged one: elements 8..16, the older situations
//! moving on by eight elements and the oldest (24..32) dropping out. The fault numbers are the
//! drive's own 16-bit codes ("linked directly from the AC drive fault system", §6.4.6); 0 is
//! no fault. VACON lists no PNU 945 (fault code), 948 (fault time) or 949 for the drive's
//! buffer (Table 108), so there are none here.
//!
//! The manual does not say what happens to a ninth fault in one situation or to a fault that
//! is reported again while active. Here: a fault already in the active situation is not
//! entered twice, and a ninth one is not entered (the first eight, which include the cause,
//! stay); both are counted ([`FaultBuffer::ignored`]) and do not change the buffer, so the
//! message counter does not move either. The counter wraps from 65535 to 0.
//!
//! WEG's CFW-11 P0944 / P0947 (§ parameters) are a one-fault variant of the same idea: counter
//! 0..1, one fault number, cleared by the drive's reset. This module follows VACON; under a WEG
//! telegram PNU 944 reads WEG's 0/1 ([`super::pnu::CardInfo::p0944`]) and P0947's value is
//! element 0, the active fault.

/// Fault situations in the buffer (PNU 950 index 0; OPTE3/E5 Table 112).
pub const SITUATIONS: usize = 4;
/// Fault messages per situation (PNU 950 index 1; OPTE3/E5 Table 112).
pub const MESSAGES: usize = 8;
/// Elements of PNU 947.
pub const LEN: usize = SITUATIONS * MESSAGES;
/// PNU 950, "scaling of the fault buffer": [situations, messages per situation].
pub const SCALING: [u16; 2] = [SITUATIONS as u16, MESSAGES as u16];

const _: () = assert!(LEN == super::pnu::FAULT_BUFFER_LEN, "PNU 947 has 4 x 8 elements");

/// The drive's fault buffer.
#[derive(Debug, Clone, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct FaultBuffer {
    numbers: [u16; LEN],
    counter: u16,
    ignored: u32,
}

impl Default for FaultBuffer {
    fn default() -> Self {
        Self::new()
    }
}

impl FaultBuffer {
    /// Empty: no fault, counter 0.
    pub const fn new() -> Self {
        FaultBuffer { numbers: [0; LEN], counter: 0, ignored: 0 }
    }

    /// The drive reports a new active fault `fault_code` (its own 16-bit number). It is
    /// appended to the active situation and the counter incremented — unless the code is 0
    /// (no fault), already active, or the situation already holds [`MESSAGES`] faults; those
    /// are counted in [`Self::ignored`] and change nothing. Returns whether the buffer changed.
    pub fn report(&mut self, fault_code: u16) -> bool {
        let active = &mut self.numbers[..MESSAGES];
        let free = active.iter().position(|&n| n == 0);
        match free {
            Some(i) if fault_code != 0 && !active.contains(&fault_code) => {
                active[i] = fault_code;
                self.changed();
                true
            }
            _ => {
                self.ignored = self.ignored.wrapping_add(1);
                false
            }
        }
    }

    /// The drive cleared its faults: the active situation (if it holds any fault) is closed and
    /// becomes the most recent acknowledged one, the oldest is dropped, the active situation is
    /// empty and the counter incremented. Without an active fault nothing changes. Returns
    /// whether the buffer changed.
    pub fn acknowledge(&mut self) -> bool {
        if self.active().iter().all(|&n| n == 0) {
            return false;
        }
        // Each situation one place down by swaps from the end, not `copy_within` (its
        // `memmove` was one of the firmware's two, 1.5 KiB of flash; footprint, issue 13 item
        // 1); the first situation's places then hold the dropped one and are cleared.
        for k in (MESSAGES..LEN).rev() {
            self.numbers.swap(k, k - MESSAGES);
        }
        self.numbers[..MESSAGES].fill(0);
        self.changed();
        true
    }

    /// Forget everything (counter included), e.g. at the card's restart.
    pub fn clear(&mut self) {
        *self = Self::new();
    }

    /// PNU 944: the fault message counter.
    pub const fn counter(&self) -> u16 {
        self.counter
    }

    /// PNU 947: the fault numbers, situation by situation (the active one first).
    pub const fn numbers(&self) -> &[u16; LEN] {
        &self.numbers
    }

    /// The active fault situation (PNU 947 elements 0..8; zero-filled after its faults).
    pub fn active(&self) -> &[u16] {
        &self.numbers[..MESSAGES]
    }

    /// Fault situation `k` (0 = active, 1 = most recently acknowledged …), if `k` < 4.
    pub fn situation(&self, k: usize) -> Option<&[u16]> {
        self.numbers.get(k * MESSAGES..(k + 1) * MESSAGES)
    }

    /// Whether a fault is active.
    pub fn has_active_fault(&self) -> bool {
        self.numbers[0] != 0
    }

    /// Reports that changed nothing (0, already active, situation full).
    pub const fn ignored(&self) -> u32 {
        self.ignored
    }

    fn changed(&mut self) {
        self.counter = self.counter.wrapping_add(1);
    }
}

#[cfg(test)]
mod tests {
    use super::super::param::{respond, ErrorValue, ParamRequest, ParamResponse, MAX_LEN};
    use super::super::pnu::{CardInfo, CardTable, PNU_FAULT_COUNTER, PNU_FAULT_NUMBERS, PNU_FAULT_SCALING};
    use super::super::table::{slots, ParamDef, Table, Type};
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn empty() {
        let f = FaultBuffer::new();
        assert_eq!((f.counter(), f.numbers(), f.has_active_fault(), f.ignored()), (0, &[0; LEN], false, 0));
        assert_eq!(SCALING, [4, 8]);
        assert_eq!(f, FaultBuffer::default());
    }

    #[test]
    fn faults_fill_the_active_situation_in_order() {
        let mut f = FaultBuffer::new();
        assert!(f.report(13) && f.report(2) && f.report(56));
        assert_eq!(f.active(), &[13, 2, 56, 0, 0, 0, 0, 0]);
        assert_eq!(f.counter(), 3, "incremented each time the buffer changes (Table 112)");
        assert!(f.has_active_fault());
        assert!(f.numbers()[MESSAGES..].iter().all(|&n| n == 0));
    }

    #[test]
    fn acknowledge_closes_the_situation_and_shifts() {
        let mut f = FaultBuffer::new();
        f.report(13);
        f.report(2);
        assert!(f.acknowledge());
        assert_eq!(f.counter(), 3);
        assert_eq!(f.active(), &[0; MESSAGES], "no fault active: the first situation is zero (§6.4.6)");
        assert_eq!(f.situation(1), Some(&[13, 2, 0, 0, 0, 0, 0, 0][..]));
        // Without an active fault an acknowledge changes nothing.
        assert!(!f.acknowledge());
        assert_eq!(f.counter(), 3);
        f.report(7);
        f.acknowledge();
        assert_eq!(f.situation(1), Some(&[7, 0, 0, 0, 0, 0, 0, 0][..]));
        assert_eq!(f.situation(2), Some(&[13, 2, 0, 0, 0, 0, 0, 0][..]));
        assert_eq!(f.situation(4), None);
    }

    #[test]
    fn the_oldest_situation_drops_out() {
        let mut f = FaultBuffer::new();
        for code in 1..=5u16 {
            f.report(code);
            f.report(100 + code);
            f.acknowledge();
        }
        assert_eq!(f.counter(), 15);
        let firsts: Vec<_> = (0..SITUATIONS).map(|k| f.situation(k).unwrap()[..2].to_vec()).collect();
        assert_eq!(firsts, [vec![0, 0], vec![5, 105], vec![4, 104], vec![3, 103]]);
    }

    #[test]
    fn ignored_reports() {
        let mut f = FaultBuffer::new();
        assert!(!f.report(0));
        assert!(f.report(9));
        assert!(!f.report(9), "already active");
        for code in 10..17 {
            assert!(f.report(code));
        }
        assert!(!f.report(99), "a ninth fault in one situation");
        assert_eq!(f.active(), &[9, 10, 11, 12, 13, 14, 15, 16]);
        assert_eq!((f.counter(), f.ignored()), (8, 3));
        // After the acknowledge the same fault may arise again.
        f.acknowledge();
        assert!(f.report(9));
        f.clear();
        assert_eq!(f, FaultBuffer::new());
    }

    #[test]
    fn counter_wraps() {
        let mut f = FaultBuffer::new();
        f.counter = u16::MAX;
        f.report(1);
        assert_eq!(f.counter(), 0);
    }

    const NO_DEFS: &[ParamDef] = &[ParamDef::new(1, "Dummy", Type::U16)];

    /// PNU 944 / 947 / 950 read through the card's table with record 47 (OPTE3/E5 §6.4).
    #[test]
    fn read_through_the_card_table() {
        let mut f = FaultBuffer::new();
        f.report(0x0102);
        f.report(0x0304);
        f.acknowledge();
        f.report(0x0506);
        let mut drive: Table<{ slots(NO_DEFS) }> = Table::new(NO_DEFS);
        let info = CardInfo {
            address: 3,
            telegram: crate::profile::selection::Telegram::None,
            baud_p963: 5,
            fault_counter: f.counter(),
            faults: *f.numbers(),
            process: super::super::pnu::ProcessView::EMPTY,
            device_id: &[0, 0x0F11, 1, 2026, 2211, 1],
        };
        let mut card = CardTable { info, drive: &mut drive };
        let [c0, c1] = PNU_FAULT_COUNTER.to_be_bytes();
        let [n0, n1] = PNU_FAULT_NUMBERS.to_be_bytes();
        let [s0, s1] = PNU_FAULT_SCALING.to_be_bytes();
        #[rustfmt::skip]
        let req = [
            0x21, 0x01, 0x01, 0x04,
            0x10, 0x00, c0, c1, 0x00, 0x00,
            0x10, 0x03, n0, n1, 0x00, 0x07,
            0x10, 0x02, s0, s1, 0x00, 0x00,
            0x10, 0x01, n0, n1, 0x00, 0x20,
        ];
        let req = ParamRequest::parse(&req).unwrap();
        let mut out = [0u8; MAX_LEN];
        let n = respond(&req, &mut card, &mut out);
        #[rustfmt::skip]
        let expected = [
            0x21, 0x81, 0x01, 0x04,
            0x42, 0x01, 0x00, 0x04,
            0x42, 0x03, 0x00, 0x00, 0x01, 0x02, 0x03, 0x04,
            0x42, 0x02, 0x00, 0x04, 0x00, 0x08,
            0x44, 0x01, 0x00, 0x03,
        ];
        assert_eq!(&out[..n], &expected);
        let r = ParamResponse::parse(&out[..n]).unwrap();
        let last = r.values().last().and_then(|b| b.error()).map(|e| e.value);
        assert_eq!(last, Some(ErrorValue::INVALID_SUBINDEX), "PNU 947 has 32 elements");
        assert_eq!(f.active()[0], 0x0506);
    }

    #[derive(Debug, Clone)]
    enum Event {
        Report(u16),
        Acknowledge,
    }

    fn events() -> impl Strategy<Value = Vec<Event>> {
        let code = prop_oneof![0u16..12, any::<u16>()];
        let event = prop_oneof![3 => code.prop_map(Event::Report), 1 => Just(Event::Acknowledge)];
        proptest::collection::vec(event, 0..200)
    }

    proptest! {
        #[test]
        fn any_sequence_keeps_the_buffer_well_formed(events in events()) {
            let mut f = FaultBuffer::new();
            let mut changes = 0u32;
            for e in events {
                let before = f.clone();
                let changed = match e {
                    Event::Report(code) => f.report(code),
                    Event::Acknowledge => f.acknowledge(),
                };
                prop_assert_eq!(changed, f.numbers() != before.numbers());
                changes += u32::from(changed);
                prop_assert_eq!(f.counter(), changes as u16);
                prop_assert_eq!(f.numbers().len(), LEN);
                for k in 0..SITUATIONS {
                    let s = f.situation(k).unwrap();
                    // Each situation: its faults first, then zeros; no fault twice.
                    let used = s.iter().take_while(|&&n| n != 0).count();
                    prop_assert!(s[used..].iter().all(|&n| n == 0), "{:?}", s);
                    let mut seen = s[..used].to_vec();
                    seen.sort_unstable();
                    seen.dedup();
                    prop_assert_eq!(seen.len(), used);
                }
                if let Event::Acknowledge = e {
                    prop_assert!(!f.has_active_fault());
                    if changed {
                        prop_assert_eq!(f.situation(1), before.situation(0));
                        prop_assert_eq!(f.situation(3), before.situation(2));
                    }
                }
            }
        }
    }
}
