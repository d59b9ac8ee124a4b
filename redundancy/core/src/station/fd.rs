//! CAN FD frames at a redundant master (feature `fd`): the station is FD-capable when its
//! layer is (every port, see [`crate::link::dual_bus::fd`]), sends FD frames through it on both
//! buses and hands the FD frames the layer delivers, each occurrence once, to the supervisor
//! and to the application.
//!
//! The supervisor passes them to its CiA 302-2 master, whose node serves USDO (CiA 1301) when
//! it is configured for a CANopen FD network ([`NodeConfig::fd`](duocan_core::NodeConfig::fd)),
//! and the master's FD answers go out through the layer on both buses like its classic frames:
//! so a tool reads and writes a redundant master's dictionary over USDO whichever bus works.
//! Everything else an FD frame is for (process data) is the application's. The layer's
//! requests and the supervisor's commands are exchanged after an FD frame as after a classic
//! one, so a node first heard in an FD frame is reachable at once.
//!
//! Error control on such a network is heartbeats alone: CAN FD has no remote frames, so node
//! guarding cannot run there (see [`crate::supervisor::fd_guarding`]).
//!
//! # Memory and overflow
//!
//! Delivered FD frames wait in a queue of [`FD_RX_QUEUE`] until the application takes them
//! ([`SupervisedStation::poll_fd_frame`]); when it is full the newest is dropped and counted
//! ([`SupervisedStation::fd_frames_dropped`]), in order otherwise.

use super::{SupervisedLink, SupervisedStation};
use crate::link::dual_bus::FdSendError;
use duocan_core::frame::FdFrame;
use duocan_core::machine::{forward_commands, forward_requests, BusLink, Station};
use duocan_core::od::ObjectDictionary;
use duocan_core::Instant;
use duocan_core::Machine;

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

    /// A CAN FD frame from `port` stamped `at`, as [`Device::handle_rx_fd`](duocan_core::machine::Device::handle_rx_fd) takes it,
    /// returning what the layer delivered (once per occurrence over two buses) without
    /// queueing it for the application: through the layer, the exchange of requests and
    /// commands a classic frame is followed by, the delivered frame to the supervisor (its
    /// master's USDO server), the exchange again, and what the master answered handed to the
    /// layer at once, at `now`. What watches the traffic beside the supervisor (a door's USDO
    /// client) reads this, not the ports' copies.
    pub fn handle_rx_fd_delivered(
        &mut self,
        now: Instant,
        port: usize,
        frame: &FdFrame,
        at: Instant,
    ) -> Option<FdFrame> {
        let Station { link, machine, .. } = &mut self.station;
        let f = link.dual_bus_mut().handle_rx_fd_at(now, port, frame, at);
        forward_requests(now, link, machine);
        forward_commands(now, machine, link);
        if let Some(f) = &f {
            machine.handle_frame_fd(now, f);
            forward_requests(now, link, machine);
            forward_commands(now, machine, link);
            while let Some(out) = machine.poll_transmit_fd() {
                BusLink::send_fd(link, now, &out);
            }
        }
        f
    }

    /// A CAN FD frame from `port` stamped `at`: [`handle_rx_fd_delivered`](Self::handle_rx_fd_delivered),
    /// the delivered frame then queued for the application too.
    pub(super) fn rx_fd(&mut self, now: Instant, port: usize, frame: &FdFrame, at: Instant) {
        if let Some(f) = self.handle_rx_fd_delivered(now, port, frame, at) {
            self.fd_rx.push(f);
        }
    }
}
