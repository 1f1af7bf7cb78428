//! The second-best hypothesis test: after the best alignment is found, the correspondences it does not
//! explain are pruned and solved again, exactly as the first time. In a place with rotational symmetry (a
//! square hall, a courtyard) or translational repetition (a corridor of identical segments, an urban grid)
//! the mutual nearest neighbours of the descriptors split between the alignments that the place admits, so
//! the rival found among the leftovers is nearly as strong as the best one; elsewhere the leftovers are
//! outliers that agree on nothing. The rival's inlier count is reported in
//! [`CoarseAlignment::rival_inlier_count`](skid_core::slots::CoarseAlignment); the host compares it with
//! the best alignment's and refuses ambiguous loops: between robots, a wrong alignment in a self-similar
//! place yields loops that agree with one another, which pairwise consistency (PCM) cannot reject.

use nalgebra::Vector3;
use skid_core::Pose;

use crate::pruning::ConsistencyGraph;
use crate::{KissMatcherConfig, PruningMode};

/// A rival closer to the best alignment than this (in translation) is the same alignment, not a rival.
pub const DISTINCT_TRANSLATION_M: f64 = 1.0;
/// A rival closer to the best alignment than this (in rotation) is the same alignment, not a rival.
pub const DISTINCT_ROTATION_RAD: f64 = 10.0 * std::f64::consts::PI / 180.0;

/// The final inliers of the strongest alignment distinct from `best` among the correspondences
/// `source[i] ↔ target[i]` that `best` does not explain (residual beyond twice the pruning bound); 0 when
/// there is none.
pub(crate) fn rival_inliers(
    config: &KissMatcherConfig,
    source: &[Vector3<f64>],
    target: &[Vector3<f64>],
    best: &Pose,
) -> usize {
    let explained_m = 2.0 * config.noise_bound_m(config.pruning_noise_bound_gain);
    let (left_source, left_target) = unexplained(source, target, best, explained_m);
    if left_source.len() < config.min_inliers.max(3) {
        return 0;
    }
    let graph = ConsistencyGraph::build(
        &left_source,
        &left_target,
        config.noise_bound_m(config.pruning_noise_bound_gain),
    );
    let kept = match config.pruning {
        PruningMode::MaxCore => graph.max_core(),
        PruningMode::MaxClique => graph.max_clique(config.max_clique_node_limit).0,
    };
    if kept.len() < 2 {
        return 0;
    }
    let kept_source: Vec<Vector3<f64>> = kept.iter().map(|&k| left_source[k]).collect();
    let kept_target: Vec<Vector3<f64>> = kept.iter().map(|&k| left_target[k]).collect();
    match crate::solver::solve(config, &kept_source, &kept_target) {
        Some((rival, rotation_inliers, inliers)) if rotation_inliers >= 2 && distinct(best, &rival) => {
            inliers
        }
        _ => 0,
    }
}

/// The correspondences `source[i] ↔ target[i]` that `best` leaves further apart than `explained_m`:
/// where a rival alignment is looked for.
pub fn unexplained(
    source: &[Vector3<f64>],
    target: &[Vector3<f64>],
    best: &Pose,
    explained_m: f64,
) -> (Vec<Vector3<f64>>, Vec<Vector3<f64>>) {
    source
        .iter()
        .zip(target)
        .filter(|(p, q)| (*q - best.transform_point(&(**p).into()).coords).norm() > explained_m)
        .map(|(p, q)| (*p, *q))
        .unzip()
}

/// True when two alignments differ by more than the same-alignment tolerances.
pub fn distinct(a: &Pose, b: &Pose) -> bool {
    skid_core::pose::moved_beyond(a, b, DISTINCT_TRANSLATION_M, DISTINCT_ROTATION_RAD)
}
