//! The SKiD-SLAM paper's scan-level registration table on simulated pairs (`skid-sim`, see [`pairs`]):
//! per world and pair kind, every method's RTE, RRE and success rate, the final inliers of the coarse
//! methods, and the reference KISS-Matcher (Python `kiss-matcher`) on the same pairs as its own row.
//! Fine-only methods start from an odometry-like prior (the truth off by a fixed-seed error of up to
//! `prior_translation_m` horizontally and `prior_yaw_deg` in yaw); coarse methods need no prior.
//!
//! [`pairs`]: super::pairs

use anyhow::Result;
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use skid_core::Pose;
use skid_eval::registration::RegistrationPair;
use skid_sim::WorldKind;

use super::pairs::{PairGeometry, PairKind, SimPair, sim_pairs, unit_hash};
use super::reference::{REFERENCE_NAME, reference_kiss_matcher};
use super::{FreeSpaceJudge, METHOD_NAMES, Methods, check_methods, percent, pose_errors, summary};
use crate::Report;

/// Parameters of the simulated table.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SimTableSettings {
    /// Threads every plugin may use.
    pub threads: usize,
    /// `planetary`, `cave`, `urban`.
    pub worlds: Vec<String>,
    pub sensor: String,
    /// Pairs per world and pair kind.
    pub pairs_per_kind: usize,
    pub pair_kinds: Vec<PairKind>,
    pub geometry: PairGeometry,
    pub seed: u64,
    /// Error of the fine methods' prior: up to this much horizontally, metres ...
    pub prior_translation_m: f64,
    /// ... and this much in yaw, degrees.
    pub prior_yaw_deg: f64,
    pub methods: Vec<String>,
    /// Run the reference KISS-Matcher (Python `kiss-matcher`) on the same pairs.
    pub reference: bool,
    /// The reference's voxel size (its examples' 0.3 m, the same as SKiD's default).
    pub reference_voxel_m: f64,
}

impl Default for SimTableSettings {
    fn default() -> Self {
        Self {
            threads: 2,
            worlds: ["planetary", "cave", "urban"].map(str::to_owned).to_vec(),
            sensor: "os1-64".to_owned(),
            pairs_per_kind: 4,
            pair_kinds: PairKind::ALL.to_vec(),
            geometry: PairGeometry::default(),
            seed: 7,
            prior_translation_m: 1.5,
            prior_yaw_deg: 20.0,
            // Every method but those the paper's table leaves out (RANSAC alone, GICP from the identity).
            methods: METHOD_NAMES
                .iter()
                .filter(|name| !matches!(**name, "RANSAC" | "GICP (identity)"))
                .map(|name| (*name).to_owned())
                .collect(),
            reference: true,
            reference_voxel_m: 0.3,
        }
    }
}

/// One method on one pair.
#[derive(Clone, Debug, Serialize)]
pub struct PairResult {
    pub world: String,
    pub kind: PairKind,
    pub anchor: usize,
    pub method: String,
    pub translation_error_m: Option<f64>,
    pub rotation_error_deg: Option<f64>,
    pub success: bool,
    pub valid: bool,
    /// Final inliers of a coarse method (of its coarse stage when refined).
    pub inliers: Option<usize>,
    /// Inliers of the coarse method's rival alignment (see `CoarseAlignment::rival_inlier_count`).
    pub rival_inliers: Option<usize>,
    /// A coarse result the runtime would refuse as ambiguous (its rival alignment nearly as strong).
    pub ambiguous: bool,
    /// A result the verifier's free-space check refuses: the clouds it aligns see through each other.
    pub free_space_refused: bool,
    pub time_ms: f64,
    pub cpu_ms: Option<f64>,
    #[serde(skip)]
    pub estimate: Option<Pose>,
    #[serde(skip)]
    pub truth: Pose,
}

/// The prior a fine-only method starts from on pair `index`: the truth off by a fixed-seed error.
fn prior_for(settings: &SimTableSettings, index: usize, truth: &Pose) -> Pose {
    let signed = |salt: u64| 2.0 * unit_hash(index, salt) - 1.0;
    truth
        * Pose::new(
            Vector3::new(
                settings.prior_translation_m * signed(1),
                settings.prior_translation_m * signed(2),
                0.0,
            ),
            Vector3::z() * settings.prior_yaw_deg.to_radians() * signed(3),
        )
}

fn result_for(world: WorldKind, pair: &SimPair, method: &str) -> PairResult {
    PairResult {
        world: world.to_string(),
        kind: pair.kind,
        anchor: pair.anchor,
        method: method.to_owned(),
        translation_error_m: None,
        rotation_error_deg: None,
        success: false,
        valid: false,
        inliers: None,
        rival_inliers: None,
        ambiguous: false,
        free_space_refused: false,
        time_ms: 0.0,
        cpu_ms: None,
        estimate: None,
        truth: pair.truth,
    }
}

/// Runs every method (and the reference) on one world's pairs.
fn world_results(
    methods: &mut Methods,
    settings: &SimTableSettings,
    world: WorldKind,
) -> Result<Vec<PairResult>> {
    let pairs = sim_pairs(
        world,
        &settings.sensor,
        settings.pairs_per_kind,
        settings.seed,
        &settings.pair_kinds,
        &settings.geometry,
    )?;
    let mut results = Vec::new();
    for (index, pair) in pairs.iter().enumerate() {
        let prior = prior_for(settings, index, &pair.truth);
        let free_space = FreeSpaceJudge::new(&pair.target, &pair.source);
        for method in &settings.methods {
            let outcome = methods.run(method, &pair.target, &pair.source, &prior)?;
            let (translation, rotation, success) = pose_errors(&outcome.estimate, &pair.truth);
            results.push(PairResult {
                translation_error_m: translation,
                rotation_error_deg: rotation,
                success,
                valid: outcome.valid,
                inliers: outcome.inliers,
                rival_inliers: outcome.rival_inliers,
                ambiguous: outcome.ambiguous(),
                free_space_refused: free_space.refuses(outcome.estimate.as_ref()),
                time_ms: outcome.time_ms,
                cpu_ms: outcome.cpu_ms,
                estimate: outcome.estimate,
                ..result_for(world, pair, method)
            });
        }
        eprintln!("{world}: pair {index} ({}) done", pair.kind.label());
    }
    if settings.reference {
        let clouds: Vec<_> = pairs.iter().map(|p| (&p.target, &p.source)).collect();
        if let Some(outcomes) = reference_kiss_matcher(&clouds, settings.reference_voxel_m)? {
            for (pair, outcome) in pairs.iter().zip(outcomes) {
                let (translation, rotation, success) = pose_errors(&Some(outcome.estimate), &pair.truth);
                results.push(PairResult {
                    translation_error_m: translation,
                    rotation_error_deg: rotation,
                    success,
                    valid: outcome.valid,
                    inliers: Some(outcome.final_inliers),
                    time_ms: outcome.time_ms,
                    estimate: Some(outcome.estimate),
                    ..result_for(world, pair, REFERENCE_NAME)
                });
            }
        }
    }
    Ok(results)
}

/// The summary row of `method` over the results that pass `keep`, labelled `data`.
fn push_summary(
    report: &mut Report,
    data: &str,
    method: &str,
    results: &[PairResult],
    keep: &dyn Fn(&PairResult) -> bool,
) -> Result<()> {
    let chosen: Vec<&PairResult> = results.iter().filter(|r| r.method == method && keep(r)).collect();
    if chosen.is_empty() {
        return Ok(());
    }
    let estimates: Vec<RegistrationPair> = chosen
        .iter()
        .map(|r| RegistrationPair {
            estimated: r.estimate,
            ground_truth: r.truth,
        })
        .collect();
    let times: Vec<f64> = chosen.iter().map(|r| r.time_ms).collect();
    let cpu: Vec<f64> = chosen.iter().filter_map(|r| r.cpu_ms).collect();
    let mut summary = summary(data, method, &estimates, &times, &cpu)?;
    if chosen.iter().any(|r| r.inliers.is_some()) && method != REFERENCE_NAME {
        let kept = chosen.iter().filter(|r| r.success && !r.ambiguous).count();
        summary.unambiguous_success_percent = Some(percent(kept, chosen.len()));
    }
    if method != REFERENCE_NAME {
        let kept = chosen
            .iter()
            .filter(|r| r.success && !r.free_space_refused)
            .count();
        summary.free_space_success_percent = Some(percent(kept, chosen.len()));
    }
    let mut row = serde_json::to_value(summary)?;
    let mut inliers: Vec<usize> = chosen.iter().filter_map(|r| r.inliers).collect();
    inliers.sort_unstable();
    row["median_inliers"] = serde_json::json!(inliers.get(inliers.len() / 2));
    report.push(&row)
}

/// Runs every method on every world's pairs, pushes one summary row per world, pair set and method
/// into `report` (pair sets: every kind but partial overlap, then each kind alone) and returns every
/// pair's result.
pub fn sim_table(
    methods: &mut Methods,
    settings: &SimTableSettings,
    report: &mut Report,
) -> Result<Vec<PairResult>> {
    check_methods(&settings.methods)?;
    let mut all = Vec::new();
    for world in &settings.worlds {
        let kind: WorldKind = world.parse()?;
        let results = world_results(methods, settings, kind)?;
        let mut names: Vec<String> = settings.methods.clone();
        if results.iter().any(|r| r.method == REFERENCE_NAME) {
            names.push(REFERENCE_NAME.to_owned());
        }
        let overlapping = |r: &PairResult| r.kind != PairKind::Partial;
        for method in &names {
            push_summary(report, &format!("sim {kind}"), method, &results, &overlapping)?;
        }
        for pair_kind in &settings.pair_kinds {
            for method in &names {
                let label = format!("sim {kind}, {}", pair_kind.label());
                push_summary(report, &label, method, &results, &|r| r.kind == *pair_kind)?;
            }
        }
        all.extend(results);
    }
    Ok(all)
}
