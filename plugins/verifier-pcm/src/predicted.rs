//! What a frame hypothesis predicts beyond its own loops. A consistent set of loops between robots `a`
//! and `b` says where `b`'s frame sits in `a`'s, and so where else the two robots' keyframes were in
//! one place: every pair of keyframes that the frame puts within `predicted_overlap_m` of each other.
//! Where they truly were, their descriptors look alike as the set's own keyframes did; a look-alike
//! stretch of two different places (a street and its quarter-turned copy, one robot's first seconds
//! and another's passage elsewhere) stops looking alike beyond it, on the rest of the routes the frame
//! lays side by side. So a set is granted only while most of the keyframe pairs it predicts farther
//! than `predicted_beyond_m` from its loops' places look alike too, once there are at least
//! `min_predicted_pairs` of them; a granted set whose routes run on apart is withdrawn when the
//! predictions fail. This is the check the SKiD issue on self-similar places asks of a merge beyond
//! pairwise consistency: evidence of another kind than more loops of the same look-alike. Descriptors
//! are compared through [`GraphView::looks_alike`]; without it (another host, a plugin descriptor
//! that cannot compare stored keyframes) nothing is predicted and the rule stands aside.

use skid_core::slots::GraphView;
use skid_core::{KeyframeId, Pose, RobotId};

use crate::consistency::PcmLoop;

/// The thresholds of the prediction test.
#[derive(Clone, Copy, Debug)]
pub(crate) struct OverlapRule {
    /// Keyframes the frame puts this close show one place; 0 turns the test off.
    pub radius_m: f64,
    /// Only keyframes of robot `a` this far from every loop's keyframe on `a` count.
    pub beyond_m: f64,
    pub min_pairs: usize,
    pub min_alike_fraction: f64,
}

/// The predicted keyframe pairs beyond the loops whose descriptors could be compared, and how many of
/// them look alike.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Predicted {
    pub pairs: usize,
    pub alike: usize,
}

impl OverlapRule {
    /// Whether the predictions refute the frame.
    pub(crate) fn refutes(&self, predicted: Predicted) -> bool {
        self.radius_m > 0.0
            && predicted.pairs >= self.min_pairs.max(1)
            && (predicted.alike as f64) < self.min_alike_fraction * predicted.pairs as f64
    }
}

/// How a robot's keyframes are placed against its first one.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Along {
    /// By the odometry chains alone.
    Odometry,
    /// By the graph's poses (the back-end's optimised estimate, loops included) where it holds both
    /// keyframes, else by the odometry.
    Estimate,
}

/// Where one member puts robot `b`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Placement {
    /// The member's index into the loops.
    pub member: usize,
    pub a_first_from_b_first: Pose,
    pub b_first_from_source: Pose,
}

/// Where each member whose keyframes the graph reaches puts robot `b`, each robot's keyframes placed
/// against its first one `along` the odometry or the estimate.
pub(crate) fn placements(
    loops: &[PcmLoop],
    members: &[usize],
    graph: &dyn GraphView,
    along: Along,
) -> Vec<Placement> {
    let first_from = |id: KeyframeId| -> Option<Pose> {
        let first = start(id.robot);
        let estimated = match along {
            Along::Estimate => graph
                .pose(first)
                .zip(graph.pose(id))
                .map(|(first_pose, pose)| first_pose.inverse() * pose),
            Along::Odometry => None,
        };
        estimated.or_else(|| Some(graph.odometry_between(first, id)?.target_from_source))
    };
    members
        .iter()
        .filter_map(|&k| {
            let member = &loops[k];
            let a_first_from_target = first_from(member.target)?;
            let b_first_from_source = first_from(member.source)?;
            Some(Placement {
                member: k,
                a_first_from_b_first: a_first_from_target
                    * member.target_from_source
                    * b_first_from_source.inverse(),
                b_first_from_source,
            })
        })
        .collect()
}

fn start(robot: RobotId) -> KeyframeId {
    KeyframeId { robot, index: 0 }
}

/// The placement nearest all the others (the smallest sum of translation distances): one frame that
/// stands for the set without being pulled by its noisiest loop.
fn medoid(frames: &[Pose]) -> Option<Pose> {
    let cost = |p: &Pose| -> f64 {
        frames
            .iter()
            .map(|q| (p.translation.vector - q.translation.vector).norm())
            .sum()
    };
    frames
        .iter()
        .map(|frame| (cost(frame), frame))
        .min_by(|x, y| x.0.total_cmp(&y.0))
        .map(|(_, frame)| *frame)
}

/// The keyframes of `robot` with their positions in its first keyframe's frame, by odometry.
fn route(robot: RobotId, graph: &dyn GraphView) -> Vec<(KeyframeId, nalgebra::Vector3<f64>)> {
    graph
        .keyframes()
        .into_iter()
        .filter(|id| id.robot == robot)
        .filter_map(|id| {
            let relative = graph.odometry_between(start(robot), id)?;
            Some((id, relative.target_from_source.translation.vector))
        })
        .collect()
}

/// The keyframe pairs the set's frame predicts beyond its loops: each keyframe of robot `a` farther
/// than `beyond_m` from every member's keyframe on `a`, with the nearest keyframe of robot `b` the
/// frame puts within `radius_m` of it; counted when both descriptors can be compared.
pub(crate) fn predicted_overlaps(
    rule: &OverlapRule,
    loops: &[PcmLoop],
    members: &[usize],
    graph: &dyn GraphView,
) -> Predicted {
    let mut predicted = Predicted::default();
    let Some(first) = members.first().and_then(|&k| loops.get(k)) else {
        return predicted;
    };
    if rule.radius_m <= 0.0 {
        return predicted;
    }
    // A host that cannot compare the keyframes of any of the set's loops has no descriptors to compare
    // (the replay of a recorded problem): nothing to predict with, and the routes need not be laid out.
    if members
        .iter()
        .all(|&k| graph.looks_alike(loops[k].target, loops[k].source).is_none())
    {
        return predicted;
    }
    let (a, b) = (first.target.robot, first.source.robot);
    let frames: Vec<Pose> = placements(loops, members, graph, Along::Odometry)
        .into_iter()
        .map(|placed| placed.a_first_from_b_first)
        .collect();
    let Some(frame) = medoid(&frames) else {
        return predicted;
    };
    let route_a = route(a, graph);
    let loop_places: Vec<nalgebra::Vector3<f64>> = members
        .iter()
        .filter_map(|&k| {
            route_a
                .iter()
                .find(|(id, _)| *id == loops[k].target)
                .map(|(_, p)| *p)
        })
        .collect();
    let route_b: Vec<(KeyframeId, nalgebra::Vector3<f64>)> = route(b, graph)
        .into_iter()
        .map(|(id, position)| (id, frame.transform_point(&position.into()).coords))
        .collect();
    for (id_a, position_a) in &route_a {
        if loop_places
            .iter()
            .any(|place| (place - position_a).norm() <= rule.beyond_m)
        {
            continue;
        }
        let nearest = route_b
            .iter()
            .map(|(id_b, position_b)| (*id_b, (position_b - position_a).norm()))
            .filter(|&(_, distance)| distance <= rule.radius_m)
            .min_by(|x, y| x.1.total_cmp(&y.1));
        let Some((id_b, _)) = nearest else {
            continue;
        };
        if let Some(alike) = graph.looks_alike(*id_a, id_b) {
            predicted.pairs += 1;
            predicted.alike += usize::from(alike);
        }
    }
    tracing::debug!(
        robots = %format!("{a}-{b}"),
        loops = members.len(),
        pairs = predicted.pairs,
        alike = predicted.alike,
        "PCM: keyframe pairs a frame hypothesis predicts beyond its loops"
    );
    predicted
}
