//! The demo's station and its scripted day, shared by the example (`examples/demo/main.rs`) and
//! its test (`tests/demo.rs`, which includes this module by path).
//!
//! One station: a strong and a weak interlocking computer, each on all four dual-bus racks
//! (turnout and misc racks on the CANopen predefined connection set, signal and track-circuit
//! racks on the railway 29-bit profile), A/B board pairs with point machines, signals, track
//! circuits and level crossings, described by EDS and DCF files ([`devices`]). Route-setting
//! commands run all day; faults are injected on a script ([`SCRIPT`]), the dead board replaced by
//! a spare without node-ID that the active master addresses by LSS ([`replacement`]), a rack's
//! buses handed over by a maintainer ([`handover`]), a board that stops by itself
//! ([`stopped`]);
//! [`analysis`] computes from the run what the demo prints and the test asserts; [`outputs`] writes the candump log, the pcap files and the SVG timeline.

pub mod analysis;
pub mod board;
pub mod devices;
pub mod field;
pub mod handover;
pub mod interlocking;
pub mod outputs;
// The timeline chart is the demo's own report, not part of the library.
pub mod replacement;
#[path = "../report/mod.rs"]
#[allow(dead_code, unused_imports)]
pub mod report;
pub mod scheme;
pub mod station;
pub mod stopped;

use devices::Devices;
use duocan::eds::EdsError;
use duocan::profile::railway::safety::PointPosition;
use duocan::profile::railway::safety::{SignalAspect, TrackCircuit};
use duocan::profile::Predefined;
use duocan::sim::SimNetwork;
use duocan::{Duration, Instant, NmtState};
use duocan_redundancy::Member;
use field::{Field, Kind, BARRIERS_DOWN, BARRIERS_UP};
use interlocking::Route;
use station::{board_node, master_node, Rack, RackSpec, RackView, STRONG, WEAK};
use std::cell::RefCell;
use std::rc::Rc;

/// Bit rate of every bus.
pub const BITRATE: u32 = 500_000;
/// Heartbeat of the boards (written by the master when it configures them).
pub const BOARD_HB: Duration = Duration::from_millis(20);
/// Heartbeat consumer time of the pair supervision: a board silent this long has failed.
pub const CONSUMER: Duration = Duration::from_millis(50);
/// Heartbeat of the masters.
pub const MASTER_HB: Duration = Duration::from_millis(20);
/// A standby master takes over when the active one has been silent this long.
pub const MASTER_TIMEOUT: Duration = Duration::from_millis(50);
/// SYNC (the interlocking cycle).
pub const SYNC: Duration = Duration::from_millis(20);
/// The CiA 302-2 multiple-master detect cycle (0x1F90 sub 6 default): the bound for two active
/// masters after a healed partition.
pub const DETECT_CYCLE: Duration = Duration::from_millis(4000);
/// The port silence limit of the dual-bus layer (3 heartbeat periods).
pub const SILENCE_LIMIT: Duration = Duration::from_millis(3 * 20);
/// While a pair slot is vacant, the active master asks this often whether a board without
/// node-ID is on the bus (LSS identify non-configured remote slave).
pub const LSS_PERIOD: Duration = Duration::from_millis(250);
/// The serial number of the spare board that replaces the dead one (the station's boards have
/// 0x1000 + node-ID).
pub const SPARE_SERIAL: u32 = 0x0002_6001;

/// The racks, in printing order.
pub const TURNOUT: usize = 0;
/// The signal rack.
pub const SIGNAL: usize = 1;
/// The track-circuit rack.
pub const TRACK: usize = 2;
/// The misc rack (level crossings).
pub const MISC: usize = 3;

/// Board pairs per rack: point machines, signals, track circuits, level crossings.
pub const PAIRS: [usize; 4] = [10, 10, 12, 4];

/// The pair whose active board is killed (P2 on the turnout rack).
pub const KILLED_PAIR: usize = 1;

/// Route setting: one route every second from 2 s to 17 s.
const ROUTES_FROM: u64 = 2_000;
const ROUTES_UNTIL: u64 = 17_000;
/// The end of the day.
pub const END: Instant = Instant::from_millis(18_000);

/// One fault or repair of the script.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Act {
    /// A bus of a rack cut.
    BusCut {
        /// Rack.
        rack: usize,
        /// 0 = bus 1.
        bus: usize,
    },
    /// The bus works again.
    BusRestored {
        /// Rack.
        rack: usize,
        /// 0 = bus 1.
        bus: usize,
    },
    /// The active board of a pair loses power.
    BoardKilled {
        /// Rack.
        rack: usize,
        /// Pair.
        pair: usize,
    },
    /// That board is replaced by a spare from the shelf, powered on without node-ID.
    BoardReplaced {
        /// Rack.
        rack: usize,
        /// Pair.
        pair: usize,
    },
    /// A computer loses power (on every rack).
    MasterKilled(usize),
    /// It is powered on again.
    MasterBack(usize),
    /// Both buses of a rack split: the weak master alone on one side.
    Partition {
        /// Rack.
        rack: usize,
    },
    /// The buses are joined again.
    Healed {
        /// Rack.
        rack: usize,
    },
    /// A maintainer's hand-over: bus `repaired` works again and, in the same instant, the other
    /// bus of the rack is cut (no overlap: one bus works at every instant).
    HandOver {
        /// Rack.
        rack: usize,
        /// The bus repaired (0 = bus 1); the other is cut.
        repaired: usize,
    },
    /// The active board of a pair stops running by itself (its application, or its CiA 301
    /// error behaviour, puts it in `state`) and goes on beating, saying so.
    BoardStops {
        /// Rack.
        rack: usize,
        /// Pair.
        pair: usize,
        /// Pre-operational or stopped.
        state: NmtState,
    },
}

/// The pair whose active board stops by itself (T9 on the track-circuit rack, 10 ms before a
/// train enters it).
pub const STOPPED_PAIR: usize = 8;

/// The scripted day. Some faults come just before a command to the device they hit (P2 at
/// 7.0 s, a signal at 8.45 s, a level crossing at 14.0 s) or a train on the track circuit (T9
/// at 9.7 s), so that commands and state changes meet failovers. The turnout rack's buses are
/// handed over while points are thrown (3.0 to 6.0 s): bus 2 cut, then repaired in the instant
/// bus 1 is cut, then bus 1 repaired.
pub const SCRIPT: [(Instant, Act); 12] = [
    (
        Instant::from_millis(2_600),
        Act::BusCut {
            rack: TURNOUT,
            bus: 1,
        },
    ),
    (
        Instant::from_millis(4_250),
        Act::BusCut {
            rack: SIGNAL,
            bus: 0,
        },
    ),
    (
        Instant::from_millis(4_600),
        Act::HandOver {
            rack: TURNOUT,
            repaired: 1,
        },
    ),
    (
        Instant::from_millis(6_200),
        Act::BusRestored {
            rack: TURNOUT,
            bus: 0,
        },
    ),
    (
        Instant::from_millis(6_980),
        Act::BoardKilled {
            rack: TURNOUT,
            pair: KILLED_PAIR,
        },
    ),
    (Instant::from_millis(8_430), Act::MasterKilled(STRONG)),
    (
        Instant::from_millis(9_690),
        Act::BoardStops {
            rack: TRACK,
            pair: STOPPED_PAIR,
            state: NmtState::PreOperational,
        },
    ),
    (
        Instant::from_millis(10_400),
        Act::BusRestored {
            rack: SIGNAL,
            bus: 0,
        },
    ),
    (
        Instant::from_millis(11_300),
        Act::BoardReplaced {
            rack: TURNOUT,
            pair: KILLED_PAIR,
        },
    ),
    (Instant::from_millis(12_300), Act::MasterBack(STRONG)),
    (Instant::from_millis(13_980), Act::Partition { rack: MISC }),
    (Instant::from_millis(15_600), Act::Healed { rack: MISC }),
];

/// What the script did, when (which board, for a kill).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Happened {
    /// When.
    pub at: Instant,
    /// What.
    pub act: Act,
    /// The board killed or brought back.
    pub member: Option<Member>,
}

/// The station after its day.
pub struct Station {
    /// The simulated network (trace, devices, events).
    pub sim: SimNetwork,
    /// Turnout, signal, track-circuit and misc racks.
    pub racks: Vec<Rc<dyn RackView>>,
    /// The script as it ran.
    pub happened: Vec<Happened>,
    /// The device descriptions the boards and masters were built from.
    pub devices: Devices,
}

/// The route schedule: per rack, the commands of the day in time order.
fn schedules() -> [Vec<Route>; 4] {
    let mut s: [Vec<Route>; 4] = Default::default();
    let mut points = [PointPosition::Normal as u8; PAIRS[TURNOUT]];
    let [np, ns, _, nx] = PAIRS;
    let ms = Instant::from_millis;
    let mut r = 0usize;
    loop {
        let t0 = ROUTES_FROM + 1000 * r as u64;
        if t0 >= ROUTES_UNTIL {
            break;
        }
        // Two points thrown for the route, the level crossing closed, then the signal cleared
        // and put back to stop behind the train, the crossing opened.
        for k in [2 * r % np, (2 * r + 1) % np] {
            points[k] = if points[k] == PointPosition::Normal as u8 {
                PointPosition::Reverse as u8
            } else {
                PointPosition::Normal as u8
            };
            s[TURNOUT].push(Route {
                at: ms(t0),
                pair: k,
                code: points[k],
            });
        }
        s[MISC].push(Route {
            at: ms(t0),
            pair: r % nx,
            code: BARRIERS_DOWN,
        });
        let aspect = if r.is_multiple_of(2) {
            SignalAspect::Proceed
        } else {
            SignalAspect::Caution
        };
        s[SIGNAL].push(Route {
            at: ms(t0 + 450),
            pair: r % ns,
            code: aspect as u8,
        });
        s[SIGNAL].push(Route {
            at: ms(t0 + 850),
            pair: r % ns,
            code: SignalAspect::Stop as u8,
        });
        s[MISC].push(Route {
            at: ms(t0 + 800),
            pair: r % nx,
            code: BARRIERS_UP,
        });
        r += 1;
    }
    for v in &mut s {
        v.sort_by_key(|x| x.at);
    }
    s
}

/// Reads the device descriptions, builds the station, runs the scripted day on it, and
/// returns it; an error if a description cannot be read.
pub fn run() -> Result<Station, EdsError> {
    run_with(|_, _| {})
}

/// [`run`], with `extra` faults injected before the day starts (for tests that check that the
/// analysis sees what goes wrong).
pub fn run_with(
    extra: impl FnOnce(&mut SimNetwork, &[Rc<dyn RackView>]),
) -> Result<Station, EdsError> {
    let devices = Devices::load()?;
    let mut sim = SimNetwork::new(2026);
    let [turnout, signal, track, misc] = schedules().map(Rc::new);
    let fields = |kind: Kind, n: usize| (0..n).map(|_| Field::new(kind)).collect::<Vec<_>>();
    let nodes = |pairs: usize| {
        let mut v = vec![master_node(STRONG), master_node(WEAK)];
        for p in 0..pairs {
            v.extend([board_node(p, Member::A), board_node(p, Member::B)]);
        }
        v
    };
    let racks: Vec<Rc<dyn RackView>> = vec![
        Rack::build(
            &mut sim,
            RackSpec {
                name: "turnout rack",
                short: "turnout",
                kind: Kind::Point,
                scheme: Predefined,
                pairs: PAIRS[TURNOUT],
                eds: devices.board.clone(),
                dcf: devices.racks[TURNOUT].clone(),
                schedule: turnout,
            },
            fields(Kind::Point, PAIRS[TURNOUT]),
        ),
        Rack::build(
            &mut sim,
            RackSpec {
                name: "signal rack",
                short: "signal",
                kind: Kind::Signal,
                scheme: scheme::railway_profile(2, nodes(PAIRS[SIGNAL])),
                pairs: PAIRS[SIGNAL],
                eds: devices.board.clone(),
                dcf: devices.racks[SIGNAL].clone(),
                schedule: signal,
            },
            fields(Kind::Signal, PAIRS[SIGNAL]),
        ),
        Rack::build(
            &mut sim,
            RackSpec {
                name: "track-circuit rack",
                short: "track",
                kind: Kind::Track,
                scheme: scheme::railway_profile(3, nodes(PAIRS[TRACK])),
                pairs: PAIRS[TRACK],
                eds: devices.board.clone(),
                dcf: devices.racks[TRACK].clone(),
                schedule: track,
            },
            fields(Kind::Track, PAIRS[TRACK]),
        ),
        Rack::build(
            &mut sim,
            RackSpec {
                name: "misc rack",
                short: "misc",
                kind: Kind::Crossing,
                scheme: Predefined,
                pairs: PAIRS[MISC],
                eds: devices.board.clone(),
                dcf: devices.racks[MISC].clone(),
                schedule: misc,
            },
            fields(Kind::Crossing, PAIRS[MISC]),
        ),
    ];
    // Trains: each route's train occupies two track circuits in turn.
    let mut r = 0u64;
    while ROUTES_FROM + 1000 * r < ROUTES_UNTIL {
        let t0 = ROUTES_FROM + 1000 * r;
        let n = PAIRS[TRACK] as u64;
        let (first, second) = ((r % n) as usize, ((r + 1) % n) as usize);
        let t = &racks[TRACK];
        let at = |ms: u64| Instant::from_millis(t0 + ms);
        t.field_set(first, at(500), TrackCircuit::Occupied as u8);
        t.field_set(second, at(700), TrackCircuit::Occupied as u8);
        t.field_set(first, at(900), TrackCircuit::Clear as u8);
        t.field_set(second, at(1_100), TrackCircuit::Clear as u8);
        r += 1;
    }
    let happened = Rc::new(RefCell::new(Vec::new()));
    for (at, act) in SCRIPT {
        let racks = racks.clone();
        let log = happened.clone();
        sim.at(at, move |sim| {
            let member = apply(sim, &racks, at, act);
            log.borrow_mut().push(Happened { at, act, member });
        });
    }
    extra(&mut sim, &racks);
    sim.run_until(END);
    let happened = happened.borrow().clone();
    Ok(Station {
        sim,
        racks,
        happened,
        devices,
    })
}

/// The board running a pair's field device now (the active member).
fn running(sim: &SimNetwork, rack: &Rc<dyn RackView>, pair: usize) -> Option<Member> {
    [Member::A, Member::B]
        .into_iter()
        .find(|m| rack.board_state(sim, pair, *m) == NmtState::Operational)
}

/// Carries out one act of the script.
fn apply(
    sim: &mut SimNetwork,
    racks: &[Rc<dyn RackView>],
    at: Instant,
    act: Act,
) -> Option<Member> {
    match act {
        Act::BusCut { rack, bus } => sim.bus_down(racks[rack].buses()[bus]),
        Act::BusRestored { rack, bus } => sim.bus_up(racks[rack].buses()[bus]),
        Act::BoardKilled { rack, pair } => {
            let m = running(sim, &racks[rack], pair)?;
            sim.power_off(racks[rack].board_dev(pair, m));
            return Some(m);
        }
        Act::HandOver { rack, repaired } => {
            let buses = racks[rack].buses();
            sim.bus_up(buses[repaired]);
            sim.bus_down(buses[1 - repaired]);
        }
        Act::BoardStops { rack, pair, state } => {
            let m = running(sim, &racks[rack], pair)?;
            racks[rack].stop_board(sim, pair, m, state, at);
            return Some(m);
        }
        Act::BoardReplaced { rack, pair } => {
            let r = &racks[rack];
            let m = [Member::A, Member::B]
                .into_iter()
                .find(|m| !sim.is_powered(r.board_dev(pair, *m)))?;
            r.plug_spare(sim, pair, m, SPARE_SERIAL, at);
            return Some(m);
        }
        Act::MasterKilled(w) => {
            for r in racks {
                sim.power_off(r.master_dev(w));
            }
        }
        Act::MasterBack(w) => {
            for r in racks {
                r.revive_master(sim, w, at);
            }
        }
        Act::Partition { rack } => {
            let r = &racks[rack];
            for (i, bus) in r.buses().into_iter().enumerate() {
                sim.partition(bus, &[&[r.master_dev(WEAK).port(i)]]);
            }
        }
        Act::Healed { rack } => {
            for bus in racks[rack].buses() {
                sim.heal(bus);
            }
        }
    }
    None
}
