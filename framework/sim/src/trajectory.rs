//! Continuous-time trajectories: a uniform cumulative cubic B-spline on SE(3), split into R³ for the
//! position and SO(3) for the orientation (Kim, Kim and Shin, "A general construction scheme for unit
//! quaternion curves", SIGGRAPH 1995; Sommer et al., "Efficient derivative computation for cumulative
//! B-splines on Lie groups", CVPR 2020).
//!
//! The spline is C² in position, so the simulated accelerometer (second derivative) and gyroscope
//! (rotation rate) are smooth and exactly consistent with the poses used for ray casting and ground truth.

use nalgebra::{Translation3, UnitQuaternion, Vector3};
use skid_core::Pose;

/// A pose trajectory through control poses spaced `dt_s` apart starting at `start_s`.
#[derive(Clone, Debug)]
pub struct Trajectory {
    start_s: f64,
    dt_s: f64,
    controls: Vec<Pose>,
}

/// Cumulative cubic B-spline basis B̃₁..B̃₃ and its first and second derivatives in u.
fn basis(u: f64) -> ([f64; 3], [f64; 3], [f64; 3]) {
    let (u2, u3) = (u * u, u * u * u);
    (
        [
            (5.0 + 3.0 * u - 3.0 * u2 + u3) / 6.0,
            (1.0 + 3.0 * u + 3.0 * u2 - 2.0 * u3) / 6.0,
            u3 / 6.0,
        ],
        [
            (3.0 - 6.0 * u + 3.0 * u2) / 6.0,
            (3.0 + 6.0 * u - 6.0 * u2) / 6.0,
            u2 / 2.0,
        ],
        [u - 1.0, 1.0 - 2.0 * u, u],
    )
}

impl Trajectory {
    /// A trajectory through `controls` (at least one). Before the first and after the last control pose
    /// the trajectory holds still.
    pub fn new(start_s: f64, dt_s: f64, controls: Vec<Pose>) -> Self {
        assert!(
            !controls.is_empty() && dt_s > 0.0,
            "a trajectory needs control poses and a positive spacing"
        );
        Self {
            start_s,
            dt_s,
            controls,
        }
    }

    pub fn start_s(&self) -> f64 {
        self.start_s
    }

    /// Time of the last control pose.
    pub fn end_s(&self) -> f64 {
        self.start_s + self.dt_s * (self.controls.len() - 1) as f64
    }

    /// The control poses.
    pub fn controls(&self) -> &[Pose] {
        &self.controls
    }

    fn control(&self, index: i64) -> &Pose {
        &self.controls[index.clamp(0, self.controls.len() as i64 - 1) as usize]
    }

    /// Segment index and parameter u for time t: the segment uses controls i−1 … i+2.
    fn locate(&self, t_s: f64) -> (i64, f64) {
        let s = (t_s - self.start_s) / self.dt_s;
        let floor = s.floor();
        (floor as i64, s - floor)
    }

    /// World-from-body pose at `t_s`.
    pub fn pose_at(&self, t_s: f64) -> Pose {
        let (i, u) = self.locate(t_s);
        let (b, _, _) = basis(u);
        let first = self.control(i - 1);
        let mut position = first.translation.vector;
        let mut rotation = first.rotation;
        for (j, weight) in b.into_iter().enumerate() {
            let (prev, next) = (self.control(i - 1 + j as i64), self.control(i + j as i64));
            position += (next.translation.vector - prev.translation.vector) * weight;
            let delta = (prev.rotation.inverse() * next.rotation).scaled_axis();
            rotation *= UnitQuaternion::from_scaled_axis(delta * weight);
        }
        Pose::from_parts(Translation3::from(position), rotation)
    }

    /// World-frame velocity and acceleration at `t_s`.
    pub fn velocity_acceleration_at(&self, t_s: f64) -> (Vector3<f64>, Vector3<f64>) {
        let (i, u) = self.locate(t_s);
        let (_, db, ddb) = basis(u);
        let (mut velocity, mut acceleration) = (Vector3::zeros(), Vector3::zeros());
        for j in 0..3 {
            let delta = self.control(i + j as i64).translation.vector
                - self.control(i - 1 + j as i64).translation.vector;
            velocity += delta * (db[j] / self.dt_s);
            acceleration += delta * (ddb[j] / (self.dt_s * self.dt_s));
        }
        (velocity, acceleration)
    }

    /// Body-frame angular velocity at `t_s` (central difference over ±0.1 ms).
    pub fn angular_velocity_at(&self, t_s: f64) -> Vector3<f64> {
        let h = 1e-4;
        let (before, after) = (self.pose_at(t_s - h), self.pose_at(t_s + h));
        (before.rotation.inverse() * after.rotation).scaled_axis() / (2.0 * h)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constant_velocity_and_turn_rate_are_reproduced() {
        let controls: Vec<Pose> = (0..50)
            .map(|k| {
                let t = f64::from(k) * 0.1;
                Pose::new(Vector3::new(2.0 * t, 0.0, 1.0), Vector3::new(0.0, 0.0, 0.3 * t))
            })
            .collect();
        let trajectory = Trajectory::new(0.0, 0.1, controls);
        let (v, a) = trajectory.velocity_acceleration_at(2.03);
        assert!((v - Vector3::new(2.0, 0.0, 0.0)).norm() < 1e-9 && a.norm() < 1e-9);
        let w = trajectory.angular_velocity_at(2.03);
        assert!((w - Vector3::new(0.0, 0.0, 0.3)).norm() < 1e-6, "{w}");
        // The spline stays on the straight line of control positions.
        let p = trajectory.pose_at(2.03).translation.vector;
        assert!((p - Vector3::new(4.06, 0.0, 1.0)).norm() < 1e-9, "{p}");
        // Numerical derivative of the position agrees with the analytic velocity.
        let numeric = (trajectory.pose_at(2.031).translation.vector
            - trajectory.pose_at(2.029).translation.vector)
            / 0.002;
        assert!((numeric - v).norm() < 1e-6);
    }
}
