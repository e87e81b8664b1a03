//! # dpm-host — the host-side reference implementation of the pbcard DPM interface
//!
//! What a drive's control board runs to integrate the PROFIBUS DP-V1 option card through its
//! dual-port memory (issue 7 item 5; ARCHITECTURE §5; the map in `docs/DPM.md`).
//!
//! The implementation itself is `pbcard_dpm::dpm::host` (`pbcard::dpm::host` in the card; `no_std`, no allocation, no `unsafe`,
//! time handed in), so that the card's own simulated drive (QEMU build, soft slave, host
//! tests) runs exactly this code; this crate is the port's entry point: it re-exports it with
//! the pbcard types a host needs, and adds, with the `std` feature (default), [`SharedDpm`],
//! an image shared in one process.
//!
//! The layout is not repeated anywhere: every offset and every block codec comes from
//! `pbcard_dpm::dpm::layout` and `pbcard_dpm::dpm::codec` (the crate `pbcard-dpm`), the card firmware's own source of truth.
//!
//! The crate's tests (`dpm-host/tests/`) run the [`Host`] against pbcard's card side (`Node`,
//! `Link`) over both transports a port meets: the memory transport ([`SharedDpm`]) and the
//! board's SPI frames ([`spi::SpiHost`] over [`spi::Loopback`], the card's `SpiSlave` behind
//! the board's reply pipeline) — every test in `config.rs`, `heartbeat.rs`, `mailbox.rs` and
//! `fields.rs` (the SPI refusals too), and the DRIVE_CMD / OUTPUTS pairing of `torn.rs`. The
//! rest of `torn.rs` (reads cut at a byte by the card's writes) and the `MemoryTransport`
//! range check stay on memory transports: an SPI READ frame carries a whole block, copied in
//! one piece and CRC-checked, so the frames cannot tear a block.
#![cfg_attr(not(feature = "std"), no_std)]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub use pbcard_dpm::dpm::host::{
    Answer, CardEvents, ConfigOutcome, Cycle, DpmTransport, Error, Host, HostStats, MemoryTransport, OpenError,
    Options, ParameterServer, Poll, ProcessImage, Table, Transport, TransportError,
};

/// The SPI transport of the board (`docs/SPI.md`): the reference SPI master ([`spi::SpiHost`]
/// over the board's [`spi::SpiBus`]), its frame codec, the CYCLIC exchange, and the in-process
/// card with the board's reply pipeline ([`spi::Loopback`]) for a port's tests.
pub mod spi {
    pub use pbcard_dpm::dpm::spi::cyclic::{CyclicReply, CyclicRequest};
    pub use pbcard_dpm::dpm::spi::{
        crc16, BusFault, Command, HostError, Loopback, Reply, ReplyError, ResultCode, SpiBus, SpiHost, SpiHostCodec,
        StatusData, PROTOCOL_VERSION, T_READY_US,
    };
}

/// The pbcard items a host works with, re-exported so a port needs one dependency path.
pub use pbcard_dpm::dpm::{
    codec, layout, CardEvent, CardFlags, CardReport, CommState, DriveCommandImage, DriveReport, DriveStateImage,
    HostConfig, Identity, Liveness, MailboxRequest, ParamValues, PdFlags, ProcessData, PzdWords, RequestKind, Status,
    Telegram, Torn,
};
pub use pbcard_fdl::time::{Duration, Instant};
pub use pbcard_profile::profile::drive_if::{CommandFlags, DriveCommand, DriveStatus, StatusFlags};

#[cfg(feature = "std")]
mod shared {
    use pbcard_dpm::dpm::host::{DpmTransport, Transport, TransportError};
    use pbcard_dpm::dpm::Dpm;

    /// An image shared by the card side and the host in one process (`std`): clone it, give one
    /// clone to the [`Host`](crate::Host), keep the other for the card's `pbcard_dpm::dpm::Link`.
    #[derive(Debug, Clone, Default)]
    pub struct SharedDpm(pub std::rc::Rc<core::cell::RefCell<Dpm>>);

    impl SharedDpm {
        /// A shared fresh image ([`Dpm::new`]).
        pub fn new() -> Self {
            Self::from(Dpm::new())
        }

        /// Borrow the image (the card side works on it between host calls).
        pub fn borrow_mut(&self) -> core::cell::RefMut<'_, Dpm> {
            self.0.borrow_mut()
        }
    }

    impl From<Dpm> for SharedDpm {
        fn from(dpm: Dpm) -> Self {
            SharedDpm(std::rc::Rc::new(core::cell::RefCell::new(dpm)))
        }
    }

    impl Transport for SharedDpm {
        fn read(&mut self, offset: u16, buf: &mut [u8]) -> Result<(), TransportError> {
            DpmTransport::new(&mut *self.0.borrow_mut()).read(offset, buf)
        }
        fn write(&mut self, offset: u16, data: &[u8]) -> Result<(), TransportError> {
            DpmTransport::new(&mut *self.0.borrow_mut()).write(offset, data)
        }
    }
}

#[cfg(feature = "std")]
pub use shared::SharedDpm;
