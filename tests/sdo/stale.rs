//! Late answers to earlier requests: on a redundant network a bus that starts to lag hands over
//! its copies of frames after their merge window, and the dual-bus layer delivers them as
//! frames of their own; the answer to an earlier transfer on the channel can then come in the
//! middle of the next one's start. An initiate answer names its object, so one that names
//! another object is not the transfer's: in every mode and direction the transfer goes on and
//! completes with its data, and the late answer is counted.

use crate::net::{booted_server, TestNode, DOMAIN, STRING};
use duocan::od::ObjectDictionary;
use duocan::sdo::{Channel, SdoClient, SdoEvent, SdoOptions, TransferMode};
use duocan::{Frame, Instant, Machine, NodeId};

const N: NodeId = NodeId::must(5);

struct Bus {
    client: SdoClient,
    node: TestNode,
    events: Vec<SdoEvent>,
    /// Every answer of the server, in order.
    answers: Vec<Frame>,
}

impl Bus {
    fn new() -> Self {
        Bus {
            client: SdoClient::new(4096),
            node: booted_server(5),
            events: vec![],
            answers: vec![],
        }
    }

    /// The client's frames, not yet delivered.
    fn requests(&mut self) -> Vec<Frame> {
        std::iter::from_fn(|| self.client.poll_transmit()).collect()
    }

    /// Delivers `requests`, then every frame either side sends, until quiet.
    fn run(&mut self, mut requests: Vec<Frame>) {
        while !requests.is_empty() {
            for f in requests.drain(..) {
                self.node.handle_frame(Instant::ZERO, &f);
            }
            while let Some(f) = self.node.poll_transmit() {
                if f.id() == Channel::predefined(N).response {
                    self.answers.push(f);
                    self.client.handle_frame(Instant::ZERO, &f);
                }
            }
            requests = self.requests();
        }
        self.events
            .extend(std::iter::from_fn(|| self.client.poll_event()));
    }

    /// One transfer in `opts` (a write of `data` or a read), run to its end; the first answer.
    fn transfer(&mut self, index: u16, data: Option<&[u8]>, opts: SdoOptions) -> Frame {
        let first = self.answers.len();
        self.start(index, data, opts);
        let requests = self.requests();
        self.run(requests);
        self.answers[first]
    }

    fn start(&mut self, index: u16, data: Option<&[u8]>, opts: SdoOptions) {
        match data {
            Some(d) => self.client.download(Instant::ZERO, N, index, 0, d, opts),
            None => self.client.upload(Instant::ZERO, N, index, 0, opts),
        }
        .unwrap();
    }
}

fn modes() -> [SdoOptions; 4] {
    [
        SdoOptions::default(),
        SdoOptions::mode(TransferMode::Expedited),
        SdoOptions::mode(TransferMode::Segmented),
        SdoOptions::mode(TransferMode::Block).with_block_size(4),
    ]
}

#[test]
fn an_answer_about_another_object_does_not_fail_the_next_transfer() {
    for opts in modes() {
        for write in [true, false] {
            let mut bus = Bus::new();
            let text = b"late";
            let data: Vec<u8> = (0..300u32).map(|i| (i * 7) as u8).collect();
            bus.node.write(Instant::ZERO, DOMAIN, 0, &data).unwrap();
            // The earlier transfer, on another object, in the same mode and direction.
            let late = bus.transfer(STRING, write.then_some(&text[..]), opts);
            assert!(bus.events.pop().unwrap().result.is_ok(), "{opts:?}");
            // The next one: its request goes out, the earlier answer's late copy comes first.
            let payload = if matches!(opts.mode, TransferMode::Expedited) {
                &data[..4]
            } else {
                &data[..]
            };
            bus.start(DOMAIN, write.then_some(payload), opts);
            let requests = bus.requests();
            bus.client.handle_frame(Instant::ZERO, &late);
            bus.run(requests);
            let e = bus.events.pop().expect("a result");
            let what = format!("{} {opts:?}", if write { "write" } else { "read" });
            assert!(e.result.is_ok(), "{what}: {:?}", e.result);
            if write {
                assert_eq!(bus.node.od().read(DOMAIN, 0).unwrap(), payload, "{what}");
            } else {
                assert_eq!(e.data(), Some(&data[..]), "{what}");
            }
            assert_eq!(bus.client.stats().stale, 1, "{what}");
            assert_eq!(bus.client.stats().failed, 0, "{what}");
            assert_eq!(bus.node.sdo_server().stats().aborted, 0, "{what}");
        }
    }
}
