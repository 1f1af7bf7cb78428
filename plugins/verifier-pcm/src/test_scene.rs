//! Fixtures the verifier's tests share: axis-aligned boxes that ray-cast scenes are built of, and a loop
//! closure with unit information.

use nalgebra::Vector3;
use skid_core::slots::LoopClosure;
use skid_core::{Information, KeyframeId, LoopId, Pose};

/// An axis-aligned box, `min` to `max`, metres in the scene's frame.
pub(crate) struct Block {
    pub min: Vector3<f64>,
    pub max: Vector3<f64>,
}

/// The distance along a unit ray from `origin` to a block, if it hits ahead.
pub(crate) fn hit(block: &Block, origin: &Vector3<f64>, direction: &Vector3<f64>) -> Option<f64> {
    let (mut near, mut far) = (0.0_f64, f64::INFINITY);
    for axis in 0..3 {
        if direction[axis].abs() < 1e-12 {
            if origin[axis] < block.min[axis] || origin[axis] > block.max[axis] {
                return None;
            }
            continue;
        }
        let a = (block.min[axis] - origin[axis]) / direction[axis];
        let b = (block.max[axis] - origin[axis]) / direction[axis];
        near = near.max(a.min(b));
        far = far.min(a.max(b));
    }
    (near <= far && near > 0.0).then_some(near)
}

/// Loop 1 between `target` and `source`, with unit information.
pub(crate) fn closure(target: KeyframeId, source: KeyframeId, target_from_source: Pose) -> LoopClosure {
    LoopClosure {
        id: LoopId(1),
        target,
        source,
        target_from_source,
        information: Information::identity(),
    }
}
