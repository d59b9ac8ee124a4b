//! Program download (CiA 302-3) and by-name SDO through both doors, to a node on both buses
//! that takes program download and carries duocan's simulated dictionary: an image larger than
//! one whole transfer streams to its store and runs, a refused one leaves the node on its
//! program; names resolve by the description, are typed by it and written back.

use crate::doors::{on_both, open, BOTH};
use duocan::cia302::program::{FlashError, ProgramDictionary, ProgramStore};
use duocan::master::ProgramStep;
use duocan::net::{sim_description, sim_dictionary, AnyValue, NetError, Network, MAX_TRANSFER};
use duocan::net::{SIM_DEVICE_NAME, SIM_HEARTBEAT_MS, SIM_VENDOR};
use duocan::od::DataType;
use duocan::od::DynamicDictionary;
use duocan::port::mem::MemBus;
use duocan::runtime::Handle;
use duocan::sdo::SdoServerConfig;
use duocan::{Instant, Node, NodeConfig, NodeId, Station};
use duocan_redundancy::net::sim_program_id;
use duocan_redundancy::DualBus;

/// A store keeping the identification of what it staged; refuses an image that starts with
/// 0xFF.
#[derive(Default)]
struct Store {
    running: u32,
    staged: Option<u32>,
}

impl ProgramStore for Store {
    fn capacity(&self) -> u32 {
        4 * MAX_TRANSFER as u32
    }
    fn stop(&mut self) {}
    fn run(&mut self) {}
    fn clear(&mut self) -> Result<(), FlashError> {
        self.staged = None;
        Ok(())
    }
    fn stage(&mut self, image: &[u8]) -> Result<(), FlashError> {
        if image.first() == Some(&0xFF) {
            return Err(FlashError::DataFormatError);
        }
        self.staged = Some(sim_program_id(image));
        Ok(())
    }
    fn activate(&mut self) -> Result<(), FlashError> {
        self.running = self.staged.take().ok_or(FlashError::NoValidProgram)?;
        Ok(())
    }
    fn identification(&self) -> u32 {
        self.running
    }
}

/// Node 5 on both buses: the simulated dictionary with program download, taking transfers as
/// large as its store.
fn program_node(
    buses: &[MemBus; 2],
) -> Handle<Station<DualBus, Node<ProgramDictionary<DynamicDictionary, Store>>>> {
    let id = NodeId::must(5);
    let od = ProgramDictionary::new(sim_dictionary(id), Store::default());
    let mut n = Node::new(NodeConfig::slave(id), od);
    n.sdo_server_mut()
        .set_config(SdoServerConfig::default().with_max_transfer(4 * MAX_TRANSFER));
    n.boot(Instant::ZERO);
    on_both(n, buses)
}

async fn an_image_streams_and_runs_and_a_refused_one_leaves_it(net: &Network) {
    let image: Vec<u8> = (0..MAX_TRANSFER * 2).map(|i| (i % 251) as u8).collect();
    let mut done = Vec::new();
    let node = net.node(5);
    let report = node
        .download_program(&image, |p| done.push(p.done))
        .await
        .unwrap();
    assert_eq!(report.bytes, image.len());
    assert_eq!(report.identification, sim_program_id(&image));
    assert_eq!(done.last(), Some(&(image.len() as u64)));
    assert!(done.windows(2).all(|w| w[0] <= w[1]));

    let mut bad = image.clone();
    bad[0] = 0xFF;
    let e = node.download_program(&bad, |_| {}).await.unwrap_err();
    let NetError::Program(pe) = &e else {
        panic!("{e}")
    };
    assert_eq!(pe.step, ProgramStep::Download);
    assert!(pe.resumed, "reset to the program it had: {e}");
    assert!(e.abort_code().is_some(), "{e}");
    let id: u32 = node.sdo().read(0x1F56, 1).await.unwrap();
    assert_eq!(
        id,
        sim_program_id(&image),
        "still the program downloaded before"
    );
}

async fn names_resolve_and_type_the_values(net: &Network) {
    let node = net.add_node(5, sim_description().unwrap());
    let sdo = node.sdo();
    for name in [
        "Producer heartbeat time",
        "producer HEARTBEAT time",
        "0x1017",
    ] {
        assert_eq!(
            sdo.read_named::<u16>(name).await.unwrap(),
            SIM_HEARTBEAT_MS,
            "{name}"
        );
    }
    sdo.write_named("Producer heartbeat time", 300u16)
        .await
        .unwrap();
    assert_eq!(sdo.read::<u16>(0x1017, 0).await.unwrap(), 300);
    assert_eq!(
        net.node(5)
            .sdo()
            .read_named::<u32>("Vendor-ID")
            .await
            .unwrap(),
        SIM_VENDOR
    );
    assert_eq!(
        sdo.read_value("Manufacturer device name").await.unwrap(),
        AnyValue::Text(SIM_DEVICE_NAME.into())
    );
    sdo.write_value("Input 2", -7i16).await.unwrap();
    assert_eq!(
        sdo.read_value("Input 2").await.unwrap(),
        AnyValue::Signed(-7)
    );
    assert_eq!(sdo.read::<i16>(0x6000, 2).await.unwrap(), -7);
    // The wrong type is refused by the description, before anything is sent.
    let e = sdo
        .read_named::<u32>("Producer heartbeat time")
        .await
        .unwrap_err();
    assert!(
        matches!(
            &e,
            NetError::WrongType {
                data_type: DataType::Unsigned16,
                ..
            }
        ),
        "{e:?}"
    );
}

#[tokio::test(start_paused = true)]
async fn program_download_and_names_through_both_doors() {
    for door in BOTH {
        let buses = [MemBus::new("bus1"), MemBus::new("bus2")];
        let net = open(door, &buses).await;
        let node = program_node(&buses);
        an_image_streams_and_runs_and_a_refused_one_leaves_it(&net).await;
        names_resolve_and_type_the_values(&net).await;
        net.close().await;
        node.shutdown().await;
    }
}
