//! The runtime on the in-memory bus: async SDO through the handle against duocan's own server,
//! every transfer mode, errors, and transfers to several nodes at once.

use crate::rt::{master, pattern, sdo_error, sdo_node, single};
use duocan::port::mem::MemBus;
use duocan::runtime::Runtime;
use duocan::sdo::{SdoErrorKind, SdoOptions, TransferMode};
use duocan::{AbortCode, NodeId};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sdo_through_the_handle_every_mode() {
    let bus = MemBus::new("mem");
    let m = Runtime::new(master(1, &[]))
        .port(bus.port())
        .spawn()
        .unwrap();
    let s5 = Runtime::new(single(sdo_node(5, false, 0, &[])))
        .port(bus.port())
        .spawn()
        .unwrap();
    let s6 = Runtime::new(single(sdo_node(6, false, 0, &[])))
        .port(bus.port())
        .spawn()
        .unwrap();
    m.boot().await.unwrap();
    s5.boot().await.unwrap();
    s6.boot().await.unwrap();
    let n5 = NodeId::new(5).unwrap();
    let n6 = NodeId::new(6).unwrap();
    let o = SdoOptions::default;

    // Expedited read and write.
    let v = m.sdo_read(n5, 0x2000, 0, o()).await.unwrap();
    assert_eq!(v, 0xCAFE_F00Du32.to_le_bytes());
    m.sdo_write(n5, 0x2000, 0, 7u32.to_le_bytes().to_vec(), o())
        .await
        .unwrap();
    assert_eq!(s5.read(0x2000, 0).await.unwrap(), 7u32.to_le_bytes());

    // Segmented both ways.
    let text = m.sdo_read(n5, 0x2001, 0, o()).await.unwrap();
    assert_eq!(text, b"duocan node over a real bus");
    let long = b"written by the master over segmented SDO".to_vec();
    m.sdo_write(
        n5,
        0x2001,
        0,
        long.clone(),
        SdoOptions::mode(TransferMode::Segmented),
    )
    .await
    .unwrap();
    assert_eq!(s5.read(0x2001, 0).await.unwrap(), long);

    // Block both ways, to two nodes at once.
    let a = pattern(3000, 1);
    let b = pattern(2500, 2);
    let (ra, rb) = tokio::join!(
        m.sdo_write(
            n5,
            0x2002,
            0,
            a.clone(),
            SdoOptions::mode(TransferMode::Block)
        ),
        m.sdo_write(
            n6,
            0x2002,
            0,
            b.clone(),
            SdoOptions::mode(TransferMode::Block)
        ),
    );
    ra.unwrap();
    rb.unwrap();
    let (ra, rb) = tokio::join!(
        m.sdo_read(n5, 0x2002, 0, SdoOptions::mode(TransferMode::Block)),
        m.sdo_read(n6, 0x2002, 0, SdoOptions::mode(TransferMode::Block)),
    );
    assert_eq!(ra.unwrap(), a);
    assert_eq!(rb.unwrap(), b);

    // Errors come back as values: a missing object, a read-only one, a node that is not there.
    let e = sdo_error(m.sdo_read(n5, 0x2100, 0, o()).await);
    assert_eq!(e.kind, SdoErrorKind::Server(AbortCode::NO_OBJECT));
    let e = sdo_error(m.sdo_write(n5, 0x1000, 0, vec![1, 2, 3, 4], o()).await);
    assert!(matches!(e.kind, SdoErrorKind::Server(_)), "{e}");
    let mut quick = o();
    quick.timeout = duocan::Duration::from_millis(100);
    let e = sdo_error(m.sdo_read(NodeId::new(9).unwrap(), 0x1000, 0, quick).await);
    assert_eq!(e.kind, SdoErrorKind::Client(AbortCode::TIMEOUT));
    // Immediate refusals do not wait: expedited mode cannot carry 5 bytes.
    let e = sdo_error(
        m.sdo_write(
            n5,
            0x2002,
            0,
            vec![0; 5],
            SdoOptions::mode(TransferMode::Expedited),
        )
        .await,
    );
    assert_eq!(e.kind, SdoErrorKind::TransferMode);
}
