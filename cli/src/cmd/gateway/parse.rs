//! A CiA 309-3 request line as a [`Request`], or the 309-3 error it is. Strict and total:
//! every line gives one of [`Line`]'s three answers, never a panic (a property test runs this
//! on any string).
//!
//! ```text
//! ["[" <sequence> "]"] [[<net>] <node>] <command> [<argument>…] ["#" <comment>]
//! ```
//!
//! Words are separated by spaces or tabs; a word in double quotes may hold spaces (a quote
//! inside doubled). `#` outside quotes starts a comment. Numbers are decimal or `0x` hex.
//! Commands and data types are case-insensitive. Before the command come zero, one (the node)
//! or two (net and node) numbers; the command is the first word that does not start with a
//! digit.

use super::value::{encode_value, DataType, ValueError, Word};
use crate::args::parse_int;

/// The 309-3 internal error codes the gateway answers with (`ERROR: <code>`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Code {
    /// 100: the request is one of 309-3's, but not one this gateway carries out.
    NotSupported = 100,
    /// 101: the request is not well formed.
    Syntax = 101,
    /// 102: the request cannot be processed as things are (the network is closed).
    InternalState = 102,
    /// 103: a time-out (a wait that ran out, other than an SDO one: those are an abort code).
    Timeout = 103,
    /// 105: no node given, and none set with `set node`.
    NoDefaultNode = 105,
    /// 106: a net other than 1.
    UnsupportedNet = 106,
    /// 107: a node-ID outside 1–127 (0 is "all nodes" for NMT commands).
    UnsupportedNode = 107,
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
    /// `help [<topic>]`.
    Help,
    /// A 309-3 request this gateway does not carry out (named, for the help).
    NotSupported,
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
    pub seq: Option<u32>,
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
    Error(Option<u32>, Code),
}

/// Longest object index, sub-index, node… word accepted: longer is a syntax error, not a
/// number parsed for ever.
const MAX_NUMBER_CHARS: usize = 24;

/// Reads one line (without its line end).
pub fn parse_line(line: &str) -> Line {
    let line = line.strip_suffix('\r').unwrap_or(line);
    let words = match split(line) {
        Some(w) => w,
        None => return Line::Error(sequence_of(line), Code::Syntax),
    };
    if words.is_empty() {
        return Line::Empty;
    }
    let mut rest = &words[..];
    let mut seq = None;
    if let Some(first) = rest
        .first()
        .filter(|w| !w.quoted && w.text.starts_with('['))
    {
        match first
            .text
            .strip_prefix('[')
            .and_then(|t| t.strip_suffix(']'))
            .and_then(number::<u32>)
        {
            Some(n) => seq = Some(n),
            None => return Line::Error(None, Code::Syntax),
        }
        rest = &rest[1..];
    }
    let err = |code| Line::Error(seq, code);
    // [[<net>] <node>]: the numbers before the command.
    let n_numbers = rest
        .iter()
        .take_while(|w| !w.quoted && w.text.starts_with(|c: char| c.is_ascii_digit()))
        .count();
    let mut ids = Vec::with_capacity(2);
    for w in &rest[..n_numbers.min(3)] {
        match number::<u32>(&w.text) {
            Some(n) => ids.push(n),
            None => return err(Code::Syntax),
        }
    }
    rest = &rest[n_numbers..];
    let Some((cmd, args)) = rest.split_first() else {
        return err(Code::Syntax);
    };
    if cmd.quoted {
        return err(Code::Syntax);
    }
    let command = match command(&cmd.text.to_ascii_lowercase(), args) {
        Ok(c) => c,
        Err(code) => return err(code),
    };
    if command == Command::NotSupported {
        // Whatever it is addressed to, the answer is the same.
        return Line::Request(Request {
            seq,
            net: None,
            node: None,
            command,
        });
    }
    // `[<net>] set …`, `info version`: a single number is the net, as 309-3 writes them.
    let (net, node) = match (ids.as_slice(), command.is_for_a_node()) {
        ([], _) => (None, None),
        ([node], true) => (None, Some(*node)),
        ([net], false) => (Some(*net), None),
        ([net, node], true) => (Some(*net), Some(*node)),
        _ => return err(Code::Syntax),
    };
    // A net or node out of range is its own error, once the request is known to be well formed.
    let net = match net.map(u16::try_from) {
        Some(Ok(n)) => Some(n),
        Some(Err(_)) => return err(Code::UnsupportedNet),
        None => None,
    };
    let node = match node.map(u8::try_from) {
        Some(Ok(n)) if n <= 127 => Some(n),
        Some(_) => return err(Code::UnsupportedNode),
        None => None,
    };
    Line::Request(Request {
        seq,
        net,
        node,
        command,
    })
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

/// The words of a line, up to a comment; `None` if a quote is not closed, or a closing quote
/// is followed by anything but a space.
fn split(line: &str) -> Option<Vec<Word>> {
    let mut words = Vec::new();
    let mut chars = line.chars().peekable();
    loop {
        while chars.next_if(|c| *c == ' ' || *c == '\t').is_some() {}
        match chars.peek() {
            None | Some('#') => return Some(words),
            Some('"') => {
                chars.next();
                let mut text = String::new();
                loop {
                    match chars.next()? {
                        '"' if chars.next_if_eq(&'"').is_some() => text.push('"'),
                        '"' => break,
                        c => text.push(c),
                    }
                }
                if chars.peek().is_some_and(|c| *c != ' ' && *c != '\t') {
                    return None;
                }
                words.push(Word { text, quoted: true });
            }
            Some(_) => {
                let mut text = String::new();
                while let Some(c) = chars.next_if(|c| !matches!(c, ' ' | '\t' | '#' | '"')) {
                    text.push(c);
                }
                if chars.peek() == Some(&'"') {
                    return None; // a quote inside a word
                }
                words.push(Word {
                    text,
                    quoted: false,
                });
            }
        }
    }
}

fn bare(w: &Word) -> Result<&str, Code> {
    if w.quoted {
        Err(Code::Syntax)
    } else {
        Ok(&w.text)
    }
}

/// The command `name` (lower case) with its arguments.
fn command(name: &str, args: &[Word]) -> Result<Command, Code> {
    use duocan::NmtCommand as N;
    let none = |c: Command| {
        if args.is_empty() {
            Ok(c)
        } else {
            Err(Code::Syntax)
        }
    };
    let sub = args.first().map(|w| w.text.to_ascii_lowercase());
    let sub = sub.as_deref();
    match name {
        "r" | "read" => match sub {
            // `r[ead] p[do] …`: reading a PDO through the gateway.
            Some("p" | "pdo") => Ok(Command::NotSupported),
            _ => read(args),
        },
        "w" | "write" => match sub {
            Some("p" | "pdo") => Ok(Command::NotSupported),
            _ => write(args),
        },
        "start" => none(Command::Nmt(N::Start)),
        "stop" => none(Command::Nmt(N::Stop)),
        "preop" | "preoperational" => none(Command::Nmt(N::EnterPreOperational)),
        "reset" => match (sub, args.len()) {
            (Some("node"), 1) => Ok(Command::Nmt(N::ResetNode)),
            (Some("comm" | "communication"), 1) => Ok(Command::Nmt(N::ResetCommunication)),
            _ => Err(Code::Syntax),
        },
        "set" => set(sub, args),
        "info" => match (sub, args.len()) {
            (Some("version"), 1) => Ok(Command::Version),
            _ => Err(Code::Syntax),
        },
        "help" => match args.len() {
            0 | 1 => Ok(Command::Help),
            _ => Err(Code::Syntax),
        },
        // 309-3 requests, and CANopenNode's, that this gateway does not carry out: node
        // guarding, heartbeat consumer set-up, PDO configuration and transfer, gateway
        // initialisation, boot-up forwarding, LSS, CANopenNode's LED and log.
        "enable" | "disable" => match sub {
            Some("guarding" | "heartbeat") => Ok(Command::NotSupported),
            _ => Err(Code::Syntax),
        },
        "init" | "boot_up_indication" | "led" | "log" => Ok(Command::NotSupported),
        n if n.starts_with("lss_") || n.starts_with("_lss_") => Ok(Command::NotSupported),
        _ => Err(Code::NotSupported),
    }
}

fn index_sub(args: &[Word]) -> Result<(u16, u8), Code> {
    match args {
        [i, s, ..] => Ok((
            number(bare(i)?).ok_or(Code::Syntax)?,
            number(bare(s)?).ok_or(Code::Syntax)?,
        )),
        _ => Err(Code::Syntax),
    }
}

fn data_type(w: &Word) -> Result<DataType, Code> {
    DataType::parse(bare(w)?).ok_or(Code::Syntax)
}

fn read(args: &[Word]) -> Result<Command, Code> {
    let (index, sub) = index_sub(args)?;
    let ty = match &args[2..] {
        [] => DataType::Bytes,
        [t] => data_type(t)?,
        _ => return Err(Code::Syntax),
    };
    Ok(Command::Read { index, sub, ty })
}

fn write(args: &[Word]) -> Result<Command, Code> {
    let (index, sub) = index_sub(args)?;
    let (ty, value) = match &args[2..] {
        [t, value @ ..] => (data_type(t)?, value),
        [] => return Err(Code::Syntax),
    };
    let data = encode_value(ty, value).map_err(|e| match e {
        ValueError::Syntax | ValueError::Length => Code::Syntax,
    })?;
    Ok(Command::Write { index, sub, data })
}

fn set(what: Option<&str>, args: &[Word]) -> Result<Command, Code> {
    if let Some(
        "heartbeat" | "id" | "command_timeout" | "command_size" | "rpdo" | "tpdo" | "tpdox",
    ) = what
    {
        return Ok(Command::NotSupported);
    }
    let value = match args {
        [_, v] => bare(v)?,
        _ => return Err(Code::Syntax),
    };
    match what {
        Some("network") => number(value).map(Command::SetNetwork).ok_or(Code::Syntax),
        Some("node") => {
            let n: u32 = number(value).ok_or(Code::Syntax)?;
            match u8::try_from(n) {
                Ok(n @ 1..=127) => Ok(Command::SetNode(n)),
                _ => Err(Code::UnsupportedNode),
            }
        }
        Some("sdo_timeout") => number(value)
            .filter(|ms| (1..=crate::args::MAX_TIMEOUT_MS).contains(ms))
            .map(Command::SetSdoTimeout)
            .ok_or(Code::Syntax),
        Some("sdo_block") => match value {
            "0" => Ok(Command::SetSdoBlock(false)),
            "1" => Ok(Command::SetSdoBlock(true)),
            _ => Err(Code::Syntax),
        },
        _ => Err(Code::NotSupported),
    }
}
