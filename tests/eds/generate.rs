//! A large EDS as vendors write them, generated (not committed): VARs of every numeric type,
//! records, `CompactSubObj` arrays, `$NODEID` defaults, limits, comments and keys in mixed
//! case. Shared with `benches/eds.rs`.

use std::fmt::Write;

/// Data types cycled through (type index, a default).
const TYPES: [(u16, &str); 8] = [
    (0x0005, "0x12"),
    (0x0006, "1000"),
    (0x0007, "$NODEID+0x4000"),
    (0x0003, "-200"),
    (0x0004, "0xFFFFFF00"),
    (0x0008, "1.25"),
    (0x0009, "text value"),
    (0x001B, "0x123456789"),
];

/// An EDS describing exactly `entries` entries (at least 8).
pub fn eds(entries: usize) -> String {
    assert!(entries >= 8);
    let mut body = String::new();
    let mut indices = Vec::new();
    // 0x1000, 0x1001 and 0x1018 (five entries): seven.
    let mut left = entries - 7;
    let mut index = 0x2000u16;
    let mut n = 0usize;
    while left > 0 {
        let (t, default) = TYPES[n % TYPES.len()];
        let _ = writeln!(body, "\n; object {n}");
        if n % 10 == 3 && left >= 9 {
            let _ = write!(
                body,
                "[{index:04X}]\nParameterName=Record {n}\nObjectType=0x9\nSubNumber=9\n\n[{index:04X}sub0]\nParameterName=Highest sub-index supported\nObjectType=0x7\nDataType=0x0005\nAccessType=ro\nDefaultValue=8\nPDOMapping=0\n"
            );
            for sub in 1..=8 {
                let _ = write!(
                    body,
                    "\n[{index:04X}sub{sub:X}]\nParameterName=Field {sub} of {n}\nObjectType=0x7\nDataType=0x0007\nAccessType=rw\nDefaultValue=0x{sub:X}\nPDOMapping=1\nLowLimit=0\nHighLimit=0xFFFF\n"
                );
            }
            left -= 9;
        } else if n % 10 == 7 && left >= 17 {
            let _ = write!(
                body,
                "[{index:04X}]\nparametername=Array {n}\nobjecttype=0x8\ncompactsubobj=16\ndatatype=0x0006\naccesstype=rww\ndefaultvalue=0 ; zero\npdomapping=1\n"
            );
            left -= 17;
        } else {
            let limits = if t == 0x0006 {
                "LowLimit=10\nHighLimit=60000\n"
            } else {
                ""
            };
            let _ = write!(
                body,
                "[{index:04X}]\nParameterName=Variable {n}\nObjectType=0x7\nDataType=0x{t:04X}\nAccessType=rw\nDefaultValue={default}\nPDOMapping=0\n{limits}"
            );
            left -= 1;
        }
        indices.push(index);
        index += 1;
        n += 1;
    }
    let mut out = String::from(
        "[FileInfo]\nFileName=large.eds\nFileVersion=1\nFileRevision=2\nEDSVersion=4.0\nDescription=A generated device\nCreatedBy=duocan tests\n\n[DeviceInfo]\nVendorName=duocan tests\nVendorNumber=0xD0CA\nProductName=Large device\nProductNumber=2\nRevisionNumber=1\nBaudRate_125=1\nBaudRate_250=1\nBaudRate_500=1\nBaudRate_1000=1\nSimpleBootUpSlave=1\nGranularity=8\nNrOfRXPDO=0\nNrOfTXPDO=0\nLSS_Supported=0\n\n[MandatoryObjects]\nSupportedObjects=3\n1=0x1000\n2=0x1001\n3=0x1018\n\n[OptionalObjects]\nSupportedObjects=0\n\n[ManufacturerObjects]\n",
    );
    let _ = writeln!(out, "SupportedObjects={}", indices.len());
    for (i, index) in indices.iter().enumerate() {
        let _ = writeln!(out, "{}=0x{index:04X}", i + 1);
    }
    out.push_str(
        "\n[1000]\nParameterName=Device type\nObjectType=0x7\nDataType=0x0007\nAccessType=ro\nDefaultValue=0x191\nPDOMapping=0\n\n[1001]\nParameterName=Error register\nObjectType=0x7\nDataType=0x0005\nAccessType=ro\nDefaultValue=0\nPDOMapping=1\n\n[1018]\nParameterName=Identity object\nObjectType=0x9\nSubNumber=5\n",
    );
    for (sub, name, v) in [
        (0, "Highest sub-index supported", "4"),
        (1, "Vendor-ID", "0xD0CA"),
        (2, "Product code", "2"),
        (3, "Revision number", "1"),
        (4, "Serial number", "0"),
    ] {
        let t = if sub == 0 { "0x0005" } else { "0x0007" };
        let _ = write!(
            out,
            "\n[1018sub{sub}]\nParameterName={name}\nObjectType=0x7\nDataType={t}\nAccessType=ro\nDefaultValue={v}\nPDOMapping=0\n"
        );
    }
    out.push_str(&body);
    out
}
