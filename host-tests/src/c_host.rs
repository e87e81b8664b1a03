//! The C reference host (`c-host/`, issue 16 item 5) linked into the tests: `build.rs`
//! compiles `c-host/src/pbcard_host.c` and the test drive `c-host/test/drive.c` with the
//! system C compiler (`-std=c99 -pedantic -Wall -Wextra -Werror`); [`CDrive`] connects the C
//! host's SPI transfer callback to any [`SpiBus`] — in the tests the card's own SPI slave with
//! the board's reply pipeline (`pbcard::dpm::spi::Loopback`), so the C code and the card
//! exchange exactly the frames of `docs/SPI.md`.
//!
//! The test drive keeps its state in C statics (the C library itself has none): one
//! [`CDrive`] exists at a time (a process-wide lock).

use std::ffi::{c_int, c_void};
use std::sync::{Mutex, MutexGuard};

use pbcard::dpm::spi::SpiBus;

type Transfer = unsafe extern "C" fn(*mut c_void, *const u8, *mut u8, usize) -> c_int;

extern "C" {
    fn pbch_drive_init(transfer: Transfer, user: *mut c_void, sck_hz: u32, telegram: u16) -> c_int;
    fn pbch_drive_step(now_ms: u32, budget_us: u32) -> c_int;
    fn pbch_cmd_flags() -> u16;
    fn pbch_cmd_setpoint() -> i16;
    fn pbch_speed() -> i16;
    fn pbch_restarts() -> u32;
    fn pbch_commands() -> u32;
    fn pbch_requests() -> u32;
    fn pbch_responses() -> u32;
    fn pbch_opens() -> u32;
    fn pbch_cycles_ok() -> u32;
    fn pbch_budget_short() -> u32;
    fn pbch_max_used_us() -> u32;
    fn pbch_max_transactions() -> u32;
    fn pbch_last_transactions() -> u32;
    fn pbch_last_bytes() -> u32;
    fn pbch_last_used_us() -> u32;
    fn pbch_card_alive() -> c_int;
    fn pbch_comm_state() -> u8;
    fn pbch_config_outcome() -> c_int;
    fn pbch_boot_id() -> u16;
    fn pbch_is_open() -> c_int;
    fn pbch_value(i: u32) -> u16;
    fn pbch_crc16(p: *const u8, n: u32) -> u16;
    fn pbch_card_event(i: u32) -> u8;
    fn pbch_set_fault(code: u16);
    fn pbch_set_warning(code: u16);
    fn pbch_max_bytes_steady() -> u32;
    fn pbch_drive_writes() -> u32;
}

/// `pbc_cycle` results (`pbcard_host.h`).
pub mod result {
    /// Done.
    pub const OK: i32 = 0;
    /// Still opening.
    pub const OPENING: i32 = 1;
    /// The budget did not allow the exchange.
    pub const BUDGET: i32 = -1;
    /// No valid reply this cycle.
    pub const NO_REPLY: i32 = -2;
}

/// `pbc_config_outcome` values (`pbcard_host.h`).
pub mod config {
    /// Written, no acknowledge yet.
    pub const WRITING: i32 = 1;
    /// Taken over by the card.
    pub const ACCEPTED: i32 = 2;
}

static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());

unsafe extern "C" fn transfer<B: SpiBus>(user: *mut c_void, mosi: *const u8, miso: *mut u8, len: usize) -> c_int {
    // SAFETY: `user` is the `Box<B>` of the `CDrive` that is stepping (no Rust reference to
    // it is alive during `pbch_drive_step`); `mosi` and `miso` are the C host's buffers of
    // `len` bytes each (`pbc_host.mosi` / `miso`, distinct arrays).
    let (bus, mosi, miso) = unsafe {
        (&mut *(user as *mut B), std::slice::from_raw_parts(mosi, len), std::slice::from_raw_parts_mut(miso, len))
    };
    match bus.transfer(mosi, miso) {
        Ok(()) => 0,
        Err(_) => -1,
    }
}

/// The C test drive over the C reference host, its SPI on `B`.
pub struct CDrive<B: SpiBus> {
    bus: *mut B,
    _one: MutexGuard<'static, ()>,
}

impl<B: SpiBus> CDrive<B> {
    /// Initialise the C host (`pbc_init`, CONFIG with `telegram`, station address kept) on
    /// `bus` at an SPI clock of `sck_hz` (the budget's time base).
    pub fn new(bus: B, sck_hz: u32, telegram: u16) -> Self {
        let one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
        let bus = Box::into_raw(Box::new(bus));
        // SAFETY: `bus` stays valid until `Drop`; the C side keeps it as the callback's user
        // pointer only.
        unsafe { pbch_drive_init(transfer::<B>, bus.cast(), sck_hz, telegram) };
        CDrive { bus, _one: one }
    }

    /// One drive cycle (`pbc_cycle` with `budget_us`, then the drive model): its result.
    pub fn step(&mut self, now_ms: u32, budget_us: u32) -> i32 {
        // SAFETY: no reference to the bus is alive (`bus_mut` borrows `self`).
        unsafe { pbch_drive_step(now_ms, budget_us) }
    }

    /// The bus (the card).
    pub fn bus_mut(&mut self) -> &mut B {
        // SAFETY: valid until `Drop`; the C side uses it only inside `step`, which takes
        // `&mut self`.
        unsafe { &mut *self.bus }
    }

    /// DRIVE_CMD.FLAGS and SPEED_SETPOINT as the drive applies them.
    pub fn command(&self) -> (u16, i16) {
        unsafe { (pbch_cmd_flags(), pbch_cmd_setpoint()) }
    }

    /// The drive's actual speed (N2).
    pub fn speed(&self) -> i16 {
        unsafe { pbch_speed() }
    }

    /// Card restarts seen (`CARD.BOOT_ID` changed), opens done, cycles with a reply, commands
    /// taken.
    pub fn counts(&self) -> (u32, u32, u32, u32) {
        unsafe { (pbch_restarts(), pbch_opens(), pbch_cycles_ok(), pbch_commands()) }
    }

    /// Parameter requests taken, answers written, exchanges or accesses put off for the budget.
    pub fn mailbox(&self) -> (u32, u32, u32) {
        unsafe { (pbch_requests(), pbch_responses(), pbch_budget_short()) }
    }

    /// The last call: transactions, bytes, budget used (µs).
    pub fn last_traffic(&self) -> (u32, u32, u32) {
        unsafe { (pbch_last_transactions(), pbch_last_bytes(), pbch_last_used_us()) }
    }

    /// The drive trips with `code` (0: cleared): `pbc_set_fault` (DRIVE) and DRIVE_STATE's
    /// fault bit and code.
    pub fn set_fault(&mut self, code: u16) {
        unsafe { pbch_set_fault(code) }
    }

    /// A warning `code` (0: none): `pbc_set_warning` and DRIVE_STATE's warning bit and code.
    pub fn set_warning(&mut self, code: u16) {
        unsafe { pbch_set_warning(code) }
    }

    /// The most bytes of a one-transaction call, and DRIVE written whole so far.
    pub fn steady_bytes_and_drive_writes(&self) -> (u32, u32) {
        unsafe { (pbch_max_bytes_steady(), pbch_drive_writes()) }
    }

    /// The most transactions and budget (µs) any call used.
    pub fn max_traffic(&self) -> (u32, u32) {
        unsafe { (pbch_max_transactions(), pbch_max_used_us()) }
    }

    /// The card's heartbeat judged alive, `STATUS.COMM_STATE` as last received.
    pub fn card(&self) -> (bool, u8) {
        unsafe { (pbch_card_alive() != 0, pbch_comm_state()) }
    }

    /// `pbc_config_outcome`.
    pub fn config_outcome(&self) -> i32 {
        unsafe { pbch_config_outcome() }
    }

    /// `CARD.BOOT_ID` as last seen, and whether the interface is open.
    pub fn boot(&self) -> (u16, bool) {
        unsafe { (pbch_boot_id(), pbch_is_open() != 0) }
    }

    /// The drive's parameter values (PNU 100, 101).
    pub fn value(&self, i: u32) -> u16 {
        unsafe { pbch_value(i) }
    }

    /// New card events (`CARD.EVENTS` counter `i`) in the last call.
    pub fn card_event(&self, i: u32) -> u8 {
        unsafe { pbch_card_event(i) }
    }

    /// The C host's CRC-16/CCITT-FALSE.
    pub fn crc16(&self, data: &[u8]) -> u16 {
        unsafe { pbch_crc16(data.as_ptr(), data.len() as u32) }
    }
}

impl<B: SpiBus> Drop for CDrive<B> {
    fn drop(&mut self) {
        // SAFETY: made by `Box::into_raw` in `new`; the C side is not called again with it
        // (the next `CDrive` initialises it with its own bus).
        drop(unsafe { Box::from_raw(self.bus) });
    }
}
