//! The tool's one error: what went wrong, said for the person at the terminal, and the exit
//! code it gives. 1 is the network's answer (an abort code with its meaning, a node that did
//! not answer, with a hint); 2 is the command line's fault (a bad argument, a file that cannot
//! be read); 3 a bus that cannot be opened (an interface that does not exist or is down, a UDP
//! socket refused), so that a script tells a missing bus from a mistyped command. clap's own
//! usage errors exit with 2 as well.

use duocan::net::NetError;
use std::fmt;

/// What a command ends with when it cannot do what it was asked.
#[derive(Debug)]
pub enum Fail {
    /// The command line asked for something that cannot be done (exit 2).
    Usage(String),
    /// The network or a node did not do it (exit 1).
    Protocol(String),
    /// The bus could not be opened (exit 3).
    Bus(String),
}

impl Fail {
    /// The process's exit code.
    pub fn code(&self) -> u8 {
        match self {
            Fail::Usage(_) => 2,
            Fail::Protocol(_) => 1,
            Fail::Bus(_) => 3,
        }
    }

    /// A usage error.
    pub fn usage(why: impl Into<String>) -> Fail {
        Fail::Usage(why.into())
    }

    /// A protocol error.
    pub fn protocol(why: impl Into<String>) -> Fail {
        Fail::Protocol(why.into())
    }

    /// A bus that could not be opened.
    pub fn bus(why: impl Into<String>) -> Fail {
        Fail::Bus(why.into())
    }
}

impl fmt::Display for Fail {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Fail::Usage(s) | Fail::Protocol(s) | Fail::Bus(s) => f.write_str(s),
        }
    }
}

impl From<NetError> for Fail {
    fn from(e: NetError) -> Fail {
        let text = e.to_string();
        match e {
            // What the user typed or gave: names, values, files, ports.
            NetError::NoSuchNode(_)
            | NetError::NoDescription { .. }
            | NetError::Name { .. }
            | NetError::WrongType { .. }
            | NetError::BadValue { .. }
            | NetError::Eds(_)
            | NetError::NoSuchPdo { .. }
            | NetError::Argument(_)
            | NetError::Port(_)
            | NetError::ListenOnly { .. } => Fail::Usage(text),
            _ if e.is_no_answer() => Fail::Protocol(format!(
                "{text}\nhint: `duocan scan` lists the nodes that answer; --timeout MS waits longer"
            )),
            _ => Fail::Protocol(text),
        }
    }
}

impl From<std::io::Error> for Fail {
    fn from(e: std::io::Error) -> Fail {
        Fail::Usage(e.to_string())
    }
}
