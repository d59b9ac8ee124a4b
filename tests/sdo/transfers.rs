//! SDO transfers client ↔ server of every size class in every mode, both directions, with the
//! dictionary checked after each one.

use crate::net::{Net, DOMAIN};
use duocan::od::ObjectDictionary;
use duocan::sdo::{Direction, SdoErrorKind, SdoOptions, TransferMode};
use duocan::NodeId;

const N: NodeId = NodeId::must(5);
const SIZES: [usize; 9] = [0, 1, 4, 5, 7, 8, 889, 890, 64 * 1024];

fn pattern(len: usize, seed: u8) -> Vec<u8> {
    (0..len)
        .map(|i| (i as u32).wrapping_mul(2_654_435_761).to_le_bytes()[1] ^ seed)
        .collect()
}

fn modes(len: usize) -> Vec<(&'static str, SdoOptions)> {
    let mut v = vec![
        ("auto", SdoOptions::default()),
        ("segmented", SdoOptions::mode(TransferMode::Segmented)),
        ("block+crc", SdoOptions::mode(TransferMode::Block)),
        (
            "block",
            SdoOptions::mode(TransferMode::Block).with_crc(false),
        ),
        (
            "block blksize 5",
            SdoOptions::mode(TransferMode::Block).with_block_size(5),
        ),
        (
            "auto with block threshold",
            SdoOptions::default().with_block_threshold(Some(8)),
        ),
    ];
    if (1..=4).contains(&len) {
        v.push(("expedited", SdoOptions::mode(TransferMode::Expedited)));
    }
    v
}

fn expected_mode(opts: &SdoOptions, len: usize, dir: Direction) -> TransferMode {
    match (opts.mode, dir) {
        (TransferMode::Block, _) => TransferMode::Block,
        (_, Direction::Upload) if (1..=4).contains(&len) => TransferMode::Expedited,
        (_, Direction::Upload) => TransferMode::Segmented,
        (TransferMode::Auto, _) if (1..=4).contains(&len) => TransferMode::Expedited,
        (TransferMode::Auto, _) if opts.block_threshold.is_some_and(|t| len >= t) => {
            TransferMode::Block
        }
        (m, _) => {
            if m == TransferMode::Auto {
                TransferMode::Segmented
            } else {
                m
            }
        }
    }
}

#[test]
fn every_size_in_every_mode_both_directions() {
    let mut net = Net::new(&[5]);
    let mut seed = 0u8;
    for len in SIZES {
        for (name, opts) in modes(len) {
            seed = seed.wrapping_add(1);
            let data = pattern(len, seed);
            net.client
                .download(net.now, N, DOMAIN, 0, &data, opts)
                .unwrap();
            let ev = net.finish();
            assert_eq!(ev.len(), 1);
            assert!(
                ev[0].result.is_ok(),
                "download {len} {name}: {:?}",
                ev[0].result
            );
            assert_eq!(
                ev[0].mode,
                expected_mode(&opts, len, Direction::Download),
                "{len} {name}"
            );
            assert_eq!(
                net.nodes[0].od().read(DOMAIN, 0).unwrap(),
                &data[..],
                "download {len} {name}"
            );

            net.client.upload(net.now, N, DOMAIN, 0, opts).unwrap();
            let ev = net.finish();
            assert_eq!(ev.len(), 1);
            assert_eq!(ev[0].data(), Some(&data[..]), "upload {len} {name}");
            assert_eq!(
                ev[0].mode,
                expected_mode(&opts, len, Direction::Upload),
                "{len} {name}"
            );
        }
    }
    assert_eq!(net.client.stats().failed, 0);
    assert_eq!(net.nodes[0].sdo_server().stats().aborted, 0);
}

#[test]
fn expedited_refuses_sizes_it_cannot_carry() {
    let mut net = Net::new(&[5]);
    for len in [0, 5] {
        let e = net
            .client
            .download(
                net.now,
                N,
                DOMAIN,
                0,
                &vec![1; len],
                SdoOptions::mode(TransferMode::Expedited),
            )
            .unwrap_err();
        assert_eq!(e.kind, SdoErrorKind::TransferMode);
    }
}
