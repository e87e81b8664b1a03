//! A simulated NOR flash for the journal's tests and the card's (`pbcard`'s tests, with the
//! feature `test-support`): never part of the firmware.

use super::Flash;

/// Simulated NOR flash: two sectors of `N` bytes, erase = 0xFF, program clears bits and may
/// only touch erased bytes, and an optional power cut after a number of byte steps (each
/// programmed byte and each erased byte is one step). The step that is cut is done
/// partially: a program clears only some of the bits it should, an erase leaves every byte
/// not yet erased with some bits set — or, with seed 0, not at all (a clean cut between two
/// steps). After the cut every operation fails.
#[derive(Clone)]
pub struct SimFlash<const N: usize> {
    pub(crate) mem: [[u8; N]; 2],
    budget: Option<u64>,
    pub(crate) steps: u64,
    seed: u64,
    clean: bool,
    pub(crate) erases: u32,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
/// The simulated power failed ([`Flash::Error`] of [`SimFlash`]).
pub struct PowerCut;

impl<const N: usize> SimFlash<N> {
    /// Two erased sectors, no power cut.
    pub fn new() -> Self {
        SimFlash { mem: [[0xFF; N]; 2], budget: None, steps: 0, seed: 1, clean: false, erases: 0 }
    }
    fn rand(&mut self) -> u8 {
        self.seed ^= self.seed << 13;
        self.seed ^= self.seed >> 7;
        self.seed ^= self.seed << 17;
        (self.seed >> 24) as u8
    }
    /// Take one step; `false` = the power fails during this step.
    fn step(&mut self) -> Result<bool, PowerCut> {
        match self.budget {
            Some(0) => Err(PowerCut),
            Some(ref mut b) => {
                *b -= 1;
                self.steps += 1;
                Ok(*b != 0)
            }
            None => {
                self.steps += 1;
                Ok(true)
            }
        }
    }
    /// The power fails during step `steps` + 1 from now (`seed` 0: a clean cut).
    pub fn cut_after(&mut self, steps: u64, seed: u64) {
        self.budget = Some(steps + 1);
        self.seed = seed | 1;
        self.clean = seed == 0;
    }
    /// Power back: operations succeed again.
    pub fn power_on(&mut self) {
        self.budget = None;
    }
}

impl<const N: usize> Flash for SimFlash<N> {
    const SECTOR_SIZE: u32 = N as u32;
    type Error = PowerCut;

    fn erase(&mut self, sector: u8) -> Result<(), PowerCut> {
        self.erases += 1;
        for i in 0..N {
            if !self.step()? {
                // Cut mid-erase: bytes from i on are only partly erased.
                for j in i..N {
                    let m = if self.clean { 0 } else { self.rand() & self.rand() };
                    self.mem[sector as usize][j] |= m;
                }
                self.budget = Some(0);
                return Err(PowerCut);
            }
            self.mem[sector as usize][i] = 0xFF;
        }
        Ok(())
    }

    fn program(&mut self, sector: u8, offset: u32, data: &[u8]) -> Result<(), PowerCut> {
        for (i, &d) in data.iter().enumerate() {
            let a = offset as usize + i;
            let old = self.mem[sector as usize][a];
            assert!(old == 0xFF || d == 0xFF, "programming a non-erased byte at {sector}:{a}");
            if !self.step()? {
                let m = if self.clean { 0xFF } else { self.rand() };
                self.mem[sector as usize][a] &= d | m;
                self.budget = Some(0);
                return Err(PowerCut);
            }
            self.mem[sector as usize][a] &= d;
        }
        Ok(())
    }

    fn read(&self, sector: u8, offset: u32, buf: &mut [u8]) {
        let o = offset as usize;
        buf.copy_from_slice(&self.mem[sector as usize][o..o + buf.len()]);
    }
}

impl<const N: usize> Default for SimFlash<N> {
    fn default() -> Self {
        Self::new()
    }
}
