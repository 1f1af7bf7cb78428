//! SKiD LiDAR-inertial odometry: the `lio` plugin of the odometry slot, a tightly coupled iterated
//! error-state Kalman filter on the manifold in the FAST-LIO2 formulation (Xu et al., "FAST-LIO2: Fast
//! Direct LiDAR-Inertial Odometry", T-RO 2022), written from the paper (FAST-LIO2's code is GPL and was
//! not used), with a voxel-hashed plane map in the manner of Faster-LIO's iVox (Bai et al., RA-L 2022).
//!
//! - [`state`]: the state (attitude, position, velocity, gyro and accelerometer biases, gravity) and its
//!   18-dimensional error state;
//! - [`propagate`]: IMU forward propagation of the state and covariance, and constant-velocity coasting
//!   across IMU gaps;
//! - [`plane_map`]: the voxel-hashed map, nearest neighbours and plane fits;
//! - [`update`]: the iterated update with point-to-plane residuals and the degeneracy test;
//! - [`LioOdometry`]: static initialisation, deskewing, the filter per scan, keyframes.

pub mod config;
mod odometry;
pub mod plane_map;
pub mod propagate;
pub mod state;
pub mod update;

pub use config::LioConfig;
pub use odometry::{LioCounters, LioOdometry, MIN_SCAN_POINTS};

use skid_core::slots::Odometry;
use skid_core::{PluginContext, PluginEntry, PluginError, Registry};

/// Registers `lio` in the odometry slot.
pub fn register(registry: &mut Registry) -> Result<(), PluginError> {
    let entry = PluginEntry::new(
        "lio",
        "LiDAR-inertial odometry: iterated error-state Kalman filter (FAST-LIO2 formulation), IMU propagation and deskewing, point-to-plane updates on a voxel-hashed map",
        |config: LioConfig, context: &PluginContext| {
            Ok(Box::new(LioOdometry::from_checked(config, context)?) as Box<dyn Odometry>)
        },
    )?;
    registry.odometry.register(entry)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn conformance() {
        // The conformance scenes carry no IMU: the filter runs LiDAR-only on its constant-velocity model.
        skid_testkit::odometry::check_odometry(
            || Box::new(LioOdometry::new(LioConfig::default(), &PluginContext::default()).unwrap()),
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
