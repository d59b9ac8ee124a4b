//! Property tests: every codec round-trips, and no sequence of frames makes a node panic, grow,
//! or leave a consistent state.

use duocan::emcy::EmcyMessage;
use duocan::heartbeat::ConsumerSetting;
use duocan::nmt::{self, NmtCommand, NmtState, NmtTarget};
use duocan::od::{comm, ObjectDictionary};
use duocan::time_stamp::TimeOfDay;
use duocan::{CobId, Duration, Frame, Id, Instant, Machine, NodeId};
use proptest::prelude::*;

fn any_id() -> impl Strategy<Value = Id> {
    prop_oneof![
        4 => (0u16..=0x7FF).prop_map(Id::Standard),
        // Weight the identifiers the stack actually decodes.
        4 => prop_oneof![Just(0u16), Just(0x80), Just(0x100), 0x81u16..0x100, 0x701u16..0x780, 0x581u16..0x680].prop_map(Id::Standard),
        1 => (0u32..=0x1FFF_FFFF).prop_map(Id::Extended),
    ]
}

fn any_frame() -> impl Strategy<Value = Frame> {
    (
        any_id(),
        any::<bool>(),
        proptest::collection::vec(any::<u8>(), 0..=8),
    )
        .prop_map(|(id, rtr, d)| {
            if rtr {
                Frame::remote(id, d.len() as u8).unwrap()
            } else {
                Frame::new(id, &d).unwrap()
            }
        })
}

fn any_state() -> impl Strategy<Value = NmtState> {
    prop_oneof![
        Just(NmtState::Initialising),
        Just(NmtState::Stopped),
        Just(NmtState::Operational),
        Just(NmtState::PreOperational)
    ]
}

fn any_cmd() -> impl Strategy<Value = NmtCommand> {
    prop_oneof![
        Just(NmtCommand::Start),
        Just(NmtCommand::Stop),
        Just(NmtCommand::EnterPreOperational),
        Just(NmtCommand::ResetNode),
        Just(NmtCommand::ResetCommunication)
    ]
}

proptest! {
    #[test]
    fn nmt_command_round_trip(cmd in any_cmd(), node in 0u8..=127) {
        let target = NodeId::new(node).map_or(NmtTarget::All, NmtTarget::Node);
        let f = nmt::command_frame(Id::Standard(0), cmd, target);
        prop_assert_eq!(nmt::parse_command(&f), Ok((cmd, node)));
    }

    #[test]
    fn error_control_round_trip(state in any_state(), toggle in any::<bool>()) {
        let f = Frame::from_array(Id::Standard(0x701), [state.code() | if toggle { 0x80 } else { 0 }]);
        prop_assert_eq!(nmt::parse_error_control(&f), Ok((state, toggle)));
    }

    #[test]
    fn emcy_round_trip(code in any::<u16>(), register in any::<u8>(), data in any::<[u8; 5]>()) {
        let m = EmcyMessage { code, register, data };
        let f = Frame::from_array(Id::Standard(0x81), m.to_bytes());
        prop_assert_eq!(EmcyMessage::from_frame(&f), Ok(m));
    }

    #[test]
    fn time_of_day_round_trip(days in any::<u16>(), ms in 0u32..86_400_000) {
        let t = TimeOfDay { days, ms };
        prop_assert_eq!(TimeOfDay::from_bytes(&t.to_bytes()), Ok(t));
        prop_assert_eq!(TimeOfDay::from_total_ms(t.total_ms()), t);
    }

    #[test]
    fn consumer_setting_round_trip(node in 1u8..=127, ms in 1u16..) {
        let s = ConsumerSetting { node: NodeId::new(node), time: Duration::from_millis(ms as u64) };
        prop_assert_eq!(ConsumerSetting::from_u32(s.to_u32()), s);
    }

    #[test]
    fn cob_id_round_trip(raw in 0u16..=0x7FF, ext in 0u32..=0x1FFF_FFFF) {
        prop_assert_eq!(CobId::standard(raw).can_id(), Some(Id::Standard(raw)));
        prop_assert_eq!(CobId::extended(ext).can_id(), Some(Id::Extended(ext)));
        prop_assert_eq!(CobId::from_id(Id::Extended(ext)).with_valid(false).with_valid(true), CobId::extended(ext));
    }

    /// Random frames at random times to a master and a slave with every service configured:
    /// nothing panics, queues stay within their capacity, the NMT state is always a real state,
    /// and deadlines never lie in the past after handle_timeout.
    #[test]
    fn random_frames_never_break_a_node(frames in proptest::collection::vec((any_frame(), 0u64..5_000), 1..300)) {
        let mut master = crate::common::node(1, true);
        let mut slave = crate::common::node(5, false);
        let mut now = Instant::ZERO;
        for n in [&mut master, &mut slave] {
            n.boot(now);
            n.set(now, comm::HEARTBEAT_PRODUCER, 0, 10u16).unwrap();
            n.set(now, comm::HEARTBEAT_CONSUMER, 1, (7u32 << 16) | 25).unwrap();
            n.set(now, comm::GUARD_TIME, 0, 10u16).unwrap();
            n.set(now, comm::LIFE_TIME_FACTOR, 0, 2u8).unwrap();
            n.set(now, comm::TIME_COB_ID, 0, 0x8000_0100u32).unwrap();
        }
        master.set(now, comm::SYNC_COB_ID, 0, 0x4000_0080u32).unwrap();
        master.set(now, comm::SYNC_PERIOD, 0, 1_000u32).unwrap();
        master.guard_node(now, NodeId::must(5), Duration::from_millis(10), 3);
        let mut sent = 0usize;
        for (f, dt) in frames {
            now += Duration::from_micros(dt);
            for n in [&mut master, &mut slave] {
                if n.poll_timeout().is_some_and(|t| t <= now) {
                    n.handle_timeout(now);
                    prop_assert!(n.poll_timeout().is_none_or(|t| t > now));
                }
                n.handle_frame(now, &f);
                let mut k = 0;
                while n.poll_transmit().is_some() { k += 1; }
                prop_assert!(k <= duocan::node::TX_QUEUE);
                sent += k;
                let mut e = 0;
                while n.poll_event().is_some() { e += 1; }
                prop_assert!(e <= duocan::node::EVENT_QUEUE);
                prop_assert!(NmtState::from_code(n.nmt_state().code()).is_some());
                prop_assert!(n.od().len() > 100, "dictionary intact");
            }
        }
        prop_assert!(sent > 0);
    }
}
