//! An example out-of-tree SKiD plugin, loaded by the host as a `cdylib` through skid-abi's C ABI.
//!
//! It provides `ring_histogram`, a simple global place descriptor: the keyframe cloud is cut into
//! concentric rings of horizontal range around the sensor and into height bands, and the descriptor is
//! the fraction of points in each (ring, band) cell, ring-major. Horizontal range and height do not
//! change when the sensor turns about its vertical axis, so the descriptor is invariant to yaw; it
//! keeps no angular information at all, which makes it cheap and coarse. It brings its own retrieval
//! index (module [`chi_squared`]): the chi-squared distance between histograms rather than L2.
//!
//! It also provides `kitti_cdylib` (module [`kitti`]), `kiss_icp_cdylib` (module [`kiss`]),
//! `gicp_cdylib` (module [`gicp`]), `pcm_cdylib` (module [`pcm`]) and `pgo_cdylib` (module [`pgo`]): the
//! built-in KITTI source, KISS-ICP odometry, GICP fine registration, PCM verifier and pose-graph back-end
//! behind the C ABI, so that one library shows every slot of Rust plugin and the boundary's cost can be
//! measured against the same code built in.
//!
//! The crate contains no `unsafe` code: it implements the slot traits of [`skid_abi`] and lets
//! [`skid_abi::export_plugins!`] generate the C side.

pub mod chi_squared;
pub mod gicp;
pub mod kiss;
pub mod kitti;
pub mod pcm;
pub mod pgo;

use serde::Deserialize;
use skid_abi::{ConfigError, DescriptorPlugin, IndexPlugin, InstanceContext, parse_config};
use skid_core::{PluginContext, RobotId};
use skid_msgs::Point;

/// The built-in plugins' context for the instance context a wrapped built-in is created with.
pub(crate) fn plugin_context(context: &InstanceContext) -> PluginContext {
    PluginContext {
        robot: RobotId(context.robot),
        fleet_size: context.fleet_size,
        threads: context.threads,
        seed: context.seed,
        output_dir: context.output_dir.as_ref().map(Into::into),
        // The source's IMU does not cross the ABI: a wrapped built-in is told there is none.
        ..PluginContext::default()
    }
}

/// Parameters of the ring histogram. Unknown keys are refused; missing keys take these defaults.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct Config {
    /// Number of range rings between `min_range_m` and `max_range_m`.
    pub num_rings: usize,
    /// Number of height bands between `min_z_m` and `max_z_m`.
    pub num_bands: usize,
    /// Points nearer than this horizontal range (the vehicle itself) are ignored, in metres.
    pub min_range_m: f32,
    /// Points farther than this horizontal range are ignored, in metres.
    pub max_range_m: f32,
    /// Lowest height counted, in the sensor frame, in metres.
    pub min_z_m: f32,
    /// Highest height counted, in the sensor frame, in metres.
    pub max_z_m: f32,
}

impl Default for Config {
    fn default() -> Self {
        Self {
            num_rings: 20,
            num_bands: 8,
            min_range_m: 2.0,
            max_range_m: 80.0,
            min_z_m: -3.0,
            max_z_m: 5.0,
        }
    }
}

/// The default config as TOML, as declared to the host; a unit test keeps it equal to `Config::default()`.
const DEFAULT_CONFIG: &str = "num_rings = 20
num_bands = 8
min_range_m = 2.0
max_range_m = 80.0
min_z_m = -3.0
max_z_m = 5.0
";

impl Config {
    /// Checks the values serde cannot: counts at least 1, ranges finite and ordered.
    fn validate(&self) -> Result<(), ConfigError> {
        for (key, count) in [("num_rings", self.num_rings), ("num_bands", self.num_bands)] {
            if !(1..=1024).contains(&count) {
                return Err(ConfigError::for_key(
                    key,
                    format!("must be between 1 and 1024, got {count}"),
                ));
            }
        }
        let finite = [self.min_range_m, self.max_range_m, self.min_z_m, self.max_z_m]
            .iter()
            .all(|v| v.is_finite());
        if !finite {
            return Err("every range and height must be finite".into());
        }
        if !(0.0 <= self.min_range_m && self.min_range_m < self.max_range_m) {
            return Err(ConfigError::for_key(
                "max_range_m",
                format!(
                    "need 0 <= min_range_m < max_range_m, got {} and {}",
                    self.min_range_m, self.max_range_m
                ),
            ));
        }
        if self.min_z_m >= self.max_z_m {
            return Err(ConfigError::for_key(
                "max_z_m",
                format!(
                    "need min_z_m < max_z_m, got {} and {}",
                    self.min_z_m, self.max_z_m
                ),
            ));
        }
        Ok(())
    }
}

/// The ring histogram descriptor.
#[derive(Clone, Debug)]
pub struct RingHistogram {
    config: Config,
}

impl RingHistogram {
    /// The (ring, band) cell of a point, or `None` when it falls outside the counted volume.
    fn cell(&self, point: &Point) -> Option<usize> {
        let c = &self.config;
        if !point.is_finite() {
            return None;
        }
        let range = (point.x * point.x + point.y * point.y).sqrt();
        if range < c.min_range_m || range >= c.max_range_m || point.z < c.min_z_m || point.z >= c.max_z_m {
            return None;
        }
        let ring = ((range - c.min_range_m) / (c.max_range_m - c.min_range_m) * c.num_rings as f32) as usize;
        let band = ((point.z - c.min_z_m) / (c.max_z_m - c.min_z_m) * c.num_bands as f32) as usize;
        // Rounding at the upper edges can land one past the last cell: clamp.
        Some(ring.min(c.num_rings - 1) * c.num_bands + band.min(c.num_bands - 1))
    }
}

impl DescriptorPlugin for RingHistogram {
    const NAME: &'static str = "ring_histogram";
    const SUMMARY: &'static str =
        "Yaw-invariant fraction of points per (range ring, height band) cell (example cdylib)";
    const DEFAULT_CONFIG: &'static str = DEFAULT_CONFIG;

    fn from_config(config: &str, context: &InstanceContext) -> Result<Self, ConfigError> {
        let config: Config = parse_config(config)?;
        config.validate()?;
        tracing::info!(
            rings = config.num_rings,
            bands = config.num_bands,
            robot = context.robot,
            "ring histogram ready"
        );
        Ok(Self { config })
    }

    fn descriptor_len(&self) -> usize {
        self.config.num_rings * self.config.num_bands
    }

    fn describe(&mut self, points: &[Point], out: &mut [f32]) -> Result<(), String> {
        out.fill(0.0);
        let mut counted = 0_usize;
        for cell in points.iter().filter_map(|point| self.cell(point)) {
            out[cell] += 1.0;
            counted += 1;
        }
        if counted == 0 {
            return Err(format!(
                "none of the {} points lies within {}..{} m range and {}..{} m height",
                points.len(),
                self.config.min_range_m,
                self.config.max_range_m,
                self.config.min_z_m,
                self.config.max_z_m
            ));
        }
        let scale = 1.0 / counted as f32;
        out.iter_mut().for_each(|value| *value *= scale);
        tracing::debug!(points = points.len(), counted, "described a cloud");
        Ok(())
    }

    fn new_index(&self) -> Option<Box<dyn IndexPlugin>> {
        Some(Box::new(chi_squared::ChiSquaredIndex::new(self.descriptor_len())))
    }
}

skid_abi::export_plugins!(
    source: kitti::KittiCdylib,
    odometry: kiss::KissIcpCdylib,
    descriptor: RingHistogram,
    fine: gicp::GicpCdylib,
    verifier: pcm::PcmCdylib,
    backend: pgo::PgoCdylib,
);

#[cfg(test)]
mod tests {
    use super::*;

    fn histogram(config: &str) -> RingHistogram {
        RingHistogram::from_config(config, &InstanceContext::default()).unwrap()
    }

    #[test]
    fn default_config_text_matches_the_default() {
        assert_eq!(parse_config::<Config>(DEFAULT_CONFIG).unwrap(), Config::default());
    }

    #[test]
    fn counts_fractions_per_cell_and_turns_without_change() {
        let mut plugin = histogram(
            "num_rings = 2\nnum_bands = 2\nmin_range_m = 0.0\nmax_range_m = 10.0\nmin_z_m = 0.0\nmax_z_m = 2.0",
        );
        let points = [
            Point::new(1.0, 0.0, 0.5),
            Point::new(0.0, 6.0, 1.5),
            Point::new(-7.0, 0.0, 1.5),
            Point::new(20.0, 0.0, 1.0),
        ];
        let mut out = vec![0.0; plugin.descriptor_len()];
        plugin.describe(&points, &mut out).unwrap();
        assert_eq!(out, [1.0 / 3.0, 0.0, 0.0, 2.0 / 3.0]);
        let turned: Vec<Point> = points.iter().map(|p| Point::new(-p.y, p.x, p.z)).collect();
        let mut turned_out = vec![0.0; plugin.descriptor_len()];
        plugin.describe(&turned, &mut turned_out).unwrap();
        assert_eq!(out, turned_out);
    }

    #[test]
    fn bad_configs_name_the_key() {
        let error = RingHistogram::from_config("num_ringz = 3", &InstanceContext::default()).unwrap_err();
        assert_eq!(error.key, "num_ringz");
        let error = RingHistogram::from_config("num_bands = 0", &InstanceContext::default()).unwrap_err();
        assert_eq!(error.key, "num_bands");
        let error = RingHistogram::from_config("min_z_m = 9.0", &InstanceContext::default()).unwrap_err();
        assert_eq!(error.key, "max_z_m");
    }

    #[test]
    fn an_empty_cloud_is_an_error() {
        let mut plugin = histogram("");
        let mut out = vec![0.0; plugin.descriptor_len()];
        assert!(
            plugin
                .describe(&[], &mut out)
                .unwrap_err()
                .contains("none of the 0 points")
        );
    }
}
