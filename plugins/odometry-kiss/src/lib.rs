//! SKiD KISS-ICP-style LiDAR odometry (Vizzo et al., "KISS-ICP: In Defense of Point-to-Point ICP",
//! RA-L 2023) with keyframing: the `kiss_icp` plugin of the odometry slot.
//!
//! - [`KissIcpOdometry`]: deskewing with the constant-velocity model, voxel downsampling (0.5 v into the
//!   map, 1.5 v for registration), the [`VoxelHashMap`] local map, the [`AdaptiveThreshold`], robust
//!   point-to-point Gauss-Newton ([`icp`]) with a deterministic parallel correspondence search, and
//!   keyframes (deskewed, voxel-downsampled sensor-frame clouds with `world_from_sensor`).
//! - [`KissIcpConfig`]: every parameter, defaulting to the reference values.
//! - [`run_sequence`] and [`evaluation`]: running any odometry alone over a source, with timing, ATE and
//!   drift, for `skid odometry`.

pub mod config;
pub mod degeneracy;
pub mod evaluation;
pub mod icp;
mod odometry;
pub mod parallel;
pub mod run;
pub mod threshold;
pub mod voxel_map;

pub use config::KissIcpConfig;
pub use evaluation::{TrajectoryErrors, trajectory_errors, umeyama_rigid};
pub use odometry::{KissIcpOdometry, MIN_SCAN_POINTS};
pub use run::{RunSummary, SequenceRun, run_sequence};
pub use threshold::AdaptiveThreshold;
pub use voxel_map::VoxelHashMap;

use skid_core::slots::Odometry;
use skid_core::{PluginContext, PluginEntry, PluginError, Registry};

/// Registers `kiss_icp` in the odometry slot.
pub fn register(registry: &mut Registry) -> Result<(), PluginError> {
    let entry = PluginEntry::new(
        "kiss_icp",
        "KISS-ICP LiDAR odometry: deskewing, voxel-hash local map, adaptive threshold, robust point-to-point ICP",
        |config: KissIcpConfig, context: &PluginContext| {
            Ok(Box::new(KissIcpOdometry::from_checked(config, context)?) as Box<dyn Odometry>)
        },
    )?;
    registry.odometry.register(entry)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn conformance() {
        skid_testkit::odometry::check_odometry(
            || Box::new(KissIcpOdometry::new(KissIcpConfig::default(), &PluginContext::default()).unwrap()),
            skid_testkit::odometry::OdometryExpectations::default(),
        );
    }

    #[test]
    fn registers_under_its_name() {
        let mut registry = Registry::new();
        register(&mut registry).unwrap();
        assert!(
            register(&mut registry).is_err(),
            "a second registration is refused"
        );
    }
}
