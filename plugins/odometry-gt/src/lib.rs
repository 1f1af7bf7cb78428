//! The `ground_truth` odometry plugin: it reads the pose the source attaches to each scan and reports it
//! as odometry, optionally corrupted by per-scan noise and systematic drift, so that place recognition,
//! registration and the back-end can be evaluated with the odometry error under control.
//!
//! Poses are reported in the odometry frame, whose origin is the first scan's sensor pose (as a real
//! odometry would), unless `start_at_ground_truth` is set. Keyframes carry the scan deskewed with the
//! constant-velocity model and voxel-downsampled.

use nalgebra::{Translation3, UnitQuaternion, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};
use skid_core::slots::{Odometry, OdometryUpdate};
use skid_core::{PluginContext, PluginEntry, PluginError, PluginResult, Pose, Registry, Scan};
use skid_geometry::{KeyframePolicy, KeyframeTrigger, deskew_constant_velocity};

/// Parameters of the `ground_truth` odometry.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct GroundTruthConfig {
    /// Standard deviation of the noise added to each inter-scan translation, per axis, in metres.
    pub translation_noise_m: f64,
    /// Standard deviation of the noise added to each inter-scan rotation, per axis, in degrees.
    pub rotation_noise_deg: f64,
    /// Systematic scale error of travelled distance, in percent (1.0 = 1% too long).
    pub scale_drift_percent: f64,
    /// Systematic heading drift, in degrees per metre travelled.
    pub yaw_drift_deg_per_m: f64,
    /// Report poses in the ground-truth world frame instead of starting at the identity.
    pub start_at_ground_truth: bool,
    /// Sweep duration used for deskewing, in seconds.
    pub scan_period_s: f64,
    /// Voxel size of keyframe clouds, in metres; 0 keeps every point.
    pub keyframe_voxel_m: f64,
    pub keyframe: KeyframePolicy,
}

impl Default for GroundTruthConfig {
    fn default() -> Self {
        Self {
            translation_noise_m: 0.0,
            rotation_noise_deg: 0.0,
            scale_drift_percent: 0.0,
            yaw_drift_deg_per_m: 0.0,
            start_at_ground_truth: false,
            scan_period_s: 0.1,
            keyframe_voxel_m: 0.25,
            keyframe: KeyframePolicy::default(),
        }
    }
}

/// Registers `ground_truth` in the odometry slot.
pub fn register(registry: &mut Registry) -> Result<(), PluginError> {
    let entry = PluginEntry::new(
        "ground_truth",
        "Ground-truth poses from the source, with optional noise and drift (for isolating later stages)",
        |config: GroundTruthConfig, context: &PluginContext| {
            Ok(Box::new(GroundTruthOdometry::new(config, context)?) as Box<dyn Odometry>)
        },
    )?;
    registry.odometry.register(entry)
}

/// The plugin state.
pub struct GroundTruthOdometry {
    config: GroundTruthConfig,
    context: PluginContext,
    rng: ChaCha8Rng,
    translation_noise: Normal<f64>,
    rotation_noise: Normal<f64>,
    trigger: KeyframeTrigger,
    /// Ground truth and estimate at the previous scan.
    previous: Option<(Pose, Pose)>,
    previous_stamp_nanos: Option<u64>,
}

/// Fewest finite points a scan must have to be used.
pub const MIN_SCAN_POINTS: usize = 10;

impl GroundTruthOdometry {
    pub fn new(config: GroundTruthConfig, context: &PluginContext) -> PluginResult<Self> {
        let normal = |std: f64, what: &str| {
            let bad = || {
                PluginError::failed(
                    "ground_truth",
                    format!("{what} must be a finite, non-negative number, got {std}"),
                )
            };
            if !(std.is_finite() && std >= 0.0) {
                return Err(bad());
            }
            Normal::new(0.0, std).map_err(|_| bad())
        };
        if !(config.scan_period_s.is_finite() && config.scan_period_s > 0.0) {
            return Err(PluginError::failed(
                "ground_truth",
                "scan_period_s must be positive",
            ));
        }
        Ok(Self {
            translation_noise: normal(config.translation_noise_m, "translation_noise_m")?,
            rotation_noise: normal(config.rotation_noise_deg.to_radians(), "rotation_noise_deg")?,
            trigger: KeyframeTrigger::new(config.keyframe.clone()),
            rng: ChaCha8Rng::seed_from_u64(context.seed ^ (u64::from(context.robot.0) << 32) ^ 0x6f64_6f6d),
            context: context.clone(),
            config,
            previous: None,
            previous_stamp_nanos: None,
        })
    }

    /// The ground-truth motion corrupted by drift and noise.
    fn corrupt(&mut self, motion: &Pose) -> Pose {
        let distance_m = motion.translation.vector.norm();
        let translation = motion.translation.vector * (1.0 + self.config.scale_drift_percent / 100.0)
            + Vector3::from_fn(|_, _| self.translation_noise.sample(&mut self.rng));
        let yaw_drift = (self.config.yaw_drift_deg_per_m * distance_m).to_radians();
        let noise = Vector3::from_fn(|_, _| self.rotation_noise.sample(&mut self.rng))
            + Vector3::new(0.0, 0.0, yaw_drift);
        let rotation = motion.rotation * UnitQuaternion::from_scaled_axis(noise);
        Pose::from_parts(Translation3::from(translation), rotation)
    }
}

impl Odometry for GroundTruthOdometry {
    fn register(&mut self, scan: &Scan) -> PluginResult<OdometryUpdate> {
        // Refuse unusable scans before touching any state, as every odometry does.
        let finite = scan.points.iter().filter(|p| p.is_finite()).count();
        if finite < MIN_SCAN_POINTS {
            return Err(PluginError::InvalidInput(format!(
                "scan {} of {}: {finite} finite points, at least {MIN_SCAN_POINTS} needed",
                scan.sequence, scan.robot
            )));
        }
        if let Some(previous) = self
            .previous_stamp_nanos
            .filter(|&previous| scan.stamp_nanos <= previous)
        {
            return Err(PluginError::InvalidInput(format!(
                "scan {} of {}: stamp {} ns does not advance past the previous scan's {previous} ns",
                scan.sequence, scan.robot, scan.stamp_nanos
            )));
        }
        let ground_truth = scan.ground_truth_world_from_sensor.ok_or_else(|| {
            PluginError::InvalidInput(format!(
                "scan {} of {} has no ground-truth pose; the ground_truth odometry needs a source that provides one",
                scan.sequence, scan.robot
            ))
        })?;
        let (world_from_sensor, previous_from_current) = match self.previous {
            None if self.config.start_at_ground_truth => (ground_truth, Pose::identity()),
            None => (Pose::identity(), Pose::identity()),
            Some((previous_truth, previous_estimate)) => {
                let motion = self.corrupt(&(previous_truth.inverse() * ground_truth));
                (previous_estimate * motion, motion)
            }
        };
        self.previous = Some((ground_truth, world_from_sensor));
        self.previous_stamp_nanos = Some(scan.stamp_nanos);
        let keyframe = self.trigger.keyframe(
            self.context.robot,
            scan.stamp_nanos,
            &world_from_sensor,
            self.config.keyframe_voxel_m,
            || deskew_constant_velocity(&scan.points, &previous_from_current, self.config.scan_period_s),
        );
        Ok(OdometryUpdate {
            stamp_nanos: scan.stamp_nanos,
            world_from_sensor,
            previous_from_current,
            keyframe,
            degenerate: false,
        })
    }
}

impl skid_core::PluginParams for GroundTruthConfig {
    fn check(&self) -> Result<(), skid_core::ParamError> {
        use skid_core::registry::check::{non_negative, positive, within};
        non_negative("translation_noise_m", self.translation_noise_m)?;
        non_negative("rotation_noise_deg", self.rotation_noise_deg)?;
        within("scale_drift_percent", self.scale_drift_percent, -50.0, 50.0)?;
        within("yaw_drift_deg_per_m", self.yaw_drift_deg_per_m, -10.0, 10.0)?;
        positive("scan_period_s", self.scan_period_s)?;
        non_negative("keyframe_voxel_m", self.keyframe_voxel_m)?;
        self.keyframe.check()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use skid_core::RawPoint;

    fn scan(sequence: u32, x_m: f64) -> Scan {
        Scan {
            sequence,
            stamp_nanos: u64::from(sequence) * 100_000_000,
            points: vec![RawPoint::new(5.0, 0.0, 0.0, 1.0, 0.0, 0); 12],
            ground_truth_world_from_sensor: Some(Pose::translation(x_m, 2.0, 0.0)),
            ..Scan::default()
        }
    }

    #[test]
    fn without_noise_reports_motion_from_the_origin() {
        let mut odometry =
            GroundTruthOdometry::new(GroundTruthConfig::default(), &PluginContext::default()).unwrap();
        let first = odometry.register(&scan(0, 10.0)).unwrap();
        assert_eq!(first.world_from_sensor, Pose::identity());
        assert_eq!(first.keyframe.as_ref().map(|k| k.id.index), Some(0));
        let second = odometry.register(&scan(1, 11.0)).unwrap();
        assert!((second.world_from_sensor.translation.x - 1.0).abs() < 1e-12);
        assert!(second.keyframe.is_none());
        let third = odometry.register(&scan(2, 12.5)).unwrap();
        assert_eq!(third.keyframe.map(|k| k.id.index), Some(1));
    }

    #[test]
    fn drift_lengthens_the_path() {
        let config = GroundTruthConfig {
            scale_drift_percent: 10.0,
            ..GroundTruthConfig::default()
        };
        let mut odometry = GroundTruthOdometry::new(config, &PluginContext::default()).unwrap();
        odometry.register(&scan(0, 0.0)).unwrap();
        let update = odometry.register(&scan(1, 10.0)).unwrap();
        assert!((update.world_from_sensor.translation.x - 11.0).abs() < 1e-9);
    }

    #[test]
    fn missing_ground_truth_is_a_clear_error() {
        let mut odometry =
            GroundTruthOdometry::new(GroundTruthConfig::default(), &PluginContext::default()).unwrap();
        let mut bad = scan(0, 0.0);
        bad.ground_truth_world_from_sensor = None;
        let error = odometry.register(&bad).unwrap_err().to_string();
        assert!(error.contains("no ground-truth pose"), "{error}");
    }

    #[test]
    fn conformance() {
        skid_testkit::odometry::check_odometry(
            || {
                Box::new(
                    GroundTruthOdometry::new(GroundTruthConfig::default(), &PluginContext::default())
                        .unwrap(),
                )
            },
            skid_testkit::odometry::OdometryExpectations {
                max_translation_error_m: 1e-9,
                max_rotation_error_deg: 1e-9,
            },
        );
    }

    #[test]
    fn negative_noise_is_refused() {
        let config = GroundTruthConfig {
            translation_noise_m: -1.0,
            ..GroundTruthConfig::default()
        };
        assert!(GroundTruthOdometry::new(config, &PluginContext::default()).is_err());
    }
}
