//! Odometry chains: each robot's keyframe poses in its own odometry frame and the covariance of every
//! step, with first-order propagation of the covariance along the chain. This is what pairwise
//! consistency (PCM) needs for the relative odometry between two keyframes of one robot.
//!
//! Propagation in O(1): along a gap-free run of keyframes starting at `s`, keyframe `k` keeps the prefix
//! `P_k = Σ_{m=s+1..k} Ad(T_{m-1}) Σ_m Ad(T_{m-1})ᵀ` (odometry-frame poses `T`, step covariances `Σ`), so
//! the covariance of `T_l⁻¹ T_h` in keyframe `l`'s frame is `Ad(T_l⁻¹) (P_h − P_l) Ad(T_l⁻¹)ᵀ`. Keyframes
//! normally arrive in order (O(1) each); one that fills a gap or replaces an earlier one recomputes the
//! prefixes of the run after it.

use std::collections::BTreeMap;

use nalgebra::{Matrix3, Matrix6};
use skid_core::slots::{GraphView, LoopClosure, RelativePose};
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
    /// Whether `step_covariance` is the step's own (false for a keyframe placed by its pose alone,
    /// before the step into it arrived).
    step_known: bool,
    /// First keyframe of the gap-free run this keyframe belongs to.
    run_start: u32,
    /// `P_k` of the module doc, in the odometry frame.
    prefix_covariance: Matrix6<f64>,
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
        self.insert_link(id, world_from_sensor, step_covariance, true);
    }

    /// Records keyframe `id` at `world_from_sensor` before the step into it is known (a peer's message
    /// that carried the step was lost): the step counts as certain, `step_covariance` of 1 µ per axis,
    /// until [`OdometryChains::insert`] gives the real one.
    pub fn insert_without_step(&mut self, id: KeyframeId, world_from_sensor: Pose) {
        self.insert_link(id, world_from_sensor, Information::identity() * 1e-6, false);
    }

    /// Whether the step into keyframe `id` is known (its own covariance, not a placeholder).
    pub fn has_step(&self, id: KeyframeId) -> bool {
        self.chains
            .get(&id.robot)
            .and_then(|chain| chain.get(&id.index))
            .is_some_and(|link| link.step_known)
    }

    fn insert_link(
        &mut self,
        id: KeyframeId,
        world_from_sensor: Pose,
        step_covariance: Information,
        step_known: bool,
    ) {
        let chain = self.chains.entry(id.robot).or_default();
        let appended = chain.last_key_value().is_none_or(|(&last, _)| id.index > last);
        chain.insert(
            id.index,
            Link {
                world_from_sensor,
                step_covariance,
                step_known,
                run_start: id.index,
                prefix_covariance: Matrix6::zeros(),
            },
        );
        // Recompute the prefixes from this keyframe to the end of its run (only this one when appended).
        let mut index = id.index;
        loop {
            let previous = index.checked_sub(1).and_then(|p| chain.get(&p)).copied();
            let Some(link) = chain.get_mut(&index) else { break };
            match previous {
                Some(previous) => {
                    let ad = adjoint(&previous.world_from_sensor);
                    link.run_start = previous.run_start;
                    link.prefix_covariance =
                        previous.prefix_covariance + ad * link.step_covariance * ad.transpose();
                }
                None => {
                    link.run_start = index;
                    link.prefix_covariance = Matrix6::zeros();
                }
            }
            if appended {
                break;
            }
            let Some(next) = index.checked_add(1) else { break };
            index = next;
        }
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
        let (low_link, high_link) = (chain.get(&low)?, chain.get(&high)?);
        if low_link.run_start != high_link.run_start {
            return None;
        }
        let ad = adjoint(&low_link.world_from_sensor.inverse());
        let mut covariance = ad * (high_link.prefix_covariance - low_link.prefix_covariance) * ad.transpose();
        covariance = (covariance + covariance.transpose()) * 0.5;
        let (target_link, source_link) = match target.index <= source.index {
            true => (low_link, high_link),
            false => (high_link, low_link),
        };
        let target_from_source = target_link.world_from_sensor.inverse() * source_link.world_from_sensor;
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

/// The chains as a graph without loops: what a verifier needs to judge loops on odometry alone.
impl GraphView for OdometryChains {
    fn pose(&self, id: KeyframeId) -> Option<Pose> {
        OdometryChains::pose(self, id)
    }

    fn odometry_between(&self, target: KeyframeId, source: KeyframeId) -> Option<RelativePose> {
        self.between(target, source)
    }

    fn keyframes(&self) -> Vec<KeyframeId> {
        OdometryChains::keyframes(self)
    }

    fn loops(&self) -> Vec<LoopClosure> {
        Vec::new()
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

    /// The covariance of `T_low⁻¹ T_high` by explicit propagation over every step in between.
    fn propagated(chain: &[(Pose, Information)], low: usize, high: usize) -> Matrix6<f64> {
        let low_pose = chain[low].0;
        let mut covariance = Matrix6::zeros();
        for index in low + 1..=high {
            let ad = adjoint(&(low_pose.inverse() * chain[index - 1].0));
            covariance += ad * chain[index].1 * ad.transpose();
        }
        covariance
    }

    #[test]
    fn prefixes_match_explicit_propagation_in_any_insertion_order() {
        let mut truth = Vec::new();
        let mut pose = Pose::new(Vector3::new(300.0, -200.0, 5.0), Vector3::new(0.0, 0.0, 1.0));
        for k in 0..60 {
            let step = Pose::new(
                Vector3::new(1.5, 0.1 * f64::from(k % 7), 0.02),
                Vector3::new(0.01, -0.02, 0.05 * f64::from(k % 5)),
            );
            pose *= step;
            truth.push((pose, Information::identity() * (1e-4 * f64::from(k % 4 + 1))));
        }
        let check = |chains: &OdometryChains| {
            for (low, high) in [(0, 59), (10, 11), (17, 42), (30, 5)] {
                let got = chains
                    .between(KeyframeId::new(1, low as u32), KeyframeId::new(1, high as u32))
                    .unwrap();
                let (l, h) = (low.min(high), low.max(high));
                let mut expected = propagated(&truth, l, h);
                if low > high {
                    let ad = adjoint(&got.target_from_source);
                    expected = ad * expected * ad.transpose();
                }
                let error = (got.covariance - expected).abs().max();
                assert!(
                    error <= 1e-9 * expected.abs().max(),
                    "{low} -> {high}: off by {error}"
                );
            }
        };
        // In order.
        let mut chains = OdometryChains::default();
        for (k, (pose, covariance)) in truth.iter().enumerate() {
            chains.insert(KeyframeId::new(1, k as u32), *pose, *covariance);
        }
        check(&chains);
        // Out of order, with a gap that is filled last: no answer across the gap until then.
        let mut chains = OdometryChains::default();
        for k in (0..60).rev().filter(|k| *k != 25) {
            chains.insert(KeyframeId::new(1, k as u32), truth[k].0, truth[k].1);
        }
        assert!(
            chains
                .between(KeyframeId::new(1, 20), KeyframeId::new(1, 30))
                .is_none()
        );
        chains.insert(KeyframeId::new(1, 25), truth[25].0, truth[25].1);
        check(&chains);
    }

    #[test]
    fn adjoint_of_identity_is_identity() {
        assert_eq!(adjoint(&Pose::identity()), Matrix6::identity());
    }
}
