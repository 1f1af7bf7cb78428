//! The paper's α/β alignment metric on a constructed two-robot example.

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use skid_core::Pose;
use skid_eval::{AlignmentKind, AlphaBetaInput, alpha_beta};

use super::{close, pose};

fn helix(phase: f64) -> Vec<Pose> {
    (0..8)
        .map(|k| {
            let s = f64::from(k) * 0.6 + phase;
            pose(5.0 * s.cos(), 5.0 * s.sin(), 0.3 * f64::from(k), [0.0, 0.1, s])
        })
        .collect()
}

#[test]
fn alpha_beta_measures_the_inter_robot_transform_error() {
    // α's map frame: est_α = A · gt_α, so Umeyama finds T^GT_α = A⁻¹. β's: est_β = B · gt_β, T^GT_β = B⁻¹.
    // The true β-to-α transform is A·B⁻¹. Giving the back-end's estimate T^α_β = A·B⁻¹·Δ:
    //   T_β,APE = (T^GT_β)⁻¹ · T^GT_α · T^α_β = B · A⁻¹ · A · B⁻¹ · Δ = B · Δ · B⁻¹,
    // whose rotation angle is angle(Δ), and whose translation is R_B · t_Δ when Δ is a pure translation.
    let a = Isometry3::new(Vector3::new(3.0, -7.0, 1.0), Vector3::new(0.1, 0.2, -0.9));
    let b = Isometry3::new(Vector3::new(-20.0, 4.0, 0.5), Vector3::new(0.0, -0.3, 2.0));
    let gt_alpha = helix(0.0);
    let gt_beta = helix(1.7);
    let est_alpha: Vec<Pose> = gt_alpha.iter().map(|p| a * p).collect();
    let est_beta: Vec<Pose> = gt_beta.iter().map(|p| b * p).collect();
    let true_alpha_from_beta = a * b.inverse();

    let exact = AlphaBetaInput {
        gt_alpha: &gt_alpha,
        est_alpha: &est_alpha,
        gt_beta: &gt_beta,
        est_beta: &est_beta,
        alpha_from_beta: true_alpha_from_beta,
    };
    let r = alpha_beta(&exact, AlignmentKind::Se3).unwrap();
    assert!(r.beta_alignment_error.translation_m < 1e-9);
    assert!(r.beta_alignment_error.rotation_deg < 1e-7);
    assert!(r.alpha.translation_m.max < 1e-9 && r.beta_in_alpha.translation_m.max < 1e-9);

    // Δ = 0.5 m along x: ‖T_β,APE translation‖ = ‖R_B (0.5,0,0)‖ = 0.5, rotation 0. β's poses mapped
    // through α's alignment, T^GT_α · T^α_β · B · g = B⁻¹ Δ B · g, are all moved by the translation
    // R_B⁻¹·(0.5,0,0), so β's in-α ATE is 0.5 at every pose, while β's own alignment sees a perfect
    // trajectory shape.
    let shifted = AlphaBetaInput {
        alpha_from_beta: true_alpha_from_beta * Translation3::new(0.5, 0.0, 0.0),
        ..exact
    };
    let r = alpha_beta(&shifted, AlignmentKind::Se3).unwrap();
    close(r.beta_alignment_error.translation_m, 0.5, 1e-9);
    close(r.beta_alignment_error.rotation_deg, 0.0, 1e-7);
    close(r.beta_in_alpha.translation_m.rmse, 0.5, 1e-9);
    close(r.beta_in_alpha.translation_m.min, 0.5, 1e-9);
    assert!(r.beta_own.translation_m.max < 1e-9);

    // Δ = a 4° rotation about z: T_β,APE rotates by 4°, and β's in-α rotation error is 4° at every pose.
    let rotated = AlphaBetaInput {
        alpha_from_beta: true_alpha_from_beta
            * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 4f64.to_radians()),
        ..exact
    };
    let r = alpha_beta(&rotated, AlignmentKind::Se3).unwrap();
    close(r.beta_alignment_error.rotation_deg, 4.0, 1e-7);
    close(r.beta_in_alpha.rotation_deg.mean, 4.0, 1e-7);
    close(r.beta_alignment_error.scale, 1.0, 1e-12);

    // A NaN inter-robot transform is refused.
    let mut bad = true_alpha_from_beta;
    bad.translation.vector.y = f64::NAN;
    assert!(
        alpha_beta(
            &AlphaBetaInput {
                alpha_from_beta: bad,
                ..exact
            },
            AlignmentKind::Se3
        )
        .is_err()
    );
}
