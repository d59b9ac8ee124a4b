//! Devices with their types erased, so one simulation holds nodes, masters and test probes.

use super::bus::Port;
use super::ids::{BusId, DevId, DeviceRef, SimError};
use super::SimNetwork;
use crate::frame::instant::Instant;
use crate::frame::{FdFrame, Frame};
use crate::machine::{Device, PortRequest, PortStatus};
use std::any::Any;
use std::sync::Arc;

/// The `Device` interface without the event type, plus the downcast back to the typed slot.
pub(super) trait ErasedDevice {
    fn handle_rx(&mut self, now: Instant, port: usize, frame: &Frame);
    fn handle_rx_at(&mut self, now: Instant, port: usize, frame: &Frame, at: Instant);
    fn handle_rx_fd(&mut self, now: Instant, port: usize, frame: &FdFrame, at: Instant);
    #[must_use]
    fn poll_transmit_fd(&mut self) -> Option<(usize, FdFrame)>;
    fn handle_port_status(&mut self, now: Instant, port: usize, status: PortStatus);
    fn handle_timeout(&mut self, now: Instant);
    #[must_use]
    fn poll_transmit(&mut self) -> Option<(usize, Frame)>;
    #[must_use]
    fn poll_port_request(&mut self) -> Option<(usize, PortRequest)>;
    #[must_use]
    fn poll_timeout(&self) -> Option<Instant>;
    /// Moves every pending event into the typed log, stamped with `now`; with a `cap`, the log
    /// holds at most that many and the rest are drained and dropped. Returns how many were.
    fn record_events(&mut self, now: Instant, cap: Option<usize>) -> u64;
    fn as_any(&self) -> &dyn Any;
    fn as_any_mut(&mut self) -> &mut dyn Any;
}

/// A device and the events it produced: the log lives next to the device so that it keeps its
/// type without the simulator knowing it.
pub(super) struct Slot<T: Device> {
    pub(super) device: T,
    pub(super) events: Vec<(Instant, T::Event)>,
}

impl<T> ErasedDevice for Slot<T>
where
    T: Device + 'static,
    T::Event: 'static,
{
    fn handle_rx(&mut self, now: Instant, port: usize, frame: &Frame) {
        self.device.handle_rx(now, port, frame);
    }
    fn handle_rx_at(&mut self, now: Instant, port: usize, frame: &Frame, at: Instant) {
        self.device.handle_rx_at(now, port, frame, at);
    }
    fn handle_rx_fd(&mut self, now: Instant, port: usize, frame: &FdFrame, at: Instant) {
        self.device.handle_rx_fd(now, port, frame, at);
    }
    fn poll_transmit_fd(&mut self) -> Option<(usize, FdFrame)> {
        self.device.poll_transmit_fd()
    }
    fn handle_port_status(&mut self, now: Instant, port: usize, status: PortStatus) {
        self.device.handle_port_status(now, port, status);
    }
    fn handle_timeout(&mut self, now: Instant) {
        self.device.handle_timeout(now);
    }
    fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
        self.device.poll_transmit()
    }
    fn poll_port_request(&mut self) -> Option<(usize, PortRequest)> {
        self.device.poll_port_request()
    }
    fn poll_timeout(&self) -> Option<Instant> {
        self.device.poll_timeout()
    }
    fn record_events(&mut self, now: Instant, cap: Option<usize>) -> u64 {
        let mut dropped = 0;
        while let Some(e) = self.device.poll_event() {
            if cap.is_some_and(|c| self.events.len() >= c) {
                dropped += 1;
            } else {
                self.events.push((now, e));
            }
        }
        dropped
    }
    fn as_any(&self) -> &dyn Any {
        self
    }
    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
}

/// What the simulator knows about one device.
pub(super) struct DeviceState {
    pub(super) name: Arc<str>,
    pub(super) dev: Box<dyn ErasedDevice>,
    /// Global index of the device's port 0; its ports are contiguous.
    pub(super) first_port: u32,
    pub(super) ports: u32,
    pub(super) powered: bool,
    /// Bumped on power-off and replacement: frames and deliveries of an earlier life carry an
    /// older generation and are discarded.
    pub(super) generation: u32,
    /// The deadline the deadline heap holds for this device (clamped to no earlier than the
    /// instant it was read); heap entries that disagree are stale.
    pub(super) deadline: Option<Instant>,
    pub(super) touched: bool,
    /// A frame pulled from the device whose port queue was full: it goes first once there is
    /// room, and until then no further frame is pulled (back-pressure).
    pub(super) held: Option<(usize, Frame, u64)>,
    /// The CAN FD frame `held` stands in for, when its serial has the FD bit.
    pub(super) held_fd: Option<FdFrame>,
    /// The device is FD-capable: only then is it asked for FD frames.
    pub(super) fd_capable: bool,
    /// Frames taken from the device so far: the next one's serial.
    pub(super) pulled: u64,
    /// Instant and count of `handle_timeout` calls there, to stop a device that keeps asking
    /// for the instant it was just given from spinning forever.
    pub(super) spin_at: Instant,
    pub(super) spins: u32,
    /// Frames and requests addressed to a port the device does not have.
    pub(super) misaddressed: u64,
    /// Events dropped because the log was full (recording off).
    pub(super) events_dropped: u64,
}

impl DeviceState {
    pub(super) fn port_range(&self) -> std::ops::Range<usize> {
        let first = self.first_port as usize;
        first..first + self.ports as usize
    }
}

impl SimNetwork {
    /// Adds a device with port `i` attached to `buses[i]`. The device is driven from the
    /// current instant on: `handle_timeout(now)` before the simulation continues.
    pub fn add_device<T>(
        &mut self,
        name: impl Into<String>,
        device: T,
        buses: &[BusId],
    ) -> Result<DevId<T>, SimError>
    where
        T: Device + 'static,
        T::Event: 'static,
    {
        let ports = device.port_count();
        if ports != buses.len() {
            return Err(SimError::PortCount {
                ports,
                buses: buses.len(),
            });
        }
        if let Some(&b) = buses.iter().find(|b| b.index() >= self.buses.len()) {
            return Err(SimError::UnknownBus(b));
        }
        let name = name.into();
        let fd_capable = device.fd_capable();
        self.check_fd(buses.iter().copied(), fd_capable, &name)?;
        let index = self.devices.len() as u32;
        let first_port = self.ports.len() as u32;
        for (local, bus) in buses.iter().enumerate() {
            let p = self.ports.len() as u32;
            let mut port = Port::new(index, local as u32, bus.0);
            port.fd_capable = fd_capable;
            self.ports.push(port);
            let bus = &mut self.buses[bus.index()];
            bus.ports.push(p);
            // Segment 0 is the bus, or its "everyone else" group when partitioned.
            bus.segments[0].insert_member(p);
        }
        self.devices.push(DeviceState {
            name: Arc::from(name),
            dev: Box::new(Slot {
                device,
                events: Vec::new(),
            }),
            first_port,
            ports: ports as u32,
            powered: true,
            generation: 0,
            deadline: None,
            touched: false,
            held: None,
            held_fd: None,
            fd_capable,
            pulled: 0,
            spin_at: Instant::ZERO,
            spins: 0,
            misaddressed: 0,
            events_dropped: 0,
        });
        self.touch(index);
        Ok(DevId::new(index))
    }

    /// Number of devices.
    pub fn device_count(&self) -> usize {
        self.devices.len()
    }

    /// Every device, in creation order.
    pub fn devices(&self) -> impl Iterator<Item = DeviceRef> {
        (0..self.devices.len() as u32).map(DeviceRef)
    }

    /// The device's name.
    pub fn device_name(&self, dev: impl Into<DeviceRef>) -> &str {
        &self.device_state(dev.into()).name
    }

    /// The device's number of ports.
    pub fn port_count(&self, dev: impl Into<DeviceRef>) -> usize {
        self.device_state(dev.into()).ports as usize
    }

    /// Frames and port requests the device addressed to ports it does not have (dropped).
    pub fn misaddressed(&self, dev: impl Into<DeviceRef>) -> u64 {
        self.device_state(dev.into()).misaddressed
    }

    /// The device.
    ///
    /// # Panics
    /// If `id` does not come from this simulation.
    pub fn device<T>(&self, id: DevId<T>) -> &T
    where
        T: Device + 'static,
        T::Event: 'static,
    {
        &self.slot(id).device
    }

    /// The device, for changing it. The simulation treats it as touched: before simulating
    /// further it calls `handle_timeout(now)` and drains it, so a frame it queued now goes out
    /// at the current instant.
    ///
    /// # Panics
    /// If `id` does not come from this simulation.
    pub fn device_mut<T>(&mut self, id: DevId<T>) -> &mut T
    where
        T: Device + 'static,
        T::Event: 'static,
    {
        self.touch(id.index);
        &mut self.slot_mut(id).device
    }

    /// Events the device dropped because its log was full: with recording off
    /// ([`set_recording`](Self::set_recording)) the log holds at most
    /// [`event_capacity`](Self::set_event_capacity) events until they are taken.
    pub fn events_dropped(&self, dev: impl Into<DeviceRef>) -> u64 {
        self.device_state(dev.into()).events_dropped
    }

    /// Events the device produced, each with the instant it was drained.
    pub fn events<T>(&self, id: DevId<T>) -> &[(Instant, T::Event)]
    where
        T: Device + 'static,
        T::Event: 'static,
    {
        &self.slot(id).events
    }

    /// Takes the device's events out of its log.
    pub fn take_events<T>(&mut self, id: DevId<T>) -> Vec<(Instant, T::Event)>
    where
        T: Device + 'static,
        T::Event: 'static,
    {
        std::mem::take(&mut self.slot_mut(id).events)
    }

    /// Cuts the device's power: it receives nothing, its timers stop, its queued frames are
    /// dropped and a frame it has on the wire reaches nobody. Its state is kept for
    /// [`power_on`](Self::power_on); use [`replace`](Self::replace) for a reboot.
    pub fn power_off(&mut self, dev: impl Into<DeviceRef>) {
        let d = dev.into().index();
        self.device_state(DeviceRef(d as u32));
        if self.devices[d].powered {
            self.devices[d].powered = false;
            self.forget_life(d);
        }
    }

    /// Restores power: the device resumes with the state it had, driven at once
    /// (`handle_timeout(now)`); deadlines it missed are due now.
    pub fn power_on(&mut self, dev: impl Into<DeviceRef>) {
        let d = dev.into().index();
        self.device_state(DeviceRef(d as u32));
        if !self.devices[d].powered {
            self.devices[d].powered = true;
            for p in self.devices[d].port_range() {
                self.refresh_port(p);
                self.hold_again(p);
            }
            self.touch(d as u32);
        }
    }

    /// Whether the device has power.
    pub fn is_powered(&self, dev: impl Into<DeviceRef>) -> bool {
        self.device_state(dev.into()).powered
    }

    /// Reboots the device as `device` (powered on, queues empty, driven at once) and returns
    /// the old value. Its event log continues.
    pub fn replace<T>(&mut self, id: DevId<T>, device: T) -> Result<T, SimError>
    where
        T: Device + 'static,
        T::Event: 'static,
    {
        let d = id.index();
        let ports = self.device_state(id.erased()).ports as usize;
        if device.port_count() != ports {
            return Err(SimError::PortCount {
                ports: device.port_count(),
                buses: ports,
            });
        }
        let fd_capable = device.fd_capable();
        let state = &self.devices[d];
        let buses = state.port_range().map(|p| BusId(self.ports[p].bus));
        self.check_fd(buses, fd_capable, &state.name.clone())?;
        self.devices[d].fd_capable = fd_capable;
        for p in self.devices[d].port_range() {
            self.ports[p].fd_capable = fd_capable;
        }
        let old = std::mem::replace(&mut self.slot_mut(id).device, device);
        self.forget_life(d);
        self.devices[d].powered = true;
        for p in self.devices[d].port_range() {
            self.refresh_port(p);
            self.hold_again(p);
        }
        self.touch(id.index);
        Ok(old)
    }

    /// Ends the device's current life: queued frames, pending deliveries and its deadline.
    fn forget_life(&mut self, d: usize) {
        let dev = &mut self.devices[d];
        dev.generation = dev.generation.wrapping_add(1);
        dev.deadline = None;
        dev.held = None;
        dev.held_fd = None;
        let ports = dev.port_range();
        for p in ports {
            let port = &mut self.ports[p];
            port.queue.clear();
            port.fd_queue.clear();
            port.delayed = 0;
            // Its controllers start afresh: error counters at zero, none bus-off.
            port.tec = 0;
            port.bus_off = None;
            port.suspended = None;
            self.refresh_port(p);
        }
    }

    /// A classic-only device may not be attached to a CAN FD bus (see [`BusConfig::fd`](super::BusConfig::fd)).
    fn check_fd(
        &self,
        mut buses: impl Iterator<Item = BusId>,
        fd_capable: bool,
        device: &str,
    ) -> Result<(), SimError> {
        match buses.find(|b| !fd_capable && self.buses[b.index()].fd) {
            Some(bus) => Err(SimError::ClassicOnFdBus {
                bus,
                device: device.to_owned(),
            }),
            None => Ok(()),
        }
    }

    pub(super) fn touch(&mut self, d: u32) {
        let dev = &mut self.devices[d as usize];
        if !dev.touched {
            dev.touched = true;
            self.touched.push(d);
        }
    }

    fn slot<T>(&self, id: DevId<T>) -> &Slot<T>
    where
        T: Device + 'static,
        T::Event: 'static,
    {
        match self
            .devices
            .get(id.index())
            .and_then(|d| d.dev.as_any().downcast_ref::<Slot<T>>())
        {
            Some(s) => s,
            None => panic!("{id:?} is not a device of this simulation"),
        }
    }

    fn slot_mut<T>(&mut self, id: DevId<T>) -> &mut Slot<T>
    where
        T: Device + 'static,
        T::Event: 'static,
    {
        match self
            .devices
            .get_mut(id.index())
            .and_then(|d| d.dev.as_any_mut().downcast_mut::<Slot<T>>())
        {
            Some(s) => s,
            None => panic!("{id:?} is not a device of this simulation"),
        }
    }
}
