//! The distributed pose graph of one robot (SKiD-SLAM, eq. 6 and `X_dis,α`): robot α optimises its own
//! keyframes plus the peer keyframes that its inter-robot loops touch, the peer keyframes of one robot
//! joined by that robot's odometry composed between them (one factor per consecutive pair of touched
//! keyframes, its information the inverse of the composed covariance).
//!
//! Before a peer is first connected, its keyframes are in its own odometry frame; the first loop that
//! reaches it from an aligned robot moves all of them rigidly into α's frame (`T_q ← T_c · z_cq`), so
//! that Levenberg-Marquardt starts near the solution.

use std::collections::{BTreeMap, BTreeSet};

use nalgebra::Isometry3;
use skid_core::slots::LoopClosure;
use skid_core::{KeyframeId, Pose, RobotId};

use crate::chain::Chains;
use crate::error::PgoError;
use crate::problem::{Problem, RawEdge, Unanchored};
use crate::se3::se3_adjoint;

/// Which part of the graph an optimisation covers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Scope {
    /// Every keyframe, odometry edge and loop (a centralised solve).
    Full,
    /// Robot `own`'s keyframes and the peer keyframes its loops touch.
    Distributed { own: RobotId },
}

/// The problem built for one optimisation, with the keyframe of each pose.
pub struct Subgraph {
    pub problem: Problem<Isometry3<f64>, 6>,
    pub keyframes: Vec<KeyframeId>,
    /// The loop each factor of `problem` measures (`None` for odometry), in factor order.
    pub factor_loops: Vec<Option<skid_core::LoopId>>,
}

/// The loops an optimisation uses: all of them, or those with an endpoint on `own`.
pub fn active_loops(loops: &BTreeMap<skid_core::LoopId, LoopClosure>, scope: Scope) -> Vec<&LoopClosure> {
    loops
        .values()
        .filter(|l| match scope {
            Scope::Full => true,
            Scope::Distributed { own } => l.target.robot == own || l.source.robot == own,
        })
        .collect()
}

/// Moves peers that active loops connect to an aligned robot into the aligned frame; returns the robots
/// aligned now.
pub fn align_peers(
    poses: &mut BTreeMap<KeyframeId, Pose>,
    aligned: &mut BTreeSet<RobotId>,
    loops: &[&LoopClosure],
) -> Vec<RobotId> {
    let mut newly = Vec::new();
    loop {
        let mut changed = false;
        for l in loops {
            let (t_in, s_in) = (
                aligned.contains(&l.target.robot),
                aligned.contains(&l.source.robot),
            );
            if t_in == s_in {
                continue;
            }
            // The unaligned endpoint's pose implied by the aligned one and the measurement.
            let (moving, implied) = if t_in {
                let Some(t) = poses.get(&l.target) else { continue };
                (l.source, t * l.target_from_source)
            } else {
                let Some(s) = poses.get(&l.source) else { continue };
                (l.target, s * l.target_from_source.inverse())
            };
            let Some(current) = poses.get(&moving) else {
                continue;
            };
            let correction = implied * current.inverse();
            for (id, pose) in poses.iter_mut() {
                if id.robot == moving.robot {
                    *pose = correction * *pose;
                }
            }
            aligned.insert(moving.robot);
            newly.push(moving.robot);
            changed = true;
        }
        if !changed {
            return newly;
        }
    }
}

/// Builds the problem of `scope` from the graph's current estimate.
pub fn build(
    poses: &BTreeMap<KeyframeId, Pose>,
    chains: &Chains,
    loops: &[&LoopClosure],
    scope: Scope,
    loop_is_robust: bool,
) -> Result<Subgraph, PgoError> {
    // Which keyframes take part.
    let mut included: BTreeSet<KeyframeId> = BTreeSet::new();
    for id in poses.keys() {
        if matches!(scope, Scope::Full) || matches!(scope, Scope::Distributed { own } if id.robot == own) {
            included.insert(*id);
        }
    }
    let mut touched: BTreeMap<RobotId, BTreeSet<u32>> = BTreeMap::new();
    for l in loops {
        for id in [l.target, l.source] {
            if !included.contains(&id) {
                touched.entry(id.robot).or_default().insert(id.index);
            }
        }
    }
    for (robot, indices) in &touched {
        for index in indices {
            included.insert(KeyframeId {
                robot: *robot,
                index: *index,
            });
        }
    }
    let keyframes: Vec<KeyframeId> = included.iter().copied().collect();
    let position: BTreeMap<KeyframeId, usize> =
        keyframes.iter().enumerate().map(|(k, id)| (*id, k)).collect();
    let mut edges = Vec::new();
    // Odometry of the fully included robots.
    for (robot, chain) in &chains.robots {
        for index in chain.indices() {
            let Some(step) = chain.step(index) else { continue };
            let (from, to) = (
                KeyframeId {
                    robot: *robot,
                    index: step.from,
                },
                KeyframeId { robot: *robot, index },
            );
            if touched.contains_key(robot) {
                continue;
            }
            if let (Some(&i), Some(&j)) = (position.get(&from), position.get(&to)) {
                let information = step
                    .covariance
                    .try_inverse()
                    .ok_or_else(|| PgoError::InvalidEdge {
                        edge: crate::error::EdgeLabel {
                            index: edges.len(),
                            from: from.to_string(),
                            to: to.to_string(),
                        },
                        reason: "the odometry covariance is singular".into(),
                    })?;
                edges.push(RawEdge {
                    i,
                    j,
                    measured: step.from_from_to,
                    information,
                    robust: false,
                });
            }
        }
    }
    // Peers: consecutive touched keyframes joined by their composed odometry.
    for (robot, indices) in &touched {
        let list: Vec<u32> = indices.iter().copied().collect();
        for pair in list.windows(2) {
            let (from, to) = (
                KeyframeId {
                    robot: *robot,
                    index: pair[0],
                },
                KeyframeId {
                    robot: *robot,
                    index: pair[1],
                },
            );
            let Some(relative) = chains.between(from, to) else {
                continue;
            };
            // Left covariance in the `from` frame to the right convention of the residual.
            let ad = se3_adjoint(&relative.target_from_source.inverse());
            let right = ad * relative.covariance * ad.transpose();
            let Some(information) = ((right + right.transpose()) * 0.5).try_inverse() else {
                continue;
            };
            edges.push(RawEdge {
                i: position[&from],
                j: position[&to],
                measured: relative.target_from_source,
                information: (information + information.transpose()) * 0.5,
                robust: false,
            });
        }
    }
    let mut factor_loops = vec![None; edges.len()];
    for l in loops {
        if let (Some(&i), Some(&j)) = (position.get(&l.target), position.get(&l.source)) {
            factor_loops.push(Some(l.id));
            edges.push(RawEdge {
                i,
                j,
                measured: l.target_from_source,
                information: l.information,
                robust: loop_is_robust,
            });
        }
    }
    let mut fixed = vec![false; keyframes.len()];
    // Gauge: the own robot's first keyframe (or the first keyframe of all for a full solve).
    let anchor = match scope {
        Scope::Full => keyframes.first().copied(),
        Scope::Distributed { own } => keyframes.iter().find(|id| id.robot == own).copied(),
    };
    if let Some(anchor) = anchor.and_then(|a| position.get(&a)) {
        fixed[*anchor] = true;
    }
    let initial: Vec<Pose> = keyframes.iter().map(|id| poses[id]).collect();
    let names = keyframes.clone();
    let problem = Problem::new(initial, fixed, &edges, Unanchored::AnchorFirst, &|k| {
        names[k].to_string()
    })?;
    Ok(Subgraph {
        problem,
        keyframes,
        factor_loops,
    })
}

/// Writes an optimised subgraph back, and moves the peer keyframes between touched ones rigidly with the
/// nearest optimised keyframe of their segment.
pub fn write_back(
    poses: &mut BTreeMap<KeyframeId, Pose>,
    chains: &Chains,
    subgraph: &Subgraph,
    scope: Scope,
) {
    let mut optimised: BTreeMap<RobotId, Vec<u32>> = BTreeMap::new();
    for (id, pose) in subgraph.keyframes.iter().zip(&subgraph.problem.poses) {
        poses.insert(*id, *pose);
        optimised.entry(id.robot).or_default().push(id.index);
    }
    let Scope::Distributed { own } = scope else { return };
    for (robot, anchors) in optimised {
        if robot == own {
            continue;
        }
        let Some(chain) = chains.robots.get(&robot) else {
            continue;
        };
        for index in chain.indices() {
            if anchors.binary_search(&index).is_ok() {
                continue;
            }
            let id = KeyframeId { robot, index };
            let nearest = anchors
                .iter()
                .filter(|a| chain.segment(**a).map(|s| s.0) == chain.segment(index).map(|s| s.0))
                .min_by_key(|a| a.abs_diff(index));
            let Some(&anchor) = nearest else { continue };
            let anchor_id = KeyframeId { robot, index: anchor };
            if let (Some(relative), Some(anchor_pose)) =
                (chains.between(anchor_id, id), poses.get(&anchor_id).copied())
            {
                poses.insert(id, anchor_pose * relative.target_from_source);
            }
        }
    }
}
