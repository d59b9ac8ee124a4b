//! A no_std CANopen slave on an `embedded_can::nb::Can` controller.
//!
//! The firmware part (`firmware`) uses only `core`, a static dictionary and
//! `duocan::port::embedded::EmbeddedDriver` from duocan built without default features (no
//! heap, no std: the library builds for `thumbv7em-none-eabihf` that way). Here it runs against
//! an in-memory controller and a scripted master; on a board the main loop calls
//! `firmware::poll` whenever a frame arrived or the timer it armed fired:
//!
//! ```text
//! cargo run --example embedded_node --no-default-features
//! ```

mod firmware {
    use duocan::machine::{SinglePort, Station};
    use duocan::node::SlaveNode;
    use duocan::od::{comm, ObjectDef, StaticDictionary};
    use duocan::port::embedded::EmbeddedDriver;
    use duocan::profile::Predefined;
    use duocan::{Instant, Node, NodeConfig, NodeId};
    use embedded_can::nb::Can;

    static COMM: [ObjectDef; comm::COMM_LEN] = comm::communication();
    static IDENT: [ObjectDef; 6] = comm::identity(0x191, 0xD0CA, 1, 1, 42);
    static HB: [ObjectDef; 4] = comm::heartbeat_consumers::<4>();

    /// Objects and data bytes of the static dictionary.
    const OBJECTS: usize = 64;
    const DATA: usize = 512;
    /// The slave: a static dictionary, no node guarding.
    pub type Slave = SlaveNode<StaticDictionary<OBJECTS, DATA>>;
    /// CAN controllers: one.
    const PORTS: usize = 1;
    /// The slave on one controller.
    pub type Driver<C> = EmbeddedDriver<Station<SinglePort, Slave>, C, PORTS>;

    /// Builds the slave with node-ID `id` and a 100 ms heartbeat, and boots it.
    pub fn start<C: Can>(id: u8, can: C, now: Instant) -> Option<Driver<C>> {
        let mut od = StaticDictionary::new();
        od.load(id, &[&COMM, &IDENT, &HB]).ok()?;
        let mut node: Slave =
            Node::with_profile(NodeConfig::slave(NodeId::new(id)?), od, Predefined);
        node.set(now, comm::HEARTBEAT_PRODUCER, 0, 100u16).ok()?;
        node.boot(now);
        Some(EmbeddedDriver::new(Station::single(node), [can]))
    }

    /// One pass of the main loop: returns when the timer should fire next.
    pub fn poll<C: Can>(d: &mut Driver<C>, now: Instant) -> Option<Instant> {
        d.poll(now)
    }
}

mod host {
    use duocan::{Frame, Id, Instant, NmtState};
    use embedded_can::ErrorKind;
    use std::cell::RefCell;
    use std::collections::VecDeque;
    use std::rc::Rc;

    /// Both directions of an in-memory wire.
    #[derive(Default)]
    pub struct Wire {
        pub to_node: VecDeque<Frame>,
        pub from_node: Vec<(Instant, Frame)>,
        pub now: Instant,
    }

    /// The node's controller: one transmit mailbox, always free.
    pub struct MemCan(pub Rc<RefCell<Wire>>);

    impl embedded_can::nb::Can for MemCan {
        type Frame = Frame;
        type Error = ErrorKind;
        fn transmit(&mut self, f: &Frame) -> nb::Result<Option<Frame>, ErrorKind> {
            let mut w = self.0.borrow_mut();
            let now = w.now;
            w.from_node.push((now, *f));
            Ok(None)
        }
        fn receive(&mut self) -> nb::Result<Frame, ErrorKind> {
            self.0
                .borrow_mut()
                .to_node
                .pop_front()
                .ok_or(nb::Error::WouldBlock)
        }
    }

    pub fn run() {
        let wire = Rc::new(RefCell::new(Wire::default()));
        let mut drv = super::firmware::start(7, MemCan(wire.clone()), Instant::ZERO)
            .expect("the dictionary tables fit");
        let mut deadline = super::firmware::poll(&mut drv, Instant::ZERO);
        // The main loop: sleep until the deadline or a frame (simulated here), poll again.
        let nmt_at = Instant::from_millis(250);
        let end = Instant::from_millis(450);
        let mut nmt_sent = false;
        loop {
            let mut now = deadline.unwrap_or(end);
            if !nmt_sent && nmt_at <= now {
                // A master's NMT "start node 7" arrives: the receive interrupt wakes the loop.
                now = nmt_at;
                nmt_sent = true;
                wire.borrow_mut()
                    .to_node
                    .push_back(Frame::from_array(Id::Standard(0), [0x01, 7]));
            }
            if now > end {
                break;
            }
            wire.borrow_mut().now = now;
            deadline = super::firmware::poll(&mut drv, now);
        }
        for (t, f) in &wire.borrow().from_node {
            println!("{t}  {f}");
        }
        let state = drv.device().machine.nmt_state();
        println!("node 7 is {state:?}; port counters {:?}", drv.stats(0));
        assert_eq!(state, NmtState::Operational);
        let beats: Vec<u8> = wire
            .borrow()
            .from_node
            .iter()
            .filter(|(_, f)| f.id() == Id::Standard(0x707))
            .map(|(_, f)| f.data()[0])
            .collect();
        assert_eq!(
            beats,
            [0x00, 0x7F, 0x7F, 0x05, 0x05],
            "boot-up, then heartbeats"
        );
    }
}

fn main() {
    host::run();
}
