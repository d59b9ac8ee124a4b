//! [`HeardOn`]: which of a link's buses a node was heard on, for any number of buses.
//!
//! The front door is written once over whatever link sits below it: one port, two buses
//! joined as one logical bus, or more. What it says about a node's reach must not assume a
//! count, so the answer carries the link's bus count with the set of buses heard; its
//! `Display` says it in words ("heard on bus 2 only"). Sixteen buses at most, in two bytes and
//! a count: a link with more would be a network of networks, not one logical bus.
//!
//! ```
//! use duocan::net::HeardOn;
//!
//! let reach = HeardOn::from([false, true]);
//! assert!(!reach.on(0) && reach.on(1) && reach.buses() == 2);
//! assert_eq!(reach.to_string(), "heard on bus 2 only");
//! assert_eq!(HeardOn::from([true, true]).to_string(), "heard on both buses");
//! assert_eq!(HeardOn::new(3).with(0).with(2).to_string(), "heard on buses 1 and 3");
//! assert_eq!(HeardOn::new(2).to_string(), "heard on no bus");
//! ```

use core::fmt;

/// The buses a node was heard on, of the `buses()` a link has (bus 1 is index 0): what
/// [`Network::heard_on`](super::Network::heard_on) answers and
/// [`NetEvent::Reach`](super::NetEvent::Reach) carries.
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct HeardOn {
    heard: u16,
    buses: u8,
}

impl HeardOn {
    /// The most buses a link can report on.
    pub const MAX_BUSES: usize = 16;

    /// Heard on none of `buses` buses (cut to [`HeardOn::MAX_BUSES`]).
    #[must_use]
    pub fn new(buses: usize) -> Self {
        HeardOn {
            heard: 0,
            // Cut to 16 first: fits a byte.
            buses: buses.min(Self::MAX_BUSES) as u8,
        }
    }

    /// The same, heard on bus index `bus` too (0: bus 1); a bus the link does not have is
    /// left out.
    #[must_use]
    pub fn with(mut self, bus: usize) -> Self {
        if bus < self.buses() {
            self.heard |= 1 << bus;
        }
        self
    }

    /// Whether the node was heard on bus index `bus` (0: bus 1).
    #[must_use]
    pub fn on(self, bus: usize) -> bool {
        bus < self.buses() && self.heard & (1 << bus) != 0
    }

    /// How many buses the link has.
    #[must_use]
    pub fn buses(self) -> usize {
        usize::from(self.buses)
    }

    /// How many of them the node was heard on.
    #[must_use]
    pub fn count(self) -> usize {
        self.heard.count_ones() as usize
    }

    /// Heard on every bus of the link.
    #[must_use]
    pub fn everywhere(self) -> bool {
        self.count() == self.buses()
    }

    /// Heard on no bus.
    #[must_use]
    pub fn nowhere(self) -> bool {
        self.heard == 0
    }

    /// The indices of the buses it was heard on, in order (0: bus 1).
    pub fn iter(self) -> impl Iterator<Item = usize> {
        (0..self.buses()).filter(move |&b| self.on(b))
    }
}

impl<const N: usize> From<[bool; N]> for HeardOn {
    /// `heard[i]`: heard on bus index `i`.
    fn from(heard: [bool; N]) -> Self {
        (0..N)
            .filter(|&b| heard[b])
            .fold(HeardOn::new(N), HeardOn::with)
    }
}

/// Equal to the array of as many booleans, `heard[i]` for bus index `i`.
impl<const N: usize> PartialEq<[bool; N]> for HeardOn {
    fn eq(&self, heard: &[bool; N]) -> bool {
        *self == HeardOn::from(*heard)
    }
}

/// As the array of booleans it stands for: `[true, false]`.
impl fmt::Debug for HeardOn {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_list()
            .entries((0..self.buses()).map(|b| self.on(b)))
            .finish()
    }
}

/// "heard on both buses", "heard on every bus" (more than two), "heard on bus 2 only",
/// "heard on buses 1 and 3", "heard on no bus".
impl fmt::Display for HeardOn {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match (self.count(), self.buses()) {
            (0, _) => f.write_str("heard on no bus"),
            (2, 2) => f.write_str("heard on both buses"),
            (n, b) if n == b && b > 2 => f.write_str("heard on every bus"),
            (1, b) if b > 1 => write!(f, "heard on bus {} only", self.iter().sum::<usize>() + 1),
            (1, _) => f.write_str("heard on bus 1"),
            (n, _) => {
                f.write_str("heard on buses ")?;
                for (i, b) in self.iter().enumerate() {
                    let sep = match i {
                        0 => "",
                        i if i + 1 == n => " and ",
                        _ => ", ",
                    };
                    write!(f, "{sep}{}", b + 1)?;
                }
                Ok(())
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::HeardOn;

    #[test]
    fn any_number_of_buses_reads_in_words() {
        let four = HeardOn::new(4);
        assert_eq!(four.with(1).to_string(), "heard on bus 2 only");
        assert_eq!(
            four.with(0).with(1).with(3).to_string(),
            "heard on buses 1, 2 and 4"
        );
        assert_eq!(
            (0..4).fold(four, HeardOn::with).to_string(),
            "heard on every bus"
        );
        assert_eq!(HeardOn::from([true]).to_string(), "heard on bus 1");
        // A bus the link does not have is never heard.
        assert_eq!(four.with(9), four);
        assert!(!four.with(9).on(9));
        assert_eq!(HeardOn::new(99).buses(), HeardOn::MAX_BUSES);
        assert_eq!(
            format!("{:?}", HeardOn::from([true, false])),
            "[true, false]"
        );
        assert_eq!(four.with(3).iter().collect::<Vec<_>>(), [3]);
    }
}
