//! Global and fine registration as the SKiD-SLAM paper evaluates it (Kim et al., "SKiD-SLAM";
//! KISS-Matcher, Lim et al., ICRA 2025; GICP, Segal et al., RSS 2009), shared by the
//! `registration-coarse`, `table2-registration` and `fig-yaw-sweep` profiles: the plugins under test
//! built through the registry as the runtime builds them, each method run on a pair with its wall and
//! CPU time, and the paper's success test (translation < 2 m and rotation < 5°).

pub mod pairs;
pub mod reference;
pub mod sim;
pub mod sweep;

use std::time::Instant;

use anyhow::{Result, bail};
use serde::Serialize;
use skid_core::slots::{CoarseRegistration, FineRegistration};
use skid_core::{Cloud, Params, PluginContext, Pose, Registry};
use skid_eval::registration::{RegistrationPair, RegistrationThresholds, registration_stats};
use skid_geometry::voxel_downsample;
use skid_verifier_pcm::free_space::FreeSpaceConfig;

/// Every method name the registration profiles know.
pub const METHOD_NAMES: [&str; 10] = [
    "ICP",
    "PLANE-ICP",
    "GICP",
    "V-GICP",
    "KISS-Matcher",
    "KISS-Matcher + GICP",
    PEER_CLOUD_METHOD,
    "RANSAC",
    "RANSAC + GICP",
    "GICP (identity)",
];

/// SKiD's default pair on the target cloud as a peer receives it: quantised to `loops.cloud_grid_m`
/// (the runtime's default) and decoded, as every inter-robot candidate's cloud travels.
pub const PEER_CLOUD_METHOD: &str = "KISS-Matcher + GICP (peer cloud)";

/// `cloud` as a peer receives it: through the wire's quantisation at the runtime's default grid.
pub fn as_peer_receives(cloud: &Cloud) -> Result<Cloud> {
    let grid_m = skid_config::LoopsSection::default().cloud_grid_m as f32;
    let finite: Vec<_> = cloud.points.iter().filter(|p| p.is_finite()).copied().collect();
    let packed = skid_protocol::CompressedPoints::encode(&finite, grid_m, false)?;
    Ok(Cloud::new(packed.decode()?))
}

/// One summary row: a method on a set of pairs.
#[derive(Serialize)]
pub struct Row {
    pub data: String,
    pub method: String,
    pub pairs: usize,
    pub success_rate_percent: f64,
    /// Coarse methods: the success rate when a result whose rival alignment holds at least
    /// [`REPORTED_RIVAL_RATIO`] of its inliers counts as a refusal, as the runtime counts it with
    /// `loops.ambiguous_rival_ratio` set to that.
    pub unambiguous_success_percent: Option<f64>,
    /// The success rate when a result the verifier's free-space check refuses (at its defaults, on the
    /// pair's clouds at the keyframes' 0.25 m voxels) counts as a failure.
    pub free_space_success_percent: Option<f64>,
    pub rte_cm: Option<f64>,
    pub rre_deg: Option<f64>,
    pub mean_time_ms: f64,
    pub max_time_ms: f64,
    /// Mean CPU time per pair over all threads (see [`process_cpu_s`]).
    pub mean_cpu_ms: Option<f64>,
}

/// The plugins under test, built through the registry as the runtime builds them.
pub struct Methods {
    kiss: Box<dyn CoarseRegistration>,
    ransac: Box<dyn CoarseRegistration>,
    gicp: Box<dyn FineRegistration>,
    icp: Box<dyn FineRegistration>,
    plane_icp: Box<dyn FineRegistration>,
    vgicp: Box<dyn FineRegistration>,
}

impl Methods {
    /// Builds every method with its default parameters, each allowed `threads` threads.
    pub fn new(threads: usize) -> Result<Self> {
        let mut registry = Registry::new();
        skid_coarse_kiss_matcher::register(&mut registry)?;
        skid_coarse_ransac::register(&mut registry)?;
        skid_fine_gicp::register(&mut registry)?;
        let context = PluginContext {
            threads,
            ..PluginContext::default()
        };
        let fine = |variant: &str| -> Result<Box<dyn FineRegistration>> {
            let params = Params::from_toml_str(&format!("variant = \"{variant}\""))?;
            Ok(registry.fine.create("gicp", &params, &context)?)
        };
        Ok(Self {
            kiss: registry
                .coarse
                .create("kiss_matcher", &Params::default(), &context)?,
            ransac: registry.coarse.create("ransac", &Params::default(), &context)?,
            gicp: fine("gicp")?,
            icp: fine("icp")?,
            plane_icp: fine("plane_icp")?,
            vgicp: fine("vgicp")?,
        })
    }

    /// Runs the method called `name` (one of [`METHOD_NAMES`]); fine-only methods start from `prior`,
    /// except "GICP (identity)", which starts from the identity.
    pub fn run(&mut self, name: &str, target: &Cloud, source: &Cloud, prior: &Pose) -> Result<Outcome> {
        Ok(match name {
            "ICP" => fine(self.icp.as_mut(), target, source, prior),
            "PLANE-ICP" => fine(self.plane_icp.as_mut(), target, source, prior),
            "GICP" => fine(self.gicp.as_mut(), target, source, prior),
            "V-GICP" => fine(self.vgicp.as_mut(), target, source, prior),
            "KISS-Matcher" => coarse(self.kiss.as_mut(), target, source),
            "KISS-Matcher + GICP" => coarse_fine(self.kiss.as_mut(), self.gicp.as_mut(), target, source),
            PEER_CLOUD_METHOD => {
                let received = as_peer_receives(target)?;
                coarse_fine(self.kiss.as_mut(), self.gicp.as_mut(), &received, source)
            }
            "RANSAC" => coarse(self.ransac.as_mut(), target, source),
            "RANSAC + GICP" => coarse_fine(self.ransac.as_mut(), self.gicp.as_mut(), target, source),
            "GICP (identity)" => fine(self.gicp.as_mut(), target, source, &Pose::identity()),
            other => bail!(
                "unknown registration method `{other}`; methods: {}",
                METHOD_NAMES.join(", ")
            ),
        })
    }
}

/// Checks that every name is a known method.
pub fn check_methods(names: &[String]) -> Result<()> {
    for name in names {
        if !METHOD_NAMES.contains(&name.as_str()) {
            bail!(
                "unknown registration method `{name}`; methods: {}",
                METHOD_NAMES.join(", ")
            );
        }
    }
    Ok(())
}

/// An estimate (or none) and the time it took.
pub struct Outcome {
    pub estimate: Option<Pose>,
    pub valid: bool,
    /// Final inliers of a coarse method (of the coarse stage when refined); `None` for fine methods.
    pub inliers: Option<usize>,
    /// Inliers of the coarse method's rival alignment; `None` for fine methods.
    pub rival_inliers: Option<usize>,
    pub time_ms: f64,
    pub cpu_ms: Option<f64>,
}

/// The `loops.ambiguous_rival_ratio` the registration tables report the cost of (the runtime's test is
/// off by default).
pub const REPORTED_RIVAL_RATIO: f64 = 0.5;

impl Outcome {
    /// True when the runtime, with `loops.ambiguous_rival_ratio` = [`REPORTED_RIVAL_RATIO`], would refuse
    /// this result as ambiguous.
    pub fn ambiguous(&self) -> bool {
        let ratio = REPORTED_RIVAL_RATIO;
        match (self.inliers, self.rival_inliers) {
            (Some(inliers), Some(rival)) => {
                ratio > 0.0 && rival > 0 && rival as f64 >= ratio * inliers as f64
            }
            _ => false,
        }
    }
}

/// The percentage of `total` that `count` is (0 for an empty set).
pub fn percent(count: usize, total: usize) -> f64 {
    100.0 * count as f64 / total.max(1) as f64
}

/// The voxel edge keyframe clouds are kept at (what the verifier's checks see), metres.
const KEYFRAME_VOXEL_M: f32 = 0.25;

/// A pair's two clouds as the verifier's free-space check sees them: in their sensors' frames, at the
/// keyframes' voxels, judged with the check's defaults.
pub struct FreeSpaceJudge {
    config: FreeSpaceConfig,
    target_kept: Vec<skid_core::Point>,
    source_kept: Vec<skid_core::Point>,
}

impl FreeSpaceJudge {
    /// `target` and `source` in their sensors' frames.
    pub fn new(target: &Cloud, source: &Cloud) -> Self {
        Self {
            config: FreeSpaceConfig::default(),
            target_kept: voxel_downsample(&target.points, KEYFRAME_VOXEL_M),
            source_kept: voxel_downsample(&source.points, KEYFRAME_VOXEL_M),
        }
    }

    /// Whether the check refuses `estimate` (`target_from_source` between the sensors' frames); a
    /// method that gave no estimate is not refused.
    pub fn refuses(&self, estimate: Option<&Pose>) -> bool {
        estimate.is_some_and(|estimate| {
            let count = self.config.count(&self.target_kept, &self.source_kept, estimate);
            self.config.judge(&count).is_some()
        })
    }
}

/// CPU seconds (user + system, all threads) this process has used, from `/proc/self/stat` (Linux; 10 ms
/// ticks). Wall time on a shared machine counts other people's work too; CPU time divided by the threads
/// bounds what the pair would take on an idle one.
pub fn process_cpu_s() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    let fields: Vec<&str> = stat.rsplit(')').next()?.split_whitespace().collect();
    let ticks = fields.get(11)?.parse::<f64>().ok()? + fields.get(12)?.parse::<f64>().ok()?;
    Some(ticks / 100.0)
}

fn timed<T>(work: impl FnOnce() -> T) -> (T, f64, Option<f64>) {
    let (start, cpu_start) = (Instant::now(), process_cpu_s());
    let value = work();
    let time_ms = start.elapsed().as_secs_f64() * 1e3;
    let cpu_ms = cpu_start.zip(process_cpu_s()).map(|(a, b)| (b - a) * 1e3);
    (value, time_ms, cpu_ms)
}

fn coarse(method: &mut dyn CoarseRegistration, target: &Cloud, source: &Cloud) -> Outcome {
    let (result, time_ms, cpu_ms) = timed(|| method.align(target.view(), source.view(), None));
    let inliers = result.as_ref().ok().map(|a| a.inlier_count);
    let rival_inliers = result.as_ref().ok().map(|a| a.rival_inlier_count);
    Outcome {
        inliers,
        rival_inliers,
        ..outcome(
            result.map(|a| (a.target_from_source, a.valid)).ok(),
            time_ms,
            cpu_ms,
        )
    }
}

/// An outcome from an estimate and its validity (`None` = the method failed).
fn outcome(result: Option<(Pose, bool)>, time_ms: f64, cpu_ms: Option<f64>) -> Outcome {
    Outcome {
        estimate: result.map(|(pose, _)| pose),
        valid: result.is_some_and(|(_, valid)| valid),
        inliers: None,
        rival_inliers: None,
        time_ms,
        cpu_ms,
    }
}

/// Fine registration from `guess`; the time includes preparing both clouds.
fn fine(method: &mut dyn FineRegistration, target: &Cloud, source: &Cloud, guess: &Pose) -> Outcome {
    let (result, time_ms, cpu_ms) = timed(|| {
        method
            .prepare(target.view())
            .and_then(|t| method.prepare(source.view()).map(|s| (t, s)))
            .and_then(|(t, s)| method.refine(&t, &s, guess))
    });
    outcome(
        result.map(|a| (a.target_from_source, a.converged)).ok(),
        time_ms,
        cpu_ms,
    )
}

/// Coarse, then fine from the coarse estimate (from the identity when the coarse stage gave nothing).
fn coarse_fine(
    coarse_method: &mut dyn CoarseRegistration,
    fine_method: &mut dyn FineRegistration,
    target: &Cloud,
    source: &Cloud,
) -> Outcome {
    let first = coarse(coarse_method, target, source);
    let guess = first.estimate.unwrap_or_else(Pose::identity);
    let second = fine(fine_method, target, source, &guess);
    Outcome {
        time_ms: first.time_ms + second.time_ms,
        cpu_ms: first.cpu_ms.zip(second.cpu_ms).map(|(a, b)| a + b),
        inliers: first.inliers,
        rival_inliers: first.rival_inliers,
        ..second
    }
}

/// Translation error (m), rotation error (°) and the paper's success test (< 2 m and < 5°).
pub fn pose_errors(estimate: &Option<Pose>, truth: &Pose) -> (Option<f64>, Option<f64>, bool) {
    let Some(estimate) = estimate else {
        return (None, None, false);
    };
    let translation_m = (truth.translation.vector - estimate.translation.vector).norm();
    let rotation_deg = (estimate.rotation.inverse() * truth.rotation)
        .angle()
        .to_degrees();
    let success = translation_m < 2.0 && rotation_deg < 5.0;
    (Some(translation_m), Some(rotation_deg), success)
}

/// Mean of `values`, `None` when empty.
pub fn mean(values: &[f64]) -> Option<f64> {
    (!values.is_empty()).then(|| values.iter().sum::<f64>() / values.len() as f64)
}

/// The summary row of one method on `pairs` (RTE/RRE/success from skid-eval).
pub fn summary(
    data: &str,
    method: &str,
    pairs: &[RegistrationPair],
    times_ms: &[f64],
    cpu_ms: &[f64],
) -> Result<Row> {
    let stats = registration_stats(pairs, &RegistrationThresholds::default())?;
    Ok(Row {
        data: data.to_owned(),
        method: method.to_owned(),
        pairs: stats.pairs,
        success_rate_percent: 100.0 * stats.success_rate,
        unambiguous_success_percent: None,
        free_space_success_percent: None,
        rte_cm: stats.rte_cm,
        rre_deg: stats.rre_deg,
        mean_time_ms: times_ms.iter().sum::<f64>() / times_ms.len().max(1) as f64,
        max_time_ms: times_ms.iter().copied().fold(0.0, f64::max),
        mean_cpu_ms: mean(cpu_ms),
    })
}

/// The note under a registration table.
pub const REGISTRATION_NOTE: &str = "Success: translation error < 2 m and rotation error < 5°; RTE and RRE average the successes only. Times are wall-clock per pair on the given threads and include feature extraction (coarse) and preparing both clouds (fine); `mean_cpu_ms` is the process CPU time per pair over all threads (10 ms ticks), which other load on the machine does not inflate. \"GICP (identity)\" starts from the identity.";
