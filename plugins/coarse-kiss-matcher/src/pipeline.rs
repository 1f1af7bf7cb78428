//! The KISS-Matcher pipeline (Lim et al., ICRA 2025) end to end, with a report of every stage: voxel
//! sampling, Faster-PFH, matching, pruning, GNC-TLS rotation and TLS translation, then the second-best
//! hypothesis test of [`crate::rival`]. Every early exit says
//! why in `invalid_reason`; nothing here panics or returns NaN.

use std::time::Instant;

use nalgebra::Vector3;
use skid_core::slots::CoarseAlignment;
use skid_core::{CloudView, Pose};

use crate::features::{compute_features, voxel_sample};
use crate::matching::{match_descriptors, matched_points};
use crate::pruning::ConsistencyGraph;
use crate::solver::solve;
use crate::{KissMatcherConfig, PruningMode};

/// Wall-clock seconds spent in each stage.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StageTimings {
    pub voxel_s: f64,
    pub features_s: f64,
    pub matching_s: f64,
    pub pruning_s: f64,
    pub solver_s: f64,
    /// The second-best hypothesis test ([`crate::rival`]).
    pub rival_s: f64,
    pub total_s: f64,
}

/// Everything one alignment found out.
#[derive(Clone, Debug)]
pub struct KissMatcherReport {
    pub alignment: CoarseAlignment,
    /// Points after voxel sampling.
    pub target_points: usize,
    pub source_points: usize,
    /// Points with a Faster-PFH descriptor.
    pub target_keypoints: usize,
    pub source_keypoints: usize,
    /// Correspondences after matching (before pruning).
    pub correspondences: usize,
    /// Correspondences kept by the graph pruning.
    pub pruned: usize,
    /// Translation-invariant measurements GNC-TLS kept.
    pub rotation_inliers: usize,
    /// Pruned correspondences within the translation bound on every axis.
    pub final_inliers: usize,
    /// Final inliers of the strongest distinct alignment among the correspondences the best one leaves
    /// out ([`crate::rival`]); 0 when there is none.
    pub rival_inliers: usize,
    /// With `max_clique` pruning: whether the clique was proven maximum within the node budget.
    pub clique_proven: Option<bool>,
    /// Why the result is not valid; `None` when it is.
    pub invalid_reason: Option<String>,
    pub timings: StageTimings,
}

impl KissMatcherReport {
    fn new() -> Self {
        Self {
            alignment: CoarseAlignment {
                target_from_source: Pose::identity(),
                inlier_count: 0,
                correspondence_count: 0,
                rival_inlier_count: 0,
                valid: false,
            },
            target_points: 0,
            source_points: 0,
            target_keypoints: 0,
            source_keypoints: 0,
            correspondences: 0,
            pruned: 0,
            rotation_inliers: 0,
            final_inliers: 0,
            rival_inliers: 0,
            clique_proven: None,
            invalid_reason: None,
            timings: StageTimings::default(),
        }
    }

    fn invalid(mut self, start: Instant, reason: String) -> Self {
        self.alignment.valid = false;
        self.invalid_reason = Some(reason);
        self.timings.total_s = start.elapsed().as_secs_f64();
        self
    }
}

/// Runs the pipeline on the current rayon pool. The clouds must be finite (the caller checks).
pub(crate) fn run(
    config: &KissMatcherConfig,
    target: CloudView<'_>,
    source: CloudView<'_>,
) -> KissMatcherReport {
    let start = Instant::now();
    let mut report = KissMatcherReport::new();
    let voxel_m = config.voxel_size_m as f32;
    let min_points = config.min_inliers.max(3);

    let (target_points, source_points) = rayon::join(
        || voxel_sample(target, voxel_m, config.voxel_sampling),
        || voxel_sample(source, voxel_m, config.voxel_sampling),
    );
    report.target_points = target_points.len();
    report.source_points = source_points.len();
    report.timings.voxel_s = start.elapsed().as_secs_f64();
    for (what, count) in [("target", target_points.len()), ("source", source_points.len())] {
        if count < min_points {
            let reason = format!(
                "{what} cloud: {count} points after {voxel_m} m voxel sampling, at least {min_points} needed"
            );
            return report.invalid(start, reason);
        }
    }

    // Keyframe clouds are in the sensor frame, so normals are oriented towards the origin.
    let stage = Instant::now();
    let params = config.feature_params();
    let viewpoint = Vector3::zeros();
    let (target_features, source_features) = rayon::join(
        || compute_features(&target_points, &viewpoint, &params),
        || compute_features(&source_points, &viewpoint, &params),
    );
    report.target_keypoints = target_features.len();
    report.source_keypoints = source_features.len();
    report.timings.features_s = stage.elapsed().as_secs_f64();
    for (what, count) in [
        ("target", target_features.len()),
        ("source", source_features.len()),
    ] {
        if count < min_points {
            let reason = format!(
                "{what} cloud: {count} Faster-PFH keypoints, at least {min_points} needed (featureless, too sparse or degenerate geometry)"
            );
            return report.invalid(start, reason);
        }
    }

    let stage = Instant::now();
    let matches = match_descriptors(
        &source_features.descriptors,
        &target_features.descriptors,
        &config.match_params(),
    );
    report.correspondences = matches.len();
    report.alignment.correspondence_count = matches.len();
    report.timings.matching_s = stage.elapsed().as_secs_f64();
    if matches.len() < 2 {
        let reason = format!(
            "{} correspondences after descriptor matching, at least 2 needed",
            matches.len()
        );
        return report.invalid(start, reason);
    }

    let stage = Instant::now();
    let (matched_source, matched_target) = matched_points(&matches, &source_features, &target_features);
    let graph = ConsistencyGraph::build(
        &matched_source,
        &matched_target,
        config.noise_bound_m(config.pruning_noise_bound_gain),
    );
    let kept = match config.pruning {
        PruningMode::MaxCore => graph.max_core(),
        PruningMode::MaxClique => {
            let (clique, proven) = graph.max_clique(config.max_clique_node_limit);
            report.clique_proven = Some(proven);
            clique
        }
    };
    let pruned_source: Vec<Vector3<f64>> = kept.iter().map(|&k| matched_source[k]).collect();
    let pruned_target: Vec<Vector3<f64>> = kept.iter().map(|&k| matched_target[k]).collect();
    report.pruned = kept.len();
    report.timings.pruning_s = stage.elapsed().as_secs_f64();
    // The solver needs two correspondences; with fewer than `min_inliers` the result is still solved
    // (as the reference does) and handed back, marked invalid by the final-inlier test below, so a
    // caller that refines invalid alignments starts from the best estimate there is.
    if kept.len() < 2 {
        let reason = format!(
            "{} mutually consistent correspondences after pruning, at least 2 needed",
            kept.len()
        );
        return report.invalid(start, reason);
    }

    let stage = Instant::now();
    let Some((target_from_source, rotation_inliers, inliers)) = solve(config, &pruned_source, &pruned_target)
    else {
        return report.invalid(
            start,
            "the robust solver found no finite rotation and translation".into(),
        );
    };
    report.rotation_inliers = rotation_inliers;
    report.final_inliers = inliers;
    report.alignment.target_from_source = target_from_source;
    report.alignment.inlier_count = inliers;
    report.timings.solver_s = stage.elapsed().as_secs_f64();
    if rotation_inliers < 2 {
        return report.invalid(
            start,
            format!("GNC-TLS kept {rotation_inliers} rotation measurements, at least 2 needed"),
        );
    }
    if inliers < config.min_inliers {
        let reason = format!("{inliers} final inliers, at least {} needed", config.min_inliers);
        return report.invalid(start, reason);
    }
    let stage = Instant::now();
    report.rival_inliers =
        crate::rival::rival_inliers(config, &matched_source, &matched_target, &target_from_source);
    report.alignment.rival_inlier_count = report.rival_inliers;
    report.timings.rival_s = stage.elapsed().as_secs_f64();
    report.alignment.valid = true;
    report.timings.total_s = start.elapsed().as_secs_f64();
    report
}
