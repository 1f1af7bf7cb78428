//! SKiD coarse registration: KISS-Matcher (Lim et al., "KISS-Matcher: Fast and Robust Point Cloud
//! Registration Revisited", ICRA 2025), the default `[coarse] plugin = "kiss_matcher"` of SKiD-SLAM.
//!
//! Pipeline (each stage in its own module, parameters in [`KissMatcherConfig`], defaults from the paper
//! and the reference library):
//! 1. voxel sampling at v = 0.3 m (each voxel's centroid, as the reference samples; deterministic);
//! 2. [`features`]: Faster-PFH — one radius search per point at 5v, PCA normals within 3v oriented to the
//!    sensor (the cloud frame's origin), 33-bin histograms;
//! 3. [`matching`]: mutual nearest neighbours in descriptor space, squared-distance cap 900, ratio test
//!    0.9, at most 5,000 correspondences;
//! 4. [`pruning`]: pairwise-consistency graph with bound 1.0v, inliers = maximum k-core (or the exact
//!    maximum clique);
//! 5. [`solver`]: GNC-TLS rotation on the chain of translation-invariant measurements (bound 2 × 0.75v;
//!    factor 1.4, 100 iterations, cost threshold 0.005), component-wise TLS translation (bound 0.75v);
//!    noise bounds clamped to at most 1 m;
//! 6. valid when at least 5 final (translation) inliers remain;
//! 7. [`rival`]: the correspondences the result leaves out are pruned and solved again, and the
//!    strongest distinct alignment's inlier count is reported (the host refuses ambiguous places).
//!
//! The feature and matching modules are public so the RANSAC baseline shares them. The `prior` of
//! [`CoarseRegistration::align`] is ignored: KISS-Matcher is global.

pub mod features;
pub mod front;
pub mod kdtree;
pub mod matching;
mod pipeline;
pub mod pruning;
pub mod rival;
pub mod solver;

use serde::{Deserialize, Serialize};
use skid_core::slots::{CoarseAlignment, CoarseRegistration};
use skid_core::{
    CloudView, ParamError, PluginContext, PluginEntry, PluginError, PluginResult, Pose, Registry,
};

pub use features::VoxelSampling;
pub use pipeline::{KissMatcherReport, StageTimings};

/// The plugin's name in the coarse slot.
pub const PLUGIN_NAME: &str = "kiss_matcher";

/// Which dense subgraph of the consistency graph is kept as inliers.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum PruningMode {
    /// The maximum k-core (the default: fast, and no worse in the authors' experiments).
    MaxCore,
    /// The exact maximum clique (branch and bound, stopped after `max_clique_node_limit` nodes).
    MaxClique,
}

/// Parameters of `kiss_matcher`; `Default` holds the reference values.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct KissMatcherConfig {
    /// Voxel size v of the sampling, in metres; the radii and noise bounds scale with it.
    pub voxel_size_m: f64,
    /// `centroid` (the reference's sampling) or `first_point` of each voxel.
    pub voxel_sampling: VoxelSampling,
    /// Normals, FPFH descriptors and their matching (`[coarse.kiss_matcher.fpfh]`), radii in multiples
    /// of v.
    pub fpfh: front::FpfhConfig<front::KissMatcherDefaults>,
    pub pruning: PruningMode,
    /// Branch-and-bound node budget of the exact maximum clique.
    pub max_clique_node_limit: u64,
    /// Pairwise-consistency bound as a multiple of v.
    pub pruning_noise_bound_gain: f64,
    /// Solver noise bound as a multiple of v (translation; doubled for rotation measurements).
    pub solver_noise_bound_gain: f64,
    /// Noise bounds are clamped to at most this many metres; 0 disables the clamp.
    pub max_noise_bound_m: f64,
    /// GNC: growth factor of μ.
    pub gnc_factor: f64,
    pub gnc_max_iterations: usize,
    pub gnc_cost_threshold: f64,
    /// Fewest final inliers for a valid result.
    pub min_inliers: usize,
}

impl Default for KissMatcherConfig {
    fn default() -> Self {
        Self {
            voxel_size_m: 0.3,
            voxel_sampling: VoxelSampling::Centroid,
            fpfh: front::FpfhConfig::default(),
            pruning: PruningMode::MaxCore,
            max_clique_node_limit: 1_000_000,
            pruning_noise_bound_gain: 1.0,
            solver_noise_bound_gain: 0.75,
            max_noise_bound_m: 1.0,
            gnc_factor: 1.4,
            gnc_max_iterations: 100,
            gnc_cost_threshold: 0.005,
            min_inliers: 5,
        }
    }
}

impl KissMatcherConfig {
    /// Checks every value; the error names the offending key.
    pub fn validate(&self) -> Result<(), ParamError> {
        front::check_voxel_size(self.voxel_size_m)?;
        self.fpfh.validate().map_err(|error| error.in_table("fpfh"))?;
        for (value, key) in [
            (self.pruning_noise_bound_gain, "pruning_noise_bound_gain"),
            (self.solver_noise_bound_gain, "solver_noise_bound_gain"),
            (self.gnc_cost_threshold, "gnc_cost_threshold"),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(ParamError::at(
                    key,
                    format!("must be a positive number, got {value}"),
                ));
            }
        }
        if !(self.max_noise_bound_m.is_finite() && self.max_noise_bound_m >= 0.0) {
            return Err(ParamError::at(
                "max_noise_bound_m",
                format!("must be 0 or positive, got {}", self.max_noise_bound_m),
            ));
        }
        if !(self.gnc_factor.is_finite() && self.gnc_factor > 1.0) {
            return Err(ParamError::at(
                "gnc_factor",
                format!("must be greater than 1, got {}", self.gnc_factor),
            ));
        }
        if self.gnc_max_iterations == 0 {
            return Err(ParamError::at("gnc_max_iterations", "must be at least 1"));
        }
        Ok(())
    }

    /// A noise bound of `gain` × v, clamped to `max_noise_bound_m` when that is set.
    pub fn noise_bound_m(&self, gain: f64) -> f64 {
        let bound = gain * self.voxel_size_m;
        if self.max_noise_bound_m > 0.0 {
            bound.min(self.max_noise_bound_m)
        } else {
            bound
        }
    }

    /// The feature-extraction settings in metres.
    pub fn feature_params(&self) -> features::FeatureParams {
        self.fpfh.feature_params(self.voxel_size_m)
    }

    /// The matching settings.
    pub fn match_params(&self) -> matching::MatchParams {
        self.fpfh.match_params()
    }
}

/// Registers `kiss_matcher` in the coarse slot.
pub fn register(registry: &mut Registry) -> Result<(), PluginError> {
    let entry = PluginEntry::new(
        PLUGIN_NAME,
        "KISS-Matcher global registration: Faster-PFH, mutual matching, k-core pruning, GNC-TLS (Lim et al., ICRA 2025)",
        |config: KissMatcherConfig, context: &PluginContext| {
            Ok(Box::new(KissMatcher::from_checked(config, context)?) as Box<dyn CoarseRegistration>)
        },
    )?;
    registry.coarse.register(entry)
}

/// Builds the rayon pool a plugin runs on: `threads` workers (at least one), nothing beyond.
pub fn thread_pool(plugin: &str, threads: usize) -> PluginResult<rayon::ThreadPool> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads.max(1))
        .thread_name(move |i| format!("skid-coarse-{i}"))
        .build()
        .map_err(|e| PluginError::failed(plugin, format!("cannot start {threads} worker threads: {e}")))
}

/// The plugin state: its configuration, its thread pool and the report of the last alignment.
pub struct KissMatcher {
    config: KissMatcherConfig,
    pool: rayon::ThreadPool,
    last_report: Option<KissMatcherReport>,
}

impl KissMatcher {
    pub fn new(config: KissMatcherConfig, context: &PluginContext) -> PluginResult<Self> {
        Self::from_checked(skid_core::registry::check::checked(PLUGIN_NAME, config)?, context)
    }

    /// [`KissMatcher::new`] for a configuration the registry has checked already (it is checked once, when
    /// the configuration is loaded).
    pub(crate) fn from_checked(config: KissMatcherConfig, context: &PluginContext) -> PluginResult<Self> {
        Ok(Self {
            pool: thread_pool(PLUGIN_NAME, context.threads)?,
            config,
            last_report: None,
        })
    }

    pub fn config(&self) -> &KissMatcherConfig {
        &self.config
    }

    /// Aligns `source` to `target` and returns the full report: every stage's counts and times, and why
    /// the result is invalid when it is. Non-finite points are an error.
    pub fn align_with_report(
        &mut self,
        target: CloudView<'_>,
        source: CloudView<'_>,
    ) -> PluginResult<KissMatcherReport> {
        target.ensure_usable("target cloud", 0)?;
        source.ensure_usable("source cloud", 0)?;
        let config = &self.config;
        let report = self.pool.install(|| pipeline::run(config, target, source));
        self.last_report = Some(report.clone());
        Ok(report)
    }

    /// The report of the last successful call to `align`, if any.
    pub fn last_report(&self) -> Option<&KissMatcherReport> {
        self.last_report.as_ref()
    }
}

impl CoarseRegistration for KissMatcher {
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

impl skid_core::PluginParams for KissMatcherConfig {
    fn check(&self) -> Result<(), skid_core::ParamError> {
        self.validate()
    }
}

#[cfg(test)]
mod tests;
