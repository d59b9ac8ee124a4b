//! The shapes of sans-IO machines and how they stack.
//!
//! ```text
//!   Machine    one logical bus: a node, an SDO client pool, a supervisor …
//!   BusLink    ports below, one logical bus above: a single port, or the dual-bus layer
//!   Device     ports only: what a driver (simulator, tokio runtime) talks to
//!   Station    = BusLink + Machine, which is a Device
//! ```
//!
//! Between the link and the machine of a station, two paths run after every input: the link's
//! [`LinkRequest`]s up to the machine (the node owns the state a redundancy scheme changes), and
//! the machine's [`Machine::LinkCommand`]s down to the link (a supervisor decides which pair
//! member's process data the link delivers). Most machines and links have nothing to say on the
//! second path: their command type is [`Infallible`] and the default methods do nothing.
//!
//! Drivers own time and I/O and do the same five things to every device: hand it frames, hand it
//! port status, call `handle_timeout` at (or after) `poll_timeout`, drain `poll_transmit` to the
//! ports, drain `poll_event` to the application. Every method may be called at any time;
//! `handle_timeout` does whatever is due at `now` and nothing else.
//!
//! A node on one port, run by hand the way any driver runs a [`Device`]:
//!
//! ```
//! use duocan_core::od::comm;
//! use duocan_core::{Device, Frame, Id, Instant, Node, NodeConfig, NodeId, Station};
//!
//! let mut node = Node::new(NodeConfig::slave(NodeId::must(5)), comm::standard_dictionary(5, Default::default()));
//! node.set(Instant::ZERO, comm::HEARTBEAT_PRODUCER, 0, 50u16)?; // a heartbeat every 50 ms
//! node.boot(Instant::ZERO);
//! let mut dev = Station::single(node); // the node (a Machine) on one port (a BusLink)
//!
//! // The driver's loop: send what is ready, sleep until the next deadline, handle it.
//! let mut sent = Vec::new();
//! let mut now = Instant::ZERO;
//! while now <= Instant::from_millis(100) {
//!     while let Some((port, frame)) = dev.poll_transmit() {
//!         sent.push((now.as_micros() / 1000, port, frame));
//!     }
//!     now = dev.poll_timeout().unwrap();
//!     dev.handle_timeout(now);
//! }
//! let hb = |state| Frame::from_array(Id::Standard(0x705), [state]);
//! // The boot-up, then heartbeats saying "pre-operational" (0x7F), all on port 0.
//! assert_eq!(sent, [(0, 0, hb(0x00)), (50, 0, hb(0x7F)), (100, 0, hb(0x7F))]);
//! # Ok::<(), duocan_core::AbortCode>(())
//! ```

mod forward;
mod health;

pub use health::{PortReason, PortState};

use crate::frame::cob_id::NodeId;
use crate::frame::instant::{earliest, Instant};
use crate::frame::queue::Bounded;
#[cfg(feature = "fd")]
use crate::frame::FdFrame;
use crate::frame::Frame;
use core::convert::Infallible;
use core::fmt;

/// A protocol machine on one logical bus.
pub trait Machine {
    /// What the machine tells its application.
    type Event;
    /// What the machine tells the link below it (a [`Station`] hands them on with
    /// [`BusLink::handle_command`]); [`Infallible`] for a machine with nothing to tell.
    type LinkCommand;
    /// A frame arrived from the (logical) bus.
    fn handle_frame(&mut self, now: Instant, frame: &Frame);
    /// The same, with the instant its port stamped it on the bus (`at`, before `now` when the
    /// receive path runs behind): a machine whose deadlines wait for a node's answer can allow
    /// for the delay. By default the stamp is not used.
    fn handle_frame_at(&mut self, now: Instant, frame: &Frame, at: Instant) {
        let _ = at;
        self.handle_frame(now, frame);
    }
    /// Time passed; do what is due at `now`.
    fn handle_timeout(&mut self, now: Instant);
    /// Next frame to put on the bus.
    #[must_use]
    fn poll_transmit(&mut self) -> Option<Frame>;
    /// Earliest instant at which `handle_timeout` has work, if any.
    #[must_use]
    fn poll_timeout(&self) -> Option<Instant>;
    /// Next event for the application.
    #[must_use]
    fn poll_event(&mut self) -> Option<Self::Event>;
    /// The link below asks something of this machine (see [`LinkRequest`]); machines that have
    /// no state to change there ignore it.
    fn handle_link_request(&mut self, now: Instant, req: LinkRequest) {
        let _ = (now, req);
    }
    /// Next command for the link below; a [`Station`] drains them after every input, so that the
    /// link acts on them at the instant they were decided.
    #[must_use]
    fn poll_link_command(&mut self) -> Option<Self::LinkCommand> {
        None
    }
    /// A CAN FD frame arrived from the (logical) bus (feature `fd`). The default ignores it: a
    /// machine without CAN FD services never sees one. FD frames are kept apart from classic
    /// ones (as in [`Device::handle_rx_fd`]) so that the classic path stays as it was.
    #[cfg(feature = "fd")]
    fn handle_frame_fd(&mut self, now: Instant, frame: &FdFrame) {
        let _ = (now, frame);
    }
    /// Next CAN FD frame to put on the bus (feature `fd`); asked after the classic ones of
    /// [`Machine::poll_transmit`]. The default has none.
    #[cfg(feature = "fd")]
    #[must_use]
    fn poll_transmit_fd(&mut self) -> Option<FdFrame> {
        None
    }
}

/// What a bus link asks of the machine above it: the effects a redundancy scheme has on the
/// node, which the link itself cannot apply because the node owns its state and dictionary.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LinkRequest {
    /// Go to pre-operational (ECSS bus toggle: the redundancy master's heartbeat was lost).
    EnterPreOperational,
    /// An UNSIGNED8 status entry the link maintains changed (ECSS Bdefault and Ctoggle, the
    /// CiA 302-6 channel error counter): write it so that it reads true over SDO. A dictionary
    /// without the entry ignores it.
    SetStatus {
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// The new value.
        value: u8,
    },
    /// The link judged the error-control messages (heartbeats, boot-ups) of a remote `node`
    /// implausible (`suspect`: heard far faster than its heartbeat period allows, or on one bus
    /// only while the other bus carries lower-priority heartbeats), or plausible again. A
    /// machine that watches the node (a redundant master's supervisor) takes its heartbeats as
    /// no sign of life while it is suspect; others ignore it.
    NodeSuspect {
        /// The remote node.
        node: NodeId,
        /// True from the verdict on, false once every reason has ended.
        suspect: bool,
        /// At the verdict: its heartbeats come far too fast on *both* buses, so a second
        /// device beats with its node-ID beside it (a duplicate node-ID, a babble on both).
        /// They tell nothing of the node then, whose own board may well run; a reset would
        /// reach both devices. False when the evidence is that the node may be gone: one bus
        /// too fast while the other is silent for it, or heard on one bus only. Always false
        /// with `suspect` false.
        duplicated: bool,
    },
}

/// Why a port failed to send, or what a controller reported (SocketCAN error frames, simulated
/// faults, `embedded-can` error kinds).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ErrorCause {
    /// The controller went bus-off.
    BusOff,
    /// The controller is error passive.
    ErrorPassive,
    /// An error counter passed the warning level.
    ErrorWarning,
    /// Nobody acknowledged the frame (alone on the bus, or the bus is cut).
    NoAck,
    /// Bit error (sent one level, read the other).
    Bit,
    /// Stuff error.
    Stuff,
    /// Form error.
    Form,
    /// CRC error.
    Crc,
    /// Receive overflow: frames were lost in the controller or driver.
    RxOverflow,
    /// Transmission did not complete in time.
    TxTimeout,
    /// The bus is stuck dominant or transceiver failure.
    Transceiver,
    /// The network interface is down or missing.
    InterfaceDown,
    /// The controller restarted after bus-off.
    Restarted,
    /// Anything else the driver reported.
    Other,
}

impl fmt::Display for ErrorCause {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            ErrorCause::BusOff => "bus-off",
            ErrorCause::ErrorPassive => "error passive",
            ErrorCause::ErrorWarning => "error warning",
            ErrorCause::NoAck => "no acknowledge",
            ErrorCause::Bit => "bit error",
            ErrorCause::Stuff => "stuff error",
            ErrorCause::Form => "form error",
            ErrorCause::Crc => "CRC error",
            ErrorCause::RxOverflow => "receive overflow",
            ErrorCause::TxTimeout => "transmit timeout",
            ErrorCause::Transceiver => "transceiver fault",
            ErrorCause::InterfaceDown => "interface down",
            ErrorCause::Restarted => "controller restarted",
            ErrorCause::Other => "controller error",
        })
    }
}

/// What a port driver reports besides received frames.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PortStatus {
    /// A frame was sent (acknowledged on the bus), where the driver can tell.
    TxOk,
    /// A frame could not be sent.
    TxFailed(ErrorCause),
    /// The controller reported an error (error frame, state change).
    Error(ErrorCause),
    /// The port is unusable (interface down, socket closed).
    Down(ErrorCause),
    /// The port is usable again (reopened, restarted, interface up).
    Up,
}

/// What a device asks of a port driver.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PortRequest {
    /// Re-initialise the port: reopen the socket, restart the controller after bus-off.
    Reinit,
}

/// Anything with CAN ports: what a driver runs.
pub trait Device {
    /// What the device tells its application.
    type Event;
    /// Number of CAN ports (1 for a plain node, 2 for a dual-bus device).
    fn port_count(&self) -> usize;
    /// A frame arrived on `port`.
    fn handle_rx(&mut self, now: Instant, port: usize, frame: &Frame);
    /// A frame that arrived on `port` at `at`, handled at `now` (`at <= now`): `at` is its
    /// receive timestamp, taken where the frame arrived (the controller, the kernel's socket,
    /// the simulator's wire), not when a task got to it. A device that merges two ports tells
    /// a frame's two copies apart by these times even when a port's reader ran late; one that
    /// has no use for them (the default) handles the frame as [`Device::handle_rx`] at `now`.
    ///
    /// Every port of one device stamps with the clock `now` is read from: the two copies of a
    /// frame are compared by their stamps, so a driver whose controllers keep clocks of their
    /// own (hardware timestamps) puts them on that clock before it hands a frame over. Two
    /// clocks that drift apart look like a bus whose frames come later and later: while both
    /// buses carry frames the dual-bus layer measures and follows that, but not under every
    /// other fault at once. duocan's drivers (SocketCAN and UDP: the kernel's stamps on the
    /// monotonic clock; the simulator; `embedded-can`: the time of `poll`) all use one clock.
    fn handle_rx_at(&mut self, now: Instant, port: usize, frame: &Frame, at: Instant) {
        let _ = at;
        self.handle_rx(now, port, frame);
    }
    /// The driver of `port` reports something.
    fn handle_port_status(&mut self, now: Instant, port: usize, status: PortStatus);
    /// Time passed; do what is due at `now`.
    fn handle_timeout(&mut self, now: Instant);
    /// Next frame to send, with the port to send it on.
    #[must_use]
    fn poll_transmit(&mut self) -> Option<(usize, Frame)>;
    /// Next request to a port driver.
    #[must_use]
    fn poll_port_request(&mut self) -> Option<(usize, PortRequest)> {
        None
    }
    /// Earliest instant at which `handle_timeout` has work, if any.
    #[must_use]
    fn poll_timeout(&self) -> Option<Instant>;
    /// Next event for the application.
    #[must_use]
    fn poll_event(&mut self) -> Option<Self::Event>;
    /// Whether every port of the device speaks CAN FD (feature `fd`): it receives FD frames
    /// ([`Device::handle_rx_fd`]) and may send them ([`Device::poll_transmit_fd`]). The
    /// default is a classic-only device. A classic-only controller answers an FD frame on its
    /// bus with error frames, so FD frames belong only on a network where every node is
    /// FD-capable: the simulator refuses a classic-only device on a bus with a data bit rate.
    #[cfg(feature = "fd")]
    fn fd_capable(&self) -> bool {
        false
    }
    /// A CAN FD frame that arrived on `port` at `at` (its receive timestamp, as for
    /// [`Device::handle_rx_at`]), handled at `now`. The default ignores it: FD frames are kept
    /// apart from classic ones so that the classic path (`&Frame`, 16 bytes) stays as it was.
    #[cfg(feature = "fd")]
    fn handle_rx_fd(&mut self, now: Instant, port: usize, frame: &FdFrame, at: Instant) {
        let _ = (now, port, frame, at);
    }
    /// Next CAN FD frame to send, with the port to send it on; a driver asks after the classic
    /// frames of [`Device::poll_transmit`] (each kind keeps its order). The default has none.
    #[must_use]
    #[cfg(feature = "fd")]
    fn poll_transmit_fd(&mut self) -> Option<(usize, FdFrame)> {
        None
    }
}

/// The layer between ports and a logical bus: one port passed through, or two ports merged.
pub trait BusLink {
    /// What the layer reports (port health, channel switches).
    type Event;
    /// What the layer takes from the machine above (see [`Machine::LinkCommand`]);
    /// [`Infallible`] for a layer that takes nothing.
    type Command;
    /// Number of ports below.
    fn port_count(&self) -> usize;
    /// A frame from `port`; returns the logical frame to deliver upward, if any.
    fn handle_rx(&mut self, now: Instant, port: usize, frame: &Frame) -> Option<Frame>;
    /// A frame from `port` that arrived at `at`, its receive timestamp (see
    /// [`Device::handle_rx_at`]), handled at `now`. The default ignores the timestamp: a layer
    /// with one port has no twins to tell apart.
    fn handle_rx_at(
        &mut self,
        now: Instant,
        port: usize,
        frame: &Frame,
        at: Instant,
    ) -> Option<Frame> {
        let _ = at;
        self.handle_rx(now, port, frame)
    }
    /// Port driver status.
    fn handle_port_status(&mut self, now: Instant, port: usize, status: PortStatus);
    /// A logical frame to send.
    fn send(&mut self, now: Instant, frame: &Frame);
    /// Next frame for a port.
    #[must_use]
    fn poll_transmit(&mut self) -> Option<(usize, Frame)>;
    /// Next request to a port driver.
    #[must_use]
    fn poll_port_request(&mut self) -> Option<(usize, PortRequest)> {
        None
    }
    /// Time passed.
    fn handle_timeout(&mut self, now: Instant);
    /// Earliest deadline.
    #[must_use]
    fn poll_timeout(&self) -> Option<Instant>;
    /// Next event.
    #[must_use]
    fn poll_event(&mut self) -> Option<Self::Event>;
    /// Next request to the machine above; a [`Station`] applies them after every input.
    #[must_use]
    fn poll_machine_request(&mut self) -> Option<LinkRequest> {
        None
    }
    /// A command of the machine above; layers that have no state to change there ignore it.
    fn handle_command(&mut self, now: Instant, cmd: Self::Command) {
        let _ = (now, cmd);
    }
    /// Whether the layer carries CAN FD frames (feature `fd`; see [`Device::fd_capable`]). The
    /// default is a classic-only layer, which drops what the methods below are given.
    #[cfg(feature = "fd")]
    fn fd_capable(&self) -> bool {
        false
    }
    /// A CAN FD frame from `port` that arrived at `at`; returns the logical frame to deliver
    /// upward, if any (feature `fd`). The default delivers nothing.
    #[cfg(feature = "fd")]
    fn handle_rx_fd(
        &mut self,
        now: Instant,
        port: usize,
        frame: &FdFrame,
        at: Instant,
    ) -> Option<FdFrame> {
        let _ = (now, port, frame, at);
        None
    }
    /// A logical CAN FD frame to send (feature `fd`). The default drops it.
    #[cfg(feature = "fd")]
    fn send_fd(&mut self, now: Instant, frame: &FdFrame) {
        let _ = (now, frame);
    }
    /// Next CAN FD frame for a port (feature `fd`). The default has none.
    #[cfg(feature = "fd")]
    #[must_use]
    fn poll_transmit_fd(&mut self) -> Option<(usize, FdFrame)> {
        None
    }
}

/// The trivial link: one port is the logical bus. Counts what the port reports.
///
/// With the feature `fd`, a link built with [`SinglePort::fd`] carries CAN FD frames as well
/// (its port is FD-capable); one built with [`SinglePort::new`] stays classic.
#[derive(Debug, Default)]
pub struct SinglePort {
    out: Bounded<Frame, 4>,
    #[cfg(feature = "fd")]
    out_fd: Option<Bounded<FdFrame, 4>>,
    /// Frames received.
    pub rx_frames: u64,
    /// Frames reported sent.
    pub tx_ok: u64,
    /// Frames reported failed.
    pub tx_failed: u64,
    /// Last error the port reported.
    pub last_error: Option<ErrorCause>,
}

impl SinglePort {
    /// A pass-through link.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }
    /// A pass-through link whose port speaks CAN FD (feature `fd`): FD frames go both ways,
    /// four held for the driver at most (more are dropped, as classic ones are).
    #[cfg(feature = "fd")]
    #[must_use]
    pub fn fd() -> Self {
        SinglePort {
            out_fd: Some(Bounded::new()),
            ..Self::default()
        }
    }
}

impl BusLink for SinglePort {
    type Event = Infallible;
    type Command = Infallible;
    fn port_count(&self) -> usize {
        1
    }
    fn handle_rx(&mut self, _: Instant, _: usize, frame: &Frame) -> Option<Frame> {
        self.rx_frames += 1;
        Some(*frame)
    }
    fn handle_port_status(&mut self, _: Instant, _: usize, status: PortStatus) {
        match status {
            PortStatus::TxOk => self.tx_ok += 1,
            PortStatus::TxFailed(c) => {
                self.tx_failed += 1;
                self.last_error = Some(c);
            }
            PortStatus::Error(c) | PortStatus::Down(c) => self.last_error = Some(c),
            PortStatus::Up => {}
        }
    }
    fn send(&mut self, _: Instant, frame: &Frame) {
        self.out.push(*frame);
    }
    fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
        self.out.pop().map(|f| (0, f))
    }
    fn handle_timeout(&mut self, _: Instant) {}
    fn poll_timeout(&self) -> Option<Instant> {
        None
    }
    fn poll_event(&mut self) -> Option<Infallible> {
        None
    }
    #[cfg(feature = "fd")]
    fn fd_capable(&self) -> bool {
        self.out_fd.is_some()
    }
    #[cfg(feature = "fd")]
    fn handle_rx_fd(
        &mut self,
        _: Instant,
        _: usize,
        frame: &FdFrame,
        _: Instant,
    ) -> Option<FdFrame> {
        self.out_fd.as_ref()?;
        self.rx_frames += 1;
        Some(*frame)
    }
    #[cfg(feature = "fd")]
    fn send_fd(&mut self, _: Instant, frame: &FdFrame) {
        if let Some(q) = &mut self.out_fd {
            q.push(*frame);
        }
    }
    #[cfg(feature = "fd")]
    fn poll_transmit_fd(&mut self) -> Option<(usize, FdFrame)> {
        self.out_fd.as_mut()?.pop().map(|f| (0, f))
    }
}

/// An event of a [`Station`]: from its link or from its machine.
#[derive(Clone, Debug, PartialEq)]
pub enum StationEvent<L, M> {
    /// From the bus link (port health, channel switch).
    Link(L),
    /// From the machine (node, supervisor).
    Machine(M),
}

/// A machine on a link: the unit a driver runs.
///
/// After every input the station hands the link's [`LinkRequest`]s to the machine and the
/// machine's [`Machine::LinkCommand`]s to the link (which must take them: `M::LinkCommand:
/// Into<L::Command>`, trivially true when the machine has none).
#[derive(Debug)]
pub struct Station<L, M> {
    /// The link below.
    pub link: L,
    /// The machine above.
    pub machine: M,
    now: Instant,
}

impl<M: Machine> Station<SinglePort, M> {
    /// A machine on a single port.
    #[must_use]
    pub fn single(machine: M) -> Self {
        Station::new(SinglePort::new(), machine)
    }
}

impl<L: BusLink, M: Machine> Station<L, M> {
    /// A machine on a link.
    #[must_use]
    pub fn new(link: L, machine: M) -> Self {
        Station {
            link,
            machine,
            now: Instant::ZERO,
        }
    }
}

impl<L: BusLink, M: Machine> Station<L, M>
where
    M::LinkCommand: Into<L::Command>,
{
    /// The link's requests up, then the machine's commands down.
    fn forward(&mut self, now: Instant) {
        forward_requests(now, &mut self.link, &mut self.machine);
        forward_commands(now, &mut self.machine, &mut self.link);
    }
    /// What the link made of a received frame: its requests, then the frame it delivers, to
    /// the machine.
    fn received(&mut self, now: Instant, f: Option<Frame>, at: Option<Instant>) {
        self.forward(now);
        if let Some(f) = f {
            match at {
                Some(at) => self.machine.handle_frame_at(now, &f, at),
                None => self.machine.handle_frame(now, &f),
            }
            self.forward(now);
        }
    }

    /// A frame from `port` (its receive timestamp `at`, if its driver gives one), as
    /// [`Device::handle_rx_at`] takes it, returning what the link delivered to the machine:
    /// once per occurrence over two buses. What watches the traffic beside the machine (a
    /// door decoding process data) reads this, not the ports' copies.
    #[inline]
    pub fn handle_rx_delivered(
        &mut self,
        now: Instant,
        port: usize,
        frame: &Frame,
        at: Option<Instant>,
    ) -> Option<Frame> {
        self.now = now;
        let f = match at {
            Some(at) => self.link.handle_rx_at(now, port, frame, at),
            None => self.link.handle_rx(now, port, frame),
        };
        self.received(now, f, at);
        f
    }
}

impl<L: BusLink, M: Machine> Device for Station<L, M>
where
    M::LinkCommand: Into<L::Command>,
{
    type Event = StationEvent<L::Event, M::Event>;

    fn port_count(&self) -> usize {
        self.link.port_count()
    }
    fn handle_rx(&mut self, now: Instant, port: usize, frame: &Frame) {
        self.handle_rx_delivered(now, port, frame, None);
    }
    fn handle_rx_at(&mut self, now: Instant, port: usize, frame: &Frame, at: Instant) {
        self.handle_rx_delivered(now, port, frame, Some(at));
    }
    fn handle_port_status(&mut self, now: Instant, port: usize, status: PortStatus) {
        self.now = now;
        self.link.handle_port_status(now, port, status);
        self.forward(now);
    }
    fn handle_timeout(&mut self, now: Instant) {
        self.now = now;
        self.link.handle_timeout(now);
        // What the link decided is in force before the machine's timers run.
        forward_requests(now, &mut self.link, &mut self.machine);
        self.machine.handle_timeout(now);
        self.forward(now);
    }
    fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
        loop {
            if let Some(x) = self.link.poll_transmit() {
                return Some(x);
            }
            let f = self.machine.poll_transmit()?;
            self.link.send(self.now, &f);
        }
    }
    fn poll_port_request(&mut self) -> Option<(usize, PortRequest)> {
        self.link.poll_port_request()
    }
    fn poll_timeout(&self) -> Option<Instant> {
        earliest(self.link.poll_timeout(), self.machine.poll_timeout())
    }
    fn poll_event(&mut self) -> Option<Self::Event> {
        if let Some(e) = self.link.poll_event() {
            return Some(StationEvent::Link(e));
        }
        self.machine.poll_event().map(StationEvent::Machine)
    }
    #[cfg(feature = "fd")]
    fn fd_capable(&self) -> bool {
        self.link.fd_capable()
    }
    #[cfg(feature = "fd")]
    fn handle_rx_fd(&mut self, now: Instant, port: usize, frame: &FdFrame, at: Instant) {
        self.now = now;
        let f = self.link.handle_rx_fd(now, port, frame, at);
        self.forward(now);
        if let Some(f) = f {
            self.machine.handle_frame_fd(now, &f);
            self.forward(now);
        }
    }
    #[cfg(feature = "fd")]
    fn poll_transmit_fd(&mut self) -> Option<(usize, FdFrame)> {
        loop {
            if let Some(x) = self.link.poll_transmit_fd() {
                return Some(x);
            }
            let f = self.machine.poll_transmit_fd()?;
            self.link.send_fd(self.now, &f);
        }
    }
}

/// Hands the link's requests to the machine above it.
pub fn forward_requests<L: BusLink, M: Machine>(now: Instant, link: &mut L, machine: &mut M) {
    while let Some(r) = link.poll_machine_request() {
        machine.handle_link_request(now, r);
    }
}

/// Hands the machine's commands to the link below it.
pub fn forward_commands<M: Machine, L: BusLink>(now: Instant, machine: &mut M, link: &mut L)
where
    M::LinkCommand: Into<L::Command>,
{
    while let Some(c) = machine.poll_link_command() {
        link.handle_command(now, c.into());
    }
}

/// An event of a [`Composite`].
#[derive(Clone, Debug, PartialEq)]
pub enum CompositeEvent<A, B> {
    /// From the first machine.
    A(A),
    /// From the second machine.
    B(B),
}

/// Two machines on one logical bus: every frame goes to both (each ignores what is not its
/// business), their outputs are merged. How a node and an SDO client pool, or a node and a
/// supervisor, become one machine for a station. Commands for the link come from both, in the
/// first machine's type: a machine that commands the link goes first.
#[derive(Debug, Default)]
pub struct Composite<A, B> {
    /// The first machine.
    pub a: A,
    /// The second machine.
    pub b: B,
}

impl<A: Machine, B: Machine> Composite<A, B> {
    /// Composes two machines.
    #[must_use]
    pub fn new(a: A, b: B) -> Self {
        Composite { a, b }
    }
}

impl<A: Machine, B: Machine> Machine for Composite<A, B>
where
    B::LinkCommand: Into<A::LinkCommand>,
{
    type Event = CompositeEvent<A::Event, B::Event>;
    type LinkCommand = A::LinkCommand;
    fn handle_frame(&mut self, now: Instant, frame: &Frame) {
        self.a.handle_frame(now, frame);
        self.b.handle_frame(now, frame);
    }
    fn handle_timeout(&mut self, now: Instant) {
        self.a.handle_timeout(now);
        self.b.handle_timeout(now);
    }
    fn poll_transmit(&mut self) -> Option<Frame> {
        self.a.poll_transmit().or_else(|| self.b.poll_transmit())
    }
    fn poll_timeout(&self) -> Option<Instant> {
        earliest(self.a.poll_timeout(), self.b.poll_timeout())
    }
    fn poll_event(&mut self) -> Option<Self::Event> {
        if let Some(e) = self.a.poll_event() {
            return Some(CompositeEvent::A(e));
        }
        self.b.poll_event().map(CompositeEvent::B)
    }
    fn handle_link_request(&mut self, now: Instant, req: LinkRequest) {
        self.a.handle_link_request(now, req);
        self.b.handle_link_request(now, req);
    }
    fn poll_link_command(&mut self) -> Option<A::LinkCommand> {
        self.a
            .poll_link_command()
            .or_else(|| self.b.poll_link_command().map(Into::into))
    }
    #[cfg(feature = "fd")]
    fn handle_frame_fd(&mut self, now: Instant, frame: &FdFrame) {
        self.a.handle_frame_fd(now, frame);
        self.b.handle_frame_fd(now, frame);
    }
    #[cfg(feature = "fd")]
    fn poll_transmit_fd(&mut self) -> Option<FdFrame> {
        self.a
            .poll_transmit_fd()
            .or_else(|| self.b.poll_transmit_fd())
    }
}
