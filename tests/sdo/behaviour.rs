//! How the SDO server and client behave beyond single clean transfers: retransmission after a
//! lost block segment, fallback when the server has no block transfer, the protocol switch,
//! several sessions at once, custom channels, copy-then-write, the upload snapshot, and the NMT
//! state.

use crate::net::{server, Net, TestNode, DOMAIN, STRING, VALUES};
use duocan::od::{Access, ObjectDef, ObjectDictionary};
use duocan::sdo::{
    Channel, HeapBuffer, SdoClient, SdoErrorKind, SdoOptions, SdoServerConfig, TransferMode,
};
use duocan::{AbortCode, CobId, Duration, Frame, Id, Instant, Machine, NodeId};

const N: NodeId = NodeId::must(5);

fn pattern(len: usize) -> Vec<u8> {
    (0..len).map(|i| (i * 31 % 251) as u8).collect()
}

fn from_client(net: &Net, from: usize) -> Vec<[u8; 8]> {
    net.log[from..]
        .iter()
        .filter(|(_, who, _)| who.is_none())
        .map(|(_, _, f)| f.data().try_into().unwrap())
        .collect()
}

fn from_server(net: &Net, from: usize) -> Vec<(Instant, [u8; 8])> {
    net.log[from..]
        .iter()
        .filter(|(_, who, _)| who.is_some())
        .map(|(t, _, f)| (*t, f.data().try_into().unwrap()))
        .collect()
}

/// Drops the first frame for which `pick` says yes, once.
fn lose_once(mut pick: impl FnMut(&Frame) -> bool + 'static) -> crate::net::Lose {
    let mut done = false;
    Box::new(move |f| {
        if !done && pick(f) {
            done = true;
            return true;
        }
        false
    })
}

#[test]
fn a_lost_block_download_segment_is_sent_again_from_the_last_good_one() {
    let mut net = Net::new(&[5]);
    net.lose = Some(lose_once(|f| {
        f.id() == Id::Standard(0x605) && f.data()[0] == 10
    }));
    let data = pattern(890);
    net.client
        .download(
            net.now,
            N,
            DOMAIN,
            0,
            &data,
            SdoOptions::mode(TransferMode::Block),
        )
        .unwrap();
    assert!(net.finish()[0].result.is_ok());
    assert_eq!(net.nodes[0].od().read(DOMAIN, 0).unwrap(), &data[..]);
    let acks: Vec<[u8; 3]> = from_server(&net, 0)
        .iter()
        .filter(|(_, d)| d[0] == 0xA2)
        .map(|(_, d)| [d[0], d[1], d[2]])
        .collect();
    // Segment 10 lost: the sub-block ends with 127, the server confirms 9; the client sends the
    // remaining 119 segments (10..=128) as the next sub-block.
    assert_eq!(acks, [[0xA2, 9, 127], [0xA2, 119, 127]]);
    let segments = from_client(&net, 0).len() - 2;
    assert_eq!(segments, 127 + 119);
}

#[test]
fn a_lost_end_of_sub_block_is_recovered_by_the_servers_sub_block_timer() {
    let mut net = Net::new(&[5]);
    // The segment that closes the first sub-block (127) never arrives.
    net.lose = Some(lose_once(|f| {
        f.id() == Id::Standard(0x605) && f.data()[0] == 127
    }));
    let data = pattern(2000);
    let t0 = net.now;
    net.client
        .download(
            net.now,
            N,
            DOMAIN,
            0,
            &data,
            SdoOptions::mode(TransferMode::Block),
        )
        .unwrap();
    assert!(net.finish()[0].result.is_ok());
    assert_eq!(net.nodes[0].od().read(DOMAIN, 0).unwrap(), &data[..]);
    let first_ack = from_server(&net, 0)
        .into_iter()
        .find(|(_, d)| d[0] == 0xA2)
        .unwrap();
    assert_eq!(
        first_ack,
        (
            t0 + Duration::from_millis(500),
            [0xA2, 126, 127, 0, 0, 0, 0, 0]
        )
    );
}

#[test]
fn a_lost_block_upload_segment_is_sent_again() {
    let mut net = Net::new(&[5]);
    let data = pattern(1500);
    net.nodes[0].write(net.now, DOMAIN, 0, &data).unwrap();
    net.lose = Some(lose_once(|f| {
        f.id() == Id::Standard(0x585) && f.data()[0] == 50
    }));
    let t0 = net.now;
    net.client
        .upload(net.now, N, DOMAIN, 0, SdoOptions::mode(TransferMode::Block))
        .unwrap();
    let ev = net.finish();
    assert_eq!(ev[0].data(), Some(&data[..]));
    let acks: Vec<[u8; 3]> = from_client(&net, 0)
        .iter()
        .filter(|d| d[0] == 0xA2)
        .map(|d| [d[0], d[1], d[2]])
        .collect();
    assert_eq!(acks[0], [0xA2, 49, 127]);
    assert_eq!(net.now, t0, "recovered without waiting for a timer");
}

#[test]
fn block_falls_back_to_segmented_when_the_server_has_no_block_transfer() {
    let mut net = Net::new(&[5]);
    net.nodes[0]
        .sdo_server_mut()
        .set_config(SdoServerConfig::default().with_block(false));
    let data = pattern(890);
    net.client
        .download(
            net.now,
            N,
            DOMAIN,
            0,
            &data,
            SdoOptions::mode(TransferMode::Block),
        )
        .unwrap();
    let ev = net.finish();
    assert!(ev[0].result.is_ok());
    assert_eq!(ev[0].mode, TransferMode::Segmented);
    assert_eq!(net.nodes[0].od().read(DOMAIN, 0).unwrap(), &data[..]);
    assert_eq!(
        from_server(&net, 0)[0].1,
        [0x80, 0x00, 0x20, 0x00, 0x01, 0x00, 0x04, 0x05]
    );
    assert_eq!(
        from_client(&net, 0)[1],
        [0x21, 0x00, 0x20, 0x00, 0x7A, 0x03, 0x00, 0x00]
    );
    let from = net.log.len();
    net.client
        .upload(net.now, N, DOMAIN, 0, SdoOptions::mode(TransferMode::Block))
        .unwrap();
    let ev = net.finish();
    assert_eq!(ev[0].data(), Some(&data[..]));
    assert_eq!(ev[0].mode, TransferMode::Segmented);
    assert_eq!(
        from_client(&net, from)[1],
        [0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0]
    );
    // Small data falls back to expedited.
    net.client
        .download(
            net.now,
            N,
            VALUES,
            3,
            &500u32.to_le_bytes(),
            SdoOptions::mode(TransferMode::Block),
        )
        .unwrap();
    assert_eq!(net.finish()[0].mode, TransferMode::Expedited);
    assert_eq!(net.nodes[0].od().get_value::<u32>(VALUES, 3), Ok(500));
    assert_eq!(net.client.stats().fallbacks, 3);
}

#[test]
fn protocol_switch_threshold_lets_the_server_answer_small_uploads_plainly() {
    let mut net = Net::new(&[5]);
    let opts = SdoOptions::mode(TransferMode::Block).with_pst(21);
    net.client.upload(net.now, N, VALUES, 1, opts).unwrap();
    let ev = net.finish();
    assert_eq!(ev[0].data(), Some(&7u32.to_le_bytes()[..]));
    assert_eq!(ev[0].mode, TransferMode::Expedited);
    net.nodes[0]
        .write(net.now, STRING, 0, b"twenty-one bytes!!!!")
        .unwrap();
    net.client.upload(net.now, N, STRING, 0, opts).unwrap();
    let ev = net.finish();
    assert_eq!(ev[0].data(), Some(&b"twenty-one bytes!!!!"[..]));
    assert_eq!(ev[0].mode, TransferMode::Segmented);
    net.nodes[0].write(net.now, DOMAIN, 0, &[1; 22]).unwrap();
    net.client.upload(net.now, N, DOMAIN, 0, opts).unwrap();
    assert_eq!(net.finish()[0].mode, TransferMode::Block);
}

#[test]
fn several_servers_at_once_one_transfer_per_server() {
    let mut net = Net::new(&[5, 6, 7]);
    let mut ids = vec![];
    for (k, node) in [5u8, 6, 7].into_iter().enumerate() {
        let mode = [
            TransferMode::Block,
            TransferMode::Segmented,
            TransferMode::Block,
        ][k];
        let data = vec![node; 890 + k];
        ids.push(
            net.client
                .download(
                    net.now,
                    NodeId::must(node),
                    DOMAIN,
                    0,
                    &data,
                    SdoOptions::mode(mode),
                )
                .unwrap(),
        );
    }
    assert_eq!(net.client.in_flight(), 3);
    assert!(net.client.is_busy(NodeId::must(6)));
    let busy = net
        .client
        .upload(net.now, NodeId::must(6), DOMAIN, 0, SdoOptions::default())
        .unwrap_err();
    assert_eq!(busy.kind, SdoErrorKind::Busy);
    assert!(busy.to_string().contains("already running"));
    let ev = net.finish();
    assert_eq!(ev.len(), 3);
    for (k, node) in [5u8, 6, 7].into_iter().enumerate() {
        let e = ev.iter().find(|e| e.request == ids[k]).unwrap();
        assert!(e.result.is_ok());
        assert_eq!(e.node, NodeId::must(node));
        assert_eq!(
            net.nodes[k].od().read(DOMAIN, 0).unwrap(),
            &vec![node; 890 + k][..]
        );
    }
    // The block transfers' segments were interleaved on the bus, not sent one after the other.
    let firsts: Vec<usize> = [0x605u16, 0x607]
        .iter()
        .map(|id| {
            net.log
                .iter()
                .rposition(|(_, _, f)| f.id() == Id::Standard(*id))
                .unwrap()
        })
        .collect();
    let starts: Vec<usize> = [0x605u16, 0x607]
        .iter()
        .map(|id| {
            net.log
                .iter()
                .position(|(_, _, f)| f.id() == Id::Standard(*id))
                .unwrap()
        })
        .collect();
    assert!(starts[1] < firsts[0] && starts[0] < firsts[1]);
}

#[test]
fn sessions_stay_taken_until_their_result_is_polled() {
    let mut c: SdoClient<HeapBuffer, 2> = SdoClient::with_limit(100);
    let now = Instant::ZERO;
    let up = |c: &mut SdoClient<HeapBuffer, 2>, n: u8| {
        c.upload(now, NodeId::must(n), DOMAIN, 0, SdoOptions::default())
    };
    up(&mut c, 5).unwrap();
    up(&mut c, 6).unwrap();
    let e = up(&mut c, 7).unwrap_err();
    assert_eq!(e.kind, SdoErrorKind::NoSession { sessions: 2 });
    // Node 5 answers; its result waits to be polled, so the session is still taken.
    c.handle_frame(
        now,
        &Frame::from_array(Id::Standard(0x585), [0x4F, 0x00, 0x20, 0x00, 9, 0, 0, 0]),
    );
    assert_eq!(c.in_flight(), 1);
    assert_eq!(
        up(&mut c, 7).unwrap_err().kind,
        SdoErrorKind::NoSession { sessions: 2 }
    );
    let ev = c.poll_event().unwrap();
    assert_eq!(ev.data(), Some(&[9u8][..]));
    up(&mut c, 7).unwrap();
    assert_eq!(c.stats().events_dropped, 0);
    // Too much data for the client's limit.
    let e = c
        .download(
            now,
            NodeId::must(8),
            DOMAIN,
            0,
            &[0; 101],
            SdoOptions::default(),
        )
        .unwrap_err();
    assert_eq!(
        e.kind,
        SdoErrorKind::TooLong {
            len: 101,
            limit: 100
        }
    );
}

#[test]
fn the_caller_can_abort_a_running_request() {
    let mut c: SdoClient = SdoClient::new(1000);
    let id = c
        .download(Instant::ZERO, N, DOMAIN, 0, &[1; 50], SdoOptions::default())
        .unwrap();
    while c.poll_transmit().is_some() {}
    assert!(c.abort(Instant::ZERO, id, AbortCode::LOCAL_CONTROL));
    let f = c.poll_transmit().unwrap();
    assert_eq!(f.data(), [0x80, 0x00, 0x20, 0x00, 0x21, 0x00, 0x00, 0x08]);
    let e = c.poll_event().unwrap();
    assert_eq!(e.request, id);
    assert_eq!(
        e.result.unwrap_err().kind,
        SdoErrorKind::Client(AbortCode::LOCAL_CONTROL)
    );
    assert!(!c.abort(Instant::ZERO, id, AbortCode::LOCAL_CONTROL));
    assert_eq!(c.poll_timeout(), None);
}

/// A node whose SDO server listens on 29-bit identifiers (0x1200 defaults of a custom profile).
fn extended_server(id: u8) -> TestNode {
    let mut n = server(id);
    let od = n.od_mut();
    od.upsert(ObjectDef::u32(
        0x1200,
        1,
        Access::Ro,
        CobId::extended(0x1AB_0600 + id as u32).0,
    ));
    od.upsert(ObjectDef::u32(
        0x1200,
        2,
        Access::Ro,
        CobId::extended(0x1AB_0580 + id as u32).0,
    ));
    n
}

fn extended_channel(node: NodeId) -> Channel {
    Channel::from_cob_ids(
        CobId::extended(0x1AB_0600 + node.raw() as u32).0,
        CobId::extended(0x1AB_0580 + node.raw() as u32).0,
    )
    .unwrap()
}

#[test]
fn custom_channels_with_29_bit_identifiers() {
    let mut net = Net::new(&[]);
    net.nodes.push(extended_server(5));
    net.nodes[0].boot(net.now);
    net.flush();
    assert_eq!(
        net.nodes[0].sdo_server().rx_id(),
        Some(Id::Extended(0x1AB_0605))
    );
    // Per request…
    let opts = SdoOptions::mode(TransferMode::Block).with_channel(Some(extended_channel(N)));
    let from = net.log.len();
    net.client
        .download(net.now, N, DOMAIN, 0, &pattern(100), opts)
        .unwrap();
    assert!(net.finish()[0].result.is_ok());
    assert!(net.log[from..].iter().all(|(_, _, f)| f.id().is_extended()));
    // … or for every node.
    net.client = SdoClient::new(1000).with_channels(extended_channel);
    net.client
        .upload(net.now, N, DOMAIN, 0, SdoOptions::default())
        .unwrap();
    assert_eq!(net.finish()[0].data(), Some(&pattern(100)[..]));
    // The predefined identifiers reach nobody now.
    let mut c: SdoClient = SdoClient::new(1000);
    std::mem::swap(&mut net.client, &mut c);
    net.client
        .upload(net.now, N, DOMAIN, 0, SdoOptions::default())
        .unwrap();
    assert!(net.finish()[0].result.as_ref().unwrap_err().is_timeout());
    assert_eq!(
        Channel::from_cob_ids(0x8000_0605, 0x585),
        None,
        "invalid COB-ID"
    );
}

// ----- server internals seen from the bus -----

fn slave() -> TestNode {
    crate::net::booted_server(5)
}

fn send(n: &mut TestNode, id: u16, d: &[u8]) -> Vec<Vec<u8>> {
    n.handle_frame(Instant::ZERO, &Frame::new(Id::Standard(id), d).unwrap());
    let mut out = vec![];
    while let Some(f) = n.poll_transmit() {
        if f.id() == Id::Standard(0x585) {
            out.push(f.data().to_vec());
        }
    }
    out
}

#[test]
fn an_upload_reads_the_value_as_it_was_when_the_upload_started() {
    let mut n = slave();
    n.write(Instant::ZERO, STRING, 0, b"the first value")
        .unwrap();
    assert_eq!(
        send(&mut n, 0x605, &[0x40, 0x01, 0x20, 0x00, 0, 0, 0, 0])[0][..5],
        [0x41, 0x01, 0x20, 0x00, 15]
    );
    let mut got = send(&mut n, 0x605, &[0x60, 0, 0, 0, 0, 0, 0, 0])[0][1..8].to_vec();
    // The application changes the entry in the middle of the upload.
    n.write(Instant::ZERO, STRING, 0, b"SECOND").unwrap();
    got.extend_from_slice(&send(&mut n, 0x605, &[0x70, 0, 0, 0, 0, 0, 0, 0])[0][1..8]);
    let last = send(&mut n, 0x605, &[0x60, 0, 0, 0, 0, 0, 0, 0]);
    assert_eq!(last[0][0], 0x0D, "t=0, n=6, c=1");
    got.push(last[0][1]);
    assert_eq!(got, b"the first value");
}

#[test]
fn an_aborted_download_leaves_the_entry_as_it_was() {
    let mut n = slave();
    n.write(Instant::ZERO, DOMAIN, 0, b"keep me").unwrap();
    // Block download, two segments, then the client aborts.
    send(&mut n, 0x605, &[0xC6, 0x00, 0x20, 0x00, 30, 0, 0, 0]);
    send(&mut n, 0x605, &[0x01, 1, 2, 3, 4, 5, 6, 7]);
    send(&mut n, 0x605, &[0x02, 1, 2, 3, 4, 5, 6, 7]);
    assert!(send(&mut n, 0x605, &[0x80, 0x00, 0x20, 0x00, 0, 0, 0, 8]).is_empty());
    assert_eq!(n.od().read(DOMAIN, 0), Ok(&b"keep me"[..]));
    assert!(n.sdo_server().is_idle());
    assert_eq!(n.sdo_server().stats().client_aborts, 1);
    // Segmented: all segments but the last, then an abort.
    send(&mut n, 0x605, &[0x21, 0x00, 0x20, 0x00, 10, 0, 0, 0]);
    send(&mut n, 0x605, &[0x00, 1, 2, 3, 4, 5, 6, 7]);
    send(&mut n, 0x605, &[0x80, 0x00, 0x20, 0x00, 0, 0, 4, 5]);
    assert_eq!(n.od().read(DOMAIN, 0), Ok(&b"keep me"[..]));
}

#[test]
fn stopped_means_no_sdo_and_a_reset_drops_the_transfer() {
    let mut n = slave();
    send(&mut n, 0x605, &[0x21, 0x00, 0x20, 0x00, 10, 0, 0, 0]);
    // NMT stop: the transfer is gone, requests get no answer at all.
    send(&mut n, 0x000, &[0x02, 5]);
    assert!(send(&mut n, 0x605, &[0x00, 1, 2, 3, 4, 5, 6, 7]).is_empty());
    assert!(send(&mut n, 0x605, &[0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0]).is_empty());
    assert_eq!(n.poll_timeout(), None);
    // Pre-operational again: served, but the old transfer is not resumed.
    send(&mut n, 0x000, &[0x80, 5]);
    assert_eq!(
        send(&mut n, 0x605, &[0x10, 1, 2, 3, 0, 0, 0, 0]),
        [vec![0x80, 0x00, 0x00, 0x00, 0x01, 0x00, 0x04, 0x05]]
    );
    // Reset communication in the middle of a transfer drops it too.
    send(&mut n, 0x605, &[0x21, 0x00, 0x20, 0x00, 10, 0, 0, 0]);
    send(&mut n, 0x000, &[0x82, 5]);
    assert!(n.sdo_server().is_idle());
    assert!(n.od().read(DOMAIN, 0).unwrap().is_empty());
    assert_eq!(n.sdo_server().rx_id(), Some(Id::Standard(0x605)));
}

/// A driver that takes one frame every 20 ms (a very slow bus): a sub-block of 127 segments
/// takes 2.5 s to leave, longer than the 1 s timeout, and neither side gives up while its own
/// segments are still waiting to be taken.
#[test]
fn a_slow_bus_does_not_time_out_a_sub_block_still_being_sent() {
    let payload = pattern(889);
    for upload in [true, false] {
        let mut n = slave();
        n.write(Instant::ZERO, DOMAIN, 0, &payload).unwrap();
        let mut c: SdoClient = SdoClient::new(2000);
        let mut now = Instant::ZERO;
        let opts = SdoOptions::mode(TransferMode::Block);
        if upload {
            c.upload(now, N, DOMAIN, 0, opts).unwrap();
        } else {
            c.download(now, N, DOMAIN, 0, &payload, opts).unwrap();
        }
        let e = loop {
            now += Duration::from_millis(20);
            if n.poll_timeout().is_some_and(|t| t <= now) {
                n.handle_timeout(now);
            }
            if c.poll_timeout().is_some_and(|t| t <= now) {
                c.handle_timeout(now);
            }
            // One frame each way per step.
            if let Some(f) = c.poll_transmit() {
                n.handle_frame(now, &f);
            }
            if let Some(f) = n.poll_transmit() {
                c.handle_frame(now, &f);
            }
            if let Some(e) = c.poll_event() {
                break e;
            }
            assert!(now < Instant::from_secs(60), "no result");
        };
        assert!(e.result.is_ok(), "{:?}", e.result);
        assert!(now > Instant::from_millis(2540), "{now}");
        assert_eq!(n.od().read(DOMAIN, 0), Ok(&payload[..]));
        if upload {
            assert_eq!(e.data(), Some(&payload[..]));
        }
    }
}

/// Who sends a CRC: a block download's end frame (the client's) carries it only when both sides
/// offer CRC, and the server checks it only then; a block upload's end frame (the server's)
/// carries it whenever the server announced CRC support, asked for or not, because clients
/// (python `canopen` among them) check it whenever that bit is set. A server without CRC support
/// says so in its initiate answers and never computes it.
#[test]
fn crc_sent_as_each_side_announced_it() {
    let data: Vec<u8> = (1..=20).collect();
    for (server_crc, client_crc) in [(false, true), (true, false), (true, true), (false, false)] {
        let mut net = Net::new(&[5]);
        net.nodes[0]
            .sdo_server_mut()
            .set_config(SdoServerConfig::default().with_crc(server_crc));
        let opts = SdoOptions::mode(TransferMode::Block).with_crc(client_crc);
        net.client
            .download(net.now, N, DOMAIN, 0, &data, opts)
            .unwrap();
        assert!(net.finish()[0].result.is_ok());
        net.client.upload(net.now, N, DOMAIN, 0, opts).unwrap();
        assert_eq!(net.finish()[0].data(), Some(&data[..]));
        let end = |server: bool| -> Vec<[u8; 2]> {
            net.log
                .iter()
                .filter(|(_, who, f)| who.is_some() == server && f.data()[0] == 0xC5)
                .map(|(_, _, f)| [f.data()[1], f.data()[2]])
                .collect()
        };
        let crc = |on: bool| if on { [0xD3, 0xEA] } else { [0, 0] };
        let case = format!("server {server_crc} client {client_crc}");
        assert_eq!(
            end(false),
            [crc(server_crc && client_crc)],
            "download end, {case}"
        );
        assert_eq!(end(true), [crc(server_crc)], "upload end, {case}");
        // The server's initiate answers carry its sc bit.
        let sc = net
            .log
            .iter()
            .filter(|(_, who, _)| who.is_some())
            .any(|(_, _, f)| f.data()[0] == 0xA4 || f.data()[0] == 0xC6);
        assert_eq!(sc, server_crc);
    }
}
