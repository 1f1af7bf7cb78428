//! Conversions between the ABI's graph values and skid-core's, for the wrapped built-in verifier and
//! back-end.

use skid_abi::ffi::{AbiKeyframeId, AbiLoop};
use skid_abi::transform::{abi_from_pose, pose_from_abi};
use skid_core::slots::LoopClosure;
use skid_core::{Information, KeyframeId, LoopId, RobotId};

pub(crate) fn host_id(id: AbiKeyframeId) -> KeyframeId {
    KeyframeId {
        robot: RobotId(id.robot),
        index: id.index,
    }
}

pub(crate) fn abi_id(id: KeyframeId) -> AbiKeyframeId {
    AbiKeyframeId {
        robot: id.robot.0,
        index: id.index,
    }
}

/// A 6×6 matrix as the ABI's row-major array.
pub(crate) fn row_major(matrix: &Information) -> [f64; 36] {
    let mut out = [0.0; 36];
    for row in 0..6 {
        for column in 0..6 {
            out[row * 6 + column] = matrix[(row, column)];
        }
    }
    out
}

/// A lent loop as skid-core's; `Err` when its transform is not a rigid motion.
pub(crate) fn closure(lent: &AbiLoop) -> Result<LoopClosure, String> {
    Ok(LoopClosure {
        id: LoopId(lent.id),
        target: host_id(lent.target),
        source: host_id(lent.source),
        target_from_source: pose_from_abi(&lent.target_from_source)?,
        information: Information::from_row_slice(&lent.information),
    })
}

/// skid-core's loop as the ABI's.
pub(crate) fn abi_loop(closure: &LoopClosure) -> AbiLoop {
    AbiLoop {
        id: closure.id.0,
        target: abi_id(closure.target),
        source: abi_id(closure.source),
        target_from_source: abi_from_pose(&closure.target_from_source),
        information: row_major(&closure.information),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use skid_core::Pose;

    #[test]
    fn a_loop_round_trips() {
        let lent = AbiLoop {
            id: 7,
            target: AbiKeyframeId { robot: 1, index: 4 },
            source: AbiKeyframeId { robot: 2, index: 9 },
            target_from_source: abi_from_pose(&Pose::translation(1.0, 2.0, 3.0)),
            information: [0.5; 36],
        };
        let back = abi_loop(&closure(&lent).unwrap());
        assert_eq!((back.id, back.target, back.source), (7, lent.target, lent.source));
        assert_eq!(back.information, lent.information);
        assert_eq!(back.target_from_source, lent.target_from_source);
    }
}
