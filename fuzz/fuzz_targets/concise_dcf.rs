//! Concise DCFs (CiA 302-3, the master's 0x1F22): any bytes through the parser. Never a panic;
//! the allocation-free check and the parser agree; what parses writes back as the same bytes,
//! and configures a slave with its entries in order (the producer heartbeat aside). What the
//! master's 0x1F22 accepts is exactly what parses.
#![no_main]

use duocan::master::{objects, validate_concise, ConciseDcf, ConfigStep, SlaveConfig};
use duocan::od::{comm, ObjectDictionary};
use duocan::NodeId;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let parsed = ConciseDcf::parse(data);
    assert_eq!(
        validate_concise(data),
        parsed.as_ref().map(|d| d.entries.len() as u32).map_err(|e| *e)
    );
    let mut od = objects::master_dictionary(1, comm::Identity::default());
    let accepted = od.write(objects::CONCISE_DCF, 5, data).is_ok();
    assert_eq!(accepted, data.is_empty() || parsed.is_ok());
    let Ok(dcf) = parsed else { return };
    assert_eq!(dcf.to_bytes(), data);
    let cfg = SlaveConfig::new(NodeId::must(5)).with_concise(&dcf);
    let mut steps = cfg.steps.iter();
    let mut heartbeat_taken = false;
    for e in &dcf.entries {
        let heartbeat = (e.index, e.sub, e.data.len()) == (comm::HEARTBEAT_PRODUCER, 0, 2);
        if heartbeat && !heartbeat_taken {
            heartbeat_taken = true;
            continue;
        }
        let Some(ConfigStep::Write { index, sub, data }) = steps.next() else {
            panic!("entry {e:?} not written");
        };
        assert_eq!((*index, *sub, data), (e.index, e.sub, &e.data));
    }
    assert!(steps.next().is_none());
});
