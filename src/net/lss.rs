//! The network's LSS master (CiA 305) as async calls: python `canopen`'s `network.lss`.
//!
//! The master is the library's sans-IO [`LssMaster`](crate::cia305::LssMaster), run inside the
//! network's runtime by the door itself, whatever core the network runs on: its requests
//! (0x7E5) leave as the network's own frames on every bus of the link, while the core may
//! send (listen-only: none; a standby master: none; a master replacing a board by LSS of its
//! own: not until that is done), the slaves' answers (0x7E4) come back merged like any frame, and the
//! runtime gives it the time. LSS has no addresses, so calls take turns: one request runs at a
//! time, whoever calls. Each call returns when the master's own timeout decided
//! ([`NetOptions::with_lss`](super::NetOptions::with_lss)).

use super::core::LSS_PLAN;
use super::error::NetError;
use super::Network;
use crate::cia305::{
    BitTiming, IdentifyRange, Inquiry, LssAddress, LssError, LssMaster, LssMasterEvent,
    LssMasterEventKind, LssMode, LssOutcome, LssPlan,
};
use crate::frame::cob_id::NodeId;
use crate::frame::instant::{Duration, Instant};
use tokio::sync::oneshot;

/// The LSS master of a [`Network`]: `net.lss().inquire(Inquiry::NodeId).await?`.
#[derive(Clone)]
pub struct NetLss {
    net: Network,
}

/// What a fastscan did ([`NetLss::fastscan`]).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
#[non_exhaustive]
pub struct FastscanReport {
    /// The slaves found and the node-ID each was given, in the order found.
    pub assigned: Vec<(LssAddress, NodeId)>,
    /// A slave found that got no node-ID, or was lost, or refused: where the scan stopped
    /// (the slaves in `assigned` keep theirs). `None`: every non-configured slave was found.
    pub stopped: Option<LssError>,
    /// Request frames the master wrote.
    pub requests: u32,
    /// Answers the master received (after the merge, on two buses).
    pub answers: u32,
    /// Times the scan started over after a confirmation went wrong (a stray or late answer,
    /// or a slave that left: see [the fastscan](crate::cia305::fastscan#starting-over)).
    pub restarts: u32,
    /// Requests of the attempts given up: `requests` less these is what
    /// [`fastscan_cost`](crate::cia305::fastscan_cost) predicts for the slaves found.
    pub abandoned: u32,
    /// From the first request to the end, on the network's clock.
    pub took: Duration,
}

/// What the watch of a fastscan collects.
#[derive(Default)]
struct Scan {
    assigned: Vec<(LssAddress, NodeId)>,
    end: Option<(Instant, Option<LssError>)>,
}

impl NetLss {
    pub(super) fn new(net: Network) -> Self {
        NetLss { net }
    }

    /// The master's turn (held while the guard lives): LSS requests run one at a time.
    async fn turn(&self) -> Result<tokio::sync::MutexGuard<'_, ()>, NetError> {
        if self.net.is_listen_only() {
            return Err(NetError::ListenOnly { node: None });
        }
        Ok(self.net.shared.lss_turn.lock().await)
    }

    /// Starts a request with `start` on the door's master and waits for the master's results
    /// until `done` has the outcome; `done` sees what `start` returned. The caller holds the
    /// turn.
    async fn request<T, R>(
        &self,
        start: impl FnOnce(&mut LssMaster<LSS_PLAN>, Instant) -> Result<T, NetError> + Send + 'static,
        mut done: impl FnMut(&T, &LssMasterEvent) -> Option<Result<R, NetError>> + Send + 'static,
    ) -> Result<R, NetError>
    where
        T: Clone + Send + 'static,
        R: Send + 'static,
    {
        let (tx, rx) = oneshot::channel();
        self.net
            .shared
            .handle
            .try_call(move |d, now| {
                d.lss_start(now, start, |t| {
                    let (t, mut tx) = (t.clone(), Some(tx));
                    Box::new(move |e| match done(&t, e) {
                        Some(r) => {
                            if let Some(tx) = tx.take() {
                                let _ = tx.send(r);
                            }
                            true
                        }
                        None => false,
                    })
                })
                .map(drop)
            })
            .await?;
        rx.await.unwrap_or(Err(NetError::Closed))
    }

    /// Runs one request: `start` starts it on the master, the master's next result ends it.
    async fn run(
        &self,
        start: impl FnOnce(&mut LssMaster<LSS_PLAN>, Instant) -> Result<(), LssError> + Send + 'static,
    ) -> Result<LssOutcome, NetError> {
        let _turn = self.turn().await?;
        self.request(
            move |m, now| start(m, now).map_err(NetError::Lss),
            |(), e| match e.kind {
                LssMasterEventKind::Done(o) => Some(Ok(o)),
                LssMasterEventKind::Failed(e) => Some(Err(NetError::Lss(e))),
                _ => None,
            },
        )
        .await
    }

    /// Switch state global: every slave to `mode` (python `send_switch_state_global`).
    pub async fn switch_global(&self, mode: LssMode) -> Result<(), NetError> {
        self.run(move |m, now| m.switch_global(now, mode))
            .await
            .map(drop)
    }

    /// Switch state selective: the slave with `address` to configuration mode; an error if
    /// none answered.
    pub async fn switch_selective(&self, address: LssAddress) -> Result<(), NetError> {
        self.run(move |m, now| m.switch_selective(now, address))
            .await
            .map(drop)
    }

    /// Configure node-ID (1–127, or 0xFF for none) of the slave in configuration mode.
    pub async fn configure_node_id(&self, node: u8) -> Result<(), NetError> {
        self.run(move |m, now| m.configure_node_id(now, node))
            .await
            .map(drop)
    }

    /// Configure bit timing of the slave in configuration mode.
    pub async fn configure_bit_timing(&self, timing: BitTiming) -> Result<(), NetError> {
        self.run(move |m, now| m.configure_bit_timing(now, timing))
            .await
            .map(drop)
    }

    /// Activate bit timing: the slaves in configuration mode switch after `delay_ms`.
    pub async fn activate_bit_timing(&self, delay_ms: u16) -> Result<(), NetError> {
        self.run(move |m, now| m.activate_bit_timing(now, delay_ms))
            .await
            .map(drop)
    }

    /// Store configuration of the slave in configuration mode.
    pub async fn store(&self) -> Result<(), NetError> {
        self.run(move |m, now| m.store(now)).await.map(drop)
    }

    /// Inquire an identity part or the node-ID (in the low byte; 0xFF: none) of the slave in
    /// configuration mode.
    pub async fn inquire(&self, q: Inquiry) -> Result<u32, NetError> {
        match self.run(move |m, now| m.inquire(now, q)).await? {
            LssOutcome::Inquired(_, v) => Ok(v),
            // The master ends an inquiry with its value or an error, nothing else.
            _ => Err(NetError::Closed),
        }
    }

    /// Identify remote slave: whether any slave lies in `range` (waits the whole timeout).
    pub async fn identify_remote(&self, range: IdentifyRange) -> Result<bool, NetError> {
        self.identified(
            self.run(move |m, now| m.identify_remote(now, range))
                .await?,
        )
    }

    /// Identify non-configured remote slave: whether any slave without a node-ID is there.
    pub async fn identify_non_configured(&self) -> Result<bool, NetError> {
        self.identified(
            self.run(move |m, now| m.identify_non_configured(now))
                .await?,
        )
    }

    fn identified(&self, o: LssOutcome) -> Result<bool, NetError> {
        match o {
            LssOutcome::Identified(_, heard) => Ok(heard),
            _ => Err(NetError::Closed),
        }
    }

    /// Fastscan: finds every non-configured slave and gives it its node-ID from `plan`. A scan
    /// that stopped on the way ends `Ok` too, with the reason in
    /// [`FastscanReport::stopped`]: the slaves configured before stay configured.
    pub async fn fastscan(&self, plan: LssPlan<LSS_PLAN>) -> Result<FastscanReport, NetError> {
        let _turn = self.turn().await?;
        let mut scan = Scan::default();
        let (begun, before, scan) = self
            .request(
                move |lss, now| {
                    let before = lss.stats();
                    lss.fastscan(now, plan)
                        .map(|()| (now, before))
                        .map_err(NetError::Lss)
                },
                move |&(begun, before), e| {
                    match e.kind {
                        LssMasterEventKind::Assigned { address, node } => {
                            scan.assigned.push((address, node));
                        }
                        LssMasterEventKind::ScanFinished { .. } => scan.end = Some((e.at, None)),
                        LssMasterEventKind::Failed(err) => scan.end = Some((e.at, Some(err))),
                        _ => {}
                    }
                    scan.end?;
                    Some(Ok((begun, before, core::mem::take(&mut scan))))
                },
            )
            .await?;
        let after = self.net.shared.handle.call(|d, _| d.lss.stats()).await?;
        let (end, stopped) = scan.end.unwrap_or((begun, None));
        Ok(FastscanReport {
            assigned: scan.assigned,
            stopped,
            requests: after.requests.wrapping_sub(before.requests),
            answers: after.answers.wrapping_sub(before.answers),
            restarts: after.restarts.wrapping_sub(before.restarts),
            abandoned: after.abandoned.wrapping_sub(before.abandoned),
            took: end - begun,
        })
    }
}
