//! Integration tests: hardware in the loop: the sweep assembler and the mock rig on pseudo-terminals that speak the real protocols.
//!
//! One test binary for all of them (each module a former binary of its own), so the library
//! is linked once for them and they share one harness, `tests/common`.

#[path = "../common/mod.rs"]
mod common;

mod rig_hil;
mod sweep_hil;
