//! Conformance of coarse and fine registration: a known `target_from_source` is recovered from the scene
//! seen from two poses (fresh samples each, so no point correspondence is exact), and degenerate input
//! is reported (invalid / not converged / an error) without NaN or panics.

use nalgebra::Vector3;
use skid_core::slots::{CoarseRegistration, FineRegistration};
use skid_core::{Cloud, CloudView, Point, Pose};

use crate::pose_error;
use crate::scene::{Scene, planar_pose};

/// Tolerances for the recovered pose.
#[derive(Clone, Copy, Debug)]
pub struct RegistrationExpectations {
    pub max_translation_error_m: f64,
    pub max_rotation_error_deg: f64,
}

/// A target cloud, a source cloud and the true `target_from_source`.
pub fn synthetic_pair(source_pose: &Pose, points: usize) -> (Cloud, Cloud, Pose) {
    let scene = Scene::new(11, 120.0);
    let target_pose = planar_pose(0.0, 0.0, 1.8, 0.0);
    let target = scene.sample(&target_pose, points, 60.0, 21);
    let source = scene.sample(source_pose, points, 60.0, 22);
    (target, source, target_pose.inverse() * source_pose)
}

/// Fine registration: recovers the truth from guesses perturbed by up to `perturbation_m` metres and
/// `perturbation_deg` degrees, and reports degenerate input and an unreachable guess as not converged.
/// The same as running every check of [`fine_checks`].
pub fn check_fine(
    registration: &mut dyn FineRegistration,
    perturbation_m: f64,
    perturbation_deg: f64,
    expect: RegistrationExpectations,
) {
    for (_, check) in fine_checks(perturbation_m, perturbation_deg, expect) {
        check(registration);
    }
}

/// One named check of the fine suite: it panics (by assertion) when the plugin fails it.
pub type FineCheck = (&'static str, Box<dyn Fn(&mut dyn FineRegistration)>);

/// One named check of the coarse suite.
pub type CoarseCheck = (&'static str, Box<dyn Fn(&mut dyn CoarseRegistration)>);

/// The fine registration suite as named checks, for reports such as `skid plugins --check`.
pub fn fine_checks(
    perturbation_m: f64,
    perturbation_deg: f64,
    expect: RegistrationExpectations,
) -> Vec<FineCheck> {
    vec![
        (
            "recovers a perturbed transform",
            Box::new(move |registration: &mut dyn FineRegistration| {
                fine_recovers_perturbed_transform(registration, perturbation_m, perturbation_deg, expect)
            }),
        ),
        (
            "degenerate input is not converged, with a reason",
            Box::new(|registration: &mut dyn FineRegistration| fine_reports_degenerate_input(registration)),
        ),
        (
            "no correspondences within reach is not converged",
            Box::new(|registration: &mut dyn FineRegistration| {
                fine_reports_an_unreachable_guess(registration)
            }),
        ),
    ]
}

/// A pose as `t = [x, y, z] m, r = [rx, ry, rz]°` (the rotation vector), for failure messages.
pub fn pose_text(pose: &Pose) -> String {
    let t = pose.translation.vector;
    let r = pose.rotation.scaled_axis() * 180.0 / std::f64::consts::PI;
    format!(
        "t = [{:.3}, {:.3}, {:.3}] m, r = [{:.2}, {:.2}, {:.2}]°",
        t.x, t.y, t.z, r.x, r.y, r.z
    )
}

/// Recovers the truth from three perturbed guesses, converged, with finite information.
pub fn fine_recovers_perturbed_transform(
    registration: &mut dyn FineRegistration,
    perturbation_m: f64,
    perturbation_deg: f64,
    expect: RegistrationExpectations,
) {
    let (target, source, truth) = synthetic_pair(&planar_pose(2.0, 1.0, 1.8, 5f64.to_radians()), 30_000);
    let prepared_target = registration.prepare(target.view()).expect("prepare target");
    let prepared_source = registration.prepare(source.view()).expect("prepare source");
    let directions = [
        Vector3::new(1.0, 0.0, 0.0),
        Vector3::new(-0.6, 0.8, 0.0),
        Vector3::new(0.0, -0.7, 0.7),
    ];
    for (case, direction) in directions.iter().enumerate() {
        let perturbation = Pose::new(
            direction * perturbation_m,
            Vector3::new(0.1, -0.2, 1.0).normalize() * perturbation_deg.to_radians(),
        );
        let guess = truth * perturbation;
        let result = registration
            .refine(&prepared_target, &prepared_source, &guess)
            .expect("refine");
        let (translation_m, rotation_deg) = pose_error(&truth, &result.target_from_source);
        // What a plugin author needs to see when a case fails: where it started, where it ended, and
        // what the plugin said about it.
        let seen = format!(
            "guess {}, result {}, truth {}, converged {}, failure {:?}, inlier ratio {:.3}",
            pose_text(&guess),
            pose_text(&result.target_from_source),
            pose_text(&truth),
            result.converged,
            result.failure,
            result.inlier_ratio
        );
        assert!(
            translation_m <= expect.max_translation_error_m && rotation_deg <= expect.max_rotation_error_deg,
            "case {case}: off by {translation_m:.3} m, {rotation_deg:.3}° ({seen})"
        );
        assert!(result.converged, "case {case}: not converged ({seen})");
        assert!(
            result.failure.is_none(),
            "case {case}: a converged result carries no failure"
        );
        assert!(
            result.information.iter().all(|v| v.is_finite()),
            "finite information"
        );
        assert!(
            result.inlier_ratio > 0.3 && result.inlier_ratio <= 1.0,
            "case {case}: inlier ratio {}",
            result.inlier_ratio
        );
    }
}

/// Too few points and collinear points: an error, or a result that is not converged and says why.
pub fn fine_reports_degenerate_input(registration: &mut dyn FineRegistration) {
    let tiny = Cloud::new(vec![Point::new(1.0, 2.0, 3.0), Point::new(2.0, 2.0, 3.0)]);
    let line = Cloud::new((0..200).map(|i| Point::new(i as f32 * 0.1, 0.0, 0.0)).collect());
    for (case, cloud) in [tiny, line].iter().enumerate() {
        let refined = registration.prepare(CloudView::from(cloud)).and_then(|prepared| {
            registration.refine(&prepared, &prepared, &Pose::translation(0.3, 0.0, 0.0))
        });
        if let Ok(result) = refined {
            assert!(
                !result.converged,
                "degenerate case {case} must not claim convergence"
            );
            assert!(
                result.failure.as_deref().is_some_and(|reason| !reason.is_empty()),
                "degenerate case {case} must say why it did not converge"
            );
            assert!(
                result
                    .target_from_source
                    .translation
                    .vector
                    .iter()
                    .all(|v| v.is_finite())
            );
        }
    }
}

/// A guess 1 km off: no correspondence within reach, so not converged (or an error), never NaN.
pub fn fine_reports_an_unreachable_guess(registration: &mut dyn FineRegistration) {
    let (target, source, _) = synthetic_pair(&planar_pose(2.0, 1.0, 1.8, 5f64.to_radians()), 30_000);
    let prepared_target = registration.prepare(target.view()).expect("prepare target");
    let prepared_source = registration.prepare(source.view()).expect("prepare source");
    let far = Pose::translation(1000.0, 0.0, 0.0);
    let result = registration.refine(&prepared_target, &prepared_source, &far);
    if let Ok(result) = result {
        assert!(
            !result.converged && result.failure.is_some(),
            "no correspondences within the maximum distance: not converged, with a reason"
        );
        assert!(
            result
                .target_from_source
                .translation
                .vector
                .iter()
                .all(|v| v.is_finite())
        );
    }
}

/// Coarse registration: recovers yaws all around with a `offset_m` translation, without a prior, and
/// reports three points as invalid. The same as running every check of [`coarse_checks`].
pub fn check_coarse(
    registration: &mut dyn CoarseRegistration,
    yaws_deg: &[f64],
    offset_m: f64,
    expect: RegistrationExpectations,
) {
    for (_, check) in coarse_checks(yaws_deg.to_vec(), offset_m, expect) {
        check(registration);
    }
}

/// The coarse registration suite as named checks.
pub fn coarse_checks(
    yaws_deg: Vec<f64>,
    offset_m: f64,
    expect: RegistrationExpectations,
) -> Vec<CoarseCheck> {
    vec![
        (
            "recovers large unknown transforms",
            Box::new(move |registration: &mut dyn CoarseRegistration| {
                coarse_recovers_unknown_transforms(registration, &yaws_deg, offset_m, expect)
            }),
        ),
        (
            "three points are not a valid registration",
            Box::new(|registration: &mut dyn CoarseRegistration| coarse_reports_tiny_input(registration)),
        ),
    ]
}

/// Recovers each yaw with an `offset_m` translation, valid.
pub fn coarse_recovers_unknown_transforms(
    registration: &mut dyn CoarseRegistration,
    yaws_deg: &[f64],
    offset_m: f64,
    expect: RegistrationExpectations,
) {
    for &yaw_deg in yaws_deg {
        let (target, source, truth) =
            synthetic_pair(&planar_pose(offset_m, 0.0, 1.8, yaw_deg.to_radians()), 20_000);
        let result = registration
            .align(target.view(), source.view(), None)
            .expect("align");
        let (translation_m, rotation_deg) = pose_error(&truth, &result.target_from_source);
        assert!(result.valid, "yaw {yaw_deg}°: valid");
        assert!(
            translation_m <= expect.max_translation_error_m && rotation_deg <= expect.max_rotation_error_deg,
            "yaw {yaw_deg}°: off by {translation_m:.3} m, {rotation_deg:.3}°"
        );
    }
}

/// Three points: an error, or a result marked invalid with a finite transform.
pub fn coarse_reports_tiny_input(registration: &mut dyn CoarseRegistration) {
    let tiny = Cloud::new(vec![
        Point::new(1.0, 2.0, 3.0),
        Point::new(2.0, 2.0, 3.0),
        Point::new(3.0, 1.0, 3.0),
    ]);
    if let Ok(result) = registration.align(tiny.view(), tiny.view(), None) {
        assert!(
            !result.valid,
            "three points cannot give a valid global registration"
        );
        assert!(
            result
                .target_from_source
                .translation
                .vector
                .iter()
                .all(|v| v.is_finite())
        );
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use skid_core::PluginResult;
    use skid_core::slots::{FineAlignment, PreparedCloud};

    use super::*;

    /// A fine registration that returns its guess, converged: what a plugin that never moves looks like.
    struct Stays;

    impl FineRegistration for Stays {
        fn prepare(&mut self, cloud: CloudView<'_>) -> PluginResult<PreparedCloud> {
            Ok(PreparedCloud {
                cloud: Arc::new(Cloud::new(cloud.points().to_vec())),
                cache: Arc::new(()),
            })
        }

        fn refine(
            &mut self,
            _: &PreparedCloud,
            _: &PreparedCloud,
            guess: &Pose,
        ) -> PluginResult<FineAlignment> {
            Ok(FineAlignment {
                target_from_source: *guess,
                information: skid_core::Information::identity(),
                converged: true,
                iterations: 1,
                inlier_count: 0,
                inlier_ratio: 0.0,
                error: 0.0,
                failure: None,
            })
        }
    }

    #[test]
    fn a_failed_fine_case_shows_the_guess_the_result_and_the_convergence_flag() {
        let failed = std::panic::catch_unwind(|| {
            fine_recovers_perturbed_transform(
                &mut Stays,
                0.5,
                5.0,
                RegistrationExpectations {
                    max_translation_error_m: 0.05,
                    max_rotation_error_deg: 0.5,
                },
            );
        });
        let panic = failed.expect_err("a plugin that stays at its guess passed");
        let message = panic.downcast_ref::<String>().cloned().unwrap_or_default();
        for word in [
            "guess t = [",
            "result t = [",
            "truth t = [",
            "converged true",
            "failure None",
        ] {
            assert!(message.contains(word), "`{word}` missing from: {message}");
        }
    }
}
