//! By-name access with a device description: names resolve, types are checked, wrong ones
//! are errors naming node, name and what to do.

use duocan::eds::{Description, ImportOptions, LookupErrorKind};
use duocan::net::{sim_description, NetError, NetOptions, Network, SIM_HEARTBEAT_MS};
use duocan::od::DataType;
use std::time::Duration;

fn quick() -> NetOptions {
    NetOptions::default().with_sdo_timeout(Duration::from_millis(200))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn names_resolve_by_name_address_and_case() {
    let net = Network::simulated([5], quick()).unwrap();
    crate::door_checks::names_resolve(&net).await;
    net.close().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn wrong_type_unknown_and_ambiguous_names_are_errors() {
    let net = Network::simulated([5], quick()).unwrap();
    let bare = net.node(5);
    let e = bare.sdo().read_named::<u16>("0x1017").await.unwrap_err();
    assert_eq!(
        e,
        NetError::NoDescription {
            node: duocan::NodeId::must(5)
        }
    );
    assert!(e.to_string().contains("add_node(5"), "{e}");

    let node = bare.with_description(sim_description().unwrap());
    let sdo = node.sdo();
    let e = sdo
        .read_named::<u32>("Producer heartbeat time")
        .await
        .unwrap_err();
    match &e {
        NetError::WrongType {
            data_type,
            asked,
            index,
            ..
        } => {
            assert_eq!(
                (*data_type, *asked, *index),
                (DataType::Unsigned16, DataType::Unsigned32, 0x1017)
            );
        }
        other => panic!("{other:?}"),
    }
    let msg = e.to_string();
    assert!(
        msg.contains("node 5") && msg.contains("UNSIGNED16") && msg.contains("use u16"),
        "{msg}"
    );

    let e = sdo
        .read_named::<u16>("Producer heartbeat")
        .await
        .unwrap_err();
    assert!(matches!(&e, NetError::Name { error, .. } if error.kind == LookupErrorKind::NotFound));
    assert!(e.to_string().contains("\"Producer heartbeat\""), "{e}");

    // Every PDO mapping record has entries named "Application object".
    let e = sdo.read_value("Application object").await.unwrap_err();
    match &e {
        NetError::Name { error, .. } => {
            assert!(matches!(error.kind, LookupErrorKind::Ambiguous { .. }))
        }
        other => panic!("{other:?}"),
    }
    assert!(e.to_string().contains("by its address"), "{e}");

    // A value outside the entry's type is refused before anything is sent.
    let e = sdo.write_value("Status", 256u16).await.unwrap_err();
    assert!(matches!(e, NetError::BadValue { .. }), "{e:?}");
    assert!(e.to_string().contains("UNSIGNED8"), "{e}");
    net.close().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_description_from_an_eds_file() {
    let dir = std::env::temp_dir().join(format!("duocan-named-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("sensor.eds");
    std::fs::write(
        &path,
        "[1017]\nParameterName=Producer heartbeat time\nDataType=0x0006\nAccessType=rw\n\
         [MandatoryObjects]\nSupportedObjects=1\n1=0x1017\n",
    )
    .unwrap();
    let net = Network::simulated([6], quick()).unwrap();
    let node = net.add_node_eds(6, &path).unwrap();
    assert_eq!(
        node.sdo()
            .read_named::<u16>("Producer Heartbeat Time")
            .await
            .unwrap(),
        SIM_HEARTBEAT_MS
    );
    let e = net.add_node_eds(6, dir.join("missing.eds")).err().unwrap();
    assert!(matches!(e, NetError::Eds(_)), "{e:?}");
    let parsed = Description::parse(b"[1017]\n", "x.eds", &ImportOptions::lenient()).unwrap();
    assert!(net.node(7).with_description(parsed).description().is_some());
    std::fs::remove_dir_all(&dir).ok();
    net.close().await;
}
