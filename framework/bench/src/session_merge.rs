//! Session merges for `cargo xtask bench relocalise`: the map's session merged with sessions of the same
//! world made on other days (the mapping mission driven again one season later, with another LiDAR and
//! other noise), and with sessions made far from it (a robot wandering from a junction the map never
//! came near), through `skid_merge::merge_sessions` exactly as `skid session merge` runs it. A day's
//! session must be placed within 0.5 m and 1° of the truth; a far one must be reported, never placed.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde::Serialize;
use skid_core::Registry;
use skid_sim::{World, WorldKind};

use crate::relocalise::{
    RelocaliseSettings, figure, is_false_fix, mapped_positions, mission_again_sets, start_junctions,
};
use crate::slam::build_fleet;

/// One merge.
#[derive(Clone, Debug, Serialize)]
pub struct MergeRow {
    pub session: String,
    /// `another day` or `far from the map`.
    pub kind: &'static str,
    pub placed: bool,
    pub robots: usize,
    pub robots_localised: usize,
    pub loops: usize,
    /// Median keyframe error of the placed session against the truth, metres and degrees.
    pub error_m: Option<f64>,
    pub error_deg: Option<f64>,
    pub false_merge: bool,
    pub merge_s: f64,
}

/// Runs a mission and writes its outputs; returns its session folder.
fn make_session(name: &str, mut sets: Vec<String>, registry: &Registry, out: &Path) -> Result<PathBuf> {
    sets.extend([
        format!("run.name={name}"),
        "output.record=false".to_owned(),
        "output.session=true".to_owned(),
        format!("run.output_dir=\"{}\"", out.join("runs").display()),
    ]);
    let mut fleet = build_fleet(name, None, sets, registry)?;
    let summary = fleet
        .run_lockstep(|_| {})
        .with_context(|| format!("running {name}"))?;
    let (folder, _) = skid_runtime::write_outputs(&fleet, &summary)?;
    Ok(folder.join("session"))
}

fn merge_row(
    map: &Path,
    session: &Path,
    kind: &'static str,
    registry: &Registry,
    out: &Path,
) -> Result<MergeRow> {
    let name = session
        .parent()
        .and_then(Path::file_name)
        .map_or_else(|| "session".to_owned(), |n| n.to_string_lossy().into_owned());
    let merged = out.join("merged").join(&name);
    let _ = std::fs::remove_dir_all(&merged);
    let request = skid_merge::MergeRequest {
        sessions: vec![map.to_path_buf(), session.to_path_buf()],
        out: merged,
        sets: Vec::new(),
    };
    let report = skid_merge::merge_sessions(&request, registry)
        .with_context(|| format!("merging {} into the map", session.display()))?;
    let outcome = report.sessions.first().context("the merge reports no session")?;
    Ok(MergeRow {
        session: name,
        kind,
        placed: outcome.placed,
        robots: outcome.robots.len(),
        robots_localised: outcome.robots.iter().filter(|r| r.localised).count(),
        loops: outcome.robots.iter().map(|r| r.loops).sum(),
        error_m: outcome.error_m,
        error_deg: outcome.error_deg,
        false_merge: outcome.placed && is_false_fix(outcome.error_m, outcome.error_deg),
        merge_s: report.wall_s,
    })
}

/// Makes the other days' and the far sessions and merges each with the map in `map`.
pub fn run_merges(
    settings: &RelocaliseSettings,
    map: &Path,
    registry: &Registry,
    out: &Path,
    mut on_row: impl FnMut(&MergeRow) -> Result<()>,
) -> Result<Vec<MergeRow>> {
    let base_sets = |route_seed: usize| {
        let mut sets = mission_again_sets(settings);
        sets.push(format!("source.sim.route_seed={route_seed}"));
        sets
    };
    let mut rows = Vec::new();
    for day in 1..=settings.merge_other_days {
        let session = make_session(&format!("day-{day}"), base_sets(day), registry, out)?;
        let row = merge_row(map, &session, "another day", registry, out)?;
        on_row(&row)?;
        rows.push(row);
    }
    let mapped = mapped_positions(map)?;
    let world = World::shared(settings.world.parse::<WorldKind>()?, settings.seed);
    let (_, far) = start_junctions(&world, &mapped, settings.off_map_start_m);
    for (index, junction) in far
        .iter()
        .step_by(5)
        .take(settings.merge_far_sessions)
        .enumerate()
    {
        let mut sets = base_sets(100 + index);
        sets.extend([
            "run.robots=1".to_owned(),
            format!("run.max_scans={}", settings.trial_max_scans),
            "source.sim.mission=wander".to_owned(),
            format!("source.sim.start_junction={junction}"),
        ]);
        let session = make_session(&format!("far-{index}"), sets, registry, out)?;
        let row = merge_row(map, &session, "far from the map", registry, out)?;
        on_row(&row)?;
        rows.push(row);
    }
    Ok(rows)
}

/// The merges as a table.
pub fn merge_markdown(rows: &[MergeRow]) -> String {
    if rows.is_empty() {
        return String::new();
    }
    let header: Vec<String> = [
        "session merged with the map",
        "placed",
        "robots localised",
        "loops",
        "frame error [m / °] ↓",
        "false merges ↓",
        "merge time [s]",
    ]
    .map(str::to_owned)
    .to_vec();
    let table: Vec<Vec<String>> = rows
        .iter()
        .map(|row| {
            vec![
                format!("{} ({})", row.session, row.kind),
                if row.placed { "yes".into() } else { "no".into() },
                format!("{} of {}", row.robots_localised, row.robots),
                row.loops.to_string(),
                format!("{} / {}", figure(row.error_m, 3), figure(row.error_deg, 2)),
                usize::from(row.false_merge).to_string(),
                format!("{:.1}", row.merge_s),
            ]
        })
        .collect();
    format!(
        "Sessions merged with the map (`skid session merge`): the mapping mission on other days (the trials' \
         sensor and season, other noise) and one robot's session far from the map.\n\n{}",
        crate::markdown_table(&header, &table)
    )
}
