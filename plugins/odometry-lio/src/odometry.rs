//! The `lio` odometry: a tightly coupled LiDAR-inertial iterated error-state Kalman filter in the
//! FAST-LIO2 formulation (Xu et al., T-RO 2022), with a voxel-hashed plane map (Faster-LIO's iVox).
//!
//! Per scan (stamp `t`, the start of the sweep; its IMU samples are those since the previous stamp):
//! 1. the IMU samples are checked (non-finite or non-monotonic ones are dropped, with a warning) and the
//!    state propagated through them to `t` ([`crate::propagate`]); a gap longer than `max_imu_gap_s`,
//!    or a scan without samples, is crossed at constant velocity, with a warning;
//! 2. until `init_duration_s` of samples have been seen, the robot is taken to stand still: their mean
//!    gives the gyroscope bias and gravity (static initialisation, as FAST-LIO2 does);
//! 3. each point is moved to the sensor frame at `t` by the motion the filter predicts over its time
//!    offset. The sweep's own IMU samples arrive with the next scan, so that motion is the latest
//!    bias-corrected angular rate and acceleration held over the sweep (FAST-LIO2 integrates the
//!    samples inside the sweep backwards instead; its scans come after their IMU data);
//! 4. the iterated update against the map ([`crate::update`]), with degeneracy reported;
//! 5. the scan enters the map, and keyframes come out as from `kiss_icp`: the deskewed, voxel-downsampled
//!    cloud in the sensor frame at `t` with `world_from_sensor`.
//!
//! The odometry's world frame is the first scan's sensor frame, as for every odometry in SKiD. Without
//! any IMU (a source without one) the filter runs on a constant-velocity model with a wide process noise,
//! so the LiDAR carries the estimate.

use nalgebra::{Point3, UnitQuaternion, Vector3};
use skid_core::slots::{Odometry, OdometryUpdate};
use skid_core::{ImuSample, PluginContext, PluginError, PluginResult, Point, Pose, RobotId, Scan};
use skid_geometry::{KeyframeTrigger, voxel_downsample};

use crate::config::LioConfig;
use crate::plane_map::PlaneMap;
use crate::propagate::ProcessNoise;
use crate::state::{BA, BG, Covariance, GRAV, POS, ROT, State, VEL};
use crate::update::{UpdateOutcome, UpdateSettings, iterated_update};

mod motion;

/// Fewest finite points a scan must have to be used.
pub const MIN_SCAN_POINTS: usize = 10;

/// Accelerations (m/s²) and angular-rate changes (rad/s per s) the constant-velocity model leaves open.
const COAST_ACCEL_SIGMA_MPS2: f64 = 2.0;
const COAST_GYRO_SIGMA_RADPS: f64 = 1.0;

/// Counters of what the filter met, for summaries and tests.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct LioCounters {
    pub scans: u64,
    /// Scans whose update found a direction the planes barely constrain.
    pub degenerate_scans: u64,
    /// Scans crossed without IMU samples (no IMU, or a gap).
    pub imu_gaps: u64,
    /// IMU samples dropped: not finite, or not after the previous one.
    pub bad_imu_samples: u64,
    /// Scans whose update found no plane (the prediction stood).
    pub unconstrained_scans: u64,
}

/// Velocity variance (m²/s²) when the initialisation ends with the robot already moving: two scan
/// registrations 0.1 s apart give the velocity to a few tenths of a metre per second.
const INITIAL_MOVING_VELOCITY_VARIANCE: f64 = 0.1;

/// The static initialisation's running sums.
#[derive(Clone, Debug, Default)]
struct StaticInit {
    samples: usize,
    first_nanos: Option<u64>,
    last_nanos: u64,
    gyro_sum: Vector3<f64>,
    accel_sum: Vector3<f64>,
}

/// The estimator's state between scans.
pub struct LioOdometry {
    config: LioConfig,
    robot: RobotId,
    pool: Option<rayon::ThreadPool>,
    noise: ProcessNoise,
    map: PlaneMap,
    trigger: KeyframeTrigger,
    state: State,
    covariance: Covariance,
    /// The time of `state`, and the last accepted IMU sample.
    state_nanos: Option<u64>,
    last_sample: Option<ImuSample>,
    init: StaticInit,
    initialised: bool,
    imu_from_sensor: Option<Pose>,
    /// The last scans' sensor poses, for the constant-velocity model without IMU.
    last_world_from_sensor: Option<(u64, Pose)>,
    previous_world_from_sensor: Option<(u64, Pose)>,
    counters: LioCounters,
    last_update: Option<UpdateOutcome>,
}

impl std::fmt::Debug for LioOdometry {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LioOdometry")
            .field("robot", &self.robot)
            .field("map_points", &self.map.point_count())
            .field("state", &self.state)
            .field("counters", &self.counters)
            .finish()
    }
}

fn initial_covariance() -> Covariance {
    let mut covariance = Covariance::zeros();
    for (start, variance) in [
        (ROT, 1e-6),
        (POS, 1e-6),
        (VEL, 1e-2),
        (BG, 1e-4),
        (BA, 1e-2),
        (GRAV, 1e-4),
    ] {
        for i in start..start + 3 {
            covariance[(i, i)] = variance;
        }
    }
    covariance
}

fn pose_from_config(values: &[f64; 6]) -> Pose {
    let [x, y, z, roll, pitch, yaw] = *values;
    Pose::from_parts(
        nalgebra::Translation3::new(x, y, z),
        UnitQuaternion::from_euler_angles(roll.to_radians(), pitch.to_radians(), yaw.to_radians()),
    )
}

fn sample_is_finite(sample: &ImuSample) -> bool {
    sample
        .accel_mps2
        .iter()
        .chain(&sample.gyro_radps)
        .all(|v| v.is_finite())
}

impl LioOdometry {
    /// A fresh filter; the world frame will be the first scan's sensor frame.
    pub fn new(config: LioConfig, context: &PluginContext) -> PluginResult<Self> {
        skid_core::PluginParams::check(&config).map_err(PluginError::Params)?;
        Self::from_checked(config, context)
    }

    /// [`LioOdometry::new`] for a configuration the registry has checked already (it is checked once, when
    /// the configuration is loaded).
    pub(crate) fn from_checked(config: LioConfig, context: &PluginContext) -> PluginResult<Self> {
        let pool = if context.threads > 1 {
            Some(
                rayon::ThreadPoolBuilder::new()
                    .num_threads(context.threads)
                    .thread_name(|index| format!("lio-{index}"))
                    .build()
                    .map_err(|e| PluginError::failed("lio", format!("cannot build a thread pool: {e}")))?,
            )
        } else {
            None
        };
        Ok(Self {
            noise: ProcessNoise {
                gyro_variance: config.gyro_variance,
                accel_variance: config.accel_variance,
                gyro_bias_variance: config.gyro_bias_variance,
                accel_bias_variance: config.accel_bias_variance,
            },
            map: PlaneMap::new(config.map_voxel_m, config.max_points_per_voxel),
            trigger: KeyframeTrigger::new(config.keyframe.clone()),
            robot: context.robot,
            pool,
            state: State::default(),
            covariance: initial_covariance(),
            state_nanos: None,
            last_sample: None,
            init: StaticInit::default(),
            initialised: false,
            imu_from_sensor: config.imu_from_sensor.as_ref().map(pose_from_config),
            last_world_from_sensor: None,
            previous_world_from_sensor: None,
            counters: LioCounters::default(),
            last_update: None,
            config,
        })
    }

    pub fn counters(&self) -> &LioCounters {
        &self.counters
    }

    /// The filter's state (IMU in the world frame) after the last scan.
    pub fn state(&self) -> &State {
        &self.state
    }

    /// Whether the static initialisation has fixed gravity and the gyroscope bias.
    pub fn initialised(&self) -> bool {
        self.initialised
    }

    /// Diagnostics of the last update.
    pub fn last_update(&self) -> Option<&UpdateOutcome> {
        self.last_update.as_ref()
    }

    /// A scan whose stamp does not advance is refused before anything changes.
    fn check_stamp(&self, scan: &Scan) -> PluginResult<()> {
        if let Some((previous, _)) = self
            .last_world_from_sensor
            .filter(|(t, _)| scan.stamp_nanos <= *t)
        {
            return Err(PluginError::InvalidInput(format!(
                "scan {} of {}: stamp {} ns does not advance past the previous scan's {previous} ns",
                scan.sequence, scan.robot, scan.stamp_nanos
            )));
        }
        Ok(())
    }

    fn too_few_points(&self, scan: &Scan, count: usize, what: &str) -> PluginError {
        PluginError::InvalidInput(format!(
            "scan {} of {}: {count} {what}, at least {MIN_SCAN_POINTS} needed",
            scan.sequence, scan.robot
        ))
    }

    /// The IMU samples of `scan` that can be used: finite and after the last one used.
    fn usable_samples(&mut self, scan: &Scan) -> Vec<ImuSample> {
        let mut after = self.last_sample.map(|s| s.stamp_nanos);
        let mut usable = Vec::with_capacity(scan.imu.len());
        let mut dropped = 0u64;
        for sample in &scan.imu {
            let advances = after.is_none_or(|t| sample.stamp_nanos > t);
            if sample_is_finite(sample) && advances && sample.stamp_nanos <= scan.stamp_nanos {
                after = Some(sample.stamp_nanos);
                usable.push(*sample);
            } else {
                dropped += 1;
            }
        }
        if dropped > 0 {
            self.counters.bad_imu_samples += dropped;
            tracing::warn!(
                robot = %self.robot,
                scan = scan.sequence,
                dropped,
                "lio: IMU samples dropped (not finite, or not after the previous sample)"
            );
        }
        usable
    }

    /// Accumulates samples while the robot stands still; fixes gravity and the gyro bias once enough
    /// time is covered.
    fn initialise(&mut self, samples: &[ImuSample], imu_from_sensor: &Pose) {
        for sample in samples {
            self.init.samples += 1;
            self.init.first_nanos.get_or_insert(sample.stamp_nanos);
            self.init.last_nanos = sample.stamp_nanos;
            self.init.gyro_sum += Vector3::from(sample.gyro_radps);
            self.init.accel_sum += Vector3::from(sample.accel_mps2);
        }
        let covered_s = self
            .init
            .first_nanos
            .map_or(0.0, |first| (self.init.last_nanos - first) as f64 * 1e-9);
        if self.init.samples < 2 || covered_s + 1e-9 < self.config.init_duration_s {
            return;
        }
        let count = self.init.samples as f64;
        let mean_accel = self.init.accel_sum / count;
        // The world frame is the first scan's sensor frame: the IMU sits at `sensor_from_imu` in it.
        let world_from_imu = self.state.world_from_imu();
        self.state.gyro_bias = self.init.gyro_sum / count;
        self.state.gravity = world_from_imu.rotation * (-mean_accel);
        self.state.accel_bias = Vector3::zeros();
        // A robot already moving (a recording that starts mid-drive) keeps the velocity the LiDAR saw,
        // held loosely: the filter's own velocity is only as good as two scan registrations.
        if let Some((velocity, _)) = self.cv_motion() {
            self.state.velocity = velocity;
            for i in VEL..VEL + 3 {
                self.covariance[(i, i)] = self.covariance[(i, i)].max(INITIAL_MOVING_VELOCITY_VARIANCE);
            }
        }
        self.initialised = true;
        tracing::info!(
            robot = %self.robot,
            samples = self.init.samples,
            gravity_mps2 = self.state.gravity.norm(),
            gyro_bias_radps = ?self.state.gyro_bias.as_slice(),
            extrinsic_m = ?imu_from_sensor.translation.vector.as_slice(),
            "lio: static initialisation done"
        );
    }

    fn run_update(&self, points: &[Vector3<f64>]) -> Option<UpdateOutcome> {
        let settings = UpdateSettings {
            point_variance_m2: self.config.point_variance_m2,
            plane_neighbours: self.config.plane_neighbours,
            max_plane_distance_m: self.config.max_plane_distance_m,
            max_iterations: self.config.max_iterations,
            degeneracy_ratio: self.config.degeneracy_ratio,
        };
        let imu_from_sensor = self.imu_from_sensor();
        let run = || {
            iterated_update(
                &self.state,
                &self.covariance,
                &imu_from_sensor,
                points,
                &self.map,
                &settings,
            )
        };
        match &self.pool {
            Some(pool) => pool.install(run),
            None => run(),
        }
    }
}

fn positions(points: &[Point]) -> Vec<Vector3<f64>> {
    points
        .iter()
        .map(|p| Vector3::new(f64::from(p.x), f64::from(p.y), f64::from(p.z)))
        .collect()
}

impl Odometry for LioOdometry {
    fn register(&mut self, scan: &Scan) -> PluginResult<OdometryUpdate> {
        self.check_stamp(scan)?;
        if self.imu_from_sensor.is_none() {
            self.imu_from_sensor = scan.imu_from_sensor;
        }
        let imu_from_sensor = self.imu_from_sensor();
        let first = self.state_nanos.is_none();
        let finite = scan.points.iter().filter(|p| p.is_finite()).count();
        if first {
            if finite < MIN_SCAN_POINTS {
                return Err(self.too_few_points(scan, finite, "finite points"));
            }
            // The world frame is this scan's sensor frame.
            let world_from_imu = imu_from_sensor.inverse();
            self.state.rotation = world_from_imu.rotation;
            self.state.position = world_from_imu.translation.vector;
            self.state_nanos = Some(scan.stamp_nanos);
        }
        let has_imu = !scan.imu.is_empty() || self.initialised;
        if !has_imu && finite < MIN_SCAN_POINTS {
            // Without IMU nothing is learnt from a scan without points: refuse it untouched.
            return Err(self.too_few_points(scan, finite, "finite points"));
        }
        let samples = self.usable_samples(scan);
        if !self.initialised && !samples.is_empty() {
            // Until gravity is known the IMU cannot be integrated: a robot that starts moving is followed
            // on the LiDAR's constant-velocity model, and one at rest stays put.
            if !first {
                let dt_s = self
                    .state_nanos
                    .map_or(0.0, |t| scan.stamp_nanos.saturating_sub(t) as f64 * 1e-9);
                self.coast_without_imu(dt_s);
            }
            self.initialise(&samples, &imu_from_sensor);
            self.last_sample = samples.last().copied();
            self.state_nanos = Some(scan.stamp_nanos);
        } else if self.initialised {
            // The IMU samples are used even when the scan is refused below: the motion they measured
            // happened, and the next scan is predicted from it.
            self.predict(&samples, scan.stamp_nanos, scan.sequence);
        } else if !first {
            // No IMU at all: a LiDAR-only filter on the constant-velocity model.
            let dt_s = self
                .state_nanos
                .map_or(0.0, |t| scan.stamp_nanos.saturating_sub(t) as f64 * 1e-9);
            self.coast_without_imu(dt_s);
            self.state_nanos = Some(scan.stamp_nanos);
            self.counters.imu_gaps += 1;
            if self.counters.imu_gaps == 1 {
                tracing::warn!(robot = %self.robot, "lio: the source gives no IMU samples; LiDAR-only with a constant-velocity model");
            }
        }
        if finite < MIN_SCAN_POINTS {
            return Err(self.too_few_points(scan, finite, "finite points"));
        }
        let deskewed = self.deskewed(&scan.points);
        if deskewed.len() < MIN_SCAN_POINTS {
            let band = format!(
                "points between {} m and {} m",
                self.config.min_range_m, self.config.max_range_m
            );
            return Err(self.too_few_points(scan, deskewed.len(), &band));
        }
        let filtered = voxel_downsample(&deskewed, self.config.map_voxel_m as f32);
        let points = positions(&filtered);
        let mut degenerate = false;
        if !self.map.is_empty() {
            match self.run_update(&points) {
                Some(outcome) => {
                    degenerate = outcome.degenerate;
                    if outcome.degenerate {
                        self.counters.degenerate_scans += 1;
                        // Expected on open ground (planetary terrain, long corridors): said once per
                        // robot, with repeats counted at debug level, not a warning to act on.
                        if self.counters.degenerate_scans == 1 {
                            tracing::info!(
                                robot = %self.robot,
                                scan = scan.sequence,
                                "lio: the scan's planes leave a direction unconstrained; the IMU carries it \
                                 (expected on open ground; later scans like it are counted at debug level)"
                            );
                        } else if self.counters.degenerate_scans.is_power_of_two() {
                            tracing::debug!(
                                robot = %self.robot,
                                scan = scan.sequence,
                                degenerate_scans = self.counters.degenerate_scans,
                                eigenvalues = ?outcome.information_eigenvalues,
                                "lio: the scan's planes leave a direction unconstrained; the IMU carries it"
                            );
                        }
                    }
                    self.state = outcome.state;
                    self.covariance = outcome.covariance;
                    self.last_update = Some(outcome);
                }
                None => {
                    degenerate = true;
                    self.counters.unconstrained_scans += 1;
                    if self.counters.unconstrained_scans.is_power_of_two() {
                        tracing::warn!(
                            robot = %self.robot,
                            scan = scan.sequence,
                            unconstrained_scans = self.counters.unconstrained_scans,
                            "lio: no point found a plane; keeping the prediction (repeats logged at powers of two)"
                        );
                    }
                }
            }
        }
        if !self.state.is_finite() {
            return Err(PluginError::failed(
                "lio",
                format!("scan {} of {}: the filter diverged", scan.sequence, scan.robot),
            ));
        }
        // Symmetrise: rounding in `F P Fᵀ` and the inverse slowly breaks it.
        self.covariance = 0.5 * (self.covariance + self.covariance.transpose());

        let world_from_sensor = self.state.world_from_imu() * imu_from_sensor;
        let previous_from_current = self
            .last_world_from_sensor
            .map_or(Pose::identity(), |(_, previous)| {
                previous.inverse() * world_from_sensor
            });
        let world_points: Vec<Vector3<f64>> = points
            .iter()
            .map(|p| (world_from_sensor * Point3::from(*p)).coords)
            .collect();
        self.map.add(&world_points);
        self.map
            .prune(&world_from_sensor.translation.vector, self.config.max_range_m);
        self.previous_world_from_sensor = self.last_world_from_sensor;
        self.last_world_from_sensor = Some((scan.stamp_nanos, world_from_sensor));
        self.counters.scans += 1;

        let keyframe = self.trigger.keyframe(
            self.robot,
            scan.stamp_nanos,
            &world_from_sensor,
            self.config.keyframe_voxel_m,
            || deskewed,
        );
        Ok(OdometryUpdate {
            stamp_nanos: scan.stamp_nanos,
            world_from_sensor,
            previous_from_current,
            keyframe,
            degenerate,
        })
    }
}
