//! SKiD's `iris` descriptor plugin: LiDAR-Iris (Wang et al., "LiDAR Iris for Loop-Closure Detection",
//! IROS 2020), an alternative to SOLiD, with its row-key index.
//!
//! - [`image`]: the rings × columns image of height-slice codes and its row key.
//! - [`features`]: log-Gabor filtering into a binary template and mask; phase-correlation shift.
//! - [`index`]: row-key candidates re-ranked by masked Hamming distance, with a yaw hint.
//! - `fft`: the mixed-radix FFT the filters and the shift estimate use (360 columns are not a power of 2).
//!
//! The descriptor buffer holds the code image (row-major, one value 0..=255 per pixel), 80 × 360 =
//! 28,800 values: 115,200 bytes as f32, or 28,800 bytes packed as u8 codes. The template and mask are
//! a deterministic function of the image, so the receiving index computes them instead of receiving
//! them (they would add 57,600 bytes).

pub mod features;
mod fft;
pub mod image;
pub mod index;

impl skid_core::PluginParams for IrisConfig {
    fn check(&self) -> Result<(), skid_core::ParamError> {
        self.validate().map_err(skid_core::ParamError::from_plugin_error)
    }
}

#[cfg(test)]
mod tests;

use serde::{Deserialize, Serialize};
use skid_core::slots::{Descriptor, DescriptorBuf, DescriptorIndex};
use skid_core::{CloudView, PluginContext, PluginEntry, PluginError, PluginResult, Registry};

pub use features::{Features, FilterBank};
pub use image::IrisImage;
pub use index::{IrisIndex, IrisShape};
pub use skid_keytree::{MAX_KEY_LEN, RebuildPolicy};

/// The plugin's registry name and descriptor kind.
pub const NAME: &str = "iris";

/// Parameters of the `iris` descriptor; defaults are the reference values.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct IrisConfig {
    /// Image rows: rings of `ring_width_m` from the sensor outwards.
    pub num_rings: usize,
    /// Width of a ring, in metres (the image reaches num_rings · ring_width_m).
    pub ring_width_m: f64,
    /// Image columns over 360°.
    pub num_columns: usize,
    /// Points with a smaller horizontal range are dropped, in metres.
    pub min_range_m: f64,
    /// Bottom of the lowest height slice, in metres in the sensor frame.
    pub min_height_m: f64,
    /// Height of a slice, in metres.
    pub slice_height_m: f64,
    /// Height slices (bits of a pixel code), 1 to 8.
    pub num_slices: usize,
    /// Log-Gabor scales, 1 to 4 (two template bits each).
    pub num_scales: usize,
    /// Wavelength of the finest filter, in columns.
    pub min_wavelength: f64,
    /// Wavelength ratio between successive scales.
    pub wavelength_multiplier: f64,
    /// Bandwidth: σ of the log-Gaussian over its centre frequency.
    pub sigma_on_f: f64,
    /// A filter response of smaller modulus masks its two template bits.
    pub mask_epsilon: f64,
    /// Shifts searched on each side of the phase-correlation estimate, in columns.
    pub shift_search_radius: usize,
    /// Also search around the estimate turned by 180°.
    pub match_flipped: bool,
    /// Row-key neighbours re-ranked by the Hamming distance per query.
    pub num_candidates: usize,
    /// Keys inserted since the last KD-tree build that are always scanned linearly before a rebuild.
    pub rebuild_min_pending: usize,
    /// Pending keys tolerated, as a fraction of all stored keys, before the KD-tree is rebuilt.
    pub rebuild_pending_fraction: f64,
}

impl Default for IrisConfig {
    fn default() -> Self {
        Self {
            num_rings: 80,
            ring_width_m: 1.0,
            num_columns: 360,
            min_range_m: 0.0,
            min_height_m: -5.0,
            slice_height_m: 1.0,
            num_slices: 8,
            num_scales: 4,
            min_wavelength: 18.0,
            wavelength_multiplier: 1.6,
            sigma_on_f: 0.75,
            mask_epsilon: 1e-4,
            shift_search_radius: 2,
            match_flipped: true,
            num_candidates: 6,
            rebuild_min_pending: 32,
            rebuild_pending_fraction: 0.1,
        }
    }
}

impl IrisConfig {
    /// Checks the values serde cannot.
    pub fn validate(&self) -> PluginResult<()> {
        let fail = |message: String| Err(PluginError::failed(NAME, message));
        let positive = |v: f64| v.is_finite() && v > 0.0;
        if !(1..=MAX_KEY_LEN).contains(&self.num_rings) {
            return fail(format!(
                "num_rings must be in 1..={MAX_KEY_LEN}, got {}",
                self.num_rings
            ));
        }
        if !(2..=3600).contains(&self.num_columns) {
            return fail(format!(
                "num_columns must be in 2..=3600, got {}",
                self.num_columns
            ));
        }
        if !(1..=8).contains(&self.num_slices) || !(1..=4).contains(&self.num_scales) {
            return fail(format!(
                "need 1..=8 slices and 1..=4 scales, got {} and {}",
                self.num_slices, self.num_scales
            ));
        }
        if !(positive(self.ring_width_m) && positive(self.slice_height_m) && self.min_height_m.is_finite()) {
            return fail("ring_width_m and slice_height_m must be positive, min_height_m finite".to_owned());
        }
        if !(self.min_range_m.is_finite() && self.min_range_m >= 0.0) {
            return fail(format!(
                "min_range_m must be finite and >= 0, got {}",
                self.min_range_m
            ));
        }
        if !(positive(self.min_wavelength) && positive(self.wavelength_multiplier)) {
            return fail("min_wavelength and wavelength_multiplier must be positive".to_owned());
        }
        if !(self.sigma_on_f.is_finite() && 0.0 < self.sigma_on_f && self.sigma_on_f < 1.0) {
            return fail(format!("sigma_on_f must be in (0, 1), got {}", self.sigma_on_f));
        }
        if !(self.mask_epsilon.is_finite() && self.mask_epsilon >= 0.0) {
            return fail(format!(
                "mask_epsilon must be finite and >= 0, got {}",
                self.mask_epsilon
            ));
        }
        if self.num_candidates == 0 {
            return fail("num_candidates must be at least 1".to_owned());
        }
        if !(self.rebuild_pending_fraction.is_finite() && self.rebuild_pending_fraction >= 0.0) {
            return fail(format!(
                "rebuild_pending_fraction must be finite and >= 0, got {}",
                self.rebuild_pending_fraction
            ));
        }
        Ok(())
    }

    /// Pixels in an image.
    pub fn num_values(&self) -> usize {
        self.num_rings * self.num_columns
    }

    /// Bytes one descriptor takes on the wire as the f32 `DescriptorBuf`.
    pub fn wire_size_bytes(&self) -> usize {
        self.num_values() * std::mem::size_of::<f32>()
    }

    /// Bytes one descriptor takes with its codes packed as u8.
    pub fn packed_size_bytes(&self) -> usize {
        self.num_values()
    }

    /// The log-Gabor filters of this configuration.
    pub fn filter_bank(&self) -> FilterBank {
        FilterBank::new(
            self.num_columns,
            self.num_scales,
            self.min_wavelength,
            self.wavelength_multiplier,
            self.sigma_on_f,
            self.mask_epsilon,
        )
    }
}

/// Registers `iris` in the descriptor slot.
pub fn register(registry: &mut Registry) -> Result<(), PluginError> {
    let entry = PluginEntry::new(
        NAME,
        "LiDAR-Iris (Wang et al., IROS 2020): height-slice code image, log-Gabor binary template, masked Hamming distance with FFT shift",
        |config: IrisConfig, _context: &PluginContext| {
            Ok(Box::new(IrisDescriptor::from_checked(config)?) as Box<dyn Descriptor>)
        },
    )?;
    registry.descriptor.register(entry)
}

/// The plugin state: a validated config.
pub struct IrisDescriptor {
    config: IrisConfig,
}

impl IrisDescriptor {
    pub fn new(config: IrisConfig) -> PluginResult<Self> {
        config.validate()?;
        Self::from_checked(config)
    }

    /// [`IrisDescriptor::new`] for a configuration the registry has checked already (it is checked once, when
    /// the configuration is loaded).
    pub(crate) fn from_checked(config: IrisConfig) -> PluginResult<Self> {
        Ok(Self { config })
    }

    pub fn config(&self) -> &IrisConfig {
        &self.config
    }

    /// The code image of a cloud with what was dropped.
    pub fn image(&self, cloud: CloudView<'_>) -> PluginResult<IrisImage> {
        image::iris_image(cloud.points(), &self.config)
    }

    /// Bytes one descriptor takes on the wire (f32 values).
    pub fn wire_size_bytes(&self) -> usize {
        self.config.wire_size_bytes()
    }
}

impl Descriptor for IrisDescriptor {
    fn kind(&self) -> &str {
        NAME
    }

    fn describe(&mut self, cloud: CloudView<'_>) -> PluginResult<DescriptorBuf> {
        let image = self.image(cloud)?;
        if image.points_used == 0 {
            return Err(PluginError::InvalidInput(format!(
                "no point of {} lies within the image ({} out of range, {} outside the height slices {}..{} m)",
                cloud.len(),
                image.points_out_of_range,
                image.points_outside_heights,
                self.config.min_height_m,
                self.config.min_height_m + self.config.num_slices as f64 * self.config.slice_height_m
            )));
        }
        Ok(DescriptorBuf {
            kind: NAME.to_owned(),
            values: image.codes.iter().map(|&c| f32::from(c)).collect(),
        })
    }

    fn new_index(&self) -> Box<dyn DescriptorIndex> {
        let shape = IrisShape {
            num_rings: self.config.num_rings,
            num_columns: self.config.num_columns,
            num_slices: self.config.num_slices,
            num_candidates: self.config.num_candidates,
            shift_search_radius: self.config.shift_search_radius,
            match_flipped: self.config.match_flipped,
        };
        let policy = RebuildPolicy {
            min_pending: self.config.rebuild_min_pending,
            pending_fraction: self.config.rebuild_pending_fraction,
        };
        Box::new(IrisIndex::new(shape, self.config.filter_bank(), policy))
    }
}
