//! The speed references of the profile scales, read from the drive's own parameters (issue 15
//! item 10): the card's [`Scales`] are not fixed at 50 Hz but follow what the drive is
//! commissioned with.
//!
//! | family | read from the drive (through the DPM parameter mailbox) | scale |
//! |---|---|---|
//! | VACON PPO / Bypass (OPTE3/E5 §6.3.5, Table 29) | ID 101 minimum, ID 102 maximum frequency, ID 111 motor nominal frequency (PNU 10001, the ID as subindex; 0.01 Hz) | 0..10000 = min..max; N2 0x4000 = ID 111 (the frequency of P10111's nominal speed, §6.3.7) |
//! | WEG (CFW500 §5.1 P0681 / P0685, P0741 PROFIdrive speed) | P0403 rated frequency (Hz), P0134 maximum speed and P10111 synchronous speed (rpm) | 8192 = P0403 = N2 0x4000; PROFIdrive 16384 = P0134 (converted to Hz through P10111 ↔ P0403) |
//! | INVT (INVT Table 2-6) | P00.03 maximum frequency Fmax, P02.02 motor rated frequency (0.01 Hz; PKW-style address group × 256 + code) | 0..Fmax; N2 0x4000 = P02.02 |
//!
//! Standard telegrams 1 / 20 and the VACON telegrams with PROFIdrive carry N2 itself: nothing
//! to read. A value the drive does not have (an error answer) keeps the card's default
//! ([`Scales::DEFAULT`], 50.00 Hz); a value out of range (0, or a minimum not below the
//! maximum) is not taken either.
//!
//! **When:** the references are read after every new selection (Chk_Cfg of a telegram, a new
//! operate mode or data profile): a parameter changed later takes effect with the next
//! selection, as a drive's fieldbus scaling normally does with the next start of the cyclic
//! exchange. Until the values are in (a few mailbox round trips, milliseconds) the defaults
//! apply; the profile keeps its state when the scale changes.
//!
//! **Mailbox sharing:** the reads go through the DPM parameter mailbox, one request at a
//! time, in the answer cache of record 47 (`app::Card`): neither takes the other's
//! answers. A read still unanswered after [`RETRY_AFTER`] is waited for again; after
//! [`TRIES`] such periods the defaults stay (counted in [`ReferenceStats::gave_up`]).

use super::param::{Attribute, ParamAddress, ParameterAccess, ValueWriter};
use super::runtime::Scales;
use super::telegram::{DataProfile, Layout, ProfileFamily};
use crate::profile::selection::Telegram;
use crate::time::{Duration, Instant};

/// How long one read may stay unanswered before it is asked again.
pub const RETRY_AFTER: Duration = Duration::from_millis(500);
/// Attempts per selection before the defaults are kept.
pub const TRIES: u8 = 3;

/// PNU 10001 "parameter in drive" (OPTE3/E5 §6.4.4.7): the VACON application ID as subindex.
const VACON_ID: u16 = 10001;

/// Which parameters a family's scales need.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Plan {
    /// N2 on the wire, or no telegram: nothing to read.
    None,
    /// VACON PPO / Bypass: ID 101, ID 102, ID 111.
    Vacon,
    /// WEG: P0403, P0134, P10111.
    Weg,
    /// INVT: P00.03, P02.02.
    Invt,
}

impl Plan {
    /// The (PNU, subindex) reads of the plan.
    const fn reads(self) -> &'static [(u16, u16)] {
        match self {
            Plan::None => &[],
            Plan::Vacon => &[(VACON_ID, 101), (VACON_ID, 102), (VACON_ID, 111)],
            Plan::Weg => &[(403, 0), (134, 0), (10111, 0)],
            Plan::Invt => &[(0x0003, 0), (0x0202, 0)],
        }
    }
}

/// Counters.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ReferenceStats {
    /// Sets of references read completely and applied.
    pub applied: u32,
    /// Reads asked again (no answer within [`RETRY_AFTER`]).
    pub retries: u32,
    /// Selections whose reads were given up ([`TRIES`]): the defaults stay.
    pub gave_up: u32,
}

/// The reader (module docs).
#[derive(Debug, Clone)]
pub struct References {
    plan: Plan,
    /// Values read so far (`Some(None)`: the drive answered with an error — default).
    values: [Option<Option<i64>>; 3],
    busy: bool,
    tries: u8,
    since: Option<Instant>,
    stats: ReferenceStats,
}

impl Default for References {
    fn default() -> Self {
        Self::new()
    }
}

impl References {
    /// Idle.
    pub const fn new() -> Self {
        References {
            plan: Plan::None,
            values: [None; 3],
            busy: false,
            tries: 0,
            since: None,
            stats: ReferenceStats { applied: 0, retries: 0, gave_up: 0 },
        }
    }

    /// A new selection: read what `telegram` with the drive's data profile `data` needs (in
    /// the Bypass operate mode the drive scales the raw words itself; the reads do no harm).
    pub fn start(&mut self, telegram: Telegram, data: DataProfile) {
        let plan = match Layout::of(telegram).map(|l| l.profile(data)) {
            Some(ProfileFamily::Profidrive20) => Plan::Vacon,
            Some(ProfileFamily::WegManufacturer | ProfileFamily::WegProfidrive) => Plan::Weg,
            Some(ProfileFamily::Invt) => Plan::Invt,
            _ => Plan::None,
        };
        *self = References { plan, busy: plan != Plan::None, stats: self.stats, ..References::new() };
    }

    /// Whether reads are outstanding.
    pub fn is_busy(&self) -> bool {
        self.busy
    }

    /// Counters.
    pub fn stats(&self) -> ReferenceStats {
        self.stats
    }

    /// Work on the reads against the drive's `table` at `now`; the new scales (from `base`,
    /// the fields this family has) once every value is in.
    pub fn service(&mut self, now: Instant, table: &mut impl ParameterAccess, base: Scales) -> Option<Scales> {
        if !self.busy {
            return None;
        }
        // No `start_job` of its own: the app shares the record-47 cache (its job's answers
        // stay; ours are asked for by key).
        for (k, &(pnu, subindex)) in self.plan.reads().iter().enumerate() {
            if self.values[k].is_some() {
                continue;
            }
            let addr = ParamAddress { attribute: Attribute::Value, elements: 1, pnu, subindex };
            let mut buf = [0u8; 8];
            let mut w = ValueWriter::new(&mut buf);
            match table.read_value(1, &addr, &mut w) {
                Ok(()) => {
                    let v = match *w.bytes() {
                        [a, b] => Some(i64::from(u16::from_be_bytes([a, b]))),
                        [a, b, c, d] => Some(i64::from(u32::from_be_bytes([a, b, c, d]))),
                        _ => None,
                    };
                    self.values[k] = Some(v);
                    self.since = None;
                }
                Err(_) if table.pending() => {
                    let since = *self.since.get_or_insert(now);
                    if now >= since + RETRY_AFTER {
                        // The answer went to another client of the mailbox: ask again.
                        self.tries += 1;
                        self.since = None;
                        if self.tries >= TRIES {
                            self.busy = false;
                            self.stats.gave_up = self.stats.gave_up.wrapping_add(1);
                        } else {
                            self.stats.retries = self.stats.retries.wrapping_add(1);
                        }
                    }
                    return None;
                }
                // The drive has no such parameter: the default stays.
                Err(_) => self.values[k] = Some(None),
            }
        }
        self.busy = false;
        self.stats.applied = self.stats.applied.wrapping_add(1);
        Some(self.scales(base))
    }

    /// The scales from the values read (module docs), in 0.01 Hz.
    fn scales(&self, base: Scales) -> Scales {
        let v = |k: usize| self.values[k].flatten().filter(|&x| x > 0);
        let hz100 = |x: i64| u32::try_from(x).unwrap_or(0);
        let mut s = base;
        match self.plan {
            Plan::None => {}
            Plan::Vacon => {
                let min = self.values[0].flatten().filter(|&x| x >= 0).map_or(s.bypass_min, hz100);
                let max = v(1).map_or(s.bypass_max, hz100);
                if min < max {
                    (s.bypass_min, s.bypass_max) = (min, max);
                }
                if let Some(n) = v(2) {
                    s.n2_reference = hz100(n);
                }
            }
            Plan::Weg => {
                if let Some(rated) = v(0) {
                    // P0403 in Hz: 8192 of P0681 / P0685 and the N2 reference.
                    s.weg_rated = hz100(rated * 100);
                    s.n2_reference = s.weg_rated;
                }
                if let (Some(p0134), Some(sync)) = (v(1), v(2)) {
                    // P0134 in rpm, P10111 the synchronous speed that P0403 stands for.
                    s.weg_p0134 = hz100(p0134 * i64::from(s.weg_rated) / sync);
                }
            }
            Plan::Invt => {
                if let Some(fmax) = v(0) {
                    s.invt_fmax = hz100(fmax);
                }
                if let Some(rated) = v(1) {
                    s.n2_reference = hz100(rated);
                }
            }
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::profile::param::ErrorValue;
    use crate::profile::selection::Family;
    use crate::profile::table::{slots, ParamDef, Table, Type};
    use crate::testkit::{FakeDrive, Indirect, Mailbox};

    /// The drives of the three families, each the one fake drive (`testkit::FakeDrive`) behind
    /// the mailbox (`testkit::Mailbox`: each value needs one more call, as over the DPM): VACON
    /// IDs 101, 102, 111 through PNU 10001; WEG P0403, P0134, P10111; INVT P00.03 (P02.02
    /// missing).
    const VACON: &[ParamDef] = &[
        ParamDef::new(101, "Min frequency", Type::U16).with_default(500),
        ParamDef::new(102, "Max frequency", Type::U16).with_default(6000),
        ParamDef::new(111, "Speed ref", Type::U16).with_default(5000),
    ];
    const WEG: &[ParamDef] = &[
        ParamDef::new(134, "Maximum speed", Type::U16).with_default(900),
        ParamDef::new(403, "Rated frequency", Type::U16).with_default(60),
        ParamDef::new(10111, "Speed ref", Type::U16).with_default(1800),
    ];
    const INVT: &[ParamDef] = &[ParamDef::new(3, "Max frequency", Type::U16).with_default(10000)];

    fn drive<const N: usize>(defs: &'static [ParamDef]) -> Mailbox<FakeDrive<N>> {
        let ids = Indirect {
            pnu: VACON_ID,
            not_found: ErrorValue::IMPERMISSIBLE_PARAMETER_NUMBER,
            ids: 101..=111,
            ids_only: true,
        };
        Mailbox::new(FakeDrive::with_table(Table::new(defs)).any_axis().indirect(ids))
    }

    /// Service until the references are read, the drive answering between the calls.
    fn run(r: &mut References, d: &mut Mailbox<impl ParameterAccess>) -> Scales {
        for k in 0..20 {
            if let Some(s) = r.service(Instant::from_millis(k), d, Scales::DEFAULT) {
                return s;
            }
            d.deliver();
        }
        panic!("not done");
    }

    #[test]
    fn each_family_reads_its_references() {
        let mut r = References::new();
        r.start(Telegram::Ppo(1), DataProfile::Factory);
        let mut d = drive::<{ slots(VACON) }>(VACON);
        let s = run(&mut r, &mut d);
        assert_eq!((s.bypass_min, s.bypass_max, s.n2_reference), (500, 6000, 5000));
        r.start(Telegram::Vendor(Family::WegCfw500, 103), DataProfile::Factory);
        let mut d = drive::<{ slots(WEG) }>(WEG);
        let s = run(&mut r, &mut d);
        assert_eq!((s.weg_rated, s.n2_reference, s.weg_p0134), (6000, 6000, 3000));
        r.start(Telegram::Vendor(Family::Invt, 1), DataProfile::Factory);
        let mut d = drive::<{ slots(INVT) }>(INVT);
        let s = run(&mut r, &mut d);
        assert_eq!((s.invt_fmax, s.n2_reference), (10000, 5000), "P02.02 missing: the default stays");
        assert_eq!(r.stats().applied, 3);
        // N2 telegrams read nothing.
        r.start(Telegram::Standard(1), DataProfile::Factory);
        assert!(!r.is_busy());
    }

    #[test]
    fn an_unanswered_read_is_retried_then_given_up() {
        // The drive never answers: the mailbox stays in flight.
        let mut silent = Mailbox::new(FakeDrive::empty());
        let mut r = References::new();
        r.start(Telegram::Vendor(Family::Invt, 1), DataProfile::Factory);
        for ms in (0..2000).step_by(10) {
            assert_eq!(r.service(Instant::from_millis(ms), &mut silent, Scales::DEFAULT), None);
        }
        assert!(!r.is_busy());
        assert_eq!((r.stats().retries, r.stats().gave_up), (2, 1));
    }
}
