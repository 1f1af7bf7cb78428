//! SKiD coarse registration baseline `[coarse] plugin = "ransac"`: FPFH features (Rusu et al., "Fast Point
//! Feature Histograms for 3D Registration", ICRA 2009) matched in descriptor space, then RANSAC (Fischler
//! & Bolles, CACM 1981) with an edge-length pre-check — the classic global registration that KISS-Matcher
//! (Lim et al., ICRA 2025) is compared against.
//!
//! Voxel sampling (voxel centroids, as Open3D's baseline pipeline samples), features and matching are
//! KISS-Matcher's shared modules
//! ([`skid_coarse_kiss_matcher::features`], [`skid_coarse_kiss_matcher::matching`]); only the estimator
//! differs. The defaults follow the usual baseline set-up: mutual nearest neighbours without a ratio
//! test or cap, inlier distance 1.5 v, edge similarity 0.9, up to 100,000 draws at 0.999 confidence.
//! The `prior` of [`CoarseRegistration::align`] is ignored.

pub mod ransac;

use std::time::Instant;

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use skid_coarse_kiss_matcher::features::{VoxelSampling, compute_features, voxel_sample};
use skid_coarse_kiss_matcher::front::{BaselineDefaults, FpfhConfig, check_voxel_size};
use skid_coarse_kiss_matcher::matching::{match_descriptors, matched_points};
use skid_coarse_kiss_matcher::thread_pool;
use skid_core::slots::{CoarseAlignment, CoarseRegistration};
use skid_core::{
    CloudView, ParamError, PluginContext, PluginEntry, PluginError, PluginResult, Pose, Registry,
};

use crate::ransac::{RansacParams, ransac};

/// The plugin's name in the coarse slot.
pub const PLUGIN_NAME: &str = "ransac";

/// Parameters of `ransac`; `Default` holds the reference values.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct RansacConfig {
    /// Voxel size v of the sampling, in metres.
    pub voxel_size_m: f64,
    /// Normals, FPFH descriptors and their matching (`[coarse.ransac.fpfh]`), radii in multiples of v;
    /// KISS-Matcher's front with the baseline's matching defaults.
    pub fpfh: FpfhConfig<BaselineDefaults>,
    /// Inlier distance as a multiple of v.
    pub inlier_distance_gain: f64,
    /// Edge-length similarity of a drawn triangle between the two clouds.
    pub edge_length_similarity: f64,
    pub max_iterations: usize,
    pub confidence: f64,
    /// Refits on the inliers after the search.
    pub refine_rounds: usize,
    /// Fewest inliers for a valid result.
    pub min_inliers: usize,
}

impl Default for RansacConfig {
    fn default() -> Self {
        Self {
            voxel_size_m: 0.3,
            fpfh: FpfhConfig::default(),
            inlier_distance_gain: 1.5,
            edge_length_similarity: 0.9,
            max_iterations: 100_000,
            confidence: 0.999,
            refine_rounds: 3,
            min_inliers: 5,
        }
    }
}

impl RansacConfig {
    /// Checks every value; the error names the offending key.
    pub fn validate(&self) -> Result<(), ParamError> {
        check_voxel_size(self.voxel_size_m)?;
        self.fpfh.validate().map_err(|error| error.in_table("fpfh"))?;
        if !(self.inlier_distance_gain.is_finite() && self.inlier_distance_gain > 0.0) {
            return Err(ParamError::at(
                "inlier_distance_gain",
                format!("must be a positive number, got {}", self.inlier_distance_gain),
            ));
        }
        if !(0.0..=1.0).contains(&self.edge_length_similarity) {
            return Err(ParamError::at(
                "edge_length_similarity",
                format!("must lie in [0, 1], got {}", self.edge_length_similarity),
            ));
        }
        if !(self.confidence > 0.0 && self.confidence < 1.0) {
            return Err(ParamError::at(
                "confidence",
                format!("must lie in (0, 1), got {}", self.confidence),
            ));
        }
        if self.max_iterations == 0 {
            return Err(ParamError::at("max_iterations", "must be at least 1"));
        }
        Ok(())
    }
}

/// Registers `ransac` in the coarse slot.
pub fn register(registry: &mut Registry) -> Result<(), PluginError> {
    let entry = PluginEntry::new(
        PLUGIN_NAME,
        "FPFH + RANSAC global registration, the classic baseline (Rusu et al., ICRA 2009)",
        |config: RansacConfig, context: &PluginContext| {
            Ok(Box::new(RansacMatcher::from_checked(config, context)?) as Box<dyn CoarseRegistration>)
        },
    )?;
    registry.coarse.register(entry)
}

/// Everything one alignment found out.
#[derive(Clone, Debug)]
pub struct RansacReport {
    pub alignment: CoarseAlignment,
    /// Points after voxel sampling (target, source).
    pub points: (usize, usize),
    /// Points with a descriptor (target, source).
    pub keypoints: (usize, usize),
    pub iterations: usize,
    /// Why the result is not valid; `None` when it is.
    pub invalid_reason: Option<String>,
    pub total_s: f64,
}

/// The plugin state.
pub struct RansacMatcher {
    config: RansacConfig,
    seed: u64,
    pool: rayon::ThreadPool,
}

impl RansacMatcher {
    pub fn new(config: RansacConfig, context: &PluginContext) -> PluginResult<Self> {
        Self::from_checked(skid_core::registry::check::checked(PLUGIN_NAME, config)?, context)
    }

    /// [`RansacMatcher::new`] for a configuration the registry has checked already (it is checked once, when
    /// the configuration is loaded).
    pub(crate) fn from_checked(config: RansacConfig, context: &PluginContext) -> PluginResult<Self> {
        Ok(Self {
            pool: thread_pool(PLUGIN_NAME, context.threads)?,
            seed: context.seed ^ (u64::from(context.robot.0) << 32) ^ 0x7261_6e73,
            config,
        })
    }

    /// Aligns `source` to `target` with the full report. Non-finite points are an error.
    pub fn align_with_report(
        &mut self,
        target: CloudView<'_>,
        source: CloudView<'_>,
    ) -> PluginResult<RansacReport> {
        target.ensure_usable("target cloud", 0)?;
        source.ensure_usable("source cloud", 0)?;
        let (config, seed) = (&self.config, self.seed);
        Ok(self.pool.install(|| run(config, seed, target, source)))
    }
}

impl CoarseRegistration for RansacMatcher {
    fn align(
        &mut self,
        target: CloudView<'_>,
        source: CloudView<'_>,
        _prior: Option<&Pose>,
    ) -> PluginResult<CoarseAlignment> {
        self.align_with_report(target, source)
            .map(|report| report.alignment)
    }
}

fn run(config: &RansacConfig, seed: u64, target: CloudView<'_>, source: CloudView<'_>) -> RansacReport {
    let start = Instant::now();
    let mut report = RansacReport {
        alignment: CoarseAlignment {
            target_from_source: Pose::identity(),
            inlier_count: 0,
            correspondence_count: 0,
            rival_inlier_count: 0,
            valid: false,
        },
        points: (0, 0),
        keypoints: (0, 0),
        iterations: 0,
        invalid_reason: None,
        total_s: 0.0,
    };
    let finish = |mut report: RansacReport, reason: Option<String>| {
        report.alignment.valid = reason.is_none();
        report.invalid_reason = reason;
        report.total_s = start.elapsed().as_secs_f64();
        report
    };
    let voxel_m = config.voxel_size_m as f32;
    let (target_points, source_points) = rayon::join(
        || voxel_sample(target, voxel_m, VoxelSampling::Centroid),
        || voxel_sample(source, voxel_m, VoxelSampling::Centroid),
    );
    report.points = (target_points.len(), source_points.len());
    let params = config.fpfh.feature_params(config.voxel_size_m);
    let (target_features, source_features) = rayon::join(
        || compute_features(&target_points, &Vector3::zeros(), &params),
        || compute_features(&source_points, &Vector3::zeros(), &params),
    );
    report.keypoints = (target_features.len(), source_features.len());
    let matches = match_descriptors(
        &source_features.descriptors,
        &target_features.descriptors,
        &config.fpfh.match_params(),
    );
    report.alignment.correspondence_count = matches.len();
    let needed = config.min_inliers.max(3);
    if matches.len() < needed {
        let reason = format!(
            "{} correspondences from {} target and {} source keypoints ({} and {} points after {voxel_m} m voxel sampling), at least {needed} needed",
            matches.len(),
            report.keypoints.0,
            report.keypoints.1,
            report.points.0,
            report.points.1
        );
        return finish(report, Some(reason));
    }
    let (matched_source, matched_target) = matched_points(&matches, &source_features, &target_features);
    let params = RansacParams {
        inlier_distance_m: config.inlier_distance_gain * config.voxel_size_m,
        edge_length_similarity: config.edge_length_similarity,
        max_iterations: config.max_iterations,
        confidence: config.confidence,
        refine_rounds: config.refine_rounds,
        seed,
    };
    let Some(result) = ransac(&matched_source, &matched_target, &params) else {
        return finish(
            report,
            Some("no RANSAC draw passed the edge-length and distance checks".into()),
        );
    };
    report.iterations = result.iterations;
    report.alignment.target_from_source = result.target_from_source;
    report.alignment.inlier_count = result.inlier_count;
    report.alignment.rival_inlier_count = rival_inliers(
        &matched_source,
        &matched_target,
        &result.target_from_source,
        &params,
    );
    let reason = (result.inlier_count < config.min_inliers).then(|| {
        format!(
            "{} inliers, at least {} needed",
            result.inlier_count, config.min_inliers
        )
    });
    finish(report, reason)
}

/// The second-best hypothesis test (as KISS-Matcher's, [`skid_coarse_kiss_matcher::rival`]): RANSAC
/// again on the correspondences the best alignment leaves out (residual beyond twice the inlier
/// distance), with another seed; the rival's inliers when it is a distinct alignment, else 0.
fn rival_inliers(
    source: &[Vector3<f64>],
    target: &[Vector3<f64>],
    best: &Pose,
    params: &RansacParams,
) -> usize {
    let explained_m = 2.0 * params.inlier_distance_m;
    let (left_source, left_target) =
        skid_coarse_kiss_matcher::rival::unexplained(source, target, best, explained_m);
    if left_source.len() < 3 {
        return 0;
    }
    let params = RansacParams {
        seed: params.seed ^ 0x5bd1_e995,
        ..*params
    };
    match ransac(&left_source, &left_target, &params) {
        Some(rival) if skid_coarse_kiss_matcher::rival::distinct(best, &rival.target_from_source) => {
            rival.inlier_count
        }
        _ => 0,
    }
}

impl skid_core::PluginParams for RansacConfig {
    fn check(&self) -> Result<(), skid_core::ParamError> {
        self.validate()
    }
}

#[cfg(test)]
mod tests;
