//! Robustness: the benchmark graphs with 20 and 100 random wrong loop closures (uniformly random
//! rotation, translation uniform in ±10 m per axis, information copied from a random true loop), rejected
//! by PCM (`skid-verifier-pcm`, loops submitted in random order over the odometry chain), by GNC-TLS in
//! the back-end (`skid_backend_pgo::gnc`), or by both in turn (`pcm+gnc`, the default profile); the
//! surviving graph is optimised and compared with the clean graph's solution. A row is `ok` when no wrong
//! loop is kept, no true loop is dropped and no pose is 1 cm or more from the clean solution. With
//! `SKID_PYTHON` set (`cargo xtask bench` sets it), GTSAM's GNC runs on the same corrupted graphs beside
//! SKiD's (`python/stage_peers.py gnc`; 20 wrong loops unless `SKID_BENCH_PGO_PEER_MAX_WRONG` says more).

use std::collections::BTreeSet;
use std::time::Instant;

use anyhow::{Context, Result};
use nalgebra::{Isometry2, Isometry3, Matrix6, Translation3, UnitQuaternion, Vector2, Vector3};
use serde::Serialize;
use skid_backend_pgo::{PgoBackend, PgoConfig, PgoOptions, PgoReport, RobustMode, optimize_pose_graph};
use skid_bench::Report;
use skid_core::slots::{Backend, LoopClosure, OdometryMeasurement};
use skid_core::{KeyframeId, LoopId, PluginContext};
use skid_io::g2o::{AnyPoseGraph, Edge, G2oReadOptions, PoseGraph3, read_g2o};
use skid_verifier_pcm::{Pcm, PcmLoop, PcmParams};

#[derive(Serialize)]
struct Row {
    graph: String,
    wrong_loops: usize,
    method: String,
    true_loops: usize,
    wrong_accepted: usize,
    true_rejected: usize,
    max_pose_difference_m: String,
    verify_s: String,
    optimise_s: String,
    ok: bool,
}

/// SplitMix64: a small seeded generator, so runs are reproducible without another dependency.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    pub fn below(&mut self, n: usize) -> usize {
        (self.uniform() * n as f64) as usize % n.max(1)
    }

    /// A uniformly random rotation (Shoemake's method).
    pub fn rotation(&mut self) -> UnitQuaternion<f64> {
        let (u1, u2, u3) = (self.uniform(), self.uniform(), self.uniform());
        let tau = std::f64::consts::TAU;
        let (a, b) = ((1.0 - u1).sqrt(), u1.sqrt());
        UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
            b * (tau * u3).cos(),
            a * (tau * u2).sin(),
            a * (tau * u2).cos(),
            b * (tau * u3).sin(),
        ))
    }
}

/// Whether an edge is odometry (consecutive ids).
fn is_odometry(from: u64, to: u64) -> bool {
    from.abs_diff(to) == 1
}

/// Adds `count` wrong loops; returns their edge indices.
fn corrupt(graph: &mut AnyPoseGraph, count: usize, rng: &mut Rng) -> BTreeSet<usize> {
    let mut wrong = BTreeSet::new();
    match graph {
        AnyPoseGraph::ThreeD(g) => {
            let ids: Vec<u64> = g.vertices.keys().copied().collect();
            let loops: Vec<usize> = (0..g.edges.len())
                .filter(|&k| !is_odometry(g.edges[k].from, g.edges[k].to))
                .collect();
            while wrong.len() < count {
                let (i, j) = (ids[rng.below(ids.len())], ids[rng.below(ids.len())]);
                if i.abs_diff(j) < 2 {
                    continue;
                }
                let t = Vector3::from_fn(|_, _| 20.0 * rng.uniform() - 10.0);
                let information = g.edges[loops[rng.below(loops.len())]].information;
                let pose = Isometry3::from_parts(Translation3::from(t), rng.rotation());
                wrong.insert(g.edges.len());
                g.edges.push(Edge {
                    from: i,
                    to: j,
                    from_from_to: pose,
                    information,
                });
            }
        }
        AnyPoseGraph::TwoD(g) => {
            let ids: Vec<u64> = g.vertices.keys().copied().collect();
            let loops: Vec<usize> = (0..g.edges.len())
                .filter(|&k| !is_odometry(g.edges[k].from, g.edges[k].to))
                .collect();
            while wrong.len() < count {
                let (i, j) = (ids[rng.below(ids.len())], ids[rng.below(ids.len())]);
                if i.abs_diff(j) < 2 {
                    continue;
                }
                let t = Vector2::new(20.0 * rng.uniform() - 10.0, 20.0 * rng.uniform() - 10.0);
                let angle = std::f64::consts::PI * (2.0 * rng.uniform() - 1.0);
                let information = g.edges[loops[rng.below(loops.len())]].information;
                wrong.insert(g.edges.len());
                g.edges.push(Edge {
                    from: i,
                    to: j,
                    from_from_to: Isometry2::new(t, angle),
                    information,
                });
            }
        }
    }
    wrong
}

/// A 2D graph in 3D: z, roll and pitch held by a stiff information (PCM works on SE(3)).
fn embed(graph: &AnyPoseGraph) -> PoseGraph3 {
    let lift = |p: &Isometry2<f64>| {
        Isometry3::from_parts(
            Translation3::new(p.translation.x, p.translation.y, 0.0),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), p.rotation.angle()),
        )
    };
    match graph {
        AnyPoseGraph::ThreeD(g) => g.clone(),
        AnyPoseGraph::TwoD(g) => PoseGraph3 {
            vertices: g.vertices.iter().map(|(id, p)| (*id, lift(p))).collect(),
            edges: g
                .edges
                .iter()
                .map(|e| {
                    let mut information = Matrix6::identity() * 1e6;
                    let map = [0usize, 1, 5];
                    for (a, &ra) in map.iter().enumerate() {
                        for (b, &rb) in map.iter().enumerate() {
                            information[(ra, rb)] = e.information[(a, b)];
                        }
                    }
                    Edge {
                        from: e.from,
                        to: e.to,
                        from_from_to: lift(&e.from_from_to),
                        information,
                    }
                })
                .collect(),
            fixed: g.fixed.clone(),
        },
    }
}

/// The odometry chain of a single-robot graph as a graph view (robot 0, keyframe index = vertex id),
/// and the indices of the edges that are not odometry.
fn chain_view(graph: &PoseGraph3) -> Result<(PgoBackend, Vec<usize>)> {
    let mut view = PgoBackend::new(PgoConfig::default(), &PluginContext::default())?;
    for (id, pose) in &graph.vertices {
        view.add_keyframe(KeyframeId::new(0, u32::try_from(*id)?), *pose)?;
    }
    let mut used = BTreeSet::new();
    let mut loops = Vec::new();
    for (k, e) in graph.edges.iter().enumerate() {
        if e.to == e.from + 1 && used.insert(e.to) {
            let measurement = OdometryMeasurement {
                target: KeyframeId::new(0, u32::try_from(e.from)?),
                source: KeyframeId::new(0, u32::try_from(e.to)?),
                target_from_source: e.from_from_to,
                information: e.information,
            };
            view.add_odometry(measurement)?;
        } else {
            loops.push(k);
        }
    }
    Ok((view, loops))
}

/// Number of edges of a graph of either dimension.
fn edge_count(graph: &AnyPoseGraph) -> usize {
    match graph {
        AnyPoseGraph::ThreeD(g) => g.edges.len(),
        AnyPoseGraph::TwoD(g) => g.edges.len(),
    }
}

/// Largest translation difference between two solutions of the same vertex set.
fn max_difference_m(a: &AnyPoseGraph, b: &AnyPoseGraph) -> f64 {
    match (a, b) {
        (AnyPoseGraph::ThreeD(a), AnyPoseGraph::ThreeD(b)) => a
            .vertices
            .iter()
            .map(|(id, p)| (p.translation.vector - b.vertices[id].translation.vector).norm())
            .fold(0.0, f64::max),
        (AnyPoseGraph::TwoD(a), AnyPoseGraph::TwoD(b)) => a
            .vertices
            .iter()
            .map(|(id, p)| (p.translation.vector - b.vertices[id].translation.vector).norm())
            .fold(0.0, f64::max),
        _ => f64::INFINITY,
    }
}

/// Optimises a copy of `graph` keeping only the edges `keep` says yes to; returns it and the seconds.
fn optimise(
    graph: &AnyPoseGraph,
    keep: &dyn Fn(usize) -> bool,
    options: &PgoOptions,
) -> Result<(AnyPoseGraph, f64)> {
    let (graph, report) = optimise_with_report(graph, keep, options)?;
    Ok((graph, report.time_s))
}

/// [`optimise`] with the optimiser's report.
fn optimise_with_report(
    graph: &AnyPoseGraph,
    keep: &dyn Fn(usize) -> bool,
    options: &PgoOptions,
) -> Result<(AnyPoseGraph, PgoReport)> {
    let mut copy = graph.clone();
    let report = match &mut copy {
        AnyPoseGraph::ThreeD(g) => {
            g.edges = g
                .edges
                .iter()
                .enumerate()
                .filter(|(k, _)| keep(*k))
                .map(|(_, e)| *e)
                .collect();
            optimize_pose_graph::<Isometry3<f64>, 6>(g, options)?
        }
        AnyPoseGraph::TwoD(g) => {
            g.edges = g
                .edges
                .iter()
                .enumerate()
                .filter(|(k, _)| keep(*k))
                .map(|(_, e)| *e)
                .collect();
            optimize_pose_graph::<Isometry2<f64>, 3>(g, options)?
        }
    };
    Ok((copy, report))
}

/// Runs one graph with `count` wrong loops through PCM and GNC.
fn case(report: &mut Report, data: &std::path::Path, file: &str, count: usize, with_pcm: bool) -> Result<()> {
    let (graph, _) =
        read_g2o(data.join(file), &G2oReadOptions::default()).with_context(|| file.to_owned())?;
    let options = PgoOptions::default();
    let (clean, _) = optimise(&graph, &|_| true, &options)?;
    let seed: u64 = std::env::var("SKID_BENCH_PGO_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0x5eed);
    let mut rng = Rng::new(seed ^ count as u64);
    let mut corrupted = graph.clone();
    let wrong = corrupt(&mut corrupted, count, &mut rng);
    let embedded = embed(&corrupted);
    let (view, loops) = chain_view(&embedded)?;
    let true_loops = loops.len() - wrong.len();
    let gnc = PgoOptions {
        robust: RobustMode::Gnc,
        ..PgoOptions::default()
    };
    let mut push = |method: &str,
                    accepted: &BTreeSet<usize>,
                    solution: &AnyPoseGraph,
                    verify_s: f64,
                    optimise_s: f64| {
        let wrong_accepted = accepted.intersection(&wrong).count();
        let true_rejected = loops
            .iter()
            .filter(|k| !wrong.contains(k) && !accepted.contains(k))
            .count();
        let difference = max_difference_m(solution, &clean);
        report.push(&Row {
            graph: file.to_owned(),
            wrong_loops: count,
            method: method.to_owned(),
            true_loops,
            wrong_accepted,
            true_rejected,
            max_pose_difference_m: format!("{difference:.4}"),
            verify_s: format!("{verify_s:.2}"),
            optimise_s: format!("{optimise_s:.2}"),
            ok: wrong_accepted == 0 && true_rejected == 0 && difference < 0.01,
        })
    };
    if with_pcm {
        let start = Instant::now();
        let mut order = loops.clone();
        for k in (1..order.len()).rev() {
            order.swap(k, rng.below(k + 1));
        }
        let mut pcm = Pcm::new(PcmParams::default()).map_err(anyhow::Error::msg)?;
        for &k in &order {
            let e = &embedded.edges[k];
            let closure = LoopClosure {
                id: LoopId(k as u64),
                target: KeyframeId::new(0, u32::try_from(e.from)?),
                source: KeyframeId::new(0, u32::try_from(e.to)?),
                target_from_source: e.from_from_to,
                information: e.information,
            };
            let pcm_loop = PcmLoop::from_closure(&closure).map_err(anyhow::Error::msg)?;
            pcm.add(pcm_loop, &view).map_err(anyhow::Error::msg)?;
        }
        let verify_s = start.elapsed().as_secs_f64();
        let accepted: BTreeSet<usize> = pcm.accepted().iter().map(|id| id.0 as usize).collect();
        let loop_set: BTreeSet<usize> = loops.iter().copied().collect();
        let in_pcm_set = |k: usize| !loop_set.contains(&k) || accepted.contains(&k);
        let (solution, optimise_s) = optimise(&corrupted, &in_pcm_set, &options)?;
        push("pcm", &accepted, &solution, verify_s, optimise_s)?;
        // PCM's set, then GNC in the back-end: what `[verifier] pcm` with `[backend.pgo] robust = "gnc"` does.
        // The report's inlier flags follow the edges of PCM's set, in order.
        let (solution, report) = optimise_with_report(&corrupted, &in_pcm_set, &gnc)?;
        let kept_loops: BTreeSet<usize> = (0..edge_count(&corrupted))
            .filter(|&k| in_pcm_set(k))
            .zip(&report.edge_inliers)
            .filter(|(k, inlier)| **inlier && loop_set.contains(k))
            .map(|(k, _)| k)
            .collect();
        push("pcm+gnc", &kept_loops, &solution, verify_s, report.time_s)?;
    }
    let (solution, gnc_report) = optimise_with_report(&corrupted, &|_| true, &gnc)?;
    let accepted: BTreeSet<usize> = loops
        .iter()
        .copied()
        .filter(|&k| gnc_report.edge_inliers[k])
        .collect();
    push("gnc", &accepted, &solution, 0.0, gnc_report.time_s)?;
    if let Some(python) = std::env::var_os("SKID_PYTHON").filter(|_| count <= peer_max_wrong_loops()) {
        let peer = gtsam_gnc(&python, &corrupted)?;
        let accepted = accepted_by_peer(&corrupted, &loops, &peer.outliers);
        // GTSAM's solution is not read back; its pose difference is not measured.
        let wrong_accepted = accepted.intersection(&wrong).count();
        let true_rejected = loops
            .iter()
            .filter(|k| !wrong.contains(k) && !accepted.contains(k))
            .count();
        let mut times = peer.ms;
        report.push(&Row {
            graph: file.to_owned(),
            wrong_loops: count,
            method: "GTSAM GNC (peer)".into(),
            true_loops,
            wrong_accepted,
            true_rejected,
            max_pose_difference_m: "–".into(),
            verify_s: "0.00".into(),
            optimise_s: format!("{:.2}", skid_bench::stats::median(&mut times) / 1e3),
            ok: wrong_accepted == 0 && true_rejected == 0,
        })?;
    }
    Ok(())
}

/// The most wrong loops a graph may have for GTSAM's GNC to run on it beside SKiD's
/// (`SKID_BENCH_PGO_PEER_MAX_WRONG`, default 20: GTSAM takes minutes on parking-garage).
fn peer_max_wrong_loops() -> usize {
    std::env::var("SKID_BENCH_PGO_PEER_MAX_WRONG")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(20)
}

/// What GTSAM's GNC answered.
#[derive(serde::Deserialize)]
struct PeerGnc {
    ms: Vec<f64>,
    outliers: Vec<[u64; 2]>,
}

/// Runs GTSAM's GNC (`python/stage_peers.py gnc`) once on `graph`, written to a temporary g2o file.
fn gtsam_gnc(python: &std::ffi::OsStr, graph: &AnyPoseGraph) -> Result<PeerGnc> {
    let folder = tempfile::tempdir()?;
    let path = folder.path().join("corrupted.g2o");
    skid_io::g2o::write_g2o(&path, graph)?;
    skid_bench::python_peers::run(python, "gnc", &[path.as_os_str(), "1".as_ref()])
}

/// The loop edges GTSAM kept: every loop whose (from, to) pair it did not name an outlier.
fn accepted_by_peer(graph: &AnyPoseGraph, loops: &[usize], outliers: &[[u64; 2]]) -> BTreeSet<usize> {
    let ends = |k: usize| match graph {
        AnyPoseGraph::ThreeD(g) => (g.edges[k].from, g.edges[k].to),
        AnyPoseGraph::TwoD(g) => (g.edges[k].from, g.edges[k].to),
    };
    let rejected: BTreeSet<(u64, u64)> = outliers.iter().map(|&[a, b]| (a, b)).collect();
    loops
        .iter()
        .copied()
        .filter(|&k| !rejected.contains(&ends(k)))
        .collect()
}

/// The robustness table.
pub fn rows(report: &mut Report, data: &std::path::Path) -> Result<()> {
    let only = std::env::var("SKID_BENCH_PGO_GRAPHS").unwrap_or_default();
    for (file, with_pcm) in [
        ("se_sync/intel.g2o", true),
        ("se_sync/sphere2500.g2o", true),
        ("se_sync/parking-garage.g2o", true),
        ("se_sync/city10000.g2o", false),
    ] {
        if !only.is_empty() && !only.split(',').any(|name| file.contains(name)) {
            continue;
        }
        for count in [20, 100] {
            case(report, data, file, count, with_pcm)?;
        }
    }
    Ok(())
}
