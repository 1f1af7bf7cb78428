//! The robot's own step: one scan from the front-end (its own source and odometry, or a feed that runs
//! them elsewhere) becomes a scan record; a keyframe enters the odometry chain and the back-end, is
//! described, shared with the peers, and queried against the descriptor index for loop candidates.

use std::sync::Arc;
use std::time::Instant;

use skid_config::ResolvedConfig;
use skid_core::slots::{DescriptorBuf, OdometryMeasurement, OptimizeBudget};
use skid_core::{Keyframe, KeyframeId, PluginError, Pose, Slot};

use super::RobotHost;
use super::candidate_queue::QueuedCandidate;
use super::loop_book::LoopEvent;
use super::own_track::ScanRecord;
use super::peer_clouds::PendingCandidate;
use crate::error::RuntimeError;
use crate::frontend::{DetachedSource, FrontEnd, FrontEndError, FrontEndOutput, OdometryOutcome};
use crate::settings::{information_from_covariance, odometry_step_covariance};

impl RobotHost {
    /// Reads and processes one scan; false when the source has ended. Returns new descriptors to
    /// broadcast through `outbox`. The scan comes from the robot's feed when its front-end runs on a
    /// thread or in another process, else from its own source and odometry.
    pub fn step(
        &mut self,
        config: &ResolvedConfig,
        outbox: &mut Vec<skid_protocol::Message>,
    ) -> Result<bool, RuntimeError> {
        let output = match self.feed.as_mut() {
            Some(feed) => feed.next(),
            None => {
                let mut front_end = self.detach_front_end();
                let output = front_end.next_output();
                self.plugins.source = front_end.source;
                self.plugins.odometry = front_end.odometry;
                output
            }
        };
        match output {
            Ok(Some(output)) => {
                self.apply_front_end(config, output, outbox)?;
                Ok(true)
            }
            Ok(None) => Ok(false),
            Err(FrontEndError { slot, source }) => Err(self.plugin_error(config, slot, source)),
        }
    }

    /// Moves this robot's source and odometry onto a feed (a thread or a process) that runs ahead.
    pub fn detach_front_end(&mut self) -> FrontEnd {
        FrontEnd {
            source: std::mem::replace(&mut self.plugins.source, Box::new(DetachedSource)),
            odometry: self.plugins.odometry.take(),
        }
    }

    /// Records one scan's front-end output and, for a keyframe, runs the rest of the pipeline.
    pub fn apply_front_end(
        &mut self,
        config: &ResolvedConfig,
        output: FrontEndOutput,
        outbox: &mut Vec<skid_protocol::Message>,
    ) -> Result<(), RuntimeError> {
        self.own.count_read(output.points);
        self.add_stage_ms("source", output.source_ms);
        let (world_from_sensor, keyframe) = match output.odometry {
            None => (Pose::identity(), None),
            Some(OdometryOutcome::Skipped { reason }) => {
                // A scan the odometry cannot use is skipped with a warning; the run goes on.
                if let Some(count) = self.own.count_skipped() {
                    tracing::warn!(
                        robot = %self.robot,
                        sequence = output.sequence,
                        skipped_so_far = count,
                        %reason,
                        "scan skipped (repeats are logged at 10, 100, 1000, …; all are counted in summary.json)"
                    );
                }
                return Ok(());
            }
            Some(OdometryOutcome::Registered {
                world_from_sensor,
                keyframe,
                degenerate,
            }) => {
                self.add_stage_ms("odometry", output.odometry_ms);
                if degenerate {
                    self.own.count_degenerate();
                }
                (world_from_sensor, keyframe)
            }
        };
        let keyframe_index = keyframe
            .as_ref()
            .map(|k| k.id.index)
            .or_else(|| self.own.current_keyframe());
        self.own.push_scan(ScanRecord {
            stamp_nanos: output.stamp_nanos,
            world_from_sensor,
            keyframe: keyframe_index,
            ground_truth: output.ground_truth,
        });
        if let Some(keyframe) = keyframe {
            self.on_keyframe(config, keyframe, outbox)?;
        }
        Ok(())
    }

    /// Adds a keyframe to the chains and the back-end, describes it, shares it, and looks for loops.
    fn on_keyframe(
        &mut self,
        config: &ResolvedConfig,
        keyframe: Keyframe,
        outbox: &mut Vec<skid_protocol::Message>,
    ) -> Result<(), RuntimeError> {
        let id = keyframe.id;
        let previous = id
            .index
            .checked_sub(1)
            .and_then(|index| self.own.keyframe(index).map(|k| (index, k.world_from_sensor)));
        let step = previous.map_or(Pose::identity(), |(_, pose)| {
            pose.inverse() * keyframe.world_from_sensor
        });
        let step_covariance = odometry_step_covariance(&config.loops, &step);
        self.chains
            .insert(id, keyframe.world_from_sensor, step_covariance);
        self.keyframe_stamps.insert(id, keyframe.stamp_nanos);
        let keyframe = Arc::new(keyframe);
        self.own.push_keyframe(Arc::clone(&keyframe));
        outbox.extend(crate::messages::chain_message(&self.chains, self.robot, id.index));
        if let Some(frames) = self.frames_message_if_due() {
            outbox.push(frames);
        }

        if let Some(backend) = self.plugins.backend.as_mut() {
            let guess = match previous {
                Some((index, _)) => backend
                    .graph()
                    .pose(KeyframeId {
                        robot: self.robot,
                        index,
                    })
                    .map_or(keyframe.world_from_sensor, |p| p * step),
                None => keyframe.world_from_sensor,
            };
            let robot = self.robot;
            let backend_error = |source| RuntimeError::Plugin {
                robot,
                slot: Slot::Backend,
                plugin: config.slot(Slot::Backend).plugin.clone(),
                source,
            };
            backend.add_keyframe(id, guess).map_err(backend_error)?;
            self.graph.insert(id);
            if let Some((index, _)) = previous {
                let measurement = OdometryMeasurement {
                    target: KeyframeId { robot, index },
                    source: id,
                    target_from_source: step,
                    information: information_from_covariance(&step_covariance),
                };
                backend.add_odometry(measurement).map_err(backend_error)?;
            }
        }

        if self.plugins.descriptor.is_some() {
            let described = self.time("descriptor", |host| {
                host.plugins
                    .descriptor
                    .as_mut()
                    .map(|d| d.describe(keyframe.cloud.view()))
            });
            match described {
                Some(Ok(descriptor)) => self.on_descriptor(config, &keyframe, descriptor, outbox)?,
                Some(Err(PluginError::InvalidInput(reason))) => {
                    tracing::warn!(robot = %self.robot, keyframe = id.index, %reason, "keyframe not described");
                }
                Some(Err(error)) => return Err(self.plugin_error(config, Slot::Descriptor, error)),
                None => {}
            }
        }

        // The new keyframe can confirm or refute what the merges so far predicted.
        self.reconsider_loops(config, outbox)?;
        if self.graph.keyframe_added(config.loops.optimize_every_keyframes) {
            self.optimize(config)?;
        }
        Ok(())
    }

    /// Stores and shares a keyframe's descriptor, then queries the index for loop candidates.
    fn on_descriptor(
        &mut self,
        config: &ResolvedConfig,
        keyframe: &Keyframe,
        descriptor: DescriptorBuf,
        outbox: &mut Vec<skid_protocol::Message>,
    ) -> Result<(), RuntimeError> {
        let id = keyframe.id;
        self.own.push_descriptor(id.index, descriptor.clone());
        outbox.push(crate::messages::descriptor_message(
            self.robot,
            keyframe,
            &descriptor,
            &self.held_descriptors,
        ));
        let loops = &config.loops;
        let robot = self.robot;
        let threshold = self.candidate_distance_limit(config);
        let (own_loops, prior_due) = self.candidate_sources(config, id.index);
        let hinted = self.hinted_position(config, keyframe);
        let chains = &self.chains;
        let exclude = |candidate: KeyframeId| {
            if crate::prior::is_prior_robot(candidate.robot) {
                let beyond_hint = hinted.is_some_and(|(at, radius_m)| {
                    chains
                        .pose(candidate)
                        .is_none_or(|pose| (pose.translation.vector - at).norm() > radius_m)
                });
                !prior_due || beyond_hint
            } else if !own_loops {
                true
            } else if candidate.robot == robot {
                !loops.intra_robot || candidate.index + loops.exclude_recent_keyframes >= id.index
            } else {
                !loops.inter_robot
            }
        };
        let Some(index) = self.index.as_mut() else {
            return Ok(());
        };
        let started = Instant::now();
        let found = if own_loops || prior_due {
            index.query(&descriptor, loops.candidates, &exclude)
        } else {
            Ok(Vec::new())
        };
        index.insert(id, descriptor).map_err(|e| RuntimeError::Plugin {
            robot,
            slot: Slot::Descriptor,
            plugin: config.slot(Slot::Descriptor).plugin.clone(),
            source: e,
        })?;
        self.add_stage_ms("retrieval", started.elapsed().as_secs_f64() * 1e3);
        let found = found.map_err(|e| self.plugin_error(config, Slot::Descriptor, e))?;
        for candidate in found.into_iter().filter(|c| c.distance <= threshold) {
            let pending = PendingCandidate {
                target: candidate.id,
                source: id,
                yaw_hint_rad: candidate.yaw_hint_rad,
            };
            if candidate.id.robot == robot {
                self.loops.count(LoopEvent::IntraCandidate);
                self.process_candidate(config, pending, outbox)?;
            } else {
                self.loops.count(LoopEvent::InterCandidate);
                let queued = QueuedCandidate {
                    candidate: pending,
                    distance: candidate.distance,
                    raised_nanos: self.now_nanos(),
                };
                self.queue_candidate(config, queued);
            }
        }
        self.admit_candidates(config, outbox)
    }

    /// Optimises the back-end's graph, if there is one.
    pub fn optimize(&mut self, config: &ResolvedConfig) -> Result<(), RuntimeError> {
        self.graph.optimized();
        let budget = OptimizeBudget {
            max_iterations: config.loops.optimize_iterations,
            ..OptimizeBudget::default()
        };
        let result = self.time("backend", |host| {
            host.plugins
                .backend
                .as_mut()
                .map(|backend| backend.optimize(budget))
        });
        match result {
            Some(Err(error)) => Err(self.plugin_error(config, Slot::Backend, error)),
            _ => Ok(()),
        }
    }
}
