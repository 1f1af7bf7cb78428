//! The optimisation problem: poses, which of them are fixed, and the relative-pose factors between them,
//! validated so that the solver never sees a non-finite number, an information matrix that is not
//! positive definite, an unknown vertex or a part of the graph that no fixed vertex anchors (the
//! least-squares pose-graph formulation of Lu & Milios, "Globally consistent range scan alignment for
//! environment mapping", 1997).

use nalgebra::{DMatrix, SMatrix, SymmetricEigen};

use crate::error::{EdgeLabel, PgoError};
use crate::group::PoseGroup;

/// One relative-pose measurement between two poses of the problem.
#[derive(Clone, Debug)]
pub struct Factor<G, const D: usize> {
    /// Index of the pose the measurement is expressed in.
    pub i: usize,
    /// Index of the measured pose.
    pub j: usize,
    /// The inverse of the measurement `Z = T_i⁻¹ T_j` (stored inverted: the residual needs `Z⁻¹`).
    pub measured_inverse: G,
    /// Symmetric positive-definite information matrix of the residual, translation first.
    pub information: SMatrix<f64, D, D>,
    /// True when the robust kernel applies (loop closures); odometry stays plain least squares.
    pub robust: bool,
}

/// Poses, fixed flags and factors.
#[derive(Clone, Debug)]
pub struct Problem<G, const D: usize> {
    pub poses: Vec<G>,
    pub fixed: Vec<bool>,
    pub factors: Vec<Factor<G, D>>,
}

/// An edge as the caller describes it, before validation.
#[derive(Clone, Debug)]
pub struct RawEdge<G, const D: usize> {
    pub i: usize,
    pub j: usize,
    pub measured: G,
    pub information: SMatrix<f64, D, D>,
    pub robust: bool,
}

/// What to do with parts of the graph that no fixed vertex anchors.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Unanchored {
    /// Refuse the graph, naming a vertex of the floating part.
    Error,
    /// Hold the first vertex of each floating part where it is.
    AnchorFirst,
}

/// Checks an information matrix: finite, symmetric to 1e-6 of its largest entry (Hessians accumulated in
/// single precision pass), positive definite. Returns the
/// symmetrised matrix or the reason it is unusable.
pub fn check_information<const D: usize>(
    information: &SMatrix<f64, D, D>,
) -> Result<SMatrix<f64, D, D>, String> {
    if information.iter().any(|v| !v.is_finite()) {
        return Err("the information matrix holds a non-finite number".to_owned());
    }
    let scale = information.amax().max(f64::MIN_POSITIVE);
    let asymmetry = (information - information.transpose()).amax();
    if asymmetry > 1e-6 * scale {
        return Err(format!(
            "the information matrix is not symmetric (largest difference {asymmetry:.3e})"
        ));
    }
    let symmetric = (information + information.transpose()) * 0.5;
    if symmetric.cholesky().is_none() {
        let min_eigenvalue = SymmetricEigen::new(DMatrix::from_column_slice(D, D, symmetric.as_slice()))
            .eigenvalues
            .min();
        return Err(format!(
            "the information matrix is not positive definite (smallest eigenvalue {min_eigenvalue:.6e})"
        ));
    }
    Ok(symmetric)
}

impl<G: PoseGroup<D>, const D: usize> Problem<G, D> {
    /// Builds and validates a problem. `vertex_name(k)` names pose `k` in error messages and
    /// `edge_label(e)` names edge `e` (its position in `edges`).
    pub fn new(
        poses: Vec<G>,
        mut fixed: Vec<bool>,
        edges: &[RawEdge<G, D>],
        unanchored: Unanchored,
        vertex_name: &dyn Fn(usize) -> String,
    ) -> Result<Self, PgoError> {
        if poses.is_empty() {
            return Err(PgoError::Empty("no vertices".to_owned()));
        }
        if fixed.len() != poses.len() {
            return Err(PgoError::Option(format!(
                "{} fixed flags for {} poses",
                fixed.len(),
                poses.len()
            )));
        }
        for (k, pose) in poses.iter().enumerate() {
            if !pose.is_finite() {
                return Err(PgoError::InvalidVertex {
                    vertex: vertex_name(k),
                    reason: "its pose is not finite".into(),
                });
            }
        }
        let label = |index: usize, edge: &RawEdge<G, D>| EdgeLabel {
            index,
            from: if edge.i < poses.len() {
                vertex_name(edge.i)
            } else {
                format!("#{}", edge.i)
            },
            to: if edge.j < poses.len() {
                vertex_name(edge.j)
            } else {
                format!("#{}", edge.j)
            },
        };
        let mut factors = Vec::with_capacity(edges.len());
        for (index, edge) in edges.iter().enumerate() {
            let invalid = |reason: String| PgoError::InvalidEdge {
                edge: label(index, edge),
                reason,
            };
            if edge.i >= poses.len() || edge.j >= poses.len() {
                return Err(invalid("it names an unknown vertex".to_owned()));
            }
            if edge.i == edge.j {
                return Err(invalid("it links a vertex to itself".to_owned()));
            }
            if !edge.measured.is_finite() {
                return Err(invalid("the measurement is not finite".to_owned()));
            }
            let information = check_information(&edge.information).map_err(invalid)?;
            factors.push(Factor {
                i: edge.i,
                j: edge.j,
                measured_inverse: edge.measured.inverse(),
                information,
                robust: edge.robust,
            });
        }
        anchor_components(poses.len(), &factors, &mut fixed, unanchored, vertex_name)?;
        Ok(Self {
            poses,
            fixed,
            factors,
        })
    }

    /// `½ Σ ρ(rᵀ Ω r)` at the current poses, with `rho` applied to robust factors only.
    pub fn cost(&self, rho: &dyn Fn(usize, f64) -> f64) -> f64 {
        self.factors
            .iter()
            .enumerate()
            .map(|(k, f)| {
                let r = G::between_residual(&f.measured_inverse, &self.poses[f.i], &self.poses[f.j]);
                let s = (r.transpose() * f.information * r)[(0, 0)];
                0.5 * if f.robust { rho(k, s) } else { s }
            })
            .sum()
    }

    /// The squared Mahalanobis norm of every factor's residual at the current poses.
    pub fn squared_norms(&self) -> Vec<f64> {
        self.factors
            .iter()
            .map(|f| {
                let r = G::between_residual(&f.measured_inverse, &self.poses[f.i], &self.poses[f.j]);
                (r.transpose() * f.information * r)[(0, 0)]
            })
            .collect()
    }
}

/// Union-find root with path halving.
fn root(parent: &mut [usize], mut k: usize) -> usize {
    while parent[k] != k {
        parent[k] = parent[parent[k]];
        k = parent[k];
    }
    k
}

/// Makes sure every connected component holds a fixed pose: refuses the graph or fixes the component's
/// first pose. A graph without any fixed pose gets its first pose fixed (the usual gauge choice).
fn anchor_components<G, const D: usize>(
    count: usize,
    factors: &[Factor<G, D>],
    fixed: &mut [bool],
    unanchored: Unanchored,
    vertex_name: &dyn Fn(usize) -> String,
) -> Result<(), PgoError> {
    if !fixed.iter().any(|f| *f) {
        fixed[0] = true;
    }
    let mut parent: Vec<usize> = (0..count).collect();
    for f in factors {
        let (a, b) = (root(&mut parent, f.i), root(&mut parent, f.j));
        if a != b {
            parent[a.max(b)] = a.min(b);
        }
    }
    let mut anchored = vec![false; count];
    let mut size = vec![0usize; count];
    for (k, is_fixed) in fixed.iter().enumerate() {
        let r = root(&mut parent, k);
        anchored[r] |= *is_fixed;
        size[r] += 1;
    }
    for (k, is_fixed) in fixed.iter_mut().enumerate() {
        let r = root(&mut parent, k);
        if !anchored[r] {
            match unanchored {
                Unanchored::Error => {
                    return Err(PgoError::Disconnected {
                        vertex: vertex_name(k),
                        count: size[r],
                    });
                }
                Unanchored::AnchorFirst => {
                    *is_fixed = true;
                    anchored[r] = true;
                }
            }
        }
    }
    Ok(())
}
