//! Slave-pair supervision on the simulated dual bus, with the NMT frames on the wire: the seed's
//! cases at exact instants.

mod supnet;

use duocan::{Duration, Instant, NmtCommand};
use duocan_redundancy::flying_master::MasterRole;
use duocan_redundancy::pairs::RoleReason;
use duocan_redundancy::Member;
use supnet::*;

fn ms(x: u64) -> Instant {
    Instant::from_millis(x)
}

#[test]
fn start_up_strong_master_active_first_members_active_weak_shadows() {
    let mut n = SupNet::new(Params::default());
    n.sim.run_until(ms(2000));
    assert_eq!(n.role(STRONG), MasterRole::Active);
    assert!(matches!(n.role(WEAK), MasterRole::Standby(Some(_))));
    for i in 0..4 {
        assert!(n.active_member(STRONG, i).is_some(), "pair {i}");
        assert_eq!(n.active_member(WEAK, i), n.active_member(STRONG, i), "pair {i}");
    }
    println!("{}", n.sim.device(n.master(STRONG)).status(ms(2000)));
    println!("{}", n.sim.device(n.master(WEAK)).status(ms(2000)));
    for x in n.nmt_first_copies() {
        println!("{x:?}");
    }
}
