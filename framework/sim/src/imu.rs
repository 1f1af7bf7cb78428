//! A 200 Hz IMU in the sensor frame: specific force and angular rate from the trajectory, with white
//! noise and bias random walk, the standard continuous-time model used by Kalibr and most VIO/LIO work
//! (Furgale et al., IROS 2013; Trawny and Roumeliotis, "Indirect Kalman filter for 3D attitude
//! estimation", 2005).
//!
//! The default is the MicroStrain 3DM-GX5-25 of the paper's rover, at its data sheet's values
//! ([`ImuNoise::gx5_25`]); [`ImuNoise::cv7`] is the 3DM-CV7-AHRS of its quadruped. Data sheets give a
//! bias *instability* B (the floor of the Allan deviation), not a random walk; SKiD takes the random
//! walk K whose Allan deviation `K·√(τ/3)` reaches B at τ = 1000 s, the end of a MEMS unit's flat
//! floor: `K = B·√(3 / 1000 s)`. The turn-on bias is drawn once per unit with the data sheet's
//! initial bias error as its 1σ.

use nalgebra::{UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};
use skid_core::ImuSample;
use skid_core::Pose;

use crate::motion::GRAVITY_MPS2;
use crate::rng::Rng;
use crate::trajectory::Trajectory;

/// IMU noise parameters (continuous-time densities).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
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
    /// 1σ of the accelerometer's bias at power-on, m/s².
    pub accel_turn_on_bias: f64,
    /// 1σ of the gyroscope's bias at power-on, rad/s.
    pub gyro_turn_on_bias: f64,
}

/// Standard gravity, for data sheets in g.
const G_MPS2: f64 = 9.80665;
/// `K = B·√(3 / τ)` with τ = 1000 s (see the module documentation).
const RANDOM_WALK_PER_INSTABILITY: f64 = 0.054_772_255_750_516_61;

impl ImuNoise {
    /// MicroStrain 3DM-GX5-25 data sheet: accelerometer noise density 100 µg/√Hz, bias instability
    /// ±0.04 mg, initial bias error ±0.002 g; gyroscope noise density 0.005 °/s/√Hz, bias instability
    /// 8 °/h, initial bias error ±0.04 °/s.
    pub fn gx5_25() -> Self {
        Self::from_data_sheet(100e-6, 0.04e-3, 0.002, 0.005, 8.0, 0.04)
    }

    /// MicroStrain 3DM-CV7-AHRS data sheet: accelerometer noise density 25 µg/√Hz, bias instability
    /// 0.01 mg; gyroscope noise density 0.0023 °/s/√Hz (angle random walk 0.14 °/√h), bias instability
    /// 1.5 °/h; initial bias errors taken as the GX5-25's.
    pub fn cv7() -> Self {
        Self::from_data_sheet(25e-6, 0.01e-3, 0.002, 0.0023, 1.5, 0.04)
    }

    /// Densities from a data sheet's units: accelerometer noise density in g/√Hz, bias instability and
    /// initial bias in g; gyroscope noise density in °/s/√Hz, bias instability in °/h, initial bias
    /// in °/s.
    fn from_data_sheet(
        accel_noise_g: f64,
        accel_instability_g: f64,
        accel_initial_g: f64,
        gyro_noise_dps: f64,
        gyro_instability_dph: f64,
        gyro_initial_dps: f64,
    ) -> Self {
        Self {
            rate_hz: 200.0,
            accel_noise_density: accel_noise_g * G_MPS2,
            accel_bias_random_walk: accel_instability_g * G_MPS2 * RANDOM_WALK_PER_INSTABILITY,
            gyro_noise_density: gyro_noise_dps.to_radians(),
            gyro_bias_random_walk: (gyro_instability_dph / 3600.0).to_radians() * RANDOM_WALK_PER_INSTABILITY,
            accel_turn_on_bias: accel_initial_g * G_MPS2,
            gyro_turn_on_bias: gyro_initial_dps.to_radians(),
        }
    }
}

impl Default for ImuNoise {
    fn default() -> Self {
        Self::gx5_25()
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
    /// Where the IMU is mounted: its pose in the sensor (LiDAR) frame.
    sensor_from_imu: Pose,
    /// The IMU's clock runs this far ahead of the LiDAR's, in seconds.
    clock_offset_s: f64,
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
            accel_turn_on_bias: 0.0,
            gyro_turn_on_bias: 0.0,
            ..ImuNoise::default()
        });
        let accel_bias =
            Vector3::new(rng.gaussian(), rng.gaussian(), rng.gaussian()) * noise_or_zero.accel_turn_on_bias;
        let gyro_bias =
            Vector3::new(rng.gaussian(), rng.gaussian(), rng.gaussian()) * noise_or_zero.gyro_turn_on_bias;
        Self {
            noise: noise_or_zero,
            rng,
            accel_bias,
            gyro_bias,
            next_index: 0,
            sensor_from_imu: Pose::identity(),
            clock_offset_s: 0.0,
        }
    }

    /// Mounts the IMU at `sensor_from_imu` in the sensor frame (a lever arm and a rotation), with its
    /// clock `clock_offset_s` ahead of the LiDAR's: samples then measure the IMU frame's motion and carry
    /// the IMU's stamps.
    pub fn mounted(mut self, sensor_from_imu: Pose, clock_offset_s: f64) -> Self {
        self.sensor_from_imu = sensor_from_imu;
        self.clock_offset_s = clock_offset_s;
        self
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
            // The IMU's clock reads `clock_offset_s` ahead: this stamp was taken at LiDAR time t.
            let t = stamp_nanos as f64 * 1e-9 - self.clock_offset_s;
            let (rotation, acceleration, rate) = self.imu_motion(trajectory, t);
            let specific_force = rotation.inverse() * (acceleration + Vector3::new(0.0, 0.0, GRAVITY_MPS2));
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

    /// The IMU frame's attitude, world acceleration and body angular rate at `t_s`: the sensor's, moved
    /// through the mounting (the lever arm adds `R̈_WS · t_SI`, taken by a central difference).
    fn imu_motion(
        &self,
        trajectory: &Trajectory,
        t_s: f64,
    ) -> (UnitQuaternion<f64>, Vector3<f64>, Vector3<f64>) {
        let sensor = trajectory.pose_at(t_s);
        let (_, sensor_acceleration) = trajectory.velocity_acceleration_at(t_s);
        let sensor_rate = trajectory.angular_velocity_at(t_s);
        let mount = self.sensor_from_imu;
        let rotation = sensor.rotation * mount.rotation;
        let rate = mount.rotation.inverse() * sensor_rate;
        let lever = mount.translation.vector;
        if lever == Vector3::zeros() {
            return (rotation, sensor_acceleration, rate);
        }
        let h = 1e-3;
        let (before, after) = (trajectory.pose_at(t_s - h), trajectory.pose_at(t_s + h));
        let lever_acceleration =
            (after.rotation * lever + before.rotation * lever - 2.0 * (sensor.rotation * lever)) / (h * h);
        (rotation, sensor_acceleration + lever_acceleration, rate)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Translation3;

    /// A sensor spinning in place about the vertical at `rate` rad/s, as control poses every 10 ms.
    fn spinning(rate: f64) -> Trajectory {
        let controls = (0..400)
            .map(|k| {
                Pose::from_parts(
                    Translation3::new(0.0, 0.0, 1.0),
                    UnitQuaternion::from_euler_angles(0.0, 0.0, rate * 0.01 * f64::from(k)),
                )
            })
            .collect();
        Trajectory::new(0.0, 0.01, controls)
    }

    #[test]
    fn a_lever_arm_feels_the_centripetal_acceleration_and_a_rotated_mount_turns_the_rates() {
        let rate = 2.0;
        // The IMU 1 m ahead of the spinning sensor: it circles at radius 1 m.
        let mount = Pose::from_parts(Translation3::new(1.0, 0.0, 0.0), UnitQuaternion::identity());
        let mut imu = ImuSimulator::new(None, 1).mounted(mount, 0.0);
        let samples = imu.samples_until(&spinning(rate), 2_000_000_000);
        let middle = samples[200];
        let expected = [-rate * rate, 0.0, GRAVITY_MPS2];
        for (got, want) in middle.accel_mps2.iter().zip(expected) {
            assert!((got - want).abs() < 1e-3, "{:?}", middle.accel_mps2);
        }
        assert!((middle.gyro_radps[2] - rate).abs() < 1e-6);
        // Mounted upside down (rolled 180°): the yaw rate and gravity change sign in its frame.
        let flipped = Pose::from_parts(
            Translation3::identity(),
            UnitQuaternion::from_euler_angles(std::f64::consts::PI, 0.0, 0.0),
        );
        let mut imu = ImuSimulator::new(None, 1).mounted(flipped, 0.0);
        let sample = imu.samples_until(&spinning(rate), 2_000_000_000)[200];
        assert!(
            (sample.gyro_radps[2] + rate).abs() < 1e-6,
            "{:?}",
            sample.gyro_radps
        );
        assert!(
            (sample.accel_mps2[2] + GRAVITY_MPS2).abs() < 1e-6,
            "{:?}",
            sample.accel_mps2
        );
    }

    #[test]
    fn a_clock_offset_shifts_the_stamps_not_the_motion() {
        let trajectory = spinning(1.0);
        let mut exact = ImuSimulator::new(None, 1);
        let mut ahead = ImuSimulator::new(None, 1).mounted(Pose::identity(), 0.05);
        let a = exact.samples_until(&trajectory, 3_000_000_000);
        let b = ahead.samples_until(&trajectory, 3_000_000_000);
        // The sample stamped 50 ms later on the offset clock measured the same instant.
        for (x, y) in a[100].accel_mps2.iter().zip(&b[110].accel_mps2) {
            assert!(
                (x - y).abs() < 1e-9,
                "{:?} {:?}",
                a[100].accel_mps2,
                b[110].accel_mps2
            );
        }
        assert_eq!(b[110].stamp_nanos, 550_000_000);
    }
}
