//! SKiD's LiDAR simulator: deterministic procedural worlds, real sensor beam patterns, robot routes
//! with exact ground truth and a 200 Hz IMU, the `sim` source plugin, KITTI export and PNG previews.
//!
//! - [`World`]: `planetary`, `cave` and `urban` worlds from a seed; terrain as a height field with a
//!   min/max mip-map, objects and caves as triangles in a binned-SAH BVH.
//! - [`Sensor`]: VLP-16, OS1-32, OS1-64, HDL-64E and a Livox-Avia-like non-repetitive solid-state model.
//! - [`Trajectory`], [`plan_route`] and [`plan_mission`]: routes for 1–16 robots — named missions in
//!   which robots start apart, explore and meet (crossing, reverse traverse, rendezvous, partial
//!   overlap, never), or the patterns around one shared route; ground and aerial motion profiles.
//! - [`SimSource`]: scans with per-point time offsets (motion distortion), noise, dropouts, spurious
//!   returns, IMU samples and ground truth; [`register`] adds it to a registry as the `sim` source.
//! - [`export_kitti`] and [`preview_png`]: files for other tools and for eyes.

pub mod bodies;
pub mod bvh;
mod error;
pub mod geometry;
pub mod heightfield;
pub mod noise;
pub mod rng;
pub mod world;

pub use error::SimError;
pub use world::{Hit, Material, RoadGraph, World, WorldKind};
pub mod gait;
pub mod imu;
pub mod mission;
pub mod motion;
pub mod route;
pub mod scan;
pub mod sensor;
pub mod sensor_errors;
mod source;
pub mod trajectory;

pub use bodies::{Body, BodyShape, Peers};
pub use gait::Profile;
pub use imu::{ImuNoise, ImuSimulator};
pub use mission::{CONVOY_GAP_M, Mission, plan_mission, plan_wander};
pub use motion::MotionSpec;
pub use route::{Overlap, Route, plan_route};
pub use scan::{ScanNoise, simulate_sweep, simulate_sweep_among};
pub use sensor::{SENSOR_NAMES, Sensor};
pub use source::{MAX_ROBOTS, NoiseModel, SimConfig, SimSource, register};
pub use trajectory::Trajectory;
mod export;
mod preview;

pub use export::{ExportSummary, export_fleet_kitti, export_kitti};
pub use preview::{preview_fleet_png, preview_png};
