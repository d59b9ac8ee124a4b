//! The answer to `help`, `help datatype` and `help lss`: the page as `#` comment lines a 309-3
//! client skips, then `OK`.

use super::parse::HelpPage;

const REQUESTS: &str = "\
requests: \"[\"<sequence>\"]\" [[<net>] <node>] <command>   (# starts a comment)
[[<net>] <node>] r[ead] <index> <sub> [<type>]   SDO upload (no type: hex bytes)
[[<net>] <node>] w[rite] <index> <sub> <type> <value>   SDO download
[[<net>] <node>] start | stop | preop[erational]   NMT (node 0: all nodes)
[[<net>] <node>] reset node | reset comm[unication]   NMT
[<net>] set network <net> | set node <1-127>   defaults for the requests that name none
[<net>] set sdo_timeout <ms> | set sdo_block <0|1>   this client's SDO transfers
[<net>] lss_...   LSS master (help lss)
info version | help [datatype|lss]
answers: [<sequence>] OK | <value> | ERROR:<code> #<meaning>
  codes: 100-107 (309-3's), 501-504 (LSS), 0x<SDO abort code>
a blank line or a comment is answered with an empty line
not supported (ERROR:100): guarding, heartbeat set-up, PDOs, init, led, log";

const DATA_TYPES: &str = "\
data types (w[rite] takes, r[ead] shows):
b   boolean, a number
i8 i16 i24 i32 i40 i48 i56 i64   signed integers (decimal; written also 0x...)
u8 u16 u24 u32 u40 u48 u56 u64   unsigned integers
x8 x16 x32 x64   unsigned integers shown as 0x and hex digits
r32 r64   real numbers (read: six significant digits, as C's %g)
vs   visible string: \"in quotes\", a quote doubled; one word may be bare
os us d   octet string, unicode string, domain: base64 on one line
t td   time of day, time difference: <days> <ms>
hex   bytes as hex pairs, spaces between
a value read whose size is not its type's shows as hex";

const LSS: &str = "\
LSS requests ([<net>] before each):
lss_switch_glob <0|1>   every slave to waiting (0) or configuration (1)
lss_switch_sel <vendor> <product> <revision> <serial>   that slave to configuration
lss_set_node <1-127|255>   node-ID of the slave in configuration (255: none)
lss_conf_bitrate 0 <index>   bit rate: 0 1000, 1 800, 2 500, 3 250, 4 125,
    6 50, 7 20, 8 10 kbit/s, 9 automatic
lss_activate_bitrate <delay_ms>   the slaves in configuration switch to it
lss_store   the slave in configuration stores node-ID and bit rate
lss_inquire_addr [<0-3>]   its vendor, product, revision, serial (one or all)
lss_get_node   its node-ID
_lss_fastscan [<ms>]   the first slave without a node-ID, left in configuration
lss_allnodes [<ms> [<first> <store> [<scan type> <value> x4]]]
    every slave without a node-ID gets one, from <first> (2) up
answers: OK | 0x<hex>... | ERROR:103 (no answer) | ERROR:501-504 (refused)";

/// The page, each line a comment, and `OK` last.
pub fn text(page: HelpPage) -> String {
    let body = match page {
        HelpPage::Requests => REQUESTS,
        HelpPage::DataTypes => DATA_TYPES,
        HelpPage::Lss => LSS,
    };
    let mut s = String::new();
    for line in body.lines() {
        s.push_str("# ");
        s.push_str(line);
        s.push('\n');
    }
    s.push_str("OK");
    s
}
