//! The graph view a robot's verifier sees: odometry chains of the robot and of its peers (from their
//! `OdomChain` messages), the back-end's optimised poses where it has them, and the accepted loops.

use std::collections::BTreeMap;

use skid_core::slots::{DescriptorIndex, GraphView, LoopClosure, RelativePose};
use skid_core::{KeyframeId, LoopId, Pose, RobotId};
use skid_geometry::OdometryChains;

/// Frames of robot `b` in robot `a` composed through third robots, one per robot `via`.
pub type FramesThroughOthers<'a> = &'a dyn Fn(RobotId, RobotId) -> Vec<(RobotId, Pose)>;

/// Borrowed pieces of a robot host, viewed as one graph.
pub struct HostGraph<'a> {
    pub chains: &'a OdometryChains,
    pub backend: Option<&'a dyn GraphView>,
    pub loops: &'a BTreeMap<LoopId, LoopClosure>,
    /// When each known keyframe (own and peers') was recorded.
    pub stamps: &'a BTreeMap<KeyframeId, u64>,
    /// Frames of `b` in `a` composed through third robots (see
    /// [`GraphView::frames_through_others`]); `None` when the host keeps none.
    pub through_others: Option<FramesThroughOthers<'a>>,
    /// The descriptors the robot holds (own and peers'), and the largest distance at which two of them
    /// show one place (a candidate's limit); `None` when the robot has no descriptor.
    pub descriptors: Option<(&'a dyn DescriptorIndex, f64)>,
}

impl GraphView for HostGraph<'_> {
    fn pose(&self, id: KeyframeId) -> Option<Pose> {
        self.backend
            .and_then(|graph| graph.pose(id))
            .or_else(|| self.chains.pose(id))
    }

    fn odometry_between(&self, target: KeyframeId, source: KeyframeId) -> Option<RelativePose> {
        self.chains.between(target, source)
    }

    fn keyframes(&self) -> Vec<KeyframeId> {
        self.chains.keyframes()
    }

    fn loops(&self) -> Vec<LoopClosure> {
        self.loops.values().cloned().collect()
    }

    fn keyframe_stamp_nanos(&self, id: KeyframeId) -> Option<u64> {
        self.stamps.get(&id).copied()
    }

    fn frames_through_others(&self, a: RobotId, b: RobotId) -> Vec<(RobotId, Pose)> {
        self.through_others.map_or_else(Vec::new, |through| through(a, b))
    }

    fn looks_alike(&self, a: KeyframeId, b: KeyframeId) -> Option<bool> {
        let (index, limit) = self.descriptors?;
        index.distance_between(a, b).map(|distance| distance <= limit)
    }
}
