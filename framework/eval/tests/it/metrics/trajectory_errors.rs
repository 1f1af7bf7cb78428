//! APE (ATE/ARE), RPE and drift against hand-computed numbers on 4-pose trajectories.

use nalgebra::{Isometry3, UnitQuaternion, Vector3};
use skid_core::Pose;
use skid_eval::{AlignmentKind, DeltaUnit, DriftOptions, EvalError, RpeOptions, ape, drift, rpe, rpe_pairs};

use super::{close, pose};

/// Ground truth: the square corners g = (1,1), (−1,1), (−1,−1), (1,−1) at z = 0 with yaws 0, 0.5, 1, 1.5.
fn square_gt() -> Vec<Pose> {
    [(1.0, 1.0), (-1.0, 1.0), (-1.0, -1.0), (1.0, -1.0)]
        .iter()
        .enumerate()
        .map(|(k, &(x, y))| pose(x, y, 0.0, [0.0, 0.0, 0.5 * k as f64]))
        .collect()
}

/// The estimate of the APE example. Positions: corners 0 and 2 moved 0.1 m outwards along the
/// diagonal, corners 1 and 3 moved 0.3 m inwards, so est_i = c_i · g_i with c = 1 ± δ/√2. Rotations:
/// R_gt,i · ΔR_i with ΔR of 1°, 2°, 0°, 3° about different axes. Then everything is moved by a rigid
/// transform `t_far` that the alignment has to undo.
fn square_est(t_far: &Isometry3<f64>) -> Vec<Pose> {
    let offsets = [0.1, -0.3, 0.1, -0.3];
    let extra = [
        UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 1f64.to_radians()),
        UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 2f64.to_radians()),
        UnitQuaternion::identity(),
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 3f64.to_radians()),
    ];
    square_gt()
        .iter()
        .zip(offsets.iter().zip(&extra))
        .map(|(g, (&delta, dr))| {
            let radial = g.translation.vector.normalize() * delta;
            let local = Isometry3::from_parts((g.translation.vector + radial).into(), g.rotation * dr);
            t_far * local
        })
        .collect()
}

#[test]
fn ape_after_se3_alignment_matches_hand_computation() {
    // Hand computation. Without t_far, the cross-covariance Σ g_i (c_i g_i)ᵀ / 4 is symmetric positive
    // semi-definite, so Umeyama's rotation is I, and the centroids are both 0, so t = 0: the optimal
    // SE(3) alignment is the identity and undoes t_far exactly when t_far is applied.
    // Translation errors ‖c_i g_i − g_i‖ = 0.1, 0.3, 0.1, 0.3:
    //   rmse = √((0.01+0.09+0.01+0.09)/4) = √0.05 = 0.2236068, mean = median = 0.2, std = 0.1,
    //   min 0.1, max 0.3.
    // Rotation errors: angle(R_gt⁻¹ · R_gt ΔR) = 1°, 2°, 0°, 3°:
    //   rmse = √(14/4) = 1.8708287, mean = median = 1.5, std = √((0.25+0.25+2.25+2.25)/4) = √1.25.
    let t_far = Isometry3::new(Vector3::new(10.0, -4.0, 2.0), Vector3::new(0.2, -0.1, 1.3));
    let result = ape(&square_gt(), &square_est(&t_far), AlignmentKind::Se3).unwrap();
    let t = result.translation_m;
    close(t.rmse, 0.05f64.sqrt(), 1e-9);
    close(t.mean, 0.2, 1e-9);
    close(t.median, 0.2, 1e-9);
    close(t.std, 0.1, 1e-9);
    close(t.min, 0.1, 1e-9);
    close(t.max, 0.3, 1e-9);
    let r = result.rotation_deg;
    close(r.rmse, 3.5f64.sqrt(), 1e-7);
    close(r.mean, 1.5, 1e-7);
    close(r.median, 1.5, 1e-7);
    close(r.std, 1.25f64.sqrt(), 1e-7);
    close(r.max, 3.0, 1e-7);
    // The alignment found is t_far⁻¹.
    close(
        result.alignment.rotation_angle_deg,
        t_far.rotation.angle().to_degrees(),
        1e-7,
    );
    close(result.alignment.scale, 1.0, 0.0);
}

#[test]
fn ape_with_sim3_removes_a_uniform_scale() {
    // est = 3 · gt positions, orientations equal: Sim(3) finds s = 1/3 and all errors vanish; SE(3)
    // cannot scale, so its best fit leaves ‖3g − g‖ = 2·√2 at every corner.
    let gt = square_gt();
    let est: Vec<Pose> = gt
        .iter()
        .map(|g| Isometry3::from_parts((3.0 * g.translation.vector).into(), g.rotation))
        .collect();
    let sim = ape(&gt, &est, AlignmentKind::Sim3).unwrap();
    close(sim.alignment.scale, 1.0 / 3.0, 1e-12);
    assert!(sim.translation_m.max < 1e-12);
    assert!(sim.rotation_deg.max < 1e-9);
    let se3 = ape(&gt, &est, AlignmentKind::Se3).unwrap();
    close(se3.translation_m.rmse, 2.0 * 2f64.sqrt(), 1e-12);
}

/// Ground truth along x, 1 m apart, identity rotations; the estimate of the RPE example.
fn line() -> (Vec<Pose>, Vec<Pose>) {
    let gt = (0..4).map(|k| pose(f64::from(k), 0.0, 0.0, [0.0; 3])).collect();
    let est = vec![
        pose(0.0, 0.0, 0.0, [0.0; 3]),
        pose(1.1, 0.0, 0.0, [0.0; 3]),
        pose(2.1, 0.2, 0.0, [0.0; 3]),
        pose(3.0, 0.2, 0.0, [0.0, 0.0, 2f64.to_radians()]),
    ];
    (gt, est)
}

#[test]
fn rpe_matches_hand_computation() {
    let (gt, est) = line();
    // Δ = 1 frame, pairs (0,1), (1,2), (2,3); E = (Q_i⁻¹Q_j)⁻¹ (P_i⁻¹P_j):
    //   (0,1): gt motion (1,0,0), est motion (1.1,0,0)         → t(E) = (0.1,0,0), 0°
    //   (1,2): gt motion (1,0,0), est motion (1.0,0.2,0)       → t(E) = (0,0.2,0), 0°
    //   (2,3): gt motion (1,0,0), est motion (0.9,0,0) + 2° yaw → t(E) = (−0.1,0,0), 2°
    // translation: rmse = √(0.06/3) = √0.02, mean = 0.4/3, median 0.1, max 0.2;
    // rotation: rmse = √(4/3), mean = 2/3, median 0, max 2.
    let r = rpe(&gt, &est, &RpeOptions::default()).unwrap();
    assert_eq!(r.pair_indices, vec![(0, 1), (1, 2), (2, 3)]);
    close(r.translation_m.rmse, 0.02f64.sqrt(), 1e-12);
    close(r.translation_m.mean, 0.4 / 3.0, 1e-12);
    close(r.translation_m.median, 0.1, 1e-12);
    close(r.translation_m.max, 0.2, 1e-12);
    close(r.rotation_deg.rmse, (4.0f64 / 3.0).sqrt(), 1e-9);
    close(r.rotation_deg.mean, 2.0 / 3.0, 1e-9);
    close(r.rotation_deg.median, 0.0, 1e-9);

    // Δ = 2 frames: ids 0, 2 → one pair (0,2): gt motion (2,0,0), est (2.1,0.2,0) → √(0.01+0.04).
    let two = RpeOptions {
        delta: 2.0,
        ..RpeOptions::default()
    };
    let r = rpe(&gt, &est, &two).unwrap();
    assert_eq!(r.pairs, 1);
    close(r.translation_m.rmse, 0.05f64.sqrt(), 1e-12);
    // All pairs with Δ = 2: (0,2) and (1,3): est motion (1.9,0.2,0) vs (2,0,0) → also √0.05.
    let all = RpeOptions {
        all_pairs: true,
        ..two
    };
    assert_eq!(rpe_pairs(&est, &all).unwrap(), vec![(0, 2), (1, 3)]);

    // Δ = 1 m along the estimate's path (steps 1.1, 1.0198, 0.9): pose 0, then the path reaches 1 m at
    // pose 1 and again at pose 2, and pose 3 is only 0.9 m further → pairs (0,1), (1,2): errors 0.1, 0.2.
    let metres = RpeOptions {
        unit: DeltaUnit::Metres,
        ..RpeOptions::default()
    };
    let r = rpe(&gt, &est, &metres).unwrap();
    assert_eq!(r.pair_indices, vec![(0, 1), (1, 2)]);
    close(r.translation_m.rmse, 0.025f64.sqrt(), 1e-12);
    // Along the ground truth (steps of exactly 1 m): poses 0, 1, 2, 3 → pairs (0,1), (1,2), (2,3).
    let from_gt = RpeOptions {
        pairs_from_reference: true,
        ..metres
    };
    assert_eq!(
        rpe(&gt, &est, &from_gt).unwrap().pair_indices,
        vec![(0, 1), (1, 2), (2, 3)]
    );
    // All pairs 2 m apart along the ground truth (path lengths 0, 1, 2, 3; tolerance 0.2 m): 0 → 2,
    // 1 → 3; pose 2 has only 1 m left, beyond the tolerance.
    let all_metres = RpeOptions {
        delta: 2.0,
        all_pairs: true,
        ..from_gt
    };
    assert_eq!(
        rpe(&gt, &est, &all_metres).unwrap().pair_indices,
        vec![(0, 2), (1, 3)]
    );
    // Along the estimate (0, 1.1, 2.1198, 3.0198): 0 → 2 (miss 0.12), 1 → 3 (miss 0.08); 2 has 0.9 left.
    let all_est = RpeOptions {
        pairs_from_reference: false,
        ..all_metres
    };
    assert_eq!(rpe_pairs(&est, &all_est).unwrap(), vec![(0, 2), (1, 3)]);
    let strict = RpeOptions {
        rel_delta_tol: 0.05,
        ..all_est
    };
    assert_eq!(rpe_pairs(&est, &strict).unwrap(), vec![(1, 3)]);
}

#[test]
fn rpe_rejects_bad_options() {
    let (gt, est) = line();
    for delta in [0.0, -1.0, 1.5, f64::NAN, 10.0] {
        let options = RpeOptions {
            delta,
            ..RpeOptions::default()
        };
        assert!(rpe(&gt, &est, &options).is_err(), "delta {delta}");
    }
    // Δ = 4 frames on 4 poses leaves no pair.
    let options = RpeOptions {
        delta: 4.0,
        ..RpeOptions::default()
    };
    assert!(matches!(rpe(&gt, &est, &options), Err(EvalError::TooFew { .. })));
    let options = RpeOptions {
        unit: DeltaUnit::Metres,
        all_pairs: true,
        rel_delta_tol: -1.0,
        ..RpeOptions::default()
    };
    assert!(matches!(
        rpe(&gt, &est, &options),
        Err(EvalError::InvalidOption { .. })
    ));
    assert!(matches!(
        rpe(&gt, &est[..3], &RpeOptions::default()),
        Err(EvalError::LengthMismatch { .. })
    ));
}

#[test]
fn drift_matches_hand_computation() {
    // Ground truth: 10 poses 1 m apart along x; estimate: the same scaled by 1.1 (10 % too long).
    // Segments of 3 m starting at every pose (step 1) end at the first pose with path > start + 3,
    // i.e. 4 poses later: starts 0..=5, 6 segments. Each has gt motion 4 m and est motion 4.4 m, so
    // ‖t(E)‖ = 0.4 and the error is 0.4 / 3 = 13.333 %. End point: 0.9 m over a 9 m path = 10 %.
    let gt: Vec<Pose> = (0..10).map(|k| pose(f64::from(k), 0.0, 0.0, [0.0; 3])).collect();
    let est: Vec<Pose> = (0..10)
        .map(|k| pose(1.1 * f64::from(k), 0.0, 0.0, [0.0; 3]))
        .collect();
    let options = DriftOptions {
        segment_lengths_m: vec![3.0, 100.0],
        step_frames: 1,
    };
    let d = drift(&gt, &est, &options).unwrap();
    close(d.path_length_m, 9.0, 1e-12);
    assert_eq!(d.segments, 6);
    assert_eq!(d.per_length.len(), 1, "no 100 m segment fits in 9 m");
    close(d.translation_percent.unwrap(), 40.0 / 3.0, 1e-9);
    close(d.rotation_deg_per_100m.unwrap(), 0.0, 1e-9);
    close(d.endpoint_percent, 10.0, 1e-9);

    // With KITTI's lengths nothing fits, and the end-point drift remains.
    let d = drift(&gt, &est, &DriftOptions::default()).unwrap();
    assert_eq!((d.segments, d.translation_percent), (0, None));
    // A standing ground truth has no path to divide by.
    let still = vec![pose(0.0, 0.0, 0.0, [0.0; 3]); 5];
    assert!(drift(&still, &still, &options).is_err());
}

#[test]
fn ape_rejects_bad_input() {
    let gt = square_gt();
    assert!(matches!(
        ape(&[], &[], AlignmentKind::Se3),
        Err(EvalError::TooFew { .. })
    ));
    assert!(matches!(
        ape(&gt, &gt[..3], AlignmentKind::Se3),
        Err(EvalError::LengthMismatch { .. })
    ));
    let mut bad = gt.clone();
    bad[2].translation.vector.x = f64::INFINITY;
    assert!(matches!(
        ape(&gt, &bad, AlignmentKind::Se3),
        Err(EvalError::NonFinite { index: 2, .. })
    ));
    // Without alignment, two poses are enough; with it, they are not.
    assert!(ape(&gt[..2], &gt[..2], AlignmentKind::None).is_ok());
    assert!(matches!(
        ape(&gt[..2], &gt[..2], AlignmentKind::Se3),
        Err(EvalError::TooFew { .. })
    ));
}
