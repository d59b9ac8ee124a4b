//! The arguments of `duocan lss` as text: bit rates, identity ranges, node-IDs to configure and
//! the fastscan plan file. Strict and total like the tool's other parsers ([`crate::args`]):
//! every string gives a value or an error that quotes it, never a panic.

use crate::args::{parse_node, parse_unsigned};
use duocan::cia305::{BitTiming, LssAddress};
use duocan::NodeId;

/// The bit rates of the CiA 301 table, in kbit/s, and their table index.
pub const BIT_RATES: [(u16, u8); 8] = [
    (1000, 0),
    (800, 1),
    (500, 2),
    (250, 3),
    (125, 4),
    (50, 6),
    (20, 7),
    (10, 8),
];

/// A bit rate in kbit/s as the CiA 301 table entry LSS configures.
pub fn parse_kbit(s: &str) -> Result<BitTiming, String> {
    let kbit: u16 = parse_unsigned(s, "a bit rate in kbit/s")?;
    BIT_RATES
        .iter()
        .find(|(k, _)| *k == kbit)
        .map(|(_, i)| BitTiming::standard(*i))
        .ok_or_else(|| {
            let list: Vec<String> = BIT_RATES.iter().map(|(k, _)| k.to_string()).collect();
            format!(
                "{s} kbit/s is not in the CiA 301 table: give {}",
                list.join(", ")
            )
        })
}

/// A 32-bit identity part (decimal or 0x hex).
pub fn parse_part(s: &str) -> Result<u32, String> {
    parse_unsigned(s, "a 32-bit identity part (0-0xFFFFFFFF)")
}

/// An identity as one argument: `VENDOR:PRODUCT:REVISION:SERIAL`.
pub fn parse_address(s: &str) -> Result<LssAddress, String> {
    let parts: Vec<&str> = s.split(':').collect();
    let [v, p, r, n] = parts.as_slice() else {
        return Err(format!("{s:?}: give VENDOR:PRODUCT:REVISION:SERIAL"));
    };
    Ok(LssAddress::from_parts([
        parse_part(v)?,
        parse_part(p)?,
        parse_part(r)?,
        parse_part(n)?,
    ]))
}

/// `LOW-HIGH` (both ends included, LOW ≤ HIGH), or one value (`N`: N to N).
pub fn parse_range(s: &str) -> Result<(u32, u32), String> {
    let (lo, hi) = match s.split_once('-') {
        Some((lo, hi)) => (parse_part(lo)?, parse_part(hi)?),
        None => {
            let v = parse_part(s)?;
            (v, v)
        }
    };
    if lo > hi {
        return Err(format!("{s}: the low end is above the high end"));
    }
    Ok((lo, hi))
}

/// The node-ID `lss set-id` gives: 1–127, or `none` (0xFF: the slave has none).
pub fn parse_lss_node(s: &str) -> Result<u8, String> {
    if s == "none" {
        return Ok(duocan::cia305::codec::UNCONFIGURED);
    }
    parse_node(s)
        .map(NodeId::raw)
        .map_err(|e| format!("{e} (or `none`)"))
}

/// One line of a plan: the identity (a part `*` is not checked) and the node-ID it gets.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PlanLine {
    /// The identity; a part 0 where the line had `*`.
    pub address: LssAddress,
    /// Whether every part was given (an exact identity) or some were `*`.
    pub exact: bool,
    /// The node-ID.
    pub node: NodeId,
}

/// A fastscan plan: one line per board, `VENDOR PRODUCT REVISION SERIAL NODE`, numbers decimal
/// or 0x hex, a part `*` where any value will do (a replacement board whose serial is not
/// known); blank lines and `#` comments are ignored. An error names the line.
pub fn parse_plan(text: &str) -> Result<Vec<PlanLine>, String> {
    let mut lines = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let line = line.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let at = |e: String| format!("line {}: {e}", n + 1);
        let words: Vec<&str> = line.split_ascii_whitespace().collect();
        let [v, p, r, s, node] = words.as_slice() else {
            return Err(at(format!(
                "{line:?}: give VENDOR PRODUCT REVISION SERIAL NODE (a part may be *)"
            )));
        };
        let mut exact = true;
        let mut part = |w: &str| -> Result<u32, String> {
            if w == "*" {
                exact = false;
                Ok(0)
            } else {
                parse_part(w).map_err(at)
            }
        };
        let parts = [part(v)?, part(p)?, part(r)?, part(s)?];
        let node = parse_node(node).map_err(at)?;
        if !exact && parts.iter().all(|p| *p == 0) {
            return Err(at(
                "every part is * or 0: such a line would take any board".into()
            ));
        }
        if lines.iter().any(|l: &PlanLine| l.node == node) {
            return Err(at(format!("node-ID {} is planned twice", node.raw())));
        }
        let address = LssAddress::from_parts(parts);
        if lines
            .iter()
            .any(|l| l.exact == exact && l.address == address)
        {
            return Err(at("this identity is planned twice".into()));
        }
        lines.push(PlanLine {
            address,
            exact,
            node,
        });
    }
    Ok(lines)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn bit_rates_are_the_cia301_table() {
        assert_eq!(parse_kbit("125"), Ok(BitTiming::standard(4)));
        assert_eq!(parse_kbit("0x3E8"), Ok(BitTiming::standard(0)));
        assert_eq!(parse_kbit("10"), Ok(BitTiming::standard(8)));
        assert_eq!(
            parse_kbit("100"),
            Err(
                "100 kbit/s is not in the CiA 301 table: give 1000, 800, 500, 250, 125, 50, 20, 10"
                    .into()
            )
        );
        for bad in ["", "-125", "125k", "1e3", " 125", "70000"] {
            assert!(parse_kbit(bad).is_err(), "{bad:?}");
        }
    }

    #[test]
    fn ranges_and_node_ids() {
        assert_eq!(parse_range("1-5"), Ok((1, 5)));
        assert_eq!(parse_range("0x10-0x20"), Ok((16, 32)));
        assert_eq!(parse_range("7"), Ok((7, 7)));
        assert_eq!(parse_range("0-0xFFFFFFFF"), Ok((0, u32::MAX)));
        assert_eq!(
            parse_range("5-1"),
            Err("5-1: the low end is above the high end".into())
        );
        for bad in ["", "-", "1-", "-1", "1--2", "1-2-3", "0x100000000", "a-b"] {
            assert!(parse_range(bad).is_err(), "{bad:?}");
        }
        assert_eq!(
            parse_address("0xD0CA00:0x305:1:2"),
            Ok(LssAddress::from_parts([0xD0CA00, 0x305, 1, 2]))
        );
        assert_eq!(
            parse_address("1:2:3"),
            Err("\"1:2:3\": give VENDOR:PRODUCT:REVISION:SERIAL".into())
        );
        for bad in ["", ":::", "1:2:3:4:5", "1:2:3:-4", "1:2:3:4 "] {
            assert!(parse_address(bad).is_err(), "{bad:?}");
        }
        assert_eq!(parse_lss_node("none"), Ok(0xFF));
        assert_eq!(parse_lss_node("0x20"), Ok(0x20));
        assert_eq!(
            parse_lss_node("0"),
            Err("node-ID 0: a node-ID is 1-127 (or `none`)".into())
        );
        assert!(parse_lss_node("255").is_err());
        assert!(parse_lss_node("None").is_err());
    }

    #[test]
    fn plan_files() {
        let text = "# boards of cabinet 3\n\
                    0x00D0CA00 0x305 1 2 0x20\n\
                    \n\
                    0x00D0CA00 0x305 * * 0x21   # a replacement, any serial\n";
        let plan = parse_plan(text).unwrap();
        assert_eq!(plan.len(), 2);
        assert_eq!(
            plan[0],
            PlanLine {
                address: LssAddress::from_parts([0xD0CA00, 0x305, 1, 2]),
                exact: true,
                node: NodeId::must(0x20),
            }
        );
        assert!(!plan[1].exact);
        assert_eq!(plan[1].address.serial, 0);
        assert_eq!(
            parse_plan("1 2 3 4\n"),
            Err(
                "line 1: \"1 2 3 4\": give VENDOR PRODUCT REVISION SERIAL NODE (a part may be *)"
                    .into()
            )
        );
        assert_eq!(
            parse_plan("1 2 3 4 5\n1 2 3 5 5\n"),
            Err("line 2: node-ID 5 is planned twice".into())
        );
        assert_eq!(
            parse_plan("1 2 3 4 5\n1 2 3 4 6\n"),
            Err("line 2: this identity is planned twice".into())
        );
        assert_eq!(
            parse_plan("* * * * 5"),
            Err("line 1: every part is * or 0: such a line would take any board".into())
        );
        assert_eq!(
            parse_plan("1 2 3 4 128"),
            Err("line 1: node-ID 128: a node-ID is 1-127".into())
        );
        assert_eq!(parse_plan(""), Ok(vec![]));
    }

    proptest! {
        #[test]
        fn no_string_panics(s in "\\PC*") {
            let _ = parse_kbit(&s);
            let _ = parse_range(&s);
            let _ = parse_lss_node(&s);
            let _ = parse_plan(&s);
            let _ = parse_address(&s);
        }

        #[test]
        fn addresses_read_back(parts in proptest::array::uniform4(any::<u32>())) {
            let s = format!("{:#x}:{}:{:#X}:{}", parts[0], parts[1], parts[2], parts[3]);
            prop_assert_eq!(parse_address(&s), Ok(LssAddress::from_parts(parts)));
        }

        #[test]
        fn plan_lines_read_back(
            parts in proptest::array::uniform4(any::<u32>()),
            node in 1u8..=127,
            hex in any::<bool>(),
        ) {
            let w = |v: u32| if hex { format!("{v:#x}") } else { v.to_string() };
            let line = format!("{} {} {} {} {}", w(parts[0]), w(parts[1]), w(parts[2]), w(parts[3]), node);
            let plan = parse_plan(&line).unwrap();
            prop_assert_eq!(plan[0].address, LssAddress::from_parts(parts));
            prop_assert_eq!(plan[0].node.raw(), node);
        }

        #[test]
        fn ranges_read_back(a in any::<u32>(), b in any::<u32>()) {
            let (lo, hi) = (a.min(b), a.max(b));
            prop_assert_eq!(parse_range(&format!("{lo}-{hi:#x}")), Ok((lo, hi)));
        }

        #[test]
        fn rates_accepted_are_the_table(k in any::<u16>()) {
            let r = parse_kbit(&k.to_string());
            prop_assert_eq!(r.is_ok(), BIT_RATES.iter().any(|(t, _)| *t == k));
            if let Ok(t) = r {
                prop_assert_eq!(t.kbit(), Some(k));
            }
        }
    }
}
