//! `gicp_cdylib`: SKiD's own GICP fine registration (`skid-fine-gicp`) exported through the C ABI.
//!
//! It shows a Rust fine-registration plugin — the slot where most published methods would go — and,
//! because the code behind it is exactly the built-in `gicp`, it is what `cargo xtask bench abi` loads
//! to measure what crossing the boundary costs per call. Its prepared cloud is the built-in's own
//! `PreparedCloud` (downsampled points, kd-tree and covariances), kept in the plugin and handed back by
//! handle.

use skid_abi::transform::{abi_from_pose, pose_from_abi};
use skid_abi::{AbiTransform, ConfigError, FineOutcome, FinePlugin, InstanceContext, parse_config};
use skid_core::CloudView;
use skid_core::slots::{FineRegistration, PreparedCloud};
use skid_fine_gicp::{GicpConfig, GicpRegistration};
use skid_msgs::Point;

/// The built-in GICP's defaults as TOML, as declared to the host; a unit test keeps them equal to
/// `GicpConfig::default()`.
const DEFAULT_CONFIG: &str = "variant = \"gicp\"
downsampling_m = 0.25
num_neighbors = 10
max_correspondence_m = 1.0
coarse_downsampling_m = 1.0
coarse_correspondence_m = 4.0
voxel_resolution_m = 1.0
voxel_search_offsets = 1
max_iterations = 20
coarse_max_iterations = 100
max_inner_iterations = 10
lambda_init = 0.001
lambda_factor = 10.0
rotation_eps_deg = 0.1
translation_eps_m = 0.001
min_points = 10
min_inliers = 10
min_extent_m = 0.05
";

/// The built-in GICP behind the C ABI.
pub struct GicpCdylib {
    inner: GicpRegistration,
}

impl FinePlugin for GicpCdylib {
    const NAME: &'static str = "gicp_cdylib";
    const SUMMARY: &'static str =
        "The built-in GICP loaded through the C ABI (example cdylib; measures the boundary)";
    const DEFAULT_CONFIG: &'static str = DEFAULT_CONFIG;
    type Prepared = PreparedCloud;

    fn from_config(config: &str, context: &InstanceContext) -> Result<Self, ConfigError> {
        let config: GicpConfig = parse_config(config)?;
        let context = crate::plugin_context(context);
        let inner =
            GicpRegistration::new(config, &context).map_err(|error| ConfigError::from(error.to_string()))?;
        Ok(Self { inner })
    }

    fn prepare(&mut self, points: &[Point]) -> Result<PreparedCloud, String> {
        self.inner
            .prepare(CloudView::new(points))
            .map_err(|error| error.to_string())
    }

    fn prepared_points(prepared: &PreparedCloud) -> &[Point] {
        &prepared.cloud.points
    }

    fn refine(
        &mut self,
        target: &PreparedCloud,
        source: &PreparedCloud,
        guess: &AbiTransform,
    ) -> Result<FineOutcome, String> {
        let guess = pose_from_abi(guess)?;
        let alignment = self
            .inner
            .refine(target, source, &guess)
            .map_err(|error| error.to_string())?;
        let mut information = [0.0; 36];
        for row in 0..6 {
            for column in 0..6 {
                information[row * 6 + column] = alignment.information[(row, column)];
            }
        }
        Ok(FineOutcome {
            target_from_source: abi_from_pose(&alignment.target_from_source),
            information,
            converged: alignment.converged,
            iterations: alignment.iterations as u64,
            inlier_count: alignment.inlier_count as u64,
            inlier_ratio: alignment.inlier_ratio,
            error: alignment.error,
            failure: alignment.failure,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_config_text_matches_the_built_in_defaults() {
        assert_eq!(
            parse_config::<GicpConfig>(DEFAULT_CONFIG).unwrap(),
            GicpConfig::default()
        );
    }

    #[test]
    fn a_bad_value_is_refused_with_its_name() {
        let Err(error) = GicpCdylib::from_config("num_neighbors = 1", &InstanceContext::default()) else {
            panic!("one neighbour was accepted")
        };
        assert!(error.message.contains("num_neighbors"), "{error}");
    }
}
