//! Every abort path, on the side CiA 301 puts it: the server's answers to bad requests and bad
//! accesses (frame by frame), the client's answers to bad responses, timeouts on both sides. An
//! aborted download never changes the dictionary.

use crate::net::{
    booted_server, Net, TestNode, DOMAIN, HOOKED, SMALL_DOMAIN, STRING, VALUES, VETO, WIDE,
};
use duocan::od::{comm, ObjectDictionary};
use duocan::sdo::{SdoClient, SdoErrorKind, SdoEvent, SdoOptions, SdoServerConfig, TransferMode};
use duocan::{AbortCode, Duration, Frame, Id, Instant, Machine, NodeId};

const N: NodeId = NodeId::must(5);
const T0: Instant = Instant::from_millis(10);

fn slave() -> TestNode {
    booted_server(5)
}

/// Hands the server one request; returns its answers.
fn send(n: &mut TestNode, now: Instant, d: [u8; 8]) -> Vec<[u8; 8]> {
    n.handle_frame(now, &Frame::from_array(Id::Standard(0x605), d));
    drain(n)
}

fn drain(n: &mut TestNode) -> Vec<[u8; 8]> {
    let mut out = vec![];
    while let Some(f) = n.poll_transmit() {
        if f.id() == Id::Standard(0x585) {
            out.push(f.data().try_into().unwrap());
        }
    }
    out
}

fn abort(index: u16, sub: u8, code: AbortCode) -> [u8; 8] {
    let i = index.to_le_bytes();
    let c = code.0.to_le_bytes();
    [0x80, i[0], i[1], sub, c[0], c[1], c[2], c[3]]
}

fn domain(n: &TestNode) -> Vec<u8> {
    n.od().read(DOMAIN, 0).unwrap().to_vec()
}

// ----- server side, frame by frame -----

#[test]
fn server_toggle_bit_not_alternated() {
    let mut n = slave();
    assert_eq!(
        send(&mut n, T0, [0x21, 0x00, 0x20, 0x00, 14, 0, 0, 0]),
        [[0x60, 0x00, 0x20, 0x00, 0, 0, 0, 0]]
    );
    assert_eq!(
        send(&mut n, T0, [0x00, 1, 2, 3, 4, 5, 6, 7]),
        [[0x20, 0, 0, 0, 0, 0, 0, 0]]
    );
    // The second segment must have t=1.
    assert_eq!(
        send(&mut n, T0, [0x01, 1, 2, 3, 4, 5, 6, 7]),
        [abort(DOMAIN, 0, AbortCode::TOGGLE_BIT)]
    );
    assert!(domain(&n).is_empty(), "nothing written");
    // Upload: the first segment request must have t=0.
    send(&mut n, T0, [0x40, 0x01, 0x20, 0x00, 0, 0, 0, 0]);
    n.write(T0, STRING, 0, b"twelve bytes").unwrap();
    send(&mut n, T0, [0x40, 0x01, 0x20, 0x00, 0, 0, 0, 0]);
    assert_eq!(
        send(&mut n, T0, [0x70, 0, 0, 0, 0, 0, 0, 0]),
        [abort(STRING, 0, AbortCode::TOGGLE_BIT)]
    );
}

#[test]
fn server_unknown_or_unexpected_command() {
    let mut n = slave();
    // ccs = 7 does not exist.
    assert_eq!(
        send(&mut n, T0, [0xE0, 0x00, 0x20, 0x00, 0, 0, 0, 0]),
        [abort(DOMAIN, 0, AbortCode::COMMAND_SPECIFIER)]
    );
    // A segment without a transfer.
    assert_eq!(
        send(&mut n, T0, [0x00, 0, 0, 0, 0, 0, 0, 0]),
        [abort(0, 0, AbortCode::COMMAND_SPECIFIER)]
    );
    // An upload segment request during a download.
    send(&mut n, T0, [0x21, 0x00, 0x20, 0x00, 14, 0, 0, 0]);
    assert_eq!(
        send(&mut n, T0, [0x60, 0, 0, 0, 0, 0, 0, 0]),
        [abort(DOMAIN, 0, AbortCode::COMMAND_SPECIFIER)]
    );
    // Block start without a block upload.
    assert_eq!(
        send(&mut n, T0, [0xA3, 0, 0, 0, 0, 0, 0, 0]),
        [abort(0, 0, AbortCode::COMMAND_SPECIFIER)]
    );
    // Not SDO frames at all: refused without an answer, reported as malformed.
    n.handle_frame(
        T0,
        &Frame::new(Id::Standard(0x605), &[0x40, 0, 0x20]).unwrap(),
    );
    n.handle_frame(T0, &Frame::remote(Id::Standard(0x605), 8).unwrap());
    assert!(drain(&mut n).is_empty());
    assert_eq!(n.sdo_server().stats().malformed, 2);
}

#[test]
fn server_block_transfer_not_supported_answers_command_specifier() {
    let mut n = slave();
    n.sdo_server_mut()
        .set_config(SdoServerConfig::default().with_block(false));
    assert_eq!(
        send(&mut n, T0, [0xC6, 0x00, 0x20, 0x00, 20, 0, 0, 0]),
        [abort(DOMAIN, 0, AbortCode::COMMAND_SPECIFIER)]
    );
    assert_eq!(
        send(&mut n, T0, [0xA4, 0x00, 0x20, 0x00, 127, 0, 0, 0]),
        [abort(DOMAIN, 0, AbortCode::COMMAND_SPECIFIER)]
    );
}

#[test]
fn server_invalid_block_size() {
    let mut n = slave();
    n.write(T0, DOMAIN, 0, &[9; 100]).unwrap();
    for blksize in [0u8, 128, 255] {
        assert_eq!(
            send(&mut n, T0, [0xA4, 0x00, 0x20, 0x00, blksize, 0, 0, 0]),
            [abort(DOMAIN, 0, AbortCode::INVALID_BLOCK_SIZE)]
        );
    }
    // In the acknowledgement of a sub-block.
    assert_eq!(
        send(&mut n, T0, [0xA4, 0x00, 0x20, 0x00, 5, 0, 0, 0]),
        [[0xC6, 0x00, 0x20, 0x00, 100, 0, 0, 0]]
    );
    assert_eq!(send(&mut n, T0, [0xA3, 0, 0, 0, 0, 0, 0, 0]).len(), 5);
    assert_eq!(
        send(&mut n, T0, [0xA2, 5, 0, 0, 0, 0, 0, 0]),
        [abort(DOMAIN, 0, AbortCode::INVALID_BLOCK_SIZE)]
    );
}

#[test]
fn server_invalid_sequence_number() {
    let mut n = slave();
    n.sdo_server_mut()
        .set_config(SdoServerConfig::default().with_block_size(10));
    assert_eq!(
        send(&mut n, T0, [0xC6, 0x00, 0x20, 0x00, 100, 0, 0, 0]),
        [[0xA4, 0x00, 0x20, 0x00, 10, 0, 0, 0]]
    );
    assert!(send(&mut n, T0, [0x01, 1, 2, 3, 4, 5, 6, 7]).is_empty());
    // Sequence numbers run 1..=10 here.
    assert_eq!(
        send(&mut n, T0, [0x0B, 1, 2, 3, 4, 5, 6, 7]),
        [abort(DOMAIN, 0, AbortCode::INVALID_SEQUENCE)]
    );
    assert!(domain(&n).is_empty());
    send(&mut n, T0, [0xC6, 0x00, 0x20, 0x00, 100, 0, 0, 0]);
    assert_eq!(
        send(&mut n, T0, [0x00, 1, 2, 3, 4, 5, 6, 7]),
        [abort(DOMAIN, 0, AbortCode::INVALID_SEQUENCE)]
    );
    // Block upload: acknowledging more segments than were sent.
    n.write(T0, DOMAIN, 0, &[9; 100]).unwrap();
    send(&mut n, T0, [0xA4, 0x00, 0x20, 0x00, 5, 0, 0, 0]);
    assert_eq!(send(&mut n, T0, [0xA3, 0, 0, 0, 0, 0, 0, 0]).len(), 5);
    assert_eq!(
        send(&mut n, T0, [0xA2, 6, 5, 0, 0, 0, 0, 0]),
        [abort(DOMAIN, 0, AbortCode::INVALID_SEQUENCE)]
    );
}

#[test]
fn server_crc_error_leaves_the_entry_unchanged() {
    let mut n = slave();
    n.write(T0, DOMAIN, 0, b"old").unwrap();
    send(&mut n, T0, [0xC6, 0x00, 0x20, 0x00, 20, 0, 0, 0]);
    send(&mut n, T0, [0x01, 1, 2, 3, 4, 5, 6, 7]);
    send(&mut n, T0, [0x02, 8, 9, 10, 11, 12, 13, 14]);
    assert_eq!(
        send(&mut n, T0, [0x83, 15, 16, 17, 18, 19, 20, 0]),
        [[0xA2, 3, 127, 0, 0, 0, 0, 0]]
    );
    // The right CRC is 0xEAD3.
    assert_eq!(
        send(&mut n, T0, [0xC5, 0xD4, 0xEA, 0, 0, 0, 0, 0]),
        [abort(DOMAIN, 0, AbortCode::CRC_ERROR)]
    );
    assert_eq!(domain(&n), b"old");
    // Without CRC on the client side the field is not checked.
    send(&mut n, T0, [0xC2, 0x00, 0x20, 0x00, 20, 0, 0, 0]);
    send(&mut n, T0, [0x01, 1, 2, 3, 4, 5, 6, 7]);
    send(&mut n, T0, [0x02, 8, 9, 10, 11, 12, 13, 14]);
    send(&mut n, T0, [0x83, 15, 16, 17, 18, 19, 20, 0]);
    assert_eq!(
        send(&mut n, T0, [0xC5, 0, 0, 0, 0, 0, 0, 0]),
        [[0xA1, 0, 0, 0, 0, 0, 0, 0]]
    );
    assert_eq!(domain(&n), (1..=20).collect::<Vec<u8>>());
}

#[test]
fn server_timeout_aborts_exactly_and_writes_nothing() {
    let mut n = slave();
    send(&mut n, T0, [0x21, 0x00, 0x20, 0x00, 14, 0, 0, 0]);
    let t1 = T0 + Duration::from_millis(300);
    send(&mut n, t1, [0x00, 1, 2, 3, 4, 5, 6, 7]);
    let deadline = t1 + Duration::from_millis(1000);
    assert_eq!(n.poll_timeout(), Some(deadline));
    n.handle_timeout(deadline - Duration::from_micros(1));
    assert!(drain(&mut n).is_empty());
    n.handle_timeout(deadline);
    assert_eq!(drain(&mut n), [abort(DOMAIN, 0, AbortCode::TIMEOUT)]);
    assert!(domain(&n).is_empty());
    assert!(n.sdo_server().is_idle());
}

#[test]
fn server_block_sub_block_timer_acknowledges_what_arrived() {
    let mut n = slave();
    send(&mut n, T0, [0xC6, 0x00, 0x20, 0x00, 100, 0, 0, 0]);
    send(&mut n, T0, [0x01, 1, 2, 3, 4, 5, 6, 7]);
    send(&mut n, T0, [0x02, 1, 2, 3, 4, 5, 6, 7]);
    // Segment 3 and the rest of the sub-block are lost: 500 ms (the default sub-block timer)
    // later the server says "2".
    assert_eq!(n.poll_timeout(), Some(T0 + Duration::from_millis(500)));
    n.handle_timeout(T0 + Duration::from_millis(500));
    assert_eq!(drain(&mut n), [[0xA2, 2, 127, 0, 0, 0, 0, 0]]);
}

// ----- access checks, client to server: the client reports the server's code -----

fn failing(net: &mut Net, ev: Vec<SdoEvent>) -> AbortCode {
    assert_eq!(ev.len(), 1);
    let e = ev[0].result.as_ref().unwrap_err();
    let SdoErrorKind::Server(code) = e.kind else {
        panic!("expected a server abort, got {e}")
    };
    // The report names node, object and the meaning of the code.
    let text = e.to_string();
    assert!(text.contains("node 5"), "{text}");
    assert!(
        text.contains(&format!("object {:#06x} sub {}", e.index, e.sub)),
        "{text}"
    );
    assert!(text.contains(code.description().unwrap()), "{text}");
    let _ = net;
    code
}

fn download(net: &mut Net, index: u16, sub: u8, data: &[u8], mode: TransferMode) -> AbortCode {
    net.client
        .download(net.now, N, index, sub, data, SdoOptions::mode(mode))
        .unwrap();
    let ev = net.finish();
    failing(net, ev)
}

fn upload(net: &mut Net, index: u16, sub: u8, mode: TransferMode) -> AbortCode {
    net.client
        .upload(net.now, N, index, sub, SdoOptions::mode(mode))
        .unwrap();
    let ev = net.finish();
    failing(net, ev)
}

#[test]
fn object_and_sub_index_must_exist() {
    let mut net = Net::new(&[5]);
    for mode in [
        TransferMode::Auto,
        TransferMode::Segmented,
        TransferMode::Block,
    ] {
        assert_eq!(upload(&mut net, 0x3000, 0, mode), AbortCode::NO_OBJECT);
        assert_eq!(upload(&mut net, VALUES, 9, mode), AbortCode::NO_SUB_INDEX);
        assert_eq!(
            download(&mut net, 0x3000, 0, &[1; 9], mode),
            AbortCode::NO_OBJECT
        );
        assert_eq!(
            download(&mut net, VALUES, 9, &[1; 9], mode),
            AbortCode::NO_SUB_INDEX
        );
    }
    assert_eq!(
        download(&mut net, 0x3000, 0, &[1], TransferMode::Expedited),
        AbortCode::NO_OBJECT
    );
}

#[test]
fn access_rights_read_of_write_only_and_write_of_read_only() {
    let mut net = Net::new(&[5]);
    for mode in [TransferMode::Auto, TransferMode::Block] {
        assert_eq!(upload(&mut net, VALUES, 2, mode), AbortCode::WRITE_ONLY);
    }
    for mode in [
        TransferMode::Expedited,
        TransferMode::Segmented,
        TransferMode::Block,
    ] {
        assert_eq!(
            download(&mut net, VALUES, 1, &[1, 0, 0, 0], mode),
            AbortCode::READ_ONLY
        );
        // const
        assert_eq!(
            download(&mut net, VALUES, 0, &[1], mode),
            AbortCode::READ_ONLY
        );
        assert_eq!(
            download(&mut net, comm::IDENTITY, 1, &[1, 0, 0, 0], mode),
            AbortCode::READ_ONLY
        );
    }
    assert_eq!(net.nodes[0].od().get_value::<u32>(VALUES, 1), Ok(7));
}

#[test]
fn lengths_too_high_and_too_low() {
    let mut net = Net::new(&[5]);
    for mode in [TransferMode::Segmented, TransferMode::Block] {
        assert_eq!(
            download(&mut net, VALUES, 3, &[1; 5], mode),
            AbortCode::LENGTH_TOO_HIGH
        );
        assert_eq!(
            download(&mut net, VALUES, 3, &[1; 2], mode),
            AbortCode::LENGTH_TOO_LOW
        );
        assert_eq!(
            download(&mut net, STRING, 0, &[b'x'; 21], mode),
            AbortCode::LENGTH_TOO_HIGH
        );
        assert_eq!(
            download(&mut net, WIDE, 0, &[1; 7], mode),
            AbortCode::LENGTH_TOO_LOW
        );
        assert_eq!(
            download(&mut net, SMALL_DOMAIN, 0, &[1; 101], mode),
            AbortCode::LENGTH_TOO_HIGH
        );
    }
    assert_eq!(
        download(&mut net, VALUES, 3, &[1; 2], TransferMode::Expedited),
        AbortCode::LENGTH_TOO_LOW
    );
    assert_eq!(
        download(&mut net, WIDE, 0, &[1; 4], TransferMode::Expedited),
        AbortCode::LENGTH_TOO_LOW
    );
    assert_eq!(net.nodes[0].od().get_value::<u32>(VALUES, 3), Ok(100));
    assert_eq!(net.nodes[0].od().read(STRING, 0), Ok(&b""[..]));
}

#[test]
fn segmented_download_shorter_or_longer_than_announced() {
    let mut n = slave();
    // Announces 10 bytes, sends 3 and says "last".
    send(&mut n, T0, [0x21, 0x00, 0x20, 0x00, 10, 0, 0, 0]);
    assert_eq!(
        send(&mut n, T0, [0x09, 1, 2, 3, 0, 0, 0, 0]),
        [abort(DOMAIN, 0, AbortCode::LENGTH_TOO_LOW)]
    );
    // Announces 10 bytes, sends 14.
    send(&mut n, T0, [0x21, 0x00, 0x20, 0x00, 10, 0, 0, 0]);
    send(&mut n, T0, [0x00, 1, 2, 3, 4, 5, 6, 7]);
    assert_eq!(
        send(&mut n, T0, [0x11, 1, 2, 3, 4, 5, 6, 7]),
        [abort(DOMAIN, 0, AbortCode::LENGTH_TOO_HIGH)]
    );
    assert!(domain(&n).is_empty());
}

#[test]
fn value_range_limits_and_hook_veto() {
    let mut net = Net::new(&[5]);
    for mode in [
        TransferMode::Expedited,
        TransferMode::Segmented,
        TransferMode::Block,
    ] {
        assert_eq!(
            download(&mut net, VALUES, 3, &5u32.to_le_bytes(), mode),
            AbortCode::VALUE_TOO_LOW
        );
        assert_eq!(
            download(&mut net, VALUES, 3, &2000u32.to_le_bytes(), mode),
            AbortCode::VALUE_TOO_HIGH
        );
        assert_eq!(
            download(&mut net, HOOKED, 0, &[3, 0], mode),
            AbortCode::LOCAL_CONTROL
        );
        // 0x1003 sub 0 accepts only 0 (CiA 301: 0x06090030 otherwise).
        assert_eq!(
            download(&mut net, comm::ERROR_HISTORY, 0, &[5], mode),
            AbortCode::VALUE_RANGE
        );
    }
    assert_eq!(net.nodes[0].od().get_value::<u32>(VALUES, 3), Ok(100));
    net.client
        .download(net.now, N, HOOKED, 0, &[4, 0], SdoOptions::default())
        .unwrap();
    assert!(net.finish()[0].result.is_ok());
}

#[test]
fn device_state_refusal() {
    let mut net = Net::new(&[5]);
    // The SYNC counter overflow may not change while SYNC is produced (0x1006 ≠ 0).
    net.nodes[0]
        .set(net.now, comm::SYNC_PERIOD, 0, 10_000u32)
        .unwrap();
    assert_eq!(
        download(
            &mut net,
            comm::SYNC_OVERFLOW,
            0,
            &[10],
            TransferMode::Expedited
        ),
        AbortCode::DEVICE_STATE
    );
    net.nodes[0]
        .set(net.now, comm::SYNC_PERIOD, 0, 0u32)
        .unwrap();
    net.client
        .download(
            net.now,
            N,
            comm::SYNC_OVERFLOW,
            0,
            &[10],
            SdoOptions::default(),
        )
        .unwrap();
    assert!(net.finish()[0].result.is_ok());
}

#[test]
fn out_of_memory_on_the_server() {
    let mut net = Net::new(&[5]);
    net.nodes[0]
        .sdo_server_mut()
        .set_config(SdoServerConfig::default().with_max_transfer(100));
    for mode in [TransferMode::Segmented, TransferMode::Block] {
        assert_eq!(
            download(&mut net, DOMAIN, 0, &[1; 101], mode),
            AbortCode::OUT_OF_MEMORY
        );
    }
    net.nodes[0].write(net.now, DOMAIN, 0, &[1; 101]).unwrap();
    assert_eq!(
        upload(&mut net, DOMAIN, 0, TransferMode::Auto),
        AbortCode::OUT_OF_MEMORY
    );
    // Announced sizes are checked up front; an unannounced one as the data comes.
    let mut n = slave();
    n.sdo_server_mut()
        .set_config(SdoServerConfig::default().with_max_transfer(10));
    send(&mut n, T0, [0x20, 0x00, 0x20, 0x00, 0, 0, 0, 0]);
    send(&mut n, T0, [0x00, 1, 2, 3, 4, 5, 6, 7]);
    assert_eq!(
        send(&mut n, T0, [0x10, 1, 2, 3, 4, 5, 6, 7]),
        [abort(DOMAIN, 0, AbortCode::OUT_OF_MEMORY)]
    );
    assert!(n.sdo_server().buffer_len() <= 10);
}

/// Whatever code the dictionary or the application refuses a write with reaches the client's
/// caller unchanged, typed, with its CiA 301 meaning: every code of the standard.
#[test]
fn every_abort_code_reaches_the_caller_with_its_meaning() {
    let mut net = Net::new(&[5]);
    for code in AbortCode::ALL {
        for mode in [
            TransferMode::Expedited,
            TransferMode::Segmented,
            TransferMode::Block,
        ] {
            assert_eq!(
                download(&mut net, VETO, 0, &code.0.to_le_bytes(), mode),
                *code
            );
        }
    }
    assert_eq!(net.nodes[0].od().get_value::<u32>(VETO, 0), Ok(0));
    // A code the standard does not define is still carried faithfully.
    net.client
        .download(
            net.now,
            N,
            VETO,
            0,
            &0x1234_5678u32.to_le_bytes(),
            SdoOptions::default(),
        )
        .unwrap();
    let e = net.finish()[0].result.clone().unwrap_err();
    assert_eq!(e.kind, SdoErrorKind::Server(AbortCode(0x1234_5678)));
    assert!(e.to_string().contains("not a CiA 301 abort code"));
}

// ----- client side: answers to bad responses, frame by frame -----

fn client() -> SdoClient {
    SdoClient::new(1000)
}

/// Hands the client one server frame; returns the client's frames.
fn reply(c: &mut SdoClient, now: Instant, d: [u8; 8]) -> Vec<[u8; 8]> {
    c.handle_frame(now, &Frame::from_array(Id::Standard(0x585), d));
    out(c)
}

fn out(c: &mut SdoClient) -> Vec<[u8; 8]> {
    let mut v = vec![];
    while let Some(f) = c.poll_transmit() {
        assert_eq!(f.id(), Id::Standard(0x605));
        v.push(f.data().try_into().unwrap());
    }
    v
}

/// The client answers `answer` with an abort of `code` and reports `code` to its caller.
fn client_aborts(c: &mut SdoClient, now: Instant, answer: [u8; 8], code: AbortCode) {
    assert_eq!(reply(c, now, answer), [abort(DOMAIN, 0, code)]);
    assert_eq!(client_error(c), SdoErrorKind::Client(code));
}

/// An upload of [`DOMAIN`] whose request went out.
fn start_upload(c: &mut SdoClient) {
    c.upload(T0, N, DOMAIN, 0, SdoOptions::default()).unwrap();
    out(c);
}

fn client_error(c: &mut SdoClient) -> SdoErrorKind {
    let e = c.poll_event().expect("a result");
    e.result.unwrap_err().kind
}

#[test]
fn client_toggle_bit_not_alternated() {
    let mut c = client();
    start_upload(&mut c);
    assert_eq!(
        reply(&mut c, T0, [0x41, 0x00, 0x20, 0x00, 14, 0, 0, 0]),
        [[0x60, 0, 0, 0, 0, 0, 0, 0]]
    );
    client_aborts(
        &mut c,
        T0,
        [0x10, 1, 2, 3, 4, 5, 6, 7],
        AbortCode::TOGGLE_BIT,
    );
    // Download: the server must echo the toggle bit of the segment.
    c.download(T0, N, DOMAIN, 0, &[1; 10], SdoOptions::default())
        .unwrap();
    out(&mut c);
    reply(&mut c, T0, [0x60, 0x00, 0x20, 0x00, 0, 0, 0, 0]);
    client_aborts(
        &mut c,
        T0,
        [0x30, 0, 0, 0, 0, 0, 0, 0],
        AbortCode::TOGGLE_BIT,
    );
}

#[test]
fn client_unknown_or_unexpected_command() {
    let mut c = client();
    start_upload(&mut c);
    client_aborts(
        &mut c,
        T0,
        [0xE0, 0x00, 0x20, 0x00, 0, 0, 0, 0],
        AbortCode::COMMAND_SPECIFIER,
    );
    // A download response to an upload.
    start_upload(&mut c);
    client_aborts(
        &mut c,
        T0,
        [0x60, 0x00, 0x20, 0x00, 0, 0, 0, 0],
        AbortCode::COMMAND_SPECIFIER,
    );
}

/// An answer that names another object answers an earlier request (a lagging bus's late
/// copy): ignored; when nothing else comes, the timeout says what did.
#[test]
fn client_answer_about_another_object() {
    let mut c = client();
    start_upload(&mut c);
    assert_eq!(
        reply(&mut c, T0, [0x4F, 0x01, 0x20, 0x00, 1, 0, 0, 0]),
        [[0; 8]; 0]
    );
    assert_eq!(c.stats().stale, 1);
    assert!(c.poll_event().is_none());
    let timeout = T0 + SdoOptions::default().timeout;
    c.handle_timeout(timeout - Duration::from_micros(1));
    assert!(out(&mut c).is_empty());
    c.handle_timeout(timeout);
    assert_eq!(
        out(&mut c),
        [abort(DOMAIN, 0, AbortCode::PARAMETER_INCOMPATIBLE)]
    );
    assert_eq!(
        client_error(&mut c),
        SdoErrorKind::Client(AbortCode::PARAMETER_INCOMPATIBLE)
    );
    // The next transfer on the channel starts clean: a plain timeout.
    c.upload(timeout, N, DOMAIN, 0, SdoOptions::default())
        .unwrap();
    out(&mut c);
    c.handle_timeout(timeout + SdoOptions::default().timeout);
    assert_eq!(out(&mut c), [abort(DOMAIN, 0, AbortCode::TIMEOUT)]);
    assert_eq!(
        client_error(&mut c),
        SdoErrorKind::Client(AbortCode::TIMEOUT)
    );
}

#[test]
fn client_invalid_block_size() {
    let mut c = client();
    c.download(
        T0,
        N,
        DOMAIN,
        0,
        &[1; 100],
        SdoOptions::mode(TransferMode::Block),
    )
    .unwrap();
    assert_eq!(out(&mut c), [[0xC6, 0x00, 0x20, 0x00, 100, 0, 0, 0]]);
    client_aborts(
        &mut c,
        T0,
        [0xA4, 0x00, 0x20, 0x00, 0, 0, 0, 0],
        AbortCode::INVALID_BLOCK_SIZE,
    );
    // In a sub-block acknowledgement.
    c.download(
        T0,
        N,
        DOMAIN,
        0,
        &[1; 100],
        SdoOptions::mode(TransferMode::Block),
    )
    .unwrap();
    out(&mut c);
    assert_eq!(
        reply(&mut c, T0, [0xA4, 0x00, 0x20, 0x00, 4, 0, 0, 0]).len(),
        4
    );
    assert_eq!(
        reply(&mut c, T0, [0xA2, 4, 200, 0, 0, 0, 0, 0]),
        [abort(DOMAIN, 0, AbortCode::INVALID_BLOCK_SIZE)]
    );
}

#[test]
fn client_invalid_sequence_number() {
    let mut c = client();
    let opts = SdoOptions::mode(TransferMode::Block).with_block_size(10);
    c.upload(T0, N, DOMAIN, 0, opts).unwrap();
    assert_eq!(out(&mut c), [[0xA4, 0x00, 0x20, 0x00, 10, 0, 0, 0]]);
    assert_eq!(
        reply(&mut c, T0, [0xC6, 0x00, 0x20, 0x00, 100, 0, 0, 0]),
        [[0xA3, 0, 0, 0, 0, 0, 0, 0]]
    );
    client_aborts(
        &mut c,
        T0,
        [0x0B, 1, 2, 3, 4, 5, 6, 7],
        AbortCode::INVALID_SEQUENCE,
    );
    // Block download: the server acknowledges a segment that was never sent.
    c.download(
        T0,
        N,
        DOMAIN,
        0,
        &[1; 100],
        SdoOptions::mode(TransferMode::Block),
    )
    .unwrap();
    out(&mut c);
    assert_eq!(
        reply(&mut c, T0, [0xA4, 0x00, 0x20, 0x00, 4, 0, 0, 0]).len(),
        4
    );
    client_aborts(
        &mut c,
        T0,
        [0xA2, 5, 4, 0, 0, 0, 0, 0],
        AbortCode::INVALID_SEQUENCE,
    );
}

#[test]
fn client_crc_error() {
    let mut c = client();
    c.upload(T0, N, DOMAIN, 0, SdoOptions::mode(TransferMode::Block))
        .unwrap();
    out(&mut c);
    reply(&mut c, T0, [0xC6, 0x00, 0x20, 0x00, 20, 0, 0, 0]);
    reply(&mut c, T0, [0x01, 1, 2, 3, 4, 5, 6, 7]);
    reply(&mut c, T0, [0x02, 8, 9, 10, 11, 12, 13, 14]);
    assert_eq!(
        reply(&mut c, T0, [0x83, 15, 16, 17, 18, 19, 20, 0]),
        [[0xA2, 3, 127, 0, 0, 0, 0, 0]]
    );
    client_aborts(
        &mut c,
        T0,
        [0xC5, 0x00, 0xEA, 0, 0, 0, 0, 0],
        AbortCode::CRC_ERROR,
    );
}

#[test]
fn client_timeout_aborts_exactly() {
    let mut c = client();
    let opts = SdoOptions::default().with_timeout(Duration::from_millis(250));
    c.upload(T0, N, DOMAIN, 0, opts).unwrap();
    out(&mut c);
    let t1 = T0 + Duration::from_millis(100);
    reply(&mut c, t1, [0x41, 0x00, 0x20, 0x00, 14, 0, 0, 0]);
    assert_eq!(c.poll_timeout(), Some(t1 + Duration::from_millis(250)));
    c.handle_timeout(t1 + Duration::from_millis(249));
    assert!(out(&mut c).is_empty());
    c.handle_timeout(t1 + Duration::from_millis(250));
    assert_eq!(out(&mut c), [abort(DOMAIN, 0, AbortCode::TIMEOUT)]);
    let e = c.poll_event().unwrap();
    assert_eq!(e.at, t1 + Duration::from_millis(250));
    let err = e.result.unwrap_err();
    assert!(err.is_timeout());
    assert_eq!(err.kind, SdoErrorKind::Client(AbortCode::TIMEOUT));
    assert!(err.to_string().contains("no answer in time"));
    assert_eq!(c.poll_timeout(), None);
}

#[test]
fn a_timed_out_transfers_abort_leaves_before_the_next_request_on_its_channel() {
    // The abort of a transfer that timed out is still waiting to be sent when the caller, told
    // of the time-out, starts the next transfer with the same node: the server must see the
    // abort first (seen the other way round, it aborts the new transfer; CANopenNode did).
    let mut c = client();
    let opts = SdoOptions::default().with_timeout(Duration::from_millis(250));
    // Another session busy too, so that a free session other than the old one exists.
    c.upload(T0, NodeId::must(6), DOMAIN, 0, opts).unwrap();
    c.upload(T0, N, DOMAIN, 0, opts).unwrap();
    while c.poll_transmit().is_some() {}
    let t1 = T0 + Duration::from_millis(250);
    c.handle_timeout(t1);
    while c.poll_event().is_some() {}
    c.upload(t1, N, 0x1018, 1, opts).unwrap();
    let frames: Vec<(Id, [u8; 8])> = core::iter::from_fn(|| c.poll_transmit())
        .map(|f| (f.id(), f.data().try_into().unwrap()))
        .filter(|(id, _)| *id == Id::Standard(0x605))
        .collect();
    assert_eq!(
        frames.iter().map(|f| f.1).collect::<Vec<_>>(),
        [
            abort(DOMAIN, 0, AbortCode::TIMEOUT),
            [0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0]
        ]
    );
}

#[test]
fn client_out_of_memory_and_length_mismatch() {
    let mut c = client();
    start_upload(&mut c);
    client_aborts(
        &mut c,
        T0,
        [0x41, 0x00, 0x20, 0x00, 0xE9, 0x03, 0, 0],
        AbortCode::OUT_OF_MEMORY,
    );
    // Fewer bytes than announced.
    start_upload(&mut c);
    reply(&mut c, T0, [0x41, 0x00, 0x20, 0x00, 10, 0, 0, 0]);
    client_aborts(
        &mut c,
        T0,
        [0x01, 1, 2, 3, 4, 5, 6, 7],
        AbortCode::LENGTH_TOO_LOW,
    );
    // The server aborting is reported as the server's code.
    start_upload(&mut c);
    assert!(reply(&mut c, T0, abort(DOMAIN, 0, AbortCode::HARDWARE_ERROR)).is_empty());
    assert_eq!(
        client_error(&mut c),
        SdoErrorKind::Server(AbortCode::HARDWARE_ERROR)
    );
}

#[test]
fn client_and_server_timeouts_end_to_end() {
    // The server goes silent (stopped): the client times out.
    let mut net = Net::new(&[5]);
    net.nodes[0].set_nmt_state(net.now, duocan::NmtState::Stopped);
    let t = net.now;
    net.client
        .upload(net.now, N, DOMAIN, 0, SdoOptions::default())
        .unwrap();
    let ev = net.finish();
    assert_eq!(ev[0].at, t + Duration::from_millis(1000));
    assert_eq!(
        ev[0].result.as_ref().unwrap_err().kind,
        SdoErrorKind::Client(AbortCode::TIMEOUT)
    );
    // The client's segment is lost; the server waits 1 s, the client 1.5 s: the server times
    // out first and says so.
    let mut net = Net::new(&[5]);
    let mut n = 0;
    net.lose = Some(Box::new(move |f| {
        n += 1;
        f.id() == Id::Standard(0x605) && n == 3
    }));
    let t = net.now;
    net.client
        .download(
            net.now,
            N,
            DOMAIN,
            0,
            &[5; 20],
            SdoOptions::mode(TransferMode::Segmented).with_timeout(Duration::from_millis(1500)),
        )
        .unwrap();
    let ev = net.finish();
    assert_eq!(ev[0].at, t + Duration::from_millis(1000));
    assert_eq!(
        ev[0].result.as_ref().unwrap_err().kind,
        SdoErrorKind::Server(AbortCode::TIMEOUT)
    );
    assert!(net.nodes[0].od().read(DOMAIN, 0).unwrap().is_empty());
}
