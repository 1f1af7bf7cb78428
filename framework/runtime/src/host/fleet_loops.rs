//! The fleet's loops in this robot's graph (`loops.fleet_loops`): loops peers found between other
//! robots, or within themselves, which each robot broadcasts beside its loops with single peers. They
//! enter this robot's back-end once both their robots are placed in its graph, and a loop between a
//! placed robot and one that is not places the latter's whole chain through it, so a robot is drawn into
//! this one's frame through any robot already in it. This is how Swarm-SLAM's optimiser merges every
//! robot linked by any loop, and how Kimera-Multi's robots share what their outlier rejection kept; the
//! paper's distributed graph joins each peer by its odometry alone. On COSMO-Bench's real problems the
//! peers' own loops and their loops with third robots bring every robot within 1.25× of GTSAM's
//! centralised GNC (`docs/records/`).
//!
//! A peer's loop is a claim, not a fact, here as on the loops a peer accepted with this robot: each goes
//! through a verifier of this robot's own (a second instance of the configured one, so the fleet's
//! loops are pooled by robot pair apart from this robot's own), judged on the poses alone (the finder
//! checked the fit on the clouds), and enters the back-end only once that verifier accepts it. A robot
//! that forges loops between itself and a third robot meets the same consistency test as the finder's.

use std::collections::BTreeMap;

use skid_config::ResolvedConfig;
use skid_core::slots::{LoopCandidate, LoopClosure, Verdict};
use skid_core::{CloudView, Information, LoopId, Pose, RobotId};

use super::RobotHost;
use super::announced::Pair;
use crate::error::RuntimeError;

/// The fleet loops get back-end ids from here up, clear of the ids of the loop book's own loops.
const FIRST_FLEET_LOOP_ID: u64 = 1 << 48;

/// Most fleet loops held from one peer; more are refused and counted as a fault of that peer.
pub(crate) const MAX_FLEET_LOOPS_PER_PEER: usize = 20_000;

/// Where one of the fleet's loops stands here.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Standing {
    /// Waiting for the odometry of its keyframes before the verifier can judge it.
    AwaitingPoses,
    /// Submitted; the verifier has not decided (or refused it, or withdrew it).
    Judged,
    /// Accepted by this robot's fleet verifier, waiting for both its robots to be placed in the graph.
    Accepted,
    /// In the back-end.
    InBackend,
}

/// One loop a peer found, and where it stands.
#[derive(Clone, Debug)]
struct FleetLoop {
    closure: LoopClosure,
    from: RobotId,
    standing: Standing,
}

/// What a peer's announcement did to the book.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) enum Received {
    /// A loop not held before.
    New,
    /// Held already (a repeat).
    Known,
    /// The sender holds its limit of fleet loops here.
    Full,
}

/// The fleet loops this robot holds, by keyframe pair.
#[derive(Debug, Default)]
pub(crate) struct FleetLoopBook {
    loops: BTreeMap<Pair, FleetLoop>,
    pairs: BTreeMap<LoopId, Pair>,
    per_peer: BTreeMap<RobotId, usize>,
    next_id: u64,
}

impl FleetLoopBook {
    /// Records a loop `from` announced.
    pub(crate) fn receive(
        &mut self,
        from: RobotId,
        pair: Pair,
        target_from_source: Pose,
        information: Information,
    ) -> Received {
        if self.loops.contains_key(&pair) {
            return Received::Known;
        }
        let Some(id) = FIRST_FLEET_LOOP_ID.checked_add(self.next_id).map(LoopId) else {
            return Received::Full;
        };
        let held = self.per_peer.entry(from).or_default();
        if *held >= MAX_FLEET_LOOPS_PER_PEER {
            return Received::Full;
        }
        *held += 1;
        self.next_id += 1;
        self.pairs.insert(id, pair);
        let closure = LoopClosure {
            id,
            target: pair.0,
            source: pair.1,
            target_from_source,
            information,
        };
        self.loops.insert(
            pair,
            FleetLoop {
                closure,
                from,
                standing: Standing::AwaitingPoses,
            },
        );
        Received::New
    }

    /// The loops waiting for their keyframes' odometry; each counts as submitted from here on.
    pub(crate) fn take_awaiting_poses(&mut self) -> Vec<LoopClosure> {
        let mut ready = Vec::new();
        for held in self.loops.values_mut() {
            if held.standing == Standing::AwaitingPoses {
                held.standing = Standing::Judged;
                ready.push(held.closure.clone());
            }
        }
        ready
    }

    /// A loop the verifier could not judge yet waits for its odometry again.
    pub(crate) fn await_poses(&mut self, id: LoopId) {
        if let Some(held) = self.pairs.get(&id).and_then(|pair| self.loops.get_mut(pair)) {
            held.standing = Standing::AwaitingPoses;
        }
    }

    /// The verifier accepted a loop: it waits for its robots' placement.
    pub(crate) fn accepted(&mut self, id: LoopId) {
        if let Some(held) = self.pairs.get(&id).and_then(|pair| self.loops.get_mut(pair))
            && held.standing == Standing::Judged
        {
            held.standing = Standing::Accepted;
        }
    }

    /// The verifier refused or withdrew a loop; returns its id when it was in the back-end.
    pub(crate) fn refused(&mut self, id: LoopId) -> Option<LoopId> {
        let held = self.pairs.get(&id).and_then(|pair| self.loops.get_mut(pair))?;
        let was_in_backend = held.standing == Standing::InBackend;
        held.standing = Standing::Judged;
        was_in_backend.then_some(id)
    }

    /// Forgets a loop its finder retracted; returns its id when it was in the back-end.
    pub(crate) fn retract(&mut self, from: RobotId, pair: Pair) -> Option<LoopId> {
        if self.loops.get(&pair).is_none_or(|held| held.from != from) {
            return None;
        }
        let held = self.loops.remove(&pair)?;
        self.pairs.remove(&held.closure.id);
        if let Some(count) = self.per_peer.get_mut(&from) {
            *count = count.saturating_sub(1);
        }
        (held.standing == Standing::InBackend).then_some(held.closure.id)
    }

    /// The accepted loops not in the back-end yet.
    pub(crate) fn waiting(&self) -> Vec<LoopClosure> {
        self.loops
            .values()
            .filter(|held| held.standing == Standing::Accepted)
            .map(|held| held.closure.clone())
            .collect()
    }

    /// Records that a loop entered the back-end.
    pub(crate) fn entered(&mut self, pair: Pair) {
        if let Some(held) = self.loops.get_mut(&pair) {
            held.standing = Standing::InBackend;
        }
    }

    /// The loops in the back-end.
    pub(crate) fn in_backend(&self) -> impl Iterator<Item = &LoopClosure> {
        self.loops
            .values()
            .filter(|held| held.standing == Standing::InBackend)
            .map(|held| &held.closure)
    }

    /// Loops held, and of them those in the back-end.
    pub(crate) fn counts(&self) -> (usize, usize) {
        (self.loops.len(), self.in_backend().count())
    }
}

impl RobotHost {
    /// Whether `robot`'s keyframes are placed in this robot's graph (it is this robot, or a peer whose
    /// chain joined).
    fn placed_in_graph(&self, robot: RobotId) -> bool {
        robot == self.robot || self.graph.has_peer(robot)
    }

    /// Puts the waiting fleet loops into the back-end where both robots are placed, placing a robot
    /// through a loop that joins it to a placed one, until nothing more can enter.
    pub(crate) fn place_fleet_loops(&mut self, config: &ResolvedConfig) -> Result<(), RuntimeError> {
        if self.plugins.backend.is_none() {
            return Ok(());
        }
        loop {
            let mut progress = false;
            for closure in self.fleet_loops.waiting() {
                let (target, source) = (closure.target, closure.source);
                let placed = (
                    self.placed_in_graph(target.robot),
                    self.placed_in_graph(source.robot),
                );
                let through = match placed {
                    (true, true) => None,
                    (true, false) => Some((target, source, closure.target_from_source)),
                    (false, true) => Some((source, target, closure.target_from_source.inverse())),
                    (false, false) => continue,
                };
                if let Some((placed_end, other_end, placed_from_other)) = through {
                    let Some(placed_pose) = self.backend_graph().and_then(|graph| graph.pose(placed_end))
                    else {
                        continue;
                    };
                    self.place_peer_chain(config, placed_pose, other_end, &placed_from_other)?;
                    progress |= self.graph.has_peer(other_end.robot);
                }
                if self.graph.contains(target) && self.graph.contains(source) {
                    self.add_fleet_loop(config, closure)?;
                    progress = true;
                }
            }
            if !progress {
                return Ok(());
            }
        }
    }

    fn add_fleet_loop(&mut self, config: &ResolvedConfig, closure: LoopClosure) -> Result<(), RuntimeError> {
        let pair = (closure.target, closure.source);
        self.backend_add_loop(config, closure)?;
        self.fleet_loops.entered(pair);
        Ok(())
    }

    /// A loop `from` found that does not join this robot: held (`loops.fleet_loops`), or refused and
    /// counted when the fleet does not share its loops, when `from` is not one of its robots (a robot
    /// announces only the loops it found), or when `from` holds its limit here.
    pub(crate) fn receive_fleet_loop(
        &mut self,
        config: &ResolvedConfig,
        from: RobotId,
        pair: Pair,
        target_from_source: Pose,
        information: Information,
    ) {
        let (target, source) = pair;
        if !config.loops.fleet_loops || (target.robot != from && source.robot != from) {
            self.peer_faults.record(
                self.robot,
                from,
                "loop_not_shared",
                format_args!("a loop {target} ↔ {source} that is not between {from} and this robot"),
            );
            return;
        }
        if self
            .fleet_loops
            .receive(from, pair, target_from_source, information)
            == Received::Full
        {
            self.peer_faults.record(
                self.robot,
                from,
                "fleet_loops_full",
                format_args!(
                    "{MAX_FLEET_LOOPS_PER_PEER} loops of this peer held already; {target} ↔ {source} refused"
                ),
            );
        }
    }

    /// Submits the fleet's loops whose keyframes the odometry known here places to the fleet verifier,
    /// and puts those it accepts into the back-end.
    pub(crate) fn judge_fleet_loops(&mut self, config: &ResolvedConfig) -> Result<(), RuntimeError> {
        for closure in self.fleet_loops.take_awaiting_poses() {
            if self.chains.pose(closure.target).is_none() || self.chains.pose(closure.source).is_none() {
                self.fleet_loops.await_poses(closure.id);
                continue;
            }
            let submitted = LoopCandidate {
                closure,
                target_cloud: CloudView::default(),
                source_cloud: CloudView::default(),
            };
            let verdict = self.judge_by(config, true, submitted)?;
            self.apply_fleet_verdict(config, verdict)?;
        }
        self.place_fleet_loops(config)
    }

    /// Lets the fleet verifier re-judge the fleet's loops against the graph as it is now.
    pub(crate) fn reconsider_fleet_loops(&mut self, config: &ResolvedConfig) -> Result<(), RuntimeError> {
        if let Some(verdict) = self.reconsidered(config, true)? {
            self.apply_fleet_verdict(config, verdict)?;
            self.place_fleet_loops(config)?;
        }
        Ok(())
    }

    /// Applies the fleet verifier's verdict: accepted loops wait for placement, refused or withdrawn
    /// ones leave the back-end.
    fn apply_fleet_verdict(&mut self, config: &ResolvedConfig, verdict: Verdict) -> Result<(), RuntimeError> {
        for id in verdict.accepted {
            self.fleet_loops.accepted(id);
        }
        let refused = verdict
            .retracted
            .into_iter()
            .chain(verdict.rejected.into_iter().map(|(id, _)| id));
        for id in refused {
            if let Some(id) = self.fleet_loops.refused(id) {
                self.backend_remove_loop(config, id)?;
            }
        }
        Ok(())
    }

    /// A fleet loop its finder retracted leaves the book and the back-end.
    pub(crate) fn retract_fleet_loop(
        &mut self,
        config: &ResolvedConfig,
        from: RobotId,
        pair: Pair,
    ) -> Result<(), RuntimeError> {
        match self.fleet_loops.retract(from, pair) {
            Some(id) => self.backend_remove_loop(config, id),
            None => Ok(()),
        }
    }

    /// The loops peers found that do not join this robot and are in its back-end
    /// (`loops.fleet_loops`).
    pub fn fleet_loops_in_graph(&self) -> Vec<LoopClosure> {
        self.fleet_loops.in_backend().cloned().collect()
    }

    /// Fleet loops held, and of them those in the back-end (for the run summary).
    pub(crate) fn fleet_loop_counts(&self) -> (usize, usize) {
        self.fleet_loops.counts()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use skid_core::KeyframeId;

    fn pair(a: u32, i: u32, b: u32, j: u32) -> Pair {
        let id = |robot, index| KeyframeId {
            robot: RobotId(robot),
            index,
        };
        (id(a, i), id(b, j))
    }

    #[test]
    fn a_loop_is_held_once_enters_when_accepted_and_only_its_finder_retracts_it() {
        let mut book = FleetLoopBook::default();
        let loop_12 = pair(1, 4, 2, 9);
        let (from, other) = (RobotId(1), RobotId(2));
        let received = book.receive(from, loop_12, Pose::identity(), Information::identity());
        assert_eq!(received, Received::New);
        let again = book.receive(from, loop_12, Pose::identity(), Information::identity());
        assert_eq!(again, Received::Known);
        assert!(book.waiting().is_empty(), "not judged yet");
        let submitted = book.take_awaiting_poses();
        assert_eq!(submitted.len(), 1);
        let id = submitted[0].id;
        assert!(id.0 >= FIRST_FLEET_LOOP_ID, "clear of the own loops' ids");
        assert!(book.take_awaiting_poses().is_empty(), "submitted once");
        book.accepted(id);
        assert_eq!(book.waiting().len(), 1);
        book.entered(loop_12);
        assert_eq!(book.counts(), (1, 1));
        assert!(book.waiting().is_empty());
        // Withdrawn by the verifier: out of the back-end, still held; accepted again, it waits again.
        assert_eq!(book.refused(id), Some(id));
        assert_eq!(book.counts(), (1, 0));
        book.accepted(id);
        book.entered(loop_12);
        assert_eq!(
            book.retract(other, loop_12),
            None,
            "only the finder retracts its loop"
        );
        assert_eq!(book.counts(), (1, 1));
        assert_eq!(book.retract(from, loop_12), Some(id));
        assert_eq!(book.counts(), (0, 0));
    }

    #[test]
    fn a_peer_holds_at_most_its_limit_of_loops() {
        let mut book = FleetLoopBook::default();
        for index in 0..MAX_FLEET_LOOPS_PER_PEER as u32 {
            let received = book.receive(
                RobotId(1),
                pair(1, index, 1, index + 100_000),
                Pose::identity(),
                Information::identity(),
            );
            assert_eq!(received, Received::New);
        }
        let over = pair(1, 0, 2, 0);
        let refused = book.receive(RobotId(1), over, Pose::identity(), Information::identity());
        assert_eq!(refused, Received::Full);
        let other_peer = book.receive(RobotId(2), over, Pose::identity(), Information::identity());
        assert_eq!(other_peer, Received::New, "the limit is per peer");
    }
}
