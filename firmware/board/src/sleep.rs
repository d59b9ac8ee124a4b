//! Sleeping until there is work: the processor waits for an event (`WFE`) and the
//! peripherals' interrupt lines are that event, with no interrupt handler at all.
//!
//! The interrupts stay disabled in the NVIC; with `SEVONPEND` set, an interrupt that becomes
//! pending still wakes the processor. The loop clears the pending bits *before* it polls, so
//! that a frame arriving while it polls, or between the poll and the `WFE`, is a new
//! transition to pending: the event is latched and the `WFE` returns at once. Nothing is
//! shared with a handler, so the loop owns every peripheral outright.

use crate::hal::pac::Interrupt;
use cortex_m::peripheral::{NVIC, SCB};

/// The interrupt lines that wake the loop: each controller's two receive FIFOs and its
/// transmit mailboxes, and the timer.
pub const WAKE_LINES: [Interrupt; 10] = [
    Interrupt::CAN1_RX0,
    Interrupt::CAN1_RX1,
    Interrupt::CAN1_TX,
    Interrupt::CAN2_RX0,
    Interrupt::CAN2_RX1,
    Interrupt::CAN2_TX,
    Interrupt::CAN3_RX0,
    Interrupt::CAN3_RX1,
    Interrupt::CAN3_TX,
    Interrupt::TIM2,
];

/// The processor's side of sleeping.
pub struct Sleep {
    _scb: SCB,
}

impl Sleep {
    /// Lets pending (disabled) interrupts wake the processor.
    pub fn new(mut scb: SCB) -> Sleep {
        scb.set_sevonpend();
        Sleep { _scb: scb }
    }

    /// Forgets what woke the processor, before the loop polls.
    pub fn rearm(&self) {
        for line in WAKE_LINES {
            NVIC::unpend(line);
        }
    }

    /// Waits for the next wake-up: a frame, a free mailbox, the timer's compare or wrap.
    pub fn wait(&self) {
        cortex_m::asm::wfe();
    }
}
