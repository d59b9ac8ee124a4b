//! A controller held error passive (a marginal transceiver): its transmit error counter above
//! 127 without reaching bus-off, the suspend-transmission time after each of its frames and
//! its passive (recessive) error flags.

use super::timing::bits_duration;
use super::tx_dead::{PASSIVE, SUSPEND_BITS, WARNING};
use super::SimNetwork;
use crate::frame::instant::Instant;
use crate::machine::{ErrorCause, PortStatus};
use crate::sim::PortRef;

/// The highest counter a controller that is not bus-off can have.
const HIGHEST_PASSIVE: u16 = 255;

impl SimNetwork {
    /// Holds one port controller's transmit error counter at `tec` or above (`Some`, clamped
    /// to 128..=255: a marginal transceiver whose occasional bit errors keep the counter
    /// there, error passive without reaching bus-off; those errors themselves are not
    /// simulated, add [`FaultRates::corrupt_sent`](super::FaultRates::corrupt_sent) for them),
    /// or lets it go (`None`). Held, the controller is error
    /// passive as ISO 11898-1 has it: it still sends and receives every frame, but after each
    /// frame it sent (delivered or not) it waits the suspend-transmission time, 8 bit times
    /// after the intermission, before it may start another, so a frame another node queues
    /// meanwhile goes first whatever its identifier; and an error it detects while receiving
    /// raises a passive (recessive) error flag, which loses that frame for this port alone
    /// (`PortStatus::Error(ErrorCause::Crc)`, as a dropped frame is traced) instead of
    /// destroying it for every node. Its device is told `Error(ErrorWarning)` when the counter
    /// passes 95 and `Error(ErrorPassive)` when it passes 127, as a SocketCAN controller
    /// reports its state changes. Let go, the counter counts down by one for every frame sent
    /// (as it always does) and at 127 the controller is error active again: its device is told
    /// `Up` (SocketCAN's "back to error active"). A controller whose counter is 128 or more
    /// for another reason (a dead transmitter's failed attempts) is error passive in the same
    /// way. A reboot of the device starts its controllers at zero; one still held goes error
    /// passive again at once. Nothing is drawn at random: the other nodes' frames and the
    /// generator's sequence are those of a bus without the fault, except where this port
    /// would have destroyed a frame it received.
    pub fn set_port_error_passive(&mut self, port: PortRef, tec: Option<u16>) {
        let p = self.port_index(port);
        let floor = tec.map_or(0, |t| t.clamp(PASSIVE, HIGHEST_PASSIVE));
        self.ports[p].tec_floor = floor;
        if floor > 0 {
            self.raise_tec(p, floor);
        }
    }

    /// The level a port's transmit error counter is held at
    /// ([`set_port_error_passive`](Self::set_port_error_passive); `None` when not held).
    pub fn port_error_passive_hold(&self, port: PortRef) -> Option<u16> {
        let floor = self.ports[self.port_index(port)].tec_floor;
        (floor > 0).then_some(floor)
    }

    /// Whether the port's controller is error passive (its transmit error counter at 128 or
    /// more, not bus-off).
    pub fn is_port_error_passive(&self, port: PortRef) -> bool {
        let port = &self.ports[self.port_index(port)];
        port.tec >= PASSIVE && port.bus_off.is_none()
    }

    /// Raises port `p`'s transmit error counter to `to` (never lowers it), telling its device
    /// of the levels it passes.
    pub(super) fn raise_tec(&mut self, p: usize, to: u16) {
        let before = self.ports[p].tec;
        if to <= before || self.ports[p].bus_off.is_some() {
            return;
        }
        self.ports[p].tec = to;
        if before < WARNING && to >= WARNING {
            self.port_status(p, PortStatus::Error(ErrorCause::ErrorWarning));
        }
        if before < PASSIVE && to >= PASSIVE {
            self.port_status(p, PortStatus::Error(ErrorCause::ErrorPassive));
        }
    }

    /// A frame port `p` sent was delivered: its counter counts down by one, not below the level
    /// it is held at; back under 128 its controller is error active again.
    pub(super) fn tx_ok_tec(&mut self, p: usize) {
        let port = &mut self.ports[p];
        let before = port.tec;
        port.tec = before.saturating_sub(1).max(port.tec_floor);
        if before >= PASSIVE && port.tec < PASSIVE {
            self.port_status(p, PortStatus::Up);
        }
    }

    /// Port `p` ended a frame it sent at `end`: error passive, it may not start another before
    /// the suspend-transmission time is over (its place in arbitration comes back then).
    pub(super) fn suspend_after(&mut self, p: usize, end: Instant) {
        if self.ports[p].tec < PASSIVE {
            return;
        }
        let bitrate = self.buses[self.ports[p].bus as usize].bitrate;
        let until = end + bits_duration(SUSPEND_BITS, bitrate);
        self.ports[p].suspended = Some(until);
        // Out of the arbitration its frame's end put it back in.
        self.refresh_port(p);
        self.at(until, move |s| {
            if s.ports[p].suspended == Some(until) {
                s.ports[p].suspended = None;
                s.refresh_port(p);
            }
        });
    }

    /// Whether port `p` waits out its suspend-transmission time at this instant.
    pub(super) fn is_suspended(&self, p: usize) -> bool {
        self.ports[p].suspended.is_some_and(|t| t > self.now)
    }

    /// After a reboot of its device, a controller still held error passive goes there again
    /// (its counter started at zero).
    pub(super) fn hold_again(&mut self, p: usize) {
        let floor = self.ports[p].tec_floor;
        if floor > 0 {
            self.at(self.now, move |s| {
                let floor = s.ports[p].tec_floor;
                if floor > 0 {
                    s.raise_tec(p, floor);
                }
            });
        }
    }
}
