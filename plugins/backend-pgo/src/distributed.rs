//! The distributed pose graph of one robot (SKiD-SLAM, eq. 6 and `X_dis,α`): robot α optimises its own
//! keyframes plus the peer keyframes that its inter-robot loops touch, the peer keyframes of one robot
//! joined by that robot's odometry composed between them (one factor per consecutive pair of touched
//! keyframes, its information the inverse of the composed covariance).
//!
//! With the fleet's loops shared (`loops.fleet_loops`), the loops between peers and the peers' own
//! loops touch peer keyframes the same way (Swarm-SLAM's fleet graph, condensed as above).
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
use crate::own_chain;
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

/// A prior on a keyframe: its pose in the world frame and the information of the residual
/// `Log(Z⁻¹ T)`, translation first. In the problem it is a factor from the world origin, one extra pose
/// held fixed, to the keyframe (GTSAM's `PriorFactor` has the same residual).
#[derive(Clone, Copy, Debug)]
pub struct Prior {
    pub world_from_sensor: Pose,
    pub information: nalgebra::Matrix6<f64>,
}

/// The problem built for one optimisation, with the keyframe of each pose (the world origin, when
/// priors need it, is the problem's last pose and has no keyframe).
pub struct Subgraph {
    pub problem: Problem<Isometry3<f64>, 6>,
    pub keyframes: Vec<KeyframeId>,
    /// The loop each factor of `problem` measures (`None` for odometry), in factor order.
    pub factor_loops: Vec<Option<skid_core::LoopId>>,
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
    priors: &BTreeMap<KeyframeId, Prior>,
    scope: Scope,
    loop_is_robust: bool,
) -> Result<Subgraph, PgoError> {
    // Which keyframes take part: every one in a full solve; in a distributed one, the own keyframes
    // that keep a variable (see `crate::own_chain`).
    let mut included: BTreeSet<KeyframeId> = BTreeSet::new();
    let own_kept = match scope {
        Scope::Full => {
            included.extend(poses.keys().copied());
            Vec::new()
        }
        Scope::Distributed { own } => {
            let anchored: Vec<u32> = priors
                .keys()
                .filter(|id| id.robot == own)
                .map(|id| id.index)
                .collect();
            let kept = chains
                .robots
                .get(&own)
                .map(|chain| own_chain::kept_keyframes(chain, own, loops, &anchored))
                .unwrap_or_default();
            included.extend(
                kept.iter()
                    .map(|&index| KeyframeId { robot: own, index })
                    .filter(|id| poses.contains_key(id)),
            );
            kept
        }
    };
    let mut touched: BTreeMap<RobotId, BTreeSet<u32>> = BTreeMap::new();
    for l in loops {
        for id in [l.target, l.source] {
            if !included.contains(&id) {
                touched.entry(id.robot).or_default().insert(id.index);
            }
        }
    }
    // A peer that takes part keeps its priors' keyframes too.
    for id in priors.keys() {
        if !included.contains(id)
            && let Some(indices) = touched.get_mut(&id.robot)
        {
            indices.insert(id.index);
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
    // Every odometry step of every robot in a full solve (a distributed one composes them below).
    let fully_included = chains.robots.iter().filter(|_| scope == Scope::Full);
    for (robot, chain) in fully_included {
        for index in chain.indices() {
            let Some(step) = chain.step(index) else { continue };
            let (from, to) = (
                KeyframeId {
                    robot: *robot,
                    index: step.from,
                },
                KeyframeId { robot: *robot, index },
            );
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
    // Peers, and the own robot in a distributed solve: consecutive included keyframes joined by their
    // composed odometry.
    let own_robot = match scope {
        Scope::Distributed { own } => Some((own, own_kept)),
        Scope::Full => None,
    };
    let composed = touched
        .iter()
        .map(|(robot, indices)| (*robot, indices.iter().copied().collect::<Vec<u32>>()))
        .chain(own_robot);
    for (robot, list) in composed {
        for pair in list.windows(2) {
            let from = KeyframeId {
                robot,
                index: pair[0],
            };
            let to = KeyframeId {
                robot,
                index: pair[1],
            };
            if let (Some(&i), Some(&j)) = (position.get(&from), position.get(&to))
                && let Some(edge) = composed_edge(chains, from, to, i, j)
            {
                edges.push(edge);
            }
        }
    }
    // Priors: factors from the world origin, the pose after the keyframes.
    let origin = keyframes.len();
    for (id, prior) in priors {
        if let Some(&j) = position.get(id) {
            edges.push(RawEdge {
                i: origin,
                j,
                measured: prior.world_from_sensor,
                information: prior.information,
                robust: false,
            });
        }
    }
    let with_origin = edges.iter().any(|edge| edge.i == origin);
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
    let mut initial: Vec<Pose> = keyframes.iter().map(|id| poses[id]).collect();
    if with_origin {
        // Gauge: the world the priors are given in.
        fixed.push(true);
        initial.push(Pose::identity());
    } else {
        // Gauge: the own robot's first keyframe (or the first keyframe of all for a full solve).
        let anchor = match scope {
            Scope::Full => keyframes.first().copied(),
            Scope::Distributed { own } => keyframes.iter().find(|id| id.robot == own).copied(),
        };
        if let Some(anchor) = anchor.and_then(|a| position.get(&a)) {
            fixed[*anchor] = true;
        }
    }
    let names = keyframes.clone();
    let problem = Problem::new(initial, fixed, &edges, Unanchored::AnchorFirst, &|k| {
        names
            .get(k)
            .map_or_else(|| "the world origin".to_owned(), ToString::to_string)
    })?;
    Ok(Subgraph {
        problem,
        keyframes,
        factor_loops,
    })
}

/// The odometry of a robot composed from keyframe `from` to `to` (positions `i` and `j`) as one factor;
/// `None` across a gap in the odometry or for a singular covariance.
fn composed_edge(
    chains: &Chains,
    from: KeyframeId,
    to: KeyframeId,
    i: usize,
    j: usize,
) -> Option<RawEdge<Isometry3<f64>, 6>> {
    let relative = chains.between(from, to)?;
    // Left covariance in the `from` frame to the right convention of the residual.
    let ad = se3_adjoint(&relative.target_from_source.inverse());
    let right = ad * relative.covariance * ad.transpose();
    let information = ((right + right.transpose()) * 0.5).try_inverse()?;
    Some(RawEdge {
        i,
        j,
        measured: relative.target_from_source,
        information: (information + information.transpose()) * 0.5,
        robust: false,
    })
}

/// Writes an optimised subgraph back. In a distributed solve, when the subgraph was `solved`, the own
/// keyframes left out of it are put back along the chain ([`own_chain::place_between`]); the peer
/// keyframes between touched ones move rigidly with the nearest optimised keyframe of their segment, all
/// of them after a solve and otherwise only those after `placed_through` (the last placed of each peer,
/// which this updates): nothing else moved.
pub fn write_back(
    poses: &mut BTreeMap<KeyframeId, Pose>,
    chains: &Chains,
    subgraph: &Subgraph,
    scope: Scope,
    solved: bool,
    placed_through: &mut BTreeMap<RobotId, u32>,
) {
    let mut optimised: BTreeMap<RobotId, Vec<u32>> = BTreeMap::new();
    for (id, pose) in subgraph.keyframes.iter().zip(&subgraph.problem.poses) {
        poses.insert(*id, *pose);
        optimised.entry(id.robot).or_default().push(id.index);
    }
    let Scope::Distributed { own } = scope else { return };
    for (robot, anchors) in optimised {
        let Some(chain) = chains.robots.get(&robot) else {
            continue;
        };
        if robot == own {
            if solved {
                own_chain::place_between(poses, chain, own, &anchors);
            }
            continue;
        }
        let indices: Vec<u32> = match placed_through.get(&robot) {
            Some(&last) if !solved => chain.indices_after(last).collect(),
            _ => chain.indices().collect(),
        };
        if let Some(&last) = indices.last() {
            placed_through.insert(robot, last);
        }
        for index in indices {
            let Err(above) = anchors.binary_search(&index) else {
                continue;
            };
            // The anchors in index order: the nearest in the segment is the one just below or just above.
            let segment = chain.segment(index).map(|s| s.0);
            let nearest = [above.checked_sub(1), Some(above)]
                .into_iter()
                .flatten()
                .filter_map(|k| anchors.get(k).copied())
                .filter(|a| chain.segment(*a).map(|s| s.0) == segment)
                .min_by_key(|a| a.abs_diff(index));
            let Some(anchor) = nearest else { continue };
            let anchor_id = KeyframeId { robot, index: anchor };
            let id = KeyframeId { robot, index };
            if let (Some(relative), Some(anchor_pose)) =
                (chains.between(anchor_id, id), poses.get(&anchor_id).copied())
            {
                poses.insert(id, anchor_pose * relative.target_from_source);
            }
        }
    }
}
