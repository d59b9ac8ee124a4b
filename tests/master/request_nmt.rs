//! Request NMT (0x1F82): another node writes the master's 0x1F82 sub n over SDO to have it send
//! an NMT command to node n (sub 128: all), and reads it for node n's state.

use crate::net::*;
use duocan::machine::{CompositeEvent, StationEvent};
use duocan::master::objects::{request, REQUEST_ALL, REQUEST_NMT};
use duocan::master::{BootPhase, MasterConfig, MasterEventKind as K, SlaveConfig};
use duocan::sdo::{SdoClient, SdoError, SdoErrorKind, SdoOptions, TransferBuffer};
use duocan::sim::DevId;
use duocan::{AbortCode, Duration, Instant, NmtCommand, NmtState, NmtTarget, NodeId};

const BITRATE: u32 = 500_000;

struct Rig {
    n: Net,
    tool: DevId<Tool>,
}

fn rig(config: MasterConfig) -> Rig {
    let (n, tool) = with_tool(BITRATE, config, 64);
    Rig { n, tool }
}

fn network() -> MasterConfig {
    let mut net = MasterConfig::new();
    for id in [2, 3] {
        net = net.slave(
            SlaveConfig::new(NodeId::must(id))
                .identity(expected(id))
                .heartbeat(20, 60)
                .write_u16(APP, 1, 0x55),
        );
    }
    net
}

impl Rig {
    /// Runs one SDO request of the tool to the master until its result.
    fn sdo(
        &mut self,
        start: impl FnOnce(&mut SdoClient, Instant) -> Result<duocan::sdo::RequestId, SdoError>,
    ) -> Result<Vec<u8>, SdoError> {
        let now = self.n.sim.now();
        let id = start(&mut self.n.sim.device_mut(self.tool).machine.b, now).unwrap();
        loop {
            self.n.sim.step().expect("idle without a result");
            for (_, e) in self.n.sim.take_events(self.tool) {
                if let StationEvent::Machine(CompositeEvent::B(e)) = e {
                    assert_eq!(e.request, id);
                    return e.result.map(|b| b.as_slice().to_vec());
                }
            }
        }
    }

    fn write(&mut self, sub: u8, value: u8) -> Result<(), SdoError> {
        self.sdo(|c, now| {
            c.download(
                now,
                MASTER_ID,
                REQUEST_NMT,
                sub,
                &[value],
                SdoOptions::default(),
            )
        })
        .map(|_| ())
    }

    fn read(&mut self, sub: u8) -> u8 {
        let v = self
            .sdo(|c, now| c.upload(now, MASTER_ID, REQUEST_NMT, sub, SdoOptions::default()))
            .unwrap();
        assert_eq!(v.len(), 1);
        v[0]
    }

    fn run_for(&mut self, ms: u64) {
        self.n.sim.run_for(Duration::from_millis(ms));
    }

    fn requests(&self) -> Vec<(NmtTarget, NmtCommand, bool)> {
        all(&self.n.events(), |k| match k {
            K::NmtRequest { target, cmd, sent } => Some((*target, *cmd, *sent)),
            _ => None,
        })
        .into_iter()
        .map(|(_, r)| r)
        .collect()
    }
}

#[test]
fn another_node_resets_a_slave_through_the_master_and_it_comes_back_configured() {
    let mut r = rig(network());
    assert_eq!(r.read(3), request::START);
    assert_eq!(r.read(50), request::UNKNOWN);
    let t = r.n.sim.now();
    r.write(3, request::RESET_NODE).unwrap();
    // The master's answer to the write follows its NMT command on the bus.
    let t_req = r.n.sim.now();
    r.run_for(50);
    assert_eq!(
        r.requests(),
        [(
            NmtTarget::Node(NodeId::must(3)),
            NmtCommand::ResetNode,
            true
        )]
    );
    // The master sent reset node to 3 right after the write; 3 rebooted, was configured
    // again (its application entry was reset) and started.
    let resets: Vec<_> = nmt_frames(&r.n.sim)
        .into_iter()
        .filter(|(at, cs, node)| *at > t && (*cs, *node) == (0x81, 3))
        .collect();
    assert_eq!(resets.len(), 1);
    assert!(resets[0].0 > t && resets[0].0 < t_req);
    let started = all(&r.n.events(), |k| match k {
        K::SlaveStarted { node, .. } if node.raw() == 3 => Some(()),
        _ => None,
    });
    let back = started.last().unwrap().0;
    assert!(back > t_req && back - t < Duration::from_millis(6));
    println!(
        "node 0x7E writes 0x1F82 sub 3 = 6 at {:.3} ms: reset node 3 on the bus at {:.3} ms, write confirmed at {:.3} ms, slave 3 started again at {:.3} ms",
        ms(t),
        ms(resets[0].0),
        ms(t_req),
        ms(back)
    );
    assert_eq!(r.n.slave(3).nmt_state(), NmtState::Operational);
    assert_eq!(r.n.m().slave(NodeId::must(3)).boot_ups, 2);
    assert_eq!(r.read(3), request::START);
}

#[test]
fn all_nodes_stopped_and_one_started_the_reads_follow() {
    let mut r = rig(network());
    r.write(REQUEST_ALL, request::STOP).unwrap();
    r.run_for(100);
    for id in [2, 3] {
        assert_eq!(r.n.slave(id).nmt_state(), NmtState::Stopped);
        assert_eq!(r.read(id), request::STOP);
    }
    // The tool itself obeyed the broadcast too (it is a plain slave).
    assert_eq!(
        r.n.sim.device(r.tool).machine.a.nmt_state(),
        NmtState::Stopped
    );
    // Its SDO client is a machine of its own, and the master does not obey NMT: asking goes on.
    r.write(2, request::START).unwrap();
    r.write(3, request::PRE_OPERATIONAL).unwrap();
    r.run_for(100);
    assert_eq!(r.n.slave(2).nmt_state(), NmtState::Operational);
    assert_eq!(r.n.slave(3).nmt_state(), NmtState::PreOperational);
    assert_eq!(r.read(2), request::START);
    assert_eq!(r.read(3), request::PRE_OPERATIONAL);
    assert_eq!(
        r.requests(),
        [
            (NmtTarget::All, NmtCommand::Stop, true),
            (NmtTarget::Node(NodeId::must(2)), NmtCommand::Start, true),
            (
                NmtTarget::Node(NodeId::must(3)),
                NmtCommand::EnterPreOperational,
                true
            ),
        ]
    );
    assert_eq!(r.read(REQUEST_ALL), request::UNKNOWN);
    // The master's own node kept running.
    assert_eq!(r.n.m().node().nmt_state(), NmtState::Operational);
}

#[test]
fn undefined_request_values_are_refused_with_an_abort() {
    let mut r = rig(network());
    for v in [0u8, 1, 2, 3, 8, 128] {
        let e = r.write(2, v).unwrap_err();
        assert_eq!(e.kind, SdoErrorKind::Server(AbortCode::VALUE_RANGE), "{v}");
    }
    let e = r.write(0, request::START).unwrap_err();
    assert_eq!(e.kind, SdoErrorKind::Server(AbortCode::READ_ONLY));
    assert!(r.requests().is_empty());
    assert_eq!(r.read(2), request::START);
}

#[test]
fn a_standby_master_does_not_send_the_requested_command() {
    let mut r = rig(network().standby());
    let before = nmt_frames(&r.n.sim).len();
    r.write(2, request::RESET_NODE).unwrap();
    r.run_for(100);
    assert_eq!(
        r.requests(),
        [(
            NmtTarget::Node(NodeId::must(2)),
            NmtCommand::ResetNode,
            false
        )]
    );
    assert_eq!(nmt_frames(&r.n.sim).len(), before);
    assert_eq!(r.n.m().slave(NodeId::must(2)).phase, BootPhase::Observed);
}
