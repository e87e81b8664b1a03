//! The physical layer's decisions, without the hardware: which USART divisor produces each
//! PROFIBUS rate ([`divisor`]) and which rate to listen at — the ASIC-style automatic baud-rate
//! search and supervision ([`autobaud`], reference §1.6).
//!
//! The board support code owns the USART; it asks [`autobaud::Autobaud`] for the rate,
//! programs it with [`divisor::divisor_for`], and reports every frame, every receive error and
//! the passing of time back.

pub mod autobaud;
pub mod divisor;
