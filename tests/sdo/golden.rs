//! Golden frame sequences: one expedited, one segmented and one block transfer each way, byte for
//! byte as CiA 301 §7.2.4.3 lays them out (expected bytes written by hand from the standard; the
//! block CRC from an independent bitwise CRC-16/XMODEM computation).

use crate::net::{Net, DOMAIN, STRING, VALUES};
use duocan::od::ObjectDictionary;
use duocan::sdo::{SdoOptions, SdoServerConfig, TransferMode};
use duocan::{Id, NodeId};

const N: NodeId = NodeId::must(5);
const C: Option<usize> = None;
const S: Option<usize> = Some(0);

fn exchange(net: &Net, from: usize) -> Vec<(Option<usize>, u16, [u8; 8])> {
    net.log[from..]
        .iter()
        .map(|(_, who, f)| {
            let Id::Standard(id) = f.id() else {
                panic!("SDO on 11-bit identifiers here")
            };
            (*who, id, f.data().try_into().unwrap())
        })
        .collect()
}

#[test]
fn expedited_download_and_upload() {
    let mut net = Net::new(&[5]);
    net.client
        .download(
            net.now,
            N,
            VALUES,
            3,
            &500u32.to_le_bytes(),
            SdoOptions::default(),
        )
        .unwrap();
    net.finish();
    assert_eq!(
        exchange(&net, 0),
        [
            (C, 0x605, [0x23, 0x02, 0x20, 0x03, 0xF4, 0x01, 0x00, 0x00]),
            (S, 0x585, [0x60, 0x02, 0x20, 0x03, 0x00, 0x00, 0x00, 0x00]),
        ]
    );
    let from = net.log.len();
    net.client
        .upload(net.now, N, VALUES, 1, SdoOptions::default())
        .unwrap();
    let ev = net.finish();
    assert_eq!(ev[0].data(), Some(&7u32.to_le_bytes()[..]));
    assert_eq!(
        exchange(&net, from),
        [
            (C, 0x605, [0x40, 0x02, 0x20, 0x01, 0x00, 0x00, 0x00, 0x00]),
            (S, 0x585, [0x43, 0x02, 0x20, 0x01, 0x07, 0x00, 0x00, 0x00]),
        ]
    );
}

#[test]
fn segmented_download_and_upload() {
    let mut net = Net::new(&[5]);
    net.client
        .download(net.now, N, STRING, 0, b"duocan-sdo", SdoOptions::default())
        .unwrap();
    net.finish();
    assert_eq!(net.nodes[0].od().read(STRING, 0), Ok(&b"duocan-sdo"[..]));
    assert_eq!(
        exchange(&net, 0),
        [
            // ccs=1, s=1: size 10 follows.
            (C, 0x605, [0x21, 0x01, 0x20, 0x00, 0x0A, 0x00, 0x00, 0x00]),
            (S, 0x585, [0x60, 0x01, 0x20, 0x00, 0x00, 0x00, 0x00, 0x00]),
            // t=0, n=0, c=0: "duocan-"
            (C, 0x605, [0x00, b'd', b'u', b'o', b'c', b'a', b'n', b'-']),
            (S, 0x585, [0x20, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00]),
            // t=1, n=4, c=1: "sdo"
            (C, 0x605, [0x19, b's', b'd', b'o', 0x00, 0x00, 0x00, 0x00]),
            (S, 0x585, [0x30, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00]),
        ]
    );
    let from = net.log.len();
    net.client
        .upload(net.now, N, STRING, 0, SdoOptions::default())
        .unwrap();
    let ev = net.finish();
    assert_eq!(ev[0].data(), Some(&b"duocan-sdo"[..]));
    assert_eq!(
        exchange(&net, from),
        [
            (C, 0x605, [0x40, 0x01, 0x20, 0x00, 0x00, 0x00, 0x00, 0x00]),
            (S, 0x585, [0x41, 0x01, 0x20, 0x00, 0x0A, 0x00, 0x00, 0x00]),
            (C, 0x605, [0x60, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00]),
            (S, 0x585, [0x00, b'd', b'u', b'o', b'c', b'a', b'n', b'-']),
            (C, 0x605, [0x70, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00]),
            (S, 0x585, [0x19, b's', b'd', b'o', 0x00, 0x00, 0x00, 0x00]),
        ]
    );
}

#[test]
fn block_download_and_upload_with_crc() {
    let data: Vec<u8> = (1..=20).collect();
    let mut net = Net::new(&[5]);
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
    assert_eq!(net.nodes[0].od().read(DOMAIN, 0), Ok(&data[..]));
    assert_eq!(
        exchange(&net, 0),
        [
            // ccs=6, cc=1 (CRC), s=1 (size 20), cs=0.
            (C, 0x605, [0xC6, 0x00, 0x20, 0x00, 0x14, 0x00, 0x00, 0x00]),
            // scs=5, sc=1, ss=0; blksize 127.
            (S, 0x585, [0xA4, 0x00, 0x20, 0x00, 0x7F, 0x00, 0x00, 0x00]),
            (C, 0x605, [0x01, 1, 2, 3, 4, 5, 6, 7]),
            (C, 0x605, [0x02, 8, 9, 10, 11, 12, 13, 14]),
            // c=1, seqno 3: the last segment, six bytes of data.
            (C, 0x605, [0x83, 15, 16, 17, 18, 19, 20, 0]),
            // ss=2: ackseq 3, next blksize 127.
            (S, 0x585, [0xA2, 0x03, 0x7F, 0x00, 0x00, 0x00, 0x00, 0x00]),
            // cs=1, n=1 unused byte; CRC 0xEAD3.
            (C, 0x605, [0xC5, 0xD3, 0xEA, 0x00, 0x00, 0x00, 0x00, 0x00]),
            (S, 0x585, [0xA1, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00]),
        ]
    );
    let from = net.log.len();
    net.client
        .upload(net.now, N, DOMAIN, 0, SdoOptions::mode(TransferMode::Block))
        .unwrap();
    let ev = net.finish();
    assert_eq!(ev[0].data(), Some(&data[..]));
    assert_eq!(
        exchange(&net, from),
        block_upload_1_to_20(true, true, 0xEAD3)
    );
}

/// A client that does not ask for CRC (cc=0) still gets the real CRC in the end frame when the
/// server's initiate response sets sc=1: CiA 301 ties the CRC to the server's bit, and clients
/// such as python `canopen` check it whenever that bit is set.
#[test]
fn block_upload_without_client_crc_carries_the_real_crc() {
    let data: Vec<u8> = (1..=20).collect();
    let mut net = Net::new(&[5]);
    net.nodes[0].write(net.now, DOMAIN, 0, &data).unwrap();
    let opts = SdoOptions::mode(TransferMode::Block).with_crc(false);
    net.client.upload(net.now, N, DOMAIN, 0, opts).unwrap();
    let ev = net.finish();
    assert_eq!(ev[0].data(), Some(&data[..]));
    // The client did not ask (cc=0), the server announced CRC (sc=1): the end frame carries
    // the CRC-16 of bytes 1..=20, not zero.
    assert_eq!(exchange(&net, 0), block_upload_1_to_20(false, true, 0xEAD3));
}

/// A server configured without CRC support does not set sc, and its end frame carries 0.
#[test]
fn block_upload_from_a_server_without_crc_support() {
    let data: Vec<u8> = (1..=20).collect();
    let mut net = Net::new(&[5]);
    net.nodes[0].write(net.now, DOMAIN, 0, &data).unwrap();
    net.nodes[0]
        .sdo_server_mut()
        .set_config(SdoServerConfig::default().with_crc(false));
    net.client
        .upload(net.now, N, DOMAIN, 0, SdoOptions::mode(TransferMode::Block))
        .unwrap();
    let ev = net.finish();
    assert_eq!(ev[0].data(), Some(&data[..]));
    assert_eq!(exchange(&net, 0), block_upload_1_to_20(true, false, 0));
}

/// The block upload of bytes 1..=20 from node 5, frame by frame: `cc` is the client's CRC bit,
/// `sc` the server's, `crc` what the server's end frame carries.
fn block_upload_1_to_20(cc: bool, sc: bool, crc: u16) -> Vec<(Option<usize>, u16, [u8; 8])> {
    let [lo, hi] = crc.to_le_bytes();
    vec![
        // ccs=5, cc, cs=0; blksize 127, pst 0.
        (
            C,
            0x605,
            [0xA0 | u8::from(cc) << 2, 0x00, 0x20, 0x00, 0x7F, 0, 0, 0],
        ),
        // scs=6, sc, s=1, ss=0; size 20.
        (
            S,
            0x585,
            [0xC2 | u8::from(sc) << 2, 0x00, 0x20, 0x00, 0x14, 0, 0, 0],
        ),
        // cs=3: start.
        (C, 0x605, [0xA3, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00]),
        (S, 0x585, [0x01, 1, 2, 3, 4, 5, 6, 7]),
        (S, 0x585, [0x02, 8, 9, 10, 11, 12, 13, 14]),
        (S, 0x585, [0x83, 15, 16, 17, 18, 19, 20, 0]),
        (C, 0x605, [0xA2, 0x03, 0x7F, 0x00, 0x00, 0x00, 0x00, 0x00]),
        // ss=1, n=1; the CRC.
        (S, 0x585, [0xC5, lo, hi, 0x00, 0x00, 0x00, 0x00, 0x00]),
        (C, 0x605, [0xA1, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00]),
    ]
}
