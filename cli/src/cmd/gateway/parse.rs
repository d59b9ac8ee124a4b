//! A CiA 309-3 request line as a [`Request`], or the 309-3 error it is. Strict and total:
//! every line gives one of [`Line`]'s three answers, never a panic (a property test runs this
//! on any string); an error says in its [`Bad::why`] what was wrong.
//!
//! ```text
//! "[" <sequence> "]" [[<net>] <node>] <command> [<argument>…] ["#" <comment>]
//! ```
//!
//! The sequence number is part of every request (309-3 writes it so, and CANopenNode's gateway
//! refuses a request without it): a line without one is a syntax error, not a request.
//!
//! Words are separated by spaces or tabs; a word in double quotes may hold spaces (a quote
//! inside doubled). `#` outside quotes starts a comment. Numbers are decimal or `0x` hex.
//! Commands and data types are case-insensitive. Before the command come zero, one (the node)
//! or two (net and node) numbers; the command is the first word that does not start with a
//! digit.

pub use super::error::{Bad, Code};
use super::lss::{parse_lss, LssRequest};
use super::value::{encode_value, DataType, Word};
use crate::args::parse_int;

/// Which page `help` shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HelpPage {
    /// The requests (`help`).
    Requests,
    /// The data types (`help datatype`).
    DataTypes,
    /// The LSS requests (`help lss`).
    Lss,
}

/// What a request asks for.
#[derive(Clone, Debug, PartialEq)]
pub enum Command {
    /// `r[ead] <index> <sub> [<type>]` (no type: the bytes in hex).
    Read {
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// The type to show the value as.
        ty: DataType,
    },
    /// `w[rite] <index> <sub> <type> <value>`.
    Write {
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// The bytes to write.
        data: Vec<u8>,
    },
    /// `start`, `stop`, `preop[erational]`, `reset node`, `reset comm[unication]`.
    Nmt(duocan::NmtCommand),
    /// `set network <net>`.
    SetNetwork(u16),
    /// `set node <node>`.
    SetNode(u8),
    /// `set sdo_timeout <ms>`.
    SetSdoTimeout(u64),
    /// `set sdo_block <0|1>`.
    SetSdoBlock(bool),
    /// `info version`.
    Version,
    /// `help [datatype|lss]`.
    Help(HelpPage),
    /// An LSS request (`lss_…`, `_lss_fastscan`).
    Lss(LssRequest),
    /// A 309-3 request this gateway does not carry out: what it is, for the answer.
    NotSupported(&'static str),
}

impl Command {
    /// True for the commands addressed to a node (which take `[[<net>] <node>]`).
    pub fn is_for_a_node(&self) -> bool {
        matches!(
            self,
            Command::Read { .. } | Command::Write { .. } | Command::Nmt(_)
        )
    }
}

/// A request: its sequence number, net and node as given, and the command.
#[derive(Clone, Debug, PartialEq)]
pub struct Request {
    /// The sequence number, echoed in the response.
    pub seq: u32,
    /// The net, if given.
    pub net: Option<u16>,
    /// The node, if given.
    pub node: Option<u8>,
    /// What to do.
    pub command: Command,
}

/// What a line is.
#[derive(Clone, Debug, PartialEq)]
pub enum Line {
    /// Blank, or only a comment: no response.
    Empty,
    /// A request.
    Request(Request),
    /// An error to answer at once (with the sequence number, if it could be read).
    Error(Option<u32>, Bad),
}

/// Longest object index, sub-index, node… word accepted: longer is a syntax error, not a
/// number parsed for ever.
const MAX_NUMBER_CHARS: usize = 24;

/// Reads one line (without its line end).
pub fn parse_line(line: &str) -> Line {
    let line = line.strip_suffix('\r').unwrap_or(line);
    let words = match split(line) {
        Ok(w) => w,
        Err(why) => return Line::Error(sequence_of(line), Bad::syntax(why)),
    };
    if words.is_empty() {
        return Line::Empty;
    }
    let seq = match words.first().filter(|w| !w.quoted) {
        Some(w) => match w.text.strip_prefix('[').and_then(|t| t.strip_suffix(']')) {
            Some(n) => match number::<u32>(n) {
                Some(n) => n,
                None => {
                    let why = format!("{}: a sequence number is 0 to 4294967295", w.text);
                    return Line::Error(None, Bad::syntax(why));
                }
            },
            None => {
                let why = "a request starts with its sequence number: [<sequence>]";
                return Line::Error(None, Bad::syntax(why));
            }
        },
        None => return Line::Error(None, Bad::syntax("a request starts with [<sequence>]")),
    };
    match request(&words[1..]) {
        Ok((net, node, command)) => Line::Request(Request {
            seq,
            net,
            node,
            command,
        }),
        Err(bad) => Line::Error(Some(seq), bad),
    }
}

/// The words after the sequence number: `[[<net>] <node>] <command> …`.
fn request(words: &[Word]) -> Result<(Option<u16>, Option<u8>, Command), Bad> {
    // [[<net>] <node>]: the numbers before the command.
    let n_numbers = words
        .iter()
        .take_while(|w| !w.quoted && w.text.starts_with(|c: char| c.is_ascii_digit()))
        .count();
    let mut ids = Vec::with_capacity(2);
    for w in &words[..n_numbers.min(3)] {
        let n = number::<u32>(&w.text)
            .ok_or_else(|| Bad::syntax(format!("{}: not a net or node number", w.text)))?;
        ids.push(n);
    }
    let Some((cmd, args)) = words[n_numbers..].split_first() else {
        return Err(Bad::syntax("no command"));
    };
    if cmd.quoted {
        return Err(Bad::syntax(format!(
            "\"{}\": a command is not quoted",
            cmd.text
        )));
    }
    let command = command(&cmd.text.to_ascii_lowercase(), args)?;
    if let Command::NotSupported(_) = command {
        // Whatever it is addressed to, the answer is the same.
        return Ok((None, None, command));
    }
    // `[<net>] set …`, `[<net>] lss_…`: a single number is the net, as 309-3 writes them.
    let (net, node) = match (ids.as_slice(), command.is_for_a_node()) {
        ([], _) => (None, None),
        ([node], true) => (None, Some(*node)),
        ([net], false) => (Some(*net), None),
        ([net, node], true) => (Some(*net), Some(*node)),
        _ => {
            let why = if command.is_for_a_node() {
                "more than <net> <node> before the command"
            } else {
                "this command takes at most a net before it"
            };
            return Err(Bad::syntax(why));
        }
    };
    // A net or node out of range is its own error, once the request is known to be well formed.
    let net = match net.map(u16::try_from) {
        Some(Ok(n)) => Some(n),
        Some(Err(_)) => return Err(Bad::because(Code::UnsupportedNet, "a net is 0 to 65535")),
        None => None,
    };
    let node = match node.map(u8::try_from) {
        Some(Ok(n)) if n <= 127 => Some(n),
        Some(_) => return Err(Bad::because(Code::UnsupportedNode, "a node is 0 to 127")),
        None => None,
    };
    Ok((net, node, command))
}

/// The sequence number at the start of a line that cannot be split into words (an open
/// quote), so that its error still says which request it answers.
fn sequence_of(line: &str) -> Option<u32> {
    let w = line.split_ascii_whitespace().next()?;
    w.strip_prefix('[')?.strip_suffix(']').and_then(number)
}

/// A number of type `T`: decimal, or `0x` hex.
fn number<T: TryFrom<i128>>(s: &str) -> Option<T> {
    if s.len() > MAX_NUMBER_CHARS {
        return None;
    }
    parse_int(s, false).ok().and_then(|v| T::try_from(v).ok())
}

/// The words of a line, up to a comment; an error if a quote is not closed, or a closing
/// quote is followed by anything but a space.
fn split(line: &str) -> Result<Vec<Word>, &'static str> {
    let mut words = Vec::new();
    let mut chars = line.chars().peekable();
    loop {
        while chars.next_if(|c| *c == ' ' || *c == '\t').is_some() {}
        match chars.peek() {
            None | Some('#') => return Ok(words),
            Some('"') => {
                chars.next();
                let mut text = String::new();
                loop {
                    match chars.next().ok_or("a quote is not closed")? {
                        '"' if chars.next_if_eq(&'"').is_some() => text.push('"'),
                        '"' => break,
                        c => text.push(c),
                    }
                }
                if chars.peek().is_some_and(|c| *c != ' ' && *c != '\t') {
                    return Err("a closing quote is followed by more than a space");
                }
                words.push(Word { text, quoted: true });
            }
            Some(_) => {
                let mut text = String::new();
                while let Some(c) = chars.next_if(|c| !matches!(c, ' ' | '\t' | '#' | '"')) {
                    text.push(c);
                }
                if chars.peek() == Some(&'"') {
                    return Err("a quote inside a word");
                }
                words.push(Word {
                    text,
                    quoted: false,
                });
            }
        }
    }
}

fn bare(w: &Word) -> Result<&str, Bad> {
    if w.quoted {
        Err(Bad::syntax(format!(
            "\"{}\": not a quoted word here",
            w.text
        )))
    } else {
        Ok(&w.text)
    }
}

/// The word `w` as a number of type `T` (`what` says which, for the error).
pub fn number_arg<T: TryFrom<i128>>(w: &Word, what: &str) -> Result<T, Bad> {
    number(bare(w)?).ok_or_else(|| Bad::syntax(format!("{}: not {what}", w.text)))
}

/// The command `name` (lower case) with its arguments.
fn command(name: &str, args: &[Word]) -> Result<Command, Bad> {
    use duocan::NmtCommand as N;
    let none = |c: Command| {
        if args.is_empty() {
            Ok(c)
        } else {
            Err(Bad::syntax(format!("{name} takes no argument")))
        }
    };
    let sub = args.first().map(|w| w.text.to_ascii_lowercase());
    let sub = sub.as_deref();
    match name {
        "r" | "read" => match sub {
            // `r[ead] p[do] …`: reading a PDO through the gateway.
            Some("p" | "pdo") => Ok(Command::NotSupported("PDO read")),
            _ => read(args),
        },
        "w" | "write" => match sub {
            Some("p" | "pdo") => Ok(Command::NotSupported("PDO write")),
            _ => write(args),
        },
        "start" => none(Command::Nmt(N::Start)),
        "stop" => none(Command::Nmt(N::Stop)),
        "preop" | "preoperational" => none(Command::Nmt(N::EnterPreOperational)),
        "reset" => match (sub, args.len()) {
            (Some("node"), 1) => Ok(Command::Nmt(N::ResetNode)),
            (Some("comm" | "communication"), 1) => Ok(Command::Nmt(N::ResetCommunication)),
            _ => Err(Bad::syntax("reset node | reset comm[unication]")),
        },
        "set" => set(sub, args),
        "info" => match (sub, args.len()) {
            (Some("version"), 1) => Ok(Command::Version),
            _ => Err(Bad::syntax("info version")),
        },
        "help" => match (sub, args.len()) {
            (None, _) => Ok(Command::Help(HelpPage::Requests)),
            (Some("datatype"), 1) => Ok(Command::Help(HelpPage::DataTypes)),
            (Some("lss"), 1) => Ok(Command::Help(HelpPage::Lss)),
            _ => Err(Bad::syntax("help [datatype|lss]")),
        },
        // 309-3 requests, and CANopenNode's, that this gateway does not carry out: node
        // guarding, heartbeat consumer set-up, gateway initialisation, boot-up forwarding,
        // CANopenNode's LED and log.
        "enable" | "disable" => match sub {
            Some("guarding") => Ok(Command::NotSupported("node guarding")),
            Some("heartbeat") => Ok(Command::NotSupported("heartbeat consumer set-up")),
            _ => Err(Bad::syntax(format!("{name} guarding | {name} heartbeat"))),
        },
        "init" => Ok(Command::NotSupported("init")),
        "boot_up_indication" => Ok(Command::NotSupported("boot-up indication")),
        "led" => Ok(Command::NotSupported("led")),
        "log" => Ok(Command::NotSupported("log")),
        n if n.starts_with("lss_") || n.starts_with("_lss_") => {
            parse_lss(n, args).map(Command::Lss)
        }
        _ => Err(Bad::because(
            Code::NotSupported,
            format!("{name}: not a request (help lists them)"),
        )),
    }
}

fn index_sub(args: &[Word]) -> Result<(u16, u8), Bad> {
    match args {
        [i, s, ..] => Ok((
            number_arg(i, "an index (0 to 0xFFFF)")?,
            number_arg(s, "a sub-index (0 to 255)")?,
        )),
        _ => Err(Bad::syntax("give <index> <sub-index>")),
    }
}

fn data_type(w: &Word) -> Result<DataType, Bad> {
    DataType::parse(bare(w)?).ok_or_else(|| {
        Bad::syntax(format!(
            "{}: not a data type (help datatype lists them)",
            w.text
        ))
    })
}

fn read(args: &[Word]) -> Result<Command, Bad> {
    let (index, sub) = index_sub(args)?;
    let ty = match &args[2..] {
        [] => DataType::Bytes,
        [t] => data_type(t)?,
        _ => {
            return Err(Bad::syntax(
                "r[ead] <index> <sub-index> [<type>]: one word too many",
            ))
        }
    };
    Ok(Command::Read { index, sub, ty })
}

fn write(args: &[Word]) -> Result<Command, Bad> {
    let (index, sub) = index_sub(args)?;
    let (ty, value) = match &args[2..] {
        [t, value @ ..] => (data_type(t)?, value),
        [] => return Err(Bad::syntax("w[rite] <index> <sub-index> <type> <value>")),
    };
    let data = encode_value(ty, value).map_err(Bad::syntax)?;
    Ok(Command::Write { index, sub, data })
}

fn set(what: Option<&str>, args: &[Word]) -> Result<Command, Bad> {
    let unsupported = match what {
        Some("heartbeat") => Some("set heartbeat"),
        Some("id") => Some("set id"),
        Some("command_timeout" | "command_size") => Some("set command_*"),
        Some("rpdo" | "tpdo" | "tpdox") => Some("PDO configuration"),
        _ => None,
    };
    if let Some(what) = unsupported {
        return Ok(Command::NotSupported(what));
    }
    let value = match args {
        [_, v] => v,
        _ => return Err(Bad::syntax("set <what> <value>")),
    };
    match what {
        // The net is not checked here: see `exec` for what a net number means.
        Some("network") => number_arg(value, "a net (0 to 65535)").map(Command::SetNetwork),
        Some("node") => {
            let n: u32 = number_arg(value, "a node (1 to 127)")?;
            match u8::try_from(n) {
                Ok(n @ 1..=127) => Ok(Command::SetNode(n)),
                _ => Err(Bad::because(
                    Code::UnsupportedNode,
                    "a default node is 1 to 127",
                )),
            }
        }
        Some("sdo_timeout") => number(bare(value)?)
            .filter(|ms| (1..=crate::args::MAX_TIMEOUT_MS).contains(ms))
            .map(Command::SetSdoTimeout)
            .ok_or_else(|| {
                let max = crate::args::MAX_TIMEOUT_MS;
                Bad::syntax(format!("{}: an SDO time-out is 1 to {max} ms", value.text))
            }),
        Some("sdo_block") => match bare(value)? {
            "0" => Ok(Command::SetSdoBlock(false)),
            "1" => Ok(Command::SetSdoBlock(true)),
            v => Err(Bad::syntax(format!("{v}: sdo_block is 0 or 1"))),
        },
        _ => Err(Bad::because(
            Code::NotSupported,
            format!("set {}: not a setting", what.unwrap_or_default()),
        )),
    }
}
