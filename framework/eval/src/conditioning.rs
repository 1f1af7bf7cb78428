//! Whether an SE(3) alignment determines its rotation. Umeyama's fit uses positions only, so when the
//! ground-truth positions lie nearly on a line (a straight drive, a short run) the rotation about that
//! line is fixed by noise alone, and the ARE measured after it can read 90° or more while every relative
//! rotation is right. The spread of the positions tells: the eigenvalues `λ₁ ≥ λ₂ ≥ λ₃` of their
//! covariance; with `λ₂/λ₁` below [`MIN_EIGENVALUE_RATIO`] the alignment is called ill-conditioned and
//! the ARE should be read with the RPE (which needs no alignment) beside it.

use nalgebra::{Matrix3, Vector3};
use serde::Serialize;
use skid_core::Pose;

/// Below this `λ₂/λ₁` (a lateral spread under about 3% of the spread along the path, in standard
/// deviations) the rotation about the path's main axis is taken as unobservable.
pub const MIN_EIGENVALUE_RATIO: f64 = 1e-3;

/// How well the positions of a trajectory fix an alignment's rotation.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct AlignmentConditioning {
    /// Eigenvalues of the position covariance, largest first, in m².
    pub position_covariance_eigenvalues_m2: [f64; 3],
    /// `λ₂ / λ₁` (0 when the positions do not spread at all).
    pub eigenvalue_ratio: f64,
    /// True when the rotation about the main axis is not determined (see the module doc).
    pub ill_conditioned: bool,
}

impl AlignmentConditioning {
    /// A sentence for reports, when the alignment is ill-conditioned.
    pub fn warning(&self) -> Option<String> {
        self.ill_conditioned.then(|| {
            format!(
                "the ground-truth path is nearly a straight line (λ₂/λ₁ = {:.1e} < {MIN_EIGENVALUE_RATIO:.0e}): \
                 the SE(3) alignment's rotation about it is not observable, so the ARE is not meaningful; \
                 read the RPE rotation instead",
                self.eigenvalue_ratio
            )
        })
    }
}

/// The conditioning of an alignment onto the positions of `truth`.
pub fn alignment_conditioning(truth: &[Pose]) -> AlignmentConditioning {
    let count = truth.len().max(1) as f64;
    let mean: Vector3<f64> = truth.iter().map(|p| p.translation.vector).sum::<Vector3<f64>>() / count;
    let covariance: Matrix3<f64> = truth
        .iter()
        .map(|p| {
            let d = p.translation.vector - mean;
            d * d.transpose()
        })
        .sum::<Matrix3<f64>>()
        / count;
    let mut eigenvalues: Vec<f64> = covariance
        .symmetric_eigenvalues()
        .iter()
        .map(|v| v.max(0.0))
        .collect();
    eigenvalues.sort_by(|a, b| b.total_cmp(a));
    let ratio = if eigenvalues[0] > 0.0 {
        eigenvalues[1] / eigenvalues[0]
    } else {
        0.0
    };
    AlignmentConditioning {
        position_covariance_eigenvalues_m2: [eigenvalues[0], eigenvalues[1], eigenvalues[2]],
        eigenvalue_ratio: ratio,
        ill_conditioned: ratio < MIN_EIGENVALUE_RATIO,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};

    fn at(x: f64, y: f64) -> Pose {
        Pose::from_parts(Translation3::new(x, y, 0.0), UnitQuaternion::identity())
    }

    #[test]
    fn a_straight_path_is_ill_conditioned_and_a_curve_is_not() {
        // 13 m straight with 2 cm of lateral wobble, as on KITTI 00's first frames.
        let straight: Vec<Pose> = (0..16)
            .map(|i| at(0.86 * i as f64, 0.02 * (i as f64).sin()))
            .collect();
        let conditioning = alignment_conditioning(&straight);
        assert!(conditioning.ill_conditioned, "{conditioning:?}");
        assert!(conditioning.warning().is_some());
        // A quarter circle of 10 m radius.
        let curve: Vec<Pose> = (0..16)
            .map(|i| {
                let angle = std::f64::consts::FRAC_PI_2 * i as f64 / 15.0;
                at(10.0 * angle.cos(), 10.0 * angle.sin())
            })
            .collect();
        let conditioning = alignment_conditioning(&curve);
        assert!(!conditioning.ill_conditioned, "{conditioning:?}");
        assert!(conditioning.warning().is_none());
        assert!(alignment_conditioning(&[at(1.0, 1.0)]).ill_conditioned);
    }
}
