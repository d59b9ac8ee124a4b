//! The answer to `help`: the requests and data types, as `#` comment lines a 309-3 client
//! skips, then `OK`.

const HELP: &str = "\
requests: [\"[\"<sequence>\"]\"] [[<net>] <node>] <command>
[[<net>] <node>] r[ead] <index> <sub> [<type>]   SDO upload (no type: hex bytes)
[[<net>] <node>] w[rite] <index> <sub> <type> <value>   SDO download
[[<net>] <node>] start | stop | preop[erational]   NMT (node 0: all nodes)
[[<net>] <node>] reset node | reset comm[unication]   NMT
[<net>] set network 1 | set node <1-127>   defaults for the requests that name none
[<net>] set sdo_timeout <ms> | set sdo_block <0|1>   this client's SDO transfers
info version | help
types: b i8 i16 i24 i32 i40 i48 i56 i64 u8 … u64 x8 x16 x32 x64 r32 r64
       vs (\"quoted\", \"\" for a quote) os us d (base64) t td (<days> <ms>) hex
answers: OK | <value> | ERROR: <code> (100-107) | ERROR: 0x<SDO abort code>
not supported (ERROR: 100): guarding, heartbeat set-up, PDOs, init, LSS";

/// The help text, each line a comment, and `OK` last.
pub fn text() -> String {
    let mut s = String::new();
    for line in HELP.lines() {
        s.push_str("# ");
        s.push_str(line);
        s.push('\n');
    }
    s.push_str("OK");
    s
}
