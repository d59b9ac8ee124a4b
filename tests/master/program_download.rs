//! Program download (CiA 302-3): the master replaces a slave's program over SDO block transfer
//! (stop, clear, image, start, identification checked against 0x1F55), with progress events;
//! a transfer cut midway (the slave restarts, or the bus drops) leaves the old program in
//! control and names the step; a wrong identification after start is reported. The slave is
//! a duocan node whose program objects are served by a program store.

use crate::net::*;
use duocan::cia302::program::{FlashError, ProgramDictionary, ProgramStore};
use duocan::machine::SinglePort;
use duocan::master::{
    objects::EXPECTED_SOFTWARE, MasterConfig, MasterEventKind as K, ProgramDownloadError,
    ProgramErrorKind, ProgramReport, ProgramStep, SlaveConfig,
};
use duocan::od::{comm, DynamicDictionary, ObjectDictionary};
use duocan::sim::{BusConfig, DevId, FaultRates, SimNetwork};
use duocan::{AbortCode, Duration, Id, Instant, Node, NodeConfig, NodeId, Station};

const SLAVE: u8 = 6;
const OLD: u32 = 0x0100_0000;
const NEW: u32 = 0x0200_0005;

/// A program store in RAM. An image is its identification (4 bytes), a body, and a checksum
/// of both (4 bytes, the wrapping sum of the bytes): what staging verifies.
#[derive(Default)]
struct Flash {
    running: Option<u32>,
    staged: Option<u32>,
    /// True while the program runs.
    on: bool,
    /// Images staged, activations.
    stagings: u32,
    activations: u32,
}

fn image(identification: u32, body: usize) -> Vec<u8> {
    let mut v = identification.to_le_bytes().to_vec();
    v.extend((0..body).map(|i| (i * 7 + 3) as u8));
    let sum = v.iter().fold(0u32, |s, b| s.wrapping_add(*b as u32));
    v.extend(sum.to_le_bytes());
    v
}

impl ProgramStore for Flash {
    fn capacity(&self) -> u32 {
        32 * 1024
    }
    fn stop(&mut self) {
        self.on = false;
    }
    fn run(&mut self) {
        self.on = self.running.is_some();
    }
    fn clear(&mut self) -> Result<(), FlashError> {
        self.staged = None;
        Ok(())
    }
    fn stage(&mut self, image: &[u8]) -> Result<(), FlashError> {
        self.stagings += 1;
        let Some((body, sum)) = image.split_last_chunk::<4>().filter(|(b, _)| b.len() >= 4) else {
            return Err(FlashError::DataFormatUnknown);
        };
        let want = body.iter().fold(0u32, |s, b| s.wrapping_add(*b as u32));
        if u32::from_le_bytes(*sum) != want {
            return Err(FlashError::DataFormatError);
        }
        self.staged = Some(u32::from_le_bytes(body[..4].try_into().unwrap()));
        Ok(())
    }
    fn activate(&mut self) -> Result<(), FlashError> {
        self.running = Some(self.staged.take().ok_or(FlashError::NoValidProgram)?);
        self.activations += 1;
        Ok(())
    }
    fn identification(&self) -> u32 {
        self.running.unwrap_or(0)
    }
}

type Outcome = Result<ProgramReport, ProgramDownloadError>;
type Od = ProgramDictionary<DynamicDictionary, Flash>;
type Slave = Station<SinglePort, Node<Od>>;

fn updatable() -> Slave {
    let flash = Flash {
        running: Some(OLD),
        on: true,
        ..Flash::default()
    };
    let od = ProgramDictionary::new(slave_dictionary(SLAVE, identity(SLAVE), None), flash);
    Station::single(Node::new(NodeConfig::slave(NodeId::must(SLAVE)), od))
}

struct Rig {
    sim: SimNetwork,
    bus: duocan::sim::BusId,
    master: DevId<MasterDev>,
    slave: DevId<Slave>,
}

/// The master and the slave, booted and running; the master expects `expected` after an
/// update.
fn rig(expected: u32) -> Rig {
    let n = NodeId::must(SLAVE);
    let net = MasterConfig::new().slave(SlaveConfig::new(n).identity(expected_id()));
    let mut m = master(net);
    m.node_mut()
        .od_mut()
        .write(EXPECTED_SOFTWARE, SLAVE, &expected.to_le_bytes())
        .unwrap();
    let mut sim = SimNetwork::new(3);
    let bus = sim.add_bus(BusConfig::new("can0", 500_000));
    let master = sim
        .add_device("master", Station::single(m), &[bus])
        .unwrap();
    let slave = sim.add_device("slave", updatable(), &[bus]).unwrap();
    sim.device_mut(slave).machine.boot(Instant::ZERO);
    sim.device_mut(master).machine.boot(Instant::ZERO);
    sim.run_until(Instant::from_millis(100));
    Rig {
        sim,
        bus,
        master,
        slave,
    }
}

fn expected_id() -> duocan::master::ExpectedIdentity {
    expected(SLAVE)
}

impl Rig {
    fn flash(&self) -> &Flash {
        self.sim.device(self.slave).machine.od().store()
    }
    fn download(&mut self, image: Vec<u8>) {
        let now = self.sim.now();
        let n = NodeId::must(SLAVE);
        self.sim
            .device_mut(self.master)
            .machine
            .download_program(now, n, image)
            .unwrap();
    }
    /// Progress reports and the outcome, once it came.
    fn outcome(&self) -> (Vec<(usize, usize)>, Option<Outcome>) {
        let events = master_events(self.sim.events(self.master));
        let progress = all(&events, |k| match k {
            K::ProgramProgress { done, total, .. } => Some((*done, *total)),
            _ => None,
        });
        let result = find(&events, |k| match k {
            K::ProgramDownloaded { result, .. } => Some(*result),
            _ => None,
        });
        (
            progress.into_iter().map(|(_, p)| p).collect(),
            result.map(|(_, r)| r),
        )
    }
    /// Writes to the slave's 0x1F51 sub 1 after `from`: the commands sent.
    fn commands(&self, from: Instant) -> Vec<u8> {
        frames(&self.sim)
            .into_iter()
            .filter(|(t, f)| {
                *t >= from
                    && f.id() == Id::Standard(0x600 + SLAVE as u16)
                    && f.data()[0] == 0x2F
                    && f.data()[1..4] == [0x51, 0x1F, 1]
            })
            .map(|(_, f)| f.data()[4])
            .collect()
    }
}

#[test]
fn a_program_is_replaced_with_progress_and_verified() {
    let mut r = rig(NEW);
    let img = image(NEW, 12_000);
    let total = img.len();
    let t = r.sim.now();
    r.download(img);
    r.sim.run_for(Duration::from_millis(2_000));
    let (progress, result) = r.outcome();
    assert_eq!(
        result,
        Some(Ok(ProgramReport {
            node: NodeId::must(SLAVE),
            bytes: total,
            identification: NEW
        }))
    );
    // From 0 to all of it, rising, with steps between (block transfer confirms sub-blocks).
    assert_eq!(progress.first(), Some(&(0, total)));
    assert_eq!(progress.last(), Some(&(total, total)));
    assert!(progress.windows(2).all(|w| w[0].0 < w[1].0), "{progress:?}");
    assert!(progress.len() > 5, "{progress:?}");
    // Stop, clear, start: in that order, nothing else.
    assert_eq!(r.commands(t), [0, 3, 1]);
    let f = r.flash();
    assert_eq!((f.running, f.on, f.activations), (Some(NEW), true, 1));
    // Block transfer: the image went as 7-byte segments, not as expedited or segmented
    // requests (0x21 / 0x00 / 0x10 command bytes).
    let init = frames(&r.sim).into_iter().find(|(at, fr)| {
        *at >= t && fr.id() == Id::Standard(0x600 + SLAVE as u16) && fr.data()[1..3] == [0x50, 0x1F]
    });
    assert_eq!(init.map(|(_, fr)| fr.data()[0] & 0xE0), Some(0xC0));
}

#[test]
fn a_wrong_identification_after_start_is_reported() {
    let mut r = rig(0x0300_0000);
    r.download(image(NEW, 500));
    r.sim.run_for(Duration::from_millis(1_000));
    let (_, result) = r.outcome();
    let e = result.unwrap().unwrap_err();
    assert_eq!(e.step, ProgramStep::Verify);
    assert_eq!(
        e.kind,
        ProgramErrorKind::WrongIdentification {
            expected: 0x0300_0000,
            actual: NEW
        }
    );
    assert!(e.to_string().contains("verify (0x1F56)"), "{e}");
    // Started (it cannot be undone), and reported as what it is.
    assert_eq!(r.flash().running, Some(NEW));
}

#[test]
fn an_image_the_slave_refuses_leaves_the_old_program_running() {
    let mut r = rig(NEW);
    let mut img = image(NEW, 3_000);
    img[100] ^= 0xFF;
    let t = r.sim.now();
    r.download(img);
    r.sim.run_for(Duration::from_millis(1_000));
    let e = r.outcome().1.unwrap().unwrap_err();
    assert_eq!(
        (e.step, e.code(), e.resumed),
        (ProgramStep::Download, Some(AbortCode::CANNOT_STORE), true)
    );
    // Never started: stop, clear, then reset (not start).
    assert_eq!(r.commands(t), [0, 3, 2]);
    let f = r.flash();
    assert_eq!(
        (f.running, f.on, f.stagings, f.activations),
        (Some(OLD), true, 1, 0)
    );
    // 0x1F57: the data format error code (3) in bits 1–7.
    let od = r.sim.device(r.slave).machine.od();
    assert_eq!(od.get_u32(0x1F57, 1), Some(3 << 1));
    assert_eq!(od.get_u32(0x1F56, 1), Some(OLD));
}

/// A download of a 20 kB image, started now; when.
fn large_download() -> (Rig, Instant) {
    let mut r = rig(NEW);
    let t = r.sim.now();
    r.download(image(NEW, 20_000));
    (r, t)
}

#[test]
fn a_slave_restarting_midway_cuts_the_transfer_and_the_old_program_runs_again() {
    let (mut r, t) = large_download();
    // Midway through the image (about 400 ms at 500 kbit/s), the slave's node restarts: its
    // SDO server forgot the transfer and aborts the segments that keep coming.
    let slave = r.slave;
    r.sim.at(t + Duration::from_millis(150), move |sim| {
        let now = sim.now();
        sim.device_mut(slave).machine.boot(now);
    });
    r.sim.run_for(Duration::from_millis(2_000));
    let (progress, result) = r.outcome();
    let e = result.unwrap().unwrap_err();
    assert_eq!(
        (e.step, e.code(), e.resumed),
        (
            ProgramStep::Download,
            Some(AbortCode::COMMAND_SPECIFIER),
            true
        )
    );
    let done = progress.last().unwrap().0;
    assert!(0 < done && done < progress[0].1, "{progress:?}");
    // Stop, clear, then resets until the slave, past the segments still on the bus, takes
    // one; never start.
    let commands = r.commands(t);
    assert_eq!(commands[..3], [0, 3, 2]);
    assert!(commands[2..].iter().all(|c| *c == 2), "{commands:?}");
    let f = r.flash();
    assert_eq!(
        (f.running, f.on, f.stagings, f.activations),
        (Some(OLD), true, 0, 0)
    );
    // Its boot-up came during the download: the master boots it once the download ended.
    let events = master_events(r.sim.events(r.master));
    let configured = all(&events, |k| {
        matches!(k, K::SlaveConfigured { .. }).then_some(())
    });
    let ended = find(&events, |k| {
        matches!(k, K::ProgramDownloaded { .. }).then_some(())
    });
    let ended = ended.unwrap().0;
    let again: Vec<_> = configured.iter().filter(|(at, _)| *at > t).collect();
    assert_eq!(again.len(), 1, "{configured:?}");
    assert!(again[0].0 >= ended);
}

#[test]
fn a_bus_that_drops_midway_fails_the_download_and_the_old_program_stays_in_control() {
    let (mut r, t) = large_download();
    let bus = r.bus;
    r.sim.at(t + Duration::from_millis(150), move |sim| {
        sim.set_bus_faults(bus, FaultRates::default().with_drop(1.0));
    });
    r.sim.at(t + Duration::from_millis(1_500), move |sim| {
        sim.set_bus_faults(bus, FaultRates::default());
    });
    r.sim.run_for(Duration::from_millis(3_000));
    let e = r.outcome().1.unwrap().unwrap_err();
    // The transfer timed out; the reset that would run the old program again was lost too.
    assert_eq!(
        (e.step, e.code(), e.resumed),
        (ProgramStep::Download, Some(AbortCode::TIMEOUT), false)
    );
    assert!(e.to_string().contains("download (0x1F50)"), "{e}");
    // The new image never reached the store; the old program is still the one in control
    // (stopped: the master could not tell it to run again, and says so).
    let f = r.flash();
    assert_eq!((f.running, f.stagings, f.activations), (Some(OLD), 0, 0));
    assert!(!r.commands(t).contains(&1));
}

#[test]
fn a_master_that_becomes_standby_midway_sends_nothing_more() {
    let (mut r, t) = large_download();
    let master = r.master;
    let cut = t + Duration::from_millis(150);
    r.sim.at(cut, move |sim| {
        let now = sim.now();
        sim.device_mut(master).machine.set_active(now, false);
    });
    r.sim.run_for(Duration::from_millis(2_000));
    let e = r.outcome().1.unwrap().unwrap_err();
    assert_eq!((e.step, e.resumed), (ProgramStep::Download, false));
    // Its abort of the transfer is the last frame it sends the slave.
    let to_slave: Vec<_> = frames(&r.sim)
        .into_iter()
        .filter(|(at, f)| *at > cut && f.id() == Id::Standard(0x600 + SLAVE as u16))
        .collect();
    let last = to_slave.last().unwrap().1;
    assert_eq!(last.data()[0], 0x80);
    assert_eq!(last.data()[4..8], AbortCode::GENERAL.0.to_le_bytes());
    assert_eq!(r.flash().activations, 0);
}

#[test]
fn a_download_is_refused_while_one_runs() {
    let mut r = rig(NEW);
    r.download(image(NEW, 2_000));
    let now = r.sim.now();
    let m = &mut r.sim.device_mut(r.master).machine;
    let n = NodeId::must(SLAVE);
    assert_eq!(
        m.download_program(now, n, vec![1]),
        Err(duocan::master::MasterError::Busy(n))
    );
    let huge = vec![0; m.sdo().limit() + 1];
    assert!(matches!(
        m.download_program(now, NodeId::must(7), huge),
        Err(duocan::master::MasterError::ImageTooLarge { .. })
    ));
    let _ = comm::DEVICE_TYPE;
}
