//! Benchmark-independent tests of the skid-eval metrics against numbers computed by hand (the
//! computation is written next to each expected value), following the definitions of the SKiD-SLAM
//! paper (Sec. "Evaluation Metrics") and evo.

mod alpha_beta;
mod associate;
mod others;
mod pr;
mod trajectory_errors;
mod umeyama;

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use skid_core::Pose;

/// A pose from a position and a rotation vector (axis · angle in radians).
pub fn pose(x: f64, y: f64, z: f64, rotation_vector: [f64; 3]) -> Pose {
    Isometry3::from_parts(
        Translation3::new(x, y, z),
        UnitQuaternion::from_scaled_axis(Vector3::from(rotation_vector)),
    )
}

/// Asserts `|a − b| ≤ tol` with a readable message.
#[track_caller]
pub fn close(a: f64, b: f64, tol: f64) {
    assert!((a - b).abs() <= tol, "{a} != {b} (tolerance {tol})");
}
