//! RANSAC over putative correspondences (Fischler & Bolles, CACM 1981), in the form feature-based global
//! registration baselines use (Rusu et al., ICRA 2009; Open3D's `registration_ransac_based_on_feature_
//! matching`): draw three correspondences, reject the draw unless its edge lengths agree in both clouds,
//! fit a rigid motion, count correspondences within the inlier distance, stop when the confidence is
//! reached, then refit on the inliers.
//!
//! Draws are made in fixed-size batches, each with its own ChaCha stream derived from the seed, and
//! batches are evaluated in parallel and reduced in batch order, so the result depends on the seed only,
//! not on the number of threads.

use nalgebra::{Matrix3, Translation3, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use skid_coarse_kiss_matcher::solver::rotation_from_covariance;
use skid_core::Pose;

/// Draws per batch.
const BATCH: usize = 256;
/// Batches evaluated between two checks of the stopping rule.
const BATCHES_PER_ROUND: usize = 8;

/// RANSAC settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RansacParams {
    /// A correspondence is an inlier when the moved source point lies within this of its target point.
    pub inlier_distance_m: f64,
    /// Edge-length check: every edge of the drawn triangle must be at least this fraction of its
    /// counterpart in the other cloud.
    pub edge_length_similarity: f64,
    pub max_iterations: usize,
    /// Stop once the chance of having missed an all-inlier draw is below 1 − confidence.
    pub confidence: f64,
    /// Refits on the inliers after the search.
    pub refine_rounds: usize,
    pub seed: u64,
}

/// The best hypothesis.
#[derive(Clone, Debug)]
pub struct RansacResult {
    pub target_from_source: Pose,
    pub inlier_count: usize,
    pub iterations: usize,
}

/// Rigid motion (Kabsch/Umeyama without scale) taking `source[i]` onto `target[i]` for the chosen indices.
pub fn fit_rigid(source: &[Vector3<f64>], target: &[Vector3<f64>], indices: &[usize]) -> Option<Pose> {
    if indices.len() < 3 {
        return None;
    }
    let count = indices.len() as f64;
    let source_centre = indices.iter().map(|&i| source[i]).sum::<Vector3<f64>>() / count;
    let target_centre = indices.iter().map(|&i| target[i]).sum::<Vector3<f64>>() / count;
    let mut covariance = Matrix3::zeros();
    for &i in indices {
        covariance += (target[i] - target_centre) * (source[i] - source_centre).transpose();
    }
    let rotation = rotation_from_covariance(&covariance)?;
    let translation = target_centre - rotation * source_centre;
    translation.iter().all(|v| v.is_finite()).then(|| {
        Pose::from_parts(
            Translation3::from(translation),
            UnitQuaternion::from_rotation_matrix(&rotation),
        )
    })
}

fn inliers(source: &[Vector3<f64>], target: &[Vector3<f64>], pose: &Pose, threshold_sq: f64) -> Vec<usize> {
    (0..source.len())
        .filter(|&i| {
            (pose.rotation * source[i] + pose.translation.vector - target[i]).norm_squared() <= threshold_sq
        })
        .collect()
}

fn inlier_count(source: &[Vector3<f64>], target: &[Vector3<f64>], pose: &Pose, threshold_sq: f64) -> usize {
    let (rotation, translation) = (pose.rotation.to_rotation_matrix(), pose.translation.vector);
    source
        .iter()
        .zip(target)
        .filter(|(s, t)| (rotation * *s + translation - *t).norm_squared() <= threshold_sq)
        .count()
}

/// Whether the triangle's edges have about the same lengths in both clouds.
fn edges_agree(source: &[Vector3<f64>], target: &[Vector3<f64>], draw: &[usize; 3], similarity: f64) -> bool {
    [(0, 1), (1, 2), (2, 0)].iter().all(|&(a, b)| {
        let source_length = (source[draw[a]] - source[draw[b]]).norm();
        let target_length = (target[draw[a]] - target[draw[b]]).norm();
        source_length >= similarity * target_length && target_length >= similarity * source_length
    })
}

/// Draws a batch of hypotheses; returns the best as (inliers, global draw index, pose).
fn run_batch(
    source: &[Vector3<f64>],
    target: &[Vector3<f64>],
    params: &RansacParams,
    batch: usize,
) -> Option<(usize, usize, Pose)> {
    let mut rng = ChaCha8Rng::seed_from_u64(params.seed);
    rng.set_stream(batch as u64);
    let n = source.len();
    let threshold_sq = params.inlier_distance_m * params.inlier_distance_m;
    let mut best: Option<(usize, usize, Pose)> = None;
    for k in 0..BATCH {
        let draw = [
            rng.random_range(0..n),
            rng.random_range(0..n),
            rng.random_range(0..n),
        ];
        if draw[0] == draw[1] || draw[1] == draw[2] || draw[0] == draw[2] {
            continue;
        }
        if !edges_agree(source, target, &draw, params.edge_length_similarity) {
            continue;
        }
        let Some(pose) = fit_rigid(source, target, &draw) else {
            continue;
        };
        // The drawn correspondences themselves must fit (Open3D's distance checker).
        if draw.iter().any(|&i| {
            (pose * nalgebra::Point3::from(source[i]))
                .coords
                .metric_distance(&target[i])
                > params.inlier_distance_m
        }) {
            continue;
        }
        let count = inlier_count(source, target, &pose, threshold_sq);
        if best.as_ref().is_none_or(|(c, _, _)| count > *c) {
            best = Some((count, batch * BATCH + k, pose));
        }
    }
    best
}

/// Iterations needed to draw one all-inlier triple with the given confidence at inlier ratio `ratio`.
pub fn required_iterations(ratio: f64, confidence: f64, max_iterations: usize) -> usize {
    if ratio <= 0.0 {
        return max_iterations;
    }
    let all_inliers = ratio.min(1.0).powi(3);
    if all_inliers >= 1.0 {
        return 1;
    }
    let needed = (1.0 - confidence).ln() / (1.0 - all_inliers).ln();
    if needed.is_finite() && needed >= 0.0 {
        (needed.ceil() as usize).min(max_iterations)
    } else {
        max_iterations
    }
}

/// Runs RANSAC on the correspondences `source[i] ↔ target[i]` on the current rayon pool. `None` when no
/// draw gave a hypothesis (fewer than three correspondences, or none passing the checks).
pub fn ransac(
    source: &[Vector3<f64>],
    target: &[Vector3<f64>],
    params: &RansacParams,
) -> Option<RansacResult> {
    let n = source.len().min(target.len());
    let (source, target) = (&source[..n], &target[..n]);
    if n < 3 {
        return None;
    }
    let mut best: Option<(usize, usize, Pose)> = None;
    let mut next_batch = 0;
    let mut needed = params.max_iterations;
    while next_batch * BATCH < needed {
        let batches: Vec<usize> = (next_batch..next_batch + BATCHES_PER_ROUND).collect();
        next_batch += BATCHES_PER_ROUND;
        let results: Vec<Option<(usize, usize, Pose)>> = batches
            .par_iter()
            .map(|&b| run_batch(source, target, params, b))
            .collect();
        for candidate in results.into_iter().flatten() {
            if best.as_ref().is_none_or(|(c, _, _)| candidate.0 > *c) {
                best = Some(candidate);
            }
        }
        if let Some((count, _, _)) = &best {
            needed = required_iterations(*count as f64 / n as f64, params.confidence, params.max_iterations);
        }
    }
    let (mut count, _, mut pose) = best?;
    let threshold_sq = params.inlier_distance_m * params.inlier_distance_m;
    for _ in 0..params.refine_rounds {
        let members = inliers(source, target, &pose, threshold_sq);
        let Some(refit) = fit_rigid(source, target, &members) else {
            break;
        };
        let refit_count = inlier_count(source, target, &refit, threshold_sq);
        if refit_count < count {
            break;
        }
        (pose, count) = (refit, refit_count);
    }
    Some(RansacResult {
        target_from_source: pose,
        inlier_count: count,
        iterations: (next_batch * BATCH).min(params.max_iterations.max(BATCH)),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use skid_core::Pose;

    fn params(seed: u64) -> RansacParams {
        RansacParams {
            inlier_distance_m: 0.45,
            edge_length_similarity: 0.9,
            max_iterations: 100_000,
            confidence: 0.999,
            refine_rounds: 3,
            seed,
        }
    }

    #[test]
    fn finds_the_motion_among_outliers_and_is_reproducible() {
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let truth = Pose::new(Vector3::new(8.0, -2.0, 0.3), Vector3::new(0.02, -0.01, 2.5));
        let mut source = Vec::new();
        let mut target = Vec::new();
        for k in 0..500 {
            let p = Vector3::from_fn(|_, _| rng.random_range(-30.0..30.0));
            source.push(p);
            target.push(if k % 4 == 0 {
                (truth * nalgebra::Point3::from(p)).coords
                    + Vector3::from_fn(|_, _| rng.random_range(-0.05..0.05))
            } else {
                Vector3::from_fn(|_, _| rng.random_range(-30.0..30.0))
            });
        }
        let result = ransac(&source, &target, &params(1)).unwrap();
        let delta = truth.inverse() * result.target_from_source;
        assert!(
            delta.translation.vector.norm() < 0.1 && delta.rotation.angle() < 0.01,
            "{delta:?}"
        );
        assert!(
            (125..=130).contains(&result.inlier_count),
            "{}",
            result.inlier_count
        );
        assert!(
            result.iterations < 100_000,
            "stopped early: {}",
            result.iterations
        );
        let again = ransac(&source, &target, &params(1)).unwrap();
        assert_eq!(again.target_from_source, result.target_from_source);
    }

    #[test]
    fn too_few_or_degenerate_correspondences_give_nothing() {
        let points = vec![Vector3::new(1.0, 0.0, 0.0), Vector3::new(2.0, 0.0, 0.0)];
        assert!(ransac(&points, &points, &params(0)).is_none());
        assert!(fit_rigid(&points, &points, &[0, 1]).is_none());
        assert_eq!(required_iterations(0.0, 0.999, 10), 10);
        assert_eq!(required_iterations(1.0, 0.999, 10), 1);
        assert!(required_iterations(0.5, 0.999, 100_000) > 40);
    }
}
