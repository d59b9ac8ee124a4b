use super::*;

#[test]
fn sdo_expedited_upload_and_download() {
    let mut dec = Decoder::new();
    let got = lines(
        &mut dec,
        &[
            std(0x605, &[0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0]),
            std(0x585, &[0x43, 0x18, 0x10, 0x01, 0x23, 0x01, 0, 0]),
            std(0x605, &[0x2B, 0x17, 0x10, 0x00, 0xE8, 0x03, 0, 0]),
            std(0x585, &[0x60, 0x17, 0x10, 0x00, 0, 0, 0, 0]),
            std(0x605, &[0x2F, 0x00, 0x20, 0x01, 0x7F, 0, 0, 0]),
            std(0x585, &[0x42, 0x00, 0x20, 0x02, 1, 2, 3, 4]),
        ],
    );
    assert_eq!(
        got,
        [
            "node 5 SDO upload 0x1018:01 request",
            "node 5 SDO upload 0x1018:01 = 0x00000123",
            "node 5 SDO download 0x1017:00 = 0x03e8",
            "node 5 SDO download 0x1017:00 accepted",
            "node 5 SDO download 0x2000:01 = 0x7f",
            "node 5 SDO upload 0x2000:02 = 0x04030201 (size not indicated)",
        ]
    );
}

#[test]
fn sdo_segmented_upload_counts_segments_and_totals() {
    let mut dec = Decoder::new();
    let got = lines(
        &mut dec,
        &[
            std(0x605, &[0x40, 0x08, 0x10, 0x00, 0, 0, 0, 0]),
            std(0x585, &[0x41, 0x08, 0x10, 0x00, 20, 0, 0, 0]),
            std(0x605, &[0x60, 0, 0, 0, 0, 0, 0, 0]),
            std(0x585, &[0x00, b'd', b'u', b'o', b'c', b'a', b'n', b' ']),
            std(0x605, &[0x70, 0, 0, 0, 0, 0, 0, 0]),
            std(0x585, &[0x10, b'r', b'a', b'i', b'l', b'w', b'a', b'y']),
            std(0x605, &[0x60, 0, 0, 0, 0, 0, 0, 0]),
            // n = 1: six bytes, last.
            std(0x585, &[0x03, b' ', b'n', b'o', b'd', b'e', b'!', 0]),
        ],
    );
    assert_eq!(
        got,
        [
            "node 5 SDO upload 0x1008:00 request",
            "node 5 SDO upload 0x1008:00 segmented, 20 bytes",
            "node 5 SDO upload 0x1008:00 segment 1 request",
            "node 5 SDO upload 0x1008:00 segment 1 (7 bytes)",
            "node 5 SDO upload 0x1008:00 segment 2 request",
            "node 5 SDO upload 0x1008:00 segment 2 (7 bytes)",
            "node 5 SDO upload 0x1008:00 segment 3 request",
            "node 5 SDO upload 0x1008:00 segment 3 (6 bytes), last: 20 bytes in all",
        ]
    );
    // Another node's transfer is its own; this one's context is unchanged.
    assert_eq!(
        dec.decode(&std(0x586, &[0x00, 1, 2, 3, 4, 5, 6, 7]))
            .to_string(),
        "node 6 SDO upload (transfer unknown) segment (7 bytes)"
    );
}

#[test]
fn sdo_segmented_download() {
    let mut dec = Decoder::new();
    let got = lines(
        &mut dec,
        &[
            std(0x60A, &[0x21, 0x00, 0x20, 0x00, 9, 0, 0, 0]),
            std(0x58A, &[0x60, 0x00, 0x20, 0x00, 0, 0, 0, 0]),
            std(0x60A, &[0x00, 1, 2, 3, 4, 5, 6, 7]),
            std(0x58A, &[0x20, 0, 0, 0, 0, 0, 0, 0]),
            std(0x60A, &[0x1B, 8, 9, 0, 0, 0, 0, 0]),
            std(0x58A, &[0x30, 0, 0, 0, 0, 0, 0, 0]),
        ],
    );
    assert_eq!(
        got,
        [
            "node 10 SDO download 0x2000:00 segmented, 9 bytes",
            "node 10 SDO download 0x2000:00 accepted",
            "node 10 SDO download 0x2000:00 segment 1 (7 bytes)",
            "node 10 SDO download 0x2000:00 segment 1 confirmed",
            "node 10 SDO download 0x2000:00 segment 2 (2 bytes), last: 9 bytes in all",
            "node 10 SDO download 0x2000:00 segment 2 confirmed",
        ]
    );
}

#[test]
fn sdo_block_download_with_segments_in_context() {
    let mut dec = Decoder::new();
    let got = lines(
        &mut dec,
        &[
            std(0x605, &[0xC6, 0x50, 0x1F, 0x01, 10, 0, 0, 0]),
            std(0x585, &[0xA4, 0x50, 0x1F, 0x01, 127, 0, 0, 0]),
            std(0x605, &[0x01, 1, 2, 3, 4, 5, 6, 7]),
            // The last segment: 3 bytes of data, 4 unused (said by the end frame).
            std(0x605, &[0x82, 8, 9, 10, 0, 0, 0, 0]),
            std(0x585, &[0xA2, 2, 127, 0, 0, 0, 0, 0]),
            std(0x605, &[0xD1, 0x34, 0x12, 0, 0, 0, 0, 0]),
            std(0x585, &[0xA1, 0, 0, 0, 0, 0, 0, 0]),
        ],
    );
    assert_eq!(
        got,
        [
            "node 5 SDO block download 0x1f50:01 request, 10 bytes, CRC",
            "node 5 SDO block download 0x1f50:01 accepted, block size 127, CRC",
            "node 5 SDO block download 0x1f50:01 segment 1 (sequence 1)",
            "node 5 SDO block download 0x1f50:01 segment 2 (sequence 2), last",
            "node 5 SDO block download 0x1f50:01 ack sequence 2, next block size 127",
            "node 5 SDO block download 0x1f50:01 end, 10 bytes in all, CRC 0x1234",
            "node 5 SDO block download 0x1f50:01 end confirmed",
        ]
    );
    // The transfer is over: the same bytes now decode by their command specifier.
    assert_eq!(
        dec.decode(&std(0x605, &[0x01, 1, 2, 3, 4, 5, 6, 7]))
            .to_string(),
        "node 5 SDO download (transfer unknown) segment (7 bytes), last"
    );
}

#[test]
fn sdo_block_upload_over_two_sub_blocks_with_a_repeat() {
    let mut dec = Decoder::new();
    let got = lines(
        &mut dec,
        &[
            std(0x605, &[0xA4, 0x08, 0x10, 0x00, 2, 0, 0, 0]),
            std(0x585, &[0xC6, 0x08, 0x10, 0x00, 30, 0, 0, 0]),
            std(0x605, &[0xA3, 0, 0, 0, 0, 0, 0, 0]),
            std(0x585, &[0x01, 1, 1, 1, 1, 1, 1, 1]),
            std(0x585, &[0x02, 2, 2, 2, 2, 2, 2, 2]),
            std(0x605, &[0xA2, 2, 2, 0, 0, 0, 0, 0]),
            std(0x585, &[0x01, 3, 3, 3, 3, 3, 3, 3]),
            // Lost on the way: the client acknowledges one and the server repeats.
            std(0x585, &[0x82, 4, 4, 4, 4, 4, 4, 4]),
            std(0x605, &[0xA2, 1, 2, 0, 0, 0, 0, 0]),
            std(0x585, &[0x01, 4, 4, 4, 4, 4, 4, 4]),
            std(0x585, &[0x82, 5, 5, 0, 0, 0, 0, 0]),
            std(0x605, &[0xA2, 2, 2, 0, 0, 0, 0, 0]),
            // Five segments of 7, the last with 2 data bytes: 30.
            std(0x585, &[0xC1 | (5 << 2), 0xCD, 0xAB, 0, 0, 0, 0, 0]),
            std(0x605, &[0xA1, 0, 0, 0, 0, 0, 0, 0]),
        ],
    );
    assert_eq!(
        got,
        [
            "node 5 SDO block upload 0x1008:00 request, block size 2, CRC",
            "node 5 SDO block upload 0x1008:00 accepted, 30 bytes, CRC",
            "node 5 SDO block upload 0x1008:00 start",
            "node 5 SDO block upload 0x1008:00 segment 1 (sequence 1)",
            "node 5 SDO block upload 0x1008:00 segment 2 (sequence 2)",
            "node 5 SDO block upload 0x1008:00 ack sequence 2, next block size 2",
            "node 5 SDO block upload 0x1008:00 segment 3 (sequence 1)",
            "node 5 SDO block upload 0x1008:00 segment 4 (sequence 2), last",
            "node 5 SDO block upload 0x1008:00 ack sequence 1, next block size 2",
            "node 5 SDO block upload 0x1008:00 segment 4 (sequence 1)",
            "node 5 SDO block upload 0x1008:00 segment 5 (sequence 2), last",
            "node 5 SDO block upload 0x1008:00 ack sequence 2, next block size 2",
            "node 5 SDO block upload 0x1008:00 end, 30 bytes in all, CRC 0xabcd",
            "node 5 SDO block upload 0x1008:00 end confirmed",
        ]
    );
}

#[test]
fn sdo_abort_names_the_code_and_ends_the_transfer() {
    let mut dec = Decoder::new();
    let got = lines(
        &mut dec,
        &[
            std(0x605, &[0x40, 0x08, 0x10, 0x00, 0, 0, 0, 0]),
            std(0x585, &[0x41, 0x08, 0x10, 0x00, 20, 0, 0, 0]),
            std(0x585, &[0x80, 0x08, 0x10, 0x00, 0x00, 0x00, 0x02, 0x06]),
            std(0x585, &[0x00, 1, 2, 3, 4, 5, 6, 7]),
            std(0x605, &[0x80, 0x00, 0x20, 0x00, 0x00, 0x00, 0x04, 0x05]),
        ],
    );
    assert_eq!(
        got[2],
        "node 5 SDO abort 0x1008:00 by server: 0x06020000 (object does not exist in the object dictionary)"
    );
    assert_eq!(
        got[3],
        "node 5 SDO upload (transfer unknown) segment (7 bytes)"
    );
    assert_eq!(
        got[4],
        "node 5 SDO abort 0x2000:00 by client: 0x05040000 (SDO protocol timed out)"
    );
}

#[test]
fn sdo_bad_frames_say_what_is_wrong() {
    assert_eq!(
        line(std(0x605, &[0x40, 0x18, 0x10])),
        "node 5 SDO: 3 bytes, an SDO frame has 8 (40 18 10)"
    );
    assert_eq!(
        line(std(0x605, &[0xE0, 0, 0, 0, 0, 0, 0, 0])),
        "node 5 SDO from client: command byte 0xe0 is no CiA 301 command specifier"
    );
    assert_eq!(
        line(Frame::remote(Id::Standard(0x585), 8).unwrap()),
        "node 5 SDO: remote frame, an SDO frame carries data"
    );
}
