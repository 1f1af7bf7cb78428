//! Optimising g2o pose graphs (2D or 3D) with the options of `skid pgo FILE.g2o [--robust ...]
//! [--init chordal] [--out OUT.g2o]`, and a JSON-ready report in GTSAM's cost convention
//! (`½ Σ rᵀ Ω r`, `r = Log(Z⁻¹ T_i⁻¹ T_j)`), so results compare with other solvers.
//!
//! Gauge: the vertices of `FIX` lines are held fixed, or the lowest id when the file has none. Robust
//! kernels apply to loop closures: edges whose ids are not consecutive (`|to − from| ≠ 1`), unless
//! `robust_odometry` is set.

use std::collections::HashMap;
use std::path::Path;
use std::time::{Duration, Instant};

use nalgebra::SMatrix;
use serde::{Deserialize, Serialize};
use skid_io::g2o::{AnyPoseGraph, G2oReadOptions, GraphPose, PoseGraph, read_g2o};
use skid_io::toro::{InformationConvention, read_toro};

use crate::chordal::{chordal_2d, chordal_3d};
use crate::error::{EdgeLabel, PgoError};
use crate::gnc::{GncSettings, gnc_tls};
use crate::group::PoseGroup;
use crate::lm::{LmSettings, SystemCache, optimize};
use crate::problem::{Problem, RawEdge, Unanchored};
use crate::robust::{Kernel, RobustLoss, chi2_quantile};

/// How the loop closures are made robust.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum RobustMode {
    /// Plain least squares.
    #[default]
    None,
    Huber,
    Cauchy,
    /// Truncated least squares by plain Levenberg-Marquardt (needs a good start).
    Tls,
    /// Graduated non-convexity with the truncated-least-squares loss.
    Gnc,
}

impl RobustMode {
    /// Parses `none`, `huber`, `cauchy`, `tls` or `gnc`.
    pub fn parse(name: &str) -> Result<Self, PgoError> {
        match name {
            "none" => Ok(Self::None),
            "huber" => Ok(Self::Huber),
            "cauchy" => Ok(Self::Cauchy),
            "tls" => Ok(Self::Tls),
            "gnc" => Ok(Self::Gnc),
            other => Err(PgoError::Option(format!(
                "unknown robust mode `{other}` (none, huber, cauchy, tls, gnc)"
            ))),
        }
    }

    /// The name on the command line.
    pub fn name(&self) -> &'static str {
        match self {
            Self::None => "none",
            Self::Huber => "huber",
            Self::Cauchy => "cauchy",
            Self::Tls => "tls",
            Self::Gnc => "gnc",
        }
    }

    fn loss(&self) -> RobustLoss {
        match self {
            Self::None => RobustLoss::None,
            Self::Huber => RobustLoss::Huber,
            Self::Cauchy => RobustLoss::Cauchy,
            Self::Tls | Self::Gnc => RobustLoss::Tls,
        }
    }
}

/// The initial guess.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Initialization {
    /// The given poses: the file's vertices (or the odometry chain the reader composed for missing
    /// ones); in the back-end, the current estimate.
    #[default]
    #[serde(alias = "current")]
    File,
    /// The chordal relaxation ([`crate::chordal`]).
    Chordal,
}

impl Initialization {
    /// Parses `file` or `chordal`.
    pub fn parse(name: &str) -> Result<Self, PgoError> {
        match name {
            "file" | "none" => Ok(Self::File),
            "chordal" => Ok(Self::Chordal),
            other => Err(PgoError::Option(format!(
                "unknown initialisation `{other}` (file, chordal)"
            ))),
        }
    }
}

/// Options of [`optimize_g2o_file`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PgoOptions {
    pub robust: RobustMode,
    /// Kernel width on the Mahalanobis norm `√(rᵀΩr)`; 0 = `√χ²` quantile at `inlier_probability`.
    pub robust_width: f64,
    /// χ² probability that sets the default kernel width.
    pub inlier_probability: f64,
    /// Apply the kernel to odometry edges too.
    pub robust_odometry: bool,
    pub init: Initialization,
    pub max_iterations: usize,
    /// Stop when a step lowers the cost by less than this fraction.
    pub relative_tolerance: f64,
    pub max_duration_s: f64,
}

impl Default for PgoOptions {
    fn default() -> Self {
        Self {
            robust: RobustMode::None,
            robust_width: 0.0,
            inlier_probability: 0.99,
            robust_odometry: false,
            init: Initialization::File,
            max_iterations: 100,
            relative_tolerance: 1e-6,
            max_duration_s: 600.0,
        }
    }
}

/// What an optimisation did; serialises to the JSON line `skid pgo` prints.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct PgoReport {
    pub file: String,
    pub dimension: usize,
    pub vertices: usize,
    pub edges: usize,
    /// Edges the robust kernel applies to.
    pub loop_edges: usize,
    pub init: String,
    pub robust: String,
    pub robust_width: f64,
    /// Accepted Levenberg-Marquardt steps (summed over GNC's inner solves).
    pub iterations: usize,
    pub factorizations: usize,
    /// Seconds spent optimising, initialisation included, file reading excluded.
    pub time_s: f64,
    /// Seconds spent reading the file.
    pub read_s: f64,
    /// Cost of the file's poses, plain least squares.
    pub initial_cost: f64,
    /// Cost after the initialisation, plain least squares.
    pub start_cost: f64,
    /// Cost of the result: plain least squares, or the robust objective with a kernel.
    pub final_cost: f64,
    /// Cost of the result over the edges kept as inliers, plain least squares.
    pub final_inlier_cost: f64,
    pub converged: bool,
    pub stop: String,
    /// Loop closures beyond the kernel width at the end (rejected by TLS/GNC).
    pub outliers: usize,
    /// The cost after each accepted step (of the last solve, for GNC).
    pub costs: Vec<f64>,
    /// GNC's a-posteriori variance factor of the first run (below 1: the stated covariances are
    /// pessimistic and a second run used the scaled threshold).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub variance_factor: Option<f64>,
    /// Per edge, in file order: whether it was kept as an inlier (not serialised).
    #[serde(skip)]
    pub edge_inliers: Vec<bool>,
}

/// Reads a g2o file, optimises it and returns the report and the optimised graph.
pub fn optimize_g2o_file(
    path: impl AsRef<Path>,
    options: &PgoOptions,
) -> Result<(PgoReport, AnyPoseGraph), PgoError> {
    let path = path.as_ref();
    let start = Instant::now();
    let mut graph = read_graph_file(path)?;
    let read_s = start.elapsed().as_secs_f64();
    let mut report = match &mut graph {
        AnyPoseGraph::TwoD(g) => optimize_pose_graph::<_, 3>(g, options)?,
        AnyPoseGraph::ThreeD(g) => optimize_pose_graph::<_, 6>(g, options)?,
    };
    report.file = path.display().to_string();
    report.read_s = read_s;
    Ok((report, graph))
}

/// Reads a g2o file, or a TORO one (`.graph`, `.toro`: `VERTEX2`/`EDGE2`, `VERTEX3`/`EDGE3`).
fn read_graph_file(path: &Path) -> Result<AnyPoseGraph, PgoError> {
    let toro = path
        .extension()
        .and_then(|extension| extension.to_str())
        .is_some_and(|extension| {
            extension.eq_ignore_ascii_case("graph") || extension.eq_ignore_ascii_case("toro")
        });
    if !toro {
        return Ok(read_g2o(path, &G2oReadOptions::default())?.0);
    }
    let file = read_toro(path, InformationConvention::Toro, &G2oReadOptions::default())?;
    if !file.equivalences.is_empty() {
        tracing::warn!(
            file = %path.display(),
            count = file.equivalences.len(),
            "the TORO file's EQUIV lines (vertices to merge) are not applied"
        );
    }
    Ok(file.graph)
}

/// Writes an optimised graph as g2o.
pub fn write_g2o(path: impl AsRef<Path>, graph: &AnyPoseGraph) -> Result<(), PgoError> {
    Ok(skid_io::g2o::write_g2o(path, graph)?)
}

/// A pose type both the g2o reader and the optimiser know.
pub trait GraphGroup<const D: usize>: PoseGroup<D> + GraphPose<Information = SMatrix<f64, D, D>> {
    /// Runs the chordal initialisation on a problem of this pose type.
    fn chordal(problem: &mut Problem<Self, D>) -> Result<(), PgoError>;
}

impl GraphGroup<6> for nalgebra::Isometry3<f64> {
    fn chordal(problem: &mut Problem<Self, 6>) -> Result<(), PgoError> {
        chordal_3d(problem)
    }
}

impl GraphGroup<3> for nalgebra::Isometry2<f64> {
    fn chordal(problem: &mut Problem<Self, 3>) -> Result<(), PgoError> {
        chordal_2d(problem)
    }
}

/// Builds the validated problem of a graph, with the vertex ids in pose order.
pub fn problem_of<G: GraphGroup<D>, const D: usize>(
    graph: &PoseGraph<G>,
    robust_odometry: bool,
) -> Result<(Problem<G, D>, Vec<u64>), PgoError> {
    let ids: Vec<u64> = graph.vertices.keys().copied().collect();
    let index: HashMap<u64, usize> = ids.iter().enumerate().map(|(k, id)| (*id, k)).collect();
    let mut edges = Vec::with_capacity(graph.edges.len());
    for (k, edge) in graph.edges.iter().enumerate() {
        let lookup = |id: u64| {
            index.get(&id).copied().ok_or_else(|| PgoError::InvalidEdge {
                edge: EdgeLabel {
                    index: k,
                    from: edge.from.to_string(),
                    to: edge.to.to_string(),
                },
                reason: format!("vertex {id} is unknown (no VERTEX line and not reachable by odometry)"),
            })
        };
        let (i, j) = (lookup(edge.from)?, lookup(edge.to)?);
        let sequential = edge.from.abs_diff(edge.to) == 1;
        edges.push(RawEdge {
            i,
            j,
            measured: edge.from_from_to,
            information: edge.information,
            robust: robust_odometry || !sequential,
        });
    }
    let mut fixed = vec![false; ids.len()];
    for id in &graph.fixed {
        if let Some(&k) = index.get(id) {
            fixed[k] = true;
        }
    }
    let problem = Problem::new(
        ids.iter().map(|id| graph.vertices[id]).collect(),
        fixed,
        &edges,
        Unanchored::Error,
        &|k| ids[k].to_string(),
    )?;
    Ok((problem, ids))
}

/// Optimises an in-memory graph in place.
pub fn optimize_pose_graph<G: GraphGroup<D>, const D: usize>(
    graph: &mut PoseGraph<G>,
    options: &PgoOptions,
) -> Result<PgoReport, PgoError> {
    let start = Instant::now();
    let (mut problem, ids) = problem_of::<G, D>(graph, options.robust_odometry)?;
    let plain = |_: usize, s: f64| s;
    let initial_cost = problem.cost(&plain);
    if options.init == Initialization::Chordal {
        G::chordal(&mut problem)?;
    }
    let start_cost = problem.cost(&plain);
    let width = if options.robust_width > 0.0 {
        options.robust_width
    } else {
        chi2_quantile(D, options.inlier_probability).sqrt()
    };
    let kernel = Kernel::new(options.robust.loss(), width).map_err(PgoError::Option)?;
    if !(options.max_duration_s.is_finite() && options.max_duration_s > 0.0) {
        return Err(PgoError::Option(format!(
            "max_duration_s must be positive, got {}",
            options.max_duration_s
        )));
    }
    let settings = LmSettings {
        max_iterations: options.max_iterations,
        max_duration: Duration::from_secs_f64(options.max_duration_s),
        relative_cost_tolerance: options.relative_tolerance,
        ..LmSettings::default()
    };
    let mut cache = SystemCache::<D>::default();
    let mut costs = Vec::new();
    let mut variance_factor = None;
    let (iterations, factorizations, final_cost, converged, stop, weights) =
        if options.robust == RobustMode::Gnc {
            let gnc = GncSettings {
                threshold_squared: width * width,
                inner: settings,
                ..GncSettings::default()
            };
            let outcome = gnc_tls(&mut problem, &gnc, &mut cache)?;
            let stop = format!("{:?}", outcome.last.stop);
            costs.clone_from(&outcome.last.costs);
            variance_factor = outcome.variance_factor;
            (
                outcome.total_iterations,
                outcome.factorizations,
                outcome.last.final_cost,
                outcome.last.converged(),
                stop,
                Some(outcome.weights),
            )
        } else {
            let outcome = optimize(&mut problem, &kernel, &settings, &mut cache)?;
            costs.clone_from(&outcome.costs);
            (
                outcome.iterations,
                outcome.factorizations,
                outcome.final_cost,
                outcome.converged(),
                format!("{:?}", outcome.stop),
                None,
            )
        };
    let norms = problem.squared_norms();
    let is_outlier = |k: usize| match &weights {
        Some(w) => w[k] == 0.0,
        None => problem.factors[k].robust && options.robust != RobustMode::None && norms[k] > width * width,
    };
    let outliers = (0..norms.len()).filter(|&k| is_outlier(k)).count();
    let final_inlier_cost = (0..norms.len())
        .filter(|&k| !is_outlier(k))
        .map(|k| 0.5 * norms[k])
        .sum();
    for (k, id) in ids.iter().enumerate() {
        graph.vertices.insert(*id, problem.poses[k]);
    }
    Ok(PgoReport {
        file: String::new(),
        dimension: if D == 6 { 3 } else { 2 },
        vertices: ids.len(),
        edges: problem.factors.len(),
        loop_edges: problem.factors.iter().filter(|f| f.robust).count(),
        init: format!("{:?}", options.init).to_lowercase(),
        robust: options.robust.name().to_owned(),
        robust_width: if options.robust == RobustMode::None {
            0.0
        } else {
            width
        },
        iterations,
        factorizations,
        time_s: start.elapsed().as_secs_f64(),
        read_s: 0.0,
        initial_cost,
        start_cost,
        final_cost,
        final_inlier_cost,
        converged,
        stop,
        outliers,
        costs,
        variance_factor,
        edge_inliers: (0..norms.len()).map(|k| !is_outlier(k)).collect(),
    })
}
