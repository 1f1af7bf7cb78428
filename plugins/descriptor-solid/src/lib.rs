//! SKiD's `solid` descriptor plugin: SOLiD (Kim et al., "Narrowing your FOV with SOLiD: Spatially
//! Organized and Lightweight Global Descriptor for FOV-constrained LiDAR Place Recognition", RA-L 2024),
//! the default place-recognition descriptor of SKiD-SLAM, with its kiddo KD-tree retrieval index.
//!
//! - [`extract`]: the range × elevation and azimuth × elevation counts, the implicit elevation vector,
//!   R-SOLiD and A-SOLiD (every definition and edge case is written there).
//! - [`index`]: retrieval by cosine distance of R-SOLiD in a KD-tree, yaw hint from A-SOLiD.
//! - [`wire`]: the f32 encoding (400 bytes by default) and the optional u8 / u16 quantised encodings.
//!
//! The descriptor buffer holds R-SOLiD (`num_range_bins` values) followed by A-SOLiD (`num_azimuth_bins`
//! values). Bins, range limits and the vertical field of view are configurable, so one plugin serves
//! 360° spinning LiDARs and narrow solid-state ones: the azimuth axis always spans 360°, and a sensor that
//! sees 60° of it leaves the other azimuth bins empty, which R-SOLiD (summed over azimuth) ignores.

mod angle;
pub mod extract;
pub mod index;
mod voxel;
pub mod wire;

impl skid_core::PluginParams for SolidConfig {
    fn check(&self) -> Result<(), skid_core::ParamError> {
        self.validate().map_err(skid_core::ParamError::from_plugin_error)
    }
}

#[cfg(test)]
mod tests;

use std::sync::Mutex;

use serde::{Deserialize, Serialize};
use skid_core::slots::{Descriptor, DescriptorBuf, DescriptorIndex};
use skid_core::{CloudView, PluginContext, PluginEntry, PluginError, PluginResult, Registry};

pub use extract::SolidParts;
pub use index::SolidIndex;
pub use skid_keytree::{MAX_KEY_LEN, RebuildPolicy};
pub use wire::Quantization;

use extract::Binning;
use voxel::VoxelOccupancy;

/// The plugin's registry name and descriptor kind.
pub const NAME: &str = "solid";

/// Parameters of the `solid` descriptor. Defaults are the reference values for an HDL-64E.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct SolidConfig {
    /// Range bins over [0, max_range_m].
    pub num_range_bins: usize,
    /// Azimuth bins over 360°.
    pub num_azimuth_bins: usize,
    /// Elevation bins over [lower_fov_deg, upper_fov_deg].
    pub num_elevation_bins: usize,
    /// Points with a smaller horizontal range are dropped, in metres.
    pub min_range_m: f64,
    /// Points with a larger horizontal range are dropped, in metres.
    pub max_range_m: f64,
    /// Lower edge of the sensor's vertical field of view, in degrees (negative is below the horizon).
    pub lower_fov_deg: f64,
    /// Upper edge of the vertical field of view, in degrees.
    pub upper_fov_deg: f64,
    /// The keyframe is voxel-downsampled at this size before counting, in metres; 0 counts every point.
    pub voxel_size_m: f64,
    /// Encoding on the wire; a quantised encoding also rounds the values `describe` returns.
    pub quantization: Quantization,
    /// Keys inserted since the last KD-tree build that are always scanned linearly before a rebuild.
    pub rebuild_min_pending: usize,
    /// Pending keys tolerated, as a fraction of all stored keys, before the KD-tree is rebuilt.
    pub rebuild_pending_fraction: f64,
}

impl Default for SolidConfig {
    fn default() -> Self {
        Self {
            num_range_bins: 40,
            num_azimuth_bins: 60,
            num_elevation_bins: 32,
            min_range_m: 3.0,
            max_range_m: 80.0,
            lower_fov_deg: -24.8,
            upper_fov_deg: 2.0,
            voxel_size_m: 0.4,
            quantization: Quantization::None,
            rebuild_min_pending: 32,
            rebuild_pending_fraction: 0.1,
        }
    }
}

impl SolidConfig {
    /// Checks the values serde cannot.
    pub fn validate(&self) -> PluginResult<()> {
        let fail = |message: String| Err(PluginError::failed(NAME, message));
        if !(1..=MAX_KEY_LEN).contains(&self.num_range_bins) {
            return fail(format!(
                "num_range_bins must be in 1..={MAX_KEY_LEN}, got {}",
                self.num_range_bins
            ));
        }
        if !(1..=3600).contains(&self.num_azimuth_bins) {
            return fail(format!(
                "num_azimuth_bins must be in 1..=3600, got {}",
                self.num_azimuth_bins
            ));
        }
        if !(1..=1024).contains(&self.num_elevation_bins) {
            return fail(format!(
                "num_elevation_bins must be in 1..=1024, got {}",
                self.num_elevation_bins
            ));
        }
        if !(self.min_range_m.is_finite()
            && self.max_range_m.is_finite()
            && 0.0 <= self.min_range_m
            && self.min_range_m < self.max_range_m)
        {
            return fail(format!(
                "need 0 <= min_range_m < max_range_m, got {} and {}",
                self.min_range_m, self.max_range_m
            ));
        }
        if !(-90.0 < self.lower_fov_deg
            && self.lower_fov_deg < self.upper_fov_deg
            && self.upper_fov_deg < 90.0)
        {
            return fail(format!(
                "need -90 < lower_fov_deg < upper_fov_deg < 90, got {} and {} (check the signs: the lower edge is the negative one)",
                self.lower_fov_deg, self.upper_fov_deg
            ));
        }
        if !(self.voxel_size_m.is_finite() && self.voxel_size_m >= 0.0) {
            return fail(format!(
                "voxel_size_m must be finite and >= 0, got {}",
                self.voxel_size_m
            ));
        }
        if !(self.rebuild_pending_fraction.is_finite() && self.rebuild_pending_fraction >= 0.0) {
            return fail(format!(
                "rebuild_pending_fraction must be finite and >= 0, got {}",
                self.rebuild_pending_fraction
            ));
        }
        Ok(())
    }

    /// Values in a descriptor: R-SOLiD then A-SOLiD.
    pub fn num_values(&self) -> usize {
        self.num_range_bins + self.num_azimuth_bins
    }

    /// Bytes one descriptor takes on the wire with the configured encoding.
    pub fn wire_size_bytes(&self) -> usize {
        wire::wire_size_bytes(self.num_values(), self.quantization)
    }
}

/// Registers `solid` in the descriptor slot.
pub fn register(registry: &mut Registry) -> Result<(), PluginError> {
    let entry = PluginEntry::new(
        NAME,
        "SOLiD (Kim et al., RA-L 2024): range/azimuth x elevation point counts weighted by the elevation profile; KD-tree over R-SOLiD, yaw from A-SOLiD",
        |config: SolidConfig, _context: &PluginContext| {
            Ok(Box::new(SolidDescriptor::from_checked(config)?) as Box<dyn Descriptor>)
        },
    )?;
    registry.descriptor.register(entry)
}

/// The plugin state: a validated config, its precomputed binning and the voxel occupancy grid reused
/// between keyframes.
pub struct SolidDescriptor {
    config: SolidConfig,
    binning: Binning,
    occupancy: Mutex<VoxelOccupancy>,
}

impl SolidDescriptor {
    pub fn new(config: SolidConfig) -> PluginResult<Self> {
        config.validate()?;
        Self::from_checked(config)
    }

    /// [`SolidDescriptor::new`] for a configuration the registry has checked already (it is checked once, when
    /// the configuration is loaded).
    pub(crate) fn from_checked(config: SolidConfig) -> PluginResult<Self> {
        Ok(Self {
            binning: Binning::new(&config),
            occupancy: Mutex::new(occupancy_for(&config)),
            config,
        })
    }

    pub fn config(&self) -> &SolidConfig {
        &self.config
    }

    /// Every intermediate of the descriptor for a cloud (after voxel downsampling), before quantisation.
    pub fn parts(&self, cloud: CloudView<'_>) -> PluginResult<SolidParts> {
        let points = cloud.points();
        if self.config.voxel_size_m <= 0.0 {
            return self.binning.parts(points);
        }
        // The occupancy grid is reused from call to call; a call while another thread holds it (the
        // descriptor shared between threads) makes its own.
        let mut own;
        let mut shared = self.occupancy.try_lock();
        let occupancy = match shared.as_deref_mut() {
            Ok(occupancy) => occupancy,
            Err(_) => {
                own = occupancy_for(&self.config);
                &mut own
            }
        };
        let kept = occupancy.first_per_voxel(points).map_err(|index| {
            PluginError::InvalidInput(format!("point {index} of {} is not finite", points.len()))
        })?;
        Ok(self
            .binning
            .parts_of_finite(kept.iter().map(|&index| &points[index])))
    }

    /// Bytes one descriptor takes on the wire.
    pub fn wire_size_bytes(&self) -> usize {
        self.config.wire_size_bytes()
    }

    /// The bytes to send for a descriptor this plugin produced.
    pub fn encode(&self, descriptor: &DescriptorBuf) -> Vec<u8> {
        wire::encode(
            &descriptor.values,
            self.config.num_range_bins,
            self.config.quantization,
        )
    }

    /// The descriptor a peer sent as [`SolidDescriptor::encode`] bytes.
    pub fn decode(&self, bytes: &[u8]) -> PluginResult<DescriptorBuf> {
        let values = wire::decode(
            bytes,
            self.config.num_range_bins,
            self.config.num_azimuth_bins,
            self.config.quantization,
        )?;
        Ok(DescriptorBuf {
            kind: NAME.to_owned(),
            values,
        })
    }
}

impl Descriptor for SolidDescriptor {
    fn kind(&self) -> &str {
        NAME
    }

    fn describe(&mut self, cloud: CloudView<'_>) -> PluginResult<DescriptorBuf> {
        let parts = self.parts(cloud)?;
        if parts.points_used == 0 {
            return Err(PluginError::InvalidInput(format!(
                "no point of {} lies within {}-{} m and the vertical FOV {}..{} deg ({} out of range, {} outside the FOV after downsampling)",
                cloud.len(),
                self.config.min_range_m,
                self.config.max_range_m,
                self.config.lower_fov_deg,
                self.config.upper_fov_deg,
                parts.points_out_of_range,
                parts.points_outside_fov
            )));
        }
        let mut values = parts.r_solid;
        let mut azimuth = parts.a_solid;
        wire::quantize_in_place(&mut values, self.config.quantization);
        wire::quantize_in_place(&mut azimuth, self.config.quantization);
        values.extend(azimuth);
        Ok(DescriptorBuf {
            kind: NAME.to_owned(),
            values,
        })
    }

    fn new_index(&self) -> Box<dyn DescriptorIndex> {
        let policy = RebuildPolicy {
            min_pending: self.config.rebuild_min_pending,
            pending_fraction: self.config.rebuild_pending_fraction,
        };
        Box::new(SolidIndex::new(
            self.config.num_range_bins,
            self.config.num_azimuth_bins,
            policy,
        ))
    }
}

/// The voxel occupancy of a config: its grid spans the range limit and the heights the vertical field
/// of view reaches within it.
fn occupancy_for(config: &SolidConfig) -> VoxelOccupancy {
    let reach = |deg: f64| config.max_range_m * deg.to_radians().tan();
    VoxelOccupancy::new(
        config.voxel_size_m as f32,
        config.max_range_m as f32,
        reach(config.lower_fov_deg).min(0.0) as f32,
        reach(config.upper_fov_deg).max(0.0) as f32,
    )
}
