//! Every loop a robot's graph holds at the end of a run, judged against the ground truth when the source
//! gives one: the measured `target_from_source` against the keyframes' true relative pose
//! `(T^GT_target)⁻¹ · T^GT_source`. A loop whose error passes 2 m or 5° is false, the bound of a false merge
//! (one vocabulary across the benchmarks); the worst error of the loops kept is reported beside the
//! count, so that a tighter judgement can be read off `metrics.json` too.
//!
//! The loops are the robot's own accepted loops (within the robot and with its peers) and the fleet's
//! loops it holds (loops between other robots that place them, `loops.fleet_loops`), each loop once.

use std::collections::{BTreeMap, BTreeSet};

use serde::Serialize;
use skid_core::slots::LoopClosure;
use skid_core::{KeyframeId, Pose};

use crate::host::RobotHost;

/// A frame (a merge) or a loop farther than this from the truth is false, metres: one bound for every
/// benchmark and metric.
pub const FALSE_MERGE_M: f64 = 2.0;
/// A frame or a loop turned farther than this from the truth is false, degrees.
pub const FALSE_MERGE_DEG: f64 = 5.0;

/// One false loop, for the record.
#[derive(Clone, Debug, Serialize)]
pub struct FalseLoop {
    /// `robot:index` of the target and source keyframes.
    pub target: String,
    pub source: String,
    pub error_m: f64,
    pub error_deg: f64,
}

/// The loops of one robot's graph against the truth.
#[derive(Clone, Debug, Default, Serialize)]
pub struct LoopTruth {
    /// Loops both of whose keyframes have a ground-truth pose.
    pub checked: usize,
    /// Loops held without the truth of one of their keyframes.
    pub unchecked: usize,
    /// Checked loops farther than [`FALSE_MERGE_M`] or [`FALSE_MERGE_DEG`] from the truth.
    pub false_loops: usize,
    /// How many of the false loops join two robots.
    pub false_inter_robot: usize,
    /// The largest errors over the checked loops (each maximised on its own).
    pub worst_error_m: f64,
    pub worst_error_deg: f64,
    /// The false loops themselves, at most [`LISTED_FALSE_LOOPS`].
    pub listed: Vec<FalseLoop>,
}

/// How many false loops [`LoopTruth::listed`] names.
pub const LISTED_FALSE_LOOPS: usize = 20;

/// The true pose of every keyframe of every robot that has one, from the scan that made the keyframe.
pub(crate) fn keyframe_truths(robots: &[RobotHost]) -> BTreeMap<KeyframeId, Pose> {
    let mut truths = BTreeMap::new();
    for host in robots {
        let keyframes = host.keyframes();
        for scan in host.scans() {
            let (Some(index), Some(truth)) = (scan.keyframe, scan.ground_truth) else {
                continue;
            };
            // A scan names the keyframe at or before it; only the keyframe's own scan has its stamp.
            if keyframes
                .get(&index)
                .is_some_and(|keyframe| keyframe.stamp_nanos == scan.stamp_nanos)
            {
                truths.insert(
                    KeyframeId {
                        robot: host.robot(),
                        index,
                    },
                    truth,
                );
            }
        }
    }
    truths
}

/// Judges the loops `host`'s graph holds against `truths` ([`keyframe_truths`]).
pub(crate) fn loop_truth(host: &RobotHost, truths: &BTreeMap<KeyframeId, Pose>) -> LoopTruth {
    let mut seen = BTreeSet::new();
    let loops = host
        .accepted_loops()
        .values()
        .cloned()
        .chain(host.fleet_loops_in_graph())
        .filter(|closure| seen.insert((closure.target, closure.source)));
    judge(loops, truths)
}

fn judge(loops: impl Iterator<Item = LoopClosure>, truths: &BTreeMap<KeyframeId, Pose>) -> LoopTruth {
    let mut truth = LoopTruth::default();
    for closure in loops {
        let (Some(target), Some(source)) = (truths.get(&closure.target), truths.get(&closure.source)) else {
            truth.unchecked += 1;
            continue;
        };
        let true_target_from_source = target.inverse() * source;
        let error = true_target_from_source.inverse() * closure.target_from_source;
        let (error_m, error_deg) = (
            error.translation.vector.norm(),
            error.rotation.angle().to_degrees(),
        );
        truth.checked += 1;
        truth.worst_error_m = truth.worst_error_m.max(error_m);
        truth.worst_error_deg = truth.worst_error_deg.max(error_deg);
        if error_m > FALSE_MERGE_M || error_deg > FALSE_MERGE_DEG {
            truth.false_loops += 1;
            truth.false_inter_robot += usize::from(closure.is_inter_robot());
            if truth.listed.len() < LISTED_FALSE_LOOPS {
                truth.listed.push(FalseLoop {
                    target: format!("{}:{}", closure.target.robot.0, closure.target.index),
                    source: format!("{}:{}", closure.source.robot.0, closure.source.index),
                    error_m,
                    error_deg,
                });
            }
        }
    }
    truth
}

#[cfg(test)]
mod tests {
    use super::*;
    use skid_core::{Information, LoopId, RobotId};
    use skid_testkit::scene::x_yaw_pose;

    fn id(robot: u32, index: u32) -> KeyframeId {
        KeyframeId {
            robot: RobotId(robot),
            index,
        }
    }

    fn closure(target: KeyframeId, source: KeyframeId, target_from_source: Pose) -> LoopClosure {
        LoopClosure {
            id: LoopId(u64::from(target.index) * 1000 + u64::from(source.index)),
            target,
            source,
            target_from_source,
            information: Information::identity(),
        }
    }

    #[test]
    fn a_loop_off_by_a_block_is_false_and_one_off_by_centimetres_is_not() {
        let truths = BTreeMap::from([
            (id(0, 1), x_yaw_pose(10.0, 0.0)),
            (id(1, 4), x_yaw_pose(12.0, 90.0)),
            (id(1, 5), x_yaw_pose(30.0, 0.0)),
        ]);
        let truth_of = |a: KeyframeId, b: KeyframeId| truths[&a].inverse() * truths[&b];
        let near = truth_of(id(0, 1), id(1, 4)) * x_yaw_pose(0.05, 0.2);
        let block_off = truth_of(id(0, 1), id(1, 5)) * x_yaw_pose(100.0, 1.5);
        let turned = truth_of(id(1, 4), id(1, 5)) * x_yaw_pose(0.0, 90.0);
        let loops = [
            closure(id(0, 1), id(1, 4), near),
            closure(id(0, 1), id(1, 5), block_off),
            closure(id(1, 4), id(1, 5), turned),
            closure(id(0, 1), id(2, 0), Pose::identity()),
        ];
        let judged = judge(loops.into_iter(), &truths);
        assert_eq!(judged.checked, 3);
        assert_eq!(judged.unchecked, 1);
        assert_eq!(judged.false_loops, 2);
        assert_eq!(judged.false_inter_robot, 1);
        assert!((judged.worst_error_m - 100.0).abs() < 1e-9);
        assert!((judged.worst_error_deg - 90.0).abs() < 1e-9);
        assert_eq!(judged.listed[0].source, "1:5");
    }
}
