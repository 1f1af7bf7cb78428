//! Parameters of the `gicp` fine-registration plugin (`[fine.gicp]`), with the small_gicp defaults
//! collected in `shared/design/ALGORITHMS.md`, and their validation.

use serde::{Deserialize, Serialize};
use skid_core::{PluginError, PluginResult};

use crate::PLUGIN_NAME;

/// Which cost the plugin minimises.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Variant {
    /// Generalized ICP: plane-to-plane Mahalanobis distance between per-point covariances.
    #[default]
    Gicp,
    /// Voxelized GICP: the target is a map of Gaussian voxels (mean and mean covariance per voxel).
    Vgicp,
    /// Point-to-point ICP.
    Icp,
    /// Point-to-plane ICP on the target's normals.
    PlaneIcp,
}

impl Variant {
    /// The name used in config files.
    pub const fn key(self) -> &'static str {
        match self {
            Variant::Gicp => "gicp",
            Variant::Vgicp => "vgicp",
            Variant::Icp => "icp",
            Variant::PlaneIcp => "plane_icp",
        }
    }

    /// Every variant, the default first.
    pub const ALL: [Variant; 4] = [Variant::Gicp, Variant::Vgicp, Variant::Icp, Variant::PlaneIcp];

    /// True when `prepare` must estimate per-point covariances (or normals).
    pub const fn needs_local_features(self) -> bool {
        !matches!(self, Variant::Icp)
    }
}

impl std::fmt::Display for Variant {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.key())
    }
}

/// Parameters of the `gicp` plugin. Every value of the reference implementation is exposed.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct GicpConfig {
    /// The cost: `gicp` (default), `vgicp`, `icp` or `plane_icp`.
    pub variant: Variant,
    /// Voxel size of the centroid downsampling done by `prepare`, in metres; 0 keeps every point.
    pub downsampling_m: f64,
    /// Neighbours used for each point's covariance (or normal).
    pub num_neighbors: usize,
    /// Correspondences farther apart than this (after applying the current estimate) are rejected, metres.
    pub max_correspondence_m: f64,
    /// Voxel size of the coarse level `prepare` also builds (the fine points downsampled again), metres.
    /// A first stage registers the two clouds' coarse levels with `coarse_correspondence_m`, and the final
    /// stage starts from its result: a coarse-to-fine pyramid as in Open3D's multi-scale ICP, which widens
    /// the basin of convergence for poor guesses at a small cost (a 1 m level has several times fewer
    /// points than a 0.25 m one). Not larger than `downsampling_m` (0, say): the first stage runs on the
    /// fine points themselves.
    pub coarse_downsampling_m: f64,
    /// Rejection distance of the first (coarse) stage, metres; 0 turns the coarse stage off and leaves
    /// the single stage of small_gicp. The default keeps the fine level's ratio of correspondence distance
    /// to voxel size (1.0 m / 0.25 m) at the coarse level (4.0 m / 1.0 m). VGICP's first stage is GICP on
    /// the coarse points, as a voxel map reaches only the voxels next to a point.
    pub coarse_correspondence_m: f64,
    /// Voxel size of the VGICP Gaussian voxel map, in metres.
    pub voxel_resolution_m: f64,
    /// Voxels searched for a VGICP correspondence: 1 (the voxel holding the point, small_gicp's default), 7
    /// (and its face neighbours) or 27 (the whole 3x3x3 block; widest basin, slowest).
    pub voxel_search_offsets: usize,
    /// Most Levenberg-Marquardt linearisations (outer iterations) of the final stage.
    pub max_iterations: usize,
    /// Most linearisations of the coarse stage. Its linearisations are cheap (the coarse level has
    /// several times fewer points) and point-to-point ICP converges only linearly from a poor guess, so
    /// the budget is generous, between Open3D's 30 and KISS-ICP's 500; the other variants stop after a
    /// few on the epsilons.
    pub coarse_max_iterations: usize,
    /// Most damping adjustments per linearisation.
    pub max_inner_iterations: usize,
    /// Initial Levenberg-Marquardt damping.
    pub lambda_init: f64,
    /// Factor by which the damping grows after a rejected step and shrinks after an accepted one.
    pub lambda_factor: f64,
    /// Converged when an accepted step rotates by less than this, degrees…
    pub rotation_eps_deg: f64,
    /// …and translates by less than this, metres.
    pub translation_eps_m: f64,
    /// Fewest points a prepared cloud needs (after downsampling) to be registered.
    pub min_points: usize,
    /// Fewest inlier correspondences for a result to count as converged.
    pub min_inliers: usize,
    /// A cloud whose thinnest principal extent (standard deviation along its least-spread axis) is below
    /// this is coplanar, and one whose second principal extent is below it is collinear: neither
    /// constrains all six degrees of freedom, so registration against it never claims convergence. Metres.
    pub min_extent_m: f64,
}

impl Default for GicpConfig {
    fn default() -> Self {
        Self {
            variant: Variant::Gicp,
            downsampling_m: 0.25,
            num_neighbors: 10,
            max_correspondence_m: 1.0,
            coarse_downsampling_m: 1.0,
            coarse_correspondence_m: 4.0,
            voxel_resolution_m: 1.0,
            voxel_search_offsets: 1,
            max_iterations: 20,
            coarse_max_iterations: 100,
            max_inner_iterations: 10,
            lambda_init: 1e-3,
            lambda_factor: 10.0,
            rotation_eps_deg: 0.1,
            translation_eps_m: 1e-3,
            min_points: 10,
            min_inliers: 10,
            min_extent_m: 0.05,
        }
    }
}

impl GicpConfig {
    /// A default configuration of the given variant.
    pub fn with_variant(variant: Variant) -> Self {
        Self {
            variant,
            ..Self::default()
        }
    }

    /// Checks that every value is usable.
    pub fn validate(&self) -> PluginResult<()> {
        let bad = |what: &str, value: &dyn std::fmt::Display| {
            Err(PluginError::failed(
                PLUGIN_NAME,
                format!("{what} must be {value}"),
            ))
        };
        let non_negative = |v: f64| v.is_finite() && v >= 0.0;
        let positive = |v: f64| v.is_finite() && v > 0.0;
        if !non_negative(self.downsampling_m) {
            return bad(
                "downsampling_m",
                &format!("finite and >= 0, got {}", self.downsampling_m),
            );
        }
        if !(3..=1000).contains(&self.num_neighbors) {
            return bad(
                "num_neighbors",
                &format!("between 3 and 1000, got {}", self.num_neighbors),
            );
        }
        if !positive(self.max_correspondence_m) {
            return bad(
                "max_correspondence_m",
                &format!("positive, got {}", self.max_correspondence_m),
            );
        }
        if !non_negative(self.coarse_downsampling_m) {
            return bad(
                "coarse_downsampling_m",
                &format!("finite and >= 0, got {}", self.coarse_downsampling_m),
            );
        }
        if !non_negative(self.coarse_correspondence_m) {
            return bad(
                "coarse_correspondence_m",
                &format!("finite and >= 0, got {}", self.coarse_correspondence_m),
            );
        }
        if !positive(self.voxel_resolution_m) {
            return bad(
                "voxel_resolution_m",
                &format!("positive, got {}", self.voxel_resolution_m),
            );
        }
        if ![1, 7, 27].contains(&self.voxel_search_offsets) {
            return bad(
                "voxel_search_offsets",
                &format!("1, 7 or 27, got {}", self.voxel_search_offsets),
            );
        }
        if self.max_iterations == 0 || self.coarse_max_iterations == 0 || self.max_inner_iterations == 0 {
            return bad(
                "max_iterations, coarse_max_iterations and max_inner_iterations",
                &"at least 1",
            );
        }
        if !positive(self.lambda_init) {
            return bad("lambda_init", &format!("positive, got {}", self.lambda_init));
        }
        if !(self.lambda_factor.is_finite() && self.lambda_factor > 1.0) {
            return bad(
                "lambda_factor",
                &format!("greater than 1, got {}", self.lambda_factor),
            );
        }
        if !positive(self.rotation_eps_deg) || !positive(self.translation_eps_m) {
            return bad("rotation_eps_deg and translation_eps_m", &"positive");
        }
        if !non_negative(self.min_extent_m) {
            return bad(
                "min_extent_m",
                &format!("finite and >= 0, got {}", self.min_extent_m),
            );
        }
        Ok(())
    }

    /// The voxel size of the coarse level `prepare` builds, if it builds one.
    pub(crate) fn coarse_level_m(&self) -> Option<f64> {
        (self.coarse_correspondence_m > 0.0 && self.coarse_downsampling_m > self.downsampling_m)
            .then_some(self.coarse_downsampling_m)
    }

    /// The settings that shape what `prepare` computes: two plugin instances whose preparation keys are
    /// equal can share prepared clouds.
    pub(crate) fn preparation_key(&self) -> PreparationKey {
        PreparationKey {
            variant: self.variant,
            downsampling_m: self.downsampling_m.to_bits(),
            num_neighbors: self.num_neighbors,
            coarse_downsampling_m: self.coarse_level_m().map_or(0, f64::to_bits),
            voxel_resolution_m: if self.variant == Variant::Vgicp {
                self.voxel_resolution_m.to_bits()
            } else {
                0
            },
        }
    }
}

/// What a prepared cloud was prepared with (see [`GicpConfig::preparation_key`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct PreparationKey {
    pub variant: Variant,
    pub downsampling_m: u64,
    pub num_neighbors: usize,
    pub coarse_downsampling_m: u64,
    pub voxel_resolution_m: u64,
}

impl std::fmt::Display for PreparationKey {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "variant {}, downsampling {} m, {} neighbours",
            self.variant,
            f64::from_bits(self.downsampling_m),
            self.num_neighbors
        )?;
        if self.coarse_downsampling_m != 0 {
            write!(
                f,
                ", coarse level {} m",
                f64::from_bits(self.coarse_downsampling_m)
            )?;
        }
        if self.variant == Variant::Vgicp {
            write!(f, ", voxel map {} m", f64::from_bits(self.voxel_resolution_m))?;
        }
        Ok(())
    }
}

impl skid_core::PluginParams for GicpConfig {
    fn check(&self) -> Result<(), skid_core::ParamError> {
        self.validate().map_err(skid_core::ParamError::from_plugin_error)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use skid_core::Params;

    #[test]
    fn defaults_are_valid_and_round_trip() {
        let config = GicpConfig::default();
        config.validate().unwrap();
        let params = Params::from_config(&config).unwrap();
        assert_eq!(params.table()["variant"].as_str(), Some("gicp"));
        assert_eq!(params.parse::<GicpConfig>().unwrap(), config);
    }

    #[test]
    fn variants_parse_by_name() {
        for variant in Variant::ALL {
            let params = Params::from_toml_str(&format!("variant = \"{}\"", variant.key())).unwrap();
            assert_eq!(params.parse::<GicpConfig>().unwrap().variant, variant);
        }
        assert!(
            Params::from_toml_str("variant = \"ndt\"")
                .unwrap()
                .parse::<GicpConfig>()
                .is_err()
        );
    }

    #[test]
    fn bad_values_are_refused_with_their_name() {
        type Spoil = fn(&mut GicpConfig);
        let cases: [(&str, Spoil); 4] = [
            ("downsampling_m", |c| c.downsampling_m = -1.0),
            ("num_neighbors", |c| c.num_neighbors = 1),
            ("max_correspondence_m", |c| c.max_correspondence_m = f64::NAN),
            ("lambda_factor", |c| c.lambda_factor = 0.5),
        ];
        for (name, spoil) in cases {
            let mut config = GicpConfig::default();
            spoil(&mut config);
            let error = config.validate().unwrap_err().to_string();
            assert!(error.contains(name), "{error}");
        }
    }
}
