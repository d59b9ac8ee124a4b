//! What the server and client refuse, and how: the server's aborts (no such object, wrong
//! length, wrong type, read-only), timeouts on both sides at exact deadlines, a wrong toggle,
//! a busy second session, broadcast, and bytes that are no USDO message.

use super::*;

#[test]
fn no_such_object_wrong_length_and_read_only_are_the_servers_aborts() {
    let mut net = Net::new();
    let e = net.read(0x3000);
    assert_eq!(code(&e), Some(AbortCode::NO_OBJECT));
    assert!(matches!(
        e.result.unwrap_err().kind,
        UsdoErrorKind::Server(_)
    ));
    // A segmented write of 100 bytes to a 4-byte entry is refused at its start.
    let e = net.write(VALUE, 0, &pattern(100));
    assert_eq!(code(&e), Some(AbortCode::LENGTH_TOO_HIGH));
    // The data type announced is not the entry's.
    let e = net.write(VALUE, DataType::Unsigned16 as u8, &[1, 2]);
    assert_eq!(code(&e), Some(AbortCode::TYPE_MISMATCH));
    let e = net.write(RO, 0, &[1, 2, 3, 4]);
    assert_eq!(code(&e), Some(AbortCode::READ_ONLY));
    assert_eq!(net.od.read(VALUE, 0).unwrap(), 7u32.to_le_bytes());
}

#[test]
fn a_silent_server_times_out_on_both_sides_at_exact_deadlines() {
    let mut net = Net::new();
    // The answer to the third segment (the 8th frame on the bus) is lost.
    net.lose = |_, client, n| !client && n == 8;
    let e = net.write(DOMAIN, 0, &pattern(600));
    // The client sent segment 3 at 7 ms, its answer went at 8 ms: the client waited since the
    // answer to segment 2 at 6 ms; the server since segment 3 at 7 ms.
    assert_eq!(code(&e), Some(AbortCode::TIMEOUT));
    assert_eq!(e.at, Instant::from_millis(106));
    // The client's abort reaches the server at 107 ms, before its own deadline is handled: it
    // drops its side without an answer.
    let abort = net.client.poll_transmit().unwrap();
    assert_eq!(abort.data()[1], 0x80);
    assert_eq!(net.server.poll_timeout(), Some(Instant::from_millis(107)));
    net.server
        .handle_frame(Instant::from_millis(107), &abort, &mut net.od)
        .unwrap();
    net.server.handle_timeout(Instant::from_millis(107));
    assert!(net.server.poll_transmit().is_none());
    assert_eq!(
        (net.server.active(), net.server.stats().client_aborts),
        (0, 1)
    );
    assert_eq!(net.od.read(DOMAIN, 0).unwrap(), &[] as &[u8]);

    // The server's own timeout: a client that falls silent after the initiate.
    let mut net = Net::new();
    net.client
        .download(Instant::ZERO, SERVER, DOMAIN, 0, 0, &pattern(200), T)
        .unwrap();
    let init = net.client.poll_transmit().unwrap();
    net.server
        .handle_frame(Instant::from_millis(1), &init, &mut net.od)
        .unwrap();
    let _ack = net.server.poll_transmit().unwrap();
    assert_eq!(net.server.poll_timeout(), Some(Instant::from_millis(101)));
    net.server.handle_timeout(Instant::from_millis(101));
    let abort = Usdo::decode(net.server.poll_transmit().unwrap().data()).unwrap();
    assert_eq!(
        abort.msg,
        Msg::Abort {
            index: DOMAIN,
            sub: 0,
            code: UsdoAbort::from_code(AbortCode::TIMEOUT)
        }
    );
    assert_eq!((abort.dest, abort.session), (CLIENT.raw(), 1));
}

#[test]
fn a_segment_with_the_wrong_toggle_is_aborted() {
    let mut net = Net::new();
    net.client
        .download(Instant::ZERO, SERVER, DOMAIN, 0, 0, &pattern(200), T)
        .unwrap();
    let init = net.client.poll_transmit().unwrap();
    net.server
        .handle_frame(Instant::from_millis(1), &init, &mut net.od)
        .unwrap();
    let _ack = net.server.poll_transmit().unwrap();
    let data = UsdoPayload::new(&[0; 60]).unwrap();
    let bad = from_client(
        1,
        Msg::DownloadSegment {
            toggle: true,
            last: false,
            data,
        },
    );
    net.server
        .handle_frame(Instant::from_millis(2), &bad, &mut net.od)
        .unwrap();
    let answer = net.server.poll_transmit().unwrap();
    net.client.handle_frame(Instant::from_millis(3), &answer);
    let e = net.client.poll_event().unwrap();
    assert_eq!(code(&e), Some(AbortCode::TOGGLE_BIT));
    assert_eq!(net.server.active(), 0);
}

#[test]
fn a_second_session_of_the_same_client_is_busy_and_the_first_goes_on() {
    let mut net = Net::new();
    net.client
        .download(Instant::ZERO, SERVER, DOMAIN, 0, 0, &pattern(200), T)
        .unwrap();
    let init = net.client.poll_transmit().unwrap();
    net.server
        .handle_frame(Instant::from_millis(1), &init, &mut net.od)
        .unwrap();
    let ack = net.server.poll_transmit().unwrap();
    let other = from_client(
        42,
        Msg::UploadInitiate {
            index: VALUE,
            sub: 0,
        },
    );
    net.server
        .handle_frame(Instant::from_millis(2), &other, &mut net.od)
        .unwrap();
    let busy = Usdo::decode(net.server.poll_transmit().unwrap().data()).unwrap();
    assert_eq!(busy.session, 42);
    assert_eq!(
        busy.msg,
        Msg::Abort {
            index: VALUE,
            sub: 0,
            code: UsdoAbort::from_code(AbortCode::NO_RESOURCE)
        }
    );
    // The busy abort (session 42) is not the client's: it ignores it and goes on.
    net.client
        .handle_frame(Instant::from_millis(3), &net_frame(&busy));
    net.client.handle_frame(Instant::from_millis(3), &ack);
    net.now = Instant::from_millis(3);
    let e = net.run();
    assert!(e.result.is_ok());
    assert_eq!(net.client.stats().ignored, 1);
    assert_eq!(net.server.stats().busy, 1);
}

#[test]
fn a_broadcast_write_is_answered_by_every_server_a_broadcast_segmented_one_refused() {
    let mut servers: Vec<(UsdoServer, Od)> = [5u8, 6]
        .iter()
        .map(|&n| (UsdoServer::new(NodeId::must(n), T, 1024), od()))
        .collect();
    let data = UsdoPayload::new(&[1, 0, 0, 0]).unwrap();
    let msg = Msg::DownloadExpedited {
        index: VALUE,
        sub: 0,
        data_type: 7,
        data,
    };
    let f = Usdo {
        dest: BROADCAST,
        session: 3,
        msg,
    }
    .encode(request_id(CLIENT));
    let init = Msg::DownloadInitiate {
        index: DOMAIN,
        sub: 0,
        data_type: 0,
        size: 100,
    };
    let g = Usdo {
        dest: BROADCAST,
        session: 4,
        msg: init,
    }
    .encode(request_id(CLIENT));
    for (s, od) in &mut servers {
        s.handle_frame(Instant::ZERO, &f, od).unwrap();
        let a = s.poll_transmit().unwrap();
        assert_eq!(a.id(), answer_id(s.node()));
        assert_eq!(
            Usdo::decode(a.data()).unwrap().msg,
            Msg::DownloadAck {
                index: VALUE,
                sub: 0
            }
        );
        assert_eq!(od.read(VALUE, 0).unwrap(), [1, 0, 0, 0]);
        s.handle_frame(Instant::ZERO, &g, od).unwrap();
        let a = Usdo::decode(s.poll_transmit().unwrap().data()).unwrap();
        assert!(
            matches!(a.msg, Msg::Abort { code, .. } if code.code() == Some(AbortCode::UNSUPPORTED_ACCESS))
        );
    }
    // A request for another server is not this one's.
    let other = Usdo {
        dest: 9,
        session: 3,
        msg,
    }
    .encode(request_id(CLIENT));
    let (s, od) = &mut servers[0];
    s.handle_frame(Instant::ZERO, &other, od).unwrap();
    assert!(s.poll_transmit().is_none());
}

#[test]
fn garbage_is_refused_without_panic() {
    let mut net = Net::new();
    let f = FdFrame::new(
        request_id(CLIENT),
        &[SERVER.raw(), 0x77, 1, 0, 0x20, 0, 0, 0],
    )
    .unwrap();
    assert!(net
        .server
        .handle_frame(Instant::ZERO, &f, &mut net.od)
        .is_err());
    let a = Usdo::decode(net.server.poll_transmit().unwrap().data()).unwrap();
    assert!(
        matches!(a.msg, Msg::Abort { code, .. } if code.code() == Some(AbortCode::COMMAND_SPECIFIER))
    );
    let f = FdFrame::new(request_id(CLIENT), &[SERVER.raw()]).unwrap();
    assert!(net
        .server
        .handle_frame(Instant::ZERO, &f, &mut net.od)
        .is_err());
    assert!(net.server.poll_transmit().is_none());
    assert_eq!(net.server.stats().malformed, 2);
}
