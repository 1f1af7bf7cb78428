//! The filter's state on its manifold and its 18-dimensional error state, in the FAST-LIO2 formulation
//! (Xu et al., T-RO 2022, Sec. IV): the IMU's attitude `R ∈ SO(3)` and position `p` in the world frame,
//! its velocity `v`, the gyroscope and accelerometer biases `b_g`, `b_a`, and gravity `g` in the world
//! frame. Errors are `δx = [δθ, δp, δv, δb_g, δb_a, δg]` with the attitude perturbed on the right,
//! `R = R̂ · Exp(δθ)`, and `⊞`/`⊟` move between the two.

use nalgebra::{Matrix3, SMatrix, SVector, UnitQuaternion, Vector3};
use skid_core::Pose;

/// Dimension of the error state.
pub const DIM: usize = 18;
/// Offsets of the blocks in the error state.
pub const ROT: usize = 0;
pub const POS: usize = 3;
pub const VEL: usize = 6;
pub const BG: usize = 9;
pub const BA: usize = 12;
pub const GRAV: usize = 15;

pub type ErrorVector = SVector<f64, DIM>;
pub type Covariance = SMatrix<f64, DIM, DIM>;

/// The IMU's state in the world frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct State {
    pub rotation: UnitQuaternion<f64>,
    pub position: Vector3<f64>,
    pub velocity: Vector3<f64>,
    pub gyro_bias: Vector3<f64>,
    pub accel_bias: Vector3<f64>,
    pub gravity: Vector3<f64>,
}

impl Default for State {
    fn default() -> Self {
        Self {
            rotation: UnitQuaternion::identity(),
            position: Vector3::zeros(),
            velocity: Vector3::zeros(),
            gyro_bias: Vector3::zeros(),
            accel_bias: Vector3::zeros(),
            gravity: Vector3::new(0.0, 0.0, -9.81),
        }
    }
}

fn block(error: &ErrorVector, start: usize) -> Vector3<f64> {
    Vector3::new(error[start], error[start + 1], error[start + 2])
}

impl State {
    /// `self ⊞ δx`.
    pub fn plus(&self, error: &ErrorVector) -> Self {
        let mut rotation = self.rotation * UnitQuaternion::from_scaled_axis(block(error, ROT));
        rotation.renormalize();
        Self {
            rotation,
            position: self.position + block(error, POS),
            velocity: self.velocity + block(error, VEL),
            gyro_bias: self.gyro_bias + block(error, BG),
            accel_bias: self.accel_bias + block(error, BA),
            gravity: self.gravity + block(error, GRAV),
        }
    }

    /// `self ⊟ other`: the error that takes `other` to `self`.
    pub fn minus(&self, other: &Self) -> ErrorVector {
        let mut error = ErrorVector::zeros();
        let parts = [
            (other.rotation.inverse() * self.rotation).scaled_axis(),
            self.position - other.position,
            self.velocity - other.velocity,
            self.gyro_bias - other.gyro_bias,
            self.accel_bias - other.accel_bias,
            self.gravity - other.gravity,
        ];
        for (index, part) in parts.iter().enumerate() {
            error.fixed_rows_mut::<3>(3 * index).copy_from(part);
        }
        error
    }

    /// The IMU's pose in the world frame.
    pub fn world_from_imu(&self) -> Pose {
        Pose::from_parts(self.position.into(), self.rotation)
    }

    /// Every value finite.
    pub fn is_finite(&self) -> bool {
        self.rotation.coords.iter().all(|v| v.is_finite())
            && [
                self.position,
                self.velocity,
                self.gyro_bias,
                self.accel_bias,
                self.gravity,
            ]
            .iter()
            .all(|v| v.iter().all(|x| x.is_finite()))
    }
}

/// The skew-symmetric matrix of `v`, `[v]×`.
pub fn skew(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plus_and_minus_are_inverse() {
        let state = State {
            rotation: UnitQuaternion::from_euler_angles(0.1, -0.2, 0.3),
            position: Vector3::new(1.0, 2.0, 3.0),
            velocity: Vector3::new(0.5, 0.0, -0.1),
            ..State::default()
        };
        let mut error = ErrorVector::zeros();
        for (i, value) in error.iter_mut().enumerate() {
            *value = 0.01 * (i as f64 - 8.0);
        }
        let moved = state.plus(&error);
        assert!((moved.minus(&state) - error).norm() < 1e-12);
        assert!(state.minus(&state).norm() < 1e-15);
    }
}
