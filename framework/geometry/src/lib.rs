//! Geometry that several plugins share: voxel downsampling, motion deskewing and the keyframe policy.
//!
//! Kept apart from `skid-core` so the core stays a vocabulary crate and these algorithms can grow
//! (kd-tree wrappers, covariance estimation, Umeyama) without touching every plugin's dependencies.

pub mod chain;
pub mod deskew;
pub mod keyframe;
pub mod voxel;

pub use chain::{OdometryChains, adjoint};
pub use deskew::deskew_constant_velocity;
pub use keyframe::{KeyframePolicy, KeyframeTrigger};
pub use voxel::voxel_downsample;
