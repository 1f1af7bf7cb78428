//! Conversions between skid-core's graph types (keyframe ids, loops, 6×6 matrices) and the ABI's, for
//! the verifier and back-end wrappers.

use skid_core::slots::LoopClosure;
use skid_core::{Information, KeyframeId, LoopId, RobotId};

use crate::ffi::{AbiKeyframeId, AbiLoop};
use crate::transform::{abi_from_pose, pose_from_abi};

pub(super) fn abi_id(id: KeyframeId) -> AbiKeyframeId {
    AbiKeyframeId {
        robot: id.robot.0,
        index: id.index,
    }
}

pub(super) fn host_id(id: AbiKeyframeId) -> KeyframeId {
    KeyframeId {
        robot: RobotId(id.robot),
        index: id.index,
    }
}

pub(super) fn row_major(matrix: &Information) -> [f64; 36] {
    let mut out = [0.0; 36];
    for row in 0..6 {
        for column in 0..6 {
            out[row * 6 + column] = matrix[(row, column)];
        }
    }
    out
}

pub(super) fn abi_loop(closure: &LoopClosure) -> AbiLoop {
    AbiLoop {
        id: closure.id.0,
        target: abi_id(closure.target),
        source: abi_id(closure.source),
        target_from_source: abi_from_pose(&closure.target_from_source),
        information: row_major(&closure.information),
    }
}

/// A loop the plugin lent, as the host's closure; `Err` when its transform is not a rigid motion.
pub(super) fn loop_from_abi(lent: &AbiLoop) -> Result<LoopClosure, String> {
    Ok(LoopClosure {
        id: LoopId(lent.id),
        target: host_id(lent.target),
        source: host_id(lent.source),
        target_from_source: pose_from_abi(&lent.target_from_source)?,
        information: Information::from_row_slice(&lent.information),
    })
}
