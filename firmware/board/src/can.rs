//! The bxCAN controllers as `embedded-can` drivers: [`Port`] is any of CAN1–CAN3 behind one
//! type, so that a driver that takes an array of controllers of one type
//! ([`EmbeddedDriver`](duocan::port::embedded::EmbeddedDriver)) gets two or three of them.
//!
//! A controller leaves its configuration asleep and joins its bus when it has seen the bus
//! idle (11 recessive bits), which the driver asks for at each use until it has: a stuck bus
//! never blocks the board, the other bus runs meanwhile. Bus-off recovery is the controller's
//! own (automatic bus-off management, switched on when it joins). Every frame the bus carries
//! is received (one accept-all filter bank per controller, into FIFO 0).

use crate::hal::can::Can as HalCan;
use crate::hal::pac::{CAN1, CAN2, CAN3};
use bxcan::filter::Mask32;
use bxcan::{Fifo, Frame, Interrupts, OverrunError};
use embedded_can::nb::Can;

/// The bxCAN driver of controller `I`.
type Bx<I> = bxcan::Can<HalCan<I>>;

/// The filter banks CAN1 keeps; CAN2 gets the rest of the 28 they share (CAN3 has its own 14).
const CAN1_BANKS: u8 = 14;

/// The bit rate of the buses (the railway networks run at 500 kbit/s or 1 Mbit/s).
pub const BIT_RATE: u32 = 500_000;

/// `BTR` for `bit_rate` from the APB1 clock `pclk1`: 16 time quanta a bit, the sample point at
/// 87.5 % (13 + 1 quanta before it, 2 after), resynchronisation jump 1 quantum. `None` if the
/// clock is not a multiple of 16 × `bit_rate`.
#[must_use]
pub const fn bit_timing(pclk1: u32, bit_rate: u32) -> Option<u32> {
    let quanta = 16;
    if bit_rate == 0 || !pclk1.is_multiple_of(quanta * bit_rate) {
        return None;
    }
    let prescaler = pclk1 / (quanta * bit_rate);
    if prescaler == 0 || prescaler > 1024 {
        return None;
    }
    let (seg1, seg2, sjw) = (13, 2, 1);
    Some(((sjw - 1) << 24) | ((seg2 - 1) << 20) | ((seg1 - 1) << 16) | (prescaler - 1))
}

/// One of the three controllers, with the state of its joining the bus.
pub struct Port {
    can: Controller,
    joined: bool,
}

enum Controller {
    Can1(Bx<CAN1>),
    Can2(Bx<CAN2>),
    Can3(Bx<CAN3>),
}

/// Runs `$e` on the bxCAN driver inside, whichever controller it is.
macro_rules! each {
    ($c:expr, $can:ident => $e:expr) => {
        match $c {
            Controller::Can1($can) => $e,
            Controller::Can2($can) => $e,
            Controller::Can3($can) => $e,
        }
    };
}

/// Interrupts that wake the main loop: a frame waiting, a mailbox freed.
const WAKE: Interrupts = Interrupts::FIFO0_MESSAGE_PENDING
    .union(Interrupts::FIFO1_MESSAGE_PENDING)
    .union(Interrupts::TRANSMIT_MAILBOX_EMPTY);

impl Port {
    /// CAN1 and CAN2 (they share CAN1's filter banks), configured with `btr`, asleep until
    /// they join their buses.
    pub fn dual(can1: HalCan<CAN1>, can2: HalCan<CAN2>, btr: u32) -> [Port; 2] {
        let mut c1 = configure(bxcan::Can::builder(can1), btr);
        let mut c2 = configure(bxcan::Can::builder(can2), btr);
        let mut filters = c1.modify_filters();
        filters.set_split(CAN1_BANKS);
        filters.enable_bank(0, Fifo::Fifo0, Mask32::accept_all());
        filters
            .slave_filters()
            .enable_bank(CAN1_BANKS, Fifo::Fifo0, Mask32::accept_all());
        drop(filters);
        c1.enable_interrupts(WAKE);
        c2.enable_interrupts(WAKE);
        [
            Port::new(Controller::Can1(c1)),
            Port::new(Controller::Can2(c2)),
        ]
    }

    /// CAN3 (its own filter banks), configured with `btr`, asleep until it joins its bus.
    pub fn third(can3: HalCan<CAN3>, btr: u32) -> Port {
        let mut c3 = configure(bxcan::Can::builder(can3), btr);
        c3.modify_filters()
            .enable_bank(0, Fifo::Fifo0, Mask32::accept_all());
        c3.enable_interrupts(WAKE);
        Port::new(Controller::Can3(c3))
    }

    fn new(can: Controller) -> Port {
        Port { can, joined: false }
    }

    /// True once the controller has joined its bus.
    pub fn joined(&self) -> bool {
        self.joined
    }

    /// Acknowledges the transmit interrupt (the mailboxes that completed), so that the next
    /// completion wakes the loop again. Called before each pass of the loop.
    pub fn acknowledge(&mut self) {
        each!(&mut self.can, c => c.clear_tx_interrupt());
    }

    /// Joins the bus if not yet done (no wait: the controller synchronises in the background).
    fn join(&mut self) -> bool {
        if !self.joined {
            self.joined = each!(&mut self.can, c => c.enable_non_blocking().is_ok());
        }
        self.joined
    }
}

/// The settings every controller gets: bit timing, automatic retransmission (a frame that
/// lost arbitration or met an error is sent again by the controller), left asleep.
fn configure<I: bxcan::Instance>(builder: bxcan::CanBuilder<I>, btr: u32) -> bxcan::Can<I> {
    builder
        .set_bit_timing(btr)
        .set_automatic_retransmit(true)
        .leave_disabled()
}

impl Can for Port {
    type Frame = Frame;
    type Error = OverrunError;

    fn transmit(&mut self, frame: &Frame) -> nb::Result<Option<Frame>, OverrunError> {
        if !self.join() {
            return Err(nb::Error::WouldBlock);
        }
        each!(&mut self.can, c => Can::transmit(c, frame))
    }

    fn receive(&mut self) -> nb::Result<Frame, OverrunError> {
        if !self.join() {
            return Err(nb::Error::WouldBlock);
        }
        each!(&mut self.can, c => Can::receive(c))
    }
}

// Checked when the crate is built: BRP 6, TS1 13, TS2 2, SJW 1 at 48 MHz (ST's bit timing
// tables give the same).
const _: () = {
    assert!(matches!(bit_timing(48_000_000, 500_000), Some(0x001C_0005)));
    assert!(matches!(
        bit_timing(48_000_000, 1_000_000),
        Some(0x001C_0002)
    ));
    assert!(bit_timing(48_000_000, 700_000).is_none());
};
