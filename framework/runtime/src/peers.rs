//! Acting on the messages a robot receives from its peers (odometry chains, descriptors, cloud requests
//! and replies, loops), and asking again for clouds that did not come.

use std::sync::Arc;

use skid_config::ResolvedConfig;
use skid_core::slots::{DescriptorBuf, LoopClosure};
use skid_core::{Cloud, Information, KeyframeId, LoopId, RobotId};
use skid_protocol::{CloudMsg, CompressedPoints, Loops, Message, OdomChain, PoseMsg};

use crate::error::RuntimeError;
use crate::host::{PendingCandidate, RobotHost};
use crate::messages::{CLOUD_RESOLUTION_M, cloud_request};

/// Most peer loops waiting for keyframes this robot does not have (yet); more are refused.
const MAX_DEFERRED_LOOPS: usize = 4096;

impl RobotHost {
    /// Cloud requests unanswered for `period_nanos` by this robot's clock, sent again: the request or the
    /// reply was lost, or the peer was away. Each retry doubles the wait (up to 16 periods), so replies
    /// queued on a slow link are not answered by ever more copies. Deterministic in scan time, so the
    /// executors still agree.
    pub fn due_cloud_requests(&mut self, period_nanos: u64) -> Vec<Message> {
        let now_nanos = self.now_nanos();
        let mut again = Vec::new();
        for (&id, state) in &mut self.requested {
            let wait_nanos = state.wait_nanos.max(period_nanos);
            if now_nanos.saturating_sub(state.sent_nanos) >= wait_nanos {
                state.sent_nanos = now_nanos;
                state.wait_nanos = (2 * wait_nanos).min(16 * period_nanos);
                again.push(cloud_request(self.robot, id));
            }
        }
        again
    }

    /// Acts on one message from a peer; messages that do not make sense are logged and dropped.
    pub fn handle_message(
        &mut self,
        config: &ResolvedConfig,
        from: RobotId,
        message: Message,
        replies: &mut Vec<(RobotId, Message)>,
        outbox: &mut Vec<Message>,
    ) -> Result<(), RuntimeError> {
        match message {
            Message::Hello(_) | Message::Heartbeat(_) => {}
            Message::Descriptors(batch) => {
                let own_kind = self.plugins.descriptor.as_ref().map(|d| d.kind().to_owned());
                let Some(own_kind) = own_kind else {
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
                let Some(index) = self.index.as_mut() else {
                    return Ok(());
                };
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
                    if let Err(error) = index.insert(
                        id,
                        DescriptorBuf {
                            kind: batch.kind.clone(),
                            values,
                        },
                    ) {
                        self.peer_faults.record(
                            self.robot,
                            from,
                            "descriptor_refused",
                            format_args!("{error}"),
                        );
                    }
                }
            }
            Message::CloudRequest(request) => {
                for id in request.keyframes.into_iter().filter(|id| id.robot == self.robot) {
                    let Some(keyframe) = self.keyframes.get(&id.index) else {
                        continue;
                    };
                    let Ok(points) =
                        CompressedPoints::encode(&keyframe.cloud.points, CLOUD_RESOLUTION_M, false)
                    else {
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
                if self.peer_clouds.contains_key(&cloud.keyframe) {
                    // The second answer to a request that was sent again.
                    return Ok(());
                }
                if !self.requested.contains_key(&cloud.keyframe) {
                    self.peer_faults.record(
                        self.robot,
                        from,
                        "cloud_unrequested",
                        format_args!("a cloud of keyframe {} that was not requested", cloud.keyframe),
                    );
                    return Ok(());
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
                self.peer_clouds
                    .insert(cloud.keyframe, Arc::new(Cloud::new(points)));
                self.requested.remove(&cloud.keyframe);
                let ready: Vec<PendingCandidate> = self
                    .pending
                    .iter()
                    .copied()
                    .filter(|p| p.target == cloud.keyframe)
                    .collect();
                self.pending.retain(|p| p.target != cloud.keyframe);
                for candidate in ready {
                    self.process_candidate(config, candidate, outbox)?;
                }
            }
            Message::OdomChain(chain) => self.on_chain(config, chain)?,
            Message::Loops(loops) => self.on_peer_loops(config, from, loops, outbox)?,
        }
        Ok(())
    }

    /// Extends a peer's odometry chain (and its copy in the back-end, once it is there).
    fn on_chain(&mut self, config: &ResolvedConfig, chain: OdomChain) -> Result<(), RuntimeError> {
        let Some(mut pose) = chain.world_from_first.to_pose() else {
            return Ok(());
        };
        let robot = chain.robot;
        let first = KeyframeId {
            robot,
            index: chain.from_index,
        };
        if !self.chains.contains(first) {
            self.chains.insert(first, pose, Information::identity() * 1e-6);
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
            let covariance = information
                .try_inverse()
                .unwrap_or_else(|| Information::identity() * 1e-4);
            let id = KeyframeId { robot, index };
            self.chains.insert(id, pose, covariance);
            if let Some(frame) = self.peer_frames.get(&robot).copied() {
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
        self.retry_deferred_loops(config)
    }

    /// Loops a peer accepted (or retracted) with this robot: both sides keep the same set.
    fn on_peer_loops(
        &mut self,
        config: &ResolvedConfig,
        from: RobotId,
        loops: Loops,
        outbox: &mut Vec<Message>,
    ) -> Result<(), RuntimeError> {
        let _ = outbox;
        for message in loops.accepted {
            let pair = (message.target, message.source);
            if self.loop_by_pair.contains_key(&pair) {
                continue;
            }
            if !self.is_shared_loop(from, pair) {
                continue;
            }
            let (Some(target_from_source), Some(information)) = (
                message.target_from_source.to_pose(),
                message.information.to_information(),
            ) else {
                continue;
            };
            let id = LoopId(self.next_loop_id);
            self.next_loop_id += 1;
            let closure = LoopClosure {
                id,
                target: message.target,
                source: message.source,
                target_from_source,
                information,
            };
            self.loop_by_pair.insert(pair, id);
            self.stats.received_from_peers += 1;
            self.add_loop_to_backend(config, &closure)?;
            self.loops.insert(id, closure);
        }
        for pair in loops.retracted {
            let Some(id) = self.loop_by_pair.get(&pair).copied() else {
                continue;
            };
            if self.loops.remove(&id).is_some() {
                if let Some(backend) = self.plugins.backend.as_mut() {
                    // The loop may still be deferred (never added); a refusal is harmless then.
                    let _ = backend.remove_loop(id);
                }
                self.stats.retracted += 1;
            }
        }
        self.optimize(config)
    }

    /// Whether a loop a peer sent joins the sender and this robot, at a keyframe this robot has; a loop
    /// between other robots, or naming a keyframe that does not exist here, is refused and counted.
    fn is_shared_loop(&mut self, from: RobotId, (target, source): (KeyframeId, KeyframeId)) -> bool {
        let robots = (target.robot, source.robot);
        if robots != (self.robot, from) && robots != (from, self.robot) {
            self.peer_faults.record(
                self.robot,
                from,
                "loop_not_shared",
                format_args!("a loop {target} ↔ {source} that is not between {from} and this robot"),
            );
            return false;
        }
        let own = if target.robot == self.robot {
            target
        } else {
            source
        };
        if !self.keyframes.contains_key(&own.index) {
            // A restarted robot hears its peers' loops before it has re-made its keyframes, so such a
            // loop waits (deferred, outside the graph) until the keyframe exists, up to a bound.
            if self.deferred_loops.len() >= MAX_DEFERRED_LOOPS {
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
        let Some(own) = self.scans.last().map(|scan| scan.stamp_nanos) else {
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

    /// Adds deferred loops whose keyframes are now all in the back-end.
    fn retry_deferred_loops(&mut self, config: &ResolvedConfig) -> Result<(), RuntimeError> {
        let deferred = std::mem::take(&mut self.deferred_loops);
        for closure in deferred {
            self.add_loop_to_backend(config, &closure)?;
        }
        Ok(())
    }
}
