//! The pose types the optimiser works on, behind one trait: SE(3) (`Isometry3`, 6 degrees of freedom)
//! and SE(2) (`Isometry2`, 3 degrees of freedom).
//!
//! The residual of a relative-pose measurement `Z` between poses `T_i` and `T_j` is the one GTSAM's
//! `BetweenFactor` uses (Dellaert & Kaess, "Factor Graphs for Robot Perception", 2017):
//! `r = Log(Z⁻¹ · T_i⁻¹ · T_j)`, the full group logarithm with the translation part first
//! (`ρ = V(φ)⁻¹ t`, then the rotation vector `φ`), so that costs compare with GTSAM's. Poses are perturbed
//! on the right, `T ← T · Exp(δ)`; the Jacobians are then `∂r/∂δ_j = J_r⁻¹(r)` and
//! `∂r/∂δ_i = −J_r⁻¹(r) · Ad(T_j⁻¹ T_i)` (Solà, Deray & Atchuthan, "A micro Lie theory for state
//! estimation in robotics", 2018).

use nalgebra::{SMatrix, SVector};

/// A Lie group of rigid transforms with `D` degrees of freedom, tangent vectors ordered translation first.
pub trait PoseGroup<const D: usize>: Copy + std::fmt::Debug + Send + Sync + 'static {
    /// The identity transform.
    fn identity() -> Self;

    /// `self * other`.
    fn compose(&self, other: &Self) -> Self;

    /// `self⁻¹`.
    fn inverse(&self) -> Self;

    /// `self · Exp(delta)`.
    fn retract(&self, delta: &SVector<f64, D>) -> Self;

    /// `Log(self)`, translation part first.
    fn log(&self) -> SVector<f64, D>;

    /// The inverse of the right Jacobian of the group at the tangent vector `xi`.
    fn right_jacobian_inverse(xi: &SVector<f64, D>) -> SMatrix<f64, D, D>;

    /// The adjoint matrix: `self · Exp(δ) = Exp(Ad(self) δ) · self`.
    fn adjoint(&self) -> SMatrix<f64, D, D>;

    /// True when every number of the transform is finite.
    fn is_finite(&self) -> bool;

    /// The residual `Log(measured⁻¹ · T_i⁻¹ · T_j)` and its Jacobians with respect to right perturbations
    /// of `T_i` and `T_j`.
    fn between_linearized(
        measured_inverse: &Self,
        pose_i: &Self,
        pose_j: &Self,
    ) -> (SVector<f64, D>, SMatrix<f64, D, D>, SMatrix<f64, D, D>) {
        let j_from_i = pose_j.inverse().compose(pose_i);
        let error = measured_inverse.compose(&j_from_i.inverse());
        let residual = error.log();
        let jacobian_j = Self::right_jacobian_inverse(&residual);
        let jacobian_i = -(jacobian_j * j_from_i.adjoint());
        (residual, jacobian_i, jacobian_j)
    }

    /// The residual `Log(measured⁻¹ · T_i⁻¹ · T_j)` alone.
    fn between_residual(measured_inverse: &Self, pose_i: &Self, pose_j: &Self) -> SVector<f64, D> {
        measured_inverse.compose(&pose_i.inverse().compose(pose_j)).log()
    }
}
