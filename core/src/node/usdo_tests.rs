//! A node on a CANopen FD network serving USDO (CiA 1301), end to end through frames: a USDO
//! client on one side, the node in a station on an FD-capable port on the other, every frame
//! handed over as a driver would (`handle_rx_fd`, `poll_transmit_fd`).

use crate::cia1301::usdo::{UsdoClient, UsdoEvent};
use crate::cia301::sdo::DefaultBuffer;
use crate::frame::instant::{Duration, Instant};
use crate::frame::{FdFrame, Frame, Id};
use crate::machine::{Device, SinglePort, Station};
use crate::nmt::{command_frame, NmtCommand, NmtTarget};
use crate::od::abort::AbortCode;
use crate::od::{comm, Access, DataType, DynamicDictionary, ObjectDef, ObjectDictionary};
use crate::{Node, NodeConfig, NodeId};
use std::vec::Vec;

const SERVER: NodeId = NodeId::must(5);
const CLIENT: NodeId = NodeId::must(1);
const VALUE: u16 = 0x2000;
const DOMAIN: u16 = 0x2001;
const T: Duration = Duration::from_millis(100);

type Fd = Station<SinglePort, Node<DynamicDictionary>>;

/// Node 5 on an FD port (or a classic one), booted and started, with a value and a domain.
fn node(fd_node: bool, fd_port: bool) -> Fd {
    let mut od = comm::standard_dictionary(SERVER.raw(), Default::default());
    od.insert_all(&[
        ObjectDef::u32(VALUE, 0, Access::Rw, 7),
        ObjectDef::bytes(DOMAIN, 0, DataType::Domain, 1024),
    ])
    .unwrap();
    let node = Node::new(NodeConfig::slave(SERVER).with_fd(fd_node), od);
    let link = if fd_port {
        SinglePort::fd()
    } else {
        SinglePort::new()
    };
    let mut dev = Station::new(link, node);
    dev.machine.boot(Instant::ZERO);
    let start = command_frame(Id::Standard(0), NmtCommand::Start, NmtTarget::All);
    dev.handle_rx(Instant::ZERO, 0, &start);
    while dev.poll_transmit().is_some() {}
    dev
}

/// The client and a device exchanging frames one millisecond apart until the client has its
/// result (or `limit` milliseconds passed): the event, and every FD frame the device sent. The
/// device is node 5 in a station by default; a CiA 302 master's tests use it too.
pub(crate) struct Bus<D = Fd> {
    now: Instant,
    client: UsdoClient,
    pub dev: D,
    server: NodeId,
    pub answers: Vec<FdFrame>,
}

impl Bus {
    fn new(dev: Fd) -> Bus {
        Bus::serving(dev, SERVER)
    }
}

impl<D: Device> Bus<D> {
    /// The client of node-ID 1 and `dev`, which serves USDO as node `server`.
    pub fn serving(dev: D, server: NodeId) -> Self {
        Bus {
            now: Instant::from_millis(1),
            client: UsdoClient::new(CLIENT, 4096),
            dev,
            server,
            answers: Vec::new(),
        }
    }
    fn run(&mut self) -> UsdoEvent<DefaultBuffer> {
        for _ in 0..1000 {
            if let Some(e) = self.client.poll_event() {
                return e;
            }
            self.now += Duration::from_millis(1);
            while let Some(f) = self.client.poll_transmit() {
                self.dev.handle_rx_fd(self.now, 0, &f, self.now);
            }
            while let Some((port, f)) = self.dev.poll_transmit_fd() {
                assert_eq!(port, 0);
                self.answers.push(f);
                self.client.handle_frame(self.now, &f);
            }
            if self.dev.poll_timeout().is_some_and(|t| t <= self.now) {
                self.dev.handle_timeout(self.now);
            }
            if self.client.poll_timeout().is_some_and(|t| t <= self.now) {
                self.client.handle_timeout(self.now);
            }
        }
        panic!("no result");
    }
    /// Reads sub 0 of `index` (sub `sub` with [`Bus::read_sub`]).
    pub fn read(&mut self, index: u16) -> Result<Vec<u8>, AbortCode> {
        self.read_sub(index, 0)
    }
    pub fn read_sub(&mut self, index: u16, sub: u8) -> Result<Vec<u8>, AbortCode> {
        self.client
            .upload(self.now, self.server, index, sub, T)
            .unwrap();
        let e = self.run();
        e.result.map(|b| e_data(&b)).map_err(|e| e.code().unwrap())
    }
    pub fn write(&mut self, index: u16, data: &[u8]) -> Result<(), AbortCode> {
        self.client
            .download(self.now, self.server, index, 0, 0, data, T)
            .unwrap();
        self.run().result.map(drop).map_err(|e| e.code().unwrap())
    }
}

fn e_data(b: &DefaultBuffer) -> Vec<u8> {
    use crate::cia301::sdo::TransferBuffer;
    b.as_slice().to_vec()
}

#[test]
fn an_fd_node_serves_expedited_reads_and_writes_from_its_dictionary() {
    let mut bus = Bus::new(node(true, true));
    assert!(bus.dev.fd_capable());
    assert_eq!(bus.read(VALUE), Ok(7u32.to_le_bytes().to_vec()));
    assert_eq!(bus.write(VALUE, &0xDEAD_BEEFu32.to_le_bytes()), Ok(()));
    assert_eq!(
        bus.dev.machine.od().get(VALUE, 0).unwrap().data,
        0xDEAD_BEEFu32.to_le_bytes()
    );
    assert_eq!(bus.read(VALUE), Ok(0xDEAD_BEEFu32.to_le_bytes().to_vec()));
    // The answers are CAN FD frames from the node's identifier, with the bit rate switch.
    assert!(bus
        .answers
        .iter()
        .all(|f| f.id() == Id::Standard(0x585) && f.brs()));
    let u = bus.dev.machine.usdo_server().unwrap().stats();
    assert_eq!((u.completed, u.aborted), (3, 0));
}

#[test]
fn a_usdo_write_has_the_stacks_reactions() {
    // Writing the heartbeat period over USDO starts the heartbeat, as a local or SDO write.
    let mut bus = Bus::new(node(true, true));
    assert_eq!(bus.write(0x1017, &50u16.to_le_bytes()), Ok(()));
    let t = bus.dev.poll_timeout().unwrap();
    assert!(t <= bus.now + Duration::from_millis(50), "{t}");
    bus.dev.handle_timeout(t);
    assert_eq!(
        bus.dev.poll_transmit(),
        Some((0, Frame::from_array(Id::Standard(0x705), [0x05])))
    );
}

#[test]
fn a_segmented_write_and_read_go_whole() {
    let mut bus = Bus::new(node(true, true));
    let data: Vec<u8> = (0..700u32).map(|i| (i * 7 % 251) as u8).collect();
    assert_eq!(bus.write(DOMAIN, &data), Ok(()));
    assert_eq!(bus.dev.machine.od().get(DOMAIN, 0).unwrap().data, &data[..]);
    // 700 bytes: an initiate, then twelve segments of at most 60 bytes, each answered.
    assert_eq!(bus.answers.len(), 1 + 700usize.div_ceil(60));
    bus.answers.clear();
    assert_eq!(bus.read(DOMAIN), Ok(data));
    assert_eq!(bus.answers.len(), 1 + 700usize.div_ceil(60));
    assert!(bus.answers.iter().all(|f| f.data().len() <= 64));
    assert_eq!(bus.dev.machine.usdo_server().unwrap().active(), 0);
}

#[test]
fn refusals_come_back_as_aborts_and_leave_the_dictionary_as_it_was() {
    let mut bus = Bus::new(node(true, true));
    assert_eq!(bus.read(0x2FFF), Err(AbortCode::NO_OBJECT));
    assert_eq!(bus.write(0x1000, &[1, 2, 3, 4]), Err(AbortCode::READ_ONLY));
    // A value of the wrong size for a UNSIGNED32.
    assert!(bus.write(VALUE, &[1, 2]).is_err());
    assert_eq!(bus.read(VALUE), Ok(7u32.to_le_bytes().to_vec()));
    // Past the domain's size: refused, the entry unchanged.
    assert!(bus.write(DOMAIN, &[0xAA; 2000]).is_err());
    assert_eq!(bus.dev.machine.od().get(DOMAIN, 0).unwrap().data.len(), 0);
    let u = bus.dev.machine.usdo_server().unwrap().stats();
    assert_eq!(u.aborted, 4);
}

#[test]
fn a_client_that_falls_silent_is_aborted_by_the_node_at_its_timeout() {
    let mut dev = node(true, true);
    let mut client: UsdoClient = UsdoClient::new(CLIENT, 4096);
    let now = Instant::from_millis(1);
    client
        .download(now, SERVER, DOMAIN, 0, 0, &[0x55; 300], T)
        .unwrap();
    let f = client.poll_transmit().unwrap();
    dev.handle_rx_fd(now, 0, &f, now);
    assert!(dev.poll_transmit_fd().is_some()); // accepted
    assert_eq!(dev.machine.usdo_server().unwrap().active(), 1);
    // The client never sends its segments: the node's timer ends the transfer with an abort.
    let t = dev.poll_timeout().unwrap();
    assert!(t <= now + dev.machine.sdo_server().config().timeout);
    dev.handle_timeout(t);
    let (_, abort) = dev.poll_transmit_fd().unwrap();
    client.handle_frame(t, &abort);
    let e = client.poll_event().unwrap();
    assert_eq!(e.result.unwrap_err().code(), Some(AbortCode::TIMEOUT));
    assert_eq!(dev.machine.usdo_server().unwrap().active(), 0);
}

#[test]
fn a_stopped_node_does_not_answer_and_its_transfers_are_dropped() {
    let mut bus = Bus::new(node(true, true));
    let stop = command_frame(Id::Standard(0), NmtCommand::Stop, NmtTarget::All);
    bus.dev.handle_rx(bus.now, 0, &stop);
    while bus.dev.poll_transmit().is_some() {}
    assert_eq!(bus.read(VALUE), Err(AbortCode::TIMEOUT));
    assert!(bus.answers.is_empty());
}

#[test]
fn usdo_is_served_only_by_a_node_configured_for_fd_on_an_fd_port() {
    // A node not configured for FD ignores USDO requests (the client times out) …
    let mut bus = Bus::new(node(false, true));
    assert!(bus.dev.machine.usdo_server().is_none());
    assert_eq!(bus.read(VALUE), Err(AbortCode::TIMEOUT));
    assert!(bus.answers.is_empty());
    // … and a station on a classic port delivers no FD frame to the node.
    let mut bus = Bus::new(node(true, false));
    assert!(!bus.dev.fd_capable());
    assert_eq!(bus.read(VALUE), Err(AbortCode::TIMEOUT));
    assert!(bus.answers.is_empty());
}

#[test]
fn classic_sdo_still_reaches_an_fd_node() {
    // A classic expedited upload of 0x2000 from node 5's SDO server: 0x605 in, 0x585 out.
    let mut dev = node(true, true);
    let now = Instant::from_millis(1);
    let req = Frame::from_array(Id::Standard(0x605), [0x40, 0x00, 0x20, 0, 0, 0, 0, 0]);
    dev.handle_rx(now, 0, &req);
    let (_, f) = dev.poll_transmit().unwrap();
    assert_eq!(f.id(), Id::Standard(0x585));
    assert_eq!(f.data(), [0x43, 0x00, 0x20, 0, 7, 0, 0, 0]);
    assert!(dev.poll_transmit_fd().is_none());
}

#[test]
fn after_a_reset_the_usdo_server_serves_again() {
    let mut bus = Bus::new(node(true, true));
    let reset = command_frame(
        Id::Standard(0),
        NmtCommand::ResetCommunication,
        NmtTarget::All,
    );
    bus.dev.handle_rx(bus.now, 0, &reset);
    while bus.dev.poll_transmit().is_some() {}
    // Pre-operational after the reset: USDO is served there too.
    assert_eq!(bus.read(VALUE), Ok(7u32.to_le_bytes().to_vec()));
}
