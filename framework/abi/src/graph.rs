//! Conversions between skid-core's graph types (keyframe ids, loops, priors, 6×6 matrices) and the ABI's
//! (feature `core`, on with `host`): the host's verifier and back-end wrappers use them, and so does a
//! Rust plugin that wraps a skid-core implementation (the example cdylib's PCM and pose graph).

use skid_core::slots::LoopClosure;
use skid_core::{Information, KeyframeId, LoopId, Pose, RobotId};

use crate::ffi::{AbiKeyframeId, AbiLoop, AbiPrior};
use crate::transform::{abi_from_pose, pose_from_abi};

pub fn abi_id(id: KeyframeId) -> AbiKeyframeId {
    AbiKeyframeId {
        robot: id.robot.0,
        index: id.index,
    }
}

pub fn host_id(id: AbiKeyframeId) -> KeyframeId {
    KeyframeId {
        robot: RobotId(id.robot),
        index: id.index,
    }
}

/// A 6×6 matrix as the ABI's row-major array.
pub fn row_major(matrix: &Information) -> [f64; 36] {
    let mut out = [0.0; 36];
    for row in 0..6 {
        for column in 0..6 {
            out[row * 6 + column] = matrix[(row, column)];
        }
    }
    out
}

/// skid-core's loop as the ABI's.
pub fn abi_loop(closure: &LoopClosure) -> AbiLoop {
    AbiLoop {
        id: closure.id.0,
        target: abi_id(closure.target),
        source: abi_id(closure.source),
        target_from_source: abi_from_pose(&closure.target_from_source),
        information: row_major(&closure.information),
    }
}

/// A loop lent across the boundary as skid-core's; `Err` when its transform is not a rigid motion.
pub fn loop_from_abi(lent: &AbiLoop) -> Result<LoopClosure, String> {
    Ok(LoopClosure {
        id: LoopId(lent.id),
        target: host_id(lent.target),
        source: host_id(lent.source),
        target_from_source: pose_from_abi(&lent.target_from_source)?,
        information: Information::from_row_slice(&lent.information),
    })
}

/// A prior lent across the boundary as skid-core's keyframe, pose and information; `Err` when its
/// transform is not a rigid motion.
pub fn prior_from_abi(lent: &AbiPrior) -> Result<(KeyframeId, Pose, Information), String> {
    Ok((
        host_id(lent.id),
        pose_from_abi(&lent.world_from_sensor)?,
        Information::from_row_slice(&lent.information),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_loop_and_a_prior_round_trip() {
        let lent = AbiLoop {
            id: 7,
            target: AbiKeyframeId { robot: 1, index: 4 },
            source: AbiKeyframeId { robot: 2, index: 9 },
            target_from_source: abi_from_pose(&Pose::translation(1.0, 2.0, 3.0)),
            information: [0.5; 36],
        };
        let back = abi_loop(&loop_from_abi(&lent).unwrap());
        assert_eq!((back.id, back.target, back.source), (7, lent.target, lent.source));
        assert_eq!(back.information, lent.information);
        assert_eq!(back.target_from_source, lent.target_from_source);
        let mut information = [0.0; 36];
        information[1] = 2.0;
        let prior = AbiPrior {
            id: AbiKeyframeId { robot: 3, index: 1 },
            world_from_sensor: abi_from_pose(&Pose::translation(-1.0, 0.0, 4.0)),
            information,
        };
        let (id, pose, matrix) = prior_from_abi(&prior).unwrap();
        assert_eq!(abi_id(id), prior.id);
        assert_eq!(abi_from_pose(&pose), prior.world_from_sensor);
        assert_eq!(matrix[(0, 1)], 2.0);
        assert_eq!(row_major(&matrix), information);
    }
}
