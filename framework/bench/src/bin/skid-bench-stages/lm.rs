//! Levenberg-Marquardt on sphere2500 (SE-Sync's benchmark graph in the shared data): `skid-backend-pgo`
//! against GTSAM's `LevenbergMarquardtOptimizer` with its default parameters, both from the file's
//! initial estimate and from each one's own chordal initialisation (timed with it). The goal is
//! at most half GTSAM's time.

use std::ffi::{OsStr, OsString};

use anyhow::{Context, Result};
use nalgebra::Isometry3;
use serde::Deserialize;
use skid_backend_pgo::{Initialization, PgoOptions, optimize_pose_graph};
use skid_io::g2o::{G2oReadOptions, read_g2o_3d};

use skid_bench::python_peers;
use skid_bench::stats::median;

use crate::Row;

#[derive(Deserialize)]
struct PeerRun {
    ms: Vec<f64>,
    iterations: usize,
    final_cost: f64,
}

#[derive(Deserialize)]
struct PeerRuns {
    file: PeerRun,
    chordal: PeerRun,
}

/// Two rows, one per initialisation.
pub fn rows(python: Option<&OsStr>, repeats: usize) -> Result<Vec<Row>> {
    let path = skid_io::data_path("pose_graph_benchmarks/se_sync/sphere2500.g2o")?;
    let (graph, _) = read_g2o_3d(&path, &G2oReadOptions::default())?;
    let repeats_text = OsString::from(repeats.to_string());
    let mut peer_runs: Option<PeerRuns> = None;
    let mut skid_ms: [Vec<f64>; 2] = [Vec::new(), Vec::new()];
    let mut skid_outcome = [(0usize, 0.0f64); 2];
    // Rounds alternate SKiD and the peer, so both meet the shared machine in the same states.
    for _ in 0..3 {
        for (slot, init) in [Initialization::File, Initialization::Chordal]
            .into_iter()
            .enumerate()
        {
            for _ in 0..repeats {
                let mut copy = graph.clone();
                let options = PgoOptions {
                    init,
                    ..PgoOptions::default()
                };
                let report = optimize_pose_graph::<Isometry3<f64>, 6>(&mut copy, &options)
                    .context("optimising sphere2500")?;
                skid_ms[slot].push(report.time_s * 1e3);
                skid_outcome[slot] = (report.iterations, report.final_cost);
            }
        }
        if let Some(python) = python {
            let runs: PeerRuns = python_peers::run(python, "lm", &[path.as_os_str(), &repeats_text])?;
            match &mut peer_runs {
                Some(all) => {
                    all.file.ms.extend(runs.file.ms);
                    all.chordal.ms.extend(runs.chordal.ms);
                }
                None => peer_runs = Some(runs),
            }
        }
    }
    let mut rows = Vec::new();
    for (slot, name) in ["file", "chordal"].into_iter().enumerate() {
        let skid = median(&mut skid_ms[slot]);
        let peer = peer_runs.as_mut().map(|runs| {
            let run = if slot == 0 {
                &mut runs.file
            } else {
                &mut runs.chordal
            };
            (median(&mut run.ms), run.iterations, run.final_cost)
        });
        let (iterations, cost) = skid_outcome[slot];
        rows.push(Row {
            stage: format!("LM, initial estimate: {name}"),
            input: "sphere2500 (2,500 poses, 4,949 edges)".into(),
            skid: format!("{skid:.1} ms"),
            peer: peer.map_or("–".into(), |(ms, _, _)| format!("GTSAM {ms:.1} ms")),
            ratio: peer.map(|(ms, _, _)| skid / ms),
            goal: "≤ 0.5×".into(),
            detail: format!(
                "SKiD {iterations} iterations, cost {cost:.4}{}",
                peer.map_or(String::new(), |(_, it, c)| format!(
                    "; GTSAM {it} iterations, cost {c:.4}"
                ))
            ),
        });
    }
    Ok(rows)
}
