//! Integration tests: the `sqscan` tool and the library on files: cloud formats, models, learning, detection, the evaluation on real scans, and the PTU commands.
//!
//! One test binary for all of them (each module a former binary of its own), so the library
//! is linked once for them and they share one harness, `tests/common`.

#[path = "../common/mod.rs"]
mod common;

mod cloud_io;
mod detect;
mod eval_real;
mod learn;
mod models;
mod ptu_cli;
mod real_colour;
mod real_data;
mod real_learn_at;
