//! Conformance suites for the plugin slots. Every implementation of a slot instantiates its slot's suite
//! in one line from its own tests, so every plugin is held to the same contract:
//!
//! | slot | suite | what it checks |
//! |---|---|---|
//! | source | [`source::check_source`] | scans in order, stamps non-decreasing, finite points, a clean end |
//! | odometry | [`odometry::check_odometry`] | recovers a known synthetic motion; bad scans are errors, not panics |
//! | descriptor | [`descriptor::check_descriptor`] | yaw invariance, zero self-distance, yaw hint within a sector, no NaN |
//! | coarse | [`registration::check_coarse`] | recovers a large unknown transform; tiny input reports invalid |
//! | fine | [`registration::check_fine`] | recovers a perturbed transform; degenerate input is not converged |
//! | verifier | [`verifier::check_verifier`] | rejects one inconsistent loop among consistent ones |
//! | back-end | [`backend::check_backend`] | closes a loop; removing it restores the odometry solution |
//! | transport | [`transport::check_transport`] | a message round-trips to one peer and to all peers |
//!
//! Tests that load a plugin library find it with [`cdylib::dev_dependency_library`]; tests that open
//! network endpoints take their ports from [`net::free_tcp_ports`].
//!
//! For the slots that carry the heavy computation (descriptor, coarse, fine), [`threads`] checks that
//! two instances running on two threads at once give what each gives alone.
//!
//! The synthetic data comes from [`scene`]: a deterministic outdoor-like scene sampled anew for every
//! scan, so no two scans share points.

// This crate is test support: its functions are assertions, and failing loudly is their job.
#![allow(clippy::expect_used, clippy::panic)]

pub mod backend;
pub mod cdylib;
pub mod descriptor;
pub mod net;
pub mod odometry;
pub mod registration;
pub mod scene;
pub mod source;
pub mod threads;
pub mod transport;
pub mod verifier;

use skid_core::Pose;

/// Translation (metres) and rotation (degrees) between two poses.
pub fn pose_error(a: &Pose, b: &Pose) -> (f64, f64) {
    let delta = a.inverse() * b;
    (
        delta.translation.vector.norm(),
        delta.rotation.angle().to_degrees(),
    )
}
