//! Real SocketCAN on vcan0/vcan1/vcan2. Runs inside the qemu VM of `.ci/vcanvm` (the host kernel
//! has no CAN): `.ci/tier-vcan.sh`. Interfaces are switched down and up with `ip`, so the tests
//! run one at a time (`RUST_TEST_THREADS=1`, set by the tier script).

#[path = "../../tests/common/runtime.rs"]
mod rt;

use duocan::machine::{BusLink, ErrorCause, PortStatus, Station, StationEvent};
use duocan::node::NodeEventKind as K;
use duocan::port::error_frame::CAN_ERR_FLAG;
use duocan::port::socketcan::{inject_error_frame, link_state, LinkState, SocketCanPort};
use duocan::port::{Port, PortErrorKind, PortInput};
use duocan::runtime::{Runtime, RuntimeEvent};
use duocan::{Frame, Id, Instant, NmtCommand, NmtState, NmtTarget, NodeId};
use rt::{collect, node, node_event, single, until_grown, wait_for};
use std::time::Duration;

#[path = "common/cut.rs"]
mod cut;
use cut::{port_reported, LinkDown};
use std::process::Command;

/// The next input of `p`. A frame must come with the kernel's receive timestamp, no later than
/// now; it is returned without it (`None`), to be compared.
async fn recv_input(p: &mut SocketCanPort) -> PortInput {
    let x = tokio::time::timeout(Duration::from_secs(2), p.recv())
        .await
        .expect("frame within 2 s")
        .expect("port works");
    match x {
        PortInput::Frame(f, at) => {
            let at = at.expect("a SocketCAN frame comes with its receive timestamp");
            assert!(at <= std::time::Instant::now(), "stamped in the future");
            PortInput::Frame(f, None)
        }
        status => status,
    }
}

#[tokio::test]
async fn socketcan_port_sends_and_receives_every_frame_kind() {
    let mut a = SocketCanPort::open("vcan0").expect("open vcan0");
    let mut b = SocketCanPort::open("vcan0").expect("open vcan0 again");
    let frames = [
        Frame::from_array(Id::Standard(0x123), [0xDE, 0xAD, 0xBE, 0xEF]),
        Frame::from_array(Id::Extended(0x1ABC_DEF0), [1, 2, 3, 4, 5, 6, 7, 8]),
        Frame::remote(Id::Standard(0x705), 1).unwrap(),
        Frame::remote(Id::Extended(0x1F), 0).unwrap(),
        Frame::new(Id::Standard(0x000), &[]).unwrap(),
    ];
    for f in &frames {
        a.send(f).await.expect("send");
    }
    for f in &frames {
        assert_eq!(recv_input(&mut b).await, PortInput::Frame(*f, None));
    }
    let ca = a.counters().snapshot();
    let cb = b.counters().snapshot();
    assert_eq!(ca.tx_frames, 5);
    assert_eq!(cb.rx_frames, 5);
    assert_eq!(cb.rx_invalid, 0);
}

/// vcan loaded without `echo=1` does not echo in its driver (no `IFF_ECHO`): the kernel's own
/// echo would come as a frame is handed over, confirming nothing, so the port says it cannot
/// confirm transmissions and its own frames stay away (`vcan_echo.rs` has the echoing case).
#[tokio::test]
async fn a_port_on_an_interface_that_does_not_echo_cannot_confirm() {
    let mut p = SocketCanPort::open("vcan0").unwrap();
    assert!(!p.confirm_transmissions());
    p.send(&Frame::new(Id::Standard(0x123), &[1]).unwrap())
        .await
        .unwrap();
    let x = tokio::time::timeout(Duration::from_millis(200), p.recv()).await;
    assert!(x.is_err(), "nothing comes back: {x:?}");
}

#[tokio::test]
async fn error_frames_become_port_status() {
    let mut b = SocketCanPort::open("vcan0").expect("open vcan0");
    // vcan has no controller: write the error frames a controller would report.
    inject_error_frame("vcan0", 0x040, &[0; 8]).expect("inject bus-off");
    assert_eq!(
        recv_input(&mut b).await,
        PortInput::Status(PortStatus::Down(ErrorCause::BusOff))
    );
    inject_error_frame("vcan0", 0x004, &[0, 0x20, 0, 0, 0, 0, 0, 0])
        .expect("inject controller error passive");
    assert_eq!(
        recv_input(&mut b).await,
        PortInput::Status(PortStatus::Error(ErrorCause::ErrorPassive))
    );
    inject_error_frame("vcan0", 0x020 | 0x080, &[0; 8]).expect("inject no-ack");
    assert_eq!(
        recv_input(&mut b).await,
        PortInput::Status(PortStatus::TxFailed(ErrorCause::NoAck))
    );
    inject_error_frame("vcan0", 0x100, &[0; 8]).expect("inject restarted");
    assert_eq!(recv_input(&mut b).await, PortInput::Status(PortStatus::Up));
    assert_eq!(b.counters().snapshot().rx_error_frames, 4);
    assert_eq!(CAN_ERR_FLAG, 0x2000_0000);
}

#[tokio::test]
async fn missing_or_down_interfaces_give_clear_errors_and_reopen_works() {
    let e = SocketCanPort::open("vcan9").unwrap_err();
    assert_eq!(e.kind, PortErrorKind::NoSuchInterface);
    assert!(
        e.to_string().contains("ip link add dev vcan9 type vcan"),
        "{e}"
    );

    let down = LinkDown::new("vcan2");
    assert_eq!(link_state("vcan2"), LinkState::Down);
    let e = SocketCanPort::open("vcan2").unwrap_err();
    assert_eq!(e.kind, PortErrorKind::InterfaceDown);
    assert!(e.to_string().contains("ip link set vcan2 up"), "{e}");
    drop(down);
    let mut p = SocketCanPort::open("vcan2").expect("open after up");

    // Down under an open port: reads fail with ENETDOWN, reported as interface down.
    let reader = tokio::spawn(async move {
        let r = tokio::time::timeout(Duration::from_secs(3), p.recv()).await;
        (p, r)
    });
    tokio::time::sleep(Duration::from_millis(100)).await;
    let down = LinkDown::new("vcan2");
    let (mut p, r) = reader.await.unwrap();
    let err = r.expect("read woke up").expect_err("read failed");
    assert_eq!(err.kind, PortErrorKind::InterfaceDown, "{err}");
    assert_eq!(
        p.reopen().await.unwrap_err().kind,
        PortErrorKind::InterfaceDown
    );
    drop(down);
    p.reopen().await.expect("reopen after up");
    let mut q = SocketCanPort::open("vcan2").unwrap();
    q.send(&Frame::from_array(Id::Standard(0x42), [1]))
        .await
        .unwrap();
    assert_eq!(
        recv_input(&mut p).await,
        PortInput::Frame(Frame::from_array(Id::Standard(0x42), [1]), None)
    );
    assert_eq!(p.counters().snapshot().reopened, 1);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn master_and_slaves_in_separate_tasks_heartbeat_and_nmt() {
    let master = Runtime::new(single(node(1, true, 0, &[(5, 300), (6, 300)])))
        .name("master")
        .port(SocketCanPort::open("vcan0").unwrap())
        .spawn()
        .unwrap();
    let s5 = Runtime::new(single(node(5, false, 50, &[])))
        .name("slave5")
        .port(SocketCanPort::open("vcan0").unwrap())
        .spawn()
        .unwrap();
    let s6 = Runtime::new(single(node(6, false, 50, &[])))
        .name("slave6")
        .port(SocketCanPort::open("vcan0").unwrap())
        .spawn()
        .unwrap();
    let mut ev = master.subscribe();
    master.boot().await.unwrap();
    s5.boot().await.unwrap();
    s6.boot().await.unwrap();
    master.nmt(NmtCommand::Start, NmtTarget::All).await.unwrap();
    let mut operational = std::collections::BTreeSet::new();
    wait_for(&mut ev, 5, "both slaves operational", |e| {
        if let Some(K::RemoteState {
            node,
            to: NmtState::Operational,
            ..
        }) = node_event(e)
        {
            operational.insert(node.raw());
        }
        (operational.len() == 2).then_some(())
    })
    .await;
    assert_eq!(s5.nmt_state().await.unwrap(), NmtState::Operational);
    // Slave 6 stops: the master's consumer times it out, and only it.
    s6.shutdown().await;
    let lost = wait_for(
        &mut ev,
        5,
        "heartbeat timeout of node 6",
        |e| match node_event(e) {
            Some(K::HeartbeatTimeout { node, .. }) => Some(node.raw()),
            _ => None,
        },
    )
    .await;
    assert_eq!(lost, 6);
    let later = collect(&mut ev, 500).await;
    assert!(
        !later.iter().any(
            |e| matches!(node_event(e), Some(K::HeartbeatTimeout { node, .. }) if node.raw() == 5)
        ),
        "node 5 keeps its heartbeat"
    );
    // NMT stop to node 5 through the handle.
    master
        .nmt(NmtCommand::Stop, NmtTarget::Node(NodeId::new(5).unwrap()))
        .await
        .unwrap();
    wait_for(&mut ev, 5, "node 5 stopped", |e| match node_event(e) {
        Some(K::RemoteState {
            node,
            to: NmtState::Stopped,
            ..
        }) if node.raw() == 5 => Some(()),
        _ => None,
    })
    .await;
    master.shutdown().await;
    s5.shutdown().await;
}

/// A minimal two-port link for this test: sends every frame on both ports, delivers what the
/// active port receives, and makes the other port active when the active one goes down. (The
/// real dual-bus layer is `duocan-redundancy`; this checks what the runtime and SocketCAN ports
/// do when a wire fails.)
#[derive(Default)]
struct ActiveStandby {
    active: usize,
    up: [bool; 2],
    out: std::collections::VecDeque<(usize, Frame)>,
    events: std::collections::VecDeque<(usize, usize)>,
}

impl BusLink for ActiveStandby {
    type Event = (usize, usize);
    type Command = std::convert::Infallible;
    fn port_count(&self) -> usize {
        2
    }
    fn handle_rx(&mut self, _: Instant, port: usize, f: &Frame) -> Option<Frame> {
        (port == self.active).then_some(*f)
    }
    fn handle_port_status(&mut self, _: Instant, port: usize, s: PortStatus) {
        match s {
            PortStatus::Down(_) => {
                self.up[port] = false;
                if port == self.active && self.up[1 - port] {
                    self.active = 1 - port;
                    self.events.push_back((port, self.active));
                }
            }
            PortStatus::Up => self.up[port] = true,
            _ => {}
        }
    }
    fn send(&mut self, _: Instant, f: &Frame) {
        for p in 0..2 {
            if self.up[p] {
                self.out.push_back((p, *f));
            }
        }
    }
    fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
        self.out.pop_front()
    }
    fn handle_timeout(&mut self, _: Instant) {}
    fn poll_timeout(&self) -> Option<Instant> {
        None
    }
    fn poll_event(&mut self) -> Option<(usize, usize)> {
        self.events.pop_front()
    }
}

fn dual(n: rt::TestNode) -> Station<ActiveStandby, rt::TestNode> {
    Station::new(
        ActiveStandby {
            up: [true, true],
            ..Default::default()
        },
        n,
    )
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bus_failover_when_an_interface_goes_down_and_recovery() {
    let master = Runtime::new(dual(node(1, true, 0, &[(5, 250)])))
        .name("master")
        .port(SocketCanPort::open("vcan0").unwrap())
        .port(SocketCanPort::open("vcan1").unwrap())
        .spawn()
        .unwrap();
    let slave = Runtime::new(dual(node(5, false, 25, &[])))
        .name("slave")
        .port(SocketCanPort::open("vcan0").unwrap())
        .port(SocketCanPort::open("vcan1").unwrap())
        .spawn()
        .unwrap();
    let mut ev = master.subscribe();
    master.boot().await.unwrap();
    slave.boot().await.unwrap();
    let rx = |p: usize| master.port_counters(p).unwrap().rx_frames;
    until_grown(&mut ev, || rx(0), 5, 10, "heartbeats on vcan0").await;
    until_grown(&mut ev, || rx(1), 5, 10, "heartbeats on vcan1").await;

    let down = LinkDown::new("vcan0");
    let st = wait_for(&mut ev, 5, "port 0 reported down", |e| match e {
        RuntimeEvent::Port {
            port: 0,
            status: PortStatus::Down(c),
            ..
        } => Some(*c),
        _ => None,
    })
    .await;
    assert_eq!(st, ErrorCause::InterfaceDown);
    wait_for(&mut ev, 5, "switch to port 1", |e| match e {
        RuntimeEvent::Device(StationEvent::Link((0, 1))) => Some(()),
        _ => None,
    })
    .await;
    let during = until_grown(
        &mut ev,
        || rx(1),
        15,
        20,
        "frames on vcan1 while vcan0 is down",
    )
    .await;
    assert!(
        !during
            .iter()
            .any(|e| matches!(node_event(e), Some(K::HeartbeatTimeout { .. }))),
        "no heartbeat lost during the failover: {during:?}"
    );
    let p0 = master.port_counters(0).unwrap().rx_frames;
    tokio::time::sleep(Duration::from_millis(200)).await;
    assert_eq!(
        master.port_counters(0).unwrap().rx_frames,
        p0,
        "nothing on the dead wire"
    );

    drop(down);
    port_reported(&mut ev, 0, true, 5).await;
    // The slave's port 0 recovers too, and its frames reach the master on vcan0 again.
    until_grown(&mut ev, || rx(0), 5, 20, "frames on vcan0 after recovery").await;
    assert!(master.port_counters(0).unwrap().reopened >= 1);
    master.shutdown().await;
    slave.shutdown().await;
}

/// Our candump logs replay with can-utils' `canplayer`, and `candump -L` output parses back.
#[tokio::test]
async fn candump_logs_interoperate_with_can_utils() {
    use duocan::capture::candump::{read_log, CandumpWriter};
    use duocan::capture::Record;
    let frames = [
        Frame::from_array(Id::Standard(0x181), [1, 2, 3]),
        Frame::from_array(Id::Extended(0x18FF_0001), [0xAA; 8]),
        Frame::remote(Id::Standard(0x705), 1).unwrap(),
        Frame::new(Id::Standard(0x000), &[]).unwrap(),
    ];
    // duocan writes, canplayer replays onto vcan1, our port receives.
    let mut w = CandumpWriter::new(Vec::new());
    for (i, f) in frames.iter().enumerate() {
        w.write(1_700_000_000_000_000 + i as u64 * 1000, "can0", f)
            .unwrap();
    }
    std::fs::write("/tmp/duocan.log", w.into_inner()).unwrap();
    let mut rx = SocketCanPort::open("vcan1").unwrap();
    let st = Command::new("canplayer")
        .args(["-I", "/tmp/duocan.log", "vcan1=can0"])
        .status()
        .expect("canplayer from can-utils (the tier script adds it to the VM)");
    assert!(st.success());
    for f in &frames {
        assert_eq!(recv_input(&mut rx).await, PortInput::Frame(*f, None));
    }
    // Our port sends, candump -L logs, duocan reads the log.
    let dump = Command::new("candump")
        .args(["-L", "-n", "4", "-T", "3000", "vcan1"])
        .stdout(std::process::Stdio::piped())
        .spawn()
        .expect("candump");
    tokio::time::sleep(Duration::from_millis(200)).await;
    let mut tx = SocketCanPort::open("vcan1").unwrap();
    for f in &frames {
        tx.send(f).await.unwrap();
    }
    let out = dump.wait_with_output().unwrap();
    let text = String::from_utf8(out.stdout).unwrap();
    let back: Vec<Frame> = read_log("candump -L", text.as_bytes())
        .map(|e| match e.expect("candump line parses").record {
            Record::Frame(f) => f,
            other => panic!("unexpected record {other:?}"),
        })
        .collect();
    assert_eq!(back, frames, "candump -L output:\n{text}");
}

/// A master (node + SDO client) and two slaves, each in its own runtime on vcan0: SDO in every
/// mode, to both slaves at once.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sdo_between_runtimes_over_vcan() {
    use duocan::sdo::{SdoOptions, TransferMode};
    let m = Runtime::new(rt::master(1, &[]))
        .name("master")
        .port(SocketCanPort::open("vcan0").unwrap())
        .spawn()
        .unwrap();
    let s5 = Runtime::new(single(rt::sdo_node(5, false, 100, &[])))
        .name("slave5")
        .port(SocketCanPort::open("vcan0").unwrap())
        .spawn()
        .unwrap();
    let s6 = Runtime::new(single(rt::sdo_node(6, false, 100, &[])))
        .name("slave6")
        .port(SocketCanPort::open("vcan0").unwrap())
        .spawn()
        .unwrap();
    for h in [&s5, &s6] {
        h.boot().await.unwrap();
    }
    m.boot().await.unwrap();
    let (n5, n6) = (NodeId::new(5).unwrap(), NodeId::new(6).unwrap());
    let v = m
        .sdo_read(n5, 0x1018, 2, SdoOptions::default())
        .await
        .unwrap();
    assert_eq!(v, 5u32.to_le_bytes(), "product code of node 5");
    let text = m
        .sdo_read(n6, 0x2001, 0, SdoOptions::default())
        .await
        .unwrap();
    assert_eq!(text, b"duocan node over a real bus");
    let (a, b) = (rt::pattern(2000, 5), rt::pattern(1500, 6));
    let (ra, rb) = tokio::join!(
        m.sdo_write(
            n5,
            0x2002,
            0,
            a.clone(),
            SdoOptions::mode(TransferMode::Block)
        ),
        m.sdo_write(
            n6,
            0x2002,
            0,
            b.clone(),
            SdoOptions::mode(TransferMode::Segmented)
        ),
    );
    ra.unwrap();
    rb.unwrap();
    assert_eq!(s5.read(0x2002, 0).await.unwrap(), a);
    assert_eq!(s6.read(0x2002, 0).await.unwrap(), b);
    let back = m
        .sdo_read(n5, 0x2002, 0, SdoOptions::mode(TransferMode::Block))
        .await
        .unwrap();
    assert_eq!(back, a);
    m.shutdown().await;
    for h in [&s5, &s6] {
        h.shutdown().await;
    }
}
