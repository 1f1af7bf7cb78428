//! Odometry chains: each robot's keyframe poses in its own odometry frame and the covariance of every
//! step, with first-order propagation of the covariance along the chain. This is what pairwise
//! consistency (PCM) needs for the relative odometry between two keyframes of one robot.
//!
//! Propagation in O(1): along the keyframes of one robot from its first known one `s`, keyframe `k` keeps
//! the prefix `P_k = Σ_{m=s+1..k} Ad(T_{m-1}) Σ_m Ad(T_{m-1})ᵀ` (odometry-frame poses `T`, step
//! covariances `Σ`), so the covariance of `T_l⁻¹ T_h` in keyframe `l`'s frame is
//! `Ad(T_l⁻¹) (P_h − P_l) Ad(T_l⁻¹)ᵀ`. Keyframes normally arrive in order (O(1) each); one that fills a gap
//! or replaces an earlier one recomputes the prefixes after it.
//!
//! A peer's chain has gaps where its messages were lost. Every keyframe's pose is in the robot's one
//! odometry frame, so the relative pose across a gap is known; only the steps' covariances are not. A
//! gap of `n` steps (and a step whose own covariance has not arrived) counts as `n` of the widest step
//! this robot's chain holds, so a loop on one side of a gap can still be tested against a loop on the
//! other, with the uncertainty the missing steps would have added. Otherwise two true loops across a
//! lost message would count as inconsistent for good.

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
    /// `P_k` of the module doc, in the odometry frame.
    prefix_covariance: Matrix6<f64>,
}

/// One robot's keyframes by index, and the widest step covariance among them (the stand-in for a
/// missing step).
#[derive(Clone, Debug, Default)]
struct Chain {
    links: BTreeMap<u32, Link>,
    widest_step: Option<Information>,
}

impl Chain {
    /// The covariance `link` adds to the prefix of the keyframe `previous_index` before it, and whether
    /// it is the link's own: its own step's when that is the step from `previous_index`, else as many
    /// of the widest step as the steps it stands for.
    fn step_from(&self, previous_index: u32, index: u32, link: &Link) -> (Information, bool) {
        let steps = index.saturating_sub(previous_index);
        if steps == 1 && link.step_known {
            return (link.step_covariance, true);
        }
        let widest = self.widest_step.unwrap_or(link.step_covariance);
        (widest * f64::from(steps), false)
    }
}

/// Odometry chains of any number of robots.
#[derive(Clone, Debug, Default)]
pub struct OdometryChains {
    chains: BTreeMap<RobotId, Chain>,
}

impl OdometryChains {
    /// Records keyframe `id` at `world_from_sensor` (in its robot's odometry frame), with the covariance
    /// of the step from keyframe `id.index - 1` (ignored for the first keyframe).
    pub fn insert(&mut self, id: KeyframeId, world_from_sensor: Pose, step_covariance: Information) {
        self.insert_link(id, world_from_sensor, step_covariance, true);
    }

    /// Records keyframe `id` at `world_from_sensor` before the step into it is known (a peer's message
    /// that carried the step was lost): the step counts as the widest step of the robot's chain until
    /// [`OdometryChains::insert`] gives the real one.
    pub fn insert_without_step(&mut self, id: KeyframeId, world_from_sensor: Pose) {
        self.insert_link(id, world_from_sensor, Information::identity() * 1e-6, false);
    }

    /// Whether the step into keyframe `id` is known (its own covariance, not a placeholder).
    pub fn has_step(&self, id: KeyframeId) -> bool {
        self.chains
            .get(&id.robot)
            .and_then(|chain| chain.links.get(&id.index))
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
        let appended = chain
            .links
            .last_key_value()
            .is_none_or(|(&last, _)| id.index > last);
        if step_known
            && chain
                .widest_step
                .is_none_or(|widest| step_covariance.trace() > widest.trace())
        {
            chain.widest_step = Some(step_covariance);
        }
        chain.links.insert(
            id.index,
            Link {
                world_from_sensor,
                step_covariance,
                step_known,
                prefix_covariance: Matrix6::zeros(),
            },
        );
        // Recompute the prefixes from this keyframe to the end of the chain (only this one when appended).
        let indices: Vec<u32> = match appended {
            true => vec![id.index],
            false => chain.links.range(id.index..).map(|(&index, _)| index).collect(),
        };
        for index in indices {
            let previous = chain
                .links
                .range(..index)
                .next_back()
                .map(|(&previous_index, link)| (previous_index, *link));
            let Some(link) = chain.links.get(&index).copied() else {
                continue;
            };
            let prefix_covariance = match previous {
                Some((previous_index, previous)) => {
                    let (step, own) = chain.step_from(previous_index, index, &link);
                    // A step's own covariance is in the frame it starts from; the stand-in for missing
                    // steps is put at the gap's far end, where each rotation error it stands for has
                    // the longest lever, so that it is not narrower than the steps it replaces.
                    let frame = if own {
                        previous.world_from_sensor
                    } else {
                        link.world_from_sensor
                    };
                    let ad = adjoint(&frame);
                    previous.prefix_covariance + ad * step * ad.transpose()
                }
                None => Matrix6::zeros(),
            };
            if let Some(link) = chain.links.get_mut(&index) {
                link.prefix_covariance = prefix_covariance;
            }
        }
    }

    /// The odometry pose of a keyframe.
    pub fn pose(&self, id: KeyframeId) -> Option<Pose> {
        self.chains
            .get(&id.robot)?
            .links
            .get(&id.index)
            .map(|link| link.world_from_sensor)
    }

    /// Whether every keyframe from the first to `id` is known (the chain has no gap up to it).
    pub fn contains(&self, id: KeyframeId) -> bool {
        self.chains
            .get(&id.robot)
            .is_some_and(|chain| chain.links.contains_key(&id.index))
    }

    /// Every keyframe of every robot, ordered by robot then index.
    pub fn keyframes(&self) -> Vec<KeyframeId> {
        self.chains
            .iter()
            .flat_map(|(&robot, chain)| chain.links.keys().map(move |&index| KeyframeId { robot, index }))
            .collect()
    }

    /// The keyframes of one robot in index order, with their odometry poses.
    pub fn chain(&self, robot: RobotId) -> Vec<(u32, Pose)> {
        self.chains
            .get(&robot)
            .map(|chain| {
                chain
                    .links
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
            .links
            .get(&id.index)
            .map(|link| link.step_covariance)
    }

    /// The relative odometry `target_from_source` between two keyframes of one robot and its covariance,
    /// propagated to first order along every step in between (a gap's steps as the module doc says).
    /// `None` for different robots or unknown keyframes.
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
        let (low_link, high_link) = (chain.links.get(&low)?, chain.links.get(&high)?);
        let (target_link, source_link) = match target.index <= source.index {
            true => (low_link, high_link),
            false => (high_link, low_link),
        };
        let target_from_world = target_link.world_from_sensor.inverse();
        let target_from_source = target_from_world * source_link.world_from_sensor;
        // The steps between the two keyframes, accumulated in the world frame, moved to the target's
        // frame: whichever end is the earlier one, `target_from_source` perturbed on the left there.
        let ad = adjoint(&target_from_world);
        let covariance = ad * (high_link.prefix_covariance - low_link.prefix_covariance) * ad.transpose();
        Some(RelativePose {
            target_from_source,
            covariance: (covariance + covariance.transpose()) * 0.5,
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
        // The inverse perturbed on the left: `Exp(δ) T` inverted is `Exp(-Ad(T⁻¹) δ) T⁻¹`.
        let ad = adjoint(&backward.target_from_source);
        let moved = ad * forward.covariance * ad.transpose();
        assert!(
            (backward.covariance - moved).norm() < 1e-12 * moved.norm(),
            "{backward:?}"
        );
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
        // Out of order, with a gap that is filled last: across the gap the pose is exact and the
        // missing steps count as the widest one, so the covariance is wider than the true one; once the
        // gap is filled, exact again.
        let mut chains = OdometryChains::default();
        for k in (0..60).rev().filter(|k| !(24..=26).contains(k)) {
            chains.insert(KeyframeId::new(1, k as u32), truth[k].0, truth[k].1);
        }
        let (low, high) = (KeyframeId::new(1, 20), KeyframeId::new(1, 30));
        let across = chains.between(low, high).expect("an answer across the gap");
        let exact = truth[20].0.inverse() * truth[30].0;
        assert!((across.target_from_source.translation.vector - exact.translation.vector).norm() < 1e-9);
        let true_covariance = propagated(&truth, 20, 30);
        assert!(
            across.covariance.trace() > true_covariance.trace(),
            "the gap's stand-in steps are no narrower than the true ones"
        );
        for (k, (pose, covariance)) in truth.iter().enumerate().take(27).skip(24) {
            chains.insert(KeyframeId::new(1, k as u32), *pose, *covariance);
        }
        check(&chains);
    }

    #[test]
    fn adjoint_of_identity_is_identity() {
        assert_eq!(adjoint(&Pose::identity()), Matrix6::identity());
    }
}
