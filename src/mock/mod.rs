//! Mock devices that need the simulator: the whole scanning rig (a mock PTU and a mock profile
//! sensor that sees the scene at the PTU's current angles). Single devices live in
//! `sqscan_drivers::mock`.

pub mod rig;
