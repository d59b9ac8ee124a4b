//! The clock: TIM2, a 32-bit timer counting microseconds, extended to duocan's 64-bit
//! [`Instant`] in software, and its compare channel 1 as the wake-up at the next deadline.
//!
//! The counter wraps every 71.6 minutes; the timer's update event (enabled as a wake-up) makes
//! sure the loop reads it at least once per wrap, which is all the extension needs. Nothing
//! here uses an interrupt handler: the flags only wake the processor ([`crate::sleep`]).

use crate::hal::pac::TIM2;
use crate::hal::rcc::{Enable, Rcc, Reset};
use duocan::Instant;

/// The microsecond clock and its wake-up.
pub struct Clock {
    tim: TIM2,
    /// Wraps of the counter seen so far, as the high word.
    high: u64,
    last: u32,
}

impl Clock {
    /// Starts TIM2 at 1 MHz, free-running over its 32 bits, from 0.
    pub fn start(tim: TIM2, rcc: &mut Rcc) -> Clock {
        TIM2::enable(rcc);
        TIM2::reset(rcc);
        let ticks_per_us = rcc.clocks.timclk1().raw() / 1_000_000;
        tim.psc()
            .write(|w| w.psc().set(ticks_per_us.saturating_sub(1) as u16));
        tim.arr().write(|w| w.arr().set(u32::MAX));
        // Load the prescaler now (it is buffered until an update event), then forget the
        // flag that event set.
        tim.egr().write(|w| w.ug().set_bit());
        tim.sr().write(|w| w.uif().clear_bit().cc1if().clear_bit());
        // Each wrap wakes the loop, so that no wrap goes unseen.
        tim.dier().write(|w| w.uie().set_bit());
        tim.cr1().modify(|_, w| w.cen().set_bit());
        Clock {
            tim,
            high: 0,
            last: 0,
        }
    }

    /// The current time (monotonic: the counter is read at least once per wrap).
    pub fn now(&mut self) -> Instant {
        let cnt = self.tim.cnt().read().cnt().bits();
        if cnt < self.last {
            self.high += 1;
        }
        self.last = cnt;
        Instant::from_micros((self.high << 32) | u64::from(cnt))
    }

    /// Acknowledges the timer's wake-ups (wrap, compare), so that the next one wakes the loop
    /// again. Called before each pass of the loop.
    pub fn acknowledge(&mut self) {
        self.tim
            .sr()
            .write(|w| w.uif().clear_bit().cc1if().clear_bit());
    }

    /// Arms the wake-up for `deadline` (`None`: only frames and wraps wake the loop). Returns
    /// true if the deadline has come already: the loop must not sleep.
    pub fn wake_at(&mut self, deadline: Option<Instant>) -> bool {
        let Some(t) = deadline else {
            self.tim.dier().modify(|_, w| w.cc1ie().clear_bit());
            return false;
        };
        let now = self.now();
        if t <= now {
            return true;
        }
        // Further than one wrap ahead: the wrap's wake-up comes first and re-arms.
        if t.as_micros() - now.as_micros() < 1 << 32 {
            self.tim.ccr1().write(|w| w.ccr().set(t.as_micros() as u32));
            // The write leaves the wrap flag as it is (its bits clear on 0 only).
            self.tim.sr().write(|w| w.cc1if().clear_bit());
            self.tim.dier().modify(|_, w| w.cc1ie().set_bit());
        } else {
            self.tim.dier().modify(|_, w| w.cc1ie().clear_bit());
        }
        // The counter may have passed the compare value while it was written.
        self.now() >= t
    }
}
