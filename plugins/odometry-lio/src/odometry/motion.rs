//! How the `lio` filter moves between scans and inside one: IMU propagation to the scan stamp, the
//! constant-velocity model where there is no IMU data, and deskewing each point by the motion predicted
//! over its time offset (see the parent module's steps 1 and 3).

use nalgebra::{Point3, UnitQuaternion, Vector3};
use skid_core::{ImuSample, Point, Pose, RawPoint};

use super::{COAST_ACCEL_SIGMA_MPS2, COAST_GYRO_SIGMA_RADPS, LioOdometry};
use crate::propagate::{Motion, coast, propagate};

impl LioOdometry {
    /// Propagates the filter through `samples` and then to `stamp_nanos`.
    pub(super) fn predict(&mut self, samples: &[ImuSample], stamp_nanos: u64, scan: u32) {
        let Some(mut time) = self.state_nanos else {
            return;
        };
        let mut gap = false;
        for sample in samples {
            let dt_s = sample.stamp_nanos.saturating_sub(time) as f64 * 1e-9;
            let gap_limit_nanos = (self.config.max_imu_gap_s * 1e9) as u64;
            match self.last_sample {
                Some(previous)
                    if dt_s <= self.config.max_imu_gap_s
                        && sample.stamp_nanos - previous.stamp_nanos <= gap_limit_nanos =>
                {
                    let motion = Motion {
                        gyro_radps: 0.5
                            * (Vector3::from(previous.gyro_radps) + Vector3::from(sample.gyro_radps)),
                        accel_mps2: 0.5
                            * (Vector3::from(previous.accel_mps2) + Vector3::from(sample.accel_mps2)),
                    };
                    propagate(&mut self.state, &mut self.covariance, &motion, dt_s, &self.noise);
                }
                _ => {
                    gap |= dt_s > self.config.max_imu_gap_s;
                    let omega = self.latest_omega();
                    self.coast_for(&omega, dt_s);
                }
            }
            time = sample.stamp_nanos;
            self.last_sample = Some(*sample);
        }
        // From the last sample to the scan stamp: that sample held, unless the silence is a gap.
        let dt_s = stamp_nanos.saturating_sub(time) as f64 * 1e-9;
        match self.last_sample {
            Some(last) if dt_s <= self.config.max_imu_gap_s => {
                let motion = Motion {
                    gyro_radps: Vector3::from(last.gyro_radps),
                    accel_mps2: Vector3::from(last.accel_mps2),
                };
                propagate(&mut self.state, &mut self.covariance, &motion, dt_s, &self.noise);
            }
            _ => {
                gap |= self.last_sample.is_some();
                self.coast_without_imu(dt_s);
            }
        }
        self.state_nanos = Some(stamp_nanos);
        if gap || self.last_sample.is_none() {
            self.counters.imu_gaps += 1;
            if self.last_sample.is_some() {
                tracing::warn!(
                    robot = %self.robot,
                    scan,
                    "lio: gap in the IMU stream; crossed at constant velocity"
                );
            }
        }
    }

    /// Without IMU data: the motion of the last two scans repeated.
    pub(super) fn coast_without_imu(&mut self, dt_s: f64) {
        let omega = match self.cv_motion() {
            Some((velocity, omega)) => {
                self.state.velocity = velocity;
                omega
            }
            None => Vector3::zeros(),
        };
        self.coast_for(&omega, dt_s);
    }

    /// Crosses `dt_s` at constant velocity, turning at `omega` (no IMU measurement).
    pub(super) fn coast_for(&mut self, omega: &Vector3<f64>, dt_s: f64) {
        coast(
            &mut self.state,
            &mut self.covariance,
            omega,
            dt_s,
            COAST_ACCEL_SIGMA_MPS2,
            COAST_GYRO_SIGMA_RADPS,
        );
    }

    /// The IMU's velocity (world frame) and angular rate (its own frame) over the last two scans: the
    /// constant-velocity model.
    pub(super) fn cv_motion(&self) -> Option<(Vector3<f64>, Vector3<f64>)> {
        let ((t1, p1), (t0, p0)) = (self.last_world_from_sensor?, self.previous_world_from_sensor?);
        let interval_s = t1.checked_sub(t0).filter(|&d| d > 0)? as f64 * 1e-9;
        let sensor_from_imu = self.imu_from_sensor().inverse();
        let (w0, w1) = (p0 * sensor_from_imu, p1 * sensor_from_imu);
        Some((
            (w1.translation.vector - w0.translation.vector) / interval_s,
            (w0.rotation.inverse() * w1.rotation).scaled_axis() / interval_s,
        ))
    }

    pub(super) fn latest_omega(&self) -> Vector3<f64> {
        self.last_sample.map_or(Vector3::zeros(), |s| {
            Vector3::from(s.gyro_radps) - self.state.gyro_bias
        })
    }

    pub(super) fn imu_from_sensor(&self) -> Pose {
        self.imu_from_sensor.unwrap_or_else(Pose::identity)
    }

    /// The sensor's motion from the stamp to `offset_s` later, as the filter predicts it:
    /// `sensor(t) ← sensor(t + τ)`.
    pub(super) fn sweep_motion(&self, offset_s: f64) -> Pose {
        let imu_from_sensor = self.imu_from_sensor();
        let (omega, accel) = match self.last_sample.filter(|_| self.initialised) {
            Some(sample) => (
                Vector3::from(sample.gyro_radps) - self.state.gyro_bias,
                Vector3::from(sample.accel_mps2) - self.state.accel_bias,
            ),
            None => (
                self.cv_omega(),
                self.state.rotation.inverse() * (-self.state.gravity),
            ),
        };
        // In the IMU frame at the stamp: rotation Exp(ωτ), translation Rᵀ(vτ + ½(Ra + g)τ²).
        let rotation_world = self.state.rotation;
        let accel_world = rotation_world * accel + self.state.gravity;
        let translation = rotation_world.inverse()
            * (self.state.velocity * offset_s + 0.5 * accel_world * offset_s * offset_s);
        let imu_motion = Pose::from_parts(
            translation.into(),
            UnitQuaternion::from_scaled_axis(omega * offset_s),
        );
        imu_from_sensor.inverse() * imu_motion * imu_from_sensor
    }

    /// The angular rate of the constant-velocity model, in the IMU frame.
    pub(super) fn cv_omega(&self) -> Vector3<f64> {
        self.cv_motion().map_or(Vector3::zeros(), |(_, omega)| omega)
    }

    /// Finite points within the range band, moved to the sensor frame at the stamp.
    pub(super) fn deskewed(&self, points: &[RawPoint]) -> Vec<Point> {
        let (min_sq, max_sq) = (self.config.min_range_m.powi(2), self.config.max_range_m.powi(2));
        let timed = points
            .iter()
            .any(|p| p.time_offset_s != 0.0 && p.time_offset_s.is_finite());
        // Motions are tabulated every millisecond of the sweep rather than per point.
        let step_s = 1e-3;
        let (lo, hi) = points
            .iter()
            .filter(|p| p.is_finite())
            .fold((0.0f64, 0.0f64), |(lo, hi), p| {
                let t = f64::from(p.time_offset_s);
                (lo.min(t), hi.max(t))
            });
        let first = (lo / step_s).floor() as i64;
        let last = (hi / step_s).ceil() as i64;
        let table: Vec<Pose> = if timed && last - first < 10_000 {
            (first..=last)
                .map(|i| self.sweep_motion(i as f64 * step_s))
                .collect()
        } else {
            Vec::new()
        };
        points
            .iter()
            .filter(|p| p.is_finite())
            .filter_map(|p| {
                let position = Point3::new(f64::from(p.x), f64::from(p.y), f64::from(p.z));
                let range_sq = position.coords.norm_squared();
                if !(range_sq > min_sq && range_sq < max_sq) {
                    return None;
                }
                let moved = if table.is_empty() {
                    position
                } else {
                    let index = ((f64::from(p.time_offset_s) / step_s).round() as i64 - first)
                        .clamp(0, table.len() as i64 - 1) as usize;
                    table[index] * position
                };
                Some(Point::with_intensity(
                    moved.x as f32,
                    moved.y as f32,
                    moved.z as f32,
                    p.intensity,
                ))
            })
            .collect()
    }
}
