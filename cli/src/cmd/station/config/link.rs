//! The `profile`, `link`, `merge`, `merge_timeout_ms` and `default_bus` keys of a
//! `[[network]]` table: the identifier profile and the dual-bus layer's policy
//! (`duocan_redundancy::DualBusConfig`).
//!
//! ```toml
//! profile = "predefined"     # the CiA 301 predefined connection set, or "railway29" (below)
//! link = "active-active"     # or "cia302-6" (active-standby), "ecss" (bus toggling)
//! merge = "exact"            # active-active: "exact" (every frame once) or "sticky"
//! merge_timeout_ms = 40      # sticky: a sender's silence on its bus before it switches
//! default_bus = 1            # cia302-6: the default channel; ecss: Bdefault (1 or 2)
//! ```
//!
//! - `link = "active-active"` (default): both buses carry everything; the receive merge is
//!   `merge`: `"exact"` (default; each frame occurrence exactly once, twins matched by their
//!   timestamps) or `"sticky"` (each sender's frames from one bus, switching to the other
//!   after `merge_timeout_ms` of silence, default 40).
//! - `link = "cia302-6"`: CiA 302-6 active-standby with its defaults (1 s evaluation windows,
//!   error threshold 16), the default channel bus `default_bus`.
//! - `link = "ecss"`: ECSS-E-ST-50-15C bus toggling as the redundancy master, starting on bus
//!   `default_bus` (Ttoggle 2, Ntoggle 4).
//!
//! The health and reachability timing follow the shorter of `heartbeat_ms` and
//! `pair_heartbeat_ms`, as the builder's default does.
//!
//! `profile = "railway29"`: the whole network runs on the railway 29-bit identifier scheme
//! (`duocan_redundancy::logical::NetProfile::railway29`): heartbeats, node guarding, EMCY,
//! NMT, SYNC and SDO on 29-bit identifiers, a function code above the board address of each
//! node-ID, which is fixed (row 1, cabinet = the node-ID's high nibble, layer 1, board = its
//! low nibble) so that the file needs no address table and every device agrees on it; the
//! flying-master frames stay CiA 302-2's 11-bit ones. The boards must run the same scheme at
//! the same addresses (the simulated plant's do); a network's profile is one for all its
//! devices, which is why it is a key of the network, not of a board.

use super::{NetworkTable, Source};
use duocan::Duration;
use duocan_redundancy::logical::{NetProfile, DEFAULT_HEARTBEAT};
use duocan_redundancy::{Cia3026Config, DualBusConfig, EcssConfig, LinkMode, MergePolicy};
use toml::Spanned;

/// The identifier profiles a file may name.
pub const PROFILES: [&str; 2] = ["predefined", "railway29"];
/// The dual-bus policies a file may name.
pub const LINKS: [&str; 3] = ["active-active", "cia302-6", "ecss"];
/// The merges of the active-active policy.
pub const MERGES: [&str; 2] = ["exact", "sticky"];

/// A network's dual-bus policy as the file gives it, for `check` to show.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Link {
    /// One of [`LINKS`].
    pub link: &'static str,
    /// One of [`MERGES`] (active-active), or `None`.
    pub merge: Option<&'static str>,
    /// The sticky merge's timeout, ms.
    pub merge_timeout_ms: Option<u64>,
    /// The default bus (1 or 2) of cia302-6 and ecss.
    pub default_bus: Option<u8>,
    /// The identifier profile: one of [`PROFILES`].
    pub profile: &'static str,
}

impl Link {
    /// The identifier profile the network's builder takes.
    pub fn net_profile(&self) -> NetProfile {
        match self.profile {
            "railway29" => NetProfile::railway29(),
            _ => NetProfile::predefined(),
        }
    }
}

impl std::fmt::Display for Link {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "link {}", self.link)?;
        if let Some(m) = self.merge {
            write!(f, ", merge {m}")?;
        }
        if let Some(t) = self.merge_timeout_ms {
            write!(f, " ({t} ms)")?;
        }
        if let Some(b) = self.default_bus {
            write!(f, ", default bus {b}")?;
        }
        write!(f, ", profile {}", self.profile)
    }
}

fn one_of(
    src: &Source<'_>,
    s: &Spanned<String>,
    key: &str,
    allowed: &[&'static str],
) -> Result<&'static str, String> {
    let text = s.get_ref().trim();
    allowed.iter().copied().find(|a| *a == text).ok_or_else(|| {
        let list: Vec<String> = allowed.iter().map(|a| format!("{a:?}")).collect();
        src.span(
            s.span(),
            key,
            format!("{text:?} is none of {}", list.join(", ")),
        )
    })
}

/// The dual-bus configuration of table `t` (`None`: the builder's default), and what `check`
/// shows of it.
pub(super) fn link(
    src: &Source<'_>,
    t: &NetworkTable,
) -> Result<(Option<DualBusConfig>, Link), String> {
    let profile = match &t.profile {
        None => "predefined",
        Some(p) => one_of(src, p, "profile", &PROFILES)?,
    };
    let kind = match &t.link {
        None => "active-active",
        Some(l) => one_of(src, l, "link", &LINKS)?,
    };
    let active_active = kind == "active-active";
    let merge = match &t.merge {
        None => active_active.then_some("exact"),
        Some(m) => {
            let m2 = one_of(src, m, "merge", &MERGES)?;
            if !active_active {
                let why = format!(
                    "applies to link = \"active-active\" only: {kind} merges what it hears on \
                     both buses exactly (leave the key out)"
                );
                return Err(src.span(m.span(), "merge", why));
            }
            Some(m2)
        }
    };
    let timeout = match &t.merge_timeout_ms {
        None => None,
        Some(ms) => {
            if merge != Some("sticky") {
                return Err(src.span(ms.span(), "merge_timeout_ms", "set merge = \"sticky\" too"));
            }
            if *ms.get_ref() == 0 || *ms.get_ref() > 10_000 {
                let why = "1 to 10000 ms: above the largest lag between the buses";
                return Err(src.span(ms.span(), "merge_timeout_ms", why));
            }
            Some(*ms.get_ref())
        }
    };
    let bus = match &t.default_bus {
        None => None,
        Some(b) => {
            if active_active {
                let why = "applies to link = \"cia302-6\" or \"ecss\": active-active uses both";
                return Err(src.span(b.span(), "default_bus", why));
            }
            match *b.get_ref() {
                1 => Some(1u8),
                2 => Some(2),
                _ => {
                    let why = "1 or 2 (bus 1 is the first of `buses`)";
                    return Err(src.span(b.span(), "default_bus", why));
                }
            }
        }
    };
    let shown = Link {
        link: kind,
        merge,
        merge_timeout_ms: match merge {
            Some("sticky") => Some(timeout.unwrap_or(MergePolicy::STICKY_TIMEOUT.as_millis())),
            _ => None,
        },
        default_bus: (!active_active).then_some(bus.unwrap_or(1)),
        profile,
    };
    if t.link.is_none() && t.merge.is_none() {
        // The builder's own default: active-active, exact merge.
        return Ok((None, shown));
    }
    let port = bus.map_or(0, |b| b - 1);
    let mode = match kind {
        "cia302-6" => LinkMode::Cia302_6(Cia3026Config::default().with_default_channel(port)),
        "ecss" => LinkMode::EcssToggle(EcssConfig::master().with_bdefault(port)),
        _ => LinkMode::ActiveActive,
    };
    // The builder's default timing: the shorter of the two heartbeats.
    let ms = |d: &Option<Spanned<u64>>| {
        d.as_ref()
            .map_or(DEFAULT_HEARTBEAT, |d| Duration::from_millis(*d.get_ref()))
    };
    let guard = ms(&t.heartbeat_ms).min(ms(&t.pair_heartbeat_ms));
    let mut cfg = DualBusConfig::with_guard_period(mode, guard);
    if let Some(t) = shown.merge_timeout_ms {
        cfg = cfg.with_merge(MergePolicy::Sticky {
            timeout: Duration::from_millis(t),
        });
    }
    Ok((Some(cfg), shown))
}

#[cfg(test)]
mod tests {
    use super::super::parse;

    const HEAD: &str = "[[network]]\nname = \"a\"\nbuses = \"sim-pairs\"\nnode_id = 1\n";

    fn shown(keys: &str) -> String {
        let st = parse(&format!("{HEAD}{keys}"), "s.toml").unwrap();
        st.networks[0].link.to_string()
    }

    fn err(keys: &str) -> String {
        parse(&format!("{HEAD}{keys}"), "s.toml").unwrap_err()
    }

    #[test]
    fn each_policy_is_taken_with_its_settings() {
        assert_eq!(
            shown(""),
            "link active-active, merge exact, profile predefined"
        );
        assert_eq!(
            shown("profile = \"predefined\"\nmerge = \"sticky\"\n"),
            "link active-active, merge sticky (40 ms), profile predefined"
        );
        assert_eq!(
            shown("merge = \"sticky\"\nmerge_timeout_ms = 25\n"),
            "link active-active, merge sticky (25 ms), profile predefined"
        );
        assert_eq!(
            shown("link = \"cia302-6\"\n"),
            "link cia302-6, default bus 1, profile predefined"
        );
        assert_eq!(
            shown("link = \"ecss\"\ndefault_bus = 2\n"),
            "link ecss, default bus 2, profile predefined"
        );
    }

    #[test]
    fn the_railway_profile_is_taken_and_reaches_the_builder() {
        assert_eq!(
            shown("profile = \"railway29\"\n"),
            "link active-active, merge exact, profile railway29"
        );
        assert_eq!(
            shown("profile = \" railway29 \"\nlink = \"cia302-6\"\n"),
            "link cia302-6, default bus 1, profile railway29"
        );
        let st = parse(&format!("{HEAD}profile = \"railway29\"\n"), "s.toml").unwrap();
        let net = &st.networks[0];
        assert!(net.link.net_profile().is_railway());
        assert_eq!(net.builder.id_profile().name(), "railway29");
        let st = parse(HEAD, "s.toml").unwrap();
        assert_eq!(st.networks[0].builder.id_profile().name(), "predefined");
    }

    #[test]
    fn each_error_names_the_key_and_what_is_allowed() {
        let e = err("profile = \"can29\"\n");
        assert!(
            e.starts_with(
                "s.toml:5:11: profile: \"can29\" is none of \"predefined\", \"railway29\""
            ),
            "{e}"
        );
        let e = err("link = \"hot-standby\"\n");
        assert!(
            e.starts_with(
                "s.toml:5:8: link: \"hot-standby\" is none of \"active-active\", \"cia302-6\", \
                 \"ecss\""
            ),
            "{e}"
        );
        let e = err("merge = \"first\"\n");
        assert!(
            e.starts_with("s.toml:5:9: merge: \"first\" is none of \"exact\", \"sticky\""),
            "{e}"
        );
        let e = err("link = \"ecss\"\nmerge = \"sticky\"\n");
        assert!(
            e.starts_with("s.toml:6:9: merge: applies to link = \"active-active\" only"),
            "{e}"
        );
        let e = err("merge_timeout_ms = 30\n");
        assert!(
            e.starts_with("s.toml:5:20: merge_timeout_ms: set merge = \"sticky\" too"),
            "{e}"
        );
        let e = err("merge = \"sticky\"\nmerge_timeout_ms = 0\n");
        assert!(
            e.starts_with("s.toml:6:20: merge_timeout_ms: 1 to 10000 ms"),
            "{e}"
        );
        let e = err("default_bus = 1\n");
        assert!(
            e.starts_with("s.toml:5:15: default_bus: applies to link"),
            "{e}"
        );
        for bad in ["0", "3", "-1", "99999999999"] {
            let e = err(&format!("link = \"cia302-6\"\ndefault_bus = {bad}\n"));
            assert!(
                e.starts_with("s.toml:6:15: default_bus: 1 or 2"),
                "{bad}: {e}"
            );
        }
        // Bad input of any kind is an error, never a panic.
        for junk in [
            "link = 1",
            "merge = []",
            "profile = {}",
            "default_bus = \"1\"",
            "merge_timeout_ms = -5",
        ] {
            assert!(
                parse(&format!("{HEAD}{junk}\n"), "s.toml").is_err(),
                "{junk}"
            );
        }
    }
}
