//! SKiD's `scan_context` descriptor plugin: Scan Context (Kim & Kim, "Scan Context: Egocentric Spatial
//! Descriptor for Place Recognition within 3D Point Cloud Map", IROS 2018), an alternative to SOLiD, with
//! its ring-key KD-tree index.
//!
//! - [`extract`]: the rings × sectors grid of maximum heights and its ring and sector keys.
//! - [`index`]: ring-key candidates re-ranked by the column-shift cosine distance, with a yaw hint.
//!
//! The descriptor buffer holds the grid row-major by ring (20 × 60 = 1,200 f32 = 4,800 bytes by default).

pub mod extract;
pub mod index;

impl skid_core::PluginParams for ScanContextConfig {
    fn check(&self) -> Result<(), skid_core::ParamError> {
        self.validate().map_err(skid_core::ParamError::from_plugin_error)
    }
}

#[cfg(test)]
mod tests;

use serde::{Deserialize, Serialize};
use skid_core::slots::{Descriptor, DescriptorBuf, DescriptorIndex};
use skid_core::{CloudView, PluginContext, PluginEntry, PluginError, PluginResult, Registry};

pub use extract::ScanContextGrid;
pub use index::{ScanContextIndex, ScanContextShape};
pub use skid_keytree::{MAX_KEY_LEN, RebuildPolicy};

/// The plugin's registry name and descriptor kind.
pub const NAME: &str = "scan_context";

/// Parameters of the `scan_context` descriptor; defaults are the reference values.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct ScanContextConfig {
    /// Rings over [0, max_range_m].
    pub num_rings: usize,
    /// Sectors over 360°.
    pub num_sectors: usize,
    /// Outer edge of the last ring, in metres.
    pub max_range_m: f64,
    /// Points with a smaller horizontal range are dropped, in metres.
    pub min_range_m: f64,
    /// Added to every z so that ground points have positive heights, in metres.
    pub sensor_height_m: f64,
    /// Put points beyond max_range_m in the last ring instead of dropping them.
    pub clamp_beyond_max_range: bool,
    /// Keep a cell's negative maximum height instead of raising it to 0.
    pub keep_negative_heights: bool,
    /// Ring-key neighbours re-ranked by the full distance per query.
    pub num_candidates: usize,
    /// Fraction of the sectors searched around the sector-key pre-alignment (1 searches every shift).
    pub search_ratio: f64,
    /// Keys inserted since the last KD-tree build that are always scanned linearly before a rebuild.
    pub rebuild_min_pending: usize,
    /// Pending keys tolerated, as a fraction of all stored keys, before the KD-tree is rebuilt.
    pub rebuild_pending_fraction: f64,
}

impl Default for ScanContextConfig {
    fn default() -> Self {
        Self {
            num_rings: 20,
            num_sectors: 60,
            max_range_m: 80.0,
            min_range_m: 0.0,
            sensor_height_m: 2.0,
            clamp_beyond_max_range: false,
            keep_negative_heights: false,
            num_candidates: 10,
            search_ratio: 0.1,
            rebuild_min_pending: 32,
            rebuild_pending_fraction: 0.1,
        }
    }
}

impl ScanContextConfig {
    /// Checks the values serde cannot.
    pub fn validate(&self) -> PluginResult<()> {
        let fail = |message: String| Err(PluginError::failed(NAME, message));
        if !(1..=MAX_KEY_LEN).contains(&self.num_rings) {
            return fail(format!(
                "num_rings must be in 1..={MAX_KEY_LEN}, got {}",
                self.num_rings
            ));
        }
        if !(1..=3600).contains(&self.num_sectors) {
            return fail(format!(
                "num_sectors must be in 1..=3600, got {}",
                self.num_sectors
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
        if !self.sensor_height_m.is_finite() {
            return fail(format!(
                "sensor_height_m must be finite, got {}",
                self.sensor_height_m
            ));
        }
        if !(self.search_ratio.is_finite() && (0.0..=1.0).contains(&self.search_ratio)) {
            return fail(format!(
                "search_ratio must be in [0, 1], got {}",
                self.search_ratio
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

    /// Shifts searched on each side of the pre-alignment: round(search_ratio · num_sectors / 2).
    pub fn search_radius(&self) -> usize {
        (0.5 * self.search_ratio * self.num_sectors as f64).round() as usize
    }

    /// Bytes one descriptor takes on the wire (f32 cells).
    pub fn wire_size_bytes(&self) -> usize {
        self.num_rings * self.num_sectors * std::mem::size_of::<f32>()
    }
}

/// Registers `scan_context` in the descriptor slot.
pub fn register(registry: &mut Registry) -> Result<(), PluginError> {
    let entry = PluginEntry::new(
        NAME,
        "Scan Context (Kim & Kim, IROS 2018): max height per ring x sector; ring-key KD-tree, column-shift cosine distance",
        |config: ScanContextConfig, _context: &PluginContext| {
            Ok(Box::new(ScanContextDescriptor::from_checked(config)?) as Box<dyn Descriptor>)
        },
    )?;
    registry.descriptor.register(entry)
}

/// The plugin state: a validated config.
pub struct ScanContextDescriptor {
    config: ScanContextConfig,
}

impl ScanContextDescriptor {
    pub fn new(config: ScanContextConfig) -> PluginResult<Self> {
        config.validate()?;
        Self::from_checked(config)
    }

    /// [`ScanContextDescriptor::new`] for a configuration the registry has checked already (it is checked once, when
    /// the configuration is loaded).
    pub(crate) fn from_checked(config: ScanContextConfig) -> PluginResult<Self> {
        Ok(Self { config })
    }

    pub fn config(&self) -> &ScanContextConfig {
        &self.config
    }

    /// The grid of a cloud with what was dropped.
    pub fn grid(&self, cloud: CloudView<'_>) -> PluginResult<ScanContextGrid> {
        extract::scan_context(cloud.points(), &self.config)
    }

    /// Bytes one descriptor takes on the wire.
    pub fn wire_size_bytes(&self) -> usize {
        self.config.wire_size_bytes()
    }
}

impl Descriptor for ScanContextDescriptor {
    fn kind(&self) -> &str {
        NAME
    }

    fn describe(&mut self, cloud: CloudView<'_>) -> PluginResult<DescriptorBuf> {
        let grid = self.grid(cloud)?;
        if grid.values.iter().all(|&v| v == 0.0) {
            return Err(PluginError::InvalidInput(format!(
                "the scan context of {} points is empty: {} used, {} out of range, and no cell higher than {} m below the sensor",
                cloud.len(),
                grid.points_used,
                grid.points_out_of_range,
                self.config.sensor_height_m
            )));
        }
        Ok(DescriptorBuf {
            kind: NAME.to_owned(),
            values: grid.values,
        })
    }

    fn new_index(&self) -> Box<dyn DescriptorIndex> {
        let shape = ScanContextShape {
            num_rings: self.config.num_rings,
            num_sectors: self.config.num_sectors,
            num_candidates: self.config.num_candidates,
            search_radius: self.config.search_radius(),
        };
        let policy = RebuildPolicy {
            min_pending: self.config.rebuild_min_pending,
            pending_fraction: self.config.rebuild_pending_fraction,
        };
        Box::new(ScanContextIndex::new(shape, policy))
    }
}
