//! Casting one sweep: each firing group takes the sensor pose at its own instant (so a moving robot's
//! scan is distorted exactly like a real one), every ray is cast against the world, and the return is
//! degraded by range noise, dropouts and spurious returns.
//!
//! Effects modelled per ray, each from the ray's own random stream (results never depend on threads):
//! - range noise: Gaussian, the sensor's σ times `range_noise_scale`;
//! - dropouts: the configured rate, plus near-certain loss at grazing incidence (cos θ < 0.05) and
//!   weak-return loss when albedo · cos θ · (10 m / r)² falls below 0.002 (inverse-square falloff);
//! - spurious returns at the configured rate: half are early returns (dust, rain, glare) somewhere
//!   along the ray, half multipath reflections that appear 0.5–15 m behind the true surface;
//! - intensity: Lambertian, albedo · cos θ, with ±5 % uniform noise.

use rayon::prelude::*;
use skid_core::{Pose, RawPoint};

use crate::geometry::{Ray, V3};
use crate::rng::{Rng, combine};
use crate::sensor::Sensor;
use crate::world::World;

/// Degradations applied to a sweep.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScanNoise {
    /// Multiplies the sensor's range σ (0 = exact ranges).
    pub range_noise_scale: f64,
    /// Probability that a valid return is lost.
    pub dropout_rate: f64,
    /// Probability that a return is replaced by a spurious one.
    pub spurious_rate: f64,
}

impl ScanNoise {
    /// No noise at all: exact ranges, no dropouts, no spurious returns (the physical losses at grazing
    /// incidence and for weak returns still apply).
    pub const NONE: Self = Self {
        range_noise_scale: 0.0,
        dropout_rate: 0.0,
        spurious_rate: 0.0,
    };
}

impl Default for ScanNoise {
    fn default() -> Self {
        Self {
            range_noise_scale: 1.0,
            dropout_rate: 0.01,
            spurious_rate: 0.0005,
        }
    }
}

fn cast_ray(
    world: &World,
    sensor: &Sensor,
    noise: &ScanNoise,
    origin: V3,
    rotation: &[[f32; 3]; 3],
    dir: V3,
    key: u64,
) -> Option<(f32, f32)> {
    let world_dir = V3::new(
        rotation[0][0] * dir.x + rotation[0][1] * dir.y + rotation[0][2] * dir.z,
        rotation[1][0] * dir.x + rotation[1][1] * dir.y + rotation[1][2] * dir.z,
        rotation[2][0] * dir.x + rotation[2][1] * dir.y + rotation[2][2] * dir.z,
    );
    let hit = world.cast(&Ray::new(origin, world_dir), sensor.max_range_m as f32)?;
    let range = f64::from(hit.range_m);
    if range < sensor.min_range_m {
        return None;
    }
    let mut rng = Rng::new(key);
    let cos_incidence = f64::from(hit.normal.dot(world_dir).abs());
    let albedo = f64::from(hit.material.albedo());
    let strength = albedo * cos_incidence * (10.0 / range).powi(2);
    if rng.chance(noise.dropout_rate) || cos_incidence < 0.05 && rng.chance(0.9) || strength < 0.002 {
        return None;
    }
    let (mut range, mut intensity) = (range, albedo * cos_incidence * (1.0 + rng.range(-0.05, 0.05)));
    if rng.chance(noise.spurious_rate) {
        range = if rng.chance(0.5) {
            rng.range(sensor.min_range_m, range)
        } else {
            range + rng.range(0.5, 15.0)
        };
        intensity = rng.range(0.0, 0.1);
    }
    range += sensor.range_noise_m * noise.range_noise_scale * rng.gaussian();
    (range >= sensor.min_range_m && range <= sensor.max_range_m)
        .then_some((range as f32, intensity.clamp(0.0, 1.0) as f32))
}

/// Simulates one sweep starting at `sweep_start_s`, with `world_from_sensor(t)` giving the sensor pose
/// at absolute time t. Points are in the sensor frame of their own firing instant, in firing order.
/// `key` seeds the noise; `parallel` spreads the groups over the current rayon pool.
pub fn simulate_sweep(
    world: &World,
    sensor: &Sensor,
    world_from_sensor: &(dyn Fn(f64) -> Pose + Sync),
    sweep_start_s: f64,
    noise: &ScanNoise,
    key: u64,
    parallel: bool,
) -> Vec<RawPoint> {
    let per_group = sensor.rays_per_group();
    let group_points = |group: usize, out: &mut [Option<RawPoint>]| {
        let offset_s = sensor.group_time_offset_s(group);
        let pose = world_from_sensor(sweep_start_s + offset_s);
        let t = pose.translation.vector;
        let origin = V3::from_f64(t.x, t.y, t.z);
        let m = pose.rotation.to_rotation_matrix();
        let rotation: [[f32; 3]; 3] = std::array::from_fn(|r| std::array::from_fn(|c| m[(r, c)] as f32));
        for (ray, slot) in out.iter_mut().enumerate() {
            let dir = sensor.direction(group, ray, sweep_start_s);
            let ray_key = combine(key, (group * per_group + ray) as u64);
            *slot =
                cast_ray(world, sensor, noise, origin, &rotation, dir, ray_key).map(|(range, intensity)| {
                    let p = dir * range;
                    RawPoint::new(p.x, p.y, p.z, intensity, offset_s as f32, ray as u16)
                });
        }
    };
    let mut slots = vec![None; sensor.rays_per_sweep()];
    if parallel {
        slots
            .par_chunks_mut(per_group)
            .enumerate()
            .for_each(|(group, out)| group_points(group, out));
    } else {
        slots
            .chunks_mut(per_group)
            .enumerate()
            .for_each(|(group, out)| group_points(group, out));
    }
    slots.into_iter().flatten().collect()
}
