//! Parameters of the `kiss_icp` odometry, with the reference values of KISS-ICP (Vizzo et al., RA-L 2023)
//! as defaults (see `ALGORITHMS.md`, section KISS-ICP), and their validation.

use serde::{Deserialize, Serialize};
use skid_core::PluginError;
use skid_geometry::KeyframePolicy;

/// Parameters of the `kiss_icp` odometry (`[odometry.kiss_icp]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct KissIcpConfig {
    /// Points farther than this from the sensor are dropped, and map voxels farther than this from the
    /// robot are removed, in metres.
    pub max_range_m: f64,
    /// Points closer than this to the sensor are dropped, in metres.
    pub min_range_m: f64,
    /// Edge of the local map's voxels, in metres; KISS-ICP derives it as `max_range_m / 100`. The scan
    /// is downsampled at 0.5 of it before entering the map and at 1.5 of it for registration.
    pub voxel_size_m: f64,
    /// Most points a map voxel holds.
    pub max_points_per_voxel: usize,
    /// Correspondence threshold σ before any motion has been measured, in metres; it stays in σ's root
    /// mean square as its first sample, as in the reference implementation.
    pub initial_threshold_m: f64,
    /// Model deviations (translation + rotation arc at max range) below this are not used to adapt σ,
    /// in metres.
    pub min_motion_m: f64,
    /// Correspondences are searched within this many σ.
    pub correspondence_sigmas: f64,
    /// The robust kernel's scale is σ divided by this.
    pub kernel_scale_divisor: f64,
    /// Most Gauss-Newton iterations per scan.
    pub max_iterations: usize,
    /// ICP stops when the norm of the 6-vector update (metres and radians) falls below this.
    pub convergence_criterion: f64,
    /// Correct the motion distortion of each sweep with the constant-velocity model.
    pub deskew: bool,
    /// Voxel size of keyframe clouds, in metres; 0 keeps every point.
    pub keyframe_voxel_m: f64,
    pub keyframe: KeyframePolicy,
    /// A registration is degenerate when a direction of its point-to-plane information holds less than
    /// this fraction of its block's best (translation and rotation judged apart); 0 turns the test off.
    /// Measured translation ratios: smooth planetary ground 0.01-0.04, cave 0.08-0.18, urban 0.18-0.87.
    pub degeneracy_ratio: f64,
    /// In a degenerate registration, keep the departure from the constant-velocity prediction along the
    /// weak translation directions only in proportion to their information (the motion model carries
    /// the rest).
    pub lean_on_motion_model: bool,
}

impl Default for KissIcpConfig {
    fn default() -> Self {
        Self {
            max_range_m: 100.0,
            min_range_m: 0.0,
            voxel_size_m: 1.0,
            max_points_per_voxel: 20,
            initial_threshold_m: 2.0,
            min_motion_m: 0.1,
            correspondence_sigmas: 3.0,
            kernel_scale_divisor: 3.0,
            max_iterations: 500,
            convergence_criterion: 1e-4,
            deskew: true,
            keyframe_voxel_m: 0.25,
            keyframe: KeyframePolicy::default(),
            degeneracy_ratio: 0.05,
            lean_on_motion_model: true,
        }
    }
}

impl KissIcpConfig {
    /// Checks every value, naming the first bad one.
    pub fn validate(&self) -> Result<(), PluginError> {
        let bad = |message: String| Err(PluginError::failed("kiss_icp", message));
        let positive = [
            ("max_range_m", self.max_range_m),
            ("voxel_size_m", self.voxel_size_m),
            ("initial_threshold_m", self.initial_threshold_m),
            ("correspondence_sigmas", self.correspondence_sigmas),
            ("kernel_scale_divisor", self.kernel_scale_divisor),
            ("convergence_criterion", self.convergence_criterion),
        ];
        for (name, value) in positive {
            if !(value.is_finite() && value > 0.0) {
                return bad(format!("{name} = {value} must be a positive number"));
            }
        }
        let non_negative = [
            ("min_range_m", self.min_range_m),
            ("min_motion_m", self.min_motion_m),
            ("keyframe_voxel_m", self.keyframe_voxel_m),
        ];
        for (name, value) in non_negative {
            if !(value.is_finite() && value >= 0.0) {
                return bad(format!("{name} = {value} must be a non-negative number"));
            }
        }
        if self.min_range_m >= self.max_range_m {
            return bad(format!(
                "min_range_m = {} must be below max_range_m = {}",
                self.min_range_m, self.max_range_m
            ));
        }
        if !(0.0..1.0).contains(&self.degeneracy_ratio) {
            return bad(format!(
                "degeneracy_ratio = {} must be within [0, 1)",
                self.degeneracy_ratio
            ));
        }
        if self.max_points_per_voxel == 0 {
            return bad("max_points_per_voxel must be at least 1".to_owned());
        }
        if self.max_iterations == 0 {
            return bad("max_iterations must be at least 1".to_owned());
        }
        Ok(())
    }
}

impl skid_core::PluginParams for KissIcpConfig {
    fn check(&self) -> Result<(), skid_core::ParamError> {
        self.validate()
            .map_err(skid_core::ParamError::from_plugin_error)?;
        self.keyframe.check()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_and_bad_values_are_named() {
        assert!(KissIcpConfig::default().validate().is_ok());
        let config = KissIcpConfig {
            voxel_size_m: 0.0,
            ..KissIcpConfig::default()
        };
        let error = config.validate().unwrap_err().to_string();
        assert!(error.contains("voxel_size_m"), "{error}");
        let config = KissIcpConfig {
            min_range_m: 200.0,
            ..KissIcpConfig::default()
        };
        assert!(config.validate().is_err());
        let config = KissIcpConfig {
            max_range_m: f64::NAN,
            ..KissIcpConfig::default()
        };
        assert!(config.validate().is_err());
    }

    #[test]
    fn unknown_keys_are_refused() {
        let parsed: Result<KissIcpConfig, _> = toml::from_str("max_range = 80.0");
        assert!(parsed.is_err());
        let parsed: KissIcpConfig = toml::from_str("max_range_m = 80.0").unwrap();
        assert_eq!(parsed.max_range_m, 80.0);
        assert_eq!(parsed.voxel_size_m, 1.0);
    }
}
