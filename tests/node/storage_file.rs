//! The file medium on a real directory: atomic replacement, failures that leave the previous
//! image, bounded reads, and a node that keeps its stored parameters across a power cycle.

use duocan::od::parameters::{
    FileStorage, FileStorageOp, ParameterGroup, ParameterStorage, StoredDictionary,
};
use duocan::od::{comm, DynamicDictionary, ObjectDictionary};
use duocan::{AbortCode, Frame, Id, Instant, Machine, Node, NodeConfig, NodeId};
use std::fs;
use std::path::PathBuf;

/// A fresh directory under the system's temporary one, removed when dropped.
struct TempDir(PathBuf);

impl TempDir {
    fn new(name: &str) -> TempDir {
        let dir =
            std::env::temp_dir().join(format!("duocan-storage-{}-{name}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).unwrap();
        TempDir(dir)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = fs::remove_dir_all(&self.0);
    }
}

#[test]
fn images_are_replaced_whole_and_erased() {
    let dir = TempDir::new("roundtrip");
    let mut f = FileStorage::new(dir.0.join("params.bin"));
    let mut buf = [0u8; 64];
    assert_eq!(f.load(&mut buf).unwrap(), None, "nothing stored yet");
    f.store(b"first image").unwrap();
    assert_eq!(f.load(&mut buf).unwrap(), Some(11));
    assert_eq!(&buf[..11], b"first image");
    f.store(b"second").unwrap();
    assert_eq!(f.load(&mut buf).unwrap(), Some(6));
    assert_eq!(&buf[..6], b"second");
    assert!(!f.temp_path().exists(), "the temporary file was renamed");
    f.erase().unwrap();
    assert_eq!(f.load(&mut buf).unwrap(), None);
    f.erase().unwrap();
}

#[test]
fn a_failed_store_leaves_the_previous_image_and_no_temporary_file() {
    let dir = TempDir::new("fail");
    let mut f = FileStorage::new(dir.0.join("params.bin"));
    f.store(b"good image").unwrap();
    // The temporary file cannot be created: a directory is in its way (this fails for root
    // too, where a read-only directory would not).
    fs::create_dir(f.temp_path()).unwrap();
    let e = f.store(b"new image").unwrap_err();
    assert_eq!(e.op, FileStorageOp::Create);
    assert_eq!(e.path, f.temp_path());
    assert!(
        e.to_string()
            .starts_with("parameter storage: cannot create"),
        "{e}"
    );
    assert!(
        std::error::Error::source(&e).is_some(),
        "the system's reason"
    );
    let mut buf = [0u8; 64];
    assert_eq!(f.load(&mut buf).unwrap(), Some(10));
    assert_eq!(&buf[..10], b"good image");
    fs::remove_dir(f.temp_path()).unwrap();

    // The rename cannot replace the target: the temporary file is cleaned up.
    let mut g = FileStorage::new(dir.0.join("taken"));
    fs::create_dir(g.path()).unwrap();
    fs::write(g.path().join("occupant"), b"x").unwrap();
    let e = g.store(b"image").unwrap_err();
    assert_eq!(e.op, FileStorageOp::Rename);
    assert!(!g.temp_path().exists());
}

#[test]
fn reads_are_bounded_by_the_buffer() {
    let dir = TempDir::new("bounded");
    let mut f = FileStorage::new(dir.0.join("params.bin"));
    fs::write(f.path(), [7u8; 100]).unwrap();
    let mut buf = [0u8; 99];
    let e = f.load(&mut buf).unwrap_err();
    assert_eq!(e.op, FileStorageOp::TooLarge { capacity: 99 });
    let mut buf = [0u8; 100];
    assert_eq!(f.load(&mut buf).unwrap(), Some(100));
}

type Od = StoredDictionary<DynamicDictionary, FileStorage, 4096>;

fn board(path: PathBuf) -> Node<Od> {
    let id = NodeId::must(5);
    let od = comm::standard_dictionary(id.raw(), comm::Identity::default());
    let mut node = Node::new(
        NodeConfig::slave(id),
        StoredDictionary::new(od, FileStorage::new(path)),
    );
    node.set(Instant::ZERO, comm::HEARTBEAT_PRODUCER, 0, 1000u16)
        .unwrap();
    node.boot(Instant::ZERO);
    while node.poll_transmit().is_some() {}
    node
}

/// "save" to 0x1010 sub 2 over SDO; the abort code if refused.
fn save_communication(node: &mut Node<Od>) -> Result<(), AbortCode> {
    let req = [0x23, 0x10, 0x10, 0x02, b's', b'a', b'v', b'e'];
    node.handle_frame(Instant::ZERO, &Frame::from_array(Id::Standard(0x605), req));
    let answer = std::iter::from_fn(|| node.poll_transmit())
        .find(|f| f.id() == Id::Standard(0x585))
        .unwrap();
    match answer.data()[0] {
        0x60 => Ok(()),
        _ => {
            let d = answer.data();
            Err(AbortCode(u32::from_le_bytes([d[4], d[5], d[6], d[7]])))
        }
    }
}

#[test]
fn a_node_keeps_what_it_stored_in_its_file_across_a_power_cycle() {
    let dir = TempDir::new("node");
    let path = dir.0.join("node5.params");
    let mut node = board(path.clone());
    node.set(Instant::ZERO, comm::HEARTBEAT_PRODUCER, 0, 250u16)
        .unwrap();
    save_communication(&mut node).unwrap();
    assert!(path.exists());
    drop(node);
    let node = board(path.clone());
    assert_eq!(
        node.od().get_value::<u16>(comm::HEARTBEAT_PRODUCER, 0),
        Ok(250)
    );

    // The medium fails: the client is told (0x06060000), the file keeps the stored image.
    let before = fs::read(&path).unwrap();
    let mut node = board(path.clone());
    node.set(Instant::ZERO, comm::HEARTBEAT_PRODUCER, 0, 400u16)
        .unwrap();
    let temp = node.od().storage().temp_path().to_path_buf();
    fs::create_dir(&temp).unwrap();
    assert_eq!(
        save_communication(&mut node),
        Err(AbortCode::HARDWARE_ERROR)
    );
    assert_eq!(
        node.od().last_error().map(|e| e.op),
        Some(FileStorageOp::Create)
    );
    assert_eq!(fs::read(&path).unwrap(), before);
    fs::remove_dir(&temp).unwrap();
    let node = board(path.clone());
    assert_eq!(
        node.od().get_value::<u16>(comm::HEARTBEAT_PRODUCER, 0),
        Ok(250)
    );
    // Restoring the defaults erases the file; the next boot has the application's 1000 ms.
    let mut node = board(path.clone());
    node.restore_defaults(Instant::ZERO, ParameterGroup::All)
        .unwrap();
    assert!(!path.exists());
    assert_eq!(
        node.store_parameters(Instant::ZERO, ParameterGroup::Communication),
        Ok(())
    );
    assert!(path.exists());
    node.restore_defaults(Instant::ZERO, ParameterGroup::Communication)
        .unwrap();
    let node = board(path);
    assert_eq!(
        node.od().get_value::<u16>(comm::HEARTBEAT_PRODUCER, 0),
        Ok(1000)
    );
}
