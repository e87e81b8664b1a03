//! The two flash sectors of the card's journal (`pbcard::store::Journal`: the station address
//! and I&M1–4, 64 slots of 256 bytes per sector) on the STM32F411 (`pbcard::store::Flash`).
//!
//! Sectors 1 and 2 (16 KiB each, 0x0800_4000 and 0x0800_8000; RM0383 Table 4) belong to the
//! journal: `memory.x` keeps the vector table in sector 0 and starts the program in sector 4
//! (`_stext = 0x0801_0000`), so sectors 1–3 hold no code (sector 3 stays free). Flashing a new
//! firmware with probe-rs erases only the sectors the ELF occupies: the stored station address
//! and I&M1–4 survive a firmware update.
//!
//! Erase and program go through the FLASH registers (RM0383 §3.5): unlock with the two KEYR
//! keys, 32-bit parallelism (PSIZE = x32, 2.7–3.6 V) for whole aligned words and x8 for the
//! rest, wait for BSY, check the error flags, lock again. While the flash is busy every
//! instruction fetch from flash stalls (single bank): the caller runs this at low priority,
//! feeds the IWDG before, and restarts the line receiver afterwards. After an erase the ART
//! data cache is reset so that reads see the erased bytes.

use pbcard::store::Flash;
use stm32f4xx_hal::pac::FLASH;

/// Base address of journal sector 0 (F411 sector 1).
pub const JOURNAL_BASE: u32 = 0x0800_4000;
/// Bytes per journal sector.
pub const JOURNAL_SECTOR_SIZE: u32 = 16 * 1024;
/// The F411 sector numbers of journal sectors 0 and 1.
const SECTOR_NUMBERS: [u8; 2] = [1, 2];

const KEY1: u32 = 0x4567_0123;
const KEY2: u32 = 0xCDEF_89AB;

// FLASH_SR bits (RM0383 §3.8.4).
const SR_EOP: u32 = 1 << 0;
const SR_OPERR: u32 = 1 << 1;
const SR_WRPERR: u32 = 1 << 4;
const SR_PGAERR: u32 = 1 << 5;
const SR_PGPERR: u32 = 1 << 6;
const SR_PGSERR: u32 = 1 << 7;
const SR_RDERR: u32 = 1 << 8;
const SR_BSY: u32 = 1 << 16;
const SR_ERRORS: u32 = SR_OPERR | SR_WRPERR | SR_PGAERR | SR_PGPERR | SR_PGSERR | SR_RDERR;

// FLASH_CR bits (RM0383 §3.8.5).
const CR_PG: u32 = 1 << 0;
const CR_SER: u32 = 1 << 1;
const CR_SNB_SHIFT: u32 = 3;
const CR_PSIZE_X8: u32 = 0b00 << 8;
const CR_PSIZE_X32: u32 = 0b10 << 8;
const CR_STRT: u32 = 1 << 16;
const CR_LOCK: u32 = 1 << 31;

/// What went wrong (the FLASH_SR error bits, or an access outside the sectors).
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub enum FlashError {
    /// FLASH_SR error flags after the operation.
    Status(u32),
    /// Sector number or range outside the journal.
    Range,
}

/// Sectors 1 and 2 of the F411 as the journal's two sectors.
pub struct JournalFlash {
    flash: FLASH,
}

impl JournalFlash {
    /// Take the FLASH peripheral (the HAL has set the wait states; nothing else touches it).
    pub fn new(flash: FLASH) -> Self {
        JournalFlash { flash }
    }

    fn addr(sector: u8, offset: u32, len: usize) -> Result<u32, FlashError> {
        if sector > 1 || offset as usize + len > JOURNAL_SECTOR_SIZE as usize {
            return Err(FlashError::Range);
        }
        Ok(JOURNAL_BASE + u32::from(sector) * JOURNAL_SECTOR_SIZE + offset)
    }

    fn unlock(&mut self) {
        if self.flash.cr().read().bits() & CR_LOCK != 0 {
            self.flash.keyr().write(|w| unsafe { w.bits(KEY1) });
            self.flash.keyr().write(|w| unsafe { w.bits(KEY2) });
        }
    }

    fn lock(&mut self) {
        self.flash.cr().write(|w| unsafe { w.bits(CR_LOCK) });
    }

    #[inline(never)]
    fn wait(&mut self) -> Result<(), FlashError> {
        while self.flash.sr().read().bits() & SR_BSY != 0 {}
        let sr = self.flash.sr().read().bits();
        // Clear EOP and the error flags (write 1 to clear).
        self.flash.sr().write(|w| unsafe { w.bits(sr & (SR_ERRORS | SR_EOP)) });
        if sr & SR_ERRORS != 0 {
            Err(FlashError::Status(sr & SR_ERRORS))
        } else {
            Ok(())
        }
    }

    fn reset_data_cache(&mut self) {
        self.flash.acr().modify(|_, w| w.dcen().clear_bit());
        self.flash.acr().modify(|_, w| w.dcrst().set_bit());
        self.flash.acr().modify(|_, w| w.dcrst().clear_bit());
        self.flash.acr().modify(|_, w| w.dcen().set_bit());
    }
}

impl Flash for JournalFlash {
    const SECTOR_SIZE: u32 = JOURNAL_SECTOR_SIZE;
    type Error = FlashError;

    fn erase(&mut self, sector: u8) -> Result<(), FlashError> {
        Self::addr(sector, 0, 0)?;
        self.unlock();
        let _ = self.wait();
        let snb = u32::from(SECTOR_NUMBERS[usize::from(sector)]) << CR_SNB_SHIFT;
        self.flash.cr().write(|w| unsafe { w.bits(CR_SER | snb | CR_PSIZE_X32) });
        self.flash.cr().modify(|r, w| unsafe { w.bits(r.bits() | CR_STRT) });
        let r = self.wait();
        self.lock();
        self.reset_data_cache();
        r
    }

    fn program(&mut self, sector: u8, offset: u32, data: &[u8]) -> Result<(), FlashError> {
        let base = Self::addr(sector, offset, data.len())?;
        self.unlock();
        let _ = self.wait();
        let mut r = Ok(());
        let mut i = 0;
        while i < data.len() && r.is_ok() {
            let a = base + i as u32;
            if a.is_multiple_of(4) && data.len() - i >= 4 {
                let word = u32::from_le_bytes([data[i], data[i + 1], data[i + 2], data[i + 3]]);
                self.flash.cr().write(|w| unsafe { w.bits(CR_PG | CR_PSIZE_X32) });
                // SAFETY: `a` is inside the journal's sectors (checked above), word aligned;
                // the flash controller is in programming mode.
                unsafe { core::ptr::write_volatile(a as *mut u32, word) };
                i += 4;
            } else {
                self.flash.cr().write(|w| unsafe { w.bits(CR_PG | CR_PSIZE_X8) });
                // SAFETY: as above, one byte.
                unsafe { core::ptr::write_volatile(a as *mut u8, data[i]) };
                i += 1;
            }
            r = self.wait();
        }
        self.lock();
        r
    }

    fn read(&self, sector: u8, offset: u32, buf: &mut [u8]) {
        let Ok(base) = Self::addr(sector, offset, buf.len()) else {
            buf.fill(0);
            return;
        };
        // One copy (a volatile byte loop was unrolled for the slot size into every caller:
        // footprint, issue 13 item 1). Plain reads are right for flash: memory without read
        // side effects, and no Rust object lives there, so nothing lets the compiler keep a
        // value across a program / erase (which end before they return, `wait`).
        // SAFETY: memory-mapped flash inside the journal's sectors (checked above), `buf` a
        // distinct RAM buffer of `buf.len()` bytes.
        unsafe { core::ptr::copy_nonoverlapping(base as *const u8, buf.as_mut_ptr(), buf.len()) };
    }
}
