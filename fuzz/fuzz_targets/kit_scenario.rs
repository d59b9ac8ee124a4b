//! The failover kit's scenario files (`duocan kit validate|run|sim|check FILE`): any bytes as
//! TOML through the kit's strict reader. Never a panic; a scenario read has every name it uses
//! defined (members in buses, devices, wires of expectations) and its faults sorted by time
//! within the run's duration.
#![no_main]
// The tool's modules, included as they are: the fuzz target uses a part of them.
#![allow(dead_code, unused_imports)]

// Side by side at the root, as in the tool's kit module: `scenario` uses `super::expect`.
#[path = "../../cli/src/cmd/kit/expect.rs"]
mod expect;
#[path = "../../cli/src/cmd/kit/scenario.rs"]
mod scenario;

use libfuzzer_sys::fuzz_target;
use scenario::{Fault, Scenario};

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Ok(s) = Scenario::parse(text, "fuzz.toml") else {
        return;
    };
    let members: Vec<&str> = s.members().collect();
    assert!(s.timeline.windows(2).all(|w| w[0].0 <= w[1].0));
    assert!(s.timeline.iter().all(|(t, _)| *t <= s.duration_ms));
    for d in &s.devices {
        assert!(d.ports.iter().all(|p| members.contains(&p.as_str())));
        assert!(!d.run.is_empty());
    }
    for (_, f) in &s.timeline {
        if let Fault::Disconnect(m) | Fault::Reconnect(m) | Fault::Latency(m, _) = f {
            assert!(members.contains(&m.as_str()), "{f:?}");
        }
    }
});
