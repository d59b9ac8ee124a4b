//! The `mqtt*` keys of the `[station]` table: where the station reports to the plant (see
//! [`crate::cmd::station::mqtt`]).

use super::{Source, StationTable};
use crate::cmd::station::audit::file_name;
use toml::Spanned;

/// The MQTT broker the station publishes to, and how.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Mqtt {
    /// The broker's host name or address.
    pub host: String,
    /// Its TCP port.
    pub port: u16,
    /// The client identifier the station connects with.
    pub client_id: String,
    /// The first levels of every topic, without a trailing `/`.
    pub prefix: String,
    /// The user name and password, if the broker asks for them.
    pub login: Option<(String, String)>,
    /// Messages the outbox holds while the broker is away (then the oldest are dropped).
    pub outbox: usize,
}

/// [`Mqtt::outbox`] when the file does not say.
pub const MQTT_OUTBOX: usize = 1024;

/// The MQTT settings of table `t`; `station` (its name) makes the default prefix and client id.
pub(super) fn mqtt(
    src: &Source<'_>,
    t: &StationTable,
    station: &str,
) -> Result<Option<Mqtt>, String> {
    let Some(at) = &t.mqtt else {
        // A setting of MQTT without the broker is a broker forgotten.
        let others = [
            (
                "mqtt_client_id",
                t.mqtt_client_id.as_ref().map(Spanned::span),
            ),
            ("mqtt_prefix", t.mqtt_prefix.as_ref().map(Spanned::span)),
            ("mqtt_username", t.mqtt_username.as_ref().map(Spanned::span)),
            ("mqtt_password", t.mqtt_password.as_ref().map(Spanned::span)),
            ("mqtt_outbox", t.mqtt_outbox.as_ref().map(Spanned::span)),
        ];
        if let Some((key, Some(span))) = others.into_iter().find(|(_, s)| s.is_some()) {
            return Err(src.span(span, key, "set mqtt (the broker's host:port) too"));
        }
        return Ok(None);
    };
    let (host, port) = broker(at.get_ref().trim()).ok_or_else(|| {
        let why = format!(
            "{:?} is not a broker's host and port such as \"127.0.0.1:1883\" or \
                 \"broker.plant:1883\"",
            at.get_ref()
        );
        src.span(at.span(), "mqtt", why)
    })?;
    let client_id = match &t.mqtt_client_id {
        Some(id) => {
            let s = id.get_ref();
            if s.is_empty() || s.len() > 64 || !s.chars().all(|c| c.is_ascii_graphic()) {
                let why = "1 to 64 printable ASCII characters without spaces";
                return Err(src.span(id.span(), "mqtt_client_id", why));
            }
            s.clone()
        }
        None => format!("duocan-{}", file_name(station)),
    };
    let prefix = match &t.mqtt_prefix {
        Some(p) => {
            check_prefix(p.get_ref()).map_err(|why| src.span(p.span(), "mqtt_prefix", why))?;
            p.get_ref().clone()
        }
        None => format!("duocan/{}", file_name(station)),
    };
    let login = match (&t.mqtt_username, &t.mqtt_password) {
        (Some(u), Some(p)) => Some((u.get_ref().clone(), p.get_ref().clone())),
        (Some(u), None) => Some((u.get_ref().clone(), String::new())),
        (None, Some(p)) => {
            // MQTT 3.1.1 sends a password only with a user name.
            return Err(src.span(p.span(), "mqtt_password", "set mqtt_username too"));
        }
        (None, None) => None,
    };
    let outbox = match &t.mqtt_outbox {
        Some(n) if !(1..=1 << 20).contains(n.get_ref()) => {
            return Err(src.span(n.span(), "mqtt_outbox", "1 to 1048576 messages"));
        }
        Some(n) => *n.get_ref(),
        None => MQTT_OUTBOX,
    };
    Ok(Some(Mqtt {
        host,
        port,
        client_id,
        prefix,
        login,
        outbox,
    }))
}

/// `host:port` (an IPv6 address in brackets), the port not 0.
fn broker(s: &str) -> Option<(String, u16)> {
    let (host, port) = s.rsplit_once(':')?;
    let host = host
        .strip_prefix('[')
        .and_then(|h| h.strip_suffix(']'))
        .unwrap_or(host);
    let port: u16 = port.parse().ok().filter(|&p| p != 0)?;
    let bad = |c: char| c.is_whitespace() || c == '/' || c == '[' || c == ']';
    (!host.is_empty() && !host.contains(bad)).then(|| (host.to_string(), port))
}

/// A topic prefix: topic levels without wildcards, none empty, not a broker's own (`$…`).
fn check_prefix(p: &str) -> Result<(), &'static str> {
    if p.is_empty() || p.split('/').any(str::is_empty) {
        return Err("topic levels separated by / (none empty, no leading or trailing /)");
    }
    if p.contains(['+', '#', '\0']) {
        return Err("no wildcard (+, #) in a topic");
    }
    if p.starts_with('$') {
        return Err("topics starting with $ are the broker's own");
    }
    Ok(())
}

/// With MQTT, two networks whose names give the same topic level (see
/// [`crate::cmd::station::mqtt`]) would publish to the same topics: the second is an error,
/// placed on its name.
pub(super) fn distinct_topics(
    src: &Source<'_>,
    names: &[(String, std::ops::Range<usize>)],
) -> Result<(), String> {
    for (i, (name, at)) in names.iter().enumerate() {
        let level = file_name(name);
        if let Some((other, _)) = names[..i].iter().find(|(o, _)| file_name(o) == level) {
            let why = format!(
                "{name:?} and {other:?} are both topic level {level:?} under MQTT \
                 (letters, digits, - and _ are kept, the rest is _): name them apart"
            );
            return Err(src.span(at.clone(), "name", why));
        }
    }
    Ok(())
}
