//! The physical layer's decisions, without the hardware: which USART divisor produces each
//! PROFIBUS rate ([`divisor`]), which rate to listen at — the ASIC-style automatic baud-rate
//! search and supervision ([`autobaud`], reference §1.6) — and how a DMA receiver with a bit
//! timer cuts telegrams, keeps T_SYN, min_TSDR and max_TSDR ([`line`](mod@line), reference §1.3–1.4).
//!
//! The board support code owns the USART; it asks [`autobaud::Autobaud`] for the rate,
//! programs it with [`divisor::divisor_for`], feeds what it received through
//! [`stream::Stream`] (per character or by DMA ring pieces, [`timing::RxMode`]; the segment
//! cutter [`line::Receiver`] remains the reference model), starts responses as
//! [`line::tx_plan`] says, and reports every frame,
//! every receive error and the passing of time back. [`timing`] holds what the line interrupt
//! computes: the per-rate tick table, the "already passed?" check of a compare, the ring
//! reader and the receive-interrupt gate. [`rate_link`] splits the rate control between the line
//! interrupt (classifies telegrams, gates answers, carries out rate switches) and a lower task
//! that owns [`autobaud::Autobaud`], lock-free. [`port`] is the board contract of the line:
//! the traits the F411, QEMU and the soft slave implement for their RS485 ports. [`stream`] is
//! the seam that hands a telegram's bytes to the fast path while they arrive, and the
//! streaming framer that cuts them by length; [`ring`] walks a small DMA ring at its
//! half/full/IDLE events (pieces in place, overrun detection).

pub mod autobaud;
pub mod divisor;
pub mod line;
pub mod port;
pub mod rate_link;
pub mod ring;
pub mod stream;
#[cfg(test)]
mod tests_props;
pub mod timing;
