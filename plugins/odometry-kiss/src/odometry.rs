//! The `kiss_icp` odometry: KISS-ICP (Vizzo et al., RA-L 2023) scan by scan, plus the keyframe policy.
//!
//! Per scan: drop non-finite points; deskew with the constant-velocity model (the last inter-scan motion
//! spread over the last inter-scan interval, points moved to the middle of the sweep, where KISS-ICP
//! registers too); keep points between the
//! minimum and maximum range; downsample at 0.5 v (for the map) and that at 1.5 v (for registration);
//! predict the pose with the last motion; align to the local map with the adaptive threshold; update
//! the threshold, then the map; report the pose at the scan stamp (start of the sweep) by moving back
//! half a sweep along the estimated motion. A scan that cannot be used is an error returned before any state
//! changes, so the map is never corrupted.

use nalgebra::Point3;
use skid_core::slots::{Odometry, OdometryUpdate};
use skid_core::{PluginContext, PluginError, PluginResult, Point, Pose, RawPoint, RobotId, Scan};
use skid_geometry::{KeyframeTrigger, deskew_constant_velocity, voxel_downsample};

use crate::config::KissIcpConfig;
use crate::degeneracy::{Degeneracy, assess, lean_on_prediction};
use crate::icp::{IcpResult, IcpSettings, align_points_to_map};
use crate::parallel::Parallel;
use crate::threshold::AdaptiveThreshold;
use crate::voxel_map::VoxelHashMap;

/// Fewest finite points a scan must have to be used.
pub const MIN_SCAN_POINTS: usize = 10;

/// Raw points per deskewing chunk.
const DESKEW_CHUNK: usize = 16_384;

/// The estimator's state between scans.
pub struct KissIcpOdometry {
    config: KissIcpConfig,
    robot: RobotId,
    parallel: Parallel,
    map: VoxelHashMap,
    threshold: AdaptiveThreshold,
    trigger: KeyframeTrigger,
    /// Pose of the last registered scan at its reference time (mid-sweep when deskewing), the motion
    /// from the scan before it, and its pose at its stamp.
    last_pose: Pose,
    last_delta: Pose,
    last_stamp_pose: Pose,
    /// Stamp of the last registered scan, and the interval before it (seconds) once known.
    last_stamp_nanos: Option<u64>,
    last_interval_s: Option<f64>,
    last_registration: Option<IcpResult>,
    last_degeneracy: Option<Degeneracy>,
    degenerate_scans: u64,
}

impl std::fmt::Debug for KissIcpOdometry {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("KissIcpOdometry")
            .field("robot", &self.robot)
            .field("map_points", &self.map.point_count())
            .field("sigma_m", &self.threshold.sigma_m())
            .field("last_pose", &self.last_pose)
            .finish()
    }
}

impl KissIcpOdometry {
    /// A fresh estimator at the identity, using `context.threads` threads.
    pub fn new(config: KissIcpConfig, context: &PluginContext) -> PluginResult<Self> {
        config.validate()?;
        Self::from_checked(config, context)
    }

    /// [`KissIcpOdometry::new`] for a configuration the registry has checked already (it is checked once, when
    /// the configuration is loaded).
    pub(crate) fn from_checked(config: KissIcpConfig, context: &PluginContext) -> PluginResult<Self> {
        Ok(Self {
            parallel: Parallel::new(context.threads)?,
            map: VoxelHashMap::new(config.voxel_size_m, config.max_points_per_voxel),
            threshold: AdaptiveThreshold::new(
                config.initial_threshold_m,
                config.min_motion_m,
                config.max_range_m,
            ),
            trigger: KeyframeTrigger::new(config.keyframe.clone()),
            robot: context.robot,
            config,
            last_pose: Pose::identity(),
            last_delta: Pose::identity(),
            last_stamp_pose: Pose::identity(),
            last_stamp_nanos: None,
            last_degeneracy: None,
            degenerate_scans: 0,
            last_interval_s: None,
            last_registration: None,
        })
    }

    /// The local map.
    pub fn map(&self) -> &VoxelHashMap {
        &self.map
    }

    /// The current correspondence threshold σ in metres.
    pub fn sigma_m(&self) -> f64 {
        self.threshold.sigma_m()
    }

    /// Diagnostics of the last registration (iterations, correspondences, convergence).
    pub fn last_registration(&self) -> Option<&IcpResult> {
        self.last_registration.as_ref()
    }

    /// The degeneracy test of the last registration (`None` when it was off or had no map yet).
    pub fn last_degeneracy(&self) -> Option<&Degeneracy> {
        self.last_degeneracy.as_ref()
    }

    /// Registrations found degenerate so far.
    pub fn degenerate_scans(&self) -> u64 {
        self.degenerate_scans
    }

    /// Checks the scan before anything is changed.
    fn check_scan(&self, scan: &Scan) -> PluginResult<()> {
        let finite = scan.points.iter().filter(|p| p.is_finite()).count();
        if finite < MIN_SCAN_POINTS {
            return Err(PluginError::InvalidInput(format!(
                "scan {} of {}: {finite} finite points, at least {MIN_SCAN_POINTS} needed",
                scan.sequence, scan.robot
            )));
        }
        if let Some(previous) = self
            .last_stamp_nanos
            .filter(|&previous| scan.stamp_nanos <= previous)
        {
            return Err(PluginError::InvalidInput(format!(
                "scan {} of {}: stamp {} ns does not advance past the previous scan's {previous} ns",
                scan.sequence, scan.robot, scan.stamp_nanos
            )));
        }
        Ok(())
    }

    /// The reference time of registration, seconds after the stamp: the middle of the sweep when the
    /// scan is deskewed (as KISS-ICP does; deskewing to the start of the sweep instead makes the
    /// constant-velocity feedback unstable: a spurious rotation in the model comes back amplified and
    /// with its sign flipped on the next scan), else the stamp itself.
    fn reference_offset_s(&self, points: &[RawPoint]) -> f64 {
        if !self.config.deskew {
            return 0.0;
        }
        let offsets = points
            .iter()
            .filter(|p| p.is_finite())
            .map(|p| f64::from(p.time_offset_s));
        let (first, last) = offsets.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), t| {
            (lo.min(t), hi.max(t))
        });
        if first.is_finite() && last.is_finite() {
            0.5 * (first + last)
        } else {
            0.0
        }
    }

    /// Finite points moved to the sensor frame at `reference_s` after the stamp with the constant-velocity
    /// model (unchanged when deskewing is off, before a motion is known, or when the sensor reports no
    /// time offsets).
    fn deskew(&self, points: &[RawPoint], reference_s: f64) -> Vec<Point> {
        let timed = points
            .iter()
            .any(|p| p.time_offset_s != 0.0 && p.time_offset_s.is_finite());
        match self.last_interval_s {
            Some(interval_s) if self.config.deskew && timed => {
                let delta = self.last_delta;
                let chunks = self.parallel.map_chunks(points, DESKEW_CHUNK, |chunk| {
                    let shifted: Vec<RawPoint> = chunk
                        .iter()
                        .map(|p| RawPoint {
                            time_offset_s: (f64::from(p.time_offset_s) - reference_s) as f32,
                            ..*p
                        })
                        .collect();
                    deskew_constant_velocity(&shifted, &delta, interval_s)
                });
                chunks.concat()
            }
            _ => points
                .iter()
                .filter(|p| p.is_finite())
                .map(RawPoint::point)
                .collect(),
        }
    }

    /// Points within the configured range band.
    fn crop(&self, points: Vec<Point>) -> Vec<Point> {
        let (min_sq, max_sq) = (self.config.min_range_m.powi(2), self.config.max_range_m.powi(2));
        points
            .into_iter()
            .filter(|p| {
                let range_sq = f64::from(p.x).powi(2) + f64::from(p.y).powi(2) + f64::from(p.z).powi(2);
                range_sq > min_sq && range_sq < max_sq
            })
            .collect()
    }
}

/// The pose with its quaternion put back on the unit sphere. `inverse()` conjugates the quaternion, which
/// is only its inverse at unit norm: without this, rounding drift in the norm would grow by a constant
/// factor with every scan (prediction = last · last⁻¹ · current) and wreck the estimate after a few
/// dozen scans.
fn renormalized(mut pose: Pose) -> Pose {
    pose.rotation.renormalize();
    pose
}

fn positions(points: &[Point]) -> Vec<Point3<f64>> {
    points
        .iter()
        .map(|p| Point3::new(f64::from(p.x), f64::from(p.y), f64::from(p.z)))
        .collect()
}

impl Odometry for KissIcpOdometry {
    fn register(&mut self, scan: &Scan) -> PluginResult<OdometryUpdate> {
        self.check_scan(scan)?;
        let reference_s = self.reference_offset_s(&scan.points);
        let cropped = self.crop(self.deskew(&scan.points, reference_s));
        if cropped.len() < MIN_SCAN_POINTS {
            return Err(PluginError::InvalidInput(format!(
                "scan {} of {}: {} points between {} m and {} m, at least {MIN_SCAN_POINTS} needed",
                scan.sequence,
                scan.robot,
                cropped.len(),
                self.config.min_range_m,
                self.config.max_range_m
            )));
        }
        let voxel_m = self.config.voxel_size_m;
        let frame = voxel_downsample(&cropped, (0.5 * voxel_m) as f32);
        let source = positions(&voxel_downsample(&frame, (1.5 * voxel_m) as f32));

        let sigma_m = self.threshold.sigma_m();
        let prediction = renormalized(self.last_pose * self.last_delta);
        let settings = IcpSettings {
            max_correspondence_m: self.config.correspondence_sigmas * sigma_m,
            kernel_scale_m: sigma_m / self.config.kernel_scale_divisor,
            max_iterations: self.config.max_iterations,
            convergence_criterion: self.config.convergence_criterion,
        };
        let registration = align_points_to_map(&source, &self.map, &prediction, &settings, &self.parallel);
        let degeneracy =
            (self.config.degeneracy_ratio > 0.0 && registration.correspondences > 0).then(|| {
                let registered = &registration.world_from_sensor;
                let world: Vec<Point3<f64>> = source.iter().map(|p| registered * p).collect();
                assess(&world, &self.map, settings.max_correspondence_m)
            });
        let degenerate = degeneracy.as_ref().is_some_and(|d| {
            d.translation.is_degenerate(self.config.degeneracy_ratio)
                || d.rotation.is_degenerate(self.config.degeneracy_ratio)
        });
        // The registered pose is the sensor's at the reference time; `world_from_sensor` is at the stamp.
        let world_from_reference = match &degeneracy {
            // The motion model is leant on only once it holds a measured motion (not at the second scan).
            Some(d)
                if self.config.lean_on_motion_model
                    && self.last_interval_s.is_some()
                    && d.translation.is_degenerate(self.config.degeneracy_ratio) =>
            {
                renormalized(lean_on_prediction(
                    &registration.world_from_sensor,
                    &prediction,
                    &d.translation,
                    self.config.degeneracy_ratio,
                ))
            }
            _ => registration.world_from_sensor,
        };
        let finite = world_from_reference
            .to_homogeneous()
            .iter()
            .all(|v| v.is_finite());
        if !finite {
            return Err(PluginError::failed(
                "kiss_icp",
                format!(
                    "scan {} of {}: registration diverged to a non-finite pose",
                    scan.sequence, scan.robot
                ),
            ));
        }
        if !self.map.is_empty() && registration.correspondences == 0 {
            tracing::warn!(
                "kiss_icp: scan {} of {}: no correspondence within {:.2} m, keeping the constant-velocity prediction",
                scan.sequence,
                scan.robot,
                settings.max_correspondence_m
            );
        }
        let first = self.last_stamp_nanos.is_none();
        let delta = if first {
            Pose::identity()
        } else {
            renormalized(self.last_pose.inverse() * world_from_reference)
        };
        let interval_s = self
            .last_stamp_nanos
            .map(|previous| (scan.stamp_nanos - previous) as f64 * 1e-9);
        let stamp_from_reference = match interval_s {
            Some(interval_s) if reference_s != 0.0 => {
                Pose::identity().lerp_slerp(&delta, reference_s / interval_s)
            }
            _ => Pose::identity(),
        };
        let world_from_sensor = renormalized(world_from_reference * stamp_from_reference.inverse());
        let previous_from_current = if first {
            Pose::identity()
        } else {
            renormalized(self.last_stamp_pose.inverse() * world_from_sensor)
        };

        // Everything below changes state; nothing below can fail.
        self.threshold
            .update(&(prediction.inverse() * world_from_reference));
        self.map
            .update(&positions(&frame), &world_from_reference, self.config.max_range_m);
        self.last_interval_s = interval_s;
        self.last_stamp_nanos = Some(scan.stamp_nanos);
        self.last_delta = delta;
        self.last_pose = world_from_reference;
        self.last_stamp_pose = world_from_sensor;
        self.last_registration = Some(registration);
        if degenerate {
            self.degenerate_scans += 1;
            if self.degenerate_scans == 1 {
                tracing::info!(
                    robot = %self.robot,
                    scan = scan.sequence,
                    "kiss_icp: the scan's geometry leaves a direction unconstrained; the motion model carries it \
                     (expected in corridors and on open ground; later scans like it are counted at debug level)"
                );
            } else if self.degenerate_scans.is_power_of_two() {
                let (translation, rotation) = degeneracy.as_ref().map_or(([0.0; 3], [0.0; 3]), |d| {
                    (d.translation.ratios(), d.rotation.ratios())
                });
                tracing::debug!(
                    robot = %self.robot,
                    scan = scan.sequence,
                    degenerate_scans = self.degenerate_scans,
                    ?translation,
                    ?rotation,
                    "kiss_icp: the scan's geometry leaves a direction unconstrained (information ratios shown); the motion model carries it (repeats logged at powers of two)"
                );
            }
        }
        self.last_degeneracy = degeneracy;

        // The keyframe cloud is given in the sensor frame at the stamp, like its pose.
        let keyframe = self.trigger.keyframe(
            self.robot,
            scan.stamp_nanos,
            &world_from_sensor,
            self.config.keyframe_voxel_m,
            || {
                if stamp_from_reference == Pose::identity() {
                    cropped
                } else {
                    cropped
                        .iter()
                        .map(|p| {
                            let q = stamp_from_reference
                                * Point3::new(f64::from(p.x), f64::from(p.y), f64::from(p.z));
                            Point::with_intensity(q.x as f32, q.y as f32, q.z as f32, p.intensity)
                        })
                        .collect()
                }
            },
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
