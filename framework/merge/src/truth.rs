//! How far a placed session lies from where it truly is, when both it and the base know their ground
//! truth (the simulator's, a dataset's): the base's map frame is placed in the world by the mean of
//! what its keyframes' true and estimated poses say, and each keyframe of the placed session, put in
//! the base's frame by its placement, is compared with its true pose. The medians are the merged map's
//! frame error: what a false merge (more than 2 m or 5°) is judged by.

use skid_core::Pose;
use skid_session::Session;

/// Where `session`'s map frame sits in the world of its ground truth: the mean over its placed
/// keyframes of what each one's true and estimated poses say (full poses rather than positions alone,
/// so that a map of one straight road still fixes its roll).
pub fn world_from_map(session: &Session) -> Option<Pose> {
    let estimates: Vec<(Pose, usize)> = session
        .robots
        .iter()
        .flat_map(|robot| robot.keyframes.iter().map(move |keyframe| (robot, keyframe)))
        .filter_map(|(robot, keyframe)| {
            Some((
                keyframe.ground_truth? * robot.session_from_sensor(keyframe)?.inverse(),
                1,
            ))
        })
        .collect();
    if estimates.len() < 3 {
        return None;
    }
    skid_session::weighted_mean(&estimates)
}

fn median(mut values: Vec<f64>) -> Option<f64> {
    values.sort_by(f64::total_cmp);
    values.get(values.len() / 2).copied()
}

/// The median position (m) and rotation (°) error of `session`'s keyframes placed in the base's frame
/// by `placements` (one per robot), against their truth seen from the base's fitted frame.
pub fn placement_error(
    world_from_base: &Pose,
    session: &Session,
    placements: &[Option<Pose>],
) -> Option<(f64, f64)> {
    let (mut metres, mut degrees) = (Vec::new(), Vec::new());
    for (robot, placement) in session.robots.iter().zip(placements) {
        let Some(base_from_robot) = placement else {
            continue;
        };
        for keyframe in &robot.keyframes {
            let Some(truth) = keyframe.ground_truth else {
                continue;
            };
            let delta = (world_from_base * base_from_robot * keyframe.map_from_sensor).inverse() * truth;
            metres.push(delta.translation.vector.norm());
            degrees.push(delta.rotation.angle().to_degrees());
        }
    }
    Some((median(metres)?, median(degrees)?))
}
