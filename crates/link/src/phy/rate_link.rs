//! The rate control split between the line interrupt and a lower-priority task, lock-free
//! (issue 11 item 1 on a DMA line with autobaud): the line classifies every telegram and
//! answers only while the rate is locked; the search and supervision ([`Autobaud`],
//! reference §1.6) run in the lower task, which also decides the rate switches the line
//! then carries out. No lock, no critical section: five [`AtomicU32`] words, each with one
//! writer.
//!
//! | word | written by | read by | holds |
//! |---|---|---|---|
//! | `ok` | the line ([`RateTap::account`]) | the keeper | generation (8 bits) · count (16 bits) of error-free SD1/SD2/SD3 telegrams, any address |
//! | `to_us` | the line ([`RateTap::account`]) | the keeper | generation · count of such telegrams addressed to the station |
//! | `garbage` | the line ([`RateTap::account`]) | the keeper | count of invalid telegrams ([`Autobaud::on_garbage`], statistics) |
//! | `request` | the keeper ([`RateKeeper::poll`]) | the line ([`RateTap::take_switch`]) | generation · index into [`Baudrate::ALL`] of the rate to listen at |
//! | `verdict` | the keeper ([`RateKeeper::poll`]) | the line ([`RateTap::may_answer`]) | generation · locked · the `ok` count the keeper has accounted |
//!
//! **Generations.** Each rate switch the keeper asks for carries a new generation; the line
//! adopts it when it carries the switch out and restarts its counts tagged with it. Counts
//! of another generation (telegrams received at the old rate after the keeper had decided to
//! leave it) are never accounted, so the search cannot lock on a rate it has left.
//!
//! **The gate** ([`RateTap::may_answer`], the `detected()` gate of
//! [`crate::node::answer`]): open while the keeper's newest verdict for the line's generation
//! says "locked", or while the line has counted an error-free telegram the keeper has not
//! accounted yet — the keeper, searching, locks on it at its next poll, so the first request
//! of a master is answered at once, as the single-task integration did. Closed while a
//! switch is asked for and not carried out. The keeper accounts the counts at its poll (every
//! millisecond) with its own `now`: a lock or a Baud_Control retrigger is at most one poll
//! period late, which only extends T_bc by that much. One race is left: a telegram counted
//! between the keeper's reading of the counts and its switch request (a few instructions at
//! the end of a dwell) may be answered although the keeper then leaves the rate; the master
//! repeats and the search comes back to the rate within one scan.

use core::sync::atomic::{AtomicU32, Ordering};

use super::autobaud::{Autobaud, AutobaudStats};
use super::line::FrameClass;
use crate::time::{Baudrate, Instant};

const LOCKED: u32 = 1 << 16;

fn gen_of(word: u32) -> u8 {
    (word >> 24) as u8
}

fn index_of(rate: Baudrate) -> u32 {
    Baudrate::ALL.iter().position(|&r| r == rate).unwrap_or(0) as u32
}

/// What the line and the keeper share: put it in a `static` place and
/// [`split`](Self::split) it once.
#[derive(Debug, Default)]
pub struct RateLink {
    ok: AtomicU32,
    to_us: AtomicU32,
    garbage: AtomicU32,
    request: AtomicU32,
    verdict: AtomicU32,
}

impl RateLink {
    /// All words zero (generation 0, nothing counted, not locked).
    pub const fn new() -> Self {
        RateLink {
            ok: AtomicU32::new(0),
            to_us: AtomicU32::new(0),
            garbage: AtomicU32::new(0),
            request: AtomicU32::new(0),
            verdict: AtomicU32::new(0),
        }
    }

    /// The line half and the keeper half around `autobaud`; the line listens at
    /// `autobaud.rate()` from the start (generation 0).
    pub fn split(&mut self, autobaud: Autobaud) -> (RateTap<'_>, RateKeeper<'_>) {
        *self = RateLink::new();
        self.request.store(index_of(autobaud.rate()), Ordering::Release);
        let link: &RateLink = self;
        (
            RateTap { link, gen: 0, ok: 0, to_us: 0, garbage: 0 },
            RateKeeper { link, autobaud, gen: 0, ok_seen: 0, to_us_seen: 0, garbage_seen: 0 },
        )
    }
}

/// The line half (the line interrupt): accounts every telegram, carries out the rate
/// switches, asks the gate before every answer.
#[derive(Debug)]
pub struct RateTap<'a> {
    link: &'a RateLink,
    gen: u8,
    ok: u16,
    to_us: u16,
    garbage: u32,
}

impl RateTap<'_> {
    /// The rate switch the keeper asked for, once: program the USART to it and restart the
    /// receiver. From here on the line's counts carry the new generation.
    pub fn take_switch(&mut self) -> Option<Baudrate> {
        let r = self.link.request.load(Ordering::Acquire);
        let gen = gen_of(r << 16);
        if gen == self.gen {
            return None;
        }
        self.gen = gen;
        self.ok = 0;
        self.to_us = 0;
        let tag = u32::from(gen) << 24;
        self.link.ok.store(tag, Ordering::Release);
        self.link.to_us.store(tag, Ordering::Release);
        Baudrate::ALL.get((r & 0xFF) as usize).copied()
    }

    /// A telegram at the current rate, classified ([`super::line::classify`]).
    pub fn account(&mut self, class: FrameClass) {
        let tag = u32::from(self.gen) << 24;
        if class.invalid {
            self.garbage = self.garbage.wrapping_add(1);
            self.link.garbage.store(self.garbage, Ordering::Release);
            return;
        }
        if class.ok_sd123 {
            self.ok = self.ok.wrapping_add(1);
            self.link.ok.store(tag | u32::from(self.ok), Ordering::Release);
        }
        if class.to_us {
            self.to_us = self.to_us.wrapping_add(1);
            self.link.to_us.store(tag | u32::from(self.to_us), Ordering::Release);
        }
    }

    /// Whether an answer may go out now (the rate is locked, see the module documentation).
    /// `valid_request`: the telegram being answered is itself an error-free SD1/SD2/SD3
    /// telegram not yet [accounted](Self::account) (a request the fast path answered).
    pub fn may_answer(&self, valid_request: bool) -> bool {
        let req = self.link.request.load(Ordering::Acquire);
        if gen_of(req << 16) != self.gen {
            return false;
        }
        let v = self.link.verdict.load(Ordering::Acquire);
        if gen_of(v) != self.gen {
            return false;
        }
        v & LOCKED != 0 || valid_request || self.ok != v as u16
    }
}

/// The keeper half (a low-priority task, every millisecond): owns the [`Autobaud`] machine.
#[derive(Debug)]
pub struct RateKeeper<'a> {
    link: &'a RateLink,
    autobaud: Autobaud,
    gen: u8,
    ok_seen: u16,
    to_us_seen: u16,
    garbage_seen: u32,
}

impl RateKeeper<'_> {
    /// The line's telegrams since the last call into the machine, its timers, and the
    /// verdict for the line's gate. Returns the new rate when the search stepped on: the
    /// request is published; the platform makes the line take it ([`RateTap::take_switch`]).
    pub fn poll(&mut self, now: Instant) -> Option<Baudrate> {
        let garbage = self.link.garbage.load(Ordering::Acquire);
        // Statistics only: bounded so a long pause costs nothing.
        for _ in 0..garbage.wrapping_sub(self.garbage_seen).min(64) {
            self.autobaud.on_garbage(now);
        }
        self.garbage_seen = garbage;
        let ok = self.link.ok.load(Ordering::Acquire);
        let to_us = self.link.to_us.load(Ordering::Acquire);
        let mut new_ok = false;
        let mut new_to_us = false;
        if gen_of(ok) == self.gen && ok as u16 != self.ok_seen {
            self.ok_seen = ok as u16;
            new_ok = true;
        }
        if gen_of(to_us) == self.gen && to_us as u16 != self.to_us_seen {
            self.to_us_seen = to_us as u16;
            new_to_us = true;
        }
        // One call stands for all of them: the first locks (searching), the newest
        // addressed to us retriggers Baud_Control — the state the calls in order leave.
        if new_ok || new_to_us {
            self.autobaud.on_frame(now, true, new_to_us);
        }
        let switch = self.autobaud.poll(now);
        if let Some(rate) = switch {
            self.gen = self.gen.wrapping_add(1);
            self.ok_seen = 0;
            self.to_us_seen = 0;
            self.link.request.store((u32::from(self.gen) << 8) | index_of(rate), Ordering::Release);
        }
        let locked = if self.autobaud.detected().is_some() { LOCKED } else { 0 };
        self.link.verdict.store((u32::from(self.gen) << 24) | locked | u32::from(self.ok_seen), Ordering::Release);
        switch
    }

    /// [`Autobaud::dp_watchdog_active`].
    pub fn dp_watchdog_active(&mut self, now: Instant, active: bool) {
        self.autobaud.dp_watchdog_active(now, active);
    }

    /// The locked rate (`None` while searching), as of the last [`poll`](Self::poll).
    pub fn detected(&self) -> Option<Baudrate> {
        self.autobaud.detected()
    }

    /// The rate the line listens at (or is asked to switch to).
    pub fn rate(&self) -> Baudrate {
        self.autobaud.rate()
    }

    /// Whether the line has carried out the last switch asked for.
    pub fn switched(&self) -> bool {
        gen_of(self.link.ok.load(Ordering::Acquire)) == self.gen
    }

    /// The machine's counters.
    pub fn stats(&self) -> AutobaudStats {
        self.autobaud.stats()
    }

    /// The machine.
    pub fn autobaud(&self) -> &Autobaud {
        &self.autobaud
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const OK: FrameClass = FrameClass { ok_sd123: true, to_us: false, invalid: false };
    const TO_US: FrameClass = FrameClass { ok_sd123: true, to_us: true, invalid: false };
    const BAD: FrameClass = FrameClass { ok_sd123: false, to_us: false, invalid: true };

    fn ms(n: u64) -> Instant {
        Instant::from_millis(n)
    }

    #[test]
    fn the_gate_follows_the_keeper() {
        let mut link = RateLink::new();
        let (mut tap, mut keeper) = link.split(Autobaud::new(ms(0)));
        assert_eq!(tap.take_switch(), None, "the line starts at the search's first rate");
        assert!(!tap.may_answer(false), "searching: no answer");
        // The first valid request is answered at once (the keeper locks on it next).
        assert!(tap.may_answer(true));
        tap.account(TO_US);
        assert!(tap.may_answer(false), "counted, not yet accounted: the keeper will lock");
        assert_eq!(keeper.poll(ms(1)), None);
        assert_eq!(keeper.detected(), Some(Baudrate::B12M));
        assert!(tap.may_answer(false));
        // Baud_Control: no telegram to us for T_bc → searching again at the same rate.
        let tbc = crate::phy::autobaud::Config::default().baud_control.as_micros() / 1000;
        tap.account(OK);
        assert_eq!(keeper.poll(ms(1 + tbc)), None);
        assert_eq!(keeper.detected(), None);
        assert!(!tap.may_answer(false));
        assert!(tap.may_answer(true));
    }

    #[test]
    fn telegrams_of_a_rate_left_are_not_accounted() {
        let mut link = RateLink::new();
        let (mut tap, mut keeper) = link.split(Autobaud::new(ms(0)));
        let dwell = crate::phy::autobaud::dwell(Baudrate::B12M).as_micros() / 1000;
        // Garbage only: the search steps on.
        tap.account(BAD);
        assert_eq!(keeper.poll(ms(dwell)), Some(Baudrate::B6M));
        assert_eq!(keeper.stats().garbage, 1);
        assert!(!keeper.switched());
        // A valid telegram counted before the line carried out the switch (at 12M): ignored,
        // and the gate is shut meanwhile.
        assert!(!tap.may_answer(true));
        tap.account(OK);
        assert_eq!(keeper.poll(ms(dwell + 1)), None);
        assert_eq!(keeper.detected(), None);
        assert_eq!(tap.take_switch(), Some(Baudrate::B6M));
        assert_eq!(tap.take_switch(), None);
        assert!(keeper.switched());
        tap.account(OK);
        assert!(tap.may_answer(false));
        keeper.poll(ms(dwell + 2));
        assert_eq!(keeper.detected(), Some(Baudrate::B6M));
    }

    proptest! {
        /// Any sequence of telegram classes per millisecond and DP watchdog states: the
        /// split machine ends every millisecond in the state of one `Autobaud` fed the same
        /// telegrams at the keeper's poll time, and the gate opens exactly when that machine
        /// has (or, for a valid request, would have) locked.
        #[test]
        fn the_split_equals_one_machine(
            steps in proptest::collection::vec((proptest::collection::vec(0u8..4, 0..4), any::<bool>(), 1u64..400), 1..200)
        ) {
            let mut link = RateLink::new();
            let (mut tap, mut keeper) = link.split(Autobaud::new(ms(0)));
            let mut alone = Autobaud::new(ms(0));
            let mut t = 0u64;
            for (frames, watchdog, dt) in steps {
                for f in &frames {
                    let class = [OK, TO_US, BAD, FrameClass::default()][usize::from(*f)];
                    tap.account(class);
                }
                t += dt;
                let now = ms(t);
                keeper.dp_watchdog_active(now, watchdog);
                alone.dp_watchdog_active(now, watchdog);
                let ok = frames.iter().any(|&f| f < 2);
                let to_us = frames.contains(&1);
                for f in &frames {
                    if *f == 2 {
                        alone.on_garbage(now);
                    }
                }
                if ok {
                    alone.on_frame(now, true, to_us);
                }
                let want = alone.poll(now);
                prop_assert_eq!(keeper.poll(now), want);
                prop_assert_eq!(tap.take_switch(), want);
                prop_assert_eq!(keeper.detected(), alone.detected());
                prop_assert_eq!(keeper.rate(), alone.rate());
                prop_assert_eq!(keeper.stats(), alone.stats());
                prop_assert_eq!(tap.may_answer(false), alone.detected().is_some());
                prop_assert_eq!(tap.may_answer(true), true);
            }
        }
    }
}
