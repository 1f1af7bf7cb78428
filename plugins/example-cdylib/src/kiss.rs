//! `kiss_icp_cdylib`: SKiD's own KISS-ICP odometry (`skid-odometry-kiss`) exported through the C ABI's
//! odometry slot, the second Rust example beside the descriptor. The scan arrives borrowed and is copied
//! once into the `Scan` the built-in takes; the keyframe cloud goes back lent, not copied.

use skid_abi::transform::{abi_from_pose, pose_from_abi};
use skid_abi::{ConfigError, InstanceContext, OdometryOutcome, OdometryPlugin, ScanView, parse_config};
use skid_core::slots::Odometry;
use skid_core::{RobotId, Scan};
use skid_odometry_kiss::{KissIcpConfig, KissIcpOdometry};

/// The built-in KISS-ICP's defaults as TOML; a unit test keeps them equal to `KissIcpConfig::default()`.
const DEFAULT_CONFIG: &str = include_str!("kiss_defaults.toml");

/// The built-in KISS-ICP behind the C ABI.
pub struct KissIcpCdylib {
    inner: KissIcpOdometry,
}

impl OdometryPlugin for KissIcpCdylib {
    const NAME: &'static str = "kiss_icp_cdylib";
    const SUMMARY: &'static str = "The built-in KISS-ICP odometry loaded through the C ABI (example cdylib)";
    const DEFAULT_CONFIG: &'static str = DEFAULT_CONFIG;

    fn from_config(config: &str, context: &InstanceContext) -> Result<Self, ConfigError> {
        let config: KissIcpConfig = parse_config(config)?;
        let context = crate::plugin_context(context);
        let inner =
            KissIcpOdometry::new(config, &context).map_err(|error| ConfigError::from(error.to_string()))?;
        Ok(Self { inner })
    }

    fn register(&mut self, scan: &ScanView<'_>) -> Result<OdometryOutcome, String> {
        let transform = |value: Option<skid_abi::AbiTransform>| value.as_ref().map(pose_from_abi).transpose();
        let scan = Scan {
            robot: RobotId(scan.robot),
            sequence: scan.sequence,
            stamp_nanos: scan.stamp_nanos,
            points: scan.points.to_vec(),
            imu: scan.imu.to_vec(),
            ground_truth_world_from_sensor: transform(scan.ground_truth_world_from_sensor)?,
            imu_from_sensor: transform(scan.imu_from_sensor)?,
        };
        let update = self.inner.register(&scan).map_err(|error| error.to_string())?;
        Ok(OdometryOutcome {
            stamp_nanos: update.stamp_nanos,
            world_from_sensor: abi_from_pose(&update.world_from_sensor),
            previous_from_current: abi_from_pose(&update.previous_from_current),
            keyframe: update.keyframe.map(|keyframe| keyframe.cloud.points),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_config_text_matches_the_built_in_defaults() {
        assert_eq!(
            parse_config::<KissIcpConfig>(DEFAULT_CONFIG).unwrap(),
            KissIcpConfig::default()
        );
    }
}
