//! CiA 302-2 flying master: which of several master-capable devices is the active NMT master.
//!
//! [`FlyingMaster`] is a sans-IO machine for one master-capable device (0x1F80 bit 5). It takes
//! the flying-master frames (COB-IDs 0x71–0x76), the heartbeats of the other masters and hints of
//! a second active master; it yields frames, role changes and whether this device may command the
//! network now ([`FlyingMaster::may_command`]).
//!
//! # Frames
//!
//! | COB-ID | name                    | DLC | payload              |
//! |--------|-------------------------|-----|----------------------|
//! | 0x71   | active-master response  | 2   | priority, node-ID    |
//! | 0x72   | negotiation request     | 0   |                      |
//! | 0x73   | active-master request   | 0   |                      |
//! | 0x74   | master-capable response | 2   | priority, node-ID    |
//! | 0x75   | master-capable request  | 0   |                      |
//! | 0x76   | force negotiation       | 2   | priority, node-ID    |
//!
//! A [`Rank`] is (priority, node-ID); the lower one wins. The strong master is the one with the
//! better priority.
//!
//! # Power-on and forced negotiation (the CiA 302-2 timing)
//!
//! After power-on the device asks for the active master (0x73) and waits the active-master
//! detection timeout (0x1F90 sub 1). An answer (0x71) makes it standby. Without one it sends a
//! negotiation request (0x72); every master-capable device that is not active starts the
//! negotiation when it hears it. Each waits negotiation delay (sub 2) + priority × priority
//! slot (sub 4) + node-ID × device slot (sub 5) and then announces itself on 0x71, unless it
//! heard an announcement first: the first to announce wins, which is the best rank.
//!
//! # Takeover on loss of the active master's heartbeat (the failover bound)
//!
//! A hot standby does not negotiate when the active master's heartbeat is lost: it knows the
//! ranks and the liveness of the other master-capable devices (their heartbeats, 0x74/0x71/0x76
//! payloads). At the heartbeat deadline (last heartbeat + [`FlyingMasterConfig::master_timeout`])
//! it waits one device slot per *live* device ranked better than itself — zero when it is the
//! best one left, as the weak master of a pair always is — and then announces itself on 0x71
//! and is active. So the takeover happens exactly at the master-heartbeat timeout; the priority
//! slots of 302-2 (1.5 s each) apply only to the power-on and forced negotiations, where nobody
//! knows who is there.
//!
//! # Several active masters (healed partition)
//!
//! The active master sends 0x76 with its rank every multiple-master detect cycle (sub 6). An
//! active master that hears 0x76 or 0x71 from another device claiming to be active resolves the
//! conflict at once by rank, which is what a renegotiation between the two would decide, without
//! a period with no master: the worse one demotes and follows the better one; the better one
//! answers with 0x71 so that every device learns who is active. Any sign of another active
//! master — a SYNC or NMT command it did not send ([`FlyingMaster::foreign_activity`]), the
//! heartbeat of a master it had lost coming back — makes an active master send 0x76 at once and
//! *suspend* its NMT commands until the detection timeout has passed without a conflict: during
//! the overlap no two masters command the slaves.
//!
//! Two claims can cross: the weak master stops hearing the strong one (its only working port
//! running behind past the master timeout), takes over and announces itself; the strong one,
//! which heard it all along, steps down for it (as for a manual take-over, below); and the
//! strong one's 0x76, sent just before, reaches the weak one after that, which steps down too.
//! Each would follow the other, both beating, and nobody be active. So a master that steps down
//! after a conflict asks for the active master (0x73): the one it follows must answer (0x71) or
//! send its 0x76 within the detection timeout, else this device starts a negotiation (0x72),
//! which the best one alive wins.
//!
//! # Planned hand-over
//!
//! [`FlyingMaster::hand_over`] announces a successor on 0x71 (its rank, not this device's):
//! the successor takes over at once, this device becomes its standby. With
//! [`FlyingMasterConfig::revertive`], an active master that hears a better master alive as
//! standby for [`FlyingMasterConfig::handback_delay`] asks for a hand-over
//! ([`FlyingMaster::take_handback`]); the supervisor does it between two SYNCs so that SYNC
//! has no gap. A standby can take the role by hand ([`FlyingMaster::take_over`]): its 0x71 makes
//! an active master that has heard it alive all along step down.
//!
//! # Files
//!
//! | File | What it holds |
//! | --- | --- |
//! | `frames.rs` | the six flying-master COB-IDs and [`Rank`], the payload of three of them |
//! | `config.rs` | [`FlyingMasterConfig`]: 0x1F90, read from the dictionary, and the additions |
//! | `events.rs` | what the machine reports: [`MasterRole`], [`MasterRoleChange`] and its [`MasterReason`], [`FlyingEvent`], [`FlyingMasterError`] |
//! | `state.rs` | what it knows: the other devices ([`Peer`]) and its phase, with the timers only that phase has |
//! | `machine.rs` | [`FlyingMaster`], the protocol itself |

mod config;
mod events;
mod frames;
mod machine;
mod state;

pub use config::{
    timing_objects, FlyingMasterConfig, FLYING_MASTER_TIMING, NMT_STARTUP, STARTUP_FLYING_MASTER,
};
pub use events::{FlyingEvent, FlyingMasterError, MasterReason, MasterRole, MasterRoleChange};
pub use frames::{
    Rank, ACTIVE_MASTER_REQUEST, ACTIVE_MASTER_RESPONSE, FORCE_NEGOTIATION, MASTER_CAPABLE_REQUEST,
    MASTER_CAPABLE_RESPONSE, NEGOTIATION_REQUEST,
};
pub use machine::FlyingMaster;
pub use state::{Peer, MAX_PEERS};
