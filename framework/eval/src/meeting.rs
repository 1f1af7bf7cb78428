//! The error of a merge where the two robots met: whether robot β's map, placed in robot α's, sits where
//! it should at the places both robots saw.
//!
//! `T_β,APE` ([`crate::alpha_beta`]) and the anchored frame error
//! ([`crate::alpha_beta::anchored_frame_error`]) both compare β's frame with the truth through a whole
//! trajectory or through the robots' first poses, so each carries the odometry's drift: at 0.5 % drift a
//! 200 m route already moves a correct merge by a metre, and a merge in a map that drifted more is
//! indistinguishable from one made at the wrong place. What a merge decides is local: whether the two
//! maps coincide where the robots' routes overlap. This measure takes every pose of β that came within
//! `radius_m` of a pose of α (in truth), and compares the relative pose between the two in the merged
//! estimate, `T̂_α(i)⁻¹ · T^α_β · T̂_β(j)`, with the true one, `T_α(i)⁻¹ · T_β(j)`. The median over
//! those pairs is the merge's error at the meeting: a correct merge leaves only the drift accumulated
//! along the shared stretch, a merge at the wrong place leaves the distance between the place and its
//! look-alike.

use serde::Serialize;
use skid_core::Pose;

use crate::geometry::rotation_angle_deg;
use crate::stats::ErrorStats;

/// Two poses this close in truth are at the same place, metres: a fraction of a LiDAR's useful range,
/// so that the two robots saw largely the same surroundings.
pub const MEETING_RADIUS_M: f64 = 10.0;

/// A merge's error at the places the robots met.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct MeetingError {
    /// Poses of β with a pose of α within the radius (each β pose paired with its nearest α pose).
    pub pairs: usize,
    /// Median translation and rotation of the relative-pose errors over the pairs.
    pub translation_m: f64,
    pub rotation_deg: f64,
}

/// β's placement in α's frame judged where the robots met: `alpha` and `beta` are each robot's
/// associated (ground truth, estimate) poses, the estimates in the robots' own map frames, and
/// `alpha_from_beta` maps β's map frame into α's. `None` when no pose of β came within `radius_m` of
/// one of α (the robots never met; judge the merge another way).
pub fn meeting_frame_error(
    alpha: (&[Pose], &[Pose]),
    beta: (&[Pose], &[Pose]),
    alpha_from_beta: &Pose,
    radius_m: f64,
) -> Option<MeetingError> {
    meeting_with_fleet(&[alpha], beta, alpha_from_beta, radius_m)
}

/// β's placement in α's frame judged where β met any robot already placed there: `placed` holds each
/// such robot's (ground truth, estimate) poses with the estimates **in α's frame** (α itself among
/// them, or robots placed through others); each pose of β is paired with the nearest pose of any of
/// them within `radius_m` in truth. A robot that joined α's frame through others and never met α is
/// judged where it met them, still free of the routes' drift. `None` when β met none of them.
pub fn meeting_with_fleet(
    placed: &[(&[Pose], &[Pose])],
    (gt_beta, est_beta): (&[Pose], &[Pose]),
    alpha_from_beta: &Pose,
    radius_m: f64,
) -> Option<MeetingError> {
    let radius_sq = radius_m * radius_m;
    let (mut translations, mut rotations) = (Vec::new(), Vec::new());
    for (gt_b, est_b) in gt_beta.iter().zip(est_beta) {
        let nearest = placed
            .iter()
            .flat_map(|(gt, est)| gt.iter().zip(est.iter()))
            .map(|(gt_a, est_a)| {
                let distance_sq = (gt_a.translation.vector - gt_b.translation.vector).norm_squared();
                (distance_sq, gt_a, est_a)
            })
            .min_by(|x, y| x.0.total_cmp(&y.0));
        let Some((distance_sq, gt_a, est_a)) = nearest else {
            continue;
        };
        if distance_sq > radius_sq {
            continue;
        }
        let truth = gt_a.inverse() * gt_b;
        let estimate = est_a.inverse() * alpha_from_beta * est_b;
        let error = truth.inverse() * estimate;
        if error.translation.vector.iter().all(|v| v.is_finite()) {
            translations.push(error.translation.vector.norm());
            rotations.push(rotation_angle_deg(&error.rotation));
        }
    }
    // The same median as every other error statistic here (evo's); `None` when no pose pair met.
    let translation = ErrorStats::from_errors("meeting translation errors", &translations).ok()?;
    let rotation = ErrorStats::from_errors("meeting rotation errors", &rotations).ok()?;
    Some(MeetingError {
        pairs: translations.len(),
        translation_m: translation.median,
        rotation_deg: rotation.median,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::geometry::planar_pose as pose;

    /// A robot's (ground truth, estimate) poses.
    type Robot = (Vec<Pose>, Vec<Pose>);

    /// α drives east from the origin; β starts 100 m east, facing west, and drives back over α's route.
    /// Each estimate is in its robot's own frame (its first pose at the origin); α's drifts by a slow
    /// heading error of `drift_deg_per_m`.
    fn meeting(drift_deg_per_m: f64) -> (Robot, Robot) {
        let gt_alpha: Vec<Pose> = (0..100).map(|i| pose(f64::from(i), 0.0, 0.0)).collect();
        let mut est_alpha = vec![Pose::identity()];
        for _ in 1..100 {
            let last = est_alpha[est_alpha.len() - 1];
            est_alpha.push(last * pose(1.0, 0.0, drift_deg_per_m));
        }
        let gt_beta: Vec<Pose> = (0..100).map(|i| pose(100.0 - f64::from(i), 0.0, 180.0)).collect();
        let est_beta = gt_beta.iter().map(|p| gt_beta[0].inverse() * p).collect();
        ((gt_alpha, est_alpha), (gt_beta, est_beta))
    }

    #[test]
    fn a_merge_at_the_right_place_is_judged_by_the_maps_not_by_the_drift() {
        let ((gt_a, est_a), (gt_b, est_b)) = meeting(0.02);
        // The merge as the loops at the far end would make it: β's first pose on α's last.
        let alpha_from_beta = est_a[99] * gt_a[99].inverse() * gt_b[0];
        let error = meeting_frame_error((&gt_a, &est_a), (&gt_b, &est_b), &alpha_from_beta, 10.0).unwrap();
        assert_eq!(error.pairs, 100);
        // α's drift bends its map by 2° over 100 m; the merge itself adds nothing at the meeting, and the
        // median pair sees half the bend.
        assert!(error.rotation_deg < 1.2, "{error:?}");
        assert!(error.translation_m < 1.0, "{error:?}");
    }

    #[test]
    fn a_merge_at_a_look_alike_place_is_off_by_the_distance_between_them() {
        let ((gt_a, est_a), (gt_b, est_b)) = meeting(0.0);
        // Placed one 40 m block further east, as if a look-alike corner had been matched.
        let alpha_from_beta = pose(40.0, 0.0, 0.0) * gt_a[0].inverse() * gt_b[0];
        let error = meeting_frame_error((&gt_a, &est_a), (&gt_b, &est_b), &alpha_from_beta, 10.0).unwrap();
        assert!((error.translation_m - 40.0).abs() < 1e-6, "{error:?}");
        assert!(error.rotation_deg < 1e-6);
    }

    #[test]
    fn a_robot_is_judged_where_it_met_any_robot_already_placed() {
        let ((gt_a, est_a), (gt_b, est_b)) = meeting(0.0);
        // A third robot γ drives α's route 500 m north, never meeting α; β drives γ's route back. γ is
        // placed in α's frame 500 m north (its estimates given in α's frame), β 3 m off γ's route.
        let north = pose(0.0, 500.0, 0.0);
        let gt_c: Vec<Pose> = gt_a.iter().map(|p| north * p).collect();
        let est_c_in_alpha: Vec<Pose> = est_a.iter().map(|p| north * p).collect();
        let gt_b: Vec<Pose> = gt_b.iter().map(|p| north * p).collect();
        let alpha_from_beta = pose(3.0, 0.0, 0.0) * gt_a[0].inverse() * gt_b[0];
        assert!(meeting_frame_error((&gt_a, &est_a), (&gt_b, &est_b), &alpha_from_beta, 10.0).is_none());
        let placed = [(&gt_a[..], &est_a[..]), (&gt_c[..], &est_c_in_alpha[..])];
        let error = meeting_with_fleet(&placed, (&gt_b, &est_b), &alpha_from_beta, 10.0).unwrap();
        assert_eq!(error.pairs, 100);
        assert!((error.translation_m - 3.0).abs() < 1e-6, "{error:?}");
    }

    #[test]
    fn robots_that_never_met_have_no_meeting_error() {
        let ((gt_a, est_a), (gt_b, est_b)) = meeting(0.0);
        let far: Vec<Pose> = gt_b.iter().map(|p| pose(0.0, 500.0, 0.0) * p).collect();
        assert!(meeting_frame_error((&gt_a, &est_a), (&far, &est_b), &Pose::identity(), 10.0).is_none());
        assert!(meeting_frame_error((&[], &[]), (&gt_b, &est_b), &Pose::identity(), 10.0).is_none());
    }
}
