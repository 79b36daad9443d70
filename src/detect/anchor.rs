//! The anchor stage: the model's largest part is searched over the whole scene, and its
//! hypotheses are scored and ranked by the paper's voting over M, S and I. A single-part model's
//! candidates are these hypotheses; a compound's other parts are searched around them
//! (`compound`).

use super::accept;
use super::prepare::{Prepared, RangeNoise};
use super::report::{Detection, PartResult, PoseText};
use super::search::{Hypothesis, search_part};
use super::verify::{Scores, paper_criteria, rank_sums, score};
use super::{Acceptance, Params, box_volume};
use crate::geometry::{PlacedSuperquadric, Superquadric};
use crate::model::Model;
use crate::numeric::stream_seed;
use nalgebra::Point3;
use rayon::prelude::*;
use std::fmt;

/// Which part anchors the search, and how many hypotheses it gets.
pub struct AnchorPart {
    /// Index into the model's parts: the largest.
    pub part: usize,
    /// Hypotheses searched over the scene (the paper's m).
    pub hypotheses: usize,
}

impl AnchorPart {
    /// The largest part, with `Params::hypotheses`, else the part's own m, else one hypothesis
    /// per object-sized patch of `objects`.
    pub fn choose(model: &Model, params: &Params, objects: &[Point3<f64>]) -> AnchorPart {
        let part = (0..model.parts.len())
            .max_by(|&a, &b| box_volume(&model.parts[a].shape).total_cmp(&box_volume(&model.parts[b].shape)))
            .expect("a model has parts");
        let hypotheses = params
            .hypotheses
            .or(model.parts[part].hypotheses.map(|m| m as usize))
            .unwrap_or_else(|| auto_hypotheses(&model.parts[part].shape, objects))
            .max(1);
        tracing::debug!("anchor part {part}: {hypotheses} hypotheses");
        AnchorPart { part, hypotheses }
    }
}

/// Hypotheses for the first part when neither the caller nor the model gives m: one per
/// object-sized patch of the scene, bounded 10..=100 as in the paper.
fn auto_hypotheses(shape: &Superquadric, points: &[Point3<f64>]) -> usize {
    if points.is_empty() {
        return 10;
    }
    let mut lo = points[0];
    let mut hi = points[0];
    for p in points {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    let mut ext = [hi.x - lo.x, hi.y - lo.y, hi.z - lo.z];
    ext.sort_by(|a, b| b.total_cmp(a));
    let cell = 2.0 * shape.max_size();
    ((ext[0] * ext[1]) / (cell * cell)).ceil().clamp(10.0, 100.0) as usize
}

/// The anchor part's hypotheses of one search round, from the round's own random stream, leaving
/// out the places of the `known` hypotheses of earlier rounds.
pub fn search(
    prep: &Prepared,
    model: &Model,
    anchor: &AnchorPart,
    params: &Params,
    round: u64,
    known: &[PlacedSuperquadric],
) -> Vec<Hypothesis> {
    let all_seeds: Vec<usize> = (0..prep.sub.len()).collect();
    search_part(
        &prep.space(),
        &model.parts[anchor.part].shape,
        &all_seeds,
        anchor.hypotheses,
        &prep.settings,
        model.parts[anchor.part].open,
        &prep.checks[anchor.part],
        stream_seed(params.seed, anchor.part as u64 + 1000 * round),
        known,
    )
}

/// The anchor hypotheses scored and ranked.
pub struct Anchors {
    /// Index into the model's parts.
    pub part: usize,
    pub hypotheses: Vec<Hypothesis>,
    pub scores: Vec<Scores>,
    /// Each hypothesis' rank sum over M, S and I (smaller is better).
    pub rank: Vec<usize>,
    /// Indices into `hypotheses`, best rank first (ties by M).
    pub order: Vec<usize>,
}

/// Score the hypotheses and rank them by the paper's voting.
pub fn rank(prep: &Prepared, anchor: &AnchorPart, hypotheses: Vec<Hypothesis>, gamma: f64) -> Anchors {
    let space = prep.space();
    let scores: Vec<Scores> = hypotheses
        .par_iter()
        .map(|h| score(&space, &h.placed, h.m, gamma, &prep.samples[anchor.part]))
        .collect();
    let rank = rank_sums(&paper_criteria(&scores));
    let mut order: Vec<usize> = (0..hypotheses.len()).collect();
    order.sort_by_key(|&k| (rank[k], ordered(hypotheses[k].m)));
    let anchors = Anchors {
        part: anchor.part,
        hypotheses,
        scores,
        rank,
        order,
    };
    for ranked in anchors.ranked() {
        tracing::debug!("{ranked}");
    }
    anchors
}

impl Anchors {
    /// The hypotheses best first, for the log.
    pub fn ranked(&self) -> impl Iterator<Item = Ranked<'_>> {
        self.order.iter().map(|&k| Ranked {
            rank: self.rank[k],
            hypothesis: &self.hypotheses[k],
            scores: &self.scores[k],
        })
    }

    /// The part result of hypothesis `k`.
    pub fn part_result(&self, model: &Model, k: usize) -> PartResult {
        PartResult {
            name: model.parts[self.part].name.clone(),
            placed: Some(self.hypotheses[k].placed),
            scores: self.scores[k],
        }
    }

    /// A single-part model's candidates: every hypothesis, best rank first, through the
    /// acceptance test.
    pub fn single_part_candidates(&self, model: &Model, noise: &RangeNoise, acceptance: &Acceptance) -> Vec<Detection> {
        self.order
            .iter()
            .map(|&k| accept::assess(model, vec![self.part_result(model, k)], Vec::new(), noise, acceptance))
            .collect()
    }
}

/// One ranked anchor hypothesis: `rank .. pos (..) z (..) M .. S .. I .. cov ..`.
pub struct Ranked<'a> {
    pub rank: usize,
    pub hypothesis: &'a Hypothesis,
    pub scores: &'a Scores,
}

impl fmt::Display for Ranked<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "rank {:3} {} {}",
            self.rank,
            PoseText(&self.hypothesis.placed.pose),
            self.scores
        )
    }
}

/// Totally ordered key of a finite-or-infinite float for sorting.
fn ordered(v: f64) -> i64 {
    let b = v.to_bits() as i64;
    if b < 0 { b ^ i64::MAX } else { b }
}
