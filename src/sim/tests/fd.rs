//! CAN FD frames on the simulated wire: two-phase wire time, arbitration against classic
//! frames, faults, captures, and the rule that FD frames belong only where every node is
//! FD-capable.

use super::probe::{std_frame, Probe};
use super::tx_records;
use crate::frame::instant::{Duration, Instant};
use crate::frame::{FdFrame, Frame, Id};
use crate::machine::{Device, ErrorCause, PortStatus};
use crate::sim::{timing, BusConfig, FaultRates, RxFault, SimError, SimNetwork, TxOutcome};
use std::collections::VecDeque;

/// An FD-capable device: sends what it is given (classic and FD), records what it gets.
#[derive(Default)]
struct FdProbe {
    out: VecDeque<(usize, Frame)>,
    out_fd: VecDeque<(usize, FdFrame)>,
    rx: Vec<(Instant, Frame)>,
    rx_fd: Vec<(Instant, FdFrame, Instant)>,
    /// The first data byte of every frame received, classic or FD, in order.
    arrivals: Vec<u8>,
    status: Vec<(Instant, PortStatus)>,
    /// Says it is classic-only.
    classic: bool,
}

impl Device for FdProbe {
    type Event = ();
    fn port_count(&self) -> usize {
        1
    }
    fn fd_capable(&self) -> bool {
        !self.classic
    }
    fn handle_rx(&mut self, now: Instant, _: usize, frame: &Frame) {
        self.rx.push((now, *frame));
        self.arrivals.extend(frame.data().first());
    }
    fn handle_rx_fd(&mut self, now: Instant, _: usize, frame: &FdFrame, at: Instant) {
        self.rx_fd.push((now, *frame, at));
        self.arrivals.extend(frame.data().first());
    }
    fn handle_port_status(&mut self, now: Instant, _: usize, status: PortStatus) {
        self.status.push((now, status));
    }
    fn handle_timeout(&mut self, _: Instant) {}
    fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
        self.out.pop_front()
    }
    fn poll_transmit_fd(&mut self) -> Option<(usize, FdFrame)> {
        self.out_fd.pop_front()
    }
    fn poll_timeout(&self) -> Option<Instant> {
        None
    }
    fn poll_event(&mut self) -> Option<()> {
        None
    }
}

fn fd(id: u16, data: &[u8]) -> FdFrame {
    FdFrame::new(Id::Standard(id), data).unwrap().with_brs(true)
}

/// An FD bus at 500 kbit/s nominal, 2 Mbit/s data, with two FD probes.
fn fd_pair(seed: u64) -> (SimNetwork, crate::sim::BusId) {
    let mut sim = SimNetwork::new(seed);
    let bus = sim.add_bus(BusConfig::new("canfd0", 500_000).fd(2_000_000));
    (sim, bus)
}

#[test]
fn an_fd_frame_takes_both_phases_of_wire_time() {
    let (mut sim, bus) = fd_pair(1);
    assert!(sim.is_fd(bus));
    assert_eq!(sim.data_bitrate(bus), 2_000_000);
    let a = sim.add_device("a", FdProbe::default(), &[bus]).unwrap();
    let b = sim.add_device("b", FdProbe::default(), &[bus]).unwrap();
    let f = fd(0x181, &[0xA5; 64]);
    sim.device_mut(a).out_fd.push_back((0, f));
    sim.run_until(Instant::from_millis(5));
    let want = timing::fd_frame_duration(&f, 500_000, 2_000_000);
    // Well below the same frame without the switch.
    assert!(want < timing::fd_frame_duration(&f, 500_000, 500_000));
    let got = &sim.device(b).rx_fd;
    assert_eq!(got.len(), 1);
    assert_eq!(got[0].1, f);
    assert!(got[0].1.brs());
    assert_eq!(got[0].0, Instant::ZERO + want);
    assert_eq!(got[0].2, Instant::ZERO + want, "stamped with its wire time");
    assert_eq!(
        sim.device(a).status,
        [(Instant::ZERO + want, PortStatus::TxOk)]
    );
    let tx = tx_records(&sim);
    assert_eq!(tx.len(), 1);
    assert_eq!(tx[0].fd.as_deref(), Some(&f));
    assert_eq!(tx[0].frame.id(), f.id());
    assert_eq!(tx[0].end - tx[0].start, want);
    assert_eq!(
        sim.bus_stats(bus).busy_bits,
        u64::from(timing::fd_frame_bits(&f).total())
    );
    assert!(sim.trace()[0].to_string().contains("FD BRS A5"));
    // The classic receive path saw nothing.
    assert!(sim.device(b).rx.is_empty());
}

#[test]
fn classic_and_fd_frames_arbitrate_by_identifier() {
    let (mut sim, bus) = fd_pair(2);
    let a = sim.add_device("a", FdProbe::default(), &[bus]).unwrap();
    let b = sim.add_device("b", FdProbe::default(), &[bus]).unwrap();
    let c = sim.add_device("c", FdProbe::default(), &[bus]).unwrap();
    // Queued at the same instant: FD 0x100 beats classic 0x200, which beats FD 0x300.
    sim.device_mut(a).out.push_back((0, std_frame(0x200, &[2])));
    sim.device_mut(b).out_fd.push_back((0, fd(0x100, &[1; 12])));
    sim.device_mut(b).out_fd.push_back((0, fd(0x300, &[3; 48])));
    sim.run_until(Instant::from_millis(5));
    let order: Vec<u32> = tx_records(&sim)
        .iter()
        .map(|t| t.frame.id().raw())
        .collect();
    assert_eq!(order, [0x100, 0x200, 0x300]);
    let got = &sim.device(c);
    assert_eq!(got.rx.len(), 1);
    assert_eq!(got.rx_fd.len(), 2);
    assert!(got.rx_fd[0].0 < got.rx[0].0 && got.rx[0].0 < got.rx_fd[1].0);
    assert_eq!(sim.tx_queue_len(a.port(0)), 0);
}

#[test]
fn a_classic_only_device_on_an_fd_bus_is_a_configuration_error() {
    let (mut sim, bus) = fd_pair(3);
    let err = sim.add_device("old", Probe::new(1), &[bus]).unwrap_err();
    assert_eq!(
        err,
        SimError::ClassicOnFdBus {
            bus,
            device: "old".into()
        }
    );
    let msg = err.to_string();
    assert!(msg.contains("classic-only") && msg.contains("every node is FD-capable"));
    assert_eq!(sim.device_count(), 0);
    // On a classic bus it is welcome, and so is an FD-capable one.
    let classic = sim.add_bus(BusConfig::new("can1", 500_000));
    assert!(!sim.is_fd(classic));
    assert_eq!(sim.data_bitrate(classic), 500_000);
    sim.add_device("old", Probe::new(1), &[classic]).unwrap();
    sim.add_device("new", FdProbe::default(), &[classic])
        .unwrap();
}

#[test]
fn an_fd_frame_a_classic_node_hears_is_an_error_frame() {
    let mut sim = SimNetwork::new(4);
    let bus = sim.add_bus(BusConfig::new("can0", 500_000));
    let a = sim.add_device("a", FdProbe::default(), &[bus]).unwrap();
    let old = sim.add_device("old", Probe::new(1), &[bus]).unwrap();
    sim.device_mut(a).out_fd.push_back((0, fd(0x181, &[1; 16])));
    sim.device_mut(a).out_fd.push_back((0, fd(0x183, &[3; 16])));
    sim.device_mut(a).out.push_back((0, std_frame(0x182, &[2])));
    sim.run_until(Instant::from_millis(5));
    let tx = tx_records(&sim);
    // The classic frame went first (a driver asks for classic frames first); each FD frame
    // got one attempt.
    assert_eq!(tx.len(), 3, "not retried: {tx:?}");
    assert_eq!(tx[0].outcome, TxOutcome::Delivered { receivers: 1 });
    assert_eq!(tx[1].outcome, TxOutcome::ErrorFrame);
    assert_eq!(tx[2].outcome, TxOutcome::ErrorFrame);
    assert_eq!(tx[1].fd.as_deref(), Some(&fd(0x181, &[1; 16])));
    let form = PortStatus::Error(ErrorCause::Form);
    assert_eq!(
        sim.device(old).status_on(0),
        [(tx[1].end, form), (tx[2].end, form)]
    );
    assert_eq!(
        sim.device(old).rx_on(0),
        [(tx[0].end, std_frame(0x182, &[2]))]
    );
    let failed = PortStatus::TxFailed(ErrorCause::Form);
    assert_eq!(
        sim.device(a).status,
        [
            (tx[0].end, PortStatus::TxOk),
            (tx[1].end, failed),
            (tx[2].end, failed)
        ]
    );
    assert_eq!(sim.port_stats(a.port(0)).error_frames, 2);
    assert_eq!(sim.port_stats(a.port(0)).tx_failed, 2);
    assert_eq!(sim.bus_stats(bus).error_frames, 2);
    // The error frame lasts 7 bits longer than the good frame would have.
    let f = fd(0x181, &[1; 16]);
    assert_eq!(
        tx[1].end - tx[1].start,
        timing::fd_frame_duration(&f, 500_000, 500_000) + timing::bits_duration(7, 500_000)
    );
}

#[test]
fn faults_hit_fd_frames_too() {
    let (mut sim, bus) = fd_pair(5);
    let a = sim.add_device("a", FdProbe::default(), &[bus]).unwrap();
    let b = sim.add_device("b", FdProbe::default(), &[bus]).unwrap();
    let c = sim.add_device("c", FdProbe::default(), &[bus]).unwrap();
    // b: every second frame lost, and a fixed latency; c: every frame bit-flipped.
    sim.drop_every(b.port(0), 2);
    sim.set_port_latency(b.port(0), Duration::from_micros(300));
    sim.set_port_faults(c.port(0), FaultRates::NONE.with_corrupt_undetected(1.0));
    let frames: Vec<FdFrame> = (0..4).map(|i| fd(0x200 + i, &[i as u8; 20])).collect();
    for f in &frames {
        sim.device_mut(a).out_fd.push_back((0, *f));
    }
    sim.run_until(Instant::from_millis(5));
    let tx = tx_records(&sim);
    assert_eq!(tx.len(), 4);
    let got_b: Vec<_> = sim.device(b).rx_fd.iter().map(|r| (r.0, r.1)).collect();
    assert_eq!(
        got_b,
        [
            (tx[0].end + Duration::from_micros(300), frames[0]),
            (tx[2].end + Duration::from_micros(300), frames[2]),
        ]
    );
    assert_eq!(sim.port_stats(b.port(0)).rx_dropped, 2);
    let got_c = &sim.device(c).rx_fd;
    assert_eq!(got_c.len(), 4);
    for ((_, got, _), sent) in got_c.iter().zip(&frames) {
        let diff: u32 = got
            .data()
            .iter()
            .zip(sent.data())
            .map(|(x, y)| (x ^ y).count_ones())
            .sum();
        assert_eq!(diff, 1, "one bit flipped");
        assert_eq!(
            (got.id(), got.len(), got.brs()),
            (sent.id(), sent.len(), true)
        );
    }
    let flips = sim
        .trace()
        .iter()
        .filter(|r| {
            matches!(r, crate::sim::TraceRecord::Rx(x)
                if matches!(x.fault, RxFault::CorruptedFd { .. }) && x.fd.is_some())
        })
        .count();
    assert_eq!(flips, 4);
    assert_eq!(sim.port_stats(c.port(0)).rx_corrupted, 4);
}

#[test]
fn a_detected_error_retransmits_the_fd_frame() {
    let (mut sim, bus) = fd_pair(6);
    let a = sim.add_device("a", FdProbe::default(), &[bus]).unwrap();
    let b = sim.add_device("b", FdProbe::default(), &[bus]).unwrap();
    sim.set_bus_faults(bus, FaultRates::NONE.with_corrupt_detected(0.5));
    let frames: Vec<FdFrame> = (0..8).map(|i| fd(0x300 + i, &[i as u8; 64])).collect();
    for f in &frames {
        sim.device_mut(a).out_fd.push_back((0, *f));
    }
    sim.run_until(Instant::from_millis(50));
    let got: Vec<FdFrame> = sim.device(b).rx_fd.iter().map(|r| r.1).collect();
    assert_eq!(got, frames, "every frame arrives once, in order");
    let tx = tx_records(&sim);
    let errors = tx
        .iter()
        .filter(|t| t.outcome == TxOutcome::ErrorFrame)
        .count();
    assert!(errors > 0, "seed 6 draws some errors");
    for t in &tx {
        let f = t.fd.as_deref().expect("every attempt is an FD frame");
        assert_eq!(Some(f), frames.get(t.serial.unwrap() as usize));
    }
}

#[test]
fn an_fd_frame_from_a_disconnected_port_reaches_nobody_and_delays_keep_order() {
    let (mut sim, bus) = fd_pair(7);
    let a = sim.add_device("a", FdProbe::default(), &[bus]).unwrap();
    let b = sim.add_device("b", FdProbe::default(), &[bus]).unwrap();
    sim.disconnect(a.port(0));
    sim.device_mut(a).out_fd.push_back((0, fd(0x181, &[1; 8])));
    sim.run_until(Instant::from_millis(1));
    assert!(sim.device(b).rx_fd.is_empty());
    assert_eq!(tx_records(&sim)[0].outcome, TxOutcome::SenderDisconnected);
    sim.reconnect(a.port(0));
    sim.clear_trace();
    // Random delays on b: FD and classic frames still reach it in the order they were sent.
    sim.set_port_faults(
        b.port(0),
        FaultRates::NONE.with_delay(1.0, Duration::from_millis(2)),
    );
    for i in 0..6u8 {
        if i % 2 == 0 {
            sim.device_mut(a).out_fd.push_back((0, fd(0x400, &[i; 32])));
        } else {
            sim.device_mut(a).out.push_back((0, std_frame(0x500, &[i])));
        }
    }
    sim.run_until(Instant::from_millis(20));
    let dev = sim.device(b);
    assert_eq!((dev.rx.len(), dev.rx_fd.len()), (3, 3));
    assert!(sim.port_stats(b.port(0)).rx_delayed > 0);
    // The device's classic frames went out first (a driver asks for them first); b got them
    // all in wire order.
    assert_eq!(dev.arrivals, [1, 3, 5, 0, 2, 4]);
}

#[test]
fn captures_of_the_trace_keep_fd_frames_as_fd_records() {
    let (mut sim, bus) = fd_pair(8);
    let a = sim.add_device("a", FdProbe::default(), &[bus]).unwrap();
    sim.add_device("b", FdProbe::default(), &[bus]).unwrap();
    let f = fd(0x181, &[0x11; 12]).with_esi(true);
    sim.device_mut(a).out_fd.push_back((0, f));
    sim.device_mut(a).out.push_back((0, std_frame(0x700, &[5])));
    sim.run_until(Instant::from_millis(5));
    let mut log = Vec::new();
    sim.write_candump(&mut log).unwrap();
    let log = String::from_utf8(log).unwrap();
    let lines: Vec<&str> = log.lines().collect();
    assert_eq!(lines.len(), 2, "{log}");
    assert!(lines[0].ends_with("canfd0 700#05"), "{log}");
    assert!(
        lines[1].ends_with(&format!("canfd0 181##3{}", "11".repeat(12))),
        "{log}"
    );
    let entry = crate::capture::candump::parse_line(lines[1]).unwrap();
    assert_eq!(entry.record.fd_frame(), Some(&f));
    let mut pcap = Vec::new();
    sim.write_pcap(&mut pcap).unwrap();
    // Header 24, a classic record 16 + 8 + 1, an FD record 16 + 72.
    assert_eq!(pcap.len(), 24 + 25 + 88);
    let rec = crate::capture::pcap::decode_packet(&pcap[24 + 25 + 16..]).unwrap();
    assert_eq!(rec.fd_frame(), Some(&f));
    assert_eq!(tx_records(&sim)[1].capture_record().fd_frame(), Some(&f));
}

#[test]
fn an_fd_frame_cut_short_by_a_partition_is_sent_again() {
    let (mut sim, bus) = fd_pair(9);
    let a = sim.add_device("a", FdProbe::default(), &[bus]).unwrap();
    let b = sim.add_device("b", FdProbe::default(), &[bus]).unwrap();
    let f = fd(0x181, &[0x5A; 64]);
    sim.device_mut(a).out_fd.push_back((0, f));
    // Partitioned and healed while the frame is on the wire (it takes well over 20 µs).
    sim.at(Instant::from_micros(20), move |s| {
        s.partition(bus, &[&[a.port(0)]])
    });
    sim.at(Instant::from_micros(30), move |s| s.heal(bus));
    sim.run_until(Instant::from_millis(5));
    let tx = tx_records(&sim);
    assert_eq!(tx[0].outcome, TxOutcome::Aborted);
    assert_eq!(tx[0].fd.as_deref(), Some(&f));
    let last = tx.last().unwrap();
    assert_eq!(last.outcome, TxOutcome::Delivered { receivers: 1 });
    assert_eq!((last.fd.as_deref(), last.serial), (Some(&f), Some(0)));
    assert_eq!(sim.device(b).rx_fd.len(), 1);
    assert_eq!(sim.device(b).rx_fd[0].1, f);
}

#[test]
fn replacing_an_fd_device_by_a_classic_only_one_on_an_fd_bus_is_refused() {
    let (mut sim, bus) = fd_pair(10);
    let x = sim.add_device("x", FdProbe::default(), &[bus]).unwrap();
    let classic = FdProbe {
        classic: true,
        ..FdProbe::default()
    };
    let Err(e) = sim.replace(x, classic) else {
        panic!("a classic-only device replaced one on an FD bus")
    };
    assert_eq!(
        e,
        SimError::ClassicOnFdBus {
            bus,
            device: "x".into()
        }
    );
    // Still the FD-capable device, and an FD-capable replacement is fine.
    assert!(sim.device(x).fd_capable());
    sim.replace(x, FdProbe::default()).unwrap();
}

#[test]
fn a_full_queue_holds_fd_frames_back_without_losing_or_reordering_them() {
    let (mut sim, bus) = fd_pair(11);
    let a = sim.add_device("a", FdProbe::default(), &[bus]).unwrap();
    let b = sim.add_device("b", FdProbe::default(), &[bus]).unwrap();
    sim.set_tx_capacity(a.port(0), 1);
    let frames: Vec<FdFrame> = (0..6u8).map(|i| fd(0x100, &[i; 24])).collect();
    for f in &frames {
        sim.device_mut(a).out_fd.push_back((0, *f));
    }
    sim.device_mut(a).out.push_back((0, std_frame(0x100, &[9])));
    sim.run_until(Instant::from_millis(10));
    let got: Vec<FdFrame> = sim.device(b).rx_fd.iter().map(|r| r.1).collect();
    assert_eq!(got, frames);
    assert_eq!(sim.device(b).arrivals, [9, 0, 1, 2, 3, 4, 5]);
    assert!(sim.port_stats(a.port(0)).tx_blocked > 0);
    let serials: Vec<u64> = tx_records(&sim).iter().map(|t| t.serial.unwrap()).collect();
    assert_eq!(serials, [0, 1, 2, 3, 4, 5, 6]);
}
