//! The CiA 309-3 request lines of `duocan gateway` (from standard input or a TCP client): any
//! bytes, line by line, through the tool's parser. Never a panic; a line is empty, a request
//! or an error; a request for a node names one of 0–127 and net at most 65535. The value
//! text both ways: any bytes shown as any 309-3 type give one line; a visible string shown
//! reads back as the same bytes when written; base64 reads back.
#![no_main]
// The tool's modules, included as they are: the fuzz target uses a part of them.
#![allow(dead_code, unused_imports)]

#[path = "../../cli/src/args/mod.rs"]
mod args;

// Side by side at the root, as in the tool's gateway module: `parse` uses `super::value`,
// `super::error` and `super::lss`.
#[path = "../../cli/src/cmd/gateway/error.rs"]
mod error;
#[path = "../../cli/src/cmd/gateway/lss.rs"]
mod lss;
#[path = "../../cli/src/cmd/gateway/parse.rs"]
mod parse;
#[path = "../../cli/src/cmd/gateway/value.rs"]
mod value;

use libfuzzer_sys::fuzz_target;
use parse::{parse_line, Command, Line};
use value::{base64_decode, base64_encode, show_value, DataType};

const TYPES: [&str; 16] = [
    "b", "i8", "i24", "i64", "u16", "u56", "x8", "x64", "r32", "r64", "vs", "os", "d", "t",
    "td", "hex",
];

fuzz_target!(|data: &[u8]| {
    for raw in data.split(|b| *b == b'\n') {
        let Ok(line) = std::str::from_utf8(raw) else {
            continue;
        };
        match parse_line(line) {
            Line::Empty | Line::Error(..) => {}
            Line::Request(r) => {
                assert!(r.node.is_none_or(|n| n <= 127), "{line:?}: {r:?}");
                if let Command::SetNode(n) = r.command {
                    assert!((1..=127).contains(&n), "{line:?}");
                }
            }
        }
    }
    for ty in TYPES {
        let t = DataType::parse(ty).expect("a 309-3 type");
        let text = show_value(t, data);
        assert!(!text.contains(['\n', '\r']), "{ty}: {text:?}");
    }
    let coded = base64_encode(data);
    assert_eq!(base64_decode(&coded).as_deref(), Some(data));
    if let Ok(text) = std::str::from_utf8(data) {
        if !text.contains(|c: char| c.is_control()) && !text.ends_with('\0') {
            let shown = show_value(DataType::Visible, data);
            match parse_line(&format!("[1] w 0x2000 0 vs {shown}")) {
                Line::Request(r) => assert_eq!(
                    r.command,
                    Command::Write {
                        index: 0x2000,
                        sub: 0,
                        data: data.to_vec()
                    }
                ),
                other => panic!("{shown:?}: {other:?}"),
            }
        }
    }
});
