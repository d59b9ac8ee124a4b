//! The errors the gateway answers with: a CiA 309-3 code, and what was wrong.

/// The 309-3 internal error codes the gateway answers with (`ERROR:<code>`).
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
    /// 106: a net above 65535, or one no network of the station has.
    UnsupportedNet = 106,
    /// 107: a node-ID outside 1–127 (0 is "all nodes" for NMT commands).
    UnsupportedNode = 107,
    /// 501: an LSS slave refused with its manufacturer's error code.
    LssManufacturer = 501,
    /// 502: the LSS slave refused the node-ID.
    LssNodeId = 502,
    /// 503: the LSS slave refused the bit rate.
    LssBitRate = 503,
    /// 504: the LSS slave could not store its configuration.
    LssStore = 504,
}

impl Code {
    /// What the code means, for the `#` comment behind it (309-3's meaning, in our words).
    pub fn text(self) -> &'static str {
        match self {
            Code::NotSupported => "request not supported",
            Code::Syntax => "syntax error",
            Code::InternalState => "request not processed in the present state",
            Code::Timeout => "time-out",
            Code::NoDefaultNode => "no default node set",
            Code::UnsupportedNet => "unsupported net",
            Code::UnsupportedNode => "unsupported node",
            Code::LssManufacturer => "LSS: manufacturer-specific error",
            Code::LssNodeId => "LSS: node-ID not supported",
            Code::LssBitRate => "LSS: bit rate not supported",
            Code::LssStore => "LSS: storing the configuration failed",
        }
    }
}

/// An error to answer: its code, and what in the request was wrong (when the code alone does
/// not say).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Bad {
    /// The 309-3 code.
    pub code: Code,
    /// What was wrong, for the `#` comment.
    pub why: Option<String>,
}

impl Bad {
    /// `code`, with nothing more to say.
    pub fn code(code: Code) -> Bad {
        Bad { code, why: None }
    }

    /// `code`, because `why`.
    pub fn because(code: Code, why: impl Into<String>) -> Bad {
        Bad {
            code,
            why: Some(why.into()),
        }
    }

    /// A syntax error, because `why`.
    pub fn syntax(why: impl Into<String>) -> Bad {
        Bad::because(Code::Syntax, why)
    }
}
