//! g2o pose graphs, 2D and 3D: the graph types, the reader (with an odometry-chain initial guess for
//! vertices the file does not list) and the writer.
//!
//! ## Format
//!
//! One element per line, the tag first:
//!
//! * `VERTEX_SE3:QUAT id x y z qx qy qz qw`: pose of vertex `id` in the world frame (`world_from_vertex`).
//! * `EDGE_SE3:QUAT from to x y z qx qy qz qw` + 21 numbers: the measured pose of `to` expressed in the
//!   frame of `from` (`from_from_to`, i.e. `inv(world_from_from) * world_from_to`), then the upper
//!   triangle of the 6x6 information matrix, row by row, in the order `x y z` then rotation (g2o's
//!   rotation residual is the vector part of the error quaternion).
//! * `VERTEX_SE2 id x y theta` and `EDGE_SE2 from to dx dy dtheta` + 6 numbers (upper triangle of the
//!   3x3 information, order `x y theta`), same conventions in the plane.
//! * `FIX id [id ...]`: vertices held fixed by the optimiser (recorded in [`PoseGraph::fixed`]).
//! * Blank lines and lines starting with `#` are ignored.
//!
//! Quaternions are normalised when read (a zero quaternion is an error). Information matrices are
//! stored symmetric and **not** checked for definiteness (some published graphs, e.g. SE-Sync's
//! `cubicle.g2o`, have indefinite ones); non-finite numbers are errors.
//!
//! ## Tolerated tags
//!
//! These tags are skipped and counted in [`G2oReport::skipped`] (landmarks, priors, calibration and
//! other vertex types that a pose graph does not use): `VERTEX_XY`, `VERTEX_XYZ`, `VERTEX_TRACKXYZ`,
//! `VERTEX_POINTXYZ`, `VERTEX_SE3:EXPMAP`, `VERTEX_CAM`, `VERTEX_INTRINSICS`, `EDGE_SE2_XY`,
//! `EDGE_SE2_POINT_XY`, `EDGE_BEARING_SE2_XY`, `EDGE_SE2_PRIOR`, `EDGE_SE2_XYPRIOR`,
//! `EDGE_SE2_OFFSET`, `EDGE_SE3_XYZ`, `EDGE_SE3_POINTXYZ`, `EDGE_SE3_TRACKXYZ`, `EDGE_SE3_PRIOR`,
//! `EDGE_SE3_OFFSET`, `EDGE_PROJECT_XYZ2UV:EXPMAP`, `PARAMS_SE3OFFSET`, `PARAMS_CAMERACALIB`,
//! `PARAMS_STEREOCAMERACALIB`, `CACHE_SE3_OFFSET`. Any other tag is an error naming the line, unless
//! [`G2oReadOptions::skip_malformed`] is set. The pose tags of the other dimension (e.g.
//! `VERTEX_SE2` in a file read with [`read_g2o_3d`]) are errors.
//!
//! ## Vertices the file does not list
//!
//! Many benchmark graphs (SE-Sync's `CSAIL`, `manhattan`, `kitti_*`) have edges only. With
//! [`MissingVertices::Guess`] (the default) a missing vertex gets an initial guess by **chaining
//! odometry**: the edges `i -> i + 1` (or, when there is none, `i + 1 -> i` inverted) are composed, forwards from the nearest known vertex below
//! (`pose(i+1) = pose(i) * from_from_to`) and backwards from the nearest known vertex above. When the
//! file has no vertex lines at all, every chain start (a missing id without an `i-1 -> i` edge) is placed
//! at the origin, so the whole chain starts at the identity. Ids that still cannot be reached (typical
//! in per-robot multi-robot files, where inter-robot edges name the other robot's poses) are left
//! without a pose and listed in [`G2oReport::unresolved`]. With [`MissingVertices::Error`] any edge
//! naming a vertex without a `VERTEX` line is an error naming the edge's line.

pub(crate) mod guess;
pub(crate) mod read;
mod write;

use std::collections::BTreeMap;

use nalgebra::{Isometry2, Isometry3, Matrix3, Matrix6};

pub use read::{read_g2o, read_g2o_2d, read_g2o_3d};
pub use write::{g2o_text_2d, g2o_text_3d, write_g2o, write_g2o_2d, write_g2o_3d};

/// A pose type a graph can hold: an SE(2) or SE(3) isometry with its information-matrix type.
pub trait GraphPose: Copy + std::fmt::Debug + PartialEq {
    /// The information matrix of a relative measurement (3x3 in 2D, 6x6 in 3D).
    type Information: Copy + std::fmt::Debug + PartialEq;
    /// The identity pose.
    fn identity() -> Self;
    /// `self * other`.
    fn compose(&self, other: &Self) -> Self;
    /// `self^-1`.
    fn inverse(&self) -> Self;
}

impl GraphPose for Isometry3<f64> {
    type Information = Matrix6<f64>;
    fn identity() -> Self {
        Isometry3::identity()
    }
    fn compose(&self, other: &Self) -> Self {
        self * other
    }
    fn inverse(&self) -> Self {
        Isometry3::inverse(self)
    }
}

impl GraphPose for Isometry2<f64> {
    type Information = Matrix3<f64>;
    fn identity() -> Self {
        Isometry2::identity()
    }
    fn compose(&self, other: &Self) -> Self {
        self * other
    }
    fn inverse(&self) -> Self {
        Isometry2::inverse(self)
    }
}

/// A relative-pose measurement between two vertices.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Edge<P: GraphPose> {
    /// The vertex whose frame the measurement is expressed in.
    pub from: u64,
    /// The vertex whose pose is measured.
    pub to: u64,
    /// The pose of `to` in the frame of `from` (`inv(world_from_from) * world_from_to` when noise-free).
    pub from_from_to: P,
    /// Symmetric information matrix (inverse covariance) of the measurement, order `x y [z] rotation`.
    pub information: P::Information,
}

/// A pose graph: vertex poses in the world frame, relative measurements and the fixed vertices.
#[derive(Clone, Debug, PartialEq)]
pub struct PoseGraph<P: GraphPose> {
    /// `world_from_vertex` of every vertex that has a pose (from the file or guessed), by id.
    pub vertices: BTreeMap<u64, P>,
    /// The measurements, in file order.
    pub edges: Vec<Edge<P>>,
    /// Ids of the vertices held fixed (`FIX` lines), in file order.
    pub fixed: Vec<u64>,
}

impl<P: GraphPose> Default for PoseGraph<P> {
    fn default() -> Self {
        Self {
            vertices: BTreeMap::new(),
            edges: Vec::new(),
            fixed: Vec::new(),
        }
    }
}

impl<P: GraphPose> PoseGraph<P> {
    /// Ids named by some edge that have no pose in [`PoseGraph::vertices`], ascending, without repeats.
    pub fn missing_vertices(&self) -> Vec<u64> {
        let mut missing: Vec<u64> = self
            .edges
            .iter()
            .flat_map(|e| [e.from, e.to])
            .filter(|id| !self.vertices.contains_key(id))
            .collect();
        missing.sort_unstable();
        missing.dedup();
        missing
    }

    /// Number of edges `i -> i + 1` (odometry) and of the other edges (loop closures and the like).
    pub fn count_sequential_edges(&self) -> (usize, usize) {
        let sequential = self
            .edges
            .iter()
            .filter(|e| e.from.checked_add(1) == Some(e.to))
            .count();
        (sequential, self.edges.len() - sequential)
    }
}

/// A 3D edge (`EDGE_SE3:QUAT`).
pub type Edge3 = Edge<Isometry3<f64>>;
/// A 2D edge (`EDGE_SE2`).
pub type Edge2 = Edge<Isometry2<f64>>;
/// A 3D pose graph.
pub type PoseGraph3 = PoseGraph<Isometry3<f64>>;
/// A 2D pose graph.
pub type PoseGraph2 = PoseGraph<Isometry2<f64>>;

/// A graph of either dimension, as returned by [`read_g2o`].
#[derive(Clone, Debug, PartialEq)]
pub enum AnyPoseGraph {
    /// The file uses `VERTEX_SE2`/`EDGE_SE2`.
    TwoD(PoseGraph2),
    /// The file uses `VERTEX_SE3:QUAT`/`EDGE_SE3:QUAT` (also the result for a file with no pose lines).
    ThreeD(PoseGraph3),
}

impl AnyPoseGraph {
    /// `(vertices, edges)` counts.
    pub fn counts(&self) -> (usize, usize) {
        match self {
            AnyPoseGraph::TwoD(g) => (g.vertices.len(), g.edges.len()),
            AnyPoseGraph::ThreeD(g) => (g.vertices.len(), g.edges.len()),
        }
    }
}

/// What to do with edges naming vertices that have no `VERTEX` line.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MissingVertices {
    /// Guess their poses by chaining odometry; list the ones that cannot be reached in the report.
    #[default]
    Guess,
    /// Fail at the first such edge, naming its line.
    Error,
}

/// Options of the g2o (and TORO) readers.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct G2oReadOptions {
    /// What to do with edges naming unlisted vertices.
    pub missing_vertices: MissingVertices,
    /// Skip malformed lines and unknown tags instead of failing, listing their line numbers in
    /// [`G2oReport::malformed_lines`]. Off by default.
    pub skip_malformed: bool,
}

/// What a pose-graph reader saw besides the graph.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct G2oReport {
    /// Number of `VERTEX` lines read (vertices from the file, not guessed).
    pub vertex_lines: usize,
    /// Tolerated tags that were skipped, with how many lines each.
    pub skipped: BTreeMap<String, usize>,
    /// Ids whose pose was guessed by chaining odometry, ascending.
    pub guessed: Vec<u64>,
    /// Ids named by edges that have no pose (neither listed nor reachable by odometry), ascending.
    pub unresolved: Vec<u64>,
    /// Lines skipped as malformed under [`G2oReadOptions::skip_malformed`].
    pub malformed_lines: Vec<usize>,
}

/// Full symmetric matrix from its upper triangle given row by row.
pub(crate) fn symmetric_from_upper<const N: usize>(upper: &[f64]) -> nalgebra::SMatrix<f64, N, N> {
    let mut m = nalgebra::SMatrix::<f64, N, N>::zeros();
    let mut k = 0;
    for r in 0..N {
        for c in r..N {
            m[(r, c)] = upper[k];
            m[(c, r)] = upper[k];
            k += 1;
        }
    }
    m
}

/// The upper triangle of a square matrix, row by row.
pub(crate) fn upper_of<const N: usize>(m: &nalgebra::SMatrix<f64, N, N>) -> Vec<f64> {
    let mut upper = Vec::with_capacity(N * (N + 1) / 2);
    for r in 0..N {
        for c in r..N {
            upper.push(m[(r, c)]);
        }
    }
    upper
}
