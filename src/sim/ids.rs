//! Handles to buses, devices and ports of a [`SimNetwork`](super::SimNetwork), and its errors.

use core::fmt;
use core::hash::{Hash, Hasher};
use core::marker::PhantomData;

/// A bus of a simulation, in creation order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct BusId(pub(super) u32);

impl BusId {
    /// Position in creation order (0 for the first bus).
    pub const fn index(self) -> usize {
        self.0 as usize
    }
}

impl fmt::Display for BusId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "bus{}", self.0)
    }
}

/// A device of a simulation, untyped: what fault, power and statistics calls take.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct DeviceRef(pub(super) u32);

impl DeviceRef {
    /// Position in creation order: ties in arbitration go to the lower index.
    pub const fn index(self) -> usize {
        self.0 as usize
    }
    /// One of the device's ports.
    pub const fn port(self, port: usize) -> PortRef {
        PortRef { device: self, port }
    }
}

impl fmt::Display for DeviceRef {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "dev{}", self.0)
    }
}

/// A device of a simulation that remembers its type, so that
/// [`SimNetwork::device`](super::SimNetwork::device) hands back a `&T`.
pub struct DevId<T> {
    pub(super) index: u32,
    // `fn() -> T` keeps the handle `Copy`, `Send` and `Sync` whatever `T` is.
    _type: PhantomData<fn() -> T>,
}

impl<T> DevId<T> {
    pub(super) const fn new(index: u32) -> Self {
        DevId {
            index,
            _type: PhantomData,
        }
    }
    /// Position in creation order.
    pub const fn index(self) -> usize {
        self.index as usize
    }
    /// The untyped handle.
    pub const fn erased(self) -> DeviceRef {
        DeviceRef(self.index)
    }
    /// One of the device's ports.
    pub const fn port(self, port: usize) -> PortRef {
        self.erased().port(port)
    }
}

impl<T> Clone for DevId<T> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<T> Copy for DevId<T> {}
impl<T> PartialEq for DevId<T> {
    fn eq(&self, other: &Self) -> bool {
        self.index == other.index
    }
}
impl<T> Eq for DevId<T> {}
impl<T> Hash for DevId<T> {
    fn hash<H: Hasher>(&self, state: &mut H) {
        self.index.hash(state);
    }
}
impl<T> fmt::Debug for DevId<T> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "DevId({})", self.index)
    }
}
impl<T> From<DevId<T>> for DeviceRef {
    fn from(id: DevId<T>) -> Self {
        id.erased()
    }
}

/// One port of one device.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct PortRef {
    /// The device.
    pub device: DeviceRef,
    /// The port, as the device numbers it (`0..port_count()`).
    pub port: usize,
}

impl fmt::Display for PortRef {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}.{}", self.device, self.port)
    }
}

/// How to build a bus.
#[derive(Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub struct BusConfig {
    /// Shown in traces and `Debug` output.
    pub name: String,
    /// Bits per second (0 is treated as 1).
    pub bitrate: u32,
    /// A CAN FD bus's data phase bit rate (frames with BRS switch to it); `None`: a classic
    /// bus. See [`BusConfig::fd`].
    pub data_bitrate: Option<u32>,
}

impl BusConfig {
    /// A bus called `name` running at `bitrate` bit/s.
    #[must_use]
    pub fn new(name: impl Into<String>, bitrate: u32) -> Self {
        BusConfig {
            name: name.into(),
            bitrate,
            data_bitrate: None,
        }
    }

    /// A CAN FD bus: `bitrate` in the arbitration phase, `data_bitrate` in the data phase of
    /// frames with BRS (pass `bitrate` again for a bus that does not switch). Every device
    /// attached to it must be FD-capable ([`Device::fd_capable`](crate::Device::fd_capable)):
    /// a classic-only controller answers FD frames with error frames, so the simulator refuses
    /// one at [`add_device`](super::SimNetwork::add_device) ([`SimError::ClassicOnFdBus`]).
    #[must_use]
    pub fn fd(self, data_bitrate: u32) -> Self {
        BusConfig {
            data_bitrate: Some(data_bitrate),
            ..self
        }
    }
}

/// What the simulator refuses.
#[derive(Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum SimError {
    /// A device must get exactly one bus per port.
    PortCount {
        /// Ports the device has.
        ports: usize,
        /// Buses it was given.
        buses: usize,
    },
    /// The bus does not belong to this simulation.
    UnknownBus(BusId),
    /// A classic-only device attached to a CAN FD bus: its controller would answer every FD
    /// frame with error frames. FD frames belong only where every node is FD-capable.
    ClassicOnFdBus {
        /// The FD bus.
        bus: BusId,
        /// The device's name.
        device: String,
    },
}

impl fmt::Display for SimError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SimError::PortCount { ports, buses } => {
                write!(f, "device has {ports} ports but was given {buses} buses")
            }
            SimError::UnknownBus(b) => write!(f, "{b} is not a bus of this simulation"),
            SimError::ClassicOnFdBus { bus, device } => write!(
                f,
                "device {device:?} is classic-only but {bus} is a CAN FD bus (its controller \
                 would answer FD frames with error frames): FD frames only where every node is \
                 FD-capable"
            ),
        }
    }
}

impl std::error::Error for SimError {}
