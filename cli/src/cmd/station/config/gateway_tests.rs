use super::super::{parse, Station};
use super::{Gateway, GATEWAY_MAX_CLIENTS, GATEWAY_SOCKET_MODE};
use std::path::PathBuf;

const NETS: &str = "\n[[network]]\nname = \"a\"\nbuses = \"sim-pairs\"\nnode_id = 1\n\
                    \n[[network]]\nname = \"b\"\nbuses = \"sim-pairs\"\nnode_id = 1\n";

fn station(head: &str, nets: &str) -> Result<Station, String> {
    parse(&format!("[station]\n{head}\n{nets}"), "/etc/duocan/s.toml")
}

fn err(head: &str) -> String {
    match station(head, NETS) {
        Ok(st) => panic!("parsed: {st:?}"),
        Err(e) => e,
    }
}

#[test]
fn a_gateway_on_loopback_and_a_socket_with_the_defaults() {
    let st = station(
        "gateway = \"127.0.0.1:5555\"\ngateway_socket = \"gw.sock\"",
        NETS,
    )
    .unwrap();
    assert_eq!(
        st.gateway,
        Some(Gateway {
            tcp: Some("127.0.0.1:5555".parse().unwrap()),
            // Relative to the file's folder, as the audit folder.
            socket: Some(PathBuf::from("/etc/duocan/gw.sock")),
            socket_mode: GATEWAY_SOCKET_MODE,
            max_clients: GATEWAY_MAX_CLIENTS,
        })
    );
    assert_eq!(GATEWAY_SOCKET_MODE, 0o600);
    // Nets by their place in the file, from 1.
    let nets: Vec<u16> = st.networks.iter().map(|n| n.gateway_net).collect();
    assert_eq!(nets, [1, 2]);
    // Either listener alone; none at all is no gateway.
    let st = station(
        "gateway_socket = \"/run/gw.sock\"\ngateway_socket_mode = 0o660",
        NETS,
    );
    let gw = st.unwrap().gateway.unwrap();
    assert_eq!((gw.tcp, gw.socket_mode), (None, 0o660));
    let st = station("gateway = \"[::1]:0\"\ngateway_max_clients = 2", NETS).unwrap();
    assert_eq!(st.gateway.unwrap().max_clients, 2);
    assert_eq!(station("", NETS).unwrap().gateway, None);
}

#[test]
fn another_machines_address_needs_the_opt_in_key() {
    let e = err("gateway = \"192.168.1.2:5555\"");
    assert!(
        e.starts_with(
            "/etc/duocan/s.toml:2:11: gateway: 192.168.1.2:5555 is reachable from other machines"
        ),
        "{e}"
    );
    assert!(
        e.contains("no authentication") && e.contains("gateway_allow_remote = true"),
        "{e}"
    );
    let st = station(
        "gateway = \"192.168.1.2:5555\"\ngateway_allow_remote = true",
        NETS,
    );
    assert!(st.unwrap().gateway.unwrap().tcp.is_some());
    // `false` is no opt-in.
    let e = err("gateway = \"0.0.0.0:5555\"\ngateway_allow_remote = false");
    assert!(e.starts_with("/etc/duocan/s.toml:2:11: gateway: "), "{e}");
}

#[test]
fn each_bad_gateway_key_is_named_with_what_is_allowed() {
    let e = err("gateway = \"127.0.0.1\"");
    assert!(
        e.starts_with(
            "/etc/duocan/s.toml:2:11: gateway: \"127.0.0.1\" is not an address and port such as"
        ),
        "{e}"
    );
    let e = err("gateway = \"127.0.0.1:5555\"\ngateway_max_clients = 0");
    assert!(
        e.starts_with("/etc/duocan/s.toml:3:23: gateway_max_clients: 1 to 256"),
        "{e}"
    );
    let e = err("gateway_socket = \"gw.sock\"\ngateway_socket_mode = 0o777");
    assert!(
        e.starts_with("/etc/duocan/s.toml:3:23: gateway_socket_mode: 0o777 is not allowed: 0o600"),
        "{e}"
    );
    let e = err("gateway_socket = \" \"");
    assert!(
        e.starts_with("/etc/duocan/s.toml:2:18: gateway_socket: "),
        "{e}"
    );
    let long = format!("gateway_socket = \"/{}\"", "x".repeat(120));
    assert!(err(&long).contains("a socket's path is at most 107"));
    // Settings without a listener: a listener forgotten.
    let e = err("gateway_max_clients = 4");
    assert!(
        e.starts_with(
            "/etc/duocan/s.toml:2:23: gateway_max_clients: set gateway or gateway_socket too"
        ),
        "{e}"
    );
    let e = err("gateway_socket = \"gw.sock\"\ngateway_allow_remote = true");
    assert!(
        e.starts_with("/etc/duocan/s.toml:3:24: gateway_allow_remote: set gateway too"),
        "{e}"
    );
    let e = err("gateway = \"127.0.0.1:1\"\ngateway_socket_mode = 0o600");
    assert!(
        e.starts_with("/etc/duocan/s.toml:3:23: gateway_socket_mode: set gateway_socket too"),
        "{e}"
    );
    // An unknown key lists the known ones.
    let e = err("gateway_port = 5555");
    assert!(e.contains("gateway_socket"), "{e}");
}

#[test]
fn net_numbers_are_distinct_and_in_range() {
    let with = |a: &str, b: &str| {
        NETS.replacen("node_id = 1\n", &format!("node_id = 1\n{a}"), 1)
            .replacen(
                "\"b\"\nbuses = \"sim-pairs\"\nnode_id = 1\n",
                &format!("\"b\"\nbuses = \"sim-pairs\"\nnode_id = 1\n{b}"),
                1,
            )
    };
    let st = station("", &with("gateway_net = 10\n", "gateway_net = 20\n")).unwrap();
    let nets: Vec<u16> = st.networks.iter().map(|n| n.gateway_net).collect();
    assert_eq!(nets, [10, 20]);
    // b is 2 by its place; a took 2 by its key.
    let e = station("", &with("gateway_net = 2\n", "")).unwrap_err();
    assert!(
        e.starts_with(
            "/etc/duocan/s.toml:11:8: gateway_net: network \"b\" is net 2 by its place in the file"
        ),
        "{e}"
    );
    let e = station("", &with("", "gateway_net = 1\n")).unwrap_err();
    assert!(
        e.starts_with("/etc/duocan/s.toml:13:15: gateway_net: net 1 is network \"a\"'s already"),
        "{e}"
    );
    for bad in ["0", "65536", "-1"] {
        let e = station("", &with(&format!("gateway_net = {bad}\n"), "")).unwrap_err();
        assert!(
            e.starts_with(
                "/etc/duocan/s.toml:8:15: gateway_net: a CiA 309-3 net number, 1 to 65535"
            ),
            "{e}"
        );
    }
}
