//! The anchor stage: the model's largest part is searched over the whole scene, and its
//! hypotheses are scored and ranked by the paper's voting over M, S and I. A single-part model's
//! candidates are these hypotheses; a compound's other parts are searched around them
//! (`compound`).

use super::prepare::Prepared;
use super::refine::{self, Coarse, Refine, Refined, refine_fits};
use super::report::{Detection, PartResult, PoseText, VotesText};
use super::search::{distinct, region_fits};
use super::space::Hypothesis;
use super::verify::{Scores, paper_criteria, rank_sums, score, votes};
use super::{Params, accept, rest, select};
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
            .max_by(|&a, &b| {
                model.parts[a]
                    .shape
                    .box_volume()
                    .total_cmp(&model.parts[b].shape.box_volume())
            })
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
) -> Refined {
    let all_seeds: Vec<usize> = (0..prep.sub.len()).collect();
    // One answer of a single part is the first hypothesis, in the order of the vote, that
    // passes: the ranking takes M, S and I after the coarse rounds, and only the hypotheses
    // judged get the fine rounds. A compound's anchor candidates place its other parts, and
    // with `all` every hypothesis is judged: they get them all.
    let refine = if model.is_compound() || params.all {
        Refine::Fine
    } else {
        Refine::Deferred
    };
    let space = prep.space();
    let shape = &model.parts[anchor.part].shape;
    let seed = stream_seed(params.seed, anchor.part as u64 + 1000 * round);
    let check = &prep.checks[anchor.part];
    let mut fits = region_fits(
        &space,
        shape,
        &all_seeds,
        anchor.hypotheses,
        &prep.settings,
        check,
        seed,
    );
    // Resting starts: the best few in the first round, more in the second (which runs only when
    // the first found nothing acceptable); the ones the first round had are known by then.
    let kept = if round == 0 {
        rest::FIRST_ROUND
    } else {
        rest::LATER_ROUNDS
    };
    fits.extend(rest::resting_fits(&space, shape, stream_seed(seed, u64::MAX), kept));
    refine_fits(
        &space,
        &distinct(fits, known),
        &prep.settings,
        model.parts[anchor.part].open,
        check,
        known,
        refine,
    )
}

/// The anchor hypotheses ranked.
pub struct Anchors {
    /// Index into the model's parts.
    pub part: usize,
    pub hypotheses: Vec<Hypothesis>,
    /// Where each hypothesis' fine rounds were deferred (`Refine::Deferred`) and have not run
    /// yet: they run when it is measured.
    deferred: Vec<Option<Coarse>>,
    /// Each hypothesis' scores: complete where `measured` ([`Anchors::measure`]), else the
    /// paper's M, S and I alone (`Scores::votes`), all that ranking asks.
    pub scores: Vec<Scores>,
    pub measured: Vec<bool>,
    /// Each hypothesis' rank sum over M, S and I (smaller is better).
    pub rank: Vec<usize>,
    /// Indices into `hypotheses`, best rank first (ties by M).
    pub order: Vec<usize>,
}

/// Rank the hypotheses by the paper's voting over M, S and I. The acceptance measures are taken
/// later, of the hypotheses that are judged ([`Anchors::measure`]).
pub fn rank(prep: &Prepared, anchor: &AnchorPart, found: Refined, gamma: f64) -> Anchors {
    let space = prep.space();
    let Refined {
        hypotheses, deferred, ..
    } = found;
    let scores: Vec<Scores> = hypotheses
        .par_iter()
        .map(|h| votes(&space, &h.placed, h.m, gamma, &prep.samples[anchor.part]))
        .collect();
    let rank = rank_sums(&paper_criteria(&scores));
    let mut order: Vec<usize> = (0..hypotheses.len()).collect();
    order.sort_by_key(|&k| (rank[k], ordered(hypotheses[k].m)));
    let anchors = Anchors {
        part: anchor.part,
        measured: vec![false; hypotheses.len()],
        hypotheses,
        deferred,
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
        self.order.iter().map(|&k| self.ranked_one(k))
    }

    fn ranked_one(&self, k: usize) -> Ranked<'_> {
        Ranked {
            rank: self.rank[k],
            hypothesis: &self.hypotheses[k],
            scores: &self.scores[k],
            measured: self.measured[k],
        }
    }

    /// Hypothesis `k` as it is measured, with its complete scores: kept, or its deferred fine
    /// rounds run and its scores measured now.
    fn full_scores(&self, prep: &Prepared, model: &Model, k: usize, gamma: f64) -> (Hypothesis, Scores) {
        if self.measured[k] {
            return (self.hypotheses[k], self.scores[k]);
        }
        let space = prep.space();
        let h = match &self.deferred[k] {
            Some(c) => refine::finish_deferred(
                &space,
                &prep.checks[self.part],
                model.parts[self.part].open,
                c,
                self.hypotheses[k],
            ),
            None => self.hypotheses[k],
        };
        (h, score(&space, &h.placed, h.m, gamma, &prep.samples[self.part]))
    }

    /// Keep hypothesis `k` as measured, with its complete scores.
    fn keep(&mut self, k: usize, (h, scores): (Hypothesis, Scores)) {
        self.hypotheses[k] = h;
        self.deferred[k] = None;
        self.scores[k] = scores;
        self.measured[k] = true;
        tracing::debug!("measured {}", self.ranked_one(k));
    }

    /// Complete the scores of the hypotheses `ks` (side by side) that hold the votes alone.
    pub fn measure(&mut self, prep: &Prepared, model: &Model, ks: &[usize], gamma: f64) {
        let full: Vec<(Hypothesis, Scores)> = ks
            .par_iter()
            .map(|&k| self.full_scores(prep, model, k, gamma))
            .collect();
        for (&k, s) in ks.iter().zip(full) {
            self.keep(k, s);
        }
    }

    /// The part result of hypothesis `k`, which must have been measured.
    pub fn part_result(&self, model: &Model, k: usize) -> PartResult {
        debug_assert!(self.measured[k], "hypothesis {k} was not measured");
        self.part_with(model, &self.hypotheses[k], self.scores[k])
    }

    fn part_with(&self, model: &Model, h: &Hypothesis, scores: Scores) -> PartResult {
        PartResult {
            name: model.parts[self.part].name.clone(),
            placed: Some(h.placed),
            scores,
        }
    }

    /// A single-part model's candidates through the acceptance test, best rank first (a
    /// container standing on its base before any on its rim, as [`select::select`] prefers
    /// them), with how many of them have been through the free-space check already
    /// (`accept::free_space`).
    ///
    /// Without `Params::all` the answer is the first candidate in that order that passes the
    /// acceptance test and the free-space check: the candidates are measured a few at a time,
    /// as many as there are threads, and the search stops at the first that passes. With it,
    /// every hypothesis is a candidate.
    pub fn single_part_candidates(
        &mut self,
        prep: &Prepared,
        model: &Model,
        params: &Params,
    ) -> (Vec<Detection>, usize) {
        let noise = prep.noise();
        let mut order = self.order.clone();
        if let Some(plane) = &prep.scene.plane {
            // Stable: the ranking holds within each kind.
            order.sort_by_key(|&k| {
                let pose = self.hypotheses[k].placed.pose * model.parts[self.part].pose_in_object.inverse();
                select::upright(model, &pose, plane) == Some(false)
            });
        }
        let lazy = !params.all;
        let (judged, _) = accept::judge_in_order(prep, params, &order, lazy, |&k| {
            let (h, scores) = self.full_scores(prep, model, k, params.gamma);
            let part = self.part_with(model, &h, scores);
            (
                (h, scores),
                accept::assess(model, vec![part], Vec::new(), &noise, &params.acceptance),
            )
        });
        let mut out: Vec<Detection> = Vec::with_capacity(judged.len());
        for (&k, (measured, d)) in order.iter().zip(judged) {
            self.keep(k, measured);
            out.push(d);
        }
        // Lazily, every candidate judged has been checked (and failed, or was not found), up to
        // the one that passed.
        let checked = if lazy { out.len() } else { 0 };
        (out, checked)
    }
}

/// One ranked anchor hypothesis: `rank .. pos (..) z (..) M .. S .. I ..`, and the acceptance
/// measures once they are taken.
pub struct Ranked<'a> {
    pub rank: usize,
    pub hypothesis: &'a Hypothesis,
    pub scores: &'a Scores,
    pub measured: bool,
}

impl fmt::Display for Ranked<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "rank {:3} {} ", self.rank, PoseText(&self.hypothesis.placed.pose))?;
        if self.measured {
            write!(f, "{}", self.scores)
        } else {
            write!(f, "{}", VotesText(self.scores))
        }
    }
}

/// Totally ordered key of a finite-or-infinite float for sorting.
fn ordered(v: f64) -> i64 {
    let b = v.to_bits() as i64;
    if b < 0 { b ^ i64::MAX } else { b }
}
