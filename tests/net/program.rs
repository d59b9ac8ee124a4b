//! Program download through a remote node (`download_program`): an image larger than one
//! whole transfer of the network streams to the node's store and runs; a store that refuses
//! it leaves the node on its program.

use duocan::cia302::program::{FlashError, ProgramDictionary, ProgramStore};
use duocan::master::ProgramStep;
use duocan::net::{NetError, NetOptions, Network, MAX_TRANSFER};
use duocan::port::mem::MemBus;
use duocan::runtime::Runtime;
use duocan::sdo::SdoServerConfig;
use duocan::{Node, NodeConfig, NodeId};
use std::time::Duration;

/// A store keeping the length and byte sum of the image as its identification; refuses
/// images that start with 0xFF.
#[derive(Default)]
struct Sum {
    running: u32,
    staged: Option<u32>,
}

fn sum(image: &[u8]) -> u32 {
    image
        .iter()
        .fold(image.len() as u32, |s, b| s.wrapping_add(u32::from(*b)))
}

impl ProgramStore for Sum {
    fn capacity(&self) -> u32 {
        256 * 1024
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
        self.staged = Some(sum(image));
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

#[tokio::test(start_paused = true)]
async fn an_image_streams_to_the_node_and_runs_and_a_refused_one_leaves_it_as_it_was() {
    let bus = MemBus::new("mem");
    let opts = NetOptions::default().with_sdo_timeout(Duration::from_millis(300));
    let net = Network::open_with(bus.port(), opts).unwrap();
    let base = duocan::od::comm::standard_dictionary(4, Default::default());
    let od = ProgramDictionary::new(base, Sum::default());
    let mut n = Node::new(NodeConfig::slave(NodeId::must(4)), od);
    n.sdo_server_mut()
        .set_config(SdoServerConfig::default().with_max_transfer(256 * 1024));
    n.boot(duocan::Instant::ZERO);
    let s = Runtime::new(duocan::Station::single(n))
        .port(bus.port())
        .spawn()
        .unwrap();

    let image: Vec<u8> = (0..MAX_TRANSFER * 2).map(|i| (i % 251) as u8).collect();
    let mut done = Vec::new();
    let node = net.node(4);
    let report = node
        .download_program(&image, |p| done.push(p.done))
        .await
        .unwrap();
    assert_eq!(report.bytes, image.len());
    assert_eq!(report.identification, sum(&image));
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
    assert_eq!(id, sum(&image), "still the program downloaded before");
    net.close().await;
    s.shutdown().await;
}
