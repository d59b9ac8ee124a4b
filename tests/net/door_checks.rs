//! Checks of the front door written once and run on every door: here on one port, and in the
//! redundancy crate's tests (which include this file) over the dual link and over the
//! redundant master. The door is written once above its core, so the same checks must pass.

use duocan::cia302::program::{image_id, FlashError, RamStore};
use duocan::master::ProgramStep;
use duocan::net::{sim_description, AnyValue, NetError, Network, MAX_TRANSFER};
use duocan::net::{SIM_DEVICE_NAME, SIM_HEARTBEAT_MS, SIM_VENDOR};
use duocan::od::DataType;

/// The store behind the checked node: in RAM, refusing images that start with 0xFF (as a
/// device refuses a damaged image).
pub fn store() -> RamStore {
    RamStore::new(STORE as u32).verifying(|image| match image.first() {
        Some(0xFF) => Err(FlashError::DataFormatError),
        _ => Ok(()),
    })
}

/// What the store takes, and the node's SDO server with it.
pub const STORE: usize = 256 * 1024;

/// Node `id` (a [`store`] behind it): an image larger than one whole transfer of the
/// network streams to the node's store and runs; a store that refuses an image leaves the node
/// on its program.
pub async fn program_download(net: &Network, id: u8) {
    let image: Vec<u8> = (0..MAX_TRANSFER * 2).map(|i| (i % 251) as u8).collect();
    let mut done = Vec::new();
    let node = net.node(id);
    let report = node
        .download_program(&image, |p| done.push(p.done))
        .await
        .unwrap();
    assert_eq!(report.bytes, image.len());
    assert_eq!(report.identification, image_id(&image));
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
    assert_eq!(id, image_id(&image), "still the program downloaded before");
}

/// Node 5 (duocan's simulated dictionary) by name with its description: names resolve by
/// name, address and case, the values are typed by the description, and a wrong type is
/// refused before anything is sent.
pub async fn names_resolve(net: &Network) {
    let node = net.add_node(5, sim_description().unwrap());
    let sdo = node.sdo();
    for name in [
        "Producer heartbeat time",
        "producer HEARTBEAT time",
        "0x1017",
        "1017sub0",
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
    // A later handle from the network carries the description too.
    let again = net.node(5);
    assert_eq!(
        again.sdo().read_named::<u32>("Vendor-ID").await.unwrap(),
        SIM_VENDOR
    );
    // Dynamic: typed by the description.
    assert_eq!(
        sdo.read_value("Producer heartbeat time").await.unwrap(),
        AnyValue::Unsigned(300)
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
