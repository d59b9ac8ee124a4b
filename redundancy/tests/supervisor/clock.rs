//! The clock contract on a supervised master (supervisor, CiA 302-2 master, dual-bus layer): a
//! driver loop at the end of time handles what is due and then waits instead of spinning.

use crate::net::*;
use duocan::machine::Device;
use duocan::Instant;

#[test]
fn a_supervised_master_at_the_end_of_time_does_not_spin() {
    let mut n = SupNet::new(Params::default());
    n.sim.run_until(Instant::from_millis(1500));
    for id in [STRONG, WEAK] {
        let dev = n.master(id);
        let d = n.sim.device_mut(dev);
        let mut rounds = 0;
        while let Some(t) = d.poll_timeout() {
            assert!(
                rounds < 3,
                "master {id} still due at {t:?} after {rounds} rounds"
            );
            d.handle_timeout(Instant::MAX);
            while d.poll_transmit().is_some() {}
            while d.poll_port_request().is_some() {}
            while d.poll_event().is_some() {}
            rounds += 1;
        }
        assert_eq!(d.poll_timeout(), None, "master {id}");
    }
}
