//! Pairwise consistency maximisation (PCM; Mangelson et al., ICRA 2018) on a multi-robot pose graph
//! given as per-robot g2o files, the form `robust_distributed_mapper` and DOOR-SLAM publish: GTSAM symbol
//! keys (the robot a letter in the top byte, `a` = robot 0, the keyframe index in the low 56 bits).
//!
//! Every file is merged, an edge seen in two files (each robot's file repeats the loops it shares) is kept
//! once, consecutive keyframes of one robot are odometry and every other edge is a loop closure. The loops
//! are offered to SKiD's PCM in file order against the odometry chains, as the running system offers
//! them, deciding from the first loop on. This is `skid pcm` and the pgo benchmark's multi-robot table.

use std::collections::BTreeSet;
use std::path::PathBuf;
use std::time::Instant;

use nalgebra::Matrix6;
use skid_backend_pgo::{PgoBackend, PgoConfig};
use skid_core::slots::{Backend, LoopClosure, OdometryMeasurement};
use skid_core::{KeyframeId, LoopId, PluginContext};
use skid_io::g2o::{G2oReadOptions, PoseGraph3, read_g2o_3d};
use skid_verifier_pcm::{Pcm, PcmLoop, PcmParams};

/// Why a set could not be read or verified.
#[derive(Debug, thiserror::Error)]
pub enum PcmSetError {
    #[error("{path}: {message}")]
    Input { path: PathBuf, message: String },
    /// A g2o file that could not be read (the message names the file and line).
    #[error("{0}")]
    Read(String),
    #[error(
        "key {key} has no robot letter in its top byte ({byte:#04x}); expected GTSAM symbol keys a..z, A..Z"
    )]
    Key { key: u64, byte: u8 },
    #[error("{0}")]
    Pcm(String),
}

/// A GTSAM symbol key as a keyframe id: robot `a` = 0 … `z` = 25, `A` = 26 … `Z` = 51.
pub fn keyframe_of_key(key: u64) -> Result<KeyframeId, PcmSetError> {
    let byte = (key >> 56) as u8;
    let robot = match byte {
        b'a'..=b'z' => byte - b'a',
        b'A'..=b'Z' => byte - b'A' + 26,
        _ => return Err(PcmSetError::Key { key, byte }),
    };
    let index = u32::try_from(key & ((1 << 56) - 1)).map_err(|_| PcmSetError::Key { key, byte })?;
    Ok(KeyframeId::new(u32::from(robot), index))
}

/// A key as GTSAM prints it: the robot letter and the index (`b40`).
pub fn key_name(key: u64) -> String {
    format!("{}{}", char::from((key >> 56) as u8), key & ((1 << 56) - 1))
}

/// The merged graph of a set and what reading it found.
#[derive(Clone, Debug, Default)]
pub struct MultiRobotGraph {
    pub graph: PoseGraph3,
    pub files: Vec<PathBuf>,
    /// Edges dropped because another file already held an edge between the same two keys.
    pub duplicate_edges: usize,
    /// Malformed lines skipped, as `(file, line number)`.
    pub skipped_lines: Vec<(PathBuf, usize)>,
}

/// The `.g2o` files of `paths`: a folder stands for every `.g2o` in it, sorted by name.
fn g2o_files(paths: &[PathBuf]) -> Result<Vec<PathBuf>, PcmSetError> {
    let mut files = Vec::new();
    for path in paths {
        if path.is_dir() {
            let listing = std::fs::read_dir(path).map_err(|e| PcmSetError::Input {
                path: path.clone(),
                message: e.to_string(),
            })?;
            let mut found: Vec<PathBuf> = listing
                .filter_map(|entry| entry.ok().map(|entry| entry.path()))
                .filter(|file| file.extension().is_some_and(|ext| ext == "g2o"))
                .collect();
            found.sort();
            if found.is_empty() {
                return Err(PcmSetError::Input {
                    path: path.clone(),
                    message: "holds no .g2o file".into(),
                });
            }
            files.extend(found);
        } else {
            files.push(path.clone());
        }
    }
    Ok(files)
}

/// Reads and merges every robot's file (malformed lines are skipped and listed).
pub fn read_set(paths: &[PathBuf]) -> Result<MultiRobotGraph, PcmSetError> {
    let mut merged = MultiRobotGraph {
        files: g2o_files(paths)?,
        ..MultiRobotGraph::default()
    };
    let mut seen = BTreeSet::new();
    for file in &merged.files {
        let options = G2oReadOptions {
            skip_malformed: true,
            ..G2oReadOptions::default()
        };
        let (graph, report) = read_g2o_3d(file, &options).map_err(|e| PcmSetError::Read(e.to_string()))?;
        // Every key must name its robot; say which file holds one that does not.
        for &key in graph.vertices.keys() {
            keyframe_of_key(key).map_err(|error| PcmSetError::Input {
                path: file.clone(),
                message: format!("{error} (every file of a set is one robot's graph with GTSAM symbol keys)"),
            })?;
        }
        merged
            .skipped_lines
            .extend(report.malformed_lines.iter().map(|line| (file.clone(), *line)));
        merged.graph.vertices.extend(graph.vertices);
        for edge in graph.edges {
            let key = (edge.from.min(edge.to), edge.from.max(edge.to));
            if seen.insert(key) {
                merged.graph.edges.push(edge);
            } else {
                merged.duplicate_edges += 1;
            }
        }
    }
    Ok(merged)
}

/// A loop closure of the set, by its file keys.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SetLoop {
    /// Its order among the set's loops (the PCM loop id).
    pub id: u64,
    pub from_key: u64,
    pub to_key: u64,
}

/// What PCM decided on a set.
#[derive(Clone, Debug)]
pub struct PcmSetResult {
    pub robots: usize,
    pub loops: Vec<SetLoop>,
    pub accepted: Vec<SetLoop>,
    /// Time PCM took over all loops, milliseconds.
    pub verify_ms: f64,
}

/// Offers every loop of `set` to PCM in file order; `unit_covariance` replaces the files' information
/// matrices by identities.
pub fn run_pcm(
    set: &MultiRobotGraph,
    params: &PcmParams,
    unit_covariance: bool,
) -> Result<PcmSetResult, PcmSetError> {
    let mut chains = PgoBackend::new(PgoConfig::default(), &PluginContext::default())
        .map_err(|e| PcmSetError::Pcm(e.to_string()))?;
    let mut robots = BTreeSet::new();
    for (key, pose) in &set.graph.vertices {
        let id = keyframe_of_key(*key)?;
        robots.insert(id.robot);
        chains
            .add_keyframe(id, *pose)
            .map_err(|e| PcmSetError::Pcm(e.to_string()))?;
    }
    let mut loops = Vec::new();
    let mut closures = Vec::new();
    for edge in &set.graph.edges {
        let (from, to) = (keyframe_of_key(edge.from)?, keyframe_of_key(edge.to)?);
        let information = if unit_covariance {
            Matrix6::identity()
        } else {
            edge.information
        };
        if from.robot == to.robot && to.index == from.index + 1 {
            let odometry = OdometryMeasurement {
                target: from,
                source: to,
                target_from_source: edge.from_from_to,
                information,
            };
            chains
                .add_odometry(odometry)
                .map_err(|e| PcmSetError::Pcm(e.to_string()))?;
        } else {
            let id = loops.len() as u64;
            loops.push(SetLoop {
                id,
                from_key: edge.from,
                to_key: edge.to,
            });
            closures.push(LoopClosure {
                id: LoopId(id),
                target: from,
                source: to,
                target_from_source: edge.from_from_to,
                information,
            });
        }
    }
    let started = Instant::now();
    let mut pcm = Pcm::new(params.clone()).map_err(PcmSetError::Pcm)?;
    for closure in &closures {
        let candidate = PcmLoop::from_closure(closure).map_err(PcmSetError::Pcm)?;
        pcm.add(candidate, &chains).map_err(PcmSetError::Pcm)?;
    }
    let verify_ms = started.elapsed().as_secs_f64() * 1e3;
    let accepted_ids: BTreeSet<LoopId> = pcm.accepted().into_iter().collect();
    let accepted = loops
        .iter()
        .filter(|set_loop| accepted_ids.contains(&LoopId(set_loop.id)))
        .copied()
        .collect();
    Ok(PcmSetResult {
        robots: robots.len(),
        loops,
        accepted,
        verify_ms,
    })
}

/// The parameters `skid pcm` and the benchmark use: PCM's defaults, deciding from the first loop on.
/// A set is verified as Mangelson et al. verify it, so the runtime's earned-merge rules (spread,
/// dominance over a rival set, predictions and repeats checked on descriptors) are off: a set file holds one pair's
/// loops as a batch, with no later loops to settle a contest and no descriptors.
pub fn set_params() -> PcmParams {
    PcmParams {
        min_loops_before_decision: 1,
        min_spread_m: 0.0,
        dominance_ratio: 0.0,
        predicted_overlap_m: 0.0,
        repeat_beyond_m: 0.0,
        ..PcmParams::default()
    }
}

/// Reads `paths` and runs PCM: the convenience `skid pcm` calls.
pub fn verify_set(
    paths: &[PathBuf],
    unit_covariance: bool,
) -> Result<(MultiRobotGraph, PcmSetResult), PcmSetError> {
    let set = read_set(paths)?;
    let result = run_pcm(&set, &set_params(), unit_covariance)?;
    Ok((set, result))
}

/// The set's graph keeping its odometry and only the loops PCM accepted, to optimise after PCM.
pub fn accepted_graph(set: &MultiRobotGraph, result: &PcmSetResult) -> Result<PoseGraph3, PcmSetError> {
    let accepted: BTreeSet<(u64, u64)> = result
        .accepted
        .iter()
        .map(|set_loop| (set_loop.from_key, set_loop.to_key))
        .collect();
    let mut graph = PoseGraph3 {
        edges: Vec::new(),
        ..set.graph.clone()
    };
    for edge in &set.graph.edges {
        let (from, to) = (keyframe_of_key(edge.from)?, keyframe_of_key(edge.to)?);
        let odometry = from.robot == to.robot && to.index == from.index + 1;
        if odometry || accepted.contains(&(edge.from, edge.to)) {
            graph.edges.push(*edge);
        }
    }
    Ok(graph)
}
