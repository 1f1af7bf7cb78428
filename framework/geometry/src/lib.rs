//! Geometry that several plugins share: voxel downsampling, motion deskewing, the keyframe policy and
//! the degeneracy test of a registration.
//!
//! Kept apart from `skid-core` so the core stays a vocabulary crate and these algorithms can grow
//! (kd-tree wrappers, covariance estimation, Umeyama) without touching every plugin's dependencies.

pub mod chain;
pub mod degeneracy;
pub mod deskew;
pub mod keyframe;
pub mod voxel;

pub use chain::{OdometryChains, adjoint};
pub use degeneracy::{BlockSpectrum, marginal_spectra};
pub use deskew::deskew_constant_velocity;
pub use keyframe::{KeyframePolicy, KeyframeTrigger};
pub use voxel::{voxel_centroids, voxel_downsample};
