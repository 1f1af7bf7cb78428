//! The graph view a robot's verifier sees: odometry chains of the robot and of its peers (from their
//! `OdomChain` messages), the back-end's optimised poses where it has them, and the accepted loops.

use std::collections::BTreeMap;

use skid_core::slots::{GraphView, LoopClosure, RelativePose};
use skid_core::{KeyframeId, LoopId, Pose};
use skid_geometry::OdometryChains;

/// Borrowed pieces of a robot host, viewed as one graph.
pub struct HostGraph<'a> {
    pub chains: &'a OdometryChains,
    pub backend: Option<&'a dyn GraphView>,
    pub loops: &'a BTreeMap<LoopId, LoopClosure>,
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
}
