//! The simulated plant on the railway 29-bit profile, on tokio's paused clock: the same
//! failovers at the same instants as on the predefined set, SDO through the handle, and on
//! the wire the railway identifiers (29-bit, function · row · cabinet · layer · board · port).

use super::*;
use crate::net::RedundantEvent;
use crate::pair::Member;
use crate::supervisor::flying_master::{MasterReason, MasterRole, MasterRoleChange};
use crate::supervisor::pairs::{RoleChange, RoleReason};
use duocan::net::NetEvent;
use duocan::port::Port;
use duocan::profile::railway::{DeviceAddress, RailwayProfile};
use duocan::{Frame, Id};
use std::sync::{Arc, Mutex};

fn ms(n: u64) -> Duration {
    Duration::from_millis(n)
}

fn after(d: Duration) -> Instant {
    Instant::ZERO + d
}

/// Every frame bus `bus` carries from now on, until the bus is gone.
fn listen(bus: &MemBus) -> Arc<Mutex<Vec<Frame>>> {
    let heard = Arc::new(Mutex::new(Vec::new()));
    let mut port = bus.port();
    let out = heard.clone();
    tokio::spawn(async move {
        while let Ok(input) = port.recv().await {
            if let (Some(f), Ok(mut v)) = (input.frame(), out.lock()) {
                v.push(*f);
            }
        }
    });
    heard
}

fn rail(function: RailFunction, a: DeviceAddress) -> Id {
    railway::id(function, a)
}

#[tokio::test(start_paused = true)]
async fn on_the_railway_profile_the_plant_fails_over_at_the_same_instants_on_29_bit_frames() {
    let (hb, master_timeout, pair_hb, pair_timeout) = (ms(20), ms(50), ms(25), ms(80));
    let b = RedundantNetworkBuilder::default()
        .node_id(2)
        .heartbeat(hb)
        .master_timeout(master_timeout)
        .sync(ms(10))
        .pair(0x10, 0x50)
        .pair_heartbeat(pair_hb)
        .pair_timeout(pair_timeout)
        .peer_master(1)
        .profile(NetProfile::railway29());
    let buses = [MemBus::new("sim-bus1"), MemBus::new("sim-bus2")];
    let wire = [listen(&buses[0]), listen(&buses[1])];
    let start = tokio::time::Instant::now();
    let net = open_on(&b, Plant::Script, buses).unwrap();
    let mut stream = net.events();
    let events = tokio::spawn(async move {
        let mut out = vec![];
        while let Some(e) = stream.next().await {
            out.push(e);
        }
        out
    });
    // Node 2 is active once its peer stopped (3 s) and it took over; A stops at 4 s.
    tokio::time::sleep_until(start + std::time::Duration::from_millis(3_500)).await;
    assert_eq!(net.role().await.unwrap(), MasterRole::Active);
    let serial: u32 = net.node(0x10).sdo().read(0x1018, 2).await.unwrap();
    assert_eq!(serial, 0x10);
    let vendor: u32 = net.node(0x50).sdo().read(0x1018, 1).await.unwrap();
    assert_eq!(vendor, duocan::net::SIM_VENDOR);
    let events = events.await.unwrap();

    // The failovers, as on the predefined set (`front_door.rs`), at the same instants.
    let failovers: Vec<&NetEvent> = events.iter().filter(|e| e.is_failover()).collect();
    let lines: Vec<String> = failovers.iter().map(ToString::to_string).collect();
    assert_eq!(
        lines,
        [
            "bus 1: failed (port down: interface down)",
            "this master: active",
            "pair 0x10/0x50: B active"
        ],
        "{events:#?}"
    );
    assert_eq!(failovers[0].at(), Some(after(SIM_BUS_FAILS)));
    let Some(&RedundantEvent::MasterRole(MasterRoleChange {
        from: MasterRole::Standby(_),
        reason: MasterReason::HeartbeatLost { master, last },
        at,
        ..
    })) = failovers[1].ext()
    else {
        panic!("{:?}", failovers[1]);
    };
    assert_eq!(master.raw(), 1);
    assert_eq!(at, last + master_timeout);
    let stopped = after(SIM_PEERS_FAIL);
    assert!(last <= stopped && stopped <= last + hb, "last {last}");
    let Some(&RedundantEvent::PairRole(RoleChange {
        from: Some(Member::A),
        to: Some(Member::B),
        reason: RoleReason::ActiveSilent { last },
        at,
        ..
    })) = failovers[2].ext()
    else {
        panic!("{:?}", failovers[2]);
    };
    assert_eq!(at, last + pair_timeout);
    let stopped = after(SIM_MEMBER_FAILS);
    assert!(last <= stopped && stopped <= last + pair_hb, "last {last}");

    // On the wire: the railway identifiers of each board (row 1, cabinet = high nibble,
    // layer 1, board = low nibble), 29-bit; 11-bit only for the flying master's 0x71–0x76.
    let bus2 = wire[1].lock().map(|v| v.clone()).unwrap_or_default();
    let bus1 = wire[0].lock().map(|v| v.clone()).unwrap_or_default();
    assert!(!bus1.is_empty() && !bus2.is_empty());
    let a = DeviceAddress::board_at(1, 1, 1, 0);
    let b_addr = DeviceAddress::board_at(1, 5, 1, 0);
    assert_eq!(NetProfile::railway_address(NodeId::must(0x10)), a);
    let has = |id: Id, data: Option<&[u8]>| {
        bus2.iter()
            .any(|f| f.id() == id && data.is_none_or(|d| f.data() == d))
    };
    // Heartbeats (operational: 0x05) of both members, 0x0081_1100 and 0x0081_5100.
    assert_eq!(rail(RailFunction::Heartbeat, a), Id::Extended(0x0081_1100));
    assert!(has(rail(RailFunction::Heartbeat, a), None));
    assert!(has(rail(RailFunction::Heartbeat, b_addr), Some(&[0x05])));
    // The masters' heartbeats: node 1 at cabinet 0, board 1; node 2 board 2.
    let m2 = DeviceAddress::board_at(1, 0, 1, 2);
    assert!(has(rail(RailFunction::Heartbeat, m2), None));
    // NMT at address 0; SYNC at its railway identifier.
    assert!(bus2.iter().any(|f| f.id() == Id::Extended(0)));
    assert!(has(RailwayProfile::SYNC, Some(&[])));
    // The SDO read of 0x1018 sub 2 from node 0x10: request and response on its channel.
    let upload = |f: &Frame| f.data().get(1..4) == Some(&[0x18, 0x10, 0x02][..]);
    assert!(bus2
        .iter()
        .any(|f| f.id() == Id::Extended(0x0821_1100) && upload(f)));
    assert!(bus2
        .iter()
        .any(|f| f.id() == Id::Extended(0x0801_1100) && upload(f)));
    for f in bus1.iter().chain(&bus2) {
        match f.id() {
            Id::Extended(raw) => assert!(raw <= 0x1FFF_FFFF),
            Id::Standard(raw) => assert!((0x71..=0x76).contains(&raw), "{f:?}"),
        }
    }
    // Nothing on the predefined identifiers of the members (heartbeat 0x710, SDO 0x590).
    assert!(!has(Id::Standard(0x710), None) && !has(Id::Standard(0x590), None));
}

/// When bus 2 carried a TIME frame (0x100, six bytes), from the start of a quiet plant for
/// `secs` seconds: this master (node 1, the strong one) active, its peer (node 2, the same
/// settings) standby.
async fn time_frames(time: Option<Duration>, secs: u64) -> Vec<std::time::Duration> {
    let mut b = RedundantNetworkBuilder::default()
        .node_id(1)
        .heartbeat(ms(20))
        .master_timeout(ms(50))
        .pair(0x10, 0x50)
        .peer_master(2);
    if let Some(t) = time {
        b = b.time(t);
    }
    let buses = [MemBus::new("sim-bus1"), MemBus::new("sim-bus2")];
    let start = tokio::time::Instant::now();
    let heard = Arc::new(Mutex::new(Vec::new()));
    let mut port = buses[1].port();
    let out = heard.clone();
    tokio::spawn(async move {
        while let Ok(input) = port.recv().await {
            let time = input
                .frame()
                .is_some_and(|f| f.id() == Id::Standard(0x100) && f.data().len() == 6);
            if let (true, Ok(mut v)) = (time, out.lock()) {
                v.push(start.elapsed());
            }
        }
    });
    let net = open_on(&b, Plant::Quiet, buses).unwrap();
    tokio::time::sleep_until(start + std::time::Duration::from_secs(secs)).await;
    assert_eq!(net.role().await.unwrap(), MasterRole::Active);
    net.close().await;
    let v = heard.lock().unwrap().clone();
    v
}

/// `time(period)`: the active master produces TIME at that period from its takeover, its
/// standby peer none (one frame per period on the bus); without it, none.
#[tokio::test(start_paused = true)]
async fn the_active_master_produces_time_at_the_period_it_was_given() {
    let with = time_frames(Some(ms(100)), 3).await;
    assert!(with.len() >= 20, "{with:?}");
    assert!(with[0] < std::time::Duration::from_secs(1), "{with:?}");
    for w in with.windows(2) {
        let gap = w[1] - w[0];
        assert!(
            gap >= std::time::Duration::from_micros(99_500)
                && gap <= std::time::Duration::from_micros(100_500),
            "{with:?}"
        );
    }
    assert!(time_frames(None, 3).await.is_empty());
}
