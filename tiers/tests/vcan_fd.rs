//! CAN FD on real SocketCAN: vcan interfaces at the CAN FD MTU (72, vcan's default) carry CAN FD
//! frames between ports opened with `SocketCanPort::open_fd`; an interface at MTU 16 is refused
//! for CAN FD with an error naming it. Runs inside the qemu VM of `.ci/vcanvm` (the host kernel
//! has no CAN): `.ci/tier-vcan.sh`, one test at a time (`RUST_TEST_THREADS=1`: the MTU test
//! switches vcan2 down and up).

use duocan::port::socketcan::{interface_mtu, SocketCanPort};
use duocan::port::{AnyInput, Port, PortErrorKind, PortInput};
use duocan::{FdFrame, Frame, Id};
use std::process::Command;
use std::time::Duration;

fn ip(args: &[&str]) {
    let st = Command::new("ip").args(args).status().expect("run ip");
    assert!(st.success(), "ip {args:?} failed");
}

/// Sets an interface's MTU (down, set, up); puts the CAN FD MTU back when dropped.
struct Mtu(&'static str);

impl Mtu {
    fn set(ifname: &'static str, mtu: u32) -> Self {
        ip(&["link", "set", ifname, "down"]);
        ip(&["link", "set", ifname, "mtu", &mtu.to_string()]);
        ip(&["link", "set", ifname, "up"]);
        Mtu(ifname)
    }
}

impl Drop for Mtu {
    fn drop(&mut self) {
        for args in [
            ["link", "set", self.0, "down"].as_slice(),
            &["link", "set", self.0, "mtu", "72"],
            &["link", "set", self.0, "up"],
        ] {
            let _ = Command::new("ip").args(args).status();
        }
    }
}

/// The next input of `p` through `recv_any`: a frame must carry the kernel's receive
/// timestamp; it is returned without it, to be compared.
async fn next(p: &mut SocketCanPort) -> AnyInput {
    let x = tokio::time::timeout(Duration::from_secs(2), p.recv_any())
        .await
        .expect("frame within 2 s")
        .expect("port works");
    match x {
        AnyInput::Fd(f, at) => {
            assert!(
                at.is_some(),
                "a SocketCAN frame comes with its receive timestamp"
            );
            AnyInput::Fd(f, None)
        }
        AnyInput::Frame(f, at) => {
            assert!(
                at.is_some(),
                "a SocketCAN frame comes with its receive timestamp"
            );
            AnyInput::Frame(f, None)
        }
        status => status,
    }
}

#[tokio::test]
async fn fd_frames_travel_between_fd_ports_on_a_vcan_at_the_fd_mtu() {
    assert_eq!(
        interface_mtu("vcan0"),
        Some(72),
        "vcan's default MTU is CAN FD's"
    );
    let mut a = SocketCanPort::open_fd("vcan0").expect("open vcan0 for CAN FD");
    let mut b = SocketCanPort::open_fd("vcan0").expect("open vcan0 for CAN FD again");
    let mut classic = SocketCanPort::open("vcan0").expect("open vcan0 classic");
    assert!(a.is_fd() && !classic.is_fd());
    let twelve: Vec<u8> = (0..12).collect();
    let sent = [
        FdFrame::new(Id::Standard(0x181), &[0xA5; 64])
            .unwrap()
            .with_brs(true),
        FdFrame::new(Id::Extended(0x001A_BCDE), &twelve)
            .unwrap()
            .with_esi(true),
        FdFrame::new(Id::Standard(0x182), &[])
            .unwrap()
            .with_brs(true)
            .with_esi(true),
    ];
    for f in &sent {
        a.send_fd(f).await.expect("send an FD frame");
    }
    let plain = Frame::from_array(Id::Standard(0x701), [0x05]);
    a.send(&plain).await.expect("send a classic frame");
    for f in &sent {
        assert_eq!(next(&mut b).await, AnyInput::Fd(*f, None));
    }
    assert_eq!(next(&mut b).await, AnyInput::Frame(plain, None));
    // A classic socket gets no CAN FD frame from the kernel: only the classic one.
    let got = tokio::time::timeout(Duration::from_secs(2), classic.recv())
        .await
        .expect("frame within 2 s")
        .unwrap();
    assert!(
        matches!(got, PortInput::Frame(f, Some(_)) if f == plain),
        "{got:?}"
    );
    assert_eq!(classic.counters().snapshot().rx_invalid, 0);
    assert_eq!(b.counters().snapshot().rx_frames, 4);
    // `recv` of an FD port hands classic frames over and counts FD ones as invalid.
    a.send_fd(&sent[0]).await.unwrap();
    a.send(&plain).await.unwrap();
    let got = tokio::time::timeout(Duration::from_secs(2), b.recv())
        .await
        .expect("frame within 2 s")
        .unwrap();
    assert!(
        matches!(got, PortInput::Frame(f, Some(_)) if f == plain),
        "{got:?}"
    );
    assert_eq!(b.counters().snapshot().rx_invalid, 1);
    // A classic port refuses to send CAN FD.
    let e = classic.send_fd(&sent[0]).await.unwrap_err();
    assert_eq!(e.kind, PortErrorKind::Config);
    assert!(e.to_string().contains("classic CAN port"), "{e}");
}

#[tokio::test]
async fn an_interface_at_the_classic_mtu_refuses_fd_naming_it() {
    let _mtu = Mtu::set("vcan2", 16);
    assert_eq!(interface_mtu("vcan2"), Some(16));
    let e = SocketCanPort::open_fd("vcan2").unwrap_err();
    assert_eq!(e.kind, PortErrorKind::Config);
    let msg = e.to_string();
    assert!(
        msg.contains("vcan2 has MTU 16, not the CAN FD MTU 72"),
        "{msg}"
    );
    assert!(msg.contains("ip link set vcan2 mtu 72"), "{msg}");
    // Classic CAN is fine there.
    let mut p = SocketCanPort::open("vcan2").expect("classic open at MTU 16");
    let mut q = SocketCanPort::open("vcan2").unwrap();
    let f = Frame::from_array(Id::Standard(0x123), [1, 2, 3]);
    p.send(&f).await.unwrap();
    let got = tokio::time::timeout(Duration::from_secs(2), q.recv())
        .await
        .expect("frame within 2 s")
        .unwrap();
    assert!(
        matches!(got, PortInput::Frame(g, Some(_)) if g == f),
        "{got:?}"
    );
}
