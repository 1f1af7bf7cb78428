//! A map against the ground truth its keyframes carry (the simulator's, a dataset's): where the map's
//! frame sits in the world, and how far placed keyframes lie from where they truly were. Relocalisation
//! (`summary.json`'s `localisation`) and session merges are judged by these; a false fix or merge is one
//! more than 2 m or 5° off.

use skid_core::Pose;

use crate::Session;
use crate::place::weighted_mean;

/// Where a map frame sits in the world of the ground truth, from pairs of a keyframe's pose in the map
/// and its true pose: the mean of what each pair says (truth · estimate⁻¹). Full poses rather than
/// positions alone, so that a map along one straight road still fixes its roll. `None` with fewer than
/// three pairs.
pub fn world_from_map_pairs(pairs: impl IntoIterator<Item = (Pose, Pose)>) -> Option<Pose> {
    let estimates: Vec<(Pose, usize)> = pairs
        .into_iter()
        .map(|(estimate, truth)| (truth * estimate.inverse(), 1))
        .collect();
    if estimates.len() < 3 {
        return None;
    }
    weighted_mean(&estimates)
}

fn median(mut values: Vec<f64>) -> Option<f64> {
    values.sort_by(f64::total_cmp);
    values.get(values.len() / 2).copied()
}

/// The median position (m) and rotation (°) error of estimates against their truths, given as pairs
/// (estimate, truth) in one frame; `None` without pairs.
pub fn median_errors(pairs: impl IntoIterator<Item = (Pose, Pose)>) -> Option<(f64, f64)> {
    let (metres, degrees): (Vec<f64>, Vec<f64>) = pairs
        .into_iter()
        .map(|(estimate, truth)| {
            let delta = estimate.inverse() * truth;
            (
                delta.translation.vector.norm(),
                delta.rotation.angle().to_degrees(),
            )
        })
        .unzip();
    Some((median(metres)?, median(degrees)?))
}

impl Session {
    /// Where the session's map frame sits in the world of its keyframes' ground truth, from its placed
    /// robots' keyframes ([`world_from_map_pairs`]).
    pub fn world_from_map(&self) -> Option<Pose> {
        world_from_map_pairs(self.robots.iter().flat_map(|robot| {
            robot.keyframes.iter().filter_map(move |keyframe| {
                Some((robot.session_from_sensor(keyframe)?, keyframe.ground_truth?))
            })
        }))
    }

    /// The median error against the truth of this session's keyframes placed in a base's map frame by
    /// `base_from_robot` (one placement per robot, `None` leaving a robot out), the base's frame placed
    /// in the world by `world_from_base`.
    pub fn placement_error(
        &self,
        world_from_base: &Pose,
        base_from_robot: &[Option<Pose>],
    ) -> Option<(f64, f64)> {
        median_errors(
            self.robots
                .iter()
                .zip(base_from_robot)
                .flat_map(|(robot, placement)| {
                    robot.keyframes.iter().filter_map(move |keyframe| {
                        Some((
                            world_from_base * (*placement)? * keyframe.map_from_sensor,
                            keyframe.ground_truth?,
                        ))
                    })
                }),
        )
    }
}
