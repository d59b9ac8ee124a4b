//! A timeline chart as one standalone SVG document (no scripts, fonts or files outside it), for a
//! person to open in a browser after a run.
//!
//! One group per network; in it one lane per bus, pair and master, each a row of coloured
//! [`Span`]s (bus ok / suspect / failed / recovering, member active / standby, master active /
//! standby / down, …), and the network's [`Fault`]s as numbered vertical markers with a legend
//! line each ("① 12.30 s bus 1 cut"). A time axis in simulated seconds runs along the bottom,
//! with grid lines across every network, and a legend of the states used.
//!
//! Elements carry classes so that tests and style sheets can find them: `g.network`
//! (`data-name`), `g.lane` (`data-kind`, `data-label`), `rect.span` (`state-…`), `g.fault`,
//! `g.axis` with `text.tick-label`, `g.legend`. Hovering a span or marker shows its details
//! (`<title>`).
//!
//! ```text
//! use duocan::report::{render, Fault, Lane, LaneKind, Network, Span, State, Timeline};
//!
//! let chart = Timeline {
//!     title: "signal rack".into(),
//!     start: 0.0,
//!     end: 60.0,
//!     networks: vec![Network {
//!         name: "signal rack".into(),
//!         lanes: vec![Lane::from_changes(
//!             "bus 1",
//!             LaneKind::Bus,
//!             &[(0.0, State::Ok), (12.3, State::Failed), (40.0, State::Ok)],
//!             60.0,
//!         )],
//!         faults: vec![Fault::new(12.3, "bus 1 cut")],
//!     }],
//! };
//! let svg = render(&chart)?;
//! assert!(svg.starts_with("<svg") && svg.contains("bus 1 cut"));
//! # Ok::<(), duocan::report::ChartError>(())
//! ```

use core::fmt::{self, Write};
use duocan::Instant;
use std::collections::BTreeSet;

/// What a lane shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum LaneKind {
    /// One bus as a port sees it.
    Bus,
    /// A slave pair's (or one member's) role.
    Pair,
    /// A master's role.
    Master,
}

impl LaneKind {
    fn name(self) -> &'static str {
        match self {
            LaneKind::Bus => "bus",
            LaneKind::Pair => "pair",
            LaneKind::Master => "master",
        }
    }
}

/// The state a span shows; it decides the colour.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum State {
    /// Bus or port working.
    Ok,
    /// Port suspect.
    Suspect,
    /// Bus or port failed.
    Failed,
    /// Port re-initialised, waiting for traffic.
    Recovering,
    /// Active member or master.
    Active,
    /// Standby member or master.
    Standby,
    /// Dead, powered off, not joined.
    Down,
    /// Not known yet.
    Unknown,
}

impl State {
    /// Every state, in legend order.
    pub const ALL: [State; 8] = [
        State::Ok,
        State::Suspect,
        State::Failed,
        State::Recovering,
        State::Active,
        State::Standby,
        State::Down,
        State::Unknown,
    ];
    /// The CSS class suffix and legend word.
    pub const fn name(self) -> &'static str {
        match self {
            State::Ok => "ok",
            State::Suspect => "suspect",
            State::Failed => "failed",
            State::Recovering => "recovering",
            State::Active => "active",
            State::Standby => "standby",
            State::Down => "down",
            State::Unknown => "unknown",
        }
    }
    /// Fill colour (chosen to stay distinguishable for the common colour-vision deficiencies:
    /// failed and ok also differ in lightness).
    pub const fn color(self) -> &'static str {
        match self {
            State::Ok => "#4caf50",
            State::Suspect => "#f2b705",
            State::Failed => "#c62828",
            State::Recovering => "#42a5f5",
            State::Active => "#1b5e20",
            State::Standby => "#a5d6a7",
            State::Down => "#424242",
            State::Unknown => "#d0d0d0",
        }
    }
}

/// One interval of a lane, in simulated seconds.
#[derive(Clone, Debug, PartialEq)]
pub struct Span {
    /// Start.
    pub from: f64,
    /// End.
    pub to: f64,
    /// What it shows.
    pub state: State,
    /// Text in the bar when it fits (and in the tooltip), e.g. "A" or "node 3".
    pub label: String,
}

impl Span {
    /// A span without label.
    pub fn new(from: f64, to: f64, state: State) -> Span {
        Span {
            from,
            to,
            state,
            label: String::new(),
        }
    }
    /// The same span with a label.
    pub fn labelled(mut self, label: impl Into<String>) -> Span {
        self.label = label.into();
        self
    }
}

/// One row of a network.
#[derive(Clone, Debug, PartialEq)]
pub struct Lane {
    /// Row title ("bus 1", "pair 3 (turnout 1)", "strong master").
    pub label: String,
    /// What it shows.
    pub kind: LaneKind,
    /// Its intervals.
    pub spans: Vec<Span>,
}

impl Lane {
    /// A lane from state changes `(time, state)` in time order, the last lasting until `end`.
    pub fn from_changes(
        label: impl Into<String>,
        kind: LaneKind,
        changes: &[(f64, State)],
        end: f64,
    ) -> Lane {
        let spans = changes
            .iter()
            .enumerate()
            .map(|(i, &(t, s))| {
                let to = changes.get(i + 1).map_or(end, |c| c.0);
                Span::new(t, to, s)
            })
            .collect();
        Lane {
            label: label.into(),
            kind,
            spans,
        }
    }
}

/// A fault marker.
#[derive(Clone, Debug, PartialEq)]
pub struct Fault {
    /// When, in simulated seconds.
    pub at: f64,
    /// What happened ("bus 1 of the signal rack cut").
    pub label: String,
}

impl Fault {
    /// A marker.
    pub fn new(at: f64, label: impl Into<String>) -> Fault {
        Fault {
            at,
            label: label.into(),
        }
    }
}

/// One dual-bus network: its lanes and faults.
#[derive(Clone, Debug, PartialEq)]
pub struct Network {
    /// Its name ("turnout rack").
    pub name: String,
    /// Rows, top to bottom.
    pub lanes: Vec<Lane>,
    /// Faults injected or detected on it.
    pub faults: Vec<Fault>,
}

/// The whole chart.
#[derive(Clone, Debug, PartialEq)]
pub struct Timeline {
    /// Heading.
    pub title: String,
    /// Start of the time axis (s).
    pub start: f64,
    /// End of the time axis (s).
    pub end: f64,
    /// Networks, top to bottom.
    pub networks: Vec<Network>,
}

/// Simulated seconds of an instant (for building spans from events).
pub fn seconds(t: Instant) -> f64 {
    t.as_micros() as f64 / 1e6
}

/// Why a chart could not be drawn.
#[derive(Clone, Debug, PartialEq)]
pub enum ChartError {
    /// The time axis is empty or not finite.
    Range {
        /// Start given.
        start: f64,
        /// End given.
        end: f64,
    },
    /// A span ends before it starts, or a time is not finite.
    BadSpan {
        /// Network.
        network: String,
        /// Lane.
        lane: String,
        /// Start.
        from: f64,
        /// End.
        to: f64,
    },
    /// A fault time is not finite.
    BadFault {
        /// Network.
        network: String,
        /// The fault's label.
        label: String,
    },
}

impl fmt::Display for ChartError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ChartError::Range { start, end } => write!(
                f,
                "timeline from {start} s to {end} s: the end must be after the start"
            ),
            ChartError::BadSpan {
                network,
                lane,
                from,
                to,
            } => write!(
                f,
                "{network}, lane {lane}: span {from} s – {to} s ends before it starts or is not a time"
            ),
            ChartError::BadFault { network, label } => {
                write!(f, "{network}: fault \"{label}\" has no finite time")
            }
        }
    }
}

impl std::error::Error for ChartError {}

const WIDTH: f64 = 1200.0;
const LEFT: f64 = 210.0;
const RIGHT: f64 = 30.0;
const TOP: f64 = 58.0;
const NET_HEADER: f64 = 26.0;
const LANE_H: f64 = 18.0;
const LANE_GAP: f64 = 6.0;
const FAULT_LINE: f64 = 16.0;
const NET_GAP: f64 = 22.0;
const AXIS_H: f64 = 44.0;
const LEGEND_H: f64 = 34.0;
/// Average advance of an 11 px sans-serif character, to decide whether a label fits.
const CHAR_W: f64 = 6.4;

const STYLE: &str = "
text { font-family: 'DejaVu Sans', Verdana, Arial, sans-serif; fill: #212121; }
.title { font-size: 18px; font-weight: bold; }
.subtitle { font-size: 12px; fill: #616161; }
.network-name { font-size: 14px; font-weight: bold; }
.lane-label { font-size: 12px; }
.lane-bg { fill: #f5f5f5; }
.span { stroke: #ffffff; stroke-width: 0.5; }
.span-label { font-size: 11px; fill: #ffffff; pointer-events: none; }
.span-label.dark { fill: #212121; }
.grid line { stroke: #e0e0e0; stroke-width: 1; }
.fault line { stroke: #b71c1c; stroke-width: 1.5; stroke-dasharray: 4 3; }
.fault circle { fill: #b71c1c; }
.fault .marker-number { font-size: 10px; fill: #ffffff; font-weight: bold; }
.fault .fault-label { font-size: 12px; }
.axis line { stroke: #616161; }
.tick-label { font-size: 11px; fill: #424242; }
.axis-title { font-size: 12px; fill: #424242; }
.legend text { font-size: 12px; }
";

/// Draws the chart.
pub fn render(t: &Timeline) -> Result<String, ChartError> {
    if !(t.start.is_finite() && t.end.is_finite() && t.end > t.start) {
        return Err(ChartError::Range {
            start: t.start,
            end: t.end,
        });
    }
    validate(t)?;
    let plot_w = WIDTH - LEFT - RIGHT;
    let x = |s: f64| LEFT + (s.clamp(t.start, t.end) - t.start) / (t.end - t.start) * plot_w;
    let net_h = |n: &Network| {
        NET_HEADER
            + n.lanes.len() as f64 * (LANE_H + LANE_GAP)
            + n.faults.len() as f64 * FAULT_LINE
            + 4.0
    };
    let body: f64 = t.networks.iter().map(|n| net_h(n) + NET_GAP).sum();
    let height = TOP + body + AXIS_H + LEGEND_H;
    let ticks = ticks(t.start, t.end);

    let mut o = String::with_capacity(4096);
    // Writing to a String cannot fail.
    let _ = writeln!(
        o,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" viewBox="0 0 {w} {h}" role="img">"#,
        w = num(WIDTH),
        h = num(height)
    );
    let _ = writeln!(o, "<title>{}</title>", esc(&t.title));
    let _ = writeln!(o, "<style>{STYLE}</style>");
    let _ = writeln!(
        o,
        r##"<rect class="background" x="0" y="0" width="{}" height="{}" fill="#ffffff"/>"##,
        num(WIDTH),
        num(height)
    );
    let _ = writeln!(
        o,
        r#"<text class="title" x="16" y="26">{}</text>"#,
        esc(&t.title)
    );
    let faults: usize = t.networks.iter().map(|n| n.faults.len()).sum();
    let _ = writeln!(
        o,
        r#"<text class="subtitle" x="16" y="44">{} network(s), {} s to {} s of simulated time, {} fault(s)</text>"#,
        t.networks.len(),
        num(t.start),
        num(t.end),
        faults
    );

    let grid_bottom = TOP + body - NET_GAP;
    o.push_str("<g class=\"grid\">\n");
    for &(s, _) in &ticks {
        let _ = writeln!(
            o,
            r#"<line x1="{x}" y1="{}" x2="{x}" y2="{}"/>"#,
            num(TOP),
            num(grid_bottom),
            x = num(x(s))
        );
    }
    o.push_str("</g>\n");

    let mut y = TOP;
    let mut used = BTreeSet::new();
    for (i, n) in t.networks.iter().enumerate() {
        let _ = writeln!(
            o,
            r#"<g class="network" id="network-{i}" data-name="{}">"#,
            esc(&n.name)
        );
        let _ = writeln!(
            o,
            r#"<text class="network-name" x="16" y="{}">{}</text>"#,
            num(y + 16.0),
            esc(&n.name)
        );
        let lanes_top = y + NET_HEADER;
        let mut ly = lanes_top;
        for lane in &n.lanes {
            let _ = writeln!(
                o,
                r#"<g class="lane" data-kind="{}" data-label="{}">"#,
                lane.kind.name(),
                esc(&lane.label)
            );
            let _ = writeln!(
                o,
                r#"<text class="lane-label" x="28" y="{}">{}</text>"#,
                num(ly + 13.0),
                esc(&lane.label)
            );
            let _ = writeln!(
                o,
                r#"<rect class="lane-bg" x="{}" y="{}" width="{}" height="{}"/>"#,
                num(LEFT),
                num(ly),
                num(plot_w),
                num(LANE_H)
            );
            for s in &lane.spans {
                used.insert(s.state);
                let (x0, x1) = (x(s.from), x(s.to));
                let w = (x1 - x0).max(0.0);
                let tip = if s.label.is_empty() {
                    format!(
                        "{}: {} from {} s to {} s",
                        lane.label,
                        s.state.name(),
                        num(s.from),
                        num(s.to)
                    )
                } else {
                    format!(
                        "{}: {} ({}) from {} s to {} s",
                        lane.label,
                        s.label,
                        s.state.name(),
                        num(s.from),
                        num(s.to)
                    )
                };
                let _ = writeln!(
                    o,
                    r#"<rect class="span state-{}" x="{}" y="{}" width="{}" height="{}" fill="{}"><title>{}</title></rect>"#,
                    s.state.name(),
                    num(x0),
                    num(ly),
                    num(w),
                    num(LANE_H),
                    s.state.color(),
                    esc(&tip)
                );
                if !s.label.is_empty() && w > s.label.chars().count() as f64 * CHAR_W + 6.0 {
                    let dark = matches!(
                        s.state,
                        State::Suspect | State::Standby | State::Unknown | State::Ok
                    );
                    let _ = writeln!(
                        o,
                        r#"<text class="span-label{}" x="{}" y="{}">{}</text>"#,
                        if dark { " dark" } else { "" },
                        num(x0 + 4.0),
                        num(ly + 13.0),
                        esc(&s.label)
                    );
                }
            }
            o.push_str("</g>\n");
            ly += LANE_H + LANE_GAP;
        }
        let lanes_bottom = ly - LANE_GAP;
        let mut fy = ly + 8.0;
        for (k, f) in n.faults.iter().enumerate() {
            let fx = x(f.at);
            let tip = format!("{} s: {}", num(f.at), f.label);
            let _ = writeln!(
                o,
                r#"<g class="fault" data-at="{}"><title>{}</title>"#,
                num(f.at),
                esc(&tip)
            );
            let _ = writeln!(
                o,
                r#"<line x1="{fx}" y1="{}" x2="{fx}" y2="{}"/>"#,
                num(lanes_top - 2.0),
                num(lanes_bottom + 2.0),
                fx = num(fx)
            );
            let _ = writeln!(
                o,
                r#"<circle cx="{}" cy="{}" r="7"/><text class="marker-number" x="{}" y="{}" text-anchor="middle">{}</text>"#,
                num(fx),
                num(lanes_top - 9.0),
                num(fx),
                num(lanes_top - 5.5),
                k + 1
            );
            let _ = writeln!(
                o,
                r#"<circle cx="{}" cy="{}" r="7"/><text class="marker-number" x="{}" y="{}" text-anchor="middle">{}</text>"#,
                num(LEFT + 7.0),
                num(fy - 4.0),
                num(LEFT + 7.0),
                num(fy - 0.5),
                k + 1
            );
            let _ = writeln!(
                o,
                r#"<text class="fault-label" x="{}" y="{}">{} s  {}</text>"#,
                num(LEFT + 20.0),
                num(fy),
                num(f.at),
                esc(&f.label)
            );
            o.push_str("</g>\n");
            fy += FAULT_LINE;
        }
        o.push_str("</g>\n");
        y += net_h(n) + NET_GAP;
    }

    let ay = TOP + body;
    o.push_str("<g class=\"axis\">\n");
    let _ = writeln!(
        o,
        r#"<line x1="{}" y1="{ay}" x2="{}" y2="{ay}"/>"#,
        num(LEFT),
        num(LEFT + plot_w),
        ay = num(ay)
    );
    for (s, label) in &ticks {
        let _ = writeln!(
            o,
            r#"<line x1="{x}" y1="{}" x2="{x}" y2="{}"/><text class="tick-label" x="{x}" y="{}" text-anchor="middle">{}</text>"#,
            num(ay),
            num(ay + 5.0),
            num(ay + 18.0),
            esc(label),
            x = num(x(*s))
        );
    }
    let _ = writeln!(
        o,
        r#"<text class="axis-title" x="{}" y="{}" text-anchor="middle">simulated time (s)</text>"#,
        num(LEFT + plot_w / 2.0),
        num(ay + 36.0)
    );
    o.push_str("</g>\n");

    let ly = ay + AXIS_H + 14.0;
    o.push_str("<g class=\"legend\">\n");
    let mut lx = LEFT;
    for s in State::ALL.iter().filter(|s| used.contains(*s)) {
        let _ = writeln!(
            o,
            r#"<rect class="swatch state-{}" x="{}" y="{}" width="14" height="14" fill="{}"/><text x="{}" y="{}">{}</text>"#,
            s.name(),
            num(lx),
            num(ly - 11.0),
            s.color(),
            num(lx + 19.0),
            num(ly),
            s.name()
        );
        lx += 24.0 + s.name().len() as f64 * 7.5 + 16.0;
    }
    if faults > 0 {
        let _ = writeln!(
            o,
            r##"<line x1="{x}" y1="{}" x2="{x}" y2="{}" stroke="#b71c1c" stroke-width="1.5" stroke-dasharray="4 3"/><text x="{}" y="{}">fault</text>"##,
            num(ly - 12.0),
            num(ly + 3.0),
            num(lx + 10.0),
            num(ly),
            x = num(lx + 4.0)
        );
    }
    o.push_str("</g>\n</svg>\n");
    Ok(o)
}

fn validate(t: &Timeline) -> Result<(), ChartError> {
    for n in &t.networks {
        for l in &n.lanes {
            for s in &l.spans {
                if !(s.from.is_finite() && s.to.is_finite() && s.to >= s.from) {
                    return Err(ChartError::BadSpan {
                        network: n.name.clone(),
                        lane: l.label.clone(),
                        from: s.from,
                        to: s.to,
                    });
                }
            }
        }
        if let Some(f) = n.faults.iter().find(|f| !f.at.is_finite()) {
            return Err(ChartError::BadFault {
                network: n.name.clone(),
                label: f.label.clone(),
            });
        }
    }
    Ok(())
}

/// Tick positions and labels: a 1-2-5 step giving 5 to 12 ticks.
fn ticks(start: f64, end: f64) -> Vec<(f64, String)> {
    let raw = (end - start) / 10.0;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * mag);
    let decimals = if step >= 1.0 {
        0
    } else {
        (-step.log10().floor()) as usize
    };
    let first = (start / step).ceil() as i64;
    let last = (end / step + 1e-9).floor() as i64;
    (first..=last)
        .map(|k| {
            let s = k as f64 * step;
            (s, format!("{s:.decimals$} s"))
        })
        .collect()
}

/// A coordinate or time with at most two decimals.
fn num(v: f64) -> String {
    let s = format!("{v:.2}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" {
        "0".into()
    } else {
        s.into()
    }
}

/// XML text and attribute escaping.
fn esc(s: &str) -> String {
    let mut o = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => o.push_str("&amp;"),
            '<' => o.push_str("&lt;"),
            '>' => o.push_str("&gt;"),
            '"' => o.push_str("&quot;"),
            '\'' => o.push_str("&apos;"),
            // Control characters are not allowed in XML 1.0.
            c if (c as u32) < 0x20 && !matches!(c, '\t' | '\n' | '\r') => o.push(' '),
            c => o.push(c),
        }
    }
    o
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_are_round() {
        let t: Vec<_> = ticks(0.0, 60.0).into_iter().map(|x| x.1).collect();
        assert_eq!(t, ["0 s", "10 s", "20 s", "30 s", "40 s", "50 s", "60 s"]);
        let t: Vec<_> = ticks(0.0, 0.9).into_iter().map(|x| x.1).collect();
        assert_eq!(t.first().map(String::as_str), Some("0.0 s"));
        assert_eq!(t.last().map(String::as_str), Some("0.9 s"));
        let t = ticks(3.5, 44.0);
        assert_eq!((t.len(), t[0].0, t[7].0), (8, 5.0, 40.0));
    }

    #[test]
    fn numbers_and_escapes() {
        assert_eq!(num(1.0), "1");
        assert_eq!(num(1.25), "1.25");
        assert_eq!(num(-0.001), "0");
        assert_eq!(esc("a<b & \"c\"\u{1}"), "a&lt;b &amp; &quot;c&quot; ");
    }

    #[test]
    fn bad_input_is_an_error() {
        let mut t = Timeline {
            title: "x".into(),
            start: 5.0,
            end: 5.0,
            networks: vec![],
        };
        assert!(matches!(render(&t), Err(ChartError::Range { .. })));
        t.end = 10.0;
        t.networks.push(Network {
            name: "n".into(),
            lanes: vec![Lane {
                label: "bus 1".into(),
                kind: LaneKind::Bus,
                spans: vec![Span::new(7.0, 6.0, State::Ok)],
            }],
            faults: vec![],
        });
        let e = render(&t).unwrap_err();
        assert!(e.to_string().contains("lane bus 1"), "{e}");
        t.networks[0].lanes.clear();
        t.networks[0].faults.push(Fault::new(f64::NAN, "cut"));
        assert!(matches!(render(&t), Err(ChartError::BadFault { .. })));
    }
}
