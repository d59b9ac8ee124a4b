//! Cutting a vcan interface in the VM under a test: `ip`, an interface down until dropped, and
//! waiting for the runtime to report a port down or up. Included (`#[path]`) beside the root
//! crate's runtime helpers as `rt`.
#![allow(dead_code)]

use super::rt::wait_for;
use duocan::machine::PortStatus;
use duocan::runtime::RuntimeEvent;
use std::process::Command;
use tokio::sync::broadcast::Receiver;

pub fn ip(args: &[&str]) {
    let st = Command::new("ip").args(args).status().expect("run ip");
    assert!(st.success(), "ip {args:?} failed");
}

/// Takes an interface down; brings it back up when dropped (also when a test fails, so the next
/// test finds it up).
pub struct LinkDown(&'static str);

impl LinkDown {
    pub fn new(ifname: &'static str) -> Self {
        ip(&["link", "set", ifname, "down"]);
        LinkDown(ifname)
    }
}

impl Drop for LinkDown {
    fn drop(&mut self) {
        let _ = Command::new("ip")
            .args(["link", "set", self.0, "up"])
            .status();
    }
}

/// Waits up to `secs` for the runtime to report `port` down (`up` false) or up.
pub async fn port_reported<E: Clone>(
    ev: &mut Receiver<RuntimeEvent<E>>,
    port: usize,
    up: bool,
    secs: u64,
) {
    let what = format!(
        "runtime reports port {port} {}",
        if up { "up" } else { "down" }
    );
    wait_for(ev, secs, &what, |e| match e {
        RuntimeEvent::Port {
            port: p,
            status: PortStatus::Up,
            ..
        } if *p == port && up => Some(()),
        RuntimeEvent::Port {
            port: p,
            status: PortStatus::Down(_),
            ..
        } if *p == port && !up => Some(()),
        _ => None,
    })
    .await;
}
