//! The board's panic and HardFault path (ARCHITECTURE §2 "supervision", issue 5 item 6): the
//! line to the safe state first (transmit DMA stopped, DE released — before any logging,
//! issue 11 item 3e), then the log, the DPM OUTPUTS block to the
//! safe state and the "card fault" event raised in `CARD.EVENTS`
//! ([`pbcard::app::Card::fail_safe`]), a flag in RAM that survives the reset, then a
//! system reset. After the reset [`take_recovered_fault`] tells the firmware to raise the
//! event once more in the fresh DPM image (the transport to the drive may not have moved the
//! old one before the reset) and the BS LED shows "card fault" until data exchange.
//!
//! The application registers its card ([`CardApp`]: the card alone, or the `sim-drive`
//! bench) once its resource is in place ([`register_application`]); the fault path then writes through that pointer, aliasing
//! whatever task was running. That is acceptable only because nothing runs afterwards but the
//! reset: the write is bounded and the image is rebuilt from scratch at boot.

use core::mem::MaybeUninit;
use core::ptr::{addr_of, addr_of_mut, null_mut};
use core::sync::atomic::{AtomicBool, AtomicPtr, Ordering};

use crate::CardApp;

/// The value of [`FAULT_FLAG`] after a fault (anything else: a normal power-up).
const FAULT_MAGIC: u32 = 0xFA17_CA5D;

/// Survives a system reset (not zeroed by the startup code: `.uninit`).
#[link_section = ".uninit.pbcard_fault"]
static mut FAULT_FLAG: MaybeUninit<u32> = MaybeUninit::uninit();

static APP: AtomicPtr<CardApp> = AtomicPtr::new(null_mut());
static IN_FAULT: AtomicBool = AtomicBool::new(false);
/// The fault has been logged (a fault inside the logging — RTT, `defmt` — logs nothing more).
static LOGGED: AtomicBool = AtomicBool::new(false);

/// Remember where the application lives (call with the RTIC resource locked, once it is in
/// its final place; calling it again with the same object is harmless).
pub fn register_application(app: &mut CardApp) {
    APP.store(app as *mut CardApp, Ordering::Release);
}

/// Whether the last reset came from the fault path (clears the flag).
pub fn take_recovered_fault() -> bool {
    // SAFETY: read once in `init` before any interrupt is enabled; a u32 has no invalid values.
    unsafe {
        let v = core::ptr::read_volatile(addr_of!(FAULT_FLAG) as *const u32);
        core::ptr::write_volatile(addr_of_mut!(FAULT_FLAG) as *mut u32, 0);
        v == FAULT_MAGIC
    }
}

/// Issue 11 3e: the line to the safe state **before** anything that may take time or fail —
/// logging included (RTT may block or wait for a probe; a fault inside the logger must not
/// leave DE on): interrupts off, DE (PA8) low, transmit DMA and transmitter off.
#[inline(never)]
fn line_safe_first() {
    cortex_m::interrupt::disable();
    // SAFETY: interrupts are off and nothing but logging and the reset follows.
    unsafe { super::f411::line_safe_state() };
}

/// Whether this is the first attempt to log the fault.
fn first_log() -> bool {
    !LOGGED.swap(true, Ordering::AcqRel)
}

fn fail() -> ! {
    line_safe_first();
    // SAFETY: interrupts are off and nothing but the reset follows.
    unsafe {
        if !IN_FAULT.swap(true, Ordering::AcqRel) {
            let app = APP.load(Ordering::Acquire);
            if !app.is_null() {
                (*app).fail_safe();
            }
        }
        core::ptr::write_volatile(addr_of_mut!(FAULT_FLAG) as *mut u32, FAULT_MAGIC);
    }
    cortex_m::peripheral::SCB::sys_reset()
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    line_safe_first();
    if first_log() {
        // Where, not what: the message would link `core::fmt` (≈ 10 KiB of the card's 96 KiB
        // flash, issue 13 item 1). Even the location costs 7.7 KiB — every panic site's
        // `Location` and argument set-up, and the integer formatting of the bounds-check
        // message, stay alive once the handler reads `info` (measured: 100 492 B with it,
        // 92 832 B without; the line only: 100 468 B). So the shipped card logs that it
        // panicked, and a developer who needs the place builds with the feature
        // `panic-location` (README "Footprint"). HardFault logs its PC either way.
        #[cfg(feature = "panic-location")]
        match info.location() {
            Some(l) => defmt::error!("panic at {=str}:{=u32}", l.file(), l.line()),
            None => defmt::error!("panic"),
        }
        #[cfg(not(feature = "panic-location"))]
        {
            let _ = info;
            defmt::error!("panic (its file and line: build with --features panic-location)");
        }
    }
    fail()
}

#[cortex_m_rt::exception]
unsafe fn HardFault(ef: &cortex_m_rt::ExceptionFrame) -> ! {
    line_safe_first();
    if first_log() {
        defmt::error!("HardFault at pc {=u32:#010x}", ef.pc());
    }
    fail()
}

/// `defmt::panic!` / `defmt::assert!` log *before* they call this (the macro's order, not
/// ours): the board uses them only in `init`, before the line is started and while DE is
/// held low (`f411::init`), so no response can be on the wire while they log.
#[defmt::panic_handler]
fn defmt_panic() -> ! {
    fail()
}
