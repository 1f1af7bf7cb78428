//! Chordal initialisation (Martinec & Pajdla, CVPR 2007; Carlone et al., "Initialization techniques for
//! 3D SLAM: a survey on rotation estimation and its use in pose graph optimization", ICRA 2015): the
//! rotations solve the linear least-squares problem `Σ κ ‖R_j − R_i Z_ij‖²_F` over unconstrained 3x3 (2x2)
//! matrices and are projected back to SO(3) (SO(2)); the translations then solve the linear problem
//! `Σ τ ‖t_j − t_i − R_i t_ij‖²` with those rotations. Fixed poses keep their values. The weights are
//! SE-Sync's isotropic reductions of each information matrix (Rosen et al., IJRR 2019): in 3D
//! `τ = 3 / tr(Σ_t)`, `κ = 3 / (2 tr(Σ_R))`; in 2D `τ = 2 / tr(Σ_t)`, `κ = Ω_θθ` (`Σ` = the inverse of the
//! information). Both linear problems reuse the sparse Cholesky machinery of [`crate::linear`].

use nalgebra::{Isometry2, Isometry3, Matrix3, SMatrix, Translation3, UnitComplex, UnitQuaternion, Vector2};

use crate::error::PgoError;
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

/// The SE-Sync weights `(τ, κ)` of a 6x6 information matrix.
fn weights_3d(information: &SMatrix<f64, 6, 6>) -> (f64, f64) {
    let covariance = information.try_inverse().unwrap_or_else(SMatrix::identity);
    let t = covariance.fixed_view::<3, 3>(0, 0).trace();
    let r = covariance.fixed_view::<3, 3>(3, 3).trace();
    (3.0 / t.max(1e-300), 3.0 / (2.0 * r.max(1e-300)))
}

/// Replaces the free poses of a 3D problem by the chordal estimate.
pub fn chordal_3d(problem: &mut Problem<Isometry3<f64>, 6>) -> Result<(), PgoError> {
    let weights: Vec<(f64, f64)> = problem
        .factors
        .iter()
        .map(|f| weights_3d(&f.information))
        .collect();
    // Unknown per pose: Rᵀ (its columns are the rows of R); R_j = R_i Z  <=>  R_jᵀ = Zᵀ R_iᵀ.
    let rotation_edges: Vec<LinearEdge<3, 3>> = problem
        .factors
        .iter()
        .zip(&weights)
        .map(|(f, &(_, kappa))| {
            let z = f
                .measured_inverse
                .rotation
                .inverse()
                .to_rotation_matrix()
                .into_inner();
            LinearEdge {
                i: f.i,
                j: f.j,
                a_i: -z.transpose(),
                a_j: Matrix3::identity(),
                constant: Matrix3::zeros(),
                weight: kappa,
            }
        })
        .collect();
    let known: Vec<Matrix3<f64>> = problem
        .poses
        .iter()
        .map(|p| p.rotation.to_rotation_matrix().into_inner().transpose())
        .collect();
    let relaxed = solve_linear(&problem.fixed, &rotation_edges, &known)?;
    let rotations: Vec<UnitQuaternion<f64>> = relaxed
        .iter()
        .zip(&problem.poses)
        .map(|(m, pose)| project_to_so3(&m.transpose()).unwrap_or(pose.rotation))
        .collect();
    let translation_edges: Vec<LinearEdge<3, 1>> = problem
        .factors
        .iter()
        .zip(&weights)
        .map(|(f, &(tau, _))| {
            let measured_t = f.measured_inverse.inverse().translation.vector;
            LinearEdge {
                i: f.i,
                j: f.j,
                a_i: -Matrix3::identity(),
                a_j: Matrix3::identity(),
                constant: -(rotations[f.i] * measured_t),
                weight: tau,
            }
        })
        .collect();
    let known: Vec<_> = problem.poses.iter().map(|p| p.translation.vector).collect();
    let translations = solve_linear(&problem.fixed, &translation_edges, &known)?;
    for (k, pose) in problem.poses.iter_mut().enumerate() {
        if !problem.fixed[k] {
            *pose = Isometry3::from_parts(Translation3::from(translations[k]), rotations[k]);
        }
    }
    Ok(())
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

/// Replaces the free poses of a 2D problem by the chordal estimate.
pub fn chordal_2d(problem: &mut Problem<Isometry2<f64>, 3>) -> Result<(), PgoError> {
    let weights: Vec<(f64, f64)> = problem
        .factors
        .iter()
        .map(|f| {
            let covariance = f.information.try_inverse().unwrap_or_else(SMatrix::identity);
            let t = covariance[(0, 0)] + covariance[(1, 1)];
            (2.0 / t.max(1e-300), f.information[(2, 2)])
        })
        .collect();
    // Unknown per pose: the first column (cos, sin) of R; R_j = R_i Z gives x_j = Z x_i.
    let rotation_edges: Vec<LinearEdge<2, 1>> = problem
        .factors
        .iter()
        .zip(&weights)
        .map(|(f, &(_, kappa))| {
            let z = f
                .measured_inverse
                .rotation
                .inverse()
                .to_rotation_matrix()
                .into_inner();
            LinearEdge {
                i: f.i,
                j: f.j,
                a_i: -z,
                a_j: SMatrix::identity(),
                constant: Vector2::zeros(),
                weight: kappa,
            }
        })
        .collect();
    let known: Vec<Vector2<f64>> = problem
        .poses
        .iter()
        .map(|p| Vector2::new(p.rotation.re, p.rotation.im))
        .collect();
    let relaxed = solve_linear(&problem.fixed, &rotation_edges, &known)?;
    let rotations: Vec<UnitComplex<f64>> = relaxed
        .iter()
        .zip(&problem.poses)
        .map(|(x, pose)| {
            if x.norm() > 1e-12 && x.iter().all(|v| v.is_finite()) {
                UnitComplex::new(x.y.atan2(x.x))
            } else {
                pose.rotation
            }
        })
        .collect();
    let translation_edges: Vec<LinearEdge<2, 1>> = problem
        .factors
        .iter()
        .zip(&weights)
        .map(|(f, &(tau, _))| {
            let measured_t = f.measured_inverse.inverse().translation.vector;
            LinearEdge {
                i: f.i,
                j: f.j,
                a_i: -SMatrix::identity(),
                a_j: SMatrix::identity(),
                constant: -(rotations[f.i] * measured_t),
                weight: tau,
            }
        })
        .collect();
    let known: Vec<_> = problem.poses.iter().map(|p| p.translation.vector).collect();
    let translations = solve_linear(&problem.fixed, &translation_edges, &known)?;
    for (k, pose) in problem.poses.iter_mut().enumerate() {
        if !problem.fixed[k] {
            *pose = Isometry2::from_parts(translations[k].into(), rotations[k]);
        }
    }
    Ok(())
}
