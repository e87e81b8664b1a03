//! How the host reaches the card's DPM image: a [`Transport`] moves byte ranges of the image
//! (ARCHITECTURE §5; `docs/DPM.md`). The in-process transports here serve the host tests, the
//! soft slave and the QEMU build; on the board an SPI frame client implements the same trait.
//!
//! **Order rule.** A transport must move the bytes of one `read` or `write` in ascending address
//! order (the sequenced-block protocol of `crate::dpm` relies on it: the host reads and writes
//! a block in one ascending pass). Every transport here does; an SPI frame of command / address
//! / length / data does by construction.

use crate::dpm::spi::cyclic::{CyclicRequest, MAX_REPLY_DATA};
use crate::dpm::Dpm;

/// Why a transport access failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TransportError {
    /// The range lies (partly) outside the image.
    OutOfRange,
    /// The link to the card did not answer (no card, SPI not clocked, timeout).
    NoResponse,
    /// A frame arrived corrupted (CRC / check failed); nothing of it was used.
    Corrupt,
    /// The card refused the access (e.g. a write to a block the card writes).
    Refused,
}

impl core::fmt::Display for TransportError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            TransportError::OutOfRange => "access outside the DPM image",
            TransportError::NoResponse => "the card did not answer",
            TransportError::Corrupt => "corrupted frame",
            TransportError::Refused => "access refused by the card",
        })
    }
}

impl core::error::Error for TransportError {}

/// What one CYCLIC exchange of [`Transport::cyclic`] got back: the reply DATA's length, and
/// which request the reply answers. Over the board's pipeline (`docs/SPI.md` "One drive
/// cycle") a one-transaction cycle takes the reply to the **previous** call's request, a
/// two-transaction cycle the reply to **this** call's; the host confirms the mailbox
/// fragments a request carried by the reply to that request only.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CyclicReceipt {
    /// Bytes of reply DATA in `out`.
    pub len: usize,
    /// The reply answers the request of the previous `cyclic` call (else this call's).
    pub previous: bool,
}

/// Byte-range access to the card's DPM image (offsets as in `docs/DPM.md`).
///
/// Implement it for the board's link (SPI frames, a parallel dual-port RAM, …). Each call must
/// move its bytes in ascending address order, and a failed `write` may have written a prefix
/// of `data` (the sequenced blocks make that visible to the card as a torn block, never as data).
pub trait Transport {
    /// Read `buf.len()` bytes from `offset`.
    fn read(&mut self, offset: u16, buf: &mut [u8]) -> Result<(), TransportError>;
    /// Write `data` at `offset`.
    fn write(&mut self, offset: u16, data: &[u8]) -> Result<(), TransportError>;
    /// One drive cycle's CYCLIC exchange (`docs/SPI.md`, protocol version 2): the reply DATA
    /// into `out`, its length and the request it answers returned. `None`: this transport has none (a dual-port RAM);
    /// [`super::Host::cycle`] then uses the block accesses.
    fn cyclic(
        &mut self,
        req: &CyclicRequest<'_>,
        out: &mut [u8; MAX_REPLY_DATA],
    ) -> Option<Result<CyclicReceipt, TransportError>> {
        let _ = (req, out);
        None
    }
}

impl<T: Transport + ?Sized> Transport for &mut T {
    fn read(&mut self, offset: u16, buf: &mut [u8]) -> Result<(), TransportError> {
        (**self).read(offset, buf)
    }
    fn write(&mut self, offset: u16, data: &[u8]) -> Result<(), TransportError> {
        (**self).write(offset, data)
    }
    fn cyclic(
        &mut self,
        req: &CyclicRequest<'_>,
        out: &mut [u8; MAX_REPLY_DATA],
    ) -> Option<Result<CyclicReceipt, TransportError>> {
        (**self).cyclic(req, out)
    }
}

fn range(len: usize, offset: u16, n: usize) -> Result<core::ops::Range<usize>, TransportError> {
    let start = offset as usize;
    match start.checked_add(n) {
        Some(end) if end <= len => Ok(start..end),
        _ => Err(TransportError::OutOfRange),
    }
}

/// Any byte memory as the image: a memory-mapped dual-port RAM window, a buffer an SPI
/// driver fills, a test's array.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct MemoryTransport<M> {
    memory: M,
}

impl<M: AsRef<[u8]> + AsMut<[u8]>> MemoryTransport<M> {
    /// Access `memory` (offset 0 = the image's first byte).
    pub const fn new(memory: M) -> Self {
        MemoryTransport { memory }
    }

    /// The memory.
    pub fn memory(&self) -> &M {
        &self.memory
    }

    /// The memory, writable.
    pub fn memory_mut(&mut self) -> &mut M {
        &mut self.memory
    }
}

impl<M: AsRef<[u8]> + AsMut<[u8]>> Transport for MemoryTransport<M> {
    fn read(&mut self, offset: u16, buf: &mut [u8]) -> Result<(), TransportError> {
        let m = self.memory.as_ref();
        let r = range(m.len(), offset, buf.len())?;
        buf.copy_from_slice(&m[r]);
        Ok(())
    }
    fn write(&mut self, offset: u16, data: &[u8]) -> Result<(), TransportError> {
        let m = self.memory.as_mut();
        let r = range(m.len(), offset, data.len())?;
        m[r].copy_from_slice(data);
        Ok(())
    }
}

/// The in-process transport over a [`Dpm`] image the card side also works on (owned: `Dpm`,
/// borrowed: `&mut Dpm`, or anything that lends one).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct DpmTransport<D> {
    dpm: D,
}

impl<D: core::borrow::BorrowMut<Dpm>> DpmTransport<D> {
    /// Access `dpm`.
    pub const fn new(dpm: D) -> Self {
        DpmTransport { dpm }
    }

    /// The image (the card side: `dpm().card()` is not available through `&`, use
    /// [`Self::dpm_mut`]).
    pub fn dpm(&self) -> &Dpm {
        self.dpm.borrow()
    }

    /// The image, for the card side between host calls.
    pub fn dpm_mut(&mut self) -> &mut Dpm {
        self.dpm.borrow_mut()
    }

    /// Give the image back.
    pub fn into_inner(self) -> D {
        self.dpm
    }
}

impl<D: core::borrow::BorrowMut<Dpm>> Transport for DpmTransport<D> {
    fn read(&mut self, offset: u16, buf: &mut [u8]) -> Result<(), TransportError> {
        let img = self.dpm.borrow().as_bytes();
        let r = range(img.len(), offset, buf.len())?;
        buf.copy_from_slice(&img[r]);
        Ok(())
    }
    fn write(&mut self, offset: u16, data: &[u8]) -> Result<(), TransportError> {
        let img = self.dpm.borrow_mut().as_bytes_mut();
        let r = range(img.len(), offset, data.len())?;
        img[r].copy_from_slice(data);
        Ok(())
    }
}
