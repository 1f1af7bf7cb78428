//! Acting on the messages a robot receives from its peers (odometry chains, descriptors, cloud requests
//! and replies, loops).

use skid_config::ResolvedConfig;
use skid_core::slots::DescriptorBuf;
use skid_core::{Cloud, Information, KeyframeId, RobotId};
use skid_protocol::{CloudMsg, CompressedPoints, Loops, Message, OdomChain, PoseMsg};

use super::RobotHost;
use super::peer_clouds::CloudRefusal;
use crate::error::RuntimeError;

/// Most peer loops waiting for keyframes this robot does not have (yet); more are refused.
const MAX_DEFERRED_LOOPS: usize = 4096;

impl RobotHost {
    /// Acts on one message from a peer; messages that do not make sense are logged and dropped.
    pub fn handle_message(
        &mut self,
        config: &ResolvedConfig,
        from: RobotId,
        message: Message,
        replies: &mut Vec<(RobotId, Message)>,
        outbox: &mut Vec<Message>,
    ) -> Result<(), RuntimeError> {
        // One reading of the clock serves the whole message: when the peer was last heard, and when a
        // cloud it asks for was served.
        let now_nanos = self.now_nanos();
        self.heard_nanos.insert(from, now_nanos);
        match message {
            Message::Hello(_) | Message::Heartbeat(_) => {}
            Message::Descriptors(batch) => {
                let Some(own_kind) = self.descriptor_kind() else {
                    return Ok(());
                };
                if let Some(stamp) = batch.entries.first().map(|entry| entry.stamp_nanos) {
                    self.check_peer_clock(from, stamp);
                }
                if own_kind != batch.kind {
                    self.peer_faults.record(
                        self.robot,
                        from,
                        "descriptor_wrong_kind",
                        format_args!(
                            "descriptors of kind {:?}, this robot matches {own_kind:?}",
                            batch.kind
                        ),
                    );
                    return Ok(());
                }
                if self.index.is_none() {
                    return Ok(());
                }
                for entry in batch.entries {
                    let Ok(values) = entry.values.decode() else {
                        self.peer_faults.record(
                            self.robot,
                            from,
                            "descriptor_undecodable",
                            "descriptor values do not decode",
                        );
                        continue;
                    };
                    let id = KeyframeId {
                        robot: batch.robot,
                        index: entry.keyframe_index,
                    };
                    let descriptor = DescriptorBuf {
                        kind: batch.kind.clone(),
                        values,
                    };
                    let Some(index) = self.index.as_mut() else {
                        return Ok(());
                    };
                    // The index checks the descriptor (its length, a keyframe it holds already) before
                    // anything is looked up with it.
                    if let Err(error) = index.insert(id, descriptor.clone()) {
                        self.peer_faults.record(
                            self.robot,
                            from,
                            "descriptor_refused",
                            format_args!("{error}"),
                        );
                        continue;
                    }
                    // Only a descriptor the index took vouches for its keyframe's stamp.
                    self.keyframe_stamps.insert(id, entry.stamp_nanos);
                    let newest = self.held_descriptors.entry(id.robot).or_insert(id.index);
                    *newest = (*newest).max(id.index);
                    let newest_held = entry.held_of(self.robot);
                    self.query_arrived_descriptor(config, id, &descriptor, newest_held)?;
                }
                self.admit_candidates(config, outbox)?;
            }
            Message::CloudRequest(request) => {
                let resend_after_nanos = crate::clock::nanos_from_s(config.loops.cloud_resend_after_s);
                let grid_m = config.loops.cloud_grid_m as f32;
                for id in request.keyframes.into_iter().filter(|id| id.robot == self.robot) {
                    let Some(keyframe) = self.own.keyframe(id.index) else {
                        continue;
                    };
                    if !self
                        .served
                        .should_send(request.requester, id, now_nanos, resend_after_nanos)
                    {
                        continue;
                    }
                    let Ok(points) = CompressedPoints::encode(&keyframe.cloud.points, grid_m, false) else {
                        continue;
                    };
                    replies.push((
                        request.requester,
                        Message::Cloud(CloudMsg {
                            keyframe: id,
                            stamp_nanos: keyframe.stamp_nanos,
                            world_from_sensor: PoseMsg::from_pose(&keyframe.world_from_sensor),
                            points,
                        }),
                    ));
                }
            }
            Message::Cloud(cloud) => {
                match self.peer_clouds.check_wanted(cloud.keyframe) {
                    Ok(()) => {}
                    // The second answer to a request that was sent again.
                    Err(CloudRefusal::AlreadyHeld) => return Ok(()),
                    Err(CloudRefusal::Unrequested) => {
                        self.peer_faults.record(
                            self.robot,
                            from,
                            "cloud_unrequested",
                            format_args!("a cloud of keyframe {} that was not requested", cloud.keyframe),
                        );
                        return Ok(());
                    }
                }
                let Ok(points) = cloud.points.decode() else {
                    self.peer_faults.record(
                        self.robot,
                        from,
                        "cloud_undecodable",
                        format_args!("the cloud of keyframe {} does not decode", cloud.keyframe),
                    );
                    return Ok(());
                };
                let ready = self.peer_clouds.receive(cloud.keyframe, Cloud::new(points));
                for candidate in ready {
                    self.process_candidate(config, candidate, outbox)?;
                }
            }
            Message::OdomChain(chain) => self.on_chain(config, chain, outbox)?,
            Message::Loops(loops) => self.on_peer_loops(config, from, loops, outbox)?,
            Message::Frames(frames) => self.on_frames(config, from, frames, outbox)?,
        }
        Ok(())
    }

    /// Extends a peer's odometry chain (and its copy in the back-end, once it is there).
    fn on_chain(
        &mut self,
        config: &ResolvedConfig,
        chain: OdomChain,
        outbox: &mut Vec<Message>,
    ) -> Result<(), RuntimeError> {
        let Some(mut pose) = chain.world_from_first.to_pose() else {
            return Ok(());
        };
        let robot = chain.robot;
        let first = KeyframeId {
            robot,
            index: chain.from_index,
        };
        if !self.chains.contains(first) {
            self.chains.insert_without_step(first, pose);
        }
        for (offset, edge) in chain.edges.iter().enumerate() {
            let (Some(step), Some(information)) = (
                edge.target_from_source.to_pose(),
                edge.information.to_information(),
            ) else {
                return Ok(());
            };
            let index = chain.from_index + offset as u32 + 1;
            let previous = pose;
            pose *= step;
            // Chains overlap (each repeats the steps before its newest): a step held already is skipped.
            if self.chains.has_step(KeyframeId { robot, index }) {
                continue;
            }
            let covariance = information
                .try_inverse()
                .unwrap_or_else(|| Information::identity() * 1e-4);
            let id = KeyframeId { robot, index };
            self.chains.insert(id, pose, covariance);
            if let Some(frame) = self.graph.peer_frame(robot) {
                let guess = self
                    .plugins
                    .backend
                    .as_ref()
                    .and_then(|b| {
                        b.graph().pose(KeyframeId {
                            robot,
                            index: index - 1,
                        })
                    })
                    .map_or(frame * pose, |p| p * step);
                self.add_peer_keyframe(config, id, guess, Some((index - 1, previous, pose)))?;
            }
        }
        self.retry_deferred_loops(config, outbox)
    }

    /// Loops a peer accepted (or retracted) with this robot. An accepted one goes through this robot's
    /// own verifier, pooled with the loops it found itself between the two robots (without clouds: the
    /// peer checked the fit), so a peer's word alone never moves this robot's map; a retracted one
    /// leaves.
    fn on_peer_loops(
        &mut self,
        config: &ResolvedConfig,
        from: RobotId,
        loops: Loops,
        outbox: &mut Vec<Message>,
    ) -> Result<(), RuntimeError> {
        for message in loops.accepted {
            let pair = (message.target, message.source);
            if self.loops.knows_pair(pair) {
                continue;
            }
            let (Some(target_from_source), Some(information)) = (
                message.target_from_source.to_pose(),
                message.information.to_information(),
            ) else {
                continue;
            };
            if !self.joins_sender_and_me(from, pair) {
                self.receive_fleet_loop(config, from, pair, target_from_source, information);
                continue;
            }
            if !self.is_shared_loop(from, pair) {
                continue;
            }
            let closure = self.loops.new_loop(pair, target_from_source, information);
            self.loops.received(closure.clone());
            self.judge_when_placed(config, closure, outbox)?;
        }
        for pair in loops.retracted {
            if !self.joins_sender_and_me(from, pair) {
                self.retract_fleet_loop(config, from, pair)?;
                continue;
            }
            if let Some(id) = self.loops.retract_from_peer(pair)
                && let Some(backend) = self.plugins.backend.as_mut()
            {
                // The loop may still be deferred (never added); a refusal is harmless then.
                let _ = backend.remove_loop(id);
            }
        }
        if config.loops.fleet_loops {
            self.judge_fleet_loops(config)?;
        }
        self.optimize(config)?;
        outbox.extend(self.frames_message_if_due());
        Ok(())
    }

    /// Whether the loop between `target` and `source` joins `from` and this robot.
    fn joins_sender_and_me(&self, from: RobotId, (target, source): (KeyframeId, KeyframeId)) -> bool {
        let robots = (target.robot, source.robot);
        robots == (self.robot, from) || robots == (from, self.robot)
    }

    /// Whether a loop a peer sent (one joining the sender and this robot) names a keyframe this robot
    /// has, or may wait for it; past the bound of waiting loops it is refused and counted.
    fn is_shared_loop(&mut self, from: RobotId, (target, source): (KeyframeId, KeyframeId)) -> bool {
        let own = if target.robot == self.robot {
            target
        } else {
            source
        };
        if self.own.keyframe(own.index).is_none() {
            // A restarted robot hears its peers' loops before it has re-made its keyframes, so such a
            // loop waits (deferred, outside the graph) until the keyframe exists, up to a bound.
            if self.graph.deferred_count() + self.loops.awaiting_poses_count() >= MAX_DEFERRED_LOOPS {
                self.peer_faults.record(
                    self.robot,
                    from,
                    "loop_backlog_full",
                    format_args!(
                        "{MAX_DEFERRED_LOOPS} loops already wait for keyframes; loop at {own} refused"
                    ),
                );
                return false;
            }
            self.peer_faults.record(
                self.robot,
                from,
                "loop_unknown_keyframe",
                format_args!("a loop at keyframe {own}, which this robot does not have (yet): it waits outside the graph"),
            );
        }
        true
    }

    /// Warns (once per class limit) when a peer's stamp is far from this robot's newest scan stamp: its
    /// clock is probably off. The stamps are only labels here, so nothing else changes.
    fn check_peer_clock(&mut self, from: RobotId, stamp_nanos: u64) {
        let Some(own) = self.own.newest_stamp_nanos() else {
            return;
        };
        let offset_nanos = own.abs_diff(stamp_nanos);
        if offset_nanos > crate::peer_faults::CLOCK_OFFSET_WARNING_NANOS {
            self.peer_faults.record(
                self.robot,
                from,
                "clock_offset",
                format_args!(
                    "its stamps are {:.0} s from this robot's: is its clock set?",
                    offset_nanos as f64 * 1e-9
                ),
            );
        }
    }

    /// Adds deferred loops whose keyframes are now all in the back-end, and judges the peer loops
    /// whose keyframes the odometry now places.
    fn retry_deferred_loops(
        &mut self,
        config: &ResolvedConfig,
        outbox: &mut Vec<Message>,
    ) -> Result<(), RuntimeError> {
        let deferred = self.graph.take_deferred();
        for closure in deferred {
            self.add_loop_to_backend(config, &closure)?;
        }
        for closure in self.loops.take_awaiting_poses() {
            self.judge_when_placed(config, closure, outbox)?;
        }
        if config.loops.fleet_loops {
            self.judge_fleet_loops(config)?;
        }
        Ok(())
    }
}
