//! CAN FD frames at a redundant master (feature `fd`): the station is FD-capable when its
//! layer is (every port, see [`crate::link::dual_bus::fd`]), sends FD frames through it on both
//! buses and hands the FD frames the layer delivers, each occurrence once, to the application.
//!
//! The supervisor and the CiA 302-2 master it owns take classic frames only (the CANopen FD
//! services are not there yet): what an FD frame is for is the application's. The layer's
//! requests and the supervisor's commands are exchanged after an FD frame as after a classic
//! one, so a node first heard in an FD frame is reachable at once.
//!
//! # Memory and overflow
//!
//! Delivered FD frames wait in a queue of [`FD_RX_QUEUE`] until the application takes them
//! ([`SupervisedStation::poll_fd_frame`]); when it is full the newest is dropped and counted
//! ([`SupervisedStation::fd_frames_dropped`]), in order otherwise.

use super::{SupervisedLink, SupervisedStation};
use crate::link::dual_bus::FdSendError;
use duocan_core::frame::FdFrame;
use duocan_core::machine::{forward_commands, forward_requests, Station};
use duocan_core::od::ObjectDictionary;
use duocan_core::Instant;

/// FD frames the station holds for the application.
pub const FD_RX_QUEUE: usize = 16;

impl<D: ObjectDictionary, L: SupervisedLink> SupervisedStation<D, L> {
    /// Sends a CAN FD frame on the buses the layer routes it to; an error, nothing sent, while
    /// a port is classic-only ([`DualBus::set_port_fd`](crate::DualBus::set_port_fd)).
    pub fn send_fd(&mut self, now: Instant, frame: &FdFrame) -> Result<(), FdSendError> {
        self.station.link.dual_bus_mut().send_fd(now, frame)
    }

    /// The oldest CAN FD frame the layer delivered and the application has not taken.
    pub fn poll_fd_frame(&mut self) -> Option<FdFrame> {
        self.fd_rx.pop()
    }

    /// Delivered CAN FD frames dropped because the application did not take them.
    pub fn fd_frames_dropped(&self) -> u32 {
        self.fd_rx.dropped()
    }

    /// A CAN FD frame from `port` stamped `at`: through the layer, then the exchange of
    /// requests and commands a classic frame is followed by.
    pub(super) fn rx_fd(&mut self, now: Instant, port: usize, frame: &FdFrame, at: Instant) {
        let Station { link, machine, .. } = &mut self.station;
        if let Some(f) = link.dual_bus_mut().handle_rx_fd_at(now, port, frame, at) {
            self.fd_rx.push(f);
        }
        forward_requests(now, link, machine);
        forward_commands(now, machine, link);
    }
}
