//! The networks a gateway serves, by their CiA 309-3 net number.
//!
//! `duocan gateway` serves one network and, as CANopenNode's single-network gateway, takes any
//! net number (0–65535) as naming it: a script written for numbered networks runs unchanged on
//! the network the gateway is pointed at. A station serves all of its networks, each under a
//! number of its own; a number no network has is `ERROR:106`.

use super::error::{Bad, Code};
use duocan::net::Network;

/// The networks a gateway serves: one under every number, or several each under its own.
#[derive(Clone)]
pub struct GatewayNets {
    /// Net number, name (for the error that lists them) and handle, the default first.
    list: Vec<(u16, String, Network)>,
    /// True when the one network answers to every number.
    any_number: bool,
}

impl GatewayNets {
    /// One network, named by any net number (the standalone gateway).
    pub fn single(net: Network) -> GatewayNets {
        GatewayNets {
            list: vec![(0, String::new(), net)],
            any_number: true,
        }
    }

    /// Several networks, each under its number (distinct: the station's file checks them);
    /// the first is where each client starts.
    pub fn numbered(list: Vec<(u16, String, Network)>) -> GatewayNets {
        GatewayNets {
            list,
            any_number: false,
        }
    }

    /// The net a new client starts on (what `set network` changes).
    pub fn default_net(&self) -> u16 {
        self.list.first().map_or(0, |(n, _, _)| *n)
    }

    /// The network under net number `n`, or `ERROR:106` saying which numbers there are.
    pub fn get(&self, n: u16) -> Result<&Network, Bad> {
        if self.any_number {
            if let Some((_, _, net)) = self.list.first() {
                return Ok(net);
            }
        }
        if let Some((_, _, net)) = self.list.iter().find(|(m, _, _)| *m == n) {
            return Ok(net);
        }
        let known: Vec<String> = self
            .list
            .iter()
            .map(|(m, name, _)| format!("{m} ({name})"))
            .collect();
        Err(Bad::because(
            Code::UnsupportedNet,
            format!("no network {n} here; the nets are {}", known.join(", ")),
        ))
    }
}
