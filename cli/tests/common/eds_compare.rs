//! Two device descriptions compared entry by entry: what `eds export` of a live node keeps of
//! the node's own description (the tool's tests on the simulated nodes, and the vcan tier's on
//! CANopenNode's canopend, which includes this file).

use duocan::eds::Description;
use duocan::od::{Access, ObjectDictionary};
use std::ops::RangeInclusive;
use std::path::Path;

/// A description read strictly enough to compare: a panic naming the file when it cannot be.
pub fn read_eds(path: &Path) -> Description {
    Description::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The ways `got` differs from `want`, both read for node `node`, over the entries of `want`
/// with an index in `range`: an entry missing, or another data type, object type, access or
/// value (a default, or the value read). `const` and `ro` are the same access here: both are
/// read-only, and SDO cannot tell them apart.
pub fn differences(
    want: &Description,
    got: &Description,
    node: u8,
    range: RangeInclusive<u16>,
) -> Vec<String> {
    let (want, got) = (want.dictionary(node), got.dictionary(node));
    let read_only = |a: Access| if a == Access::Const { Access::Ro } else { a };
    let mut out = Vec::new();
    want.for_each(&mut |w| {
        let (index, sub) = (w.def.index, w.def.sub);
        if !range.contains(&index) {
            return;
        }
        let at = format!("{index:04X}sub{sub} ({})", w.name);
        let Ok(g) = got.get(index, sub) else {
            out.push(format!("{at}: missing"));
            return;
        };
        if g.def.data_type != w.def.data_type {
            out.push(format!(
                "{at}: type {:?}, not {:?}",
                g.def.data_type, w.def.data_type
            ));
        }
        if g.def.object_type != w.def.object_type {
            out.push(format!(
                "{at}: object type {:?}, not {:?}",
                g.def.object_type, w.def.object_type
            ));
        }
        if read_only(g.def.access) != read_only(w.def.access) {
            out.push(format!(
                "{at}: access {:?}, not {:?}",
                g.def.access, w.def.access
            ));
        }
        if g.data != w.data {
            out.push(format!("{at}: value {:02X?}, not {:02X?}", g.data, w.data));
        }
    });
    out.sort();
    out
}
