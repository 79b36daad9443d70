//! Geometry of tapered superquadrics: the inside-outside function, distances, the pose
//! Jacobian, surface sampling and ray queries.
//!
//! Functions named `*_local` or taking `Vector3` points work in the superquadric's own frame;
//! the methods of [`PlacedSuperquadric`] take points in the frame the pose maps into.

mod kernel;
mod moments;
mod placed;
mod powers;
pub(crate) mod ray;
mod sampling;
mod superquadric;

pub use kernel::{Kernel, lanes_of};
pub use moments::principal_axes;
pub use placed::{NearBatch, PlacedKernel};
pub use superquadric::*;

#[cfg(test)]
mod tests;
