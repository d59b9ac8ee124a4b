//! SDO server and client (`duocan::sdo`): transfers in every mode, aborts, golden frame sequences, random frame sequences, second copies, late answers, behaviour on the simulated bus.

mod aborts;
mod behaviour;
mod golden;
mod net;
mod random;
mod repeats;
mod sim;
mod stale;
mod stream;
mod transfers;
