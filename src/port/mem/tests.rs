//! The in-memory bus's pacing, stamps and CAN FD frames.

use super::*;

/// 100 frames of 8 bytes with 11-bit identifiers are 111 bits each: at 125 kbit/s (8 µs a
/// bit) the bus is busy 88.8 ms, and the sender may run 2 ms ahead of it; every frame is
/// heard, in order.
#[tokio::test(start_paused = true)]
async fn a_paced_bus_takes_the_time_its_bit_rate_gives() {
    let bus = MemBus::with_bit_rate("paced", 125_000);
    let mut tx = bus.port();
    let mut rx = bus.port();
    let start = tokio::time::Instant::now();
    for i in 0..100u8 {
        let f = Frame::new(crate::frame::Id::Standard(0x181), &[i; 8]).unwrap();
        tx.send(&f).await.unwrap();
    }
    let took = start.elapsed();
    let busy = std::time::Duration::from_micros(100 * 111 * 8);
    assert!(took >= busy - MEM_BUS_BURST && took <= busy, "{took:?}");
    for i in 0..100u8 {
        let PortInput::Frame(f, _) = rx.recv().await.unwrap() else {
            panic!("a frame")
        };
        assert_eq!(f.data(), [i; 8]);
    }
    // An unpaced bus takes no time at all.
    let bus = MemBus::new("free");
    let mut tx = bus.port();
    let start = tokio::time::Instant::now();
    for _ in 0..100 {
        tx.send(&Frame::new(crate::frame::Id::Standard(1), &[0; 8]).unwrap())
            .await
            .unwrap();
    }
    assert_eq!(start.elapsed(), std::time::Duration::ZERO);
}

/// A sender with a backlog that comes back 30 ms late (held up on a loaded machine): the
/// bus makes the 30 ms up, so 200 frames still take their bus time, not 30 ms more. A bus
/// idle for longer than it makes up starts again from its idle time.
#[tokio::test(start_paused = true)]
async fn a_paced_bus_makes_up_for_a_late_sender() {
    let bus = MemBus::with_bit_rate("paced", 125_000);
    let mut tx = bus.port();
    let f = Frame::new(crate::frame::Id::Standard(0x181), &[0; 8]).unwrap();
    let busy = |n: u32| std::time::Duration::from_micros(u64::from(n) * 111 * 8);
    let start = tokio::time::Instant::now();
    for i in 0..200 {
        if i == 100 {
            tokio::time::advance(std::time::Duration::from_millis(30)).await;
        }
        tx.send(&f).await.unwrap();
    }
    let took = start.elapsed();
    assert!(
        took >= busy(200) - MEM_BUS_BURST && took <= busy(200),
        "{took:?}"
    );
    // Idle for a second: nothing to make up, the next 100 frames take their own bus time.
    tokio::time::advance(std::time::Duration::from_secs(1)).await;
    let start = tokio::time::Instant::now();
    for _ in 0..100 {
        tx.send(&f).await.unwrap();
    }
    let took = start.elapsed();
    assert!(
        took >= busy(100) - MEM_BUS_BURST && took <= busy(100),
        "{took:?}"
    );
}

/// A frame read late keeps the instant it went onto the bus. On a paced bus, a sender with a
/// backlog that comes back 30 ms late puts its next frame on the bus at its booked time
/// (the bus made up the 30 ms): stamped so, before the instant it was sent.
#[tokio::test(start_paused = true)]
async fn a_frame_is_stamped_with_its_time_on_the_bus() {
    let f = Frame::new(crate::frame::Id::Standard(0x181), &[0; 8]).unwrap();
    let stamp = |x: PortInput| match x {
        PortInput::Frame(_, at) => at.expect("a memory bus stamps every frame"),
        other => panic!("{other:?}"),
    };
    let bus = MemBus::new("free");
    let (mut tx, mut rx) = (bus.port(), bus.port());
    let sent = tokio::time::Instant::now();
    tx.send(&f).await.unwrap();
    tokio::time::advance(std::time::Duration::from_millis(30)).await;
    assert_eq!(stamp(rx.recv().await.unwrap()), sent.into_std());

    let bus = MemBus::with_bit_rate("paced", 125_000);
    let (mut tx, mut rx) = (bus.port(), bus.port());
    let start = tokio::time::Instant::now();
    for i in 0..101 {
        if i == 100 {
            tokio::time::advance(std::time::Duration::from_millis(30)).await;
        }
        tx.send(&f).await.unwrap();
    }
    let sent = tokio::time::Instant::now();
    let mut stamps = vec![];
    for _ in 0..101 {
        stamps.push(stamp(rx.recv().await.unwrap()));
    }
    assert!(stamps.windows(2).all(|w| w[0] <= w[1]), "in order");
    // 111 bits of 8 µs each: the 101st frame is through 101 × 888 µs after the start.
    let booked = start + std::time::Duration::from_micros(101 * 888);
    assert_eq!(stamps[100], booked.into_std());
    assert!(
        sent - booked >= std::time::Duration::from_millis(25),
        "{:?}",
        sent - booked
    );
}

/// CAN FD frames cross the bus as sent (bytes, BRS and ESI), in order with the classic ones,
/// stamped; a classic read skips them, counting them as invalid.
#[tokio::test]
async fn fd_frames_cross_the_bus_in_order() {
    let bus = MemBus::new("fd");
    let (mut tx, mut rx, mut classic) = (bus.port(), bus.port(), bus.port());
    let a = FdFrame::new(crate::frame::Id::Standard(0x181), &[7; 12])
        .unwrap()
        .with_brs(true);
    let b = Frame::new(crate::frame::Id::Standard(0x182), &[1, 2]).unwrap();
    let c = FdFrame::new(crate::frame::Id::Extended(0x1234), &[9; 64])
        .unwrap()
        .with_esi(true);
    tx.send_fd(&a).await.unwrap();
    tx.send(&b).await.unwrap();
    tx.send_fd(&c).await.unwrap();
    assert!(matches!(rx.recv_any().await, Ok(AnyInput::Fd(f, Some(_))) if f == a));
    assert!(matches!(rx.recv_any().await, Ok(AnyInput::Frame(f, Some(_))) if f == b));
    assert!(matches!(rx.recv_any().await, Ok(AnyInput::Fd(f, Some(_))) if f == c));
    assert_eq!(classic.recv().await.unwrap().frame(), Some(&b));
    let seen = classic.counters().snapshot();
    assert_eq!((seen.rx_frames, seen.rx_invalid), (1, 1));
}
