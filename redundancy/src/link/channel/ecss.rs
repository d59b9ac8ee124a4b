//! ECSS-E-ST-50-15C bus toggling, as found in space-grade CANopen.
//!
//! Traffic uses one active bus (0x2000 sub 1, Bdefault, at start); frames received on the other
//! bus are not delivered. A **slave** watches the redundancy master's heartbeat (0x1016 sub 1:
//! its node-ID and the consumer time `P`) on the active bus, from its own boot-up on:
//!
//! - on loss (`P` after the last heartbeat, or after boot-up): report [`MasterLost`] and ask the
//!   node on top to enter pre-operational (`LinkRequest::EnterPreOperational`), Ctoggle = 0, wait (Ttoggle − 1) × `P`, switch bus,
//!   Ctoggle += 1; keep toggling every Ttoggle × `P` while Ctoggle < Ntoggle; when the next
//!   toggle would exceed Ntoggle, stay and report [`NoMaster`];
//! - when the master's heartbeat is heard on the active bus again, that bus becomes the default
//!   ([`MasterFound`]).
//!
//! The dual-bus layer writes Bdefault (sub 1) and Ctoggle (sub 4) into the node's dictionary as
//! they change (`LinkRequest::SetStatus`), so a master reads them over SDO.
//!
//! `P` stands for the master's heartbeat period: the consumer time is the only period a slave
//! knows. A Ttoggle of zero is treated as one. A **master** stays on its bus until commanded
//! ([`crate::DualBus::select_channel`]); its slaves follow by toggling.
//!
//! [`MasterLost`]: crate::link::events::LinkEventKind::MasterLost
//! [`NoMaster`]: crate::link::events::LinkEventKind::NoMaster
//! [`MasterFound`]: crate::link::events::LinkEventKind::MasterFound

use super::{switched, ChannelPolicy, FrameInfo, PortMask, RxRoute};
use crate::link::events::{LinkEvent, LinkEventKind, SwitchReason};
use crate::link::health::Health;
use crate::link::outbox::Outbox;
use duocan::machine::{LinkRequest, PortStatus};
use duocan::{Duration, Frame, Instant, NodeId};

/// What this device is in the bus-toggle scheme.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EcssRole {
    /// The redundancy master: selects the bus.
    Master,
    /// A slave following the master's heartbeat.
    Slave {
        /// The redundancy master (0x1016 sub 1, bits 16–23).
        master: NodeId,
        /// Its heartbeat consumer time (0x1016 sub 1, bits 0–15, ms).
        period: Duration,
    },
}

/// Bus-toggle configuration (0x2000 and 0x1016 sub 1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub struct EcssConfig {
    /// Sub 1, Bdefault: the bus (port) to start on.
    pub bdefault: u8,
    /// Sub 2, Ttoggle: heartbeat periods per toggle.
    pub ttoggle: u8,
    /// Sub 3, Ntoggle: toggles before giving up.
    pub ntoggle: u8,
    /// Master or slave.
    pub role: EcssRole,
}

// Builders: the struct is `#[non_exhaustive]` (it may gain fields), so code outside the crate
// starts from a constructor or `Default` and sets what it needs.
impl EcssConfig {
    /// The configuration with [`bdefault`](Self::bdefault) replaced.
    #[must_use]
    pub fn with_bdefault(mut self, bdefault: u8) -> Self {
        self.bdefault = bdefault;
        self
    }
    /// The configuration with [`ttoggle`](Self::ttoggle) replaced.
    #[must_use]
    pub fn with_ttoggle(mut self, ttoggle: u8) -> Self {
        self.ttoggle = ttoggle;
        self
    }
    /// The configuration with [`ntoggle`](Self::ntoggle) replaced.
    #[must_use]
    pub fn with_ntoggle(mut self, ntoggle: u8) -> Self {
        self.ntoggle = ntoggle;
        self
    }
    /// The configuration with [`role`](Self::role) replaced.
    #[must_use]
    pub fn with_role(mut self, role: EcssRole) -> Self {
        self.role = role;
        self
    }
}

impl EcssConfig {
    /// A slave of `master` whose heartbeat is expected every `period`: starts on bus 1, toggles
    /// after 2 periods, at most 4 times.
    #[must_use]
    pub const fn slave(master: NodeId, period: Duration) -> Self {
        EcssConfig {
            bdefault: 0,
            ttoggle: 2,
            ntoggle: 4,
            role: EcssRole::Slave { master, period },
        }
    }
    /// The redundancy master, on bus 1.
    #[must_use]
    pub const fn master() -> Self {
        EcssConfig {
            bdefault: 0,
            ttoggle: 2,
            ntoggle: 4,
            role: EcssRole::Master,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Phase {
    /// Not booted, or a master.
    Idle,
    Monitoring {
        deadline: Instant,
    },
    Toggling {
        next: Instant,
    },
    NoMaster,
}

/// The bus-toggle policy.
#[derive(Clone, Debug)]
pub struct Ecss {
    cfg: EcssConfig,
    active: usize,
    bdefault: u8,
    ctoggle: u8,
    phase: Phase,
}

impl Ecss {
    /// On Bdefault, idle until the node's boot-up.
    #[must_use]
    pub fn new(cfg: EcssConfig) -> Self {
        let b = cfg.bdefault.min(1);
        Ecss {
            cfg,
            active: b as usize,
            bdefault: b,
            ctoggle: 0,
            phase: Phase::Idle,
        }
    }
    /// The configuration.
    pub fn config(&self) -> &EcssConfig {
        &self.cfg
    }
    /// The active bus.
    pub fn active_bus(&self) -> usize {
        self.active
    }
    /// The current default bus (0x2000 sub 1): where the master was last found.
    pub fn bdefault(&self) -> u8 {
        self.bdefault
    }
    /// The toggle counter (0x2000 sub 4).
    pub fn ctoggle(&self) -> u8 {
        self.ctoggle
    }
    /// True after Ntoggle toggles without finding the master.
    pub fn no_master(&self) -> bool {
        self.phase == Phase::NoMaster
    }
    fn slave(&self) -> Option<(NodeId, Duration)> {
        match self.cfg.role {
            EcssRole::Slave { master, period } => Some((master, period)),
            EcssRole::Master => None,
        }
    }
    fn ttoggle(&self) -> u64 {
        self.cfg.ttoggle.max(1) as u64
    }
}

impl ChannelPolicy for Ecss {
    fn route_tx(
        &mut self,
        now: Instant,
        frame: &Frame,
        info: &FrameInfo,
        _: &Health,
        _: &mut Outbox,
    ) -> PortMask {
        if info.is_boot_up(frame) && self.phase == Phase::Idle {
            if let Some((_, period)) = self.slave() {
                self.phase = Phase::Monitoring {
                    deadline: now + period,
                };
            }
        }
        1 << self.active
    }

    fn on_rx(
        &mut self,
        now: Instant,
        port: usize,
        _: &Frame,
        info: &FrameInfo,
        out: &mut Outbox,
    ) -> RxRoute {
        if port != self.active {
            return RxRoute::Ignore;
        }
        if let Some((master, period)) = self.slave() {
            if info.heartbeat == Some(master) {
                if matches!(self.phase, Phase::Toggling { .. } | Phase::NoMaster) {
                    self.bdefault = self.active as u8;
                    out.event(LinkEvent {
                        at: now,
                        kind: LinkEventKind::MasterFound {
                            master,
                            bus: self.active as u8,
                        },
                    });
                }
                self.phase = Phase::Monitoring {
                    deadline: now + period,
                };
            }
        }
        RxRoute::Direct
    }

    fn on_status(&mut self, _: Instant, _: usize, _: PortStatus, _: &mut Outbox) {}

    fn handle_timeout(&mut self, now: Instant, out: &mut Outbox) {
        let Some((master, period)) = self.slave() else {
            return;
        };
        loop {
            match self.phase {
                Phase::Monitoring { deadline } if deadline <= now => {
                    out.event(LinkEvent {
                        at: deadline,
                        kind: LinkEventKind::MasterLost {
                            master,
                            bus: self.active as u8,
                        },
                    });
                    out.machine(LinkRequest::EnterPreOperational);
                    self.ctoggle = 0;
                    self.phase = Phase::Toggling {
                        next: deadline + period.saturating_mul(self.ttoggle() - 1),
                    };
                }
                Phase::Toggling { next } if next <= now => {
                    if self.ctoggle < self.cfg.ntoggle {
                        let from = self.active;
                        self.active = 1 - from;
                        self.ctoggle += 1;
                        out.event(LinkEvent {
                            at: next,
                            kind: LinkEventKind::Toggle {
                                from: from as u8,
                                to: self.active as u8,
                                ctoggle: self.ctoggle,
                            },
                        });
                        self.phase = Phase::Toggling {
                            next: next + period.saturating_mul(self.ttoggle()),
                        };
                    } else {
                        out.event(LinkEvent {
                            at: next,
                            kind: LinkEventKind::NoMaster {
                                bus: self.active as u8,
                                ctoggle: self.ctoggle,
                            },
                        });
                        self.phase = Phase::NoMaster;
                    }
                }
                _ => break,
            }
        }
    }

    fn poll_timeout(&self) -> Option<Instant> {
        match self.phase {
            Phase::Monitoring { deadline } => Some(deadline),
            Phase::Toggling { next } => Some(next),
            Phase::Idle | Phase::NoMaster => None,
        }
    }

    fn active(&self) -> Option<usize> {
        Some(self.active)
    }

    fn select(&mut self, now: Instant, port: usize, out: &mut Outbox) -> bool {
        let to = port.min(1);
        if to != self.active {
            let from = self.active;
            self.active = to;
            switched(out, now, from, to, SwitchReason::Command);
            if let Some((_, period)) = self.slave() {
                if self.phase != Phase::Idle {
                    self.phase = Phase::Monitoring {
                        deadline: now + period,
                    };
                }
            }
        }
        true
    }

    fn step_back(&mut self, by: Duration) {
        match &mut self.phase {
            Phase::Monitoring { deadline: t } | Phase::Toggling { next: t } => *t = *t - by,
            Phase::Idle | Phase::NoMaster => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use duocan::Id;

    fn ms(x: u64) -> Instant {
        Instant::from_millis(x)
    }
    const M: NodeId = NodeId::must(1);
    fn hb() -> (Frame, FrameInfo) {
        (
            Frame::from_array(Id::Standard(0x701), [5]),
            FrameInfo { heartbeat: Some(M) },
        )
    }
    fn booted(cfg: EcssConfig) -> (Ecss, Outbox) {
        let mut p = Ecss::new(cfg);
        let mut out = Outbox::new();
        let h = Health::new(Default::default(), Duration::from_millis(10));
        let f = Frame::from_array(Id::Standard(0x705), [0]);
        let i = FrameInfo {
            heartbeat: NodeId::new(5),
        };
        assert_eq!(p.route_tx(ms(0), &f, &i, &h, &mut out), 0b01);
        (p, out)
    }
    fn run(p: &mut Ecss, out: &mut Outbox, until: Instant) {
        while let Some(d) = p.poll_timeout().filter(|d| *d <= until) {
            p.handle_timeout(d, out);
        }
    }
    fn kinds(out: &mut Outbox) -> Vec<(Instant, LinkEventKind)> {
        let mut v = vec![];
        while let Some(e) = out.events.pop() {
            v.push((e.at, e.kind));
        }
        v
    }

    #[test]
    fn loss_toggles_after_t_minus_one_then_every_t_periods_until_n_then_no_master() {
        let cfg = EcssConfig {
            ttoggle: 3,
            ntoggle: 2,
            ..EcssConfig::slave(M, Duration::from_millis(100))
        };
        let (mut p, mut out) = booted(cfg);
        let (f, i) = hb();
        p.on_rx(ms(50), 0, &f, &i, &mut out);
        // Heard on the inactive bus: ignored, not delivered.
        assert_eq!(p.on_rx(ms(120), 1, &f, &i, &mut out), RxRoute::Ignore);
        run(&mut p, &mut out, ms(5000));
        assert_eq!(
            kinds(&mut out),
            [
                (ms(150), LinkEventKind::MasterLost { master: M, bus: 0 }),
                (
                    ms(350),
                    LinkEventKind::Toggle {
                        from: 0,
                        to: 1,
                        ctoggle: 1
                    }
                ),
                (
                    ms(650),
                    LinkEventKind::Toggle {
                        from: 1,
                        to: 0,
                        ctoggle: 2
                    }
                ),
                (ms(950), LinkEventKind::NoMaster { bus: 0, ctoggle: 2 }),
            ]
        );
        assert!(p.no_master());
    }

    #[test]
    fn master_found_on_the_other_bus_becomes_the_default() {
        let (mut p, mut out) = booted(EcssConfig::slave(M, Duration::from_millis(100)));
        run(&mut p, &mut out, ms(250));
        // Lost at 100 (boot-up + P), toggled at 200 (Ttoggle 2).
        assert_eq!(p.active_bus(), 1);
        let (f, i) = hb();
        assert_eq!(p.on_rx(ms(260), 1, &f, &i, &mut out), RxRoute::Direct);
        assert_eq!(p.bdefault(), 1);
        assert_eq!(
            kinds(&mut out),
            [
                (ms(100), LinkEventKind::MasterLost { master: M, bus: 0 }),
                (
                    ms(200),
                    LinkEventKind::Toggle {
                        from: 0,
                        to: 1,
                        ctoggle: 1
                    }
                ),
                (ms(260), LinkEventKind::MasterFound { master: M, bus: 1 }),
            ]
        );
        assert_eq!(p.poll_timeout(), Some(ms(360)));
    }

    #[test]
    fn master_stays_until_commanded() {
        let (mut p, mut out) = booted(EcssConfig::master());
        assert_eq!(p.poll_timeout(), None);
        p.select(ms(10), 1, &mut out);
        assert_eq!(p.active_bus(), 1);
        assert_eq!(
            kinds(&mut out),
            [(
                ms(10),
                LinkEventKind::Channel {
                    from: 0,
                    to: 1,
                    reason: SwitchReason::Command
                }
            )]
        );
    }
}
