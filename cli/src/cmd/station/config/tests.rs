use super::*;

const GOOD: &str = r#"
[station]
name = "depot"

[[network]]
name = "rack-1"
buses = "sim-pairs:quiet"
node_id = 1
heartbeat_ms = 50
master_timeout_ms = 150
pairs = [[0x10, 0x50], [0x11, 0x51]]
peers = [{ node = 2, priority = 1 }]
on_stop = "stop"

[[network]]
name = "rack-2"
buses = "vcan0, udp:2"
node_id = 1
"#;

#[test]
fn a_good_file_gives_every_network_with_its_settings() {
    let st = parse(GOOD, "depot.toml").unwrap();
    assert_eq!(st.name, "depot");
    assert_eq!(st.networks.len(), 2);
    let [a, b] = &st.networks[..] else {
        unreachable!()
    };
    assert_eq!(a.name, "rack-1");
    assert_eq!(a.buses, Buses::Sim("sim-pairs:quiet".into()));
    assert_eq!(a.builder.this_node(), 1);
    assert_eq!(a.builder.pairs(), [(0x10, 0x50), (0x11, 0x51)]);
    assert_eq!(a.builder.peers(), [(2, 1)]);
    assert_eq!(a.on_stop, Some(NmtCommand::Stop));
    assert_eq!(b.buses, Buses::Ports(["vcan0".into(), "udp:2".into()]));
    assert_eq!(b.on_stop, None);
}

#[test]
fn the_station_is_named_after_its_file_when_it_does_not_say() {
    let st = parse(
        "[[network]]\nname = \"a\"\nbuses = \"sim-pairs\"\nnode_id = 1\n",
        "/etc/duocan/yard.toml",
    )
    .unwrap();
    assert_eq!(st.name, "yard");
}

/// The error for `text`, which must not parse.
fn err(text: &str) -> String {
    match parse(text, "s.toml") {
        Ok(st) => panic!("parsed: {st:?}"),
        Err(e) => e,
    }
}

const HEAD: &str = "[[network]]\nname = \"a\"\nbuses = \"sim-pairs\"\n";

#[test]
fn each_error_names_the_file_line_column_and_key() {
    // Syntax, by the TOML reader.
    let e = err("[[network]]\nname = \"a\nnode_id = 1\n");
    assert!(e.starts_with("s.toml:2:"), "{e}");
    // An unknown key: the known ones listed.
    let e = err(&format!("{HEAD}node_id = 1\nheartbeat = 50\n"));
    assert!(e.starts_with("s.toml:5:1:"), "{e}");
    assert!(e.contains("heartbeat") && e.contains("heartbeat_ms"), "{e}");
    // A value of the wrong type or out of its range.
    let e = err(&format!("{HEAD}node_id = 300\n"));
    assert!(e.starts_with("s.toml:4:11:"), "{e}");
    // The builder's checks, placed on their key.
    let e = err(&format!("{HEAD}node_id = 0\n"));
    assert!(e.starts_with("s.toml:4:11: node_id: "), "{e}");
    let e = err(&format!(
        "{HEAD}node_id = 1\nheartbeat_ms = 100\nmaster_timeout_ms = 80\n"
    ));
    assert!(e.starts_with("s.toml:6:21: master_timeout_ms: "), "{e}");
    let e = err(&format!("{HEAD}node_id = 1\npairs = [[0x10, 0x10]]\n"));
    assert!(e.starts_with("s.toml:5:9: pairs: "), "{e}");
    let e = err(&format!("{HEAD}node_id = 1\npeers = [{{ node = 1 }}]\n"));
    assert!(e.starts_with("s.toml:5:9: peers: "), "{e}");
    let e = err(&format!("{HEAD}node_id = 1\nsync_ms = 0\n"));
    assert!(e.starts_with("s.toml:5:11: sync_ms: "), "{e}");
    let e = err(&format!("{HEAD}node_id = 1\ntime_ms = 0\n"));
    assert!(e.starts_with("s.toml:5:11: time_ms: "), "{e}");
    // The file's own keys.
    let e = err(&format!("{HEAD}node_id = 1\non_stop = \"halt\"\n"));
    assert!(e.starts_with("s.toml:5:11: on_stop: \"halt\""), "{e}");
    assert!(e.contains("reset-comm"), "{e}");
    let e = err("[[network]]\nname = \"a\"\nbuses = \"can0\"\nnode_id = 1\n");
    assert!(
        e.starts_with("s.toml:3:9: buses: \"can0\" is not two buses"),
        "{e}"
    );
    assert!(
        e.contains("sim-pairs:quiet") && e.contains("sim-pairs:failover"),
        "{e}"
    );
    let e = err("[[network]]\nname = \"a\"\nbuses = \"can0,can0\"\nnode_id = 1\n");
    assert!(e.contains("can0 twice"), "{e}");
    let e = err("[[network]]\nname = \"a\"\nbuses = \"udp:x,can0\"\nnode_id = 1\n");
    assert!(e.starts_with("s.toml:3:9: buses: "), "{e}");
    let e = err("[[network]]\nname = \" \"\nbuses = \"sim-pairs\"\nnode_id = 1\n");
    assert!(e.starts_with("s.toml:2:8: name: "), "{e}");
}

#[test]
fn the_station_as_a_whole_is_checked() {
    let e = err("[station]\nname = \"x\"\n");
    assert!(e.starts_with("s.toml: no [[network]]"), "{e}");
    let twice = format!(
        "{HEAD}node_id = 1\n\n[[network]]\nname = \"a\"\nbuses = \"sim-pairs\"\nnode_id = 1\n"
    );
    let e = err(&twice);
    assert!(
        e.starts_with("s.toml:7:8: name: \"a\" names two networks"),
        "{e}"
    );
    let shared = "[[network]]\nname = \"a\"\nbuses = \"can0,can1\"\nnode_id = 1\n\n\
                  [[network]]\nname = \"b\"\nbuses = \"can2, can1\"\nnode_id = 1\n";
    let e = err(shared);
    assert!(
        e.starts_with("s.toml:8:9: buses: can1 is a bus of network \"a\" already"),
        "{e}"
    );
}

/// Whatever the bytes, reading a station file gives a station or an error, never a panic.
#[test]
fn any_text_is_read_without_panicking() {
    use proptest::prelude::*;
    proptest!(|(text in "[\\[\\]a-z_ =\"0-9,{}\n.:é€😀-]{0,200}")| {
        let _ = parse(&text, "p.toml");
    });
    proptest!(|(cut in 0..GOOD.len())| {
        let _ = parse(&GOOD[..cut], "p.toml");
    });
}

#[test]
fn http_connections_are_bounded_as_the_file_says() {
    let net = "\n\n[[network]]\nname = \"a\"\nbuses = \"sim-pairs\"\nnode_id = 1\n";
    let head = "[station]\nhttp = \"127.0.0.1:0\"\nhttp_max_connections = ";
    let st = parse(&format!("{head}3{net}"), "s.toml").unwrap();
    assert_eq!(st.http.unwrap().max_connections, 3);
    for bad in ["0", "4097"] {
        let e = err(&format!("{head}{bad}{net}"));
        assert!(
            e.starts_with("s.toml:3:24: http_max_connections: 1 to 4096 connections"),
            "{e}"
        );
    }
    // Without an address, the bound is an address forgotten.
    let e = err(&format!("[station]\nhttp_max_connections = 3{net}"));
    assert!(e.contains("http_max_connections: set http too"), "{e}");
}

#[test]
fn http_is_loopback_unless_a_token_is_given() {
    let head = "[station]\nhttp = ";
    let net = "\n\n[[network]]\nname = \"a\"\nbuses = \"sim-pairs\"\nnode_id = 1\n";
    let st = parse(&format!("{head}\"127.0.0.1:0\"{net}"), "s.toml").unwrap();
    let want = Http {
        addr: "127.0.0.1:0".parse().unwrap(),
        token: None,
        control: Control::Off,
        tls: None,
        max_connections: HTTP_MAX_CONNECTIONS,
    };
    assert_eq!(st.http, Some(want));
    let e = err(&format!("{head}\"0.0.0.0:8080\"{net}"));
    assert!(
        e.starts_with("s.toml:2:8: http: 0.0.0.0:8080 is reachable from other machines"),
        "{e}"
    );
    let ok = format!("{head}\"0.0.0.0:8080\"\nhttp_token = \"0123456789abcdef\"{net}");
    let st = parse(&ok, "s.toml").unwrap();
    assert_eq!(st.http.unwrap().token.as_deref(), Some("0123456789abcdef"));
    let e = err(&format!(
        "{head}\"0.0.0.0:8080\"\nhttp_token = \"short\"{net}"
    ));
    assert!(e.starts_with("s.toml:3:14: http_token: at least 16"), "{e}");
    let e = err(&format!("{head}\"localhost\"{net}"));
    assert!(
        e.starts_with("s.toml:2:8: http: \"localhost\" is not an address"),
        "{e}"
    );
    let e = err(&format!(
        "[station]\nhttp_token = \"0123456789abcdef\"{net}"
    ));
    assert!(e.contains("http_token: set http too"), "{e}");
}

/// Control is off unless the file turns it on: with a token of its own (any address), or
/// open to loopback clients (a loopback address without a read token only).
#[test]
fn control_needs_its_own_token_or_an_explicit_loopback_opt_in() {
    let net = "\n\n[[network]]\nname = \"a\"\nbuses = \"sim-pairs\"\nnode_id = 1\n";
    let control = |keys: &str| {
        parse(&format!("[station]\n{keys}{net}"), "s.toml").map(|s| s.http.unwrap().control)
    };
    let loopback = "http = \"127.0.0.1:0\"\n";
    let anywhere = "http = \"0.0.0.0:8080\"\nhttp_token = \"read-0123456789ab\"\n";
    assert_eq!(control(loopback), Ok(Control::Off));
    assert_eq!(control(anywhere), Ok(Control::Off));
    let keys = format!("{loopback}http_control = \"none\"\n");
    assert_eq!(control(&keys), Ok(Control::Off));
    let keys = format!("{loopback}http_control = \"loopback\"\n");
    assert_eq!(control(&keys), Ok(Control::Loopback));
    let keys = format!("{anywhere}http_control_token = \"ctl-0123456789abc\"\n");
    assert_eq!(
        control(&keys),
        Ok(Control::Token("ctl-0123456789abc".into()))
    );
    let keys = format!("{loopback}http_control_token = \"ctl-0123456789abc\"\n");
    assert_eq!(
        control(&keys),
        Ok(Control::Token("ctl-0123456789abc".into()))
    );
    // Never open to another machine.
    let e = err(&format!(
        "[station]\n{anywhere}http_control = \"loopback\"{net}"
    ));
    assert!(
        e.starts_with("s.toml:4:16: http_control: 0.0.0.0:8080 is reachable from other machines"),
        "{e}"
    );
    // Nor open beside a read token, nor beside a control token.
    let e = err(&format!(
        "[station]\n{loopback}http_token = \"read-0123456789ab\"\nhttp_control = \"loopback\"{net}"
    ));
    assert!(
        e.starts_with("s.toml:4:16: http_control: reads need http_token"),
        "{e}"
    );
    let e = err(&format!(
        "[station]\n{loopback}http_control_token = \"ctl-0123456789abc\"\nhttp_control = \"loopback\"{net}"
    ));
    assert!(
        e.starts_with("s.toml:4:16: http_control: set it or http_control_token"),
        "{e}"
    );
    let e = err(&format!("[station]\n{loopback}http_control = \"all\"{net}"));
    assert!(
        e.starts_with("s.toml:3:16: http_control: \"all\" is not allowed"),
        "{e}"
    );
    // The control token: long, and not the read token.
    let e = err(&format!(
        "[station]\n{loopback}http_control_token = \"short\"{net}"
    ));
    assert!(
        e.starts_with("s.toml:3:22: http_control_token: at least 16"),
        "{e}"
    );
    let e = err(&format!(
        "[station]\n{anywhere}http_control_token = \"read-0123456789ab\"{net}"
    ));
    assert!(
        e.starts_with("s.toml:4:22: http_control_token: the same as http_token"),
        "{e}"
    );
    let e = err(&format!("[station]\nhttp_control = \"loopback\"{net}"));
    assert!(
        e.starts_with("s.toml:2:16: http_control: set http too"),
        "{e}"
    );
}

#[test]
fn the_audit_folder_is_relative_to_the_file() {
    let net = "\n[[network]]\nname = \"a\"\nbuses = \"sim-pairs\"\nnode_id = 1\n";
    let st = parse(
        &format!("[station]\naudit_dir = \"trail\"\n{net}"),
        "/etc/duocan/s.toml",
    )
    .unwrap();
    let a = st.audit.unwrap();
    assert_eq!(a.dir, std::path::Path::new("/etc/duocan/trail"));
    assert_eq!((a.max_bytes, a.keep), (AUDIT_MAX_BYTES, AUDIT_KEEP));
    let e = err(&format!(
        "[station]\naudit_dir = \"t\"\naudit_max_bytes = 100\n{net}"
    ));
    assert!(
        e.starts_with("s.toml:3:19: audit_max_bytes: at least 4096"),
        "{e}"
    );
    let e = err(&format!("[station]\naudit_max_bytes = 8192\n{net}"));
    assert!(e.contains("audit_max_bytes: set audit_dir too"), "{e}");
}

#[test]
fn mqtt_names_a_broker_and_defaults_the_rest_from_the_station() {
    let net = "\n[[network]]\nname = \"a\"\nbuses = \"sim-pairs\"\nnode_id = 1\n";
    let st = parse(
        &format!("[station]\nname = \"yard 2\"\nmqtt = \"127.0.0.1:1883\"\n{net}"),
        "s.toml",
    )
    .unwrap();
    let m = st.mqtt.unwrap();
    assert_eq!((m.host.as_str(), m.port), ("127.0.0.1", 1883));
    assert_eq!(m.client_id, "duocan-yard_2");
    assert_eq!(m.prefix, "duocan/yard_2");
    assert_eq!((m.login, m.outbox), (None, mqtt::MQTT_OUTBOX));
    let st = parse(
        &format!(
            "[station]\nmqtt = \"[::1]:8883\"\nmqtt_client_id = \"ixl-7\"\n\
             mqtt_prefix = \"plant/ixl\"\nmqtt_username = \"u\"\nmqtt_password = \"p\"\n\
             mqtt_outbox = 8\n{net}"
        ),
        "s.toml",
    )
    .unwrap();
    let m = st.mqtt.unwrap();
    assert_eq!((m.host.as_str(), m.port), ("::1", 8883));
    assert_eq!(
        (m.client_id.as_str(), m.prefix.as_str()),
        ("ixl-7", "plant/ixl")
    );
    assert_eq!(m.login, Some(("u".into(), "p".into())));
    assert_eq!(m.outbox, 8);
    assert!(parse(&format!("[station]\nname = \"x\"\n{net}"), "s.toml")
        .unwrap()
        .mqtt
        .is_none());
}

#[test]
fn each_mqtt_error_names_the_file_line_column_and_key() {
    let net = "\n[[network]]\nname = \"a\"\nbuses = \"sim-pairs\"\nnode_id = 1\n";
    let bad = |keys: &str| err(&format!("[station]\n{keys}\n{net}"));
    for (keys, want) in [
        (
            "mqtt = \"broker\"",
            "s.toml:2:8: mqtt: \"broker\" is not a broker's host and port",
        ),
        ("mqtt = \"h:0\"", "s.toml:2:8: mqtt: \"h:0\" is not"),
        ("mqtt = \"a b:1883\"", "s.toml:2:8: mqtt: "),
        (
            "mqtt = \"h:1\"\nmqtt_prefix = \"a/+/b\"",
            "s.toml:3:15: mqtt_prefix: no wildcard",
        ),
        (
            "mqtt = \"h:1\"\nmqtt_prefix = \"a//b\"",
            "s.toml:3:15: mqtt_prefix: topic levels",
        ),
        (
            "mqtt = \"h:1\"\nmqtt_prefix = \"a/\"",
            "s.toml:3:15: mqtt_prefix: topic levels",
        ),
        (
            "mqtt = \"h:1\"\nmqtt_prefix = \"$SYS/x\"",
            "s.toml:3:15: mqtt_prefix: topics starting with $",
        ),
        (
            "mqtt = \"h:1\"\nmqtt_client_id = \"a b\"",
            "s.toml:3:18: mqtt_client_id: 1 to 64",
        ),
        (
            "mqtt = \"h:1\"\nmqtt_password = \"p\"",
            "s.toml:3:17: mqtt_password: set mqtt_username too",
        ),
        (
            "mqtt = \"h:1\"\nmqtt_outbox = 0",
            "s.toml:3:15: mqtt_outbox: 1 to 1048576",
        ),
        (
            "mqtt_prefix = \"x\"",
            "s.toml:2:15: mqtt_prefix: set mqtt (the broker's host:port) too",
        ),
        (
            "mqtt = \"h:1\"\nmqtt_port = 1",
            "s.toml:3:1: unknown field `mqtt_port`",
        ),
    ] {
        let e = bad(keys);
        assert!(e.starts_with(want), "{keys}: {e}");
    }
}

#[test]
fn with_mqtt_two_networks_may_not_share_a_topic_level() {
    let two = "[[network]]\nname = \"rack 1\"\nbuses = \"sim-pairs\"\nnode_id = 1\n\n\
               [[network]]\nname = \"rack/1\"\nbuses = \"sim-pairs\"\nnode_id = 1\n";
    let e = err(&format!("[station]\nmqtt = \"h:1\"\n\n{two}"));
    assert!(
        e.starts_with(
            "s.toml:10:8: name: \"rack/1\" and \"rack 1\" are both topic level \"rack_1\""
        ),
        "{e}"
    );
    // Without a broker the names are only names.
    assert!(parse(two, "s.toml").is_ok());
}
