//! A port whose transmitter reaches nobody (a transceiver's TXD stuck recessive, a broken TX
//! line): the controller's error counter, error passive, bus-off and its automatic restart.

use super::timing::bits_duration;
use super::SimNetwork;
use crate::frame::instant::Instant;
use crate::machine::{ErrorCause, PortStatus};
use crate::sim::PortRef;

/// Bits one failing attempt takes: the start-of-frame bit (read back recessive: a bit error),
/// the error flag, its delimiter and the intermission.
pub(super) const DEAD_ATTEMPT_BITS: u32 = 1 + 6 + 8 + 3;
/// What an error-passive transmitter waits on top (suspend transmission).
pub(super) const SUSPEND_BITS: u32 = 8;
/// Recessive bits a bus-off controller waits for before it is error active again: 128
/// occurrences of 11.
pub(super) const BUS_OFF_RECOVERY_BITS: u32 = 128 * 11;
/// The transmit error counter's levels: warning, error passive, bus-off.
pub(super) const WARNING: u16 = 96;
pub(super) const PASSIVE: u16 = 128;
const BUS_OFF: u16 = 256;

impl SimNetwork {
    /// Makes one port's transmitter reach nobody (`dead`), or repairs it: a transceiver whose
    /// TXD is stuck recessive, a broken TX line. Its controller still receives every frame
    /// on the bus but cannot acknowledge any, and what it sends never reaches the wire: each
    /// attempt reads back recessive where it drove dominant, a bit error
    /// (`PortStatus::Error(ErrorCause::Bit)`) after the start-of-frame bit, the (unseen) error
    /// flag, its delimiter and the intermission (18 bit times; 26 when error passive, which
    /// suspends transmission), and the controller tries again. Its transmit error counter
    /// climbs by 8 per attempt: `Error(ErrorWarning)` at 96, `Error(ErrorPassive)` at 128,
    /// and at 256 it is bus-off: the frames it held are dropped, the device is told
    /// `Down(BusOff)`, and it neither sends nor receives until its automatic restart (as
    /// Linux's `restart-ms` does) after 128 × 11 recessive bit times, when the device is told
    /// `Up` and the counter is zero again: it receives again, and the next attempt fails
    /// again. A `PortRequest::Reinit` of a bus-off port restarts it at once. Nobody else
    /// sees any of this: the rest of the bus carries on. Repaired, the port sends again; the
    /// counter counts down by one for every frame sent. The device's other ports are not
    /// affected.
    pub fn set_port_tx_dead(&mut self, port: PortRef, dead: bool) {
        let p = self.port_index(port);
        self.ports[p].tx_dead = dead;
        self.refresh_port(p);
    }

    /// Whether the port's transmitter is dead ([`set_port_tx_dead`](Self::set_port_tx_dead)).
    pub fn is_port_tx_dead(&self, port: PortRef) -> bool {
        self.ports[self.port_index(port)].tx_dead
    }

    /// The port controller's transmit error counter (see
    /// [`set_port_tx_dead`](Self::set_port_tx_dead); zero on a port that never failed).
    pub fn port_tx_errors(&self, port: PortRef) -> u16 {
        self.ports[self.port_index(port)].tec
    }

    /// Whether the port's controller is bus-off (until its restart).
    pub fn is_port_bus_off(&self, port: PortRef) -> bool {
        self.ports[self.port_index(port)].bus_off.is_some()
    }

    /// A dead transmitter with a frame to send: its next failing attempt ends after its bit
    /// times (once armed, it stays armed until it ends).
    pub(super) fn arm_dead_attempt(&mut self, p: usize) {
        let port = &self.ports[p];
        if port.dead_wake.is_some() {
            return;
        }
        let bits = DEAD_ATTEMPT_BITS + if port.tec >= PASSIVE { SUSPEND_BITS } else { 0 };
        let at = self.now + bits_duration(bits, self.buses[port.bus as usize].bitrate);
        self.ports[p].dead_wake = Some(at);
        self.at(at, move |s| s.dead_attempt(p, at));
    }

    fn dead_attempt(&mut self, p: usize, at: Instant) {
        if self.ports[p].dead_wake != Some(at) {
            return;
        }
        self.ports[p].dead_wake = None;
        let port = &self.ports[p];
        let live = self.devices[port.dev as usize].powered
            && port.iface_up
            && port.tx_dead
            && port.bus_off.is_none()
            && !port.transmitting;
        if !live || !matches!(port.head(self.now), Ok(Some(_))) {
            self.refresh_port(p);
            return;
        }
        let port = &mut self.ports[p];
        port.stats.tx_attempts += 1;
        port.stats.error_frames += 1;
        let before = port.tec;
        port.tec = before.saturating_add(8);
        let tec = port.tec;
        if tec >= BUS_OFF {
            let until = self.now
                + bits_duration(BUS_OFF_RECOVERY_BITS, self.buses[port.bus as usize].bitrate);
            port.bus_off = Some(until);
            port.queue.clear();
            port.flushed = port.transmitting;
            let owner = port.dev;
            if self.devices[owner as usize].held.is_some() {
                self.refill.push(owner);
            }
            self.refresh_port(p);
            self.port_status(p, PortStatus::Error(ErrorCause::Bit));
            self.port_status(p, PortStatus::Down(ErrorCause::BusOff));
            self.at(until, move |s| s.restart_after_bus_off(p, until));
            return;
        }
        self.port_status(p, PortStatus::Error(ErrorCause::Bit));
        if before < WARNING && tec >= WARNING {
            self.port_status(p, PortStatus::Error(ErrorCause::ErrorWarning));
        }
        if before < PASSIVE && tec >= PASSIVE {
            self.port_status(p, PortStatus::Error(ErrorCause::ErrorPassive));
        }
        self.refresh_port(p);
    }

    fn restart_after_bus_off(&mut self, p: usize, until: Instant) {
        if self.ports[p].bus_off != Some(until) {
            return;
        }
        self.ports[p].bus_off = None;
        self.ports[p].tec = 0;
        self.refresh_port(p);
        self.port_status(p, PortStatus::Up);
        // A marginal transceiver that holds it error passive does so again.
        let floor = self.ports[p].tec_floor;
        if floor > 0 {
            self.raise_tec(p, floor);
        }
    }

    /// A re-initialisation of a bus-off port restarts its controller at once (true if it was
    /// bus-off).
    pub(super) fn restart_now(&mut self, p: usize) -> bool {
        let port = &mut self.ports[p];
        if port.bus_off.take().is_none() {
            return false;
        }
        // Held error passive by a marginal transceiver, it is at once where the hold puts it
        // (its device learns of it at the next report: the restart's `Up` comes after).
        port.tec = port.tec_floor;
        true
    }
}
