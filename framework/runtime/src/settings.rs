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
    information_of(loops.loop_sigma_m, loops.loop_sigma_rotation_deg)
}

/// The information with which the back-end weighs an accepted loop: the verifier's, or with `[loops]
/// backend_loop_sigma_rotation_deg` in place of its rotation σ when that is set; `None` when the
/// back-end weighs loops as the verifier tests them.
pub fn backend_loop_information(loops: &LoopsSection) -> Option<Information> {
    (loops.backend_loop_sigma_rotation_deg > 0.0)
        .then(|| information_of(loops.loop_sigma_m, loops.backend_loop_sigma_rotation_deg))
}

/// A diagonal information of `sigma_m` per translation axis and `sigma_deg` per rotation axis.
fn information_of(sigma_m: f64, sigma_deg: f64) -> Information {
    let sigma_m = sigma_m.max(1e-6);
    let sigma_rad = sigma_deg.to_radians().max(1e-9);
    let mut information = Information::zeros();
    for axis in 0..3 {
        information[(axis, axis)] = 1.0 / (sigma_m * sigma_m);
        information[(axis + 3, axis + 3)] = 1.0 / (sigma_rad * sigma_rad);
    }
    information
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_backend_weighs_loops_as_the_verifier_unless_its_own_rotation_sigma_is_set() {
        let mut loops = LoopsSection {
            backend_loop_sigma_rotation_deg: 0.0,
            ..LoopsSection::default()
        };
        assert!(backend_loop_information(&loops).is_none());
        loops.backend_loop_sigma_rotation_deg = 0.25;
        let verifier = loop_information(&loops);
        let backend = backend_loop_information(&loops).expect("set");
        let rotation_rad = 0.25f64.to_radians();
        for axis in 0..3 {
            assert_eq!(
                backend[(axis, axis)],
                verifier[(axis, axis)],
                "translation as the verifier's"
            );
            let expected = 1.0 / (rotation_rad * rotation_rad);
            assert!((backend[(axis + 3, axis + 3)] - expected).abs() < 1e-9 * expected);
            assert!(verifier[(axis + 3, axis + 3)] < backend[(axis + 3, axis + 3)] / 15.0);
        }
        assert_eq!(backend.iter().filter(|v| **v != 0.0).count(), 6, "diagonal");
    }
}
