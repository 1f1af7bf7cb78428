//! The prior map as a silent peer of this robot (see `crate::prior`): its keyframes' descriptors in the
//! index, their clouds held, their poses as a chain the verifier and the back-end read like a peer's
//! odometry; and where the verifier's loops with it place this robot in the prior's map frame.

use skid_config::ResolvedConfig;
use skid_core::slots::DescriptorBuf;
use skid_core::{KeyframeId, Pose, RobotId, Slot};

use super::RobotHost;
use crate::error::RuntimeError;
use crate::prior::{PriorMap, is_prior_robot, prior_step_covariance};

/// Where a robot stands in the prior's map.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Localisation {
    /// The session robot that recorded most of the prior keyframes its loops join (or, placed through
    /// a fleet peer, the prior's first keyframe).
    pub session_robot: Option<u32>,
    /// The robot's map frame in the prior's map frame.
    pub prior_from_map: Pose,
    /// Loops with the prior the verifier accepted (0 when placed through a fleet peer).
    pub loops: usize,
    /// The fleet peer whose reported frames place this robot, when it holds no loop with the prior.
    pub via: Option<RobotId>,
}

impl RobotHost {
    /// Where a new keyframe `index` looks for candidates: with its own loops (within the robot and with
    /// the fleet: always without a prior, and with one when `[prior] own_loops`), and with the prior
    /// (at every keyframe until the robot is localised, then at every `track_every_keyframes`).
    pub(crate) fn candidate_sources(&self, config: &ResolvedConfig, index: u32) -> (bool, bool) {
        let own_loops = crate::prior::closes_own_loops(config);
        if config.prior.path.is_none() {
            return (own_loops, false);
        }
        let localised = self
            .loops
            .accepted()
            .values()
            .any(|closure| is_prior_robot(closure.target.robot) || is_prior_robot(closure.source.robot));
        let prior_due = !localised || index.is_multiple_of(config.prior.track_every_keyframes.max(1));
        (own_loops, prior_due)
    }

    /// Where the user's hint (`[prior] hints`) and the odometry put `keyframe` in the prior's map, with
    /// the radius candidates must fall within; `None` without a hint for this robot.
    pub(crate) fn hinted_position(
        &self,
        config: &ResolvedConfig,
        keyframe: &skid_core::Keyframe,
    ) -> Option<(nalgebra::Vector3<f64>, f64)> {
        let [x, y, z, yaw_deg] = *config.prior.hints.get(self.robot.0 as usize)?;
        let start = Pose::from_parts(
            nalgebra::Translation3::new(x, y, z),
            nalgebra::UnitQuaternion::from_euler_angles(0.0, 0.0, yaw_deg.to_radians()),
        );
        Some((
            (start * keyframe.world_from_sensor).translation.vector,
            config.prior.hint_radius_m,
        ))
    }

    /// Takes in the prior: descriptors into the index, clouds held, the prior's keyframes as a
    /// chain in the prior's map frame.
    pub fn take_prior(&mut self, prior: &PriorMap, descriptor_plugin: &str) -> Result<(), RuntimeError> {
        let robot = self.robot;
        self.prior_session_robots = prior.keyframes.iter().map(|k| k.session_robot).collect();
        for keyframe in &prior.keyframes {
            let id = keyframe.id;
            let previous = id.index.checked_sub(1).map(|index| KeyframeId {
                robot: id.robot,
                index,
            });
            match previous.filter(|&p| self.chains.contains(p)) {
                Some(_) => self
                    .chains
                    .insert(id, keyframe.session_from_sensor, prior_step_covariance()),
                None => self.chains.insert_without_step(id, keyframe.session_from_sensor),
            }
            self.peer_clouds.hold(id, keyframe.cloud.clone());
            if let Some(index) = self.index.as_mut() {
                let descriptor = DescriptorBuf {
                    kind: prior.descriptor_kind.clone(),
                    values: keyframe.descriptor.clone(),
                };
                index
                    .insert(id, descriptor)
                    .map_err(|source| RuntimeError::Plugin {
                        robot,
                        slot: Slot::Descriptor,
                        plugin: descriptor_plugin.to_string(),
                        source,
                    })?;
            }
        }
        Ok(())
    }

    /// Where the verifier's accepted loops with the prior place this robot's map frame in the prior's
    /// map frame: the median of the placements its loops imply (each loop: the prior keyframe's pose,
    /// the loop, this robot's optimised keyframe pose). Without such loops, a robot is placed through a
    /// fleet peer that reports the prior's frame (the fleet's frame bookkeeping: chains of reported
    /// frames, checked against each other). `None` until either stands.
    pub fn localisation(&self) -> Option<Localisation> {
        self.localisation_by_loops()
            .or_else(|| self.localisation_through_peers())
    }

    /// The placement through a fleet peer, from the frame book's chains of reported frames.
    fn localisation_through_peers(&self) -> Option<Localisation> {
        let joined = self.joined_frames();
        let (&through, frame) = joined
            .iter()
            .find(|(robot, frame)| is_prior_robot(**robot) && frame.via.is_some())?;
        let prior_first = self.chains.pose(KeyframeId {
            robot: through,
            index: 0,
        })?;
        let own_first = self.keyframe_pose(0)?;
        Some(Localisation {
            session_robot: self.prior_session_robots.first().copied(),
            prior_from_map: prior_first * frame.own_first_from_robot_first.inverse() * own_first.inverse(),
            loops: 0,
            via: frame.via,
        })
    }

    /// The placement by this robot's own accepted loops with the prior: the medoid of the placements
    /// they imply (each loop: the prior keyframe's pose, the loop, this robot's optimised keyframe pose).
    fn localisation_by_loops(&self) -> Option<Localisation> {
        let mut placements = Vec::new();
        let mut session_robots: std::collections::BTreeMap<u32, usize> = std::collections::BTreeMap::new();
        for closure in self.loops.accepted().values() {
            let (own, prior, own_from_prior) = match (closure.target.robot, closure.source.robot) {
                (t, s) if t == self.robot && is_prior_robot(s) => {
                    (closure.target, closure.source, closure.target_from_source)
                }
                (t, s) if s == self.robot && is_prior_robot(t) => (
                    closure.source,
                    closure.target,
                    closure.target_from_source.inverse(),
                ),
                _ => continue,
            };
            let (Some(prior_pose), Some(own_pose)) = (self.chains.pose(prior), self.keyframe_pose(own.index))
            else {
                continue;
            };
            placements.push(prior_pose * own_from_prior.inverse() * own_pose.inverse());
            if let Some(&session_robot) = self.prior_session_robots.get(prior.index as usize) {
                *session_robots.entry(session_robot).or_default() += 1;
            }
        }
        Some(Localisation {
            session_robot: session_robots
                .into_iter()
                .max_by_key(|&(robot, loops)| (loops, std::cmp::Reverse(robot)))
                .map(|(robot, _)| robot),
            prior_from_map: median_pose(&placements)?,
            loops: placements.len(),
            via: None,
        })
    }
}

/// The placement whose summed distance to the others (metres, plus radians as metres at 10 m) is least:
/// a medoid, which one stray placement cannot drag.
fn median_pose(placements: &[Pose]) -> Option<Pose> {
    let cost = |a: &Pose| -> f64 {
        placements
            .iter()
            .map(|b| {
                let delta = a.inverse() * b;
                delta.translation.vector.norm() + 10.0 * delta.rotation.angle()
            })
            .sum()
    };
    placements
        .iter()
        .map(|p| (cost(p), *p))
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, pose)| pose)
}
