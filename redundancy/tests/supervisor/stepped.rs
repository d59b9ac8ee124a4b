//! A device whose clock misbehaves: it reads `by` ahead of the simulated time until `at`, and
//! then steps back to it (a resynchronised real-time clock). As the clock contract asks of a
//! driver whose clock can step back, the device is told once, with `handle_timeout`, at the
//! step: with the old clock's last reading (`at + by`), then with the new one (`at`), so that
//! the step it measures is exactly `by`. (A machine measures a step from the latest time it
//! was given: time that passed unseen before the step is not known to it.) Without a step it
//! is the device itself.
#![allow(dead_code)]

use core::ops::{Deref, DerefMut};
use duocan::frame::FdFrame;
use duocan::machine::{Device, PortRequest, PortStatus};
use duocan::{Duration, Frame, Instant};

/// When the clock steps back, and by how much (simulated time).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ClockStep {
    pub at: Instant,
    pub by: Duration,
}

/// A clock that jumps ahead: it reads the simulated time until `at`, and `by` ahead of it from
/// then on (an RTC set forward while the network ran). The device is woken at the jump, as a
/// driver whose clock moved past its deadline is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ClockJump {
    pub at: Instant,
    pub by: Duration,
}

pub struct Stepped<T> {
    inner: T,
    step: Option<ClockStep>,
    /// The step has happened (and the device was told).
    stepped: bool,
    jump: Option<ClockJump>,
    jumped: bool,
}

impl<T: Device> Stepped<T> {
    /// `inner`, built at its own clock's time (`by` ahead of the simulated time until the step).
    pub fn new(inner: T, step: Option<ClockStep>) -> Self {
        Stepped {
            inner,
            step,
            stepped: false,
            jump: None,
            jumped: false,
        }
    }
    /// `inner` on a clock that jumps ahead (and never steps back).
    pub fn jumping(inner: T, jump: ClockJump) -> Self {
        Stepped {
            jump: Some(jump),
            ..Self::new(inner, None)
        }
    }
    /// The device's clock reading at simulated time `now`.
    pub fn reading(step: Option<ClockStep>, now: Instant) -> Instant {
        match step {
            Some(s) if now < s.at => now + s.by,
            _ => now,
        }
    }
    fn time(&mut self, now: Instant) -> Instant {
        if let Some(j) = self.jump {
            self.jumped |= now >= j.at;
            return if self.jumped { now + j.by } else { now };
        }
        match self.step {
            Some(s) if now >= s.at && !self.stepped => {
                self.stepped = true;
                self.inner.handle_timeout(s.at + s.by);
                self.inner.handle_timeout(now);
                now
            }
            step => Self::reading(step, now),
        }
    }
}

impl<T> Deref for Stepped<T> {
    type Target = T;
    fn deref(&self) -> &T {
        &self.inner
    }
}
impl<T> DerefMut for Stepped<T> {
    fn deref_mut(&mut self) -> &mut T {
        &mut self.inner
    }
}

impl<T: Device> Device for Stepped<T> {
    type Event = T::Event;
    fn port_count(&self) -> usize {
        self.inner.port_count()
    }
    fn handle_rx(&mut self, now: Instant, port: usize, frame: &Frame) {
        let t = self.time(now);
        self.inner.handle_rx(t, port, frame);
    }
    fn handle_rx_at(&mut self, now: Instant, port: usize, frame: &Frame, at: Instant) {
        let t = self.time(now);
        // The receive timestamp read on the device's clock: ahead until the step, never later
        // than the time the frame is handled.
        let at = Self::reading(self.step.filter(|_| !self.stepped), at).min(t);
        self.inner.handle_rx_at(t, port, frame, at);
    }
    fn handle_port_status(&mut self, now: Instant, port: usize, status: PortStatus) {
        let t = self.time(now);
        self.inner.handle_port_status(t, port, status);
    }
    fn handle_timeout(&mut self, now: Instant) {
        let t = self.time(now);
        self.inner.handle_timeout(t);
    }
    fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
        self.inner.poll_transmit()
    }
    fn poll_port_request(&mut self) -> Option<(usize, PortRequest)> {
        self.inner.poll_port_request()
    }
    fn poll_timeout(&self) -> Option<Instant> {
        let d = self.inner.poll_timeout();
        if let Some(j) = self.jump {
            // Before the jump: the deadline, or the jump itself; after it, in simulated time.
            return if self.jumped {
                d.map(|d| d - j.by)
            } else {
                Some(d.map_or(j.at, |d| d.min(j.at)))
            };
        }
        match self.step {
            // Before the step: the device's deadline in simulated time, and the step itself.
            Some(s) if !self.stepped => Some(d.map_or(s.at, |d| (d - s.by).min(s.at))),
            _ => d,
        }
    }
    fn poll_event(&mut self) -> Option<T::Event> {
        self.inner.poll_event()
    }
    fn fd_capable(&self) -> bool {
        self.inner.fd_capable()
    }
    // On the device's clock, as `handle_rx_at`.
    fn handle_rx_fd(&mut self, now: Instant, port: usize, frame: &FdFrame, at: Instant) {
        let t = self.time(now);
        let at = Self::reading(self.step.filter(|_| !self.stepped), at).min(t);
        self.inner.handle_rx_fd(t, port, frame, at);
    }
    fn poll_transmit_fd(&mut self) -> Option<(usize, FdFrame)> {
        self.inner.poll_transmit_fd()
    }
}
