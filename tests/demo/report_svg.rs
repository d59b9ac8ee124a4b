//! The timeline chart is well-formed XML that a browser opens, and has the elements it claims:
//! one group per network, one lane per row, one rect per span at the right place, one marker
//! per fault, axis labels and a legend of the states used.

use crate::scenario::report::{
    render, ChartError, Fault, Lane, LaneKind, Network, Span, State, Timeline,
};
use roxmltree::{Document, Node};

const END: f64 = 60.0;

fn bus(label: &str, changes: &[(f64, State)]) -> Lane {
    Lane::from_changes(label, LaneKind::Bus, changes, END)
}

/// Four racks of a station, with the day of faults of the demo's script.
fn station() -> Timeline {
    let ok = |l: &str| bus(l, &[(0.0, State::Ok)]);
    let pair = |label: &str, changes: &[(f64, State, &str)]| Lane {
        label: label.into(),
        kind: LaneKind::Pair,
        spans: changes
            .iter()
            .enumerate()
            .map(|(i, &(t, s, who))| {
                let to = changes.get(i + 1).map_or(END, |c| c.0);
                Span::new(t, to, s).labelled(who)
            })
            .collect(),
    };
    let master = |label: &str, changes: &[(f64, State)]| {
        Lane::from_changes(label, LaneKind::Master, changes, END)
    };
    let masters = || {
        vec![
            master(
                "strong master",
                &[
                    (0.0, State::Active),
                    (30.0, State::Down),
                    (45.0, State::Standby),
                ],
            ),
            master(
                "weak master",
                &[(0.0, State::Standby), (30.1, State::Active)],
            ),
        ]
    };
    let net = |name: &str, mut lanes: Vec<Lane>, faults: Vec<Fault>| {
        lanes.extend(masters());
        Network {
            name: name.into(),
            lanes,
            faults,
        }
    };
    Timeline {
        title: "Station day: faults & failovers <demo>".into(),
        start: 0.0,
        end: END,
        networks: vec![
            net(
                "turnout rack",
                vec![
                    ok("bus 1"),
                    ok("bus 2"),
                    pair(
                        "pair 1 (points 1-2)",
                        &[(0.0, State::Active, "A"), (20.15, State::Active, "B")],
                    ),
                ],
                vec![
                    Fault::new(20.0, "board 1A killed"),
                    Fault::new(30.0, "strong master killed"),
                ],
            ),
            net(
                "signal rack",
                vec![
                    bus(
                        "bus 1",
                        &[
                            (0.0, State::Ok),
                            (12.0, State::Suspect),
                            (12.3, State::Failed),
                            (40.0, State::Recovering),
                            (40.05, State::Ok),
                        ],
                    ),
                    ok("bus 2"),
                ],
                vec![
                    Fault::new(12.0, "bus 1 cut"),
                    Fault::new(40.0, "bus 1 restored"),
                ],
            ),
            net("track-circuit rack", vec![ok("bus 1"), ok("bus 2")], vec![]),
            net(
                "misc rack",
                vec![ok("bus 1"), ok("bus 2")],
                vec![Fault::new(50.0, "partition healed")],
            ),
        ],
    }
}

fn class_is(n: &Node, class: &str) -> bool {
    n.attribute("class")
        .is_some_and(|c| c.split_whitespace().any(|x| x == class))
}

fn all<'a, 'i>(root: Node<'a, 'i>, tag: &str, class: &str) -> Vec<Node<'a, 'i>> {
    root.descendants()
        .filter(|n| n.has_tag_name(tag) && class_is(n, class))
        .collect()
}

fn f(n: &Node, attr: &str) -> f64 {
    n.attribute(attr).unwrap().parse().unwrap()
}

#[test]
fn the_chart_parses_and_has_what_it_claims() {
    let t = station();
    let svg = render(&t).unwrap();
    std::fs::write(
        std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("timeline.svg"),
        &svg,
    )
    .unwrap();
    let doc = Document::parse(&svg).expect("well-formed XML");
    let root = doc.root_element();
    assert_eq!(root.tag_name().name(), "svg");
    assert_eq!(
        root.tag_name().namespace(),
        Some("http://www.w3.org/2000/svg")
    );
    let (w, h) = (f(&root, "width"), f(&root, "height"));
    assert_eq!(
        root.attribute("viewBox"),
        Some(format!("0 0 {w} {h}").as_str())
    );
    // Standalone: no scripts, no external references.
    assert!(!root.descendants().any(|n| n.has_tag_name("script")
        || n.has_tag_name("image")
        || n.attributes().any(|a| a.name() == "href")));
    let title = root.children().find(|n| n.has_tag_name("title")).unwrap();
    assert_eq!(title.text(), Some(t.title.as_str()));

    // One group per network, in order, with its lanes and spans.
    let nets = all(root, "g", "network");
    assert_eq!(nets.len(), t.networks.len());
    let mut plot: Option<(f64, f64)> = None;
    for (g, net) in nets.iter().zip(&t.networks) {
        assert_eq!(g.attribute("data-name"), Some(net.name.as_str()));
        let lanes = all(*g, "g", "lane");
        assert_eq!(lanes.len(), net.lanes.len(), "{}", net.name);
        for (lg, lane) in lanes.iter().zip(&net.lanes) {
            let kind = match lane.kind {
                LaneKind::Bus => "bus",
                LaneKind::Pair => "pair",
                LaneKind::Master => "master",
            };
            assert_eq!(lg.attribute("data-kind"), Some(kind));
            assert_eq!(lg.attribute("data-label"), Some(lane.label.as_str()));
            let rects = all(*lg, "rect", "span");
            assert_eq!(rects.len(), lane.spans.len(), "{} {}", net.name, lane.label);
            for (r, s) in rects.iter().zip(&lane.spans) {
                assert!(class_is(r, &format!("state-{}", s.state.name())));
                assert_eq!(r.attribute("fill"), Some(s.state.color()));
                let tip = r.children().find(|n| n.has_tag_name("title")).unwrap();
                assert!(tip.text().unwrap().starts_with(&lane.label));
            }
            // Spans tile the lane: each starts where the previous ended, widths in
            // proportion to durations.
            for k in 1..rects.len() {
                let end = f(&rects[k - 1], "x") + f(&rects[k - 1], "width");
                assert!((f(&rects[k], "x") - end).abs() < 0.02);
            }
            let x0 = f(&rects[0], "x");
            let last = rects.last().unwrap();
            let x1 = f(last, "x") + f(last, "width");
            match plot {
                None => plot = Some((x0, x1)),
                Some(p) => assert!((p.0 - x0).abs() < 0.02 && (p.1 - x1).abs() < 0.02),
            }
            let per_s = (x1 - x0) / END;
            for (r, s) in rects.iter().zip(&lane.spans) {
                assert!((f(r, "width") - (s.to - s.from) * per_s).abs() < 0.02);
            }
        }
        // A marker per fault, at its time, with its label.
        let faults = all(*g, "g", "fault");
        assert_eq!(faults.len(), net.faults.len(), "{}", net.name);
        let (x0, x1) = plot.unwrap();
        for (fg, fault) in faults.iter().zip(&net.faults) {
            let line = fg.children().find(|n| n.has_tag_name("line")).unwrap();
            let want = x0 + fault.at / END * (x1 - x0);
            assert!((f(&line, "x1") - want).abs() < 0.02);
            let label = all(*fg, "text", "fault-label");
            assert!(label[0].text().unwrap().ends_with(&fault.label));
        }
    }
    // The signal rack's bus 1 failed exactly at its fault marker.
    let signal = nets[1];
    let bus1 = all(signal, "g", "lane")[0];
    let suspect = all(bus1, "rect", "state-suspect")[0];
    let cut = all(signal, "g", "fault")[0];
    let line = cut.children().find(|n| n.has_tag_name("line")).unwrap();
    assert!((f(&suspect, "x") - f(&line, "x1")).abs() < 0.02);
    let pair_labels: Vec<_> = all(nets[0], "text", "span-label")
        .iter()
        .map(|n| n.text().unwrap())
        .collect();
    assert_eq!(pair_labels, ["A", "B"]);

    // The time axis: round ticks from 0 to 60 s, and its title.
    let axis = all(root, "g", "axis");
    assert_eq!(axis.len(), 1);
    let ticks: Vec<_> = all(axis[0], "text", "tick-label")
        .iter()
        .map(|n| n.text().unwrap())
        .collect();
    assert_eq!(
        ticks,
        ["0 s", "10 s", "20 s", "30 s", "40 s", "50 s", "60 s"]
    );
    assert!(axis[0]
        .descendants()
        .any(|n| n.text() == Some("simulated time (s)")));

    // The legend names the states used, and only those.
    let legend = all(root, "g", "legend");
    let swatches: Vec<_> = all(legend[0], "rect", "swatch")
        .iter()
        .map(|n| n.attribute("class").unwrap().replace("swatch state-", ""))
        .collect();
    assert_eq!(
        swatches,
        [
            "ok",
            "suspect",
            "failed",
            "recovering",
            "active",
            "standby",
            "down"
        ]
    );
    assert!(h > 600.0 && w == 1200.0);
}

#[test]
fn the_subtitle_counts_from_the_data() {
    let mut t = station();
    t.networks.truncate(2);
    let svg = render(&t).unwrap();
    let doc = Document::parse(&svg).unwrap();
    let sub = all(doc.root_element(), "text", "subtitle")[0]
        .text()
        .unwrap();
    assert_eq!(
        sub,
        "2 network(s), 0 s to 60 s of simulated time, 4 fault(s)"
    );
}

/// The example in the renderer's module documentation.
#[test]
fn module_doc_example_renders() -> Result<(), ChartError> {
    let chart = Timeline {
        title: "signal rack".into(),
        start: 0.0,
        end: 60.0,
        networks: vec![Network {
            name: "signal rack".into(),
            lanes: vec![Lane::from_changes(
                "bus 1",
                LaneKind::Bus,
                &[(0.0, State::Ok), (12.3, State::Failed), (40.0, State::Ok)],
                60.0,
            )],
            faults: vec![Fault::new(12.3, "bus 1 cut")],
        }],
    };
    let svg = render(&chart)?;
    assert!(svg.starts_with("<svg") && svg.contains("bus 1 cut"));
    Ok(())
}
