//! 0x1010 store parameters, 0x1011 restore default parameters, and what each NMT reset
//! reloads: the power-on image (what the application configured before boot), then what was
//! stored. Every command goes over the bus as an SDO expedited download, so the answers are the
//! frames a client sees.

use duocan::node::{NodeEventKind as K, StorageAction, Writer};
use duocan::od::parameters::{
    ImageError, MemoryStorage, MemoryStorageError, ParameterGroup, ParameterStorage, StorageError,
    StoredDictionary,
};
use duocan::od::{comm, Access, DynamicDictionary, ObjectDef, ObjectDictionary, StaticDictionary};
use duocan::{AbortCode, Frame, Id, Instant, Machine, NmtState, Node, NodeConfig, NodeId};
use std::fmt;

pub const ID: NodeId = NodeId::must(5);
/// Manufacturer-specific area (0x2000–0x5FFF): stored by "all" and by sub-index 4.
pub const MANUFACTURER: u16 = 0x2000;
/// Standardised profile area (0x6000–0x9FFF): the application group.
pub const APPLICATION: u16 = 0x6000;
pub const SAVE: &[u8] = b"save";
pub const LOAD: &[u8] = b"load";

/// A medium whose next operations can be made to fail.
#[derive(Default)]
pub struct Flaky {
    pub memory: MemoryStorage<4096>,
    pub fail: bool,
}

#[derive(Debug)]
pub enum FlakyError {
    Injected,
    Memory(MemoryStorageError),
}

impl fmt::Display for FlakyError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FlakyError::Injected => f.write_str("injected medium failure"),
            FlakyError::Memory(e) => e.fmt(f),
        }
    }
}
impl std::error::Error for FlakyError {}

impl ParameterStorage for Flaky {
    type Error = FlakyError;
    fn load(&mut self, buf: &mut [u8]) -> Result<Option<usize>, FlakyError> {
        self.memory.load(buf).map_err(FlakyError::Memory)
    }
    fn store(&mut self, image: &[u8]) -> Result<(), FlakyError> {
        if self.fail {
            return Err(FlakyError::Injected);
        }
        self.memory.store(image).map_err(FlakyError::Memory)
    }
    fn erase(&mut self) -> Result<(), FlakyError> {
        if self.fail {
            return Err(FlakyError::Injected);
        }
        self.memory.erase().map_err(FlakyError::Memory)
    }
}

pub type Od = StoredDictionary<DynamicDictionary, Flaky, 4096>;
pub type Slave = Node<Od>;

pub fn ms(v: u64) -> Instant {
    Instant::from_millis(v)
}

/// The dictionary a board's firmware builds: the communication objects with 0x1010/0x1011,
/// one manufacturer-specific and one profile entry.
fn dictionary() -> DynamicDictionary {
    let mut od = comm::standard_dictionary(ID.raw(), comm::Identity::default());
    od.insert(ObjectDef::u32(MANUFACTURER, 0, Access::Rw, 7))
        .unwrap();
    od.insert(ObjectDef::u16(APPLICATION, 0, Access::Rw, 1))
        .unwrap();
    od
}

/// A slave whose application configures it before boot (the power-on image: heartbeat
/// 1000 ms, 0x2000 = 20, 0x6000 = 10) on `medium`, booted at 0.
pub fn slave(medium: Flaky) -> Slave {
    let od = StoredDictionary::new(dictionary(), medium);
    let mut node = Node::new(NodeConfig::slave(ID), od);
    node.set(ms(0), comm::HEARTBEAT_PRODUCER, 0, 1000u16)
        .unwrap();
    node.set(ms(0), MANUFACTURER, 0, 20u32).unwrap();
    node.set(ms(0), APPLICATION, 0, 10u16).unwrap();
    node.boot(ms(0));
    drain(&mut node);
    node
}

fn drain<M: Machine>(node: &mut M) -> Vec<Frame> {
    std::iter::from_fn(|| node.poll_transmit()).collect()
}

fn events<M: Machine>(node: &mut M) -> Vec<M::Event> {
    std::iter::from_fn(|| node.poll_event()).collect()
}

/// An SDO expedited download from a client: the server's answer as the client reads it.
pub fn sdo_write<M: Machine>(
    node: &mut M,
    now: Instant,
    index: u16,
    sub: u8,
    data: &[u8],
) -> Result<(), AbortCode> {
    let n = data.len();
    assert!((1..=4).contains(&n));
    let mut req = [0u8; 8];
    req[0] = 0x23 | (((4 - n) as u8) << 2);
    req[1..3].copy_from_slice(&index.to_le_bytes());
    req[3] = sub;
    req[4..4 + n].copy_from_slice(data);
    node.handle_frame(
        now,
        &Frame::from_array(Id::Standard(0x600 + ID.raw() as u16), req),
    );
    let answer = drain(node)
        .into_iter()
        .find(|f| f.id() == Id::Standard(0x580 + ID.raw() as u16))
        .expect("the server answers");
    let d = answer.data();
    assert_eq!(&d[1..4], &req[1..4], "the answer names the entry");
    match d[0] {
        0x60 => Ok(()),
        0x80 => Err(AbortCode(u32::from_le_bytes([d[4], d[5], d[6], d[7]]))),
        other => panic!("not a download answer: {other:#04x}"),
    }
}

/// An SDO expedited upload of a 32-bit entry.
fn sdo_read_u32<M: Machine>(node: &mut M, now: Instant, index: u16, sub: u8) -> u32 {
    let mut req = [0u8; 8];
    req[0] = 0x40;
    req[1..3].copy_from_slice(&index.to_le_bytes());
    req[3] = sub;
    node.handle_frame(now, &Frame::from_array(Id::Standard(0x605), req));
    let answer = drain(node)
        .into_iter()
        .find(|f| f.id() == Id::Standard(0x585))
        .expect("the server answers");
    let d = answer.data();
    assert_eq!(d[0], 0x43, "a four-byte expedited upload: {d:02x?}");
    u32::from_le_bytes([d[4], d[5], d[6], d[7]])
}

pub fn nmt<M: Machine>(node: &mut M, now: Instant, cmd: u8) {
    node.handle_frame(now, &Frame::from_array(Id::Standard(0), [cmd, ID.raw()]));
}
pub const RESET_NODE: u8 = 0x81;
pub const RESET_COMMUNICATION: u8 = 0x82;

/// (0x1017, 0x2000, 0x6000) as the dictionary holds them.
pub fn values(node: &Slave) -> (u16, u32, u16) {
    let od = node.od();
    (
        od.get_value(comm::HEARTBEAT_PRODUCER, 0).unwrap(),
        od.get_value(MANUFACTURER, 0).unwrap(),
        od.get_value(APPLICATION, 0).unwrap(),
    )
}

/// Writes 0x1017 = 500, 0x2000 = 21, 0x6000 = 11 over SDO.
fn reconfigure(node: &mut Slave, now: Instant) {
    sdo_write(
        node,
        now,
        comm::HEARTBEAT_PRODUCER,
        0,
        &500u16.to_le_bytes(),
    )
    .unwrap();
    sdo_write(node, now, MANUFACTURER, 0, &21u32.to_le_bytes()).unwrap();
    sdo_write(node, now, APPLICATION, 0, &11u16.to_le_bytes()).unwrap();
    assert_eq!(values(node), (500, 21, 11));
}

pub const POWER_ON: (u16, u32, u16) = (1000, 20, 10);

/// A slave on an empty medium, reconfigured over SDO at 1 ms.
fn reconfigured() -> Slave {
    let mut node = slave(Flaky::default());
    reconfigure(&mut node, ms(1));
    node
}

/// The heartbeat instants in `frames`, sent by the node at `times`.
fn heartbeats(log: &[(Instant, Frame)]) -> Vec<(Instant, u8)> {
    log.iter()
        .filter(|(_, f)| f.id() == Id::Standard(0x705))
        .map(|(t, f)| (*t, f.data()[0]))
        .collect()
}

/// Runs the node's timers up to `until`, recording what it sends.
fn run<M: Machine>(node: &mut M, log: &mut Vec<(Instant, Frame)>, until: Instant) {
    while let Some(t) = node.poll_timeout().filter(|t| *t <= until) {
        node.handle_timeout(t);
        log.extend(drain(node).into_iter().map(|f| (t, f)));
    }
}

#[test]
fn the_configuration_given_before_boot_survives_both_resets() {
    // The case, without any medium: a standard dictionary and a static one.
    fn check<D: ObjectDictionary>(mut node: Node<D>) {
        node.set(ms(0), comm::HEARTBEAT_PRODUCER, 0, 1000u16)
            .unwrap();
        node.boot(ms(0));
        let mut log: Vec<(Instant, Frame)> =
            drain(&mut node).into_iter().map(|f| (ms(0), f)).collect();
        nmt(&mut node, ms(10), RESET_COMMUNICATION);
        log.extend(drain(&mut node).into_iter().map(|f| (ms(10), f)));
        assert_eq!(
            node.od().get_value::<u16>(comm::HEARTBEAT_PRODUCER, 0),
            Ok(1000)
        );
        run(&mut node, &mut log, ms(2500));
        nmt(&mut node, ms(2500), RESET_NODE);
        log.extend(drain(&mut node).into_iter().map(|f| (ms(2500), f)));
        run(&mut node, &mut log, ms(4000));
        // Boot-ups at 0, 10 and 2500 ms; the 1000 ms heartbeat after each, never silent.
        assert_eq!(
            heartbeats(&log),
            [
                (ms(0), 0x00),
                (ms(10), 0x00),
                (ms(1010), 0x7F),
                (ms(2010), 0x7F),
                (ms(2500), 0x00),
                (ms(3500), 0x7F)
            ]
        );
    }
    let od = comm::standard_dictionary(ID.raw(), comm::Identity::default());
    check(Node::new(NodeConfig::slave(ID), od));
    static COMM: [ObjectDef; comm::COMM_LEN] = comm::communication();
    let mut od = StaticDictionary::<32, 256>::new();
    od.load(ID.raw(), &[&COMM]).unwrap();
    check(Node::new(NodeConfig::slave(ID), od));
}

#[test]
fn sdo_writes_are_volatile_until_stored() {
    let mut node = reconfigured();
    // Reset-communication reloads the communication area only.
    nmt(&mut node, ms(2), RESET_COMMUNICATION);
    assert_eq!(values(&node), (1000, 21, 11));
    // Reset-node reloads everything.
    nmt(&mut node, ms(3), RESET_NODE);
    assert_eq!(values(&node), POWER_ON);
    assert!(node.od().storage().memory.image().is_none());
}

#[test]
fn each_group_stores_its_area_and_the_resets_reload_it() {
    for group in ParameterGroup::ALL {
        let mut node = slave(Flaky::default());
        reconfigure(&mut node, ms(1));
        sdo_write(&mut node, ms(2), comm::STORE_PARAMETERS, group.sub(), SAVE).unwrap();
        assert!(events(&mut node).iter().any(|e| e.kind
            == K::ParametersStored {
                group,
                by: Writer::Sdo
            }));
        // What reset-node gives: stored values in the group, power-on values elsewhere.
        let pick = |index: u16, stored: u32, power_on: u32| {
            if group.contains(index) {
                stored
            } else {
                power_on
            }
        };
        let expected: (u16, u32, u16) = (
            pick(comm::HEARTBEAT_PRODUCER, 500, 1000) as u16,
            pick(MANUFACTURER, 21, 20),
            pick(APPLICATION, 11, 10) as u16,
        );
        nmt(&mut node, ms(3), RESET_NODE);
        assert_eq!(values(&node), expected, "{group}");
        // Reset-communication reloads the communication area from the same image.
        sdo_write(
            &mut node,
            ms(4),
            comm::HEARTBEAT_PRODUCER,
            0,
            &700u16.to_le_bytes(),
        )
        .unwrap();
        nmt(&mut node, ms(5), RESET_COMMUNICATION);
        assert_eq!(values(&node).0, expected.0, "{group}");
        // A power cycle: the firmware configures a new node on the same medium.
        let medium = std::mem::take(node.od_mut().storage_mut());
        let node = slave(medium);
        assert_eq!(values(&node), expected, "{group} after a power cycle");
    }
}

#[test]
fn restored_defaults_take_effect_at_the_next_reset_of_the_group() {
    let mut node = reconfigured();
    sdo_write(&mut node, ms(1), comm::STORE_PARAMETERS, 1, SAVE).unwrap();
    // Communication defaults: not at once, at the next reset-communication.
    sdo_write(&mut node, ms(2), comm::RESTORE_DEFAULTS, 2, LOAD).unwrap();
    assert!(events(&mut node).iter().any(|e| e.kind
        == K::DefaultsRestored {
            group: ParameterGroup::Communication,
            by: Writer::Sdo
        }));
    assert_eq!(values(&node), (500, 21, 11), "nothing changes at once");
    nmt(&mut node, ms(3), RESET_COMMUNICATION);
    assert_eq!(values(&node), (1000, 21, 11));
    // The rest of "all" is still stored.
    nmt(&mut node, ms(4), RESET_NODE);
    assert_eq!(values(&node), (1000, 21, 11));
    // Application defaults: reset-communication does not reload that area, reset-node does.
    sdo_write(&mut node, ms(5), comm::RESTORE_DEFAULTS, 3, LOAD).unwrap();
    nmt(&mut node, ms(6), RESET_COMMUNICATION);
    assert_eq!(values(&node), (1000, 21, 11));
    nmt(&mut node, ms(7), RESET_NODE);
    assert_eq!(values(&node), (1000, 21, 10));
    // Manufacturer defaults, the last stored group: the medium is erased.
    sdo_write(&mut node, ms(8), comm::RESTORE_DEFAULTS, 4, LOAD).unwrap();
    assert!(node.od().storage().memory.image().is_none());
    nmt(&mut node, ms(9), RESET_NODE);
    assert_eq!(values(&node), POWER_ON);
    // Restoring everything at once.
    reconfigure(&mut node, ms(10));
    sdo_write(&mut node, ms(10), comm::STORE_PARAMETERS, 1, SAVE).unwrap();
    sdo_write(&mut node, ms(11), comm::RESTORE_DEFAULTS, 1, LOAD).unwrap();
    assert!(node.od().storage().memory.image().is_none());
    assert_eq!(values(&node), (500, 21, 11), "nothing changes at once");
    nmt(&mut node, ms(12), RESET_NODE);
    assert_eq!(values(&node), POWER_ON);
}

#[test]
fn a_wrong_signature_is_refused_with_0x08000020_and_nothing_is_stored() {
    let mut node = reconfigured();
    let refused = Err(AbortCode::CANNOT_STORE);
    assert_eq!(
        sdo_write(&mut node, ms(2), comm::STORE_PARAMETERS, 1, b"savf"),
        refused
    );
    assert_eq!(
        sdo_write(&mut node, ms(2), comm::STORE_PARAMETERS, 2, LOAD),
        refused
    );
    assert_eq!(
        sdo_write(&mut node, ms(2), comm::RESTORE_DEFAULTS, 2, SAVE),
        refused
    );
    // "save" read as a big-endian number is not the signature either.
    assert_eq!(
        sdo_write(&mut node, ms(2), comm::STORE_PARAMETERS, 1, b"evas"),
        refused
    );
    assert_eq!(
        sdo_write(&mut node, ms(2), comm::STORE_PARAMETERS, 1, &b"save"[..2]),
        Err(AbortCode::LENGTH_TOO_LOW)
    );
    assert_eq!(
        sdo_write(&mut node, ms(2), comm::STORE_PARAMETERS, 0, &[4]),
        Err(AbortCode::READ_ONLY)
    );
    assert_eq!(node.od().storage().memory.stores(), 0);
    // The entry still reads as the capability: writes never land in it.
    assert_eq!(sdo_read_u32(&mut node, ms(3), comm::STORE_PARAMETERS, 1), 1);
    nmt(&mut node, ms(4), RESET_NODE);
    assert_eq!(values(&node), POWER_ON);
}

#[test]
fn a_failed_store_aborts_with_0x06060000_and_the_previous_image_survives() {
    let mut node = reconfigured();
    sdo_write(&mut node, ms(1), comm::STORE_PARAMETERS, 2, SAVE).unwrap();
    let before = node.od().storage().memory.image().unwrap().to_vec();
    events(&mut node);
    // A new value, then a medium that refuses to write.
    sdo_write(
        &mut node,
        ms(2),
        comm::HEARTBEAT_PRODUCER,
        0,
        &700u16.to_le_bytes(),
    )
    .unwrap();
    node.od_mut().storage_mut().fail = true;
    assert_eq!(
        sdo_write(&mut node, ms(3), comm::STORE_PARAMETERS, 1, SAVE),
        Err(AbortCode::HARDWARE_ERROR)
    );
    assert!(events(&mut node).iter().any(|e| e.kind
        == K::StorageFailed {
            action: StorageAction::Store(ParameterGroup::All),
            error: StorageError::Medium
        }));
    assert_eq!(
        node.od().last_error().map(ToString::to_string).as_deref(),
        Some("injected medium failure")
    );
    assert_eq!(
        sdo_write(&mut node, ms(3), comm::RESTORE_DEFAULTS, 2, LOAD),
        Err(AbortCode::HARDWARE_ERROR)
    );
    assert_eq!(node.od().storage().memory.image(), Some(&before[..]));
    // Nothing half-written: the resets reload the image of the successful store.
    node.od_mut().storage_mut().fail = false;
    nmt(&mut node, ms(4), RESET_NODE);
    assert_eq!(values(&node), (500, 20, 10));
}

#[test]
fn the_reads_give_the_capability_bits() {
    let mut node = slave(Flaky::default());
    for index in [comm::STORE_PARAMETERS, comm::RESTORE_DEFAULTS] {
        for sub in 1..=4 {
            assert_eq!(
                sdo_read_u32(&mut node, ms(1), index, sub),
                1,
                "{index:#x} {sub}"
            );
        }
    }
    // Without a medium: nothing is stored on command, and "save" cannot be stored.
    let od = comm::standard_dictionary(ID.raw(), comm::Identity::default());
    let mut plain = Node::new(NodeConfig::slave(ID), od);
    plain.boot(ms(0));
    drain(&mut plain);
    assert_eq!(
        sdo_read_u32(&mut plain, ms(1), comm::STORE_PARAMETERS, 1),
        0
    );
    assert_eq!(
        sdo_read_u32(&mut plain, ms(1), comm::RESTORE_DEFAULTS, 2),
        0
    );
    assert_eq!(
        sdo_write(&mut plain, ms(1), comm::STORE_PARAMETERS, 1, SAVE),
        Err(AbortCode::CANNOT_STORE)
    );
    assert_eq!(
        plain.store_parameters(ms(1), ParameterGroup::All),
        Err(StorageError::Unsupported)
    );
}

#[test]
fn the_application_stores_and_restores_without_the_bus() {
    let mut node = slave(Flaky::default());
    node.set(ms(1), comm::HEARTBEAT_PRODUCER, 0, 300u16)
        .unwrap();
    node.store_parameters(ms(1), ParameterGroup::Communication)
        .unwrap();
    assert!(events(&mut node).iter().any(|e| e.kind
        == K::ParametersStored {
            group: ParameterGroup::Communication,
            by: Writer::Local
        }));
    nmt(&mut node, ms(2), RESET_COMMUNICATION);
    assert_eq!(values(&node).0, 300);
    node.restore_defaults(ms(3), ParameterGroup::All).unwrap();
    nmt(&mut node, ms(4), RESET_COMMUNICATION);
    assert_eq!(values(&node).0, 1000);
    // A configuration the application makes after boot becomes the power-on image on request.
    node.set(ms(5), comm::HEARTBEAT_PRODUCER, 0, 250u16)
        .unwrap();
    node.capture_power_on(ms(5)).unwrap();
    nmt(&mut node, ms(6), RESET_NODE);
    assert_eq!(values(&node).0, 250);
}

#[test]
fn an_unreadable_image_leaves_the_power_on_values_and_says_so() {
    let mut medium = Flaky::default();
    {
        let mut node = slave(Flaky::default());
        reconfigure(&mut node, ms(1));
        sdo_write(&mut node, ms(1), comm::STORE_PARAMETERS, 1, SAVE).unwrap();
        let mut torn = node.od().storage().memory.image().unwrap().to_vec();
        // A torn write: the last bytes never reached the medium.
        torn.truncate(torn.len() - 3);
        medium.memory.store(&torn).unwrap();
    }
    let od = StoredDictionary::new(dictionary(), medium);
    let mut node: Slave = Node::new(NodeConfig::slave(ID), od);
    node.set(ms(0), comm::HEARTBEAT_PRODUCER, 0, 1000u16)
        .unwrap();
    node.boot(ms(0));
    let failed: Vec<_> = events(&mut node)
        .into_iter()
        .filter_map(|e| match e.kind {
            K::StorageFailed { action, error } => Some((action, error)),
            _ => None,
        })
        .collect();
    assert!(
        matches!(
            failed[..],
            [(
                StorageAction::Load,
                StorageError::Corrupt(ImageError::Crc { .. })
            )]
        ),
        "{failed:?}"
    );
    assert_eq!(values(&node), (1000, 7, 1));
    assert_eq!(node.nmt_state(), NmtState::PreOperational);
    // Storing again replaces the unreadable image.
    sdo_write(&mut node, ms(1), comm::STORE_PARAMETERS, 2, SAVE).unwrap();
    nmt(&mut node, ms(2), RESET_NODE);
    assert!(!events(&mut node)
        .iter()
        .any(|e| matches!(e.kind, K::StorageFailed { .. })));
}

#[test]
fn stored_values_that_no_longer_fit_the_dictionary_are_skipped_and_counted() {
    let mut node = reconfigured();
    sdo_write(&mut node, ms(1), comm::STORE_PARAMETERS, 1, SAVE).unwrap();
    let medium = std::mem::take(node.od_mut().storage_mut());
    // A firmware update: 0x2000 is gone, 0x6000 refuses 11 now.
    let mut od = comm::standard_dictionary(ID.raw(), comm::Identity::default());
    od.insert(ObjectDef::u16(APPLICATION, 0, Access::Rw, 1).limits(
        duocan::od::Limit::Unsigned(0),
        duocan::od::Limit::Unsigned(10),
    ))
    .unwrap();
    let mut node = Node::new(
        NodeConfig::slave(ID),
        StoredDictionary::<_, _, 4096>::new(od, medium),
    );
    node.boot(ms(0));
    let loaded: Vec<_> = events(&mut node)
        .into_iter()
        .filter_map(|e| match e.kind {
            K::ParametersLoaded(r) => Some((r.applied, r.skipped)),
            _ => None,
        })
        .collect();
    // 0x2000 and 0x6000 skipped; the communication parameters (0x1017 among them) applied.
    assert!(
        matches!(loaded[..], [(applied, 2)] if applied > 0),
        "{loaded:?}"
    );
    assert_eq!(
        node.od().get_value::<u16>(comm::HEARTBEAT_PRODUCER, 0),
        Ok(500)
    );
    assert_eq!(node.od().get_value::<u16>(APPLICATION, 0), Ok(1));
}

/// A static-dictionary slave with `P` bytes of power-on image, configured before boot with a
/// producer time (a 7-byte record) and one consumer (9 bytes), booted at 0.
fn static_slave<const P: usize>() -> Node<StaticDictionary<32, 256, P>> {
    static COMM: [ObjectDef; comm::COMM_LEN] = comm::communication();
    static HB: [ObjectDef; 5] = comm::heartbeat_consumers::<5>();
    let mut od = StaticDictionary::<32, 256, P>::new();
    od.load(ID.raw(), &[&COMM, &HB]).unwrap();
    let mut node = Node::new(NodeConfig::slave(ID), od);
    node.set(ms(0), comm::HEARTBEAT_PRODUCER, 0, 1000u16)
        .unwrap();
    node.set(ms(0), comm::HEARTBEAT_CONSUMER, 1, (1u32 << 16) | 300)
        .unwrap();
    node.boot(ms(0));
    node
}

#[test]
fn a_static_dictionary_without_room_for_the_power_on_image_says_so() {
    // Eight bytes: the producer time would fit, both records do not.
    let mut node = static_slave::<8>();
    assert!(events(&mut node).iter().any(|e| e.kind
        == K::StorageFailed {
            action: StorageAction::CapturePowerOn,
            error: StorageError::TooLarge {
                needed: 7 + 9,
                capacity: 8
            }
        }));
    assert_eq!(node.od().power_on_used(), 0, "all or nothing");
    // With room, the same configuration is kept.
    let mut node = static_slave::<16>();
    assert_eq!(node.od().power_on_used(), 16);
    nmt(&mut node, ms(1), RESET_NODE);
    assert_eq!(
        node.od().get_value::<u16>(comm::HEARTBEAT_PRODUCER, 0),
        Ok(1000)
    );
    assert_eq!(
        node.od().get_value::<u32>(comm::HEARTBEAT_CONSUMER, 1),
        Ok((1 << 16) | 300)
    );
}
