//! An in-process bus: ports that share frames through memory. For testing applications and the
//! runtime without sockets; every port sees every frame the others send, in order. A port
//! behind a [`Connector`] ([`MemBus::plugged_port`]) fails when the connector is pulled.
//!
//! Every frame is received with a stamp: the instant it went onto the bus (tokio's clock, so a
//! paused test clock stamps in its own time). On a paced bus ([`MemBus::with_bit_rate`]) that is
//! the end of the frame's time on the bus as the schedule books it, but never later than the
//! instant it was handed to the receivers: a sender that wakes late with a backlog puts its
//! frames on the bus at their booked times, which are earlier than the wake-up.
//!
//! The bus carries CAN FD frames too: every port sends them ([`Port::send_fd`]) and hands them
//! over through [`Port::recv_any`], in order with the classic ones; its [`Port::recv`] counts
//! them as invalid and skips them, as a real port opened for CAN FD does. A paced bus books an
//! FD frame at its bit rate throughout, as if without bit rate switching.

use super::{AnyInput, Port, PortCounters, PortError, PortErrorKind, PortInput};
use crate::frame::{FdFrame, Frame};
use crate::machine::PortStatus;
use std::sync::Arc;
use tokio::sync::broadcast;

/// Frames a slow port may fall behind before it loses some (counted as `rx_invalid`).
pub const MEM_BUS_DEPTH: usize = 4096;

/// How far ahead of real time a paced bus lets its senders run (see [`MemBus::with_bit_rate`]).
pub const MEM_BUS_BURST: std::time::Duration = std::time::Duration::from_millis(2);

/// How much bus time a paced bus with a backlog makes up when its senders come back late (see
/// [`MemBus::with_bit_rate`]).
pub const MEM_BUS_CATCH_UP: std::time::Duration = std::time::Duration::from_millis(100);

/// What the bus carries: a classic frame as it is, a CAN FD frame shared (so that every
/// classic frame in the bus's buffer does not take an FD frame's room).
#[derive(Clone, Debug)]
enum Wire {
    Classic(Frame),
    Fd(Arc<FdFrame>),
}

/// A frame on the bus: its sender, the frame, when it went onto the bus.
type Carried = (u64, Wire, std::time::Instant);

/// One in-process bus.
#[derive(Clone, Debug)]
pub struct MemBus {
    tx: broadcast::Sender<Carried>,
    name: String,
    pace: Option<std::sync::Arc<Pace>>,
}

/// The bit rate of a paced bus and its schedule.
#[derive(Debug)]
struct Pace {
    bit_ns: u64,
    booked: std::sync::Mutex<Booked>,
}

/// When the frames sent so far are through, and whether the bus has a backlog: a sender was
/// made to wait and the schedule has not caught up with real time since.
#[derive(Debug, Default)]
struct Booked {
    until: Option<tokio::time::Instant>,
    backlog: bool,
}

impl Pace {
    /// Books `frame`'s time on the bus: the instant to wait for when the senders ran more than
    /// [`MEM_BUS_BURST`] ahead, and the instant the frame is through.
    fn book(&self, frame: &Frame) -> (Option<tokio::time::Instant>, tokio::time::Instant) {
        let data = if frame.is_remote() {
            0
        } else {
            u64::from(frame.dlc())
        };
        self.book_bits(frame.id(), data)
    }

    /// [`Pace::book`] for a frame with `id` and `data` bytes.
    fn book_bits(
        &self,
        id: crate::frame::Id,
        data: u64,
    ) -> (Option<tokio::time::Instant>, tokio::time::Instant) {
        // The nominal length (no stuff bits): SOF to the intermission, 47 bits of frame around
        // the data for an 11-bit identifier, 67 for a 29-bit one.
        let overhead = if matches!(id, crate::frame::Id::Standard(_)) {
            47
        } else {
            67
        };
        let data = 8 * data;
        let time = std::time::Duration::from_nanos((overhead + data) * self.bit_ns);
        let now = tokio::time::Instant::now();
        let mut b = self.booked.lock().unwrap_or_else(|p| p.into_inner());
        // With a backlog, frames follow each other on the bus without a gap, also when their
        // sender was made to wait and woke late (a loaded machine): the time it overslept is
        // made up, not lost. Lost, it would add up differently on each of two buses that carry
        // the same frames, and a device would get its two copies of a frame further and
        // further apart. A schedule more than MEM_BUS_CATCH_UP behind was idle: from now.
        let start = match b.until {
            Some(t) if t > now || (b.backlog && t + MEM_BUS_CATCH_UP >= now) => t,
            _ => now,
        };
        let until = start + time;
        let wait = until > now + MEM_BUS_BURST;
        b.until = Some(until);
        b.backlog = wait || (b.backlog && until < now);
        (wait.then(|| until - MEM_BUS_BURST), until)
    }
}

impl MemBus {
    /// A new, empty bus that carries frames as fast as its ports send them.
    #[must_use]
    pub fn new(name: impl Into<String>) -> Self {
        MemBus {
            tx: broadcast::channel(MEM_BUS_DEPTH).0,
            name: name.into(),
            pace: None,
        }
    }

    /// A new, empty bus that carries frames at most as fast as a CAN bus of `bits_per_s` would
    /// (each frame its nominal length, without stuff bits): a sender that runs more than
    /// [`MEM_BUS_BURST`] ahead waits in [`Port::send`]. Without it a block transfer floods the
    /// bus as fast as the machine can copy frames, and the receivers, tasks that share the CPU
    /// with everything else, fall behind by as much as the flood lasts, each by its own amount:
    /// a dual-bus layer then sees the two copies of a frame further apart than two real buses
    /// would ever carry them. While the bus has a backlog, a sender that wakes late from its
    /// wait (a loaded machine) does not cost the bus time: the frames it then sends go out at
    /// once until the bus is back on its schedule (when it is at most [`MEM_BUS_CATCH_UP`]
    /// behind), so two paced buses that carry the same frames stay as close together as their
    /// senders' wake-ups. A rate of 0 is taken as 1 bit/s.
    #[must_use]
    pub fn with_bit_rate(name: impl Into<String>, bits_per_s: u32) -> Self {
        MemBus {
            pace: Some(std::sync::Arc::new(Pace {
                bit_ns: 1_000_000_000 / u64::from(bits_per_s.max(1)),
                booked: std::sync::Mutex::new(Booked::default()),
            })),
            ..MemBus::new(name)
        }
    }
    /// A port on this bus.
    pub fn port(&self) -> MemPort {
        static NEXT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);
        MemPort {
            bus: self.clone(),
            rx: Some(self.tx.subscribe()),
            me: NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
            counters: PortCounters::new(),
            echoes: false,
            confirm: false,
        }
    }
    /// A port on this bus that can confirm its transmissions ([`Port::confirm_transmissions`]),
    /// as a SocketCAN port on a controller that echoes does: its own frames come back from the
    /// bus as confirmations, in order. (A plain [`MemBus::port`] cannot: the runtime's tasks
    /// on a busy test machine would otherwise judge a dual-bus device's ports by how the
    /// machine schedules them.)
    pub fn confirming_port(&self) -> MemPort {
        MemPort {
            echoes: true,
            ..self.port()
        }
    }
}

/// A port on a [`MemBus`].
#[derive(Debug)]
pub struct MemPort {
    bus: MemBus,
    rx: Option<broadcast::Receiver<Carried>>,
    me: u64,
    counters: PortCounters,
    /// Made to confirm transmissions when asked ([`MemBus::confirming_port`]).
    echoes: bool,
    /// Its own frames come back as confirmations ([`Port::confirm_transmissions`]).
    confirm: bool,
}

impl Port for MemPort {
    fn name(&self) -> &str {
        &self.bus.name
    }
    fn counters(&self) -> PortCounters {
        self.counters.clone()
    }
    async fn recv(&mut self) -> Result<PortInput, PortError> {
        loop {
            match self.recv_wire().await? {
                AnyInput::Frame(f, at) => return Ok(PortInput::Frame(f, at)),
                AnyInput::Status(s) => return Ok(PortInput::Status(s)),
                // What a classic read cannot hand over.
                AnyInput::Fd(..) => self.counters.rx_invalid(),
            }
        }
    }
    async fn recv_any(&mut self) -> Result<AnyInput, PortError> {
        let x = self.recv_wire().await?;
        if let AnyInput::Fd(..) = x {
            self.counters.rx_frames();
        }
        Ok(x)
    }
    async fn send(&mut self, frame: &Frame) -> Result<(), PortError> {
        let booked = self.bus.pace.as_ref().map(|p| p.book(frame));
        self.put(booked, Wire::Classic(*frame)).await;
        Ok(())
    }
    async fn send_fd(&mut self, frame: &FdFrame) -> Result<(), PortError> {
        let booked = self
            .bus
            .pace
            .as_ref()
            .map(|p| p.book_bits(frame.id(), u64::try_from(frame.len()).unwrap_or(u64::MAX)));
        self.put(booked, Wire::Fd(Arc::new(*frame))).await;
        Ok(())
    }
    fn confirm_transmissions(&mut self) -> bool {
        self.confirm = self.echoes;
        self.confirm
    }
    async fn reopen(&mut self) -> Result<(), PortError> {
        self.rx = Some(self.bus.tx.subscribe());
        self.counters.reopened();
        Ok(())
    }
}

impl MemPort {
    /// The next input, classic or FD (a CAN FD frame not yet counted).
    async fn recv_wire(&mut self) -> Result<AnyInput, PortError> {
        loop {
            let Some(rx) = self.rx.as_mut() else {
                return Err(PortError::new(
                    &self.bus.name,
                    PortErrorKind::Closed,
                    "closed",
                ));
            };
            match rx.recv().await {
                // Its own frame, back from the bus: the confirmation of its transmission.
                Ok((from, _, _)) if from == self.me => {
                    if self.confirm {
                        return Ok(AnyInput::Status(PortStatus::TxOk));
                    }
                }
                Ok((_, Wire::Classic(f), at)) => {
                    self.counters.rx_frames();
                    return Ok(AnyInput::Frame(f, Some(at)));
                }
                // Counted by the caller: a frame for `recv_any`, invalid for `recv`.
                Ok((_, Wire::Fd(f), at)) => return Ok(AnyInput::Fd(*f, Some(at))),
                Err(broadcast::error::RecvError::Lagged(n)) => {
                    for _ in 0..n {
                        self.counters.rx_invalid();
                    }
                    return Ok(AnyInput::Status(PortStatus::Error(
                        crate::machine::ErrorCause::RxOverflow,
                    )));
                }
                Err(broadcast::error::RecvError::Closed) => {
                    self.rx = None;
                }
            }
        }
    }

    /// Puts `wire` onto the bus, after the wait its booking asks for.
    async fn put(
        &mut self,
        booked: Option<(Option<tokio::time::Instant>, tokio::time::Instant)>,
        wire: Wire,
    ) {
        let through = match booked {
            Some((wait, through)) => {
                if let Some(t) = wait {
                    tokio::time::sleep_until(t).await;
                }
                Some(through)
            }
            None => None,
        };
        // On the wire when it is through, but not after the receivers get it.
        let now = tokio::time::Instant::now();
        let at = through.map_or(now, |t| t.min(now)).into_std();
        // No receivers is not an error: nobody else is on the bus.
        let _ = self.bus.tx.send((self.me, wire, at));
        self.counters.tx_frames();
    }
}

/// A [`MemBus`] port behind a connector that can be pulled ([`MemBus::plugged_port`]): while
/// pulled, receiving, sending and re-opening fail with the interface down, as a real port does
/// when its cable is cut, so that what watches ports (a dual-bus layer's health, the runtime's
/// re-initialisation) sees a port fail and come back.
#[derive(Debug)]
pub struct PluggedPort {
    inner: MemPort,
    pulled: tokio::sync::watch::Receiver<bool>,
}

/// The connector of a [`PluggedPort`]: pull it, plug it back in. Cheap to clone.
#[derive(Clone, Debug)]
pub struct Connector(std::sync::Arc<tokio::sync::watch::Sender<bool>>);

impl Connector {
    /// Pulls the connector: the port goes down.
    pub fn pull(&self) {
        self.0.send_replace(true);
    }
    /// Plugs it back in: the port works again once re-opened.
    pub fn plug_in(&self) {
        self.0.send_replace(false);
    }
    /// True while pulled.
    #[must_use]
    pub fn is_pulled(&self) -> bool {
        *self.0.borrow()
    }
}

impl MemBus {
    /// A port on this bus behind a [`Connector`] (plugged in).
    pub fn plugged_port(&self) -> (PluggedPort, Connector) {
        let (tx, rx) = tokio::sync::watch::channel(false);
        let port = PluggedPort {
            inner: self.port(),
            pulled: rx,
        };
        (port, Connector(std::sync::Arc::new(tx)))
    }
}

impl PluggedPort {
    fn down(&self) -> PortError {
        PortError::new(
            &self.inner.bus.name,
            PortErrorKind::InterfaceDown,
            "connector pulled",
        )
    }
    fn is_pulled(&self) -> bool {
        *self.pulled.borrow()
    }
}

impl Port for PluggedPort {
    fn name(&self) -> &str {
        self.inner.name()
    }
    fn counters(&self) -> PortCounters {
        self.inner.counters()
    }
    async fn recv(&mut self) -> Result<PortInput, PortError> {
        if self.is_pulled() {
            return Err(self.down());
        }
        tokio::select! {
            r = self.inner.recv() => return r,
            _ = self.pulled.wait_for(|c| *c) => {}
        }
        Err(self.down())
    }
    async fn send(&mut self, frame: &Frame) -> Result<(), PortError> {
        if self.is_pulled() {
            return Err(self.down());
        }
        self.inner.send(frame).await
    }
    async fn send_fd(&mut self, frame: &FdFrame) -> Result<(), PortError> {
        if self.is_pulled() {
            return Err(self.down());
        }
        self.inner.send_fd(frame).await
    }
    async fn recv_any(&mut self) -> Result<AnyInput, PortError> {
        if self.is_pulled() {
            return Err(self.down());
        }
        tokio::select! {
            r = self.inner.recv_any() => return r,
            _ = self.pulled.wait_for(|c| *c) => {}
        }
        Err(self.down())
    }
    fn confirm_transmissions(&mut self) -> bool {
        self.inner.confirm_transmissions()
    }
    async fn reopen(&mut self) -> Result<(), PortError> {
        if self.is_pulled() {
            return Err(self.down());
        }
        self.inner.reopen().await
    }
}

#[cfg(test)]
mod tests;
