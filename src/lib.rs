//! sqscan: find known objects in laser range scans by fitting tapered superquadrics.
//!
//! The library behind the `sqscand` daemon and the `sqscan` tool; `docs/ARCHITECTURE.md` draws
//! the data flow. The public API, by job, down the data flow:
//! - [`numeric`]: one Levenberg-Marquardt solver behind [`numeric::LeastSquares`], medians and
//!   quantiles, robust weights, seeded streams.
//! - [`geometry`]: the tapered superellipsoid (inside-outside function, distances, pose
//!   Jacobian, surface sampling, ray queries); [`pose`] and [`spec`]: poses in files and on the
//!   wire, file errors that name file, field and fault.
//! - [`cloud`]: point clouds, PLY/PCD/text IO, the voxel grid and plane removal; [`model`]:
//!   object models (one to three superquadric parts) and their files.
//! - [`calibration`]: from a sensor column and raw row to a point in the base frame;
//!   [`sweep`]: the one [`sweep::Sweep`] type, assembled from profiles and PTU samples, and
//!   acquired with any PTU and [`sqscan_drivers::sensor::ProfileSource`].
//! - [`sim`]: scene files and the ray-cast scanner, which delivers the same `Sweep`; [`mock`]:
//!   the mock rig on pseudo-terminals.
//! - [`detect`]: the superquadric detector; [`grasp`]: where a parallel gripper can take what
//!   it found; [`eval`] scores it against the simulator's truth; [`learn`]: a model from a scan.
//! - [`daemon`]: `sqscand`, handed a [`daemon::Backend`] and its [`daemon::Listeners`].
//! - [`logging`], [`atomic`]: what both binaries share.
//!
//! Conventions: SI units (metres, radians, seconds); frames follow ROS REP-103 (x forward,
//! y left, z up); poses on the wire are position + quaternion `[x, y, z, w]`; every random
//! choice comes from a seeded generator.

pub mod appearance;
pub mod atomic;
pub mod calibration;
pub mod cloud;
pub mod daemon;
pub mod detect;
pub mod eval;
pub mod geometry;
pub mod grasp;
pub mod learn;
pub mod logging;
pub mod mock;
pub mod model;
pub mod numeric;
pub mod pose;
pub mod ros;
pub mod sim;
pub mod spec;
pub mod surface_samples;
pub mod sweep;
mod symmetry;
