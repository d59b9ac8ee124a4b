//! A deterministic simulated multi-bus CAN network in virtual time.

pub mod timing;
