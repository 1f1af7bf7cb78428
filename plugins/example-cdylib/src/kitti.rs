//! `kitti_cdylib`: SKiD's own KITTI folder reader (`skid-source-files`) exported through the C ABI's
//! source slot. Each scan goes to the host lent, not copied, until the host asks for the next one.

use skid_abi::transform::abi_from_pose;
use skid_abi::{ConfigError, InstanceContext, OwnedScan, SourcePlugin, parse_config};
use skid_core::slots::Source;
use skid_source_files::{KittiConfig, KittiSource};

/// The built-in source's defaults as TOML; a unit test keeps them equal to `KittiConfig::default()`.
const DEFAULT_CONFIG: &str = include_str!("kitti_defaults.toml");

/// The built-in KITTI source behind the C ABI.
pub struct KittiCdylib {
    inner: KittiSource,
}

impl SourcePlugin for KittiCdylib {
    const NAME: &'static str = "kitti_cdylib";
    const SUMMARY: &'static str =
        "The built-in KITTI folder source loaded through the C ABI (example cdylib)";
    const DEFAULT_CONFIG: &'static str = DEFAULT_CONFIG;

    fn from_config(config: &str, context: &InstanceContext) -> Result<Self, ConfigError> {
        let config: KittiConfig = parse_config(config)?;
        let context = crate::plugin_context(context);
        let inner =
            KittiSource::open(config, &context).map_err(|error| ConfigError::from(error.to_string()))?;
        Ok(Self { inner })
    }

    fn next_scan(&mut self) -> Result<Option<OwnedScan>, String> {
        let Some(scan) = self.inner.next_scan().map_err(|error| error.to_string())? else {
            return Ok(None);
        };
        Ok(Some(OwnedScan {
            robot: scan.robot.0,
            sequence: scan.sequence,
            stamp_nanos: scan.stamp_nanos,
            points: scan.points,
            imu: scan.imu,
            ground_truth_world_from_sensor: scan.ground_truth_world_from_sensor.as_ref().map(abi_from_pose),
            imu_from_sensor: scan.imu_from_sensor.as_ref().map(abi_from_pose),
        }))
    }

    fn provides_imu(&self) -> bool {
        self.inner.provides_imu()
    }

    fn remaining_hint(&self) -> Option<usize> {
        self.inner.remaining_hint()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_config_text_matches_the_built_in_defaults() {
        assert_eq!(
            parse_config::<KittiConfig>(DEFAULT_CONFIG).unwrap(),
            KittiConfig::default()
        );
    }
}
