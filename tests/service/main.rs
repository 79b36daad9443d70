//! Integration tests: the daemon as its users meet it: `sqscand` processes on the simulator and on the mock rig, their socket protocol, the soak, and the ROS 2, MCAP and live-view outputs checked by independent readers.
//!
//! One test binary for all of them (each module a former binary of its own), so the library
//! is linked once for them and they share one harness, `tests/common`.

#[path = "../common/mod.rs"]
mod common;

mod daemon;
mod mcap;
mod protocol;
mod ros2;
mod soak;
mod view;
