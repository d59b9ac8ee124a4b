//! The front door over a core of the user's own ([`Network::open_core`]): the door's calls
//! reach it through the trait, and [`Network::with_core`] reaches the rest of it, refusing a
//! wrong type by name.

use duocan::cia305::{Inquiry, LssError, LssService};
use duocan::machine::PortRequest;
use duocan::net::{CoreEvent, NetClient, NetCore, NetError, NetEvent, NetOptions, Network};
use duocan::port::mem::MemBus;
use duocan::port::{Port, PortInput};
use duocan::{Device, Frame, Id, Instant, NmtCommand, NmtState, NmtTarget, NodeId, PortStatus};
use std::collections::VecDeque;
use std::time::Duration;

#[tokio::test(start_paused = true)]
async fn the_door_runs_over_a_core_of_the_users() {
    let bus = MemBus::new("mem");
    let net =
        Network::open_core(Box::new(Stub::default()), bus.port(), NetOptions::default()).unwrap();
    let mut wire = bus.port();
    tokio::time::sleep(Duration::from_millis(10)).await;
    let node = net.node(9);

    // A boot-up the core reports is the door's: its record, its event, its wait.
    let mut events = net.events();
    wire.send(&Frame::from_array(Id::Standard(0x709), [0]))
        .await
        .unwrap();
    let at = node.wait_for_boot_up(Duration::from_secs(1)).await.unwrap();
    assert_eq!(events.next().await.and_then(|e| e.node()), NodeId::new(9));
    assert_eq!(node.last_boot_up().await.unwrap(), Some(at));
    assert_eq!(node.state().await.unwrap(), Some(NmtState::PreOperational));

    // The core's own events reach the stream as they are, typed.
    wire.send(&Frame::from_array(Id::Standard(0x0F0), [9]))
        .await
        .unwrap();
    let e = events.next().await.unwrap();
    assert_eq!(e, super::ext::alarm(9, true, e.at().unwrap()));
    assert!(e.is_failover());

    // NMT goes to the core, and what the core transmits reaches the wire.
    net.nmt_all(NmtCommand::Start).await.unwrap();
    let got = tokio::time::timeout(Duration::from_secs(1), wire.recv()).await;
    let Ok(Ok(PortInput::Frame(f, _))) = got else {
        panic!("no NMT frame: {got:?}")
    };
    assert_eq!((f.id(), f.data()), (Id::Standard(0), &[1, 0][..]));

    // What the core does not have is an error that says so, not a hang.
    assert!(node.sdo().read::<u32>(0x1018, 1).await.is_err());
    // LSS is the door's, whatever the core: the request leaves through the core's own
    // frames, and with no slave to answer it times out.
    let e = net.lss().inquire(Inquiry::NodeId).await;
    assert_eq!(
        e,
        Err(NetError::Lss(LssError::Timeout(LssService::Inquire(
            Inquiry::NodeId
        ))))
    );
    let got = tokio::time::timeout(Duration::from_secs(1), wire.recv()).await;
    let Ok(Ok(PortInput::Frame(f, _))) = got else {
        panic!("no LSS frame: {got:?}")
    };
    assert_eq!((f.id(), f.data()[0]), (Id::Standard(0x7E5), 0x5E));

    // The core's own calls: its state, with the runtime's clock.
    let (frames, nmt) = net
        .with_core(|c: &mut Stub, _| (c.frames, c.nmt))
        .await
        .unwrap();
    assert_eq!((frames, nmt), (2, 1));
    net.close().await;
}

#[tokio::test(start_paused = true)]
async fn with_core_refuses_a_core_of_another_type_by_name() {
    let bus = MemBus::new("mem");
    let net =
        Network::open_core(Box::new(Stub::default()), bus.port(), NetOptions::default()).unwrap();
    assert_eq!(
        net.with_core(|_: &mut Stub, now| now).await.ok(),
        Some(net.now())
    );
    let e = net.with_core(|_: &mut Other, _| ()).await.unwrap_err();
    assert!(
        matches!(&e, NetError::Argument(w) if w.contains("Stub") && w.contains("Other")),
        "{e}"
    );
    // The observer a plain network runs on is no user's type either.
    let plain = Network::open(bus.port()).unwrap();
    assert!(plain.with_core(|_: &mut Stub, _| ()).await.is_err());
    net.close().await;
    plain.close().await;
}

/// The smallest core: it counts frames, takes a boot-up for one and reports it, and sends one
/// NMT frame per command. No SDO client, no LSS master.
#[derive(Default)]
struct Stub {
    frames: u32,
    nmt: u32,
    out: VecDeque<Frame>,
    events: VecDeque<CoreEvent>,
    booted: Vec<(NodeId, Instant)>,
}

impl Device for Stub {
    type Event = CoreEvent;
    fn port_count(&self) -> usize {
        1
    }
    fn handle_rx(&mut self, now: Instant, port: usize, frame: &Frame) {
        self.rx(now, port, frame, None);
    }
    fn handle_port_status(&mut self, _: Instant, _: usize, _: PortStatus) {}
    fn handle_timeout(&mut self, _: Instant) {}
    fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
        self.out.pop_front().map(|f| (0, f))
    }
    fn poll_port_request(&mut self) -> Option<(usize, PortRequest)> {
        None
    }
    fn poll_timeout(&self) -> Option<Instant> {
        None
    }
    fn poll_event(&mut self) -> Option<CoreEvent> {
        self.events.pop_front()
    }
}

impl NetCore for Stub {
    fn rx(&mut self, now: Instant, _: usize, frame: &Frame, _: Option<Instant>) -> Option<Frame> {
        self.frames += 1;
        if let Id::Standard(id @ 0x701..=0x77F) = frame.id() {
            if frame.data() == [0] {
                let node = NodeId::new((id - 0x700) as u8)?;
                self.booted.push((node, now));
                self.events
                    .push_back(CoreEvent::Net(NetEvent::BootUp { node, at: now }));
            }
        }
        if let (Id::Standard(0x0F0), [raw]) = (frame.id(), frame.data()) {
            let e = super::ext::alarm(*raw, true, now);
            self.events.push_back(CoreEvent::Net(e));
        }
        Some(*frame)
    }
    fn client(&mut self) -> Result<&mut NetClient, NetError> {
        Err(NetError::Argument("the stub has no SDO client".into()))
    }
    fn nmt(&mut self, _: Instant, _: NmtCommand, _: NmtTarget) -> Result<(), NetError> {
        self.nmt += 1;
        self.out
            .push_back(Frame::from_array(Id::Standard(0), [1, 0]));
        Ok(())
    }
    fn remote(&self, node: NodeId) -> Option<(NmtState, Instant)> {
        let (_, at) = self.booted.iter().rev().find(|(n, _)| *n == node)?;
        Some((NmtState::PreOperational, *at))
    }
    fn watch_heartbeat(&mut self, _: Instant, _: NodeId, _: u16) -> Result<(), NetError> {
        Ok(())
    }
    fn set_sync(&mut self, _: Instant, _: Option<u32>) -> Result<(), NetError> {
        Err(NetError::Argument("the stub makes no SYNC".into()))
    }
    fn send(&mut self, _: Instant, frame: Frame) -> Result<(), NetError> {
        self.out.push_back(frame);
        Ok(())
    }
    fn may_send(&self, _: Instant) -> bool {
        true
    }
    fn as_any_mut(&mut self) -> &mut dyn std::any::Any {
        self
    }
}

/// A type the network's core is not.
struct Other;

impl Device for Other {
    type Event = CoreEvent;
    fn port_count(&self) -> usize {
        1
    }
    fn handle_rx(&mut self, _: Instant, _: usize, _: &Frame) {}
    fn handle_port_status(&mut self, _: Instant, _: usize, _: PortStatus) {}
    fn handle_timeout(&mut self, _: Instant) {}
    fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
        None
    }
    fn poll_timeout(&self) -> Option<Instant> {
        None
    }
    fn poll_event(&mut self) -> Option<CoreEvent> {
        None
    }
}

impl NetCore for Other {
    fn rx(&mut self, _: Instant, _: usize, frame: &Frame, _: Option<Instant>) -> Option<Frame> {
        Some(*frame)
    }
    fn client(&mut self) -> Result<&mut NetClient, NetError> {
        Err(NetError::Closed)
    }
    fn nmt(&mut self, _: Instant, _: NmtCommand, _: NmtTarget) -> Result<(), NetError> {
        Err(NetError::Closed)
    }
    fn remote(&self, _: NodeId) -> Option<(NmtState, Instant)> {
        None
    }
    fn watch_heartbeat(&mut self, _: Instant, _: NodeId, _: u16) -> Result<(), NetError> {
        Ok(())
    }
    fn set_sync(&mut self, _: Instant, _: Option<u32>) -> Result<(), NetError> {
        Ok(())
    }
    fn send(&mut self, _: Instant, _: Frame) -> Result<(), NetError> {
        Ok(())
    }
    fn may_send(&self, _: Instant) -> bool {
        false
    }
    fn as_any_mut(&mut self) -> &mut dyn std::any::Any {
        self
    }
}
