//! Values the runtime derives from the `[loops]` section: odometry-edge uncertainty and the fixed loop
//! information.

use skid_config::LoopsSection;
use skid_core::{Information, Pose};

/// The covariance of an odometry step of the given motion: translation σ grows with distance travelled
/// (with a floor), rotation σ is constant per keyframe.
pub fn odometry_step_covariance(loops: &LoopsSection, step: &Pose) -> Information {
    let distance_m = step.translation.vector.norm();
    let sigma_m = (loops.odometry_sigma_per_m * distance_m)
        .max(loops.odometry_sigma_min_m)
        .max(1e-6);
    let sigma_rad = loops.odometry_sigma_rotation_deg.to_radians().max(1e-6);
    let mut covariance = Information::zeros();
    for axis in 0..3 {
        covariance[(axis, axis)] = sigma_m * sigma_m;
        covariance[(axis + 3, axis + 3)] = sigma_rad * sigma_rad;
    }
    covariance
}

/// Inverts a covariance to an information matrix, falling back to the diagonal inverse.
pub fn information_from_covariance(covariance: &Information) -> Information {
    covariance.try_inverse().unwrap_or_else(|| {
        Information::from_diagonal(&covariance.diagonal().map(|v| if v > 0.0 { 1.0 / v } else { 1.0 }))
    })
}

/// Information of an accepted loop: `[loops] loop_sigma_m` and `loop_sigma_rotation_deg` per axis
/// (see there why a fixed value rather than the registration's Hessian).
pub fn loop_information(loops: &LoopsSection) -> Information {
    let sigma_m = loops.loop_sigma_m.max(1e-6);
    let sigma_rad = loops.loop_sigma_rotation_deg.to_radians().max(1e-9);
    let mut information = Information::zeros();
    for axis in 0..3 {
        information[(axis, axis)] = 1.0 / (sigma_m * sigma_m);
        information[(axis + 3, axis + 3)] = 1.0 / (sigma_rad * sigma_rad);
    }
    information
}
