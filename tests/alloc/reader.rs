//! The same for a port read by a thread of its own (`Port::reader`, as SocketCAN ports are):
//! the thread hands each frame to the device and writes the answer without allocating.

use super::{read_vendor, slave, two_workers, GLOBAL, NODE};
use duocan::port::{Port, PortCounters, PortError, PortInput, PortReader, READER_WAIT};
use duocan::runtime::Runtime;
use duocan::{Frame, Id, Station};
use stats_alloc::Region;
use std::sync::mpsc::{sync_channel, Receiver, SyncSender};
use std::time::Duration;

/// Bounded channels (fixed rings: no allocation per message) between the test and the thread.
struct Reader {
    from_test: Receiver<Frame>,
    to_test: SyncSender<Frame>,
}

impl PortReader for Reader {
    fn read(&mut self) -> Result<Option<PortInput>, PortError> {
        Ok(self
            .from_test
            .recv_timeout(READER_WAIT)
            .ok()
            // Stamped, as a SocketCAN port's frames are: the stamped path allocates nothing
            // either.
            .map(|f| PortInput::Frame(f, Some(std::time::Instant::now()))))
    }
    fn write(&mut self, f: &Frame) -> Result<bool, PortError> {
        Ok(self.to_test.send(*f).is_ok())
    }
}

/// Frames the device sends on commands (the boot-up) go through `send`, from the task.
struct ThreadedPort(PortCounters, Option<Reader>, SyncSender<Frame>);

impl Port for ThreadedPort {
    fn name(&self) -> &str {
        "thr0"
    }
    fn counters(&self) -> PortCounters {
        self.0.clone()
    }
    async fn recv(&mut self) -> Result<PortInput, PortError> {
        std::future::pending().await
    }
    async fn send(&mut self, f: &Frame) -> Result<(), PortError> {
        let _ = self.2.send(*f);
        Ok(())
    }
    async fn reopen(&mut self) -> Result<(), PortError> {
        Ok(())
    }
    fn reader(&mut self) -> Option<Box<dyn PortReader>> {
        self.1.take().map(|r| Box::new(r) as Box<dyn PortReader>)
    }
}

pub fn the_reader_thread_allocates_nothing_per_frame() {
    let rt = two_workers();
    let (to_port, from_test) = sync_channel(64);
    let (to_test, from_port) = sync_channel(64);
    let node = slave();
    let port = ThreadedPort(
        PortCounters::new(),
        Some(Reader {
            from_test,
            to_test: to_test.clone(),
        }),
        to_test,
    );
    let handle = {
        let _in_rt = rt.enter();
        Runtime::new(Station::single(node))
            .port(port)
            .spawn()
            .unwrap()
    };
    rt.block_on(handle.boot()).unwrap();
    let next = || {
        from_port
            .recv_timeout(Duration::from_secs(5))
            .expect("an answer")
    };
    assert_eq!(
        next().id(),
        Id::Standard(0x700 + u16::from(NODE)),
        "the boot-up"
    );
    let reads = |n: usize| {
        for _ in 0..n {
            to_port.send(read_vendor()).unwrap();
            let f = next();
            assert_eq!(f.id(), Id::Standard(0x580 + u16::from(NODE)));
            assert_eq!(&f.data()[4..6], [0x34, 0x12]);
        }
    };
    reads(1_000);
    let region = Region::new(GLOBAL);
    reads(10_000);
    let stats = region.change();
    assert_eq!(
        (stats.allocations, stats.reallocations),
        (0, 0),
        "10,000 SDO reads through the reader thread allocated: {stats:?}"
    );
    rt.block_on(handle.shutdown());
}
