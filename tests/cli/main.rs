//! The command-line tools' argument parsing, run on any string: `sdo_tool`'s numbers, node-IDs,
//! values and ports (the parser is the example's own `args.rs`).

#[allow(dead_code)]
#[path = "../../examples/sdo_tool/args.rs"]
mod args;

mod sdo_tool_args;
