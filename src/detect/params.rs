//! The detector's settings: the paper's search and voting parameters and the calibrated
//! thresholds of the acceptance test.

use nalgebra::Point3;

/// Detector settings. `Default` gives the paper's settings (n = 10 trials of 30 points, 20 LM
/// iterations, gamma = 0.2) and the calibrated acceptance thresholds.
#[derive(Debug, Clone)]
pub struct Params {
    pub seed: u64,
    /// RANSAC trials per hypothesis (paper: n = 10).
    pub trials: usize,
    /// Points per trial (paper: 30).
    pub sample_points: usize,
    /// LM iterations per fit (paper: 20).
    pub fit_iterations: usize,
    /// Surface tolerance of the S and I criteria (paper: 0.2).
    pub gamma: f64,
    /// Hypotheses for the (first) part; `None`: the model's m, else derived from the scene.
    pub hypotheses: Option<usize>,
    /// RANSAC hypotheses (each in its own region of the shell) searched for each further part of
    /// a compound around each candidate, beside the placements the model's connection gives; 0
    /// keeps only those.
    pub local_hypotheses: usize,
    /// Candidates of the first part a compound search continues from.
    pub compound_candidates: usize,
    pub remove_plane: bool,
    /// Drop points farther than this from the viewpoint (or the origin) (m).
    pub max_range: Option<f64>,
    /// Where the sensor was: orients surface normals. Camera-frame clouds have it at the origin.
    pub viewpoint: Option<Point3<f64>>,
    /// Return every accepted, non-overlapping instance instead of the best one.
    pub all: bool,
    /// With `all`, return the accepted instances that overlap a better one as well, best first:
    /// for a caller that judges them further before choosing among overlapping ones (the colour
    /// check, [`super::detect_all_checked`]), so that one it turns away does not hide another.
    pub overlapping: bool,
    pub acceptance: Acceptance,
}

/// Thresholds of the "is it there" test, calibrated on simulated scenes with and without the
/// objects (see BENCHMARKS.md).
#[derive(Debug, Clone, Copy)]
pub struct Acceptance {
    /// Least share of the visible surface that must hold points.
    pub min_coverage: f64,
    /// Least coverage of a candidate whose other measures pass and whose missing surface is
    /// hidden behind other objects: it is accepted where the covered and the hidden surface
    /// together reach `min_coverage` and the part of it in the sensor's view was seen
    /// (`min_seen_hidden`).
    pub min_coverage_hidden: f64,
    /// Least [`super::visibility::Visibility::seen_ratio`] of a candidate accepted with hidden
    /// surface.
    pub min_seen_hidden: f64,
    /// Most inside points per surface point.
    pub max_interior_ratio: f64,
    /// Most points just outside the surface per surface point.
    pub max_shell_ratio: f64,
    /// Most points continuing the explained surface's plane past the model's edge per surface
    /// point (see [`super::verify::Scores::continued_points`]).
    pub max_continued_ratio: f64,
    /// Least share of each part's visible side that, where the sensor could have seen it, it
    /// did (see [`super::visibility::Visibility::seen_ratio`]).
    pub min_seen: f64,
    /// Largest share of each part's visible side that lies where the sensor saw through, farther
    /// than [`super::visibility::DEEP_SEE_THROUGH`] from any measured part of it: the part
    /// reaching into free space (a box longer than the one measured), not its outline a few
    /// millimetres off.
    pub max_deep_see_through: f64,
    /// Largest RMS surface distance, in noise sigmas.
    pub max_rms_sigmas: f64,
    /// Largest connection angle error of a compound (rad).
    pub max_angle_error: f64,
    /// Largest connection distance error of a compound, as a share of the nominal distance.
    pub max_distance_error: f64,
}

impl Default for Acceptance {
    fn default() -> Self {
        Acceptance {
            min_coverage: 0.45,
            min_coverage_hidden: 0.3,
            min_seen_hidden: 0.9,
            max_interior_ratio: 0.15,
            max_shell_ratio: 0.08,
            max_continued_ratio: 0.1,
            min_seen: 0.5,
            max_deep_see_through: 0.02,
            max_rms_sigmas: 1.6,
            max_angle_error: 25f64.to_radians(),
            max_distance_error: 0.25,
        }
    }
}

impl Default for Params {
    fn default() -> Self {
        Params {
            seed: 0,
            trials: 10,
            sample_points: 30,
            fit_iterations: 20,
            gamma: 0.2,
            hypotheses: None,
            local_hypotheses: 4,
            compound_candidates: 6,
            remove_plane: true,
            max_range: None,
            viewpoint: None,
            all: false,
            overlapping: false,
            acceptance: Acceptance::default(),
        }
    }
}
