//! The order of a DCF's writes, as exact sequences.

use super::super::config::{ConfigStep, SlaveConfig};
use crate::eds::{Description, ImportOptions};
use crate::frame::cob_id::NodeId;
use alloc::format;
use alloc::string::String;
use alloc::vec::Vec;

/// One entry of a test DCF: (index, sub, data type, access, default, value).
type Entry<'a> = (u16, u8, u16, &'a str, &'a str, Option<&'a str>);

/// A DCF with `entries`: VARs at sub 0 alone, the others as records.
pub(crate) fn dcf(entries: &[Entry]) -> Description {
    let mut indexes: Vec<u16> = entries.iter().map(|e| e.0).collect();
    indexes.dedup();
    let mut t = String::from("[FileInfo]\nFileName=t.dcf\n[DeviceInfo]\nVendorName=T\n");
    t += &format!("[OptionalObjects]\nSupportedObjects={}\n", indexes.len());
    for (i, x) in indexes.iter().enumerate() {
        t += &format!("{}=0x{x:04X}\n", i + 1);
    }
    for x in &indexes {
        let subs: Vec<&Entry> = entries.iter().filter(|e| e.0 == *x).collect();
        let var = subs.len() == 1 && subs[0].1 == 0;
        if !var {
            t += &format!(
                "[{x:04X}]\nParameterName=O{x:04X}\nObjectType=0x9\nSubNumber={}\n",
                subs.len()
            );
        }
        for (index, sub, ty, access, default, value) in subs {
            let head = if var {
                format!("[{index:04X}]")
            } else {
                format!("[{index:04X}sub{sub:X}]")
            };
            t += &format!(
                "{head}\nParameterName=E{index:04X}.{sub}\nObjectType=0x7\nDataType=0x{ty:04X}\n\
                 AccessType={access}\nDefaultValue={default}\nPDOMapping=0\n"
            );
            if let Some(v) = value {
                t += &format!("ParameterValue={v}\n");
            }
        }
    }
    Description::parse(t.as_bytes(), "t.dcf", &ImportOptions::lenient())
        .unwrap_or_else(|e| panic!("{e}\n{t}"))
}

fn w(index: u16, sub: u8, data: &[u8]) -> ConfigStep {
    ConfigStep::Write {
        index,
        sub,
        data: data.to_vec(),
    }
}

fn steps(d: &Description) -> Vec<ConfigStep> {
    SlaveConfig::from_dcf(NodeId::must(5), d).steps
}

#[test]
fn only_values_that_differ_in_index_order_read_only_skipped() {
    let d = dcf(&[
        (0x1000, 0, 7, "ro", "0x191", Some("0x191")),
        (0x6000, 0, 6, "rw", "10", Some("10")),
        (0x2001, 0, 6, "rw", "0", Some("7")),
        (0x2000, 0, 5, "rw", "1", Some("2")),
        (0x2002, 0, 7, "const", "0", Some("9")),
        (0x2003, 0, 7, "rw", "$NODEID+0x100", Some("0x105")),
        (0x2004, 0, 7, "rw", "0", Some("$NODEID+0x100")),
    ]);
    assert_eq!(
        steps(&d),
        [
            w(0x2000, 0, &[2]),
            w(0x2001, 0, &[7, 0]),
            w(0x2004, 0, &[0x05, 0x01, 0, 0]),
        ]
    );
}

#[test]
fn store_restore_and_the_configuration_stamp_are_never_written_from_a_dcf() {
    // "save" (0x65766173) and "load" (0x64616F6C) in a DCF, and a stamp: a store midway would
    // keep half a configuration, a restore would undo it, and the master writes the stamp last.
    let d = dcf(&[
        (0x1010, 1, 7, "rw", "1", Some("0x65766173")),
        (0x1011, 1, 7, "rw", "1", Some("0x64616F6C")),
        (0x1020, 1, 7, "rw", "0", Some("9000")),
        (0x1020, 2, 7, "rw", "0", Some("3600000")),
        (0x2000, 0, 5, "rw", "0", Some("1")),
    ]);
    assert_eq!(steps(&d), [w(0x2000, 0, &[1])]);
}

#[test]
fn remapped_tpdo_invalid_first_count_zero_entries_count_then_cob_id() {
    let d = dcf(&[
        (0x1017, 0, 6, "rw", "0", Some("100")),
        (0x1800, 0, 5, "ro", "5", None),
        (0x1800, 1, 7, "rw", "$NODEID+0x180", Some("$NODEID+0x280")),
        (0x1800, 2, 5, "rw", "254", Some("1")),
        (0x1800, 5, 6, "rw", "0", Some("0")),
        (0x1A00, 0, 5, "rw", "1", Some("2")),
        (0x1A00, 1, 7, "rw", "0x60000010", Some("0x60000010")),
        (0x1A00, 2, 7, "rw", "0", Some("0x60010008")),
        (0x2000, 0, 5, "rw", "0", Some("3")),
    ]);
    let cfg = SlaveConfig::from_dcf(NodeId::must(5), &d);
    assert_eq!(
        cfg.steps,
        [
            w(0x1800, 1, &0x8000_0285u32.to_le_bytes()),
            w(0x1800, 2, &[1]),
            w(0x1A00, 0, &[0]),
            w(0x1A00, 2, &0x6001_0008u32.to_le_bytes()),
            w(0x1A00, 0, &[2]),
            w(0x1800, 1, &0x0000_0285u32.to_le_bytes()),
            w(0x2000, 0, &[3]),
        ]
    );
    // The heartbeat goes last, written by the boot process after every step.
    assert_eq!(cfg.heartbeat_producer_ms, Some(100));
}

#[test]
fn mapping_only_change_still_disables_and_reenables_at_the_comm_index() {
    let d = dcf(&[
        (0x1400, 1, 7, "rw", "$NODEID+0x200", None),
        (0x1600, 0, 5, "rw", "1", Some("1")),
        (0x1600, 1, 7, "rw", "0x62000108", Some("0x62000208")),
        (0x1300, 0, 5, "rw", "0", Some("1")),
    ]);
    assert_eq!(
        steps(&d),
        [
            w(0x1300, 0, &[1]),
            w(0x1400, 1, &0x8000_0205u32.to_le_bytes()),
            w(0x1600, 0, &[0]),
            w(0x1600, 1, &0x6200_0208u32.to_le_bytes()),
            w(0x1600, 0, &[1]),
            w(0x1400, 1, &0x0000_0205u32.to_le_bytes()),
        ]
    );
}

#[test]
fn comm_only_change_leaves_the_mapping_and_a_pdo_left_invalid_is_written_once() {
    let d = dcf(&[
        (
            0x1801,
            1,
            7,
            "rw",
            "$NODEID+0x280",
            Some("$NODEID+0x80000280"),
        ),
        (0x1801, 5, 6, "rw", "0", Some("50")),
        (0x1A01, 0, 5, "rw", "2", Some("2")),
    ]);
    assert_eq!(
        steps(&d),
        [
            w(0x1801, 1, &0x8000_0285u32.to_le_bytes()),
            w(0x1801, 5, &[50, 0]),
        ]
    );
}

#[test]
fn a_heartbeat_set_by_the_builder_is_kept_and_the_dcf_value_written_in_order() {
    let d = dcf(&[(0x1017, 0, 6, "rw", "0", Some("100"))]);
    let cfg = SlaveConfig::new(NodeId::must(5))
        .heartbeat(200, 500)
        .with_dcf(&d);
    assert_eq!(cfg.heartbeat_producer_ms, Some(200));
    assert_eq!(cfg.steps, [w(0x1017, 0, &[100, 0])]);
}

#[test]
fn srdo_configuration_valid_is_written_last_whenever_an_srdo_object_is() {
    // 0x13FE sorts before 0x13FF, whose write clears it on the slave: it goes last, written
    // even though 0xA5 is its default.
    let d = dcf(&[
        (0x1301, 2, 6, "rw", "25", Some("40")),
        (0x13FE, 0, 5, "rw", "0xA5", Some("0xA5")),
        (0x13FF, 1, 6, "rw", "0", Some("0x2034")),
        (0x2000, 0, 5, "rw", "0", Some("1")),
    ]);
    assert_eq!(
        steps(&d),
        [
            w(0x1301, 2, &[40, 0]),
            w(0x13FF, 1, &[0x34, 0x20]),
            w(0x2000, 0, &[1]),
            w(0x13FE, 0, &[0xA5]),
        ]
    );
    // No SRDO object written and 0x13FE at its default: nothing.
    let d = dcf(&[
        (0x13FE, 0, 5, "rw", "0xA5", Some("0xA5")),
        (0x2000, 0, 5, "rw", "0", Some("1")),
    ]);
    assert_eq!(steps(&d), [w(0x2000, 0, &[1])]);
}
