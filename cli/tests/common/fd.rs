//! What the CANopen FD tests share (`sdo_fd.rs`, `gateway_fd.rs`): node 5 serving USDO, and a
//! listener counting the tool's requests on a UDP bus with FD.

use duocan::machine::{SinglePort, Station};
use duocan::od::{comm, Access, DataType, DynamicDictionary, ObjectDef};
use duocan::port::udp::{UdpBusConfig, UdpPort};
use duocan::port::{AnyInput, Port};
use duocan::runtime::{Handle, Runtime};
use duocan::{Id, Node, NodeConfig, NodeId};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

/// Node 5 serving USDO (not booted), with a value (0x2000, 0xCAFEF00D) and a string (0x2001)
/// to write.
pub fn fd_node() -> Node<DynamicDictionary> {
    let mut od = comm::standard_dictionary(5, Default::default());
    od.insert_all(&[
        ObjectDef::u32(0x2000, 0, Access::Rw, 0xCAFE_F00D),
        ObjectDef::bytes(0x2001, 0, DataType::VisibleString, 200).access(Access::Rw),
    ])
    .unwrap();
    Node::new(NodeConfig::slave(NodeId::must(5)).with_fd(true), od)
}

/// Node 5 serving USDO on UDP bus `bus` with FD, booted.
pub async fn fd_node_on(bus: u8) -> Handle<Station<SinglePort, Node<DynamicDictionary>>> {
    let h = Runtime::new(Station::new(SinglePort::fd(), fd_node()))
        .port(UdpPort::open(UdpBusConfig::numbered(bus).with_fd()).unwrap())
        .spawn()
        .unwrap();
    h.boot().await.unwrap();
    h
}

/// What [`count_requests`] counts.
#[derive(Clone, Default)]
pub struct Requests {
    usdo: Arc<AtomicUsize>,
    sdo: Arc<AtomicUsize>,
}

impl Requests {
    /// The tool's USDO requests (CAN FD frames from node-ID 127).
    pub fn usdo(&self) -> usize {
        self.usdo.load(Ordering::Relaxed)
    }
    /// Classic SDO requests to node 5.
    pub fn sdo(&self) -> usize {
        self.sdo.load(Ordering::Relaxed)
    }
}

/// Counts the requests on UDP bus `bus` with FD, in a task of the runtime.
pub fn count_requests(bus: u8) -> Requests {
    let counts = Requests::default();
    let (usdo, sdo) = (counts.usdo.clone(), counts.sdo.clone());
    let mut tester = UdpPort::open(UdpBusConfig::numbered(bus).with_fd()).unwrap();
    tokio::spawn(async move {
        while let Ok(input) = tester.recv_any().await {
            match input {
                AnyInput::Fd(f, _) if f.id() == Id::Standard(0x600 + 127) => {
                    usdo.fetch_add(1, Ordering::Relaxed);
                }
                AnyInput::Frame(f, _) if f.id() == Id::Standard(0x605) => {
                    sdo.fetch_add(1, Ordering::Relaxed);
                }
                _ => {}
            }
        }
    });
    counts
}
