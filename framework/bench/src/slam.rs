//! The SKiD-SLAM paper's Table III: ATE and ARE of robot α (after its own SE(3) Umeyama alignment) and
//! of each other robot β placed in α's frame — the paper's multi-robot alignment metric
//! `T_β,APE = (T^GT_β)⁻¹ · T^GT_α · T^α_β` (skid-eval's `alpha_beta`) — per simulated world, for the
//! default pipeline (SOLiD + KISS-Matcher + GICP + PCM) against the DiSCo-like (Scan Context + ICP +
//! PCM) and DCL-like (LiDAR-Iris + ICP) profiles. Every run is the real runtime with each pipeline's own
//! front-end: a `skid_runtime::Fleet` in lockstep built from `configs/default.toml`, the pipeline's
//! profile and the bench's overrides, on a simulator mission in which the robots start apart and meet
//! (`explore_meet`: every pair crosses at a junction and one drives the other's sector backwards).
//!
//! The numbers are the runtime's own `RunMetrics` (the run's `metrics.json`): `T^α_β` is the SE(3)
//! Umeyama fit of β's keyframes as α's back-end holds them onto β's own estimate of them.

use std::path::Path;

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use skid_config::ConfigSources;
use skid_core::Registry;
use skid_runtime::Fleet;

/// One pipeline under comparison: a label and the `configs/profiles/` overlay (none = the default).
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Pipeline {
    pub name: String,
    #[serde(default)]
    pub profile: Option<String>,
}

/// Parameters of the comparison.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SlamSettings {
    pub worlds: Vec<String>,
    pub pipelines: Vec<Pipeline>,
    pub robots: u32,
    /// Scans per robot (10 Hz).
    pub max_scans: u64,
    /// `--set`-style overrides applied to every run (after the profile).
    pub sets: Vec<String>,
}

impl Default for SlamSettings {
    fn default() -> Self {
        let pipeline = |name: &str, profile: Option<&str>| Pipeline {
            name: name.to_owned(),
            profile: profile.map(str::to_owned),
        };
        Self {
            worlds: ["planetary", "cave", "urban"].map(str::to_owned).to_vec(),
            pipelines: vec![
                pipeline("SKiD (default)", None),
                pipeline("DiSCo-like", Some("disco_like")),
                pipeline("DCL-like", Some("dcl_like")),
            ],
            robots: 2,
            max_scans: 400,
            sets: Vec::new(),
        }
    }
}

/// One world, pipeline and robot β (robot 0 is α).
#[derive(Clone, Debug, Serialize)]
pub struct SlamRow {
    pub world: String,
    pub pipeline: String,
    /// Which robot is β.
    pub beta_robot: usize,
    pub scans_per_robot: usize,
    pub keyframes_alpha: usize,
    pub keyframes_beta: usize,
    /// Inter-robot loops accepted by α and β together.
    pub inter_robot_loops: usize,
    pub ate_alpha_m: Option<f64>,
    pub are_alpha_deg: Option<f64>,
    /// β's trajectory through `T^GT_α · T^α_β` against its ground truth (RMSE).
    pub ate_beta_m: Option<f64>,
    pub are_beta_deg: Option<f64>,
    /// The transform `T_β,APE` itself.
    pub t_beta_ape_m: Option<f64>,
    pub t_beta_ape_deg: Option<f64>,
    /// β after its own alignment (its trajectory alone).
    pub ate_beta_own_m: Option<f64>,
    pub descriptor_bytes_sent: u64,
    pub cloud_bytes_sent: u64,
    pub run_wall_s: f64,
    /// Why β could not be evaluated, if it could not.
    pub note: String,
}

/// The fleet of `configs/default.toml` with `profile` (from `configs/profiles/`) and the `--set`-style
/// `sets` on top, named `name` in errors.
pub fn build_fleet(
    name: &str,
    profile: Option<String>,
    sets: Vec<String>,
    registry: &Registry,
) -> Result<Fleet> {
    let sources = ConfigSources {
        config_dir: Some(crate::profile::workspace_root().join("configs")),
        profile,
        overlays: Vec::new(),
        sets,
        use_env: false,
    };
    let config = sources
        .load(registry)
        .with_context(|| format!("configuring {name}"))?;
    Fleet::build(config, registry).with_context(|| format!("building {name}"))
}

/// Runs one world with one pipeline and evaluates it: one row per robot β ≥ 1.
pub fn run_one(
    settings: &SlamSettings,
    world: &str,
    pipeline: &Pipeline,
    registry: &Registry,
    out: &Path,
) -> Result<Vec<SlamRow>> {
    let name = format!("{world}-{}", pipeline.profile.as_deref().unwrap_or("default"));
    let mut sets = settings.sets.clone();
    sets.extend([
        format!("run.name={name}"),
        format!("run.robots={}", settings.robots),
        format!("run.max_scans={}", settings.max_scans),
        format!("run.output_dir=\"{}\"", out.join("runs").display()),
        format!("source.sim.world={world}"),
    ]);
    let mut fleet = build_fleet(&name, pipeline.profile.clone(), sets, registry)?;
    let mut last = std::time::Instant::now();
    let summary = fleet
        .run_lockstep(|scans| {
            if last.elapsed().as_secs_f64() > 10.0 {
                eprintln!("{name}: {scans} scans");
                last = std::time::Instant::now();
            }
        })
        .with_context(|| format!("running {name}"))?;
    // The runtime's own metrics (also in the run's `metrics.json`): robot 0 is α, every other one a β.
    let (_, metrics) = skid_runtime::write_outputs(&fleet, &summary)?;
    let Some(alpha) = metrics.robots.first() else {
        anyhow::bail!("{name}: the comparison needs at least two robots");
    };
    if metrics.robots.len() < 2 {
        anyhow::bail!("{name}: the comparison needs at least two robots");
    }
    Ok(metrics
        .robots
        .iter()
        .enumerate()
        .skip(1)
        .map(|(beta_robot, beta)| {
            let alignment = beta.alignment.as_ref();
            let bytes = |kind: &str| beta.bytes_sent_by_kind.get(kind).copied().unwrap_or(0);
            SlamRow {
                world: world.to_owned(),
                pipeline: pipeline.name.clone(),
                beta_robot,
                scans_per_robot: alpha.scans,
                keyframes_alpha: alpha.keyframes,
                keyframes_beta: beta.keyframes,
                inter_robot_loops: metrics.inter_robot_loops_accepted,
                ate_alpha_m: alpha.trajectory.as_ref().map(|t| t.ate_m.rmse),
                are_alpha_deg: alpha.trajectory.as_ref().map(|t| t.are_deg.rmse),
                ate_beta_m: alignment.map(|a| a.beta_in_alpha_ate_m.rmse),
                are_beta_deg: alignment.map(|a| a.beta_in_alpha_are_deg.rmse),
                t_beta_ape_m: alignment.map(|a| a.beta_alignment_error.translation_m),
                t_beta_ape_deg: alignment.map(|a| a.beta_alignment_error.rotation_deg),
                ate_beta_own_m: beta.trajectory.as_ref().map(|t| t.ate_m.rmse),
                descriptor_bytes_sent: bytes("descriptors"),
                cloud_bytes_sent: bytes("cloud"),
                run_wall_s: summary.wall_s,
                note: beta.alignment_unavailable.clone().unwrap_or_default(),
            }
        })
        .collect())
}

fn cell(value: Option<f64>) -> String {
    value.map_or_else(|| "N/A".to_owned(), |v| format!("{v:.3}"))
}

/// The paper-shaped table: per world, ATE [m] and ARE [°] of α and β, one line per pipeline.
pub fn slam_markdown(settings: &SlamSettings, rows: &[SlamRow]) -> String {
    let mut header = vec!["Pipeline".to_owned()];
    for world in &settings.worlds {
        for metric in ["ATE α [m]", "ATE β [m]", "ARE α [°]", "ARE β [°]"] {
            header.push(format!("{world} {metric}"));
        }
    }
    let body: Vec<Vec<String>> = settings
        .pipelines
        .iter()
        .map(|pipeline| {
            let mut cells = vec![pipeline.name.clone()];
            for world in &settings.worlds {
                let row = rows
                    .iter()
                    .find(|r| &r.world == world && r.pipeline == pipeline.name && r.beta_robot == 1);
                let values = row.map_or([None; 4], |r| {
                    [r.ate_alpha_m, r.ate_beta_m, r.are_alpha_deg, r.are_beta_deg]
                });
                cells.extend(values.into_iter().map(cell));
            }
            cells
        })
        .collect();
    let details: Vec<String> = [
        "world",
        "pipeline",
        "β",
        "inter-robot loops",
        "T_β,APE [m]",
        "T_β,APE [°]",
        "β own ATE [m]",
        "descriptor bytes β→α",
        "cloud bytes β→α",
        "run [s]",
        "note",
    ]
    .map(str::to_owned)
    .to_vec();
    let detail_rows: Vec<Vec<String>> = rows
        .iter()
        .map(|r| {
            vec![
                r.world.clone(),
                r.pipeline.clone(),
                format!("robot {}", r.beta_robot),
                r.inter_robot_loops.to_string(),
                cell(r.t_beta_ape_m),
                cell(r.t_beta_ape_deg),
                cell(r.ate_beta_own_m),
                r.descriptor_bytes_sent.to_string(),
                r.cloud_bytes_sent.to_string(),
                format!("{:.0}", r.run_wall_s),
                r.note.clone(),
            ]
        })
        .collect();
    format!(
        "# table3-slam\n\nATE and ARE (RMSE) of robot α (robot 0) after SE(3) Umeyama alignment and of robot β (robot 1) placed through α's alignment and the back-end's `T^α_β` (Table III shape; the paper's planetary terrains: SKiD 0.198 / 1.046 m, 0.546 / 0.080°). Each pipeline runs its own front-end on the simulator's LiDAR and IMU.\n\n{}\nEvery robot β against α:\n\n{}\n{} robots, {} scans per robot (10 Hz), runtime overrides: `{}`. N/A: β never shared a loop with α, so it has no place in α's frame.\n",
        crate::report::markdown_table(&header, &body),
        crate::report::markdown_table(&details, &detail_rows),
        settings.robots,
        settings.max_scans,
        settings.sets.join("`, `"),
    )
}
