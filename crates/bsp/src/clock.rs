//! Time base: the RTIC SysTick monotonic (1 kHz, for `delay`/`delay_until` of software
//! tasks) and a microsecond [`Clock`] derived from the same SysTick (the millisecond count
//! plus the SysTick down-counter inside the current millisecond).
//!
//! The monotonic's 32-bit millisecond count wraps after 49.7 days; [`SysTickClock`] extends
//! it to 64 bits, which only needs `now()` to be called at least once per wrap period (the
//! 1 ms housekeeping task does).
//!
//! QEMU: the SysTick exception keeps its reset priority 0, the same hardware priority as the
//! highest RTIC task (the USART1 handler): neither preempts the other. F411: SysTick runs at
//! logical priority 2 (`f411::SYSTICK_PRIORITY_HW`), below the line, and [`SysTickClock`]'s
//! short critical section masks only the priorities up to 15 (BASEPRI), never the line's 16
//! (issue 11 item 3c): the line interrupts read the clock without it
//! ([`SysTickClock::line_now`], for the fast path's telegram times).
//!
//! On the F411 the line times itself with TIM5 (`crates/bsp/src/f411.rs`); this clock serves the protocol timers;
//! under QEMU the SysTick runs at 168 MHz whatever RCC says: pass that as `sysclk_hz`.

use core::cell::Cell;

use cortex_m::interrupt::{self, Mutex};
use cortex_m::peripheral::SYST;
use pbcard::time::Instant;
use rtic_monotonics::rtic_time::monotonic::TimerQueueBasedInstant;
use rtic_monotonics::systick::prelude::*;

use super::Clock;

/// Tick rate of the SysTick monotonic.
pub const MONO_HZ: u32 = 1_000; // keep equal to the literal in `systick_monotonic!` below

systick_monotonic!(Mono, 1_000);

/// Upper 32 bits of the millisecond count and the last lower half seen.
static EXTEND: Mutex<Cell<(u32, u32)>> = Mutex::new(Cell::new((0, 0)));

/// [`EXTEND`] for the line's lock-free reading ([`SysTickClock::line_now`]), one word:
/// the upper half of the millisecond count (bits 31..1) and the top bit of the last lower
/// half seen (bit 0). Written only inside the clock's critical section, after `EXTEND`.
#[cfg(feature = "board-f411")]
static EXTEND_WORD: core::sync::atomic::AtomicU32 = core::sync::atomic::AtomicU32::new(0);

/// The microsecond clock (cheap to copy; all copies share the same time base).
#[derive(Debug, Clone, Copy)]
pub struct SysTickClock {
    /// SysTick reload value (core cycles per millisecond − 1).
    reload: u32,
    /// Core cycles per microsecond.
    cycles_per_us: u32,
}

/// Start the SysTick monotonic with the core clock `sysclk_hz` (a multiple of 1 MHz).
pub fn start(syst: SYST, sysclk_hz: u32) -> SysTickClock {
    assert!(sysclk_hz.is_multiple_of(1_000_000) && sysclk_hz >= 1_000_000);
    Mono::start(syst, sysclk_hz);
    SysTickClock { reload: sysclk_hz / MONO_HZ - 1, cycles_per_us: sysclk_hz / 1_000_000 }
}

impl SysTickClock {
    /// Milliseconds since start (64-bit) and core cycles into the current millisecond.
    fn sample(&self) -> (u64, u32) {
        below_line(|cs| {
            // `Mono::now()` notices a pending SysTick wrap itself (COUNTFLAG), so inside
            // this critical section the count and the down-counter are consistent once two
            // reads of the count agree around the read of the counter.
            let mut lo = Mono::now().ticks();
            let mut cvr = SYST::get_current();
            let lo2 = Mono::now().ticks();
            if lo2 != lo {
                lo = lo2;
                cvr = SYST::get_current();
            }
            let cell = EXTEND.borrow(cs);
            let (mut hi, last) = cell.get();
            if lo < last {
                hi = hi.wrapping_add(1);
            }
            cell.set((hi, lo));
            #[cfg(feature = "board-f411")]
            EXTEND_WORD.store((hi << 1) | (lo >> 31), core::sync::atomic::Ordering::Release);
            let elapsed = self.reload.saturating_sub(cvr);
            ((u64::from(hi) << 32) | u64::from(lo), elapsed)
        })
    }
}

#[cfg(feature = "board-f411")]
impl SysTickClock {
    /// The time for the line interrupts (F411, logical priority 16, above the clock's
    /// critical section), without a critical section and without writing `EXTEND`: the
    /// millisecond count and the down-counter read as in `sample` (two reads of the count
    /// around the counter), the upper half from [`EXTEND_WORD`] (advanced here when the
    /// lower half wrapped since the tasks last read it — they do every millisecond). One
    /// race is left: the line preempting a lower reader (or the SysTick handler) between its
    /// read of the SysTick wrap flag (COUNTFLAG, cleared by that read) and its increment of
    /// the count sees the old count with the new down-counter — a time up to 1 ms early.
    /// `floor` (the line's last reading) keeps the line's own times monotonic.
    pub fn line_now(&self, floor: Instant) -> Instant {
        let mut lo = Mono::now().ticks();
        let mut cvr = SYST::get_current();
        let lo2 = Mono::now().ticks();
        if lo2 != lo {
            lo = lo2;
            cvr = SYST::get_current();
        }
        let w = EXTEND_WORD.load(core::sync::atomic::Ordering::Acquire);
        let mut hi = w >> 1;
        if w & 1 == 1 && lo >> 31 == 0 {
            hi = hi.wrapping_add(1);
        }
        let ms = (u64::from(hi) << 32) | u64::from(lo);
        let elapsed = self.reload.saturating_sub(cvr);
        let t = Instant::from_micros(ms * 1000 + u64::from(elapsed / self.cycles_per_us));
        if t < floor {
            floor
        } else {
            t
        }
    }
}

impl Clock for SysTickClock {
    fn now(&self) -> Instant {
        let (ms, cycles) = self.sample();
        Instant::from_micros(ms * 1000 + u64::from(cycles / self.cycles_per_us))
    }
}

/// The clock's critical section. QEMU: every interrupt masked (its line interrupt reads the
/// clock). F411: BASEPRI at logical priority 15 — every task that reads the clock is masked,
/// the line interrupts (16, which never read it) are not.
#[cfg(not(feature = "board-f411"))]
fn below_line<R>(f: impl FnOnce(&interrupt::CriticalSection) -> R) -> R {
    interrupt::free(f)
}

/// See the QEMU variant above.
#[cfg(feature = "board-f411")]
fn below_line<R>(f: impl FnOnce(&interrupt::CriticalSection) -> R) -> R {
    use cortex_m::register::{basepri, basepri_max};
    // Logical 15 of 16 → hardware (16 − 15) << 4.
    const BELOW_LINE: u8 = 1 << 4;
    let old = basepri::read();
    // Raising BASEPRI only masks more (a safe call); it is restored below.
    basepri_max::write(BELOW_LINE);
    cortex_m::asm::isb();
    // SAFETY: every user of `EXTEND` runs at logical priority ≤ 15, now masked: exclusive
    // access among them, which is what the token stands for here.
    let cs = unsafe { interrupt::CriticalSection::new() };
    let r = f(&cs);
    core::sync::atomic::compiler_fence(core::sync::atomic::Ordering::SeqCst);
    unsafe { basepri::write(old) };
    r
}
