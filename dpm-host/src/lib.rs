//! # dpm-host — the host-side reference implementation of the pbcard DPM interface
//!
//! What a drive's control board runs to integrate the PROFIBUS DP-V1 option card through its
//! dual-port memory (issue 7 item 5; ARCHITECTURE §5; the map in `docs/DPM.md`). `no_std`,
//! no allocation, no `unsafe`, time handed in: port it by implementing [`Transport`] for the
//! board's link to the card (SPI frames, a dual-port RAM) and calling [`Host`] from the drive's
//! cycle.
//!
//! The layout is not repeated here: every offset and every block codec comes from
//! `pbcard::dpm::layout` and `pbcard::dpm::codec`, the card firmware's own source of truth.
//!
//! * [`Host::open`] — check magic, layout version, image size, capabilities.
//! * [`Host::identity`], [`Host::status`], [`Host::card_report`] — what the card is and does
//!   (P0740 communication state, P0963 baud, addresses, active telegram, counters).
//! * [`Host::write_config`], [`Host::config_outcome`] — configuration, taken over by the card
//!   only while no cyclic exchange runs (`CARD.CONFIG_RESULT`).
//! * [`Host::read_process_data`], [`Host::write_process_data`] — DRIVE_CMD + OUTPUTS of one
//!   card cycle in, INPUTS + DRIVE_STATE out, through the sequenced blocks (torn reads are
//!   repeated, never returned).
//! * [`Host::serve_parameters`], [`Host::respond`] — the parameter mailbox ([`ParameterServer`],
//!   [`Table`] for a [`pbcard::profile::param::ParameterAccess`] table); late answers are
//!   never taken for the next request (REQ_ID).
//! * [`Host::set_fault`], [`Host::set_warning`], [`Host::set_ext_diag`], [`Host::poll`] — the
//!   DRIVE block with the drive's heartbeat every cycle, and the card's heartbeat watched
//!   (lost = the A140 situation) with the card → drive events.
//!
//! Feature `std` (default): [`SharedDpm`], an image shared in one process, and
//! `std::error::Error` for the errors.
#![cfg_attr(not(feature = "std"), no_std)]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

mod host;
mod transport;

pub use host::{
    Answer, CardEvents, ConfigOutcome, Error, Host, HostStats, OpenError, Options, ParameterServer, Poll, ProcessImage,
    Table,
};
#[cfg(feature = "std")]
pub use transport::SharedDpm;
pub use transport::{DpmTransport, MemoryTransport, Transport, TransportError};

/// The pbcard items a host works with, re-exported so a port needs one dependency path.
pub use pbcard::dpm::{
    codec, layout, CardEvent, CardFlags, CardReport, CommState, DriveCommandImage, DriveReport, DriveStateImage,
    HostConfig, Identity, Liveness, MailboxRequest, ParamValues, PdFlags, ProcessData, PzdWords, RequestKind, Status,
    Telegram, Torn,
};
pub use pbcard::profile::drive_if::{CommandFlags, DriveCommand, DriveStatus, StatusFlags};
pub use pbcard::time::{Duration, Instant};
