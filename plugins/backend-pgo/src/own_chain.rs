//! The robot's own odometry chain, compressed between the keyframes that need a pose variable (issue
//! #18: a distributed solve whose cost follows the loops, not the mission's length).
//!
//! A keyframe of the robot's own that no loop touches has only its two odometry factors. Eliminating
//! it composes them into one factor between its neighbours, with the covariance propagated to first
//! order, exactly what the distributed graph already does for peers (SKiD-SLAM, `X_dis,α`). So the
//! subgraph holds, of the own robot, only:
//! - the keyframes a loop touches,
//! - the first and last keyframe of every stretch of unbroken odometry (a segment);
//!
//! and one composed odometry factor between each consecutive pair of them in a segment.
//!
//! After a solve the keyframes left out are put back where the eliminated chain puts them: between two
//! kept keyframes `a` and `b`, keyframe `k` follows `a` by odometry, moved by its share of the correction
//! that takes the dead-reckoned `b` onto `b`'s optimised pose, shared by covariance (the chain's
//! conditional mean given both ends, to first order). It is exact at `a` and `b`.

use std::collections::BTreeMap;

use skid_core::slots::LoopClosure;
use skid_core::{KeyframeId, Pose, RobotId};

use crate::chain::Chain;
use crate::se3::{se3_exp, se3_log};

/// The own keyframes that keep a pose variable, in index order: every one a loop touches, every one in
/// `anchored` (keyframes with a prior), and the first and last of every segment.
pub fn kept_keyframes(chain: &Chain, own: RobotId, loops: &[&LoopClosure], anchored: &[u32]) -> Vec<u32> {
    let mut kept: Vec<u32> = loops
        .iter()
        .flat_map(|l| [l.target, l.source])
        .filter(|id| id.robot == own)
        .map(|id| id.index)
        .chain(anchored.iter().copied())
        .filter(|&index| chain.segment(index).is_some())
        .collect();
    let mut previous: Option<(u32, usize)> = None;
    for index in chain.indices() {
        let Some((segment, _)) = chain.segment(index) else {
            continue;
        };
        match previous {
            Some((last, last_segment)) if last_segment != segment => kept.extend([last, index]),
            None => kept.push(index),
            Some(_) => {}
        }
        previous = Some((index, segment));
    }
    kept.extend(previous.map(|(last, _)| last));
    kept.sort_unstable();
    kept.dedup();
    kept
}

/// Puts the own keyframes between kept ones (`kept`, in index order, their poses optimised in
/// `poses`) where the eliminated chain puts them.
pub fn place_between(poses: &mut BTreeMap<KeyframeId, Pose>, chain: &Chain, own: RobotId, kept: &[u32]) {
    let id = |index| KeyframeId { robot: own, index };
    for pair in kept.windows(2) {
        let (a, b) = (pair[0], pair[1]);
        let (Some(end), Some(&pose_a), Some(&pose_b)) =
            (chain.between(a, b), poses.get(&id(a)), poses.get(&id(b)))
        else {
            // Different segments: nothing joins a and b, and nothing lies between them in either.
            continue;
        };
        if b <= a + 1 {
            continue;
        }
        // The linear-Gaussian conditional mean of the chain given both ends: with perturbations on the
        // left in a's frame, keyframe k's covariance Σ_k is also its covariance with b (later steps
        // are independent of it), so k moves by Σ_k Σ_b⁻¹ δ_b when b moves by δ_b.
        let delta_b = se3_log(&(pose_a.inverse() * pose_b * end.target_from_source.inverse()));
        let Some(gain_b) = end.covariance.try_inverse().map(|inverse| inverse * delta_b) else {
            continue;
        };
        for index in chain.indices_between(a, b) {
            let Some(part) = chain.between(a, index) else {
                continue;
            };
            let delta = part.covariance * gain_b;
            poses.insert(id(index), pose_a * se3_exp(&delta) * part.target_from_source);
        }
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::{Matrix6, Translation3, UnitQuaternion};
    use skid_core::LoopId;

    use super::*;
    use crate::chain::Step;

    fn chain(indices: &[u32], gap_before: Option<u32>) -> Chain {
        let mut chain = Chain::default();
        let mut previous = None;
        for &index in indices {
            chain.add_keyframe(index);
            if let Some(from) = previous
                && Some(index) != gap_before
            {
                chain.add_step(
                    index,
                    Step {
                        from,
                        from_from_to: Pose::from_parts(
                            Translation3::new(1.0, 0.0, 0.0),
                            UnitQuaternion::from_euler_angles(0.0, 0.0, 0.05),
                        ),
                        covariance: Matrix6::identity() * 0.01,
                    },
                );
            }
            previous = Some(index);
        }
        chain
    }

    fn closure(target: KeyframeId, source: KeyframeId) -> LoopClosure {
        LoopClosure {
            id: LoopId(0),
            target,
            source,
            target_from_source: Pose::identity(),
            information: Matrix6::identity(),
        }
    }

    #[test]
    fn keeps_loop_ends_and_segment_ends() {
        let own = RobotId(0);
        let chain = chain(&(0..20).collect::<Vec<_>>(), Some(10));
        let touch = closure(
            KeyframeId { robot: own, index: 6 },
            KeyframeId {
                robot: RobotId(1),
                index: 3,
            },
        );
        let elsewhere = closure(
            KeyframeId {
                robot: RobotId(1),
                index: 4,
            },
            KeyframeId {
                robot: RobotId(2),
                index: 8,
            },
        );
        assert_eq!(
            kept_keyframes(&chain, own, &[&touch, &elsewhere], &[]),
            vec![0, 6, 9, 10, 19]
        );
        assert_eq!(
            kept_keyframes(&Chain::default(), own, &[&touch], &[]),
            Vec::<u32>::new()
        );
    }

    #[test]
    fn placement_follows_the_chain_and_meets_both_ends() {
        let own = RobotId(0);
        let chain = chain(&(0..11).collect::<Vec<_>>(), None);
        let id = |index| KeyframeId { robot: own, index };
        let end = chain.between(0, 10).unwrap().target_from_source;
        // b's optimised pose is the dead-reckoned one moved by 0.5 m and 2°.
        let shift = Pose::from_parts(
            Translation3::new(0.0, 0.5, 0.0),
            UnitQuaternion::from_euler_angles(0.0, 0.0, 0.035),
        );
        let mut poses = BTreeMap::from([(id(0), Pose::identity()), (id(10), shift * end)]);
        place_between(&mut poses, &chain, own, &[0, 10]);
        assert_eq!(poses.len(), 11);
        // Each keyframe takes the correction through its covariance: Σ_k Σ_b⁻¹ δ_b in a's frame.
        let delta_b = se3_log(&(poses[&id(10)] * end.inverse()));
        let gain = chain.between(0, 10).unwrap().covariance.try_inverse().unwrap() * delta_b;
        for k in 1..10 {
            let part = chain.between(0, k).unwrap();
            let expected = se3_exp(&(part.covariance * gain)) * part.target_from_source;
            assert!((poses[&id(k)].translation.vector - expected.translation.vector).norm() < 1e-9);
        }
        // The step from 9 to 10 keeps well under half of the correction (it is spread, not dumped).
        let last_step = poses[&id(9)].inverse() * poses[&id(10)];
        let odometry = chain.between(9, 10).unwrap().target_from_source;
        let mismatch = ((shift * end).translation.vector - end.translation.vector).norm();
        assert!((last_step.translation.vector - odometry.translation.vector).norm() < 0.5 * mismatch);
        assert!((poses[&id(10)].translation.vector - (shift * end).translation.vector).norm() < 1e-12);
        assert!(poses[&id(3)].translation.vector.iter().all(|v| v.is_finite()));
    }
}
