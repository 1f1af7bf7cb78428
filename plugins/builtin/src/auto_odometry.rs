//! The `auto` odometry, the default profile's: LiDAR-inertial odometry (`lio`, the SKiD-SLAM paper's
//! front-end, Fig. 2a) when the robot's source delivers IMU samples, and LiDAR-only KISS-ICP
//! (`kiss_icp`) when it does not. The choice is made once per robot, when the plugins are built, from
//! [`Source::provides_imu`](skid_core::slots::Source::provides_imu); each candidate keeps its own parameter
//! table (`[odometry.lio]`, `[odometry.kiss_icp]`), which the configuration hands to `auto` whole.

use serde::{Deserialize, Serialize};
use skid_core::{
    ParamError, PluginContext, PluginEntry, PluginError, PluginParams, Registry, slots::Odometry,
};
use skid_odometry_kiss::{KissIcpConfig, KissIcpOdometry};
use skid_odometry_lio::{LioConfig, LioOdometry};

/// The two candidates' parameters, as set in their own tables.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct AutoOdometryConfig {
    /// Parameters of `lio`, used when the source provides an IMU (set them in `[odometry.lio]`).
    pub lio: LioConfig,
    /// Parameters of `kiss_icp`, used when it does not (set them in `[odometry.kiss_icp]`).
    pub kiss_icp: KissIcpConfig,
}

impl PluginParams for AutoOdometryConfig {
    fn check(&self) -> Result<(), ParamError> {
        let inside = |candidate: &str, error: ParamError| {
            ParamError::at(format!("{candidate}.{}", error.path), error.message)
        };
        self.lio.check().map_err(|error| inside("lio", error))?;
        self.kiss_icp.check().map_err(|error| inside("kiss_icp", error))
    }
}

/// Builds the odometry `auto` chooses for this robot.
pub fn build(config: AutoOdometryConfig, context: &PluginContext) -> Result<Box<dyn Odometry>, PluginError> {
    if context.source_provides_imu {
        tracing::info!(
            robot = context.robot.0,
            "odometry auto: the source provides an IMU, running lio"
        );
        Ok(Box::new(LioOdometry::new(config.lio, context)?))
    } else {
        tracing::info!(
            robot = context.robot.0,
            "odometry auto: the source has no IMU, running kiss_icp"
        );
        Ok(Box::new(KissIcpOdometry::new(config.kiss_icp, context)?))
    }
}

/// Adds the `auto` odometry to `registry`.
pub fn register(registry: &mut Registry) -> Result<(), PluginError> {
    let entry = PluginEntry::new(
        "auto",
        "lio when the source provides an IMU, kiss_icp otherwise (each with its own [odometry.lio] / [odometry.kiss_icp] table)",
        build,
    )?;
    registry.odometry.register(entry)
}
