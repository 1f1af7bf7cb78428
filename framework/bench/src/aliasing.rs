//! The merge-trust benchmark: multi-robot runs in worlds that alias, over several seeds, with the merge
//! rules on and off (the rules before them: no ambiguity refusal in registration, PCM's largest
//! consistent set accepted at once, no check against the frame through a third robot), or any other
//! variants the profile lists. It counts, per world and rule set, the robots β placed in
//! robot α's frame: **false merges** (a frame more than 2 m or 5° from the truth, the one definition all
//! SKiD benchmarks use), true merges, and robots never merged; refusing everything cannot pass, since
//! the missed true merges are counted beside the false ones.
//!
//! The frame is judged where the robots met (`skid_eval::meeting_frame_error`: the relative poses
//! between the two robots' poses that were within 10 m of each other, in the merged map against the
//! truth), which is what a merge decides and carries no drift from elsewhere on the routes; a robot
//! that never met α but joined through others is judged where it met them
//! (`skid_eval::meeting_with_fleet`). Robots that met none are judged by `T_β,APE`, or at the robots'
//! first poses where a straight route leaves `T_β,APE`'s rotation undefined
//! (`skid_eval::anchored_frame_error`); both are reported beside, and both carry the odometry's drift.
//!
//! Every run is the real runtime (`skid_runtime::Fleet` in lockstep) built from `configs/default.toml`,
//! the variant's overrides and the bench's; the frame error is the runtime's own α/β metric
//! (`T_β,APE`, Kim et al., SKiD-SLAM, Sec. V).

use std::path::Path;

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use skid_core::Registry;

use crate::slam::build_fleet;

pub use skid_runtime::{FALSE_MERGE_DEG, FALSE_MERGE_M};

/// One rule set under comparison: a label and its `--set`-style overrides.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Variant {
    pub name: String,
    #[serde(default)]
    pub sets: Vec<String>,
}

/// Parameters of the benchmark.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AliasingSettings {
    pub worlds: Vec<String>,
    /// Seeds (`source.sim.seed`, and `run.seed` beside it): each builds another world, other routes and
    /// other noise.
    pub seeds: Vec<u64>,
    pub variants: Vec<Variant>,
    pub robots: u32,
    /// Scans per robot (10 Hz).
    pub max_scans: u64,
    /// `--set`-style overrides applied to every run (before the variant's).
    pub sets: Vec<String>,
}

impl Default for AliasingSettings {
    fn default() -> Self {
        Self {
            worlds: vec!["urban".to_owned(), "blocks".to_owned()],
            seeds: (1..=10).collect(),
            variants: vec![
                Variant {
                    name: "merge rules on".to_owned(),
                    sets: vec![
                        "loops.ambiguous_rival_ratio=0.5".to_owned(),
                        "verifier.pcm.consistency.together_within_s=1.0".to_owned(),
                        "verifier.pcm.consistency.repeat_beyond_m=20.0".to_owned(),
                    ],
                },
                Variant {
                    name: "no merge rules".to_owned(),
                    sets: vec![
                        "loops.ambiguous_rival_ratio=0".to_owned(),
                        "verifier.pcm.consistency.dominance_ratio=0".to_owned(),
                        "verifier.pcm.consistency.min_spread_m=0".to_owned(),
                        "verifier.pcm.consistency.cycle_tolerance_m=1e9".to_owned(),
                        "verifier.pcm.consistency.cycle_tolerance_deg=1e9".to_owned(),
                        "verifier.pcm.consistency.together_within_s=0".to_owned(),
                        "verifier.pcm.consistency.predicted_overlap_m=0".to_owned(),
                        "verifier.pcm.consistency.repeat_beyond_m=0".to_owned(),
                        "verifier.pcm.consistency.min_unseen_loops=0".to_owned(),
                        "verifier.pcm.free_space.enabled=false".to_owned(),
                        "verifier.pcm.odometry.enabled=false".to_owned(),
                        "verifier.pcm.peer_seen.enabled=false".to_owned(),
                    ],
                },
            ],
            robots: 3,
            max_scans: 900,
            sets: Vec::new(),
        }
    }
}

/// What became of one robot β in one run.
#[derive(Clone, Debug, Serialize)]
pub struct MergeRow {
    pub world: String,
    pub seed: u64,
    pub variant: String,
    pub beta_robot: usize,
    /// β's frame error when β was placed in α's frame (what decides): where the robots met, or for
    /// robots that never met `T_β,APE` (on a straight route the error at the robots' first poses).
    pub frame_error_m: Option<f64>,
    pub frame_error_deg: Option<f64>,
    /// Which measure decided: `meeting`, `T_β,APE` or `anchored`.
    pub judged_by: &'static str,
    /// Seconds of robot time until α first placed β in its frame (perhaps falsely, withdrawn later).
    pub joined_after_s: Option<f64>,
    /// Seconds of robot time until the placement β ends the run with began: the time to the merge.
    pub placed_since_s: Option<f64>,
    /// Placements of β withdrawn (or overturned) during the run that were false (more than 2 m or 5°
    /// from the truth at the robots' first poses), and the seconds β stood placed by them.
    pub withdrawn_false_placements: usize,
    pub withdrawn_false_placement_s: f64,
    /// The paper's `T_β,APE` itself, and whether either robot's route was too straight for its Umeyama
    /// alignment to fix the rotation (then `T_β,APE`'s rotation means nothing).
    pub t_beta_ape_m: Option<f64>,
    pub t_beta_ape_deg: Option<f64>,
    pub straight_route: bool,
    /// `merged` (true), `false merge` or `not merged`.
    pub outcome: &'static str,
    /// Inter-robot loops accepted in the run, and candidates refused as ambiguous by every robot.
    pub inter_robot_loops: usize,
    pub coarse_ambiguous: usize,
    /// Loops in the robots' graphs at the end more than 2 m or 5° from the truth, over every graph.
    pub false_loops_in_graphs: usize,
    pub run_wall_s: f64,
}

/// Runs one world, seed and variant: one row per robot β ≥ 1.
pub fn run_one(
    settings: &AliasingSettings,
    world: &str,
    seed: u64,
    variant: &Variant,
    registry: &Registry,
    out: &Path,
) -> Result<Vec<MergeRow>> {
    let name = format!("{world}-seed{seed}-{}", variant.name.replace(' ', "-"));
    let mut sets = settings.sets.clone();
    sets.extend(variant.sets.iter().cloned());
    sets.extend([
        format!("run.name={name}"),
        format!("run.seed={seed}"),
        format!("source.sim.seed={seed}"),
        format!("run.robots={}", settings.robots),
        format!("run.max_scans={}", settings.max_scans),
        format!("run.output_dir=\"{}\"", out.join("runs").display()),
        format!("source.sim.world={world}"),
    ]);
    let mut fleet = build_fleet(&name, None, sets, registry)?;
    let summary = fleet
        .run_lockstep(|_| {})
        .with_context(|| format!("running {name}"))?;
    let (_, metrics) = skid_runtime::write_outputs(&fleet, &summary)?;
    let coarse_ambiguous = metrics.robots.iter().map(|r| r.loops.coarse_ambiguous).sum();
    // A route too straight for its Umeyama alignment to fix the rotation about it.
    let straight = |robot: &skid_runtime::RobotMetrics| {
        robot
            .trajectory
            .as_ref()
            .is_some_and(|t| t.alignment_conditioning.ill_conditioned)
    };
    let alpha_straight = metrics.robots.first().is_some_and(straight);
    Ok(metrics
        .robots
        .iter()
        .enumerate()
        .skip(1)
        .map(|(beta_robot, beta)| {
            let straight_route = alpha_straight || straight(beta);
            let ape = beta.alignment.as_ref().map(|a| &a.beta_alignment_error);
            // Where the robots met when they did, else where β met the robots placed before it;
            // otherwise the paper's metric, or the anchored frame error where a straight route leaves
            // T_β,APE's rotation arbitrary.
            let (error, judged_by) = match beta.alignment.as_ref() {
                None => (None, "none"),
                Some(a) => match (a.meeting_frame_error, a.fleet_meeting_frame_error, straight_route) {
                    (Some(met), _, _) => (Some((met.translation_m, met.rotation_deg)), "meeting"),
                    (None, Some(met), _) => (
                        Some((met.translation_m, met.rotation_deg)),
                        "meeting with the fleet",
                    ),
                    (None, None, true) => (
                        Some((
                            a.anchored_frame_error.translation_m,
                            a.anchored_frame_error.rotation_deg,
                        )),
                        "anchored",
                    ),
                    (None, None, false) => (
                        Some((
                            a.beta_alignment_error.translation_m,
                            a.beta_alignment_error.rotation_deg,
                        )),
                        "T_β,APE",
                    ),
                },
            };
            let outcome = match error {
                None => "not merged",
                Some((m, deg)) if m > FALSE_MERGE_M || deg > FALSE_MERGE_DEG => "false merge",
                Some(_) => "merged",
            };
            let withdrawn_false: Vec<(f64, f64)> = beta
                .alignment
                .as_ref()
                .map(|a| {
                    a.placements
                        .iter()
                        .filter(|p| {
                            p.frame_error.translation_m > FALSE_MERGE_M
                                || p.frame_error.rotation_deg > FALSE_MERGE_DEG
                        })
                        .filter_map(|p| Some((p.from_s, p.until_s?)))
                        .collect()
                })
                .unwrap_or_default();
            MergeRow {
                world: world.to_owned(),
                seed,
                variant: variant.name.clone(),
                beta_robot,
                frame_error_m: error.map(|e| e.0),
                frame_error_deg: error.map(|e| e.1),
                judged_by,
                joined_after_s: beta.alignment.as_ref().and_then(|a| a.joined_after_s),
                placed_since_s: beta.alignment.as_ref().and_then(|a| a.placed_since_s),
                withdrawn_false_placements: withdrawn_false.len(),
                // Folded from +0: an empty `f64` sum is -0, which the table would print as "-0".
                withdrawn_false_placement_s: withdrawn_false
                    .iter()
                    .fold(0.0, |sum, (from, until)| sum + (until - from)),
                t_beta_ape_m: ape.map(|e| e.translation_m),
                t_beta_ape_deg: ape.map(|e| e.rotation_deg),
                straight_route,
                outcome,
                inter_robot_loops: metrics.inter_robot_loops_accepted,
                coarse_ambiguous,
                false_loops_in_graphs: metrics.false_loops_in_graphs,
                run_wall_s: summary.wall_s,
            }
        })
        .collect())
}

/// The summary: per world and variant, the robots β merged truly, falsely and not at all, and the
/// candidates refused as ambiguous.
pub fn aliasing_markdown(settings: &AliasingSettings, rows: &[MergeRow]) -> String {
    let header = [
        "world",
        "rules",
        "runs",
        "robots β",
        "false merges ↓",
        "true merges ↑",
        "not merged",
        "worst true-merge error [m / °]",
        "median time to a true merge [s]",
        "false placements withdrawn (robot-seconds placed falsely)",
        "T_β,APE over 2 m or 5° (of them on a straight route)",
        "ambiguous candidates refused",
    ]
    .map(str::to_owned);
    let mut body = Vec::new();
    for world in &settings.worlds {
        for variant in &settings.variants {
            let mine: Vec<&MergeRow> = rows
                .iter()
                .filter(|r| &r.world == world && r.variant == variant.name)
                .collect();
            let count = |outcome: &str| mine.iter().filter(|r| r.outcome == outcome).count();
            let true_merges: Vec<&&MergeRow> = mine.iter().filter(|r| r.outcome == "merged").collect();
            let worst_m = true_merges
                .iter()
                .filter_map(|r| r.frame_error_m)
                .fold(0.0, f64::max);
            let worst_deg = true_merges
                .iter()
                .filter_map(|r| r.frame_error_deg)
                .fold(0.0, f64::max);
            let mut times: Vec<f64> = true_merges.iter().filter_map(|r| r.placed_since_s).collect();
            let withdrawn: usize = mine.iter().map(|r| r.withdrawn_false_placements).sum();
            let withdrawn_s = mine
                .iter()
                .fold(0.0, |sum, r| sum + r.withdrawn_false_placement_s);
            let median_time = if times.is_empty() {
                "–".to_owned()
            } else {
                format!("{:.0}", crate::stats::median(&mut times))
            };
            let ape_over: Vec<&&MergeRow> = mine
                .iter()
                .filter(|r| {
                    r.t_beta_ape_m.is_some_and(|m| m > FALSE_MERGE_M)
                        || r.t_beta_ape_deg.is_some_and(|deg| deg > FALSE_MERGE_DEG)
                })
                .collect();
            let ape_over_straight = ape_over.iter().filter(|r| r.straight_route).count();
            let mut seeds: Vec<u64> = mine.iter().map(|r| r.seed).collect();
            seeds.dedup();
            let ambiguous: usize = seeds
                .iter()
                .filter_map(|seed| mine.iter().find(|r| r.seed == *seed))
                .map(|r| r.coarse_ambiguous)
                .sum();
            body.push(vec![
                world.clone(),
                variant.name.clone(),
                seeds.len().to_string(),
                mine.len().to_string(),
                count("false merge").to_string(),
                true_merges.len().to_string(),
                count("not merged").to_string(),
                format!("{worst_m:.2} / {worst_deg:.2}"),
                median_time,
                format!("{withdrawn} ({withdrawn_s:.0})"),
                format!("{} ({ape_over_straight})", ape_over.len()),
                ambiguous.to_string(),
            ]);
        }
    }
    format!(
        "# aliasing\n\nMerges of robots β into robot α's frame in worlds that alias, {} robots, {} scans per robot, seeds {:?}. A false merge places β's frame more than {FALSE_MERGE_M} m or {FALSE_MERGE_DEG}° from the truth, judged where the robots met (the median error of the relative poses between their poses within 10 m of each other, in the merged map), which carries no drift from elsewhere on the routes; the time to a true merge is when the placement the run ends with began, and placements withdrawn or overturned during the run are judged at the robots' first poses and counted when false; robots that never met are judged by the paper's `T_β,APE` (at the robots' first poses where a route is too straight for its Umeyama alignment). `T_β,APE` alone, which carries the odometry's drift, is counted beside. Variants: {}. Runtime overrides: `{}`.\n\n{}",
        settings.robots,
        settings.max_scans,
        settings.seeds,
        settings
            .variants
            .iter()
            .map(|v| format!("{} (`{}`)", v.name, v.sets.join("`, `")))
            .collect::<Vec<_>>()
            .join("; "),
        settings.sets.join("`, `"),
        crate::report::markdown_table(&header, &body),
    )
}
