//! Umeyama recovers known SE(3)/Sim(3) transforms exactly from noiseless points and refuses degenerate
//! point sets.

use nalgebra::{Similarity3, Translation3, UnitQuaternion, Vector3};
use skid_eval::{AlignmentKind, EvalError, align_trajectory, umeyama};

use super::{close, pose};

/// Twelve points spread in 3-D (not coplanar), without a random generator.
fn cloud() -> Vec<Vector3<f64>> {
    (0..12)
        .map(|k| {
            let k = f64::from(k);
            Vector3::new(
                (1.3 * k).sin() * 4.0 + k,
                (0.7 * k).cos() * 3.0,
                0.5 * k - (2.1 * k).sin(),
            )
        })
        .collect()
}

fn check_recovers(truth: &Similarity3<f64>, source: &[Vector3<f64>], with_scale: bool) {
    let target: Vec<Vector3<f64>> = source
        .iter()
        .map(|p| truth.transform_vector(p) + truth.isometry.translation.vector)
        .collect();
    let found = umeyama(source, &target, with_scale).unwrap();
    close(found.scaling(), truth.scaling(), 1e-12);
    assert!(found.isometry.rotation.angle_to(&truth.isometry.rotation) < 1e-12);
    assert!((found.isometry.translation.vector - truth.isometry.translation.vector).norm() < 1e-10);
}

#[test]
fn recovers_sim3_and_se3_exactly() {
    let rotation = UnitQuaternion::from_scaled_axis(Vector3::new(0.3, -1.2, 0.8));
    let translation = Translation3::new(5.0, -2.0, 0.75);
    check_recovers(
        &Similarity3::from_parts(translation, rotation, 1.7),
        &cloud(),
        true,
    );
    check_recovers(
        &Similarity3::from_parts(translation, rotation, 1.0),
        &cloud(),
        false,
    );
    // A half turn, where a trace-based rotation extraction is least stable.
    let half_turn =
        UnitQuaternion::from_scaled_axis(Vector3::new(1.0, 2.0, -0.5).normalize() * std::f64::consts::PI);
    check_recovers(
        &Similarity3::from_parts(translation, half_turn, 0.4),
        &cloud(),
        true,
    );
}

#[test]
fn planar_points_give_a_proper_rotation() {
    // All points in z = 0: the cross-covariance has rank 2, and the sign of the third singular vectors is
    // arbitrary; without the determinant correction the result could be a reflection.
    let planar: Vec<Vector3<f64>> = cloud().into_iter().map(|p| Vector3::new(p.x, p.y, 0.0)).collect();
    let yaw = UnitQuaternion::from_euler_angles(0.0, 0.0, 2.5);
    check_recovers(
        &Similarity3::from_parts(Translation3::new(1.0, 2.0, 3.0), yaw, 1.0),
        &planar,
        false,
    );
    let tilted = UnitQuaternion::from_euler_angles(0.4, -0.3, 1.0);
    check_recovers(
        &Similarity3::from_parts(Translation3::new(-1.0, 0.0, 2.0), tilted, 2.5),
        &planar,
        true,
    );
}

#[test]
fn sim3_scale_is_the_least_squares_scale() {
    // Source square of half-diagonal √2 around 0, target the same square doubled: s = 2 exactly, and
    // SE(3) (scale fixed at 1) keeps R = I and t = 0 by symmetry.
    let square = [
        Vector3::new(1.0, 1.0, 0.0),
        Vector3::new(-1.0, 1.0, 0.0),
        Vector3::new(-1.0, -1.0, 0.0),
        Vector3::new(1.0, -1.0, 0.0),
    ];
    let doubled: Vec<Vector3<f64>> = square.iter().map(|p| 2.0 * p).collect();
    let sim = umeyama(&square, &doubled, true).unwrap();
    close(sim.scaling(), 2.0, 1e-12);
    let se3 = umeyama(&square, &doubled, false).unwrap();
    close(se3.scaling(), 1.0, 0.0);
    assert!(se3.isometry.rotation.angle() < 1e-12);
    assert!(se3.isometry.translation.vector.norm() < 1e-12);
}

#[test]
fn degenerate_inputs_are_errors() {
    let two = [Vector3::new(0.0, 0.0, 0.0), Vector3::new(1.0, 0.0, 0.0)];
    assert!(matches!(
        umeyama(&two, &two, false),
        Err(EvalError::TooFew {
            needed: 3,
            got: 2,
            ..
        })
    ));

    let line: Vec<Vector3<f64>> = (0..6)
        .map(|k| Vector3::new(1.0, 2.0, 3.0) * f64::from(k) + Vector3::x())
        .collect();
    let shifted: Vec<Vector3<f64>> = line.iter().map(|p| p + Vector3::new(0.0, 5.0, 0.0)).collect();
    let err = umeyama(&line, &shifted, false).unwrap_err();
    assert!(matches!(err, EvalError::Degenerate { .. }), "{err}");
    assert!(err.to_string().contains("collinear"), "{err}");

    let same = vec![Vector3::new(1.0, 1.0, 1.0); 4];
    let err = umeyama(&same, &same, true).unwrap_err();
    assert!(err.to_string().contains("coincide"), "{err}");

    let mut nan = cloud();
    nan[3].y = f64::NAN;
    assert!(matches!(
        umeyama(&nan, &cloud(), false),
        Err(EvalError::NonFinite { index: 3, .. })
    ));
    assert!(matches!(
        umeyama(&cloud(), &cloud()[..5], false),
        Err(EvalError::LengthMismatch { .. })
    ));
}

#[test]
fn trajectory_alignment_kinds() {
    let gt: Vec<_> = cloud()
        .iter()
        .map(|p| pose(p.x, p.y, p.z, [0.0, 0.0, 0.1]))
        .collect();
    // est = (gt positions scaled by 0.5), so gt_from_est has scale 2 in Sim(3) and scale-only modes.
    let est: Vec<_> = gt
        .iter()
        .map(|p| {
            pose(
                0.5 * p.translation.x,
                0.5 * p.translation.y,
                0.5 * p.translation.z,
                [0.0; 3],
            )
        })
        .collect();
    close(
        align_trajectory(&gt, &est, AlignmentKind::Sim3)
            .unwrap()
            .scaling(),
        2.0,
        1e-12,
    );
    let scale_only = align_trajectory(&gt, &est, AlignmentKind::ScaleOnly).unwrap();
    close(scale_only.scaling(), 2.0, 1e-12);
    assert_eq!(scale_only.isometry, nalgebra::Isometry3::identity());
    assert_eq!(
        align_trajectory(&gt, &est, AlignmentKind::None).unwrap(),
        Similarity3::identity()
    );
    close(
        align_trajectory(&gt, &est, AlignmentKind::Se3).unwrap().scaling(),
        1.0,
        0.0,
    );
}
