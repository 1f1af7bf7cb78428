//! A prior map (`[prior]`): a session an earlier run left, in which this run's robots place themselves.
//!
//! The prior acts as a silent peer, as relocalisation is the inter-robot loop problem with a peer that
//! does not move: the keyframes of every robot of the session that was placed in the session's map
//! frame become one peer robot, [`PRIOR_ROBOT_BASE`], whose keyframes are numbered on from one session
//! robot to the next, whose descriptors sit in every host's index, whose keyframe clouds the hosts
//! hold, and whose "odometry chain" is its keyframes' poses in the session's map frame with a tight
//! step covariance (the step from one session robot's last keyframe to the next one's first included:
//! the session placed them in one frame). One peer, not one per session robot, so that loops with
//! places different session robots mapped are judged together, as the one map they are. Candidates
//! between a robot and the prior go through the same coarse and fine registration and the same
//! verifier (its earned-merge rules included) as loops between robots; the robot is localised once
//! the verifier grants a set of loops with the prior, and placed by them. Nothing is ever sent to the
//! prior. The session's descriptor must be the run's, parameters and all: descriptors of another kind
//! or resolution cannot be compared.

use std::path::Path;
use std::sync::Arc;

use skid_config::{PriorMode, ResolvedConfig};
use skid_core::{Cloud, Information, KeyframeId, Pose, RobotId, Slot};

use crate::error::RuntimeError;

/// The robot id the prior's keyframes take (a fleet has at most 16 robots; ids from this one up are
/// never a fleet robot's).
pub const PRIOR_ROBOT_BASE: u32 = 1000;

/// Whether `robot` is the prior peer (or any id at or above its, which no fleet robot takes).
pub fn is_prior_robot(robot: RobotId) -> bool {
    robot.0 >= PRIOR_ROBOT_BASE
}

/// Whether robots close loops within themselves and with the fleet: always without a prior, and with
/// one when `[prior] own_loops` asks for full SLAM beside the localisation or `mode = "extend"` grows
/// the prior by the run's own map.
pub(crate) fn closes_own_loops(config: &ResolvedConfig) -> bool {
    config.prior.path.is_none() || config.prior.own_loops || config.prior.mode == PriorMode::Extend
}

/// The descriptor plugin's complete parameters as a session stores them (and as a prior's are compared
/// with the run's).
pub(crate) fn descriptor_params(config: &ResolvedConfig) -> Result<serde_json::Value, serde_json::Error> {
    serde_json::to_value(config.slot(Slot::Descriptor).params.table())
}

/// The step covariance of the prior peer's chain: the session's poses are an optimised map, held to
/// 2 cm and 0.1° between consecutive keyframes.
pub(crate) fn prior_step_covariance() -> Information {
    let mut covariance = Information::identity();
    for axis in 0..3 {
        covariance[(axis, axis)] = 0.02_f64.powi(2);
        covariance[(axis + 3, axis + 3)] = 0.1_f64.to_radians().powi(2);
    }
    covariance
}

/// One keyframe of the prior.
pub struct PriorKeyframe {
    /// Its id as the prior peer's keyframe (robot [`PRIOR_ROBOT_BASE`], index = its place in
    /// [`PriorMap::keyframes`]).
    pub id: KeyframeId,
    /// The session robot that recorded it, and its index there.
    pub session_robot: u32,
    pub session_index: u32,
    /// Its pose in the session's map frame.
    pub session_from_sensor: Pose,
    pub descriptor: Vec<f32>,
    pub cloud: Arc<Cloud>,
    /// Its true pose, when the session knows it.
    pub ground_truth: Option<Pose>,
}

/// The prior as every host of the run shares it.
pub struct PriorMap {
    pub descriptor_kind: String,
    /// Keyframes of every placed session robot, by robot then index.
    pub keyframes: Vec<PriorKeyframe>,
}

fn prior_error(dir: &Path, message: impl ToString) -> RuntimeError {
    RuntimeError::Prior {
        path: dir.to_path_buf(),
        message: message.to_string(),
    }
}

/// Reads the prior `[prior] path` names, or `None` when there is none. The session's descriptor must be
/// the one the run describes its keyframes with, parameters included.
pub fn load_prior(config: &ResolvedConfig) -> Result<Option<Arc<PriorMap>>, RuntimeError> {
    let Some(path) = &config.prior.path else {
        return Ok(None);
    };
    let dir = skid_session::session_folder(path);
    let session = skid_session::read_session(&dir).map_err(|e| prior_error(&dir, e))?;
    let slot = config.slot(Slot::Descriptor);
    let Some(spec) = &session.descriptor else {
        return Err(prior_error(
            &dir,
            "the session's keyframes were not described: it cannot be localised in",
        ));
    };
    if spec.kind != slot.plugin {
        return Err(prior_error(
            &dir,
            format!(
                "the session was described with `{}`, this run describes with `{}` (descriptor.plugin)",
                spec.kind, slot.plugin
            ),
        ));
    }
    let params = descriptor_params(config).map_err(|e| prior_error(&dir, e))?;
    if let (Some(run), Some(saved)) = (params.as_object(), spec.params.as_object()) {
        for (key, value) in run {
            if saved.get(key) != Some(value) {
                return Err(prior_error(
                    &dir,
                    format!(
                        "descriptor.{}.{key} is {value} in this run but {} in the session: descriptors made differently cannot be compared",
                        slot.plugin,
                        saved.get(key).map_or("absent".to_string(), ToString::to_string)
                    ),
                ));
            }
        }
    }
    let mut keyframes = Vec::new();
    for robot in &session.robots {
        let Some(frame) = robot.map_from_robot else {
            tracing::warn!(session = %dir.display(), robot = robot.robot, "the prior's robot was never placed in its map frame; left out");
            continue;
        };
        for keyframe in &robot.keyframes {
            let Some(descriptor) = &keyframe.descriptor else {
                continue;
            };
            let points =
                skid_session::read_keyframe_cloud(&dir, robot, keyframe).map_err(|e| prior_error(&dir, e))?;
            let running = u32::try_from(keyframes.len())
                .map_err(|_| prior_error(&dir, "more keyframes than a robot can number"))?;
            keyframes.push(PriorKeyframe {
                id: KeyframeId::new(PRIOR_ROBOT_BASE, running),
                session_robot: robot.robot,
                session_index: keyframe.index,
                session_from_sensor: frame * keyframe.map_from_sensor,
                descriptor: descriptor.clone(),
                cloud: Arc::new(Cloud::new(points)),
                ground_truth: keyframe.ground_truth,
            });
        }
    }
    if keyframes.is_empty() {
        return Err(prior_error(
            &dir,
            "the session holds no placed, described keyframe",
        ));
    }
    tracing::info!(session = %dir.display(), keyframes = keyframes.len(), "prior map loaded");
    Ok(Some(Arc::new(PriorMap {
        descriptor_kind: spec.kind.clone(),
        keyframes,
    })))
}
