//! ECSS-E-ST-50-15C bus toggling, as found in space-grade CANopen: one active bus, and slaves
//! that search for the redundancy master's heartbeat by toggling between the buses.
//!
//! # The rule
//!
//! Traffic uses one active bus (0x2000 sub 1, Bdefault, at start); frames received on the other
//! bus are not delivered. A **master** stays on its bus until commanded
//! ([`crate::DualBus::select_channel`]); its slaves follow by toggling. A **slave** watches the
//! redundancy master's heartbeat (0x1016 sub 1: its node-ID and the consumer time `P`) on the
//! active bus, from its own boot-up on. With a loss detected at `L`, Ttoggle `T` and Ntoggle `N`:
//!
//! - **Loss** at `L` = the last heartbeat heard + `P` (before the first one: the boot-up + `P`):
//!   report [`MasterLost`], ask the node on top to enter pre-operational
//!   (`LinkRequest::EnterPreOperational`), Ctoggle = 0. Reported once: the next loss needs a
//!   heartbeat heard first.
//! - **Toggles** at `L + (T − 1)·P`, then every `T·P`: switch the bus, Ctoggle += 1, report
//!   [`Toggle`]. The k-th toggle is at `L + (k·T − 1)·P`.
//! - **No master**: the toggle that brings Ctoggle to `N` is the last. At its instant the bus it
//!   switched to becomes the default (Bdefault) and [`NoMaster`] is reported, once; the slave
//!   stays on that bus.
//! - **Found**: a heartbeat of the master heard on the active bus while searching or after
//!   giving up makes that bus the default ([`MasterFound`]); watching starts again from it.
//!
//! `P` stands for the master's heartbeat period: the consumer time is the only period a slave
//! knows. A Ttoggle of zero turns toggling off: the slave stays on Bdefault and this policy
//! reports nothing (the node's own heartbeat consumer still sees the loss). An Ntoggle of zero
//! gives one toggle: the count is compared after the toggle.
//!
//! The dual-bus layer writes Bdefault (sub 1) and Ctoggle (sub 4) into the node's dictionary as
//! they change (`LinkRequest::SetStatus`), so a master reads them over SDO, and a device that
//! stores its parameters starts, next time, on the bus it last settled on.
//!
//! ## Where the rule comes from
//!
//! The instants, the counting and the default bus are those of lely-core's NMT redundancy
//! manager (its ECSS redundancy service): on the heartbeat consumer's timeout for the master it
//! enters pre-operational, zeroes Ctoggle and arms a timer for (Ttoggle − 1) consumer times; the
//! timer switches the bus, counts, and re-arms for Ttoggle consumer times while Ctoggle <
//! Ntoggle, else makes the active bus the default and raises "no master" in the same step; the
//! master's heartbeat heard again makes the active bus the default and stops the timer. A Ttoggle
//! of zero leaves its manager off, and it counts the toggle before comparing with Ntoggle (hence
//! the single toggle for zero). Its heartbeat consumer reports a timeout once and only re-arms on
//! the next heartbeat, as here.
//!
//! Two things differ. From the boot-up, lely-core arms the first toggle Ttoggle consumer times
//! ahead without a loss report; here the master not heard within `P` of the boot-up is reported
//! lost then, which puts the first toggle at the same instant (`P + (T − 1)·P`). And lely-core
//! toggles between whatever bus identifiers the application gave it; here the two ports.
//!
//! ## A flaky bus does not make the network oscillate
//!
//! - A search starts only after `P` without the master's heartbeat: heartbeats dropped now and
//!   then, with gaps shorter than `P`, never start one.
//! - A search ends after at most `max(N, 1)` toggles, on the master or on "no master"; a new one
//!   needs the master heard again first. So a bus that loses everything for good costs each slave
//!   at most that many toggles, and a flaky one at most that many per time the master was heard
//!   and lost again.
//! - Only the master moves the network: it never toggles, and slaves settle on the bus they hear
//!   it on. Once the master is on a sound bus, the other bus's faults are not heard at all.
//!
//! # Memory, overflow, order
//!
//! The policy holds its configuration, the active bus, Bdefault, Ctoggle and one deadline: no
//! table, no queue (events go to the layer's bounded outbox). Ctoggle never exceeds
//! `max(N, 1)` ≤ 255. Events are reported in the order of their instants; the last toggle and
//! "no master" share an instant, the toggle first.
//!
//! The clock contract (see [`crate::link`]): a step back moves the deadline back by the step; a
//! jump ahead handles each loss and toggle once, at its own instant (the events carry it), in at
//! most `max(N, 1) + 1` rounds whatever the jump.
//!
//! [`MasterLost`]: crate::link::events::LinkEventKind::MasterLost
//! [`Toggle`]: crate::link::events::LinkEventKind::Toggle
//! [`NoMaster`]: crate::link::events::LinkEventKind::NoMaster
//! [`MasterFound`]: crate::link::events::LinkEventKind::MasterFound

use super::{switched, ChannelPolicy, FrameInfo, PortMask, RxRoute};
use crate::link::events::{LinkEvent, LinkEventKind, SwitchReason};
use crate::link::health::Health;
use crate::link::outbox::Outbox;
use duocan_core::machine::{LinkRequest, PortStatus};
use duocan_core::{Duration, Frame, Instant, NodeId};

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
    /// Sub 2, Ttoggle: consumer times (`P`) from one toggle to the next; the first comes
    /// Ttoggle − 1 of them after the loss. Zero: a slave does not toggle.
    pub ttoggle: u8,
    /// Sub 3, Ntoggle: toggles in one search before "no master" (zero counts as one).
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
    /// A slave of `master` whose heartbeat is expected every `period`: starts on bus 1; after a
    /// loss it toggles one period later, then every 2 periods, 4 times in all.
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
    /// Not booted, a master, or a slave with toggling off.
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
    /// True after a search ended without finding the master (until it is heard).
    pub fn no_master(&self) -> bool {
        self.phase == Phase::NoMaster
    }
    /// The master and `P`, for a slave that toggles (Ttoggle ≥ 1).
    fn slave(&self) -> Option<(NodeId, Duration)> {
        match self.cfg.role {
            EcssRole::Slave { master, period } if self.cfg.ttoggle > 0 => Some((master, period)),
            _ => None,
        }
    }
    /// `P` × `n`, for `n` consumer times.
    fn periods(period: Duration, n: u8) -> Duration {
        period.saturating_mul(n as u64)
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
                    // The loss already waited one consumer time.
                    self.phase = Phase::Toggling {
                        next: deadline + Self::periods(period, self.cfg.ttoggle - 1),
                    };
                }
                Phase::Toggling { next } if next <= now => {
                    // Toggle, count, then compare: the toggle that reaches Ntoggle is the last,
                    // and an Ntoggle of zero still gets one.
                    let from = self.active;
                    self.active = 1 - from;
                    self.ctoggle = self.ctoggle.saturating_add(1);
                    out.event(LinkEvent {
                        at: next,
                        kind: LinkEventKind::Toggle {
                            from: from as u8,
                            to: self.active as u8,
                            ctoggle: self.ctoggle,
                        },
                    });
                    if self.ctoggle < self.cfg.ntoggle {
                        self.phase = Phase::Toggling {
                            next: next + Self::periods(period, self.cfg.ttoggle),
                        };
                    } else {
                        // Giving up settles the slave where it is: that bus becomes the default,
                        // the one a restart begins on.
                        self.bdefault = self.active as u8;
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
    use duocan_core::Id;

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
        // The boot-up goes out on Bdefault.
        let on = 1 << cfg.bdefault;
        assert_eq!(p.route_tx(ms(0), &f, &i, &h, &mut out), on);
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
    fn toggle(at: u64, from: u8, to: u8, ctoggle: u8) -> (Instant, LinkEventKind) {
        (ms(at), LinkEventKind::Toggle { from, to, ctoggle })
    }
    fn slave(ttoggle: u8, ntoggle: u8) -> EcssConfig {
        EcssConfig::slave(M, Duration::from_millis(100))
            .with_ttoggle(ttoggle)
            .with_ntoggle(ntoggle)
    }

    #[test]
    fn loss_toggles_after_t_minus_one_then_every_t_periods_and_the_nth_toggle_is_the_last() {
        let (mut p, mut out) = booted(slave(3, 2));
        let (f, i) = hb();
        p.on_rx(ms(50), 0, &f, &i, &mut out);
        // Heard on the inactive bus: ignored, not delivered.
        assert_eq!(p.on_rx(ms(120), 1, &f, &i, &mut out), RxRoute::Ignore);
        run(&mut p, &mut out, ms(5000));
        // Lost at 50 + P; toggles (3 − 1) × P later and 3 × P after that; the second is the
        // last, and "no master" comes with it.
        assert_eq!(
            kinds(&mut out),
            [
                (ms(150), LinkEventKind::MasterLost { master: M, bus: 0 }),
                toggle(350, 0, 1, 1),
                toggle(650, 1, 0, 2),
                (ms(650), LinkEventKind::NoMaster { bus: 0, ctoggle: 2 }),
            ]
        );
        assert!(p.no_master());
        assert_eq!(p.poll_timeout(), None, "stays: nothing more to do");
    }

    #[test]
    fn giving_up_makes_the_bus_of_the_last_toggle_the_default() {
        // Three toggles end on bus 2.
        let (mut p, mut out) = booted(slave(2, 3));
        run(&mut p, &mut out, ms(60_000));
        assert_eq!(
            kinds(&mut out),
            [
                (ms(100), LinkEventKind::MasterLost { master: M, bus: 0 }),
                toggle(200, 0, 1, 1),
                toggle(400, 1, 0, 2),
                toggle(600, 0, 1, 3),
                (ms(600), LinkEventKind::NoMaster { bus: 1, ctoggle: 3 }),
            ]
        );
        assert_eq!((p.active_bus(), p.bdefault(), p.ctoggle()), (1, 1, 3));
        // The master heard there ends it; the next loss starts a new search from Ctoggle 0.
        let (f, i) = hb();
        assert_eq!(p.on_rx(ms(61_000), 1, &f, &i, &mut out), RxRoute::Direct);
        assert!(!p.no_master());
        run(&mut p, &mut out, ms(61_250));
        assert_eq!(
            kinds(&mut out),
            [
                (ms(61_000), LinkEventKind::MasterFound { master: M, bus: 1 }),
                (ms(61_100), LinkEventKind::MasterLost { master: M, bus: 1 }),
                toggle(61_200, 1, 0, 1),
            ]
        );
        assert_eq!((p.bdefault(), p.ctoggle()), (1, 1));
    }

    #[test]
    fn a_jump_ahead_over_the_whole_search_reports_each_step_at_its_instant() {
        let (mut p, mut out) = booted(slave(2, 4));
        p.handle_timeout(ms(3_600_000), &mut out);
        let got = kinds(&mut out);
        assert_eq!(got.len(), 6);
        assert_eq!(
            got[0],
            (ms(100), LinkEventKind::MasterLost { master: M, bus: 0 })
        );
        assert_eq!(got[4], toggle(800, 1, 0, 4));
        assert_eq!(
            got[5],
            (ms(800), LinkEventKind::NoMaster { bus: 0, ctoggle: 4 })
        );
        assert_eq!(p.poll_timeout(), None);
    }

    #[test]
    fn a_ttoggle_of_zero_turns_toggling_off() {
        let (mut p, mut out) = booted(slave(0, 4).with_bdefault(1));
        assert_eq!(p.poll_timeout(), None);
        run(&mut p, &mut out, ms(60_000));
        let (f, i) = hb();
        assert_eq!(p.on_rx(ms(100), 1, &f, &i, &mut out), RxRoute::Direct);
        assert_eq!(p.on_rx(ms(100), 0, &f, &i, &mut out), RxRoute::Ignore);
        p.handle_timeout(ms(60_000), &mut out);
        assert_eq!(kinds(&mut out), []);
        assert_eq!((p.active_bus(), p.bdefault(), p.ctoggle()), (1, 1, 0));
    }

    #[test]
    fn an_ntoggle_of_zero_still_toggles_once() {
        let (mut p, mut out) = booted(slave(1, 0));
        run(&mut p, &mut out, ms(60_000));
        // Ttoggle 1: the toggle comes with the loss.
        assert_eq!(
            kinds(&mut out),
            [
                (ms(100), LinkEventKind::MasterLost { master: M, bus: 0 }),
                toggle(100, 0, 1, 1),
                (ms(100), LinkEventKind::NoMaster { bus: 1, ctoggle: 1 }),
            ]
        );
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
                toggle(200, 0, 1, 1),
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
