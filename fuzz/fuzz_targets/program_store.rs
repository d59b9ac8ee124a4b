//! Program download on a node (the objects 0x1F50/0x1F51/0x1F56/0x1F57 over a program store):
//! any SDO request frames from the bus, segmented and block transfers included. Never a panic;
//! the store is called only as its contract says (an image staged only into a cleared staging
//! area while the program is stopped, activation only of an image staged and verified since),
//! and the program in control is only ever an image the store verified.
#![no_main]

use duocan::cia302::program::{FlashError, ProgramDictionary, ProgramStore};
use duocan::od::comm;
use duocan::{Frame, Id, Instant, Machine, Node, NodeConfig, NodeId};
use libfuzzer_sys::fuzz_target;

/// An image is valid when its first byte is even; its identification is its length.
#[derive(Default)]
struct Store {
    running: u32,
    on: bool,
    cleared: bool,
    staged: Option<u32>,
    verified: Vec<u32>,
}

impl ProgramStore for Store {
    fn capacity(&self) -> u32 {
        300
    }
    fn stop(&mut self) {
        self.on = false;
    }
    fn run(&mut self) {
        self.on = true;
    }
    fn clear(&mut self) -> Result<(), FlashError> {
        assert!(!self.on, "cleared while running");
        self.cleared = true;
        self.staged = None;
        Ok(())
    }
    fn stage(&mut self, image: &[u8]) -> Result<(), FlashError> {
        assert!(!self.on && self.cleared, "staged while running or not cleared");
        self.cleared = false;
        assert!(image.len() <= 300);
        if image.first().is_some_and(|b| b % 2 == 1) {
            return Err(FlashError::DataFormatError);
        }
        self.staged = Some(image.len() as u32);
        self.verified.push(image.len() as u32);
        Ok(())
    }
    fn activate(&mut self) -> Result<(), FlashError> {
        self.running = self.staged.take().expect("activated without a verified image");
        Ok(())
    }
    fn identification(&self) -> u32 {
        self.running
    }
}

fuzz_target!(|data: &[u8]| {
    let store = Store {
        running: 7,
        on: true,
        ..Store::default()
    };
    let od = ProgramDictionary::new(comm::standard_dictionary(5, Default::default()), store);
    let mut node = Node::new(NodeConfig::slave(NodeId::must(5)), od);
    let mut t = Instant::ZERO;
    node.boot(t);
    for chunk in data.chunks(8) {
        t = t + duocan::Duration::from_millis(1);
        if let Ok(f) = Frame::new(Id::Standard(0x605), chunk) {
            node.handle_frame(t, &f);
        }
        node.handle_timeout(t);
        while node.poll_transmit().is_some() {}
        while node.poll_event().is_some() {}
        let s = node.od().store();
        assert!(s.running == 7 || s.verified.contains(&s.running));
    }
});
