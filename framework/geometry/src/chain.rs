//! Odometry chains: each robot's keyframe poses in its own odometry frame and the covariance of every
//! step, with first-order propagation of the covariance along the chain. This is what pairwise
//! consistency (PCM) needs for the relative odometry between two keyframes of one robot.

use std::collections::BTreeMap;

use nalgebra::{Matrix3, Matrix6};
use skid_core::slots::RelativePose;
use skid_core::{Information, KeyframeId, Pose, RobotId};

/// The adjoint of SE(3) in (translation, rotation) order: it maps a perturbation expressed in the
/// source frame of `pose` into its target frame.
pub fn adjoint(pose: &Pose) -> Matrix6<f64> {
    let rotation = pose.rotation.to_rotation_matrix().into_inner();
    let t = pose.translation.vector;
    let skew = Matrix3::new(0.0, -t.z, t.y, t.z, 0.0, -t.x, -t.y, t.x, 0.0);
    let mut ad = Matrix6::zeros();
    ad.fixed_view_mut::<3, 3>(0, 0).copy_from(&rotation);
    ad.fixed_view_mut::<3, 3>(0, 3).copy_from(&(skew * rotation));
    ad.fixed_view_mut::<3, 3>(3, 3).copy_from(&rotation);
    ad
}

/// One robot's keyframe: its odometry pose and the covariance of the step from the previous keyframe.
#[derive(Clone, Copy, Debug)]
struct Link {
    world_from_sensor: Pose,
    step_covariance: Information,
}

/// Odometry chains of any number of robots.
#[derive(Clone, Debug, Default)]
pub struct OdometryChains {
    chains: BTreeMap<RobotId, BTreeMap<u32, Link>>,
}

impl OdometryChains {
    /// Records keyframe `id` at `world_from_sensor` (in its robot's odometry frame), with the covariance
    /// of the step from keyframe `id.index - 1` (ignored for the first keyframe).
    pub fn insert(&mut self, id: KeyframeId, world_from_sensor: Pose, step_covariance: Information) {
        self.chains.entry(id.robot).or_default().insert(
            id.index,
            Link {
                world_from_sensor,
                step_covariance,
            },
        );
    }

    /// The odometry pose of a keyframe.
    pub fn pose(&self, id: KeyframeId) -> Option<Pose> {
        self.chains
            .get(&id.robot)?
            .get(&id.index)
            .map(|link| link.world_from_sensor)
    }

    /// Whether every keyframe from the first to `id` is known (the chain has no gap up to it).
    pub fn contains(&self, id: KeyframeId) -> bool {
        self.chains
            .get(&id.robot)
            .is_some_and(|chain| chain.contains_key(&id.index))
    }

    /// Every keyframe of every robot, ordered by robot then index.
    pub fn keyframes(&self) -> Vec<KeyframeId> {
        self.chains
            .iter()
            .flat_map(|(&robot, chain)| chain.keys().map(move |&index| KeyframeId { robot, index }))
            .collect()
    }

    /// The keyframes of one robot in index order, with their odometry poses.
    pub fn chain(&self, robot: RobotId) -> Vec<(u32, Pose)> {
        self.chains
            .get(&robot)
            .map(|chain| {
                chain
                    .iter()
                    .map(|(&index, link)| (index, link.world_from_sensor))
                    .collect()
            })
            .unwrap_or_default()
    }

    /// The covariance of the step into keyframe `id`.
    pub fn step_covariance(&self, id: KeyframeId) -> Option<Information> {
        self.chains
            .get(&id.robot)?
            .get(&id.index)
            .map(|link| link.step_covariance)
    }

    /// The relative odometry `target_from_source` between two keyframes of one robot and its covariance,
    /// propagated to first order along every step in between. `None` for different robots, unknown
    /// keyframes or a gap in the chain.
    pub fn between(&self, target: KeyframeId, source: KeyframeId) -> Option<RelativePose> {
        if target.robot != source.robot {
            return None;
        }
        let chain = self.chains.get(&target.robot)?;
        let (low, high) = if target.index <= source.index {
            (target.index, source.index)
        } else {
            (source.index, target.index)
        };
        let low_pose = chain.get(&low)?.world_from_sensor;
        let mut covariance = Matrix6::zeros();
        for index in low + 1..=high {
            let previous = chain.get(&(index - 1))?.world_from_sensor;
            let ad = adjoint(&(low_pose.inverse() * previous));
            covariance += ad * chain.get(&index)?.step_covariance * ad.transpose();
        }
        let target_from_source = chain.get(&target.index)?.world_from_sensor.inverse()
            * chain.get(&source.index)?.world_from_sensor;
        if target.index > source.index {
            // The covariance was accumulated in the low (= source) frame; move it to the target frame.
            let ad = adjoint(&target_from_source);
            covariance = ad * covariance * ad.transpose();
        }
        Some(RelativePose {
            target_from_source,
            covariance,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    #[test]
    fn between_composes_poses_and_grows_covariance() {
        let mut chains = OdometryChains::default();
        let step = Pose::new(Vector3::new(1.0, 0.0, 0.0), Vector3::new(0.0, 0.0, 0.1));
        let mut pose = Pose::identity();
        for index in 0..5 {
            chains.insert(KeyframeId::new(2, index), pose, Information::identity() * 0.01);
            pose *= step;
        }
        let forward = chains
            .between(KeyframeId::new(2, 1), KeyframeId::new(2, 4))
            .unwrap();
        let expected = step * step * step;
        assert!((forward.target_from_source.translation.vector - expected.translation.vector).norm() < 1e-12);
        let one = chains
            .between(KeyframeId::new(2, 1), KeyframeId::new(2, 2))
            .unwrap();
        assert!(forward.covariance.trace() > 2.9 * one.covariance.trace());
        let backward = chains
            .between(KeyframeId::new(2, 4), KeyframeId::new(2, 1))
            .unwrap();
        let identity = forward.target_from_source * backward.target_from_source;
        assert!(identity.translation.vector.norm() < 1e-12);
        assert!(backward.covariance.iter().all(|v| v.is_finite()) && backward.covariance.trace() > 0.0);
        assert!(
            chains
                .between(KeyframeId::new(2, 1), KeyframeId::new(3, 1))
                .is_none()
        );
        assert!(
            chains
                .between(KeyframeId::new(2, 1), KeyframeId::new(2, 9))
                .is_none()
        );
    }

    #[test]
    fn adjoint_of_identity_is_identity() {
        assert_eq!(adjoint(&Pose::identity()), Matrix6::identity());
    }
}
