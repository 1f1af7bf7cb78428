//! Chordal initialisation (Martinec & Pajdla, CVPR 2007; Carlone et al., "Initialization techniques for
//! 3D SLAM: a survey on rotation estimation and its use in pose graph optimization", ICRA 2015): the
//! rotations solve the linear least-squares problem `Σ κ ‖R_j − R_i Z_ij‖²_F` over unconstrained 3x3 (2x2)
//! matrices and are projected back to SO(3) (SO(2)); the translations then solve the linear problem
//! `Σ τ ‖t_j − t_i − R_i t_ij‖²` with those rotations. Fixed poses keep their values. The weights are
//! SE-Sync's isotropic reductions of each information matrix (Rosen et al., IJRR 2019): in 3D
//! `τ = 3 / tr(Σ_t)`, `κ = 3 / (2 tr(Σ_R))`; in 2D `τ = 2 / tr(Σ_t)`, `κ = Ω_θθ` (`Σ` = the inverse of the
//! information). Both linear problems reuse the sparse Cholesky machinery of [`crate::linear`].

use nalgebra::{
    Isometry2, Isometry3, Matrix3, SMatrix, SVector, Translation3, UnitComplex, UnitQuaternion, Vector2,
};

use crate::error::PgoError;
use crate::group::PoseGroup;
use crate::linear::BlockSystem;
use crate::problem::Problem;

/// One linear residual `A_i X_i + A_j X_j + C` with scalar weight, unknowns `X` of size `D x M`.
struct LinearEdge<const D: usize, const M: usize> {
    i: usize,
    j: usize,
    a_i: SMatrix<f64, D, D>,
    a_j: SMatrix<f64, D, D>,
    constant: SMatrix<f64, D, M>,
    weight: f64,
}

/// Solves `min Σ w ‖A_i X_i + A_j X_j + C‖²_F` with the fixed poses' unknowns taken from `known`.
fn solve_linear<const D: usize, const M: usize>(
    fixed: &[bool],
    edges: &[LinearEdge<D, M>],
    known: &[SMatrix<f64, D, M>],
) -> Result<Vec<SMatrix<f64, D, M>>, PgoError> {
    let mut block_of = vec![None; fixed.len()];
    let mut blocks = 0;
    for (k, f) in fixed.iter().enumerate() {
        if !f {
            block_of[k] = Some(blocks);
            blocks += 1;
        }
    }
    if blocks == 0 {
        return Ok(known.to_vec());
    }
    let pairs: Vec<(usize, usize)> = edges
        .iter()
        .filter_map(|e| Some((block_of[e.i]?, block_of[e.j]?)))
        .collect();
    let (mut system, slots) = BlockSystem::<D>::new(blocks, &pairs)?;
    let mut values = vec![0.0; system.value_count()];
    let n = blocks * D;
    let mut rhs = vec![0.0; n * M];
    let mut next_slot = slots.iter();
    for e in edges {
        let (bi, bj) = (block_of[e.i], block_of[e.j]);
        // Move the fixed poses' terms into the constant.
        let mut constant = e.constant;
        if bi.is_none() {
            constant += e.a_i * known[e.i];
        }
        if bj.is_none() {
            constant += e.a_j * known[e.j];
        }
        for (b, a) in [(bi, &e.a_i), (bj, &e.a_j)] {
            if let Some(b) = b {
                system.add_diagonal(&mut values, b, &(a.transpose() * a * e.weight));
                let g = a.transpose() * constant * (-e.weight);
                for c in 0..M {
                    for r in 0..D {
                        rhs[c * n + b * D + r] += g[(r, c)];
                    }
                }
            }
        }
        if bi.is_some()
            && bj.is_some()
            && let Some(slot) = next_slot.next()
        {
            system.add_off_diagonal(&mut values, slot, &(e.a_i.transpose() * e.a_j * e.weight));
        }
    }
    if !system.factorize(&values) || !system.solve_factorized(&mut rhs, M)? {
        return Err(PgoError::Solver(
            "the chordal relaxation is singular (is the graph connected?)".into(),
        ));
    }
    Ok((0..fixed.len())
        .map(|k| match block_of[k] {
            Some(b) => SMatrix::<f64, D, M>::from_fn(|r, c| rhs[c * n + b * D + r]),
            None => known[k],
        })
        .collect())
}

/// What the chordal relaxation needs to know of a pose group whose information matrices are `N x N`,
/// whose translations have `D` coordinates and whose rotations are relaxed to unconstrained `D x M`
/// unknowns.
trait ChordalGroup<const N: usize, const D: usize, const M: usize>: Sized {
    type Rotation: Copy;

    /// The SE-Sync weights `(τ, κ)` of an information matrix.
    fn weights(information: &SMatrix<f64, N, N>) -> (f64, f64);

    /// `A` in the rotation residual `A X_i + X_j` of a measurement whose rotation is `z`.
    fn rotation_coefficient(z: &Self::Rotation) -> SMatrix<f64, D, D>;

    /// The relaxed unknown of a rotation.
    fn unknown_of(rotation: &Self::Rotation) -> SMatrix<f64, D, M>;

    /// The rotation nearest to a relaxed unknown, or `None` when there is none (not finite, or zero).
    fn project(unknown: &SMatrix<f64, D, M>) -> Option<Self::Rotation>;

    fn rotation(&self) -> Self::Rotation;

    fn translation(&self) -> SVector<f64, D>;

    fn rotate(rotation: &Self::Rotation, vector: &SVector<f64, D>) -> SVector<f64, D>;

    fn from_parts(translation: SVector<f64, D>, rotation: Self::Rotation) -> Self;
}

impl ChordalGroup<6, 3, 3> for Isometry3<f64> {
    type Rotation = UnitQuaternion<f64>;

    fn weights(information: &SMatrix<f64, 6, 6>) -> (f64, f64) {
        let covariance = information.try_inverse().unwrap_or_else(SMatrix::identity);
        let t = covariance.fixed_view::<3, 3>(0, 0).trace();
        let r = covariance.fixed_view::<3, 3>(3, 3).trace();
        (3.0 / t.max(1e-300), 3.0 / (2.0 * r.max(1e-300)))
    }

    // Unknown per pose: Rᵀ (its columns are the rows of R); R_j = R_i Z  <=>  R_jᵀ = Zᵀ R_iᵀ.
    fn rotation_coefficient(z: &UnitQuaternion<f64>) -> Matrix3<f64> {
        -z.to_rotation_matrix().into_inner().transpose()
    }

    fn unknown_of(rotation: &UnitQuaternion<f64>) -> Matrix3<f64> {
        rotation.to_rotation_matrix().into_inner().transpose()
    }

    fn project(unknown: &Matrix3<f64>) -> Option<UnitQuaternion<f64>> {
        project_to_so3(&unknown.transpose())
    }

    fn rotation(&self) -> UnitQuaternion<f64> {
        self.rotation
    }

    fn translation(&self) -> SVector<f64, 3> {
        self.translation.vector
    }

    fn rotate(rotation: &UnitQuaternion<f64>, vector: &SVector<f64, 3>) -> SVector<f64, 3> {
        rotation * vector
    }

    fn from_parts(translation: SVector<f64, 3>, rotation: UnitQuaternion<f64>) -> Self {
        Isometry3::from_parts(Translation3::from(translation), rotation)
    }
}

impl ChordalGroup<3, 2, 1> for Isometry2<f64> {
    type Rotation = UnitComplex<f64>;

    fn weights(information: &SMatrix<f64, 3, 3>) -> (f64, f64) {
        let covariance = information.try_inverse().unwrap_or_else(SMatrix::identity);
        let t = covariance[(0, 0)] + covariance[(1, 1)];
        (2.0 / t.max(1e-300), information[(2, 2)])
    }

    // Unknown per pose: the first column (cos, sin) of R; R_j = R_i Z gives x_j = Z x_i.
    fn rotation_coefficient(z: &UnitComplex<f64>) -> SMatrix<f64, 2, 2> {
        -z.to_rotation_matrix().into_inner()
    }

    fn unknown_of(rotation: &UnitComplex<f64>) -> Vector2<f64> {
        Vector2::new(rotation.re, rotation.im)
    }

    fn project(unknown: &Vector2<f64>) -> Option<UnitComplex<f64>> {
        (unknown.norm() > 1e-12 && unknown.iter().all(|v| v.is_finite()))
            .then(|| UnitComplex::new(unknown.y.atan2(unknown.x)))
    }

    fn rotation(&self) -> UnitComplex<f64> {
        self.rotation
    }

    fn translation(&self) -> SVector<f64, 2> {
        self.translation.vector
    }

    fn rotate(rotation: &UnitComplex<f64>, vector: &SVector<f64, 2>) -> SVector<f64, 2> {
        rotation * vector
    }

    fn from_parts(translation: SVector<f64, 2>, rotation: UnitComplex<f64>) -> Self {
        Isometry2::from_parts(translation.into(), rotation)
    }
}

/// Replaces the free poses of a problem by the chordal estimate: rotations first, then translations.
fn chordal<G, const N: usize, const D: usize, const M: usize>(
    problem: &mut Problem<G, N>,
) -> Result<(), PgoError>
where
    G: ChordalGroup<N, D, M> + PoseGroup<N>,
{
    let weights: Vec<(f64, f64)> = problem
        .factors
        .iter()
        .map(|f| G::weights(&f.information))
        .collect();
    let measured: Vec<G> = problem
        .factors
        .iter()
        .map(|f| f.measured_inverse.inverse())
        .collect();
    let rotation_edges: Vec<LinearEdge<D, M>> = problem
        .factors
        .iter()
        .zip(&weights)
        .zip(&measured)
        .map(|((f, &(_, kappa)), z)| LinearEdge {
            i: f.i,
            j: f.j,
            a_i: G::rotation_coefficient(&z.rotation()),
            a_j: SMatrix::identity(),
            constant: SMatrix::zeros(),
            weight: kappa,
        })
        .collect();
    let known: Vec<SMatrix<f64, D, M>> = problem
        .poses
        .iter()
        .map(|p| G::unknown_of(&p.rotation()))
        .collect();
    let relaxed = solve_linear(&problem.fixed, &rotation_edges, &known)?;
    let rotations: Vec<G::Rotation> = relaxed
        .iter()
        .zip(&problem.poses)
        .map(|(unknown, pose)| G::project(unknown).unwrap_or(pose.rotation()))
        .collect();
    let translation_edges: Vec<LinearEdge<D, 1>> = problem
        .factors
        .iter()
        .zip(&weights)
        .zip(&measured)
        .map(|((f, &(tau, _)), z)| LinearEdge {
            i: f.i,
            j: f.j,
            a_i: -SMatrix::identity(),
            a_j: SMatrix::identity(),
            constant: -G::rotate(&rotations[f.i], &z.translation()),
            weight: tau,
        })
        .collect();
    let known: Vec<SVector<f64, D>> = problem.poses.iter().map(G::translation).collect();
    let translations = solve_linear(&problem.fixed, &translation_edges, &known)?;
    for (k, pose) in problem.poses.iter_mut().enumerate() {
        if !problem.fixed[k] {
            *pose = G::from_parts(translations[k], rotations[k]);
        }
    }
    Ok(())
}

/// Replaces the free poses of a 3D problem by the chordal estimate.
pub fn chordal_3d(problem: &mut Problem<Isometry3<f64>, 6>) -> Result<(), PgoError> {
    chordal(problem)
}

/// Replaces the free poses of a 2D problem by the chordal estimate.
pub fn chordal_2d(problem: &mut Problem<Isometry2<f64>, 3>) -> Result<(), PgoError> {
    chordal(problem)
}

/// The rotation nearest to `m` in the Frobenius norm (by SVD), or `None` when `m` is not finite.
fn project_to_so3(m: &Matrix3<f64>) -> Option<UnitQuaternion<f64>> {
    if m.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let svd = m.svd(true, true);
    let (u, v_t) = (svd.u?, svd.v_t?);
    let mut d = Matrix3::identity();
    if (u * v_t).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    let rotation = nalgebra::Rotation3::from_matrix_unchecked(u * d * v_t);
    Some(UnitQuaternion::from_rotation_matrix(&rotation))
}
