//! Numerical tools shared by the detector, the learner and the daemon: one damped
//! Levenberg-Marquardt solver behind a small least-squares trait ([`lm`]), order statistics and
//! robust weights ([`stats`]), and independent random streams from one seed ([`stream_seed`]).

pub mod dual;
pub mod lanes;
pub mod lm;
pub mod stats;

pub use lm::{Budget, Damping, LeastSquares, LmSettings, Minimum, minimize};
pub use stats::{huber, huber_weight, least_spread_direction, median, quantile};

/// Mix a seed and an index into an independent stream seed (SplitMix64 finaliser), so profiles,
/// hypotheses or trials can be drawn in any order, in parallel, with the same result.
pub fn stream_seed(seed: u64, index: u64) -> u64 {
    let mut z = seed ^ index.wrapping_add(1).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}
