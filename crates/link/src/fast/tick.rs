//! The main loop's other half (issue 13 item 3): what a platform runs between telegrams.
//!
//! Every platform drives the card in the same shape — smoltcp's `Interface::poll(now, device,
//! sockets)` with the sockets owned by the user:
//!
//! 1. **per telegram**, the line's decision from the staging ([`FastPath`](super::FastPath):
//!    `finish` / `on_frame`), the core working on what the line queued
//!    ([`CoreLink::step`] / [`CoreLink::run`]) and, for a request the line left to the core,
//!    its deferred answer — on a single-threaded platform all of it is
//!    [`single_threaded`](super::single_threaded);
//! 2. **per application step** (1 ms, or right after a Data_Exchange), [`tick`]: the
//!    application's step over the node ([`CardApp::step`]: the DPM, the profile, the drive),
//!    the DP-V1 record work when there is some ([`Node::process_acyclic`] with the
//!    application's [`CardApp::records`]), and the staging republished
//!    ([`CoreLink::note_events`], [`CoreLink::publish`]) so the line answers from the node as
//!    it is now.
//!
//! The soft slave, the simulated-bus card of the host tests and the porting example call
//! [`single_threaded`](super::single_threaded) and [`tick`]; the RTIC firmware runs the same
//! steps at their own priorities (line interrupt 16, core task 15, DP-V1 task 8, application
//! task 1 — `firmware/src/main.rs`), which is why [`tick`] is three calls and not one object.

use super::CoreLink;
use crate::dp::Events;
use crate::node::{DataRecords, Node};
use crate::time::Instant;

/// The application a card's main loop steps (implemented above this layer: the shipped card
/// `app::Card`, the bench `pbcard_sim::bench::Application`, a product's own drive interface).
pub trait CardApp {
    /// The DP-V1 data records the application serves behind I&M, for one
    /// [`Node::process_acyclic`] ([`crate::dpv1::records::NoRecords`] for none).
    type Records<'a>: DataRecords
    where
        Self: 'a;

    /// One application step at `now` over the node (outputs to the drive, inputs and
    /// diagnosis from it): the node's events since the last step.
    fn step(&mut self, now: Instant, node: &mut Node) -> Events;

    /// The data records at `now`.
    fn records(&mut self, now: Instant) -> Self::Records<'_>;
}

/// One application step of a single-threaded main loop (see the module documentation): the
/// application's step, the DP-V1 work if the node has any, the staging republished. The
/// step's events.
pub fn tick<A: CardApp + ?Sized>(now: Instant, node: &mut Node, core: &mut CoreLink<'_>, app: &mut A) -> Events {
    let events = app.step(now, node);
    if node.has_acyclic_work() {
        node.process_acyclic(now, &mut app.records(now));
    }
    core.note_events(events);
    core.publish(node);
    events
}
