//! A 200 Hz IMU in the sensor frame: specific force and angular rate from the trajectory, with white
//! noise and bias random walk, the standard continuous-time model used by Kalibr and most VIO/LIO work
//! (Furgale et al., IROS 2013; Trawny and Roumeliotis, "Indirect Kalman filter for 3D attitude
//! estimation", 2005). Default densities are those of a mid-grade MEMS unit (ADIS16448 class).

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use skid_core::ImuSample;

use crate::motion::GRAVITY_MPS2;
use crate::rng::Rng;
use crate::trajectory::Trajectory;

/// IMU noise parameters (continuous-time densities).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ImuNoise {
    pub rate_hz: f64,
    /// Accelerometer white noise, m/s²/√Hz.
    pub accel_noise_density: f64,
    /// Accelerometer bias random walk, m/s³/√Hz.
    pub accel_bias_random_walk: f64,
    /// Gyroscope white noise, rad/s/√Hz.
    pub gyro_noise_density: f64,
    /// Gyroscope bias random walk, rad/s²/√Hz.
    pub gyro_bias_random_walk: f64,
}

impl Default for ImuNoise {
    fn default() -> Self {
        Self {
            rate_hz: 200.0,
            accel_noise_density: 2.0e-3,
            accel_bias_random_walk: 3.0e-3,
            gyro_noise_density: 1.7e-4,
            gyro_bias_random_walk: 2.0e-5,
        }
    }
}

/// Produces IMU samples in time order, carrying the bias state.
#[derive(Clone, Debug)]
pub struct ImuSimulator {
    noise: ImuNoise,
    rng: Rng,
    accel_bias: Vector3<f64>,
    gyro_bias: Vector3<f64>,
    next_index: u64,
}

impl ImuSimulator {
    /// A simulator whose first sample is at t = 0; `noise = None` gives perfect measurements.
    pub fn new(noise: Option<ImuNoise>, seed: u64) -> Self {
        let mut rng = Rng::new(seed);
        let noise_or_zero = noise.unwrap_or(ImuNoise {
            accel_noise_density: 0.0,
            accel_bias_random_walk: 0.0,
            gyro_noise_density: 0.0,
            gyro_bias_random_walk: 0.0,
            ..ImuNoise::default()
        });
        // Turn-on biases of a few mg and a few tenths of a degree per second, when noise is on.
        let on = if noise.is_some() { 1.0 } else { 0.0 };
        let accel_bias = Vector3::new(rng.gaussian(), rng.gaussian(), rng.gaussian()) * 0.03 * on;
        let gyro_bias = Vector3::new(rng.gaussian(), rng.gaussian(), rng.gaussian()) * 0.002 * on;
        Self {
            noise: noise_or_zero,
            rng,
            accel_bias,
            gyro_bias,
            next_index: 0,
        }
    }

    fn period_nanos(&self) -> u64 {
        (1e9 / self.noise.rate_hz).round() as u64
    }

    /// Every sample with a stamp up to and including `until_nanos` not yet produced.
    pub fn samples_until(&mut self, trajectory: &Trajectory, until_nanos: u64) -> Vec<ImuSample> {
        let period = self.period_nanos();
        let dt = period as f64 * 1e-9;
        let mut samples = Vec::new();
        while self.next_index * period <= until_nanos {
            let stamp_nanos = self.next_index * period;
            let t = stamp_nanos as f64 * 1e-9;
            let rotation = trajectory.pose_at(t).rotation;
            let (_, acceleration) = trajectory.velocity_acceleration_at(t);
            let specific_force = rotation.inverse() * (acceleration + Vector3::new(0.0, 0.0, GRAVITY_MPS2));
            let rate = trajectory.angular_velocity_at(t);
            let white = |rng: &mut Rng, density: f64| {
                Vector3::new(rng.gaussian(), rng.gaussian(), rng.gaussian()) * density / dt.sqrt()
            };
            let accel =
                specific_force + self.accel_bias + white(&mut self.rng, self.noise.accel_noise_density);
            let gyro = rate + self.gyro_bias + white(&mut self.rng, self.noise.gyro_noise_density);
            self.accel_bias += white(&mut self.rng, self.noise.accel_bias_random_walk) * dt;
            self.gyro_bias += white(&mut self.rng, self.noise.gyro_bias_random_walk) * dt;
            samples.push(ImuSample {
                stamp_nanos,
                accel_mps2: [accel.x, accel.y, accel.z],
                gyro_radps: [gyro.x, gyro.y, gyro.z],
            });
            self.next_index += 1;
        }
        samples
    }
}
