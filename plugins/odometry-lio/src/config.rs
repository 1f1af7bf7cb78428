//! Parameters of the `lio` odometry (`[odometry.lio]`). The noise values and the map resolution are
//! FAST-LIO2's defaults (Xu et al., "FAST-LIO2: Fast Direct LiDAR-Inertial Odometry", T-RO 2022, and its
//! released configuration: `acc_cov = gyr_cov = 0.1`, `b_acc_cov = b_gyr_cov = 1e-4`, a point
//! measurement variance of 0.001 m², 0.5 m map and scan filters, 5 neighbours per plane, at most 4
//! iterations); the rest are SKiD's.

use serde::{Deserialize, Serialize};
use skid_core::ParamError;
use skid_core::registry::check::{count_within, non_negative, positive, within};
use skid_geometry::KeyframePolicy;

/// Parameters of the `lio` odometry.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct LioConfig {
    /// Gyroscope measurement noise variance per sample, (rad/s)², as FAST-LIO2's `gyr_cov`.
    pub gyro_variance: f64,
    /// Accelerometer measurement noise variance per sample, (m/s²)², as FAST-LIO2's `acc_cov`.
    pub accel_variance: f64,
    /// Gyroscope bias random-walk variance per sample, as FAST-LIO2's `b_gyr_cov`.
    pub gyro_bias_variance: f64,
    /// Accelerometer bias random-walk variance per sample, as FAST-LIO2's `b_acc_cov`.
    pub accel_bias_variance: f64,
    /// Variance of a point's distance to its plane, m² (FAST-LIO2's `LASER_POINT_COV`).
    pub point_variance_m2: f64,
    /// Edge of the map's voxels and of the scan filter, in metres.
    pub map_voxel_m: f64,
    /// Most points a map voxel keeps.
    pub max_points_per_voxel: usize,
    /// Neighbours a plane is fitted to.
    pub plane_neighbours: usize,
    /// A plane is used only when every neighbour lies within this of it, in metres.
    pub max_plane_distance_m: f64,
    /// Most iterations of the iterated update per scan.
    pub max_iterations: usize,
    /// Points closer than this to the sensor are dropped (the robot itself), in metres.
    pub min_range_m: f64,
    /// Points farther than this are dropped, and map voxels farther than this from the robot removed.
    pub max_range_m: f64,
    /// Seconds of IMU data averaged at the start for gravity and the gyro bias (the robot at rest or at
    /// constant velocity; the LiDAR follows it meanwhile).
    pub init_duration_s: f64,
    /// IMU silence longer than this (seconds) is a gap bridged by the constant-velocity model.
    pub max_imu_gap_s: f64,
    /// A direction is degenerate when its eigenvalue of the point-to-plane information is below this
    /// fraction of the largest of its block (rotation or translation, each with the other marginalised);
    /// the filter then leans on the IMU in that direction. Measured translation ratios: the planetary
    /// world's smooth ground 0.01-0.04, the cave 0.08-0.18, the urban world 0.18-0.87, KITTI 00 0.22-0.44.
    pub degeneracy_ratio: f64,
    /// The LiDAR's pose in the IMU frame as `[x, y, z, roll, pitch, yaw]` (metres, degrees), used when
    /// the source gives none (a bag without `/tf_static`); `None` takes the source's, else identity.
    pub imu_from_sensor: Option<[f64; 6]>,
    /// Voxel size of keyframe clouds, in metres; 0 keeps every point.
    pub keyframe_voxel_m: f64,
    pub keyframe: KeyframePolicy,
}

impl Default for LioConfig {
    fn default() -> Self {
        Self {
            gyro_variance: 0.1,
            accel_variance: 0.1,
            gyro_bias_variance: 1e-4,
            accel_bias_variance: 1e-4,
            point_variance_m2: 0.001,
            map_voxel_m: 0.5,
            max_points_per_voxel: 10,
            plane_neighbours: 5,
            max_plane_distance_m: 0.1,
            max_iterations: 4,
            min_range_m: 1.0,
            max_range_m: 100.0,
            init_duration_s: 0.5,
            max_imu_gap_s: 0.05,
            degeneracy_ratio: 0.05,
            imu_from_sensor: None,
            keyframe_voxel_m: 0.25,
            keyframe: KeyframePolicy::default(),
        }
    }
}

impl skid_core::PluginParams for LioConfig {
    fn check(&self) -> Result<(), ParamError> {
        positive("gyro_variance", self.gyro_variance)?;
        positive("accel_variance", self.accel_variance)?;
        positive("gyro_bias_variance", self.gyro_bias_variance)?;
        positive("accel_bias_variance", self.accel_bias_variance)?;
        positive("point_variance_m2", self.point_variance_m2)?;
        within("map_voxel_m", self.map_voxel_m, 0.05, 10.0)?;
        count_within("max_points_per_voxel", self.max_points_per_voxel, 3, 1000)?;
        count_within("plane_neighbours", self.plane_neighbours, 3, 50)?;
        positive("max_plane_distance_m", self.max_plane_distance_m)?;
        count_within("max_iterations", self.max_iterations, 1, 100)?;
        non_negative("min_range_m", self.min_range_m)?;
        positive("max_range_m", self.max_range_m)?;
        if self.min_range_m >= self.max_range_m {
            return Err(ParamError::at(
                "min_range_m",
                format!(
                    "{} must be below max_range_m = {}",
                    self.min_range_m, self.max_range_m
                ),
            ));
        }
        within("init_duration_s", self.init_duration_s, 0.0, 10.0)?;
        positive("max_imu_gap_s", self.max_imu_gap_s)?;
        within("degeneracy_ratio", self.degeneracy_ratio, 0.0, 1.0)?;
        if let Some(values) = self.imu_from_sensor
            && values.iter().any(|v| !v.is_finite())
        {
            return Err(ParamError::at("imu_from_sensor", "every value must be finite"));
        }
        non_negative("keyframe_voxel_m", self.keyframe_voxel_m)?;
        self.keyframe.check()
    }
}
