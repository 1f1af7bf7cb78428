//! What this robot's back-end holds, kept beside it so the host never has to ask the plugin: which
//! keyframes (its own and its peers') are in the graph, where each joined peer's odometry frame was
//! placed, the loops that wait for a peer keyframe's odometry, and when the graph was last optimised.

use std::collections::{BTreeMap, BTreeSet};

use skid_core::slots::LoopClosure;
use skid_core::{KeyframeId, Pose, RobotId};

/// The host's record of its back-end's graph.
#[derive(Debug, Default)]
pub(crate) struct BackendBook {
    /// Keyframes present in the back-end's graph.
    in_graph: BTreeSet<KeyframeId>,
    /// Where each joined peer's odometry frame sits in this robot's frame, from the first loop with it.
    peer_frames: BTreeMap<RobotId, Pose>,
    /// Accepted loops that wait for a peer keyframe's odometry before entering the back-end.
    deferred_loops: Vec<LoopClosure>,
    /// How many times the back-end has optimised (observers learn of new optimisations from it).
    optimizations: u64,
    keyframes_since_optimize: u32,
}

impl BackendBook {
    pub(crate) fn contains(&self, id: KeyframeId) -> bool {
        self.in_graph.contains(&id)
    }

    /// The keyframes of `robot` in the graph, in index order.
    pub(crate) fn keyframes_of(&self, robot: RobotId) -> impl Iterator<Item = KeyframeId> + '_ {
        let first = KeyframeId { robot, index: 0 };
        let last = KeyframeId {
            robot,
            index: u32::MAX,
        };
        self.in_graph.range(first..=last).copied()
    }

    /// Records that a keyframe entered the graph.
    pub(crate) fn insert(&mut self, id: KeyframeId) {
        self.in_graph.insert(id);
    }

    /// Whether `peer`'s odometry chain has been added to the graph.
    pub(crate) fn has_peer(&self, peer: RobotId) -> bool {
        self.peer_frames.contains_key(&peer)
    }

    /// Records where `peer`'s odometry frame was placed when its chain joined the graph.
    pub(crate) fn place_peer(&mut self, peer: RobotId, frame: Pose) {
        self.peer_frames.insert(peer, frame);
    }

    /// Where `peer`'s odometry frame sits in this robot's frame, once the peer has joined.
    pub(crate) fn peer_frame(&self, peer: RobotId) -> Option<Pose> {
        self.peer_frames.get(&peer).copied()
    }

    /// The peers whose chains are in the graph.
    pub(crate) fn peers(&self) -> impl Iterator<Item = RobotId> + '_ {
        self.peer_frames.keys().copied()
    }

    /// Most loops kept waiting for keyframes.
    pub(crate) fn deferred_count(&self) -> usize {
        self.deferred_loops.len()
    }

    /// Keeps a loop until both its keyframes are in the graph.
    pub(crate) fn defer(&mut self, closure: LoopClosure) {
        self.deferred_loops.push(closure);
    }

    /// The deferred loops, to try again.
    pub(crate) fn take_deferred(&mut self) -> Vec<LoopClosure> {
        std::mem::take(&mut self.deferred_loops)
    }

    /// Counts one new keyframe; true when `every` keyframes have passed since the last optimisation.
    pub(crate) fn keyframe_added(&mut self, every: u32) -> bool {
        self.keyframes_since_optimize += 1;
        self.keyframes_since_optimize >= every.max(1)
    }

    /// Counts one optimisation.
    pub(crate) fn optimized(&mut self) {
        self.keyframes_since_optimize = 0;
        self.optimizations += 1;
    }

    pub(crate) fn optimizations(&self) -> u64 {
        self.optimizations
    }
}
