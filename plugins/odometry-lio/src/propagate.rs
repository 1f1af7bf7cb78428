//! IMU forward propagation of the state and its covariance (FAST-LIO2, Xu et al., T-RO 2022, Sec.
//! IV-C): between two samples the mean of their measurements drives the kinematics
//! `R ← R·Exp((ω − b_g)Δt)`, `p ← p + vΔt + ½(R(a − b_a) + g)Δt²`, `v ← v + (R(a − b_a) + g)Δt`, and the
//! error state moves by `F = ∂δx⁺/∂δx` with the white noise and bias random walks added as
//! `Q = diag(σ_g², σ_a², σ_bg², σ_ba²)·Δt²`, FAST-LIO2's discretisation.
//!
//! Across a gap in the IMU stream (a dead IMU, dropped samples) the state moves at constant velocity and
//! its last angular rate instead, with the covariance grown as if the accelerations were unknown, so a
//! gap degrades the prediction rather than integrating a stale sample.

use nalgebra::{Matrix3, UnitQuaternion, Vector3};

use crate::state::{BA, BG, Covariance, GRAV, POS, ROT, State, VEL, skew};

/// Process noise per sample, as in FAST-LIO2's configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProcessNoise {
    pub gyro_variance: f64,
    pub accel_variance: f64,
    pub gyro_bias_variance: f64,
    pub accel_bias_variance: f64,
}

/// One bias-corrected motion: angular rate (rad/s) and specific force (m/s²) in the IMU frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Motion {
    pub gyro_radps: Vector3<f64>,
    pub accel_mps2: Vector3<f64>,
}

fn set_block(matrix: &mut Covariance, row: usize, col: usize, value: &Matrix3<f64>) {
    matrix.fixed_view_mut::<3, 3>(row, col).copy_from(value);
}

/// Moves `state` and `covariance` forward by `dt_s` under the raw measurement `motion`.
pub fn propagate(
    state: &mut State,
    covariance: &mut Covariance,
    motion: &Motion,
    dt_s: f64,
    noise: &ProcessNoise,
) {
    if dt_s <= 0.0 {
        return;
    }
    let omega = motion.gyro_radps - state.gyro_bias;
    let accel = motion.accel_mps2 - state.accel_bias;
    let rotation = state.rotation.to_rotation_matrix().into_inner();
    let accel_world = rotation * accel + state.gravity;

    let mut f = Covariance::identity();
    let step = UnitQuaternion::from_scaled_axis(omega * dt_s);
    set_block(
        &mut f,
        ROT,
        ROT,
        &step.inverse().to_rotation_matrix().into_inner(),
    );
    let eye = Matrix3::identity();
    set_block(&mut f, ROT, BG, &(-eye * dt_s));
    set_block(&mut f, POS, VEL, &(eye * dt_s));
    set_block(&mut f, VEL, ROT, &(-rotation * skew(&accel) * dt_s));
    set_block(&mut f, VEL, BA, &(-rotation * dt_s));
    set_block(&mut f, VEL, GRAV, &(eye * dt_s));

    let dt2 = dt_s * dt_s;
    let mut q = Covariance::zeros();
    set_block(&mut q, ROT, ROT, &(eye * noise.gyro_variance * dt2));
    set_block(&mut q, VEL, VEL, &(eye * noise.accel_variance * dt2));
    set_block(&mut q, BG, BG, &(eye * noise.gyro_bias_variance * dt2));
    set_block(&mut q, BA, BA, &(eye * noise.accel_bias_variance * dt2));

    state.position += state.velocity * dt_s + 0.5 * accel_world * dt2;
    state.velocity += accel_world * dt_s;
    state.rotation *= step;
    state.rotation.renormalize();
    *covariance = f * *covariance * f.transpose() + q;
}

/// Moves `state` forward by `dt_s` at constant velocity, turning at `omega_radps` (bias-corrected), for
/// a gap without IMU samples. The covariance grows as if an acceleration of `accel_sigma_mps2` and an
/// angular-rate change of `gyro_sigma_radps` per second were unknown.
pub fn coast(
    state: &mut State,
    covariance: &mut Covariance,
    omega_radps: &Vector3<f64>,
    dt_s: f64,
    accel_sigma_mps2: f64,
    gyro_sigma_radps: f64,
) {
    if dt_s <= 0.0 {
        return;
    }
    let eye = Matrix3::identity();
    let mut f = Covariance::identity();
    set_block(&mut f, POS, VEL, &(eye * dt_s));
    let dt2 = dt_s * dt_s;
    let mut q = Covariance::zeros();
    set_block(&mut q, ROT, ROT, &(eye * (gyro_sigma_radps * dt_s).powi(2)));
    set_block(&mut q, POS, POS, &(eye * (0.5 * accel_sigma_mps2 * dt2).powi(2)));
    set_block(&mut q, VEL, VEL, &(eye * (accel_sigma_mps2 * dt_s).powi(2)));
    state.position += state.velocity * dt_s;
    state.rotation *= UnitQuaternion::from_scaled_axis(omega_radps * dt_s);
    state.rotation.renormalize();
    *covariance = f * *covariance * f.transpose() + q;
}

#[cfg(test)]
mod tests {
    use super::*;

    fn noise() -> ProcessNoise {
        ProcessNoise {
            gyro_variance: 0.1,
            accel_variance: 0.1,
            gyro_bias_variance: 1e-4,
            accel_bias_variance: 1e-4,
        }
    }

    #[test]
    fn integrates_a_turn_at_constant_speed_and_grows_the_covariance() {
        // 1 m/s forward, turning at 0.5 rad/s: the centripetal force is v·ω to the left.
        let mut state = State {
            velocity: Vector3::new(1.0, 0.0, 0.0),
            ..State::default()
        };
        let mut covariance = Covariance::identity() * 1e-6;
        let dt = 0.001;
        for _ in 0..1000 {
            let omega = Vector3::new(0.0, 0.0, 0.5);
            // Specific force: centripetal acceleration minus gravity, in the body frame.
            let accel = Vector3::new(0.0, 0.5, 0.0) - state.rotation.inverse() * state.gravity;
            propagate(
                &mut state,
                &mut covariance,
                &Motion {
                    gyro_radps: omega,
                    accel_mps2: accel,
                },
                dt,
                &noise(),
            );
        }
        // After 1 s on a circle of radius 2 m: heading 0.5 rad, position (2 sin 0.5, 2 (1 − cos 0.5)).
        let (_, _, yaw) = state.rotation.euler_angles();
        assert!((yaw - 0.5).abs() < 1e-6, "{yaw}");
        let expected = Vector3::new(2.0 * 0.5f64.sin(), 2.0 * (1.0 - 0.5f64.cos()), 0.0);
        assert!((state.position - expected).norm() < 2e-3, "{:?}", state.position);
        assert!((state.velocity.norm() - 1.0).abs() < 1e-3);
        assert!(covariance[(POS, POS)] > 1e-6 && covariance[(ROT + 2, ROT + 2)] > 1e-6);
        let before = covariance;
        coast(&mut state, &mut covariance, &Vector3::zeros(), 0.5, 1.0, 0.1);
        assert!(covariance[(POS, POS)] > before[(POS, POS)]);
    }
}
