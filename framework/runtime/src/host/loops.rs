//! Loop candidates to verified loops: coarse registration (or the descriptor's yaw hint), fine
//! registration, verification, and the back-end updates the verdict calls for. Intra- and inter-robot
//! candidates take the same path (SKiD-SLAM, Sec. III): only where the target cloud came from differs.

use nalgebra::{UnitQuaternion, Vector3};
use skid_config::ResolvedConfig;
use skid_core::slots::{CoarseAlignment, LoopCandidate, LoopClosure, Verdict, Verifier};
use skid_core::{CloudView, KeyframeId, LoopId, PluginError, Pose, Slot};

use super::RobotHost;
use super::announced::Audience;
use super::loop_book::LoopEvent;
use super::peer_clouds::PendingCandidate;
use crate::error::RuntimeError;
use crate::graph::HostGraph;
use crate::settings::{backend_loop_information, loop_information};

/// True when the coarse registration's rival alignment holds at least `ratio` of the best one's inliers
/// (`ratio = 0` turns the test off).
fn ambiguous(alignment: &CoarseAlignment, ratio: f64) -> bool {
    ratio > 0.0
        && alignment.rival_inlier_count > 0
        && alignment.rival_inlier_count as f64 >= ratio * alignment.inlier_count as f64
}

impl RobotHost {
    /// Registers and verifies one candidate; accepted loops go to the back-end (and to the peer).
    pub(crate) fn process_candidate(
        &mut self,
        config: &ResolvedConfig,
        candidate: PendingCandidate,
        outbox: &mut Vec<skid_protocol::Message>,
    ) -> Result<(), RuntimeError> {
        let pair = (candidate.target, candidate.source);
        if self.loops.knows_pair(pair) {
            self.loops.count(LoopEvent::RepeatedPair);
            return Ok(());
        }
        let (Some(target_cloud), Some(source_cloud)) =
            (self.cloud_of(candidate.target), self.cloud_of(candidate.source))
        else {
            self.loops.count(LoopEvent::CloudMissing);
            return Ok(());
        };
        let prior = candidate.yaw_hint_rad.map(|yaw| {
            Pose::from_parts(
                Vector3::zeros().into(),
                UnitQuaternion::from_euler_angles(0.0, 0.0, yaw),
            )
        });
        let guess = match self.plugins.coarse.as_mut() {
            Some(coarse) => {
                let started = std::time::Instant::now();
                let result = coarse.align(target_cloud.view(), source_cloud.view(), prior.as_ref());
                self.add_stage_ms("coarse", started.elapsed().as_secs_f64() * 1e3);
                match result {
                    Ok(alignment) if ambiguous(&alignment, config.loops.ambiguous_rival_ratio) => {
                        self.loops.count(LoopEvent::CoarseAmbiguous);
                        tracing::debug!(robot = %self.robot, target = %candidate.target, source = %candidate.source, inliers = alignment.inlier_count, rival_inliers = alignment.rival_inlier_count, "loop candidate: refused, the place admits a rival alignment nearly as strong");
                        return Ok(());
                    }
                    Ok(alignment) if alignment.valid => alignment.target_from_source,
                    Ok(alignment) if config.loops.refine_invalid_coarse && self.plugins.fine.is_some() => {
                        // The verifier judges the refined loop; a wrong one fails its fitness or PCM.
                        self.loops.count(LoopEvent::CoarseInvalidRefined);
                        alignment.target_from_source
                    }
                    Ok(_) | Err(PluginError::InvalidInput(_)) => {
                        self.loops.count(LoopEvent::CoarseInvalid);
                        tracing::debug!(robot = %self.robot, target = %candidate.target, source = %candidate.source, "loop candidate: coarse registration found no valid alignment");
                        return Ok(());
                    }
                    Err(error) => return Err(self.plugin_error(config, Slot::Coarse, error)),
                }
            }
            None => prior.unwrap_or_else(Pose::identity),
        };
        let target_from_source = match self.plugins.fine.is_some() {
            true => {
                let target = self.prepared_cloud(config, candidate.target, &target_cloud)?;
                let source = self.prepared_cloud(config, candidate.source, &source_cloud)?;
                let started = std::time::Instant::now();
                let result = self
                    .plugins
                    .fine
                    .as_mut()
                    .map(|fine| fine.refine(&target, &source, &guess));
                self.add_stage_ms("fine", started.elapsed().as_secs_f64() * 1e3);
                match result {
                    Some(Ok(fine)) if fine.converged => fine.target_from_source,
                    Some(Ok(_)) | Some(Err(PluginError::InvalidInput(_))) => {
                        self.loops.count(LoopEvent::FineNotConverged);
                        tracing::debug!(robot = %self.robot, target = %candidate.target, source = %candidate.source, "loop candidate: fine registration did not converge");
                        return Ok(());
                    }
                    Some(Err(error)) => return Err(self.plugin_error(config, Slot::Fine, error)),
                    None => guess,
                }
            }
            false => guess,
        };
        let closure = self
            .loops
            .new_loop(pair, target_from_source, loop_information(&config.loops));
        tracing::debug!(robot = %self.robot, id = ?closure.id, target = %candidate.target, source = %candidate.source, translation_m = ?target_from_source.translation.vector.as_slice(), "loop candidate: registered");
        if !self.odometry_places(&closure) {
            // The peer's odometry for its keyframe has not arrived (lost on the link, or late): the
            // verifier cannot place the loop yet, so it waits, as a peer's loop does, and is judged with
            // its clouds once the odometry comes ([`Self::judge_when_placed`]).
            self.loops.submitted(closure.clone());
            return self.judge_when_placed(config, closure, outbox);
        }
        let verdict = self.judge(
            config,
            LoopCandidate {
                closure: closure.clone(),
                target_cloud: target_cloud.view(),
                source_cloud: source_cloud.view(),
            },
        )?;
        self.loops.submitted(closure);
        self.apply_verdict(config, verdict, outbox)
    }

    /// Whether the odometry known here places both keyframes of a loop.
    fn odometry_places(&self, closure: &LoopClosure) -> bool {
        self.chains.pose(closure.target).is_some() && self.chains.pose(closure.source).is_some()
    }

    /// Judges a submitted loop once the odometry known here places both its keyframes (until then it
    /// waits, outside the verifier): a peer's loop on its pose alone, one of this robot's own with its
    /// clouds when both are still held (on its pose alone otherwise).
    pub(crate) fn judge_when_placed(
        &mut self,
        config: &ResolvedConfig,
        closure: LoopClosure,
        outbox: &mut Vec<skid_protocol::Message>,
    ) -> Result<(), RuntimeError> {
        if !self.odometry_places(&closure) {
            tracing::debug!(robot = %self.robot, target = %closure.target, source = %closure.source, "loop waits for odometry");
            self.loops.await_poses(closure.id);
            return Ok(());
        }
        let clouds = match self.loops.is_from_peer(closure.id) {
            true => None,
            false => self.cloud_of(closure.target).zip(self.cloud_of(closure.source)),
        };
        let (target_cloud, source_cloud) = clouds.as_ref().map_or(
            (CloudView::default(), CloudView::default()),
            |(target, source)| (target.view(), source.view()),
        );
        let verdict = self.judge(
            config,
            LoopCandidate {
                closure,
                target_cloud,
                source_cloud,
            },
        )?;
        self.apply_verdict(config, verdict, outbox)
    }

    /// Submits a loop to the verifier (with its clouds, or none for a loop a peer found); without a
    /// verifier every loop is accepted.
    pub(crate) fn judge(
        &mut self,
        config: &ResolvedConfig,
        submitted: LoopCandidate<'_>,
    ) -> Result<Verdict, RuntimeError> {
        self.judge_by(config, false, submitted)
    }

    /// [`Self::judge`] by the verifier of the fleet's loops when `fleet` (`loops.fleet_loops`).
    pub(crate) fn judge_by(
        &mut self,
        config: &ResolvedConfig,
        fleet: bool,
        submitted: LoopCandidate<'_>,
    ) -> Result<Verdict, RuntimeError> {
        let asked = self.ask_verifier(config, fleet, |verifier, graph| {
            let started = std::time::Instant::now();
            (verifier.submit(&submitted, graph), started.elapsed())
        });
        let Some((verdict, took)) = asked else {
            return Ok(Verdict {
                accepted: vec![submitted.closure.id],
                ..Verdict::default()
            });
        };
        self.add_stage_ms("verifier", took.as_secs_f64() * 1e3);
        verdict.map_err(|error| self.plugin_error(config, Slot::Verifier, error))
    }

    /// The verifier's (the fleet's verifier's when `fleet`) re-judgement of the loops submitted so far
    /// against the graph as it is now; `None` without that verifier.
    pub(crate) fn reconsidered(
        &mut self,
        config: &ResolvedConfig,
        fleet: bool,
    ) -> Result<Option<Verdict>, RuntimeError> {
        match self.ask_verifier(config, fleet, |verifier, graph| verifier.reconsider(graph)) {
            Some(verdict) => verdict
                .map(Some)
                .map_err(|error| self.plugin_error(config, Slot::Verifier, error)),
            None => Ok(None),
        }
    }

    /// Adds a loop whose keyframes are both in the graph to the back-end.
    pub(crate) fn backend_add_loop(
        &mut self,
        config: &ResolvedConfig,
        mut closure: LoopClosure,
    ) -> Result<(), RuntimeError> {
        if let Some(information) = backend_loop_information(&config.loops) {
            closure.information = information;
        }
        let added = self
            .plugins
            .backend
            .as_mut()
            .map(|backend| backend.add_loop(closure));
        match added {
            Some(Err(error)) => Err(self.plugin_error(config, Slot::Backend, error)),
            _ => Ok(()),
        }
    }

    /// Removes a loop from the back-end.
    pub(crate) fn backend_remove_loop(
        &mut self,
        config: &ResolvedConfig,
        id: LoopId,
    ) -> Result<(), RuntimeError> {
        let removed = self
            .plugins
            .backend
            .as_mut()
            .map(|backend| backend.remove_loop(id));
        match removed {
            Some(Err(error)) => Err(self.plugin_error(config, Slot::Backend, error)),
            _ => Ok(()),
        }
    }

    /// Runs `ask` on the verifier (the fleet's verifier when `fleet`, `loops.fleet_loops`) with the graph
    /// as this robot sees it now (its frames through third robots refreshed first); `None` without that
    /// verifier.
    pub(crate) fn ask_verifier<R>(
        &mut self,
        config: &ResolvedConfig,
        fleet: bool,
        ask: impl FnOnce(&mut dyn Verifier, &HostGraph<'_>) -> R,
    ) -> Option<R> {
        self.refresh_frames();
        let limit = self.candidate_distance_limit(config);
        let me = self.robot;
        let verifier = match fleet {
            true => self.plugins.fleet_verifier.as_mut()?,
            false => self.plugins.verifier.as_mut()?,
        };
        let _span = tracing::debug_span!("verifier", robot = %me, fleet).entered();
        let book = &self.frames;
        let through = move |a, b| book.through_others(me, a, b);
        let graph = HostGraph {
            chains: &self.chains,
            backend: self.plugins.backend.as_ref().map(|backend| backend.graph()),
            loops: self.loops.accepted(),
            stamps: &self.keyframe_stamps,
            through_others: Some(&through),
            descriptors: self.index.as_deref().map(|index| (index, limit)),
        };
        Some(ask(verifier.as_mut(), &graph))
    }

    /// Applies a verdict: retracted loops leave the graph, accepted ones enter it, peers are told.
    pub(crate) fn apply_verdict(
        &mut self,
        config: &ResolvedConfig,
        verdict: Verdict,
        outbox: &mut Vec<skid_protocol::Message>,
    ) -> Result<(), RuntimeError> {
        if !(verdict.accepted.is_empty() && verdict.rejected.is_empty() && verdict.retracted.is_empty()) {
            tracing::debug!(
                robot = %self.robot,
                accepted = ?verdict.accepted,
                rejected = ?verdict.rejected,
                retracted = ?verdict.retracted,
                "verifier verdict"
            );
        }
        for (id, reason) in verdict.rejected {
            self.loops.rejected(id, reason);
        }
        let mut changed = false;
        let mut accepted_messages = Vec::new();
        let mut retracted_messages = Vec::new();
        // Only this robot's own loops are announced: a loop a peer found is the peer's to share. They
        // go to the one peer each joins, or under `fleet_loops` every own loop goes to every peer.
        let fleet = config.loops.fleet_loops;
        let announced =
            |closure: &LoopClosure, from_peer: bool| (fleet || closure.is_inter_robot()) && !from_peer;
        for id in verdict.retracted {
            if let Some(closure) = self.loops.retract(id) {
                self.backend_remove_loop(config, id)?;
                if announced(&closure, self.loops.is_from_peer(id)) {
                    retracted_messages.push(closure);
                }
                changed = true;
            }
        }
        for id in verdict.accepted {
            let Some(closure) = self.loops.take_for_acceptance(id) else {
                continue;
            };
            self.add_loop_to_backend(config, &closure)?;
            if announced(&closure, self.loops.is_from_peer(id)) {
                accepted_messages.push(closure.clone());
            }
            self.loops.accept(closure);
            changed = true;
        }
        if changed && fleet {
            // A peer joined by this verdict may place others through the fleet's loops.
            self.place_fleet_loops(config)?;
        }
        // One message per loop, so each goes to the one peer it concerns (or, under `fleet_loops`, to
        // every peer); the audience's whole set is stated again later, in case this one is lost.
        let now_nanos = self.now_nanos();
        let audience = |robot, pair| match fleet {
            true => Audience::Fleet,
            false => Audience::Peer(crate::messages::other_robot(robot, pair)),
        };
        for closure in &accepted_messages {
            outbox.push(crate::messages::loops_message(
                self.robot,
                std::slice::from_ref(closure),
                &[],
            ));
            let pair = (closure.target, closure.source);
            self.announced
                .accepted(audience(self.robot, pair), pair, now_nanos);
        }
        for closure in &retracted_messages {
            let pair = (closure.target, closure.source);
            outbox.push(crate::messages::loops_message(self.robot, &[], &[pair]));
            self.announced
                .retracted(audience(self.robot, pair), pair, now_nanos);
        }
        if changed {
            self.optimize(config)?;
            // A merge made or withdrawn moves this robot's frames: its peers hear it now, not at its
            // next keyframe, which may never come.
            outbox.extend(self.frames_message_if_due());
        }
        Ok(())
    }

    /// Adds a loop to the back-end, first bringing in the peer's odometry chain if the loop is the first
    /// one with that peer.
    pub(crate) fn add_loop_to_backend(
        &mut self,
        config: &ResolvedConfig,
        closure: &LoopClosure,
    ) -> Result<(), RuntimeError> {
        if self.plugins.backend.is_none() {
            return Ok(());
        }
        let (own, peer, own_from_peer) = if closure.target.robot == self.robot {
            (closure.target, closure.source, closure.target_from_source)
        } else {
            (
                closure.source,
                closure.target,
                closure.target_from_source.inverse(),
            )
        };
        if peer.robot != self.robot && !self.graph.has_peer(peer.robot) {
            self.add_peer_chain(config, own, peer, &own_from_peer)?;
        }
        if !self.graph.contains(closure.target) || !self.graph.contains(closure.source) {
            // A loop to a peer keyframe whose odometry has not arrived yet waits for it.
            self.graph.defer(closure.clone());
            return Ok(());
        }
        self.backend_add_loop(config, closure.clone())
    }

    /// Adds every known keyframe of `peer`'s robot to the back-end, placed through the first loop.
    fn add_peer_chain(
        &mut self,
        config: &ResolvedConfig,
        own: KeyframeId,
        peer: KeyframeId,
        own_from_peer: &Pose,
    ) -> Result<(), RuntimeError> {
        let Some(own_pose) = self.keyframe_pose(own.index) else {
            return Ok(());
        };
        self.place_peer_chain(config, own_pose, peer, own_from_peer)
    }

    /// Adds every known keyframe of `peer`'s robot to the back-end, placed so that its keyframe `peer`
    /// sits at `placed_pose * placed_from_peer` (the pose in this robot's graph of the loop's other
    /// keyframe, and the loop's measurement from it).
    pub(crate) fn place_peer_chain(
        &mut self,
        config: &ResolvedConfig,
        placed_pose: Pose,
        peer: KeyframeId,
        placed_from_peer: &Pose,
    ) -> Result<(), RuntimeError> {
        let Some(peer_odometry) = self.chains.pose(peer) else {
            return Ok(());
        };
        // world_self_from_world_peer: where the peer's odometry frame sits in this robot's frame.
        let frame = placed_pose * placed_from_peer * peer_odometry.inverse();
        self.graph.place_peer(peer.robot, frame);
        let chain = self.chains.chain(peer.robot);
        for (position, &(index, odometry)) in chain.iter().enumerate() {
            let previous = position.checked_sub(1).map(|p| chain[p]);
            self.add_peer_keyframe(
                config,
                KeyframeId {
                    robot: peer.robot,
                    index,
                },
                frame * odometry,
                previous.map(|(i, pose)| (i, pose, odometry)),
            )?;
        }
        Ok(())
    }

    /// Adds one peer keyframe (and its odometry edge from the previous one, when consecutive). Earlier
    /// keyframes that the odometry chain knows but the back-end does not (their own chain message was lost
    /// or overtaken) are added first, so the peer's keyframes stay joined.
    pub(crate) fn add_peer_keyframe(
        &mut self,
        config: &ResolvedConfig,
        id: KeyframeId,
        guess: Pose,
        previous: Option<(u32, Pose, Pose)>,
    ) -> Result<(), RuntimeError> {
        if self.plugins.backend.is_none() || self.graph.contains(id) {
            return Ok(());
        }
        let of_peer = |index| KeyframeId {
            robot: id.robot,
            index,
        };
        let mut missing = Vec::new();
        let mut index = id.index;
        while let Some(earlier) = index.checked_sub(1) {
            if self.graph.contains(of_peer(earlier)) {
                break;
            }
            let Some(pose) = self.chains.pose(of_peer(earlier)) else {
                break;
            };
            missing.push((earlier, pose));
            index = earlier;
        }
        let frame = self.graph.peer_frame(id.robot).unwrap_or_else(Pose::identity);
        for (earlier, pose) in missing.into_iter().rev() {
            let before = earlier
                .checked_sub(1)
                .and_then(|i| self.chains.pose(of_peer(i)).map(|p| (i, p, pose)));
            self.add_linked_peer_keyframe(config, of_peer(earlier), frame * pose, before)?;
        }
        self.add_linked_peer_keyframe(config, id, guess, previous)
    }

    /// Adds one peer keyframe, with the odometry edge from `previous` when that keyframe is the one just
    /// before and is in the back-end.
    fn add_linked_peer_keyframe(
        &mut self,
        config: &ResolvedConfig,
        id: KeyframeId,
        guess: Pose,
        previous: Option<(u32, Pose, Pose)>,
    ) -> Result<(), RuntimeError> {
        let robot = self.robot;
        let plugin = config.slot(Slot::Backend).plugin.clone();
        let error = |source| RuntimeError::Plugin {
            robot,
            slot: Slot::Backend,
            plugin: plugin.clone(),
            source,
        };
        if self.graph.contains(id) {
            return Ok(());
        }
        let previous = previous.filter(|(i, _, _)| {
            i + 1 == id.index
                && self.graph.contains(KeyframeId {
                    robot: id.robot,
                    index: *i,
                })
        });
        let Some(backend) = self.plugins.backend.as_mut() else {
            return Ok(());
        };
        backend.add_keyframe(id, guess).map_err(error)?;
        self.graph.insert(id);
        if let Some((previous_index, previous_pose, pose)) = previous {
            let step = previous_pose.inverse() * pose;
            let covariance = self
                .chains
                .step_covariance(id)
                .unwrap_or_else(|| crate::settings::odometry_step_covariance(&config.loops, &step));
            let measurement = skid_core::slots::OdometryMeasurement {
                target: KeyframeId {
                    robot: id.robot,
                    index: previous_index,
                },
                source: id,
                target_from_source: step,
                information: crate::settings::information_from_covariance(&covariance),
            };
            backend.add_odometry(measurement).map_err(error)?;
        }
        Ok(())
    }
}
