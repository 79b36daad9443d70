//! sqscan: find known objects in laser range scans by fitting tapered superquadrics.
//!
//! The library behind the `sqscand` daemon and the `sqscan` tool. Modules by job:
//! - [`geometry`]: the tapered superellipsoid (inside-outside function, distances, pose
//!   Jacobian, surface sampling, ray queries).
//! - [`model`]: object models (one to three superquadric parts) loaded from `models/*.toml`.
//! - [`cloud`]: point clouds, organized range images, PLY/PCD/text IO.
//! - [`calibration`]: from a sensor column and raw row to a point in the base frame.
//! - [`mock`]: the mock scanning rig (mock PTU + mock sensor seeing a simulated scene).
//! - [`sweep`]: assembling PTU position samples and laser profiles into one organized sweep,
//!   and acquiring a sweep with the devices.
//! - [`sim`]: scene files and the ray-cast model of the laser triangulation scanner.
//! - [`detect`]: the superquadric detector; [`eval`] scores it against the simulator's truth.
//! - [`daemon`]: `sqscand`: configuration, acquisition, the socket server, systemd notification.
//!
//! Conventions: SI units (metres, radians, seconds); frames follow ROS REP-103 (x forward,
//! y left, z up); poses on the wire are position + quaternion `[x, y, z, w]`; every random
//! choice comes from a seeded generator.

pub mod atomic;
pub mod calibration;
pub mod cloud;
pub mod daemon;
pub mod detect;
pub mod eval;
pub mod geometry;
pub mod learn;
pub mod logging;
pub mod mock;
pub mod model;
pub mod numeric;
pub mod pose;
pub mod sim;
pub mod spec;
pub mod sweep;
pub mod symmetry;
