//! Where a session goes in another session's map frame (the base's), from what its robots'
//! localisations in the base say: for `skid session merge` and for a run that extends its prior.
//!
//! Each robot of the session that the verifier localised in the base gives one estimate of where the
//! session's map frame sits in the base's (its placement composed with where the session had placed
//! it). The robots of one session were already in one frame, so their estimates must agree: two that
//! differ by more than the false-merge bound (2 m or 5°) mean at least one false fix, and the session
//! is not placed at all rather than placed by a vote. Agreeing estimates are averaged, weighted by
//! their verified loops. A robot the session never placed in its own frame is placed by its own
//! localisation alone, or left unplaced.

use nalgebra::{Quaternion, Translation3, UnitQuaternion, Vector3, Vector4};
use skid_core::Pose;

/// Two estimates of one frame farther apart than this, in metres or degrees, contradict each other:
/// the bound a false merge is judged by.
pub const AGREE_M: f64 = 2.0;
pub const AGREE_DEG: f64 = 5.0;

/// What the localisation made of one robot of the session being placed.
#[derive(Clone, Debug)]
pub struct RobotStanding {
    /// Where the robot's map frame sits in the session's map frame, when the session placed it.
    pub session_from_robot: Option<Pose>,
    /// Where the verified loops place the robot's map frame in the base's; `None` when not localised.
    pub base_from_robot: Option<Pose>,
    /// The loops with the base the verifier accepted for it.
    pub loops: usize,
}

/// The outcome for a whole session.
#[derive(Clone, Debug)]
pub enum SessionPlacement {
    /// Where each robot's map frame goes in the base's (`None`: left unplaced), and where the session's
    /// map frame goes when a robot placed in it was localised.
    Placed {
        base_from_session: Option<Pose>,
        robots: Vec<Option<Pose>>,
    },
    /// No robot could be placed, or the robots contradict each other.
    NotPlaced { reason: String },
}

fn differ(a: &Pose, b: &Pose) -> (f64, f64) {
    let delta = a.inverse() * b;
    (
        delta.translation.vector.norm(),
        delta.rotation.angle().to_degrees(),
    )
}

/// The loop-weighted mean of poses that agree (translation averaged, rotation by the normalised
/// weighted quaternion sum, each quaternion on the first one's side).
pub fn weighted_mean(estimates: &[(Pose, usize)]) -> Option<Pose> {
    let (first, _) = estimates.first()?;
    let reference = first.rotation.coords;
    let (mut translation, mut rotation, mut total) = (Vector3::zeros(), Vector4::zeros(), 0.0);
    for (pose, loops) in estimates {
        let weight = (*loops).max(1) as f64;
        translation += pose.translation.vector * weight;
        let q = pose.rotation.coords;
        rotation += if q.dot(&reference) < 0.0 { -q } else { q } * weight;
        total += weight;
    }
    Some(Pose::from_parts(
        Translation3::from(translation / total),
        UnitQuaternion::from_quaternion(Quaternion::from(rotation)),
    ))
}

/// Places a session from its robots' standings (in the order of the session's robots).
pub fn place_session(robots: &[RobotStanding]) -> SessionPlacement {
    let estimates: Vec<(Pose, usize)> = robots
        .iter()
        .filter_map(|robot| {
            Some((
                robot.base_from_robot? * robot.session_from_robot?.inverse(),
                robot.loops,
            ))
        })
        .collect();
    for (i, (a, _)) in estimates.iter().enumerate() {
        for (b, _) in &estimates[i + 1..] {
            let (metres, degrees) = differ(a, b);
            if metres > AGREE_M || degrees > AGREE_DEG {
                return SessionPlacement::NotPlaced {
                    reason: format!(
                        "its robots' localisations place the session {metres:.2} m / {degrees:.1}° apart: at least one is a false fix"
                    ),
                };
            }
        }
    }
    let base_from_session = weighted_mean(&estimates);
    let placed: Vec<Option<Pose>> = robots
        .iter()
        .map(|robot| match (base_from_session, robot.session_from_robot) {
            (Some(frame), Some(in_session)) => Some(frame * in_session),
            _ => robot
                .base_from_robot
                .filter(|_| robot.session_from_robot.is_none()),
        })
        .collect();
    if placed.iter().all(Option::is_none) {
        return SessionPlacement::NotPlaced {
            reason: "no robot of the session was localised in the base".into(),
        };
    }
    SessionPlacement::Placed {
        base_from_session,
        robots: placed,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pose(x: f64, y: f64, yaw_deg: f64) -> Pose {
        Pose::from_parts(
            Translation3::new(x, y, 0.0),
            UnitQuaternion::from_euler_angles(0.0, 0.0, yaw_deg.to_radians()),
        )
    }

    fn standing(in_session: Option<Pose>, in_base: Option<Pose>, loops: usize) -> RobotStanding {
        RobotStanding {
            session_from_robot: in_session,
            base_from_robot: in_base,
            loops,
        }
    }

    #[test]
    fn agreeing_robots_place_the_whole_session_and_an_unlocalised_one_follows() {
        let frame = pose(10.0, -4.0, 30.0);
        let second = pose(5.0, 1.0, -10.0);
        let nearly = pose(0.1, 0.0, 0.5);
        let robots = [
            standing(Some(Pose::identity()), Some(frame), 6),
            standing(Some(second), Some(frame * nearly * second), 2),
            standing(Some(pose(-3.0, 2.0, 90.0)), None, 0),
            standing(None, None, 0),
        ];
        let SessionPlacement::Placed {
            base_from_session: Some(fused),
            robots: placed,
        } = place_session(&robots)
        else {
            panic!("the session should be placed");
        };
        let (metres, degrees) = differ(&fused, &frame);
        assert!(metres < 0.1 && degrees < 0.5, "{metres} m {degrees}°");
        assert!(placed[2].is_some(), "robot 2 follows its session");
        assert!(placed[3].is_none(), "a robot placed nowhere stays so");
    }

    #[test]
    fn robots_that_contradict_each_other_leave_the_session_unplaced() {
        let robots = [
            standing(Some(Pose::identity()), Some(pose(10.0, 0.0, 0.0)), 9),
            standing(Some(pose(5.0, 0.0, 0.0)), Some(pose(15.0, 0.0, 90.0)), 3),
        ];
        let SessionPlacement::NotPlaced { reason } = place_session(&robots) else {
            panic!("contradicting robots must not place the session");
        };
        assert!(reason.contains("false fix"), "{reason}");
        let SessionPlacement::NotPlaced { .. } = place_session(&[standing(Some(Pose::identity()), None, 0)])
        else {
            panic!("a session no robot localised stays unplaced");
        };
    }

    #[test]
    fn a_robot_the_session_never_placed_is_placed_by_its_own_localisation() {
        let own = pose(-2.0, 7.0, 45.0);
        let SessionPlacement::Placed {
            base_from_session,
            robots,
        } = place_session(&[standing(None, Some(own), 4)])
        else {
            panic!("placed by its own localisation");
        };
        assert!(base_from_session.is_none());
        assert_eq!(robots[0], Some(own));
    }
}
