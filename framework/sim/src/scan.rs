//! Casting one sweep: each firing group takes the sensor pose at its own instant (so a moving robot's
//! scan is distorted exactly like a real one), every ray is cast against the world, and the return is
//! degraded by range noise, dropouts and spurious returns.
//!
//! Effects modelled per ray, each from the ray's own random stream (results never depend on threads);
//! the data-sheet models are [`crate::sensor_errors`]'s:
//! - beam angles: the ray leaves along the unit's true beam direction, the point is reported along its
//!   calibration table's;
//! - range noise: Gaussian, the data-sheet σ at the return's signal-to-noise ratio, times
//!   `range_noise_scale`;
//! - dropouts: the configured rate, plus near-certain loss at grazing incidence (cos θ < 0.05) and
//!   weak-return loss below the sensor's detection threshold (its rated range on an 80 % target);
//! - mixed returns next to depth edges, from the beam's divergence (spinning sensors);
//! - spurious returns at the configured rate: half are early returns (dust, rain, glare) somewhere
//!   along the ray, half multipath reflections that appear 0.5–15 m behind the true surface;
//! - intensity: Lambertian, albedo · cos θ, with ±5 % uniform noise.

use rayon::prelude::*;
use skid_core::{Pose, RawPoint};

use crate::bodies::{Peers, PlacedBody, cast_bodies};
use crate::geometry::{Ray, V3};
use crate::rng::{Rng, combine};
use crate::sensor::SWEEP_PERIOD_S;
use crate::sensor::Sensor;
use crate::sensor_errors::{BeamErrors, detection_probability, mix_depth_edges, range_sigma_m, snr};
use crate::world::{Hit, Material, World};

/// Degradations applied to a sweep.
#[derive(Clone, Debug, PartialEq)]
pub struct ScanNoise {
    /// Multiplies the sensor's range σ (0 = exact ranges).
    pub range_noise_scale: f64,
    /// Probability that a valid return is lost.
    pub dropout_rate: f64,
    /// Probability that a return is replaced by a spurious one.
    pub spurious_rate: f64,
    /// Mixed returns at depth edges (beam divergence).
    pub mixed_returns: bool,
    /// The unit's beam-angle errors.
    pub beam_errors: BeamErrors,
}

impl ScanNoise {
    /// No noise at all: exact ranges and angles, no dropouts, no spurious or mixed returns (the physical
    /// losses at grazing incidence and for weak returns still apply).
    pub const NONE: Self = Self {
        range_noise_scale: 0.0,
        dropout_rate: 0.0,
        spurious_rate: 0.0,
        mixed_returns: false,
        beam_errors: BeamErrors::none(),
    };
}

impl Default for ScanNoise {
    /// The data sheets' errors, without beam-angle errors (they belong to a unit: see
    /// [`BeamErrors::drawn`]).
    fn default() -> Self {
        Self {
            range_noise_scale: 1.0,
            dropout_rate: 0.01,
            spurious_rate: 0.0005,
            mixed_returns: true,
            beam_errors: BeamErrors::none(),
        }
    }
}

fn cast_ray(
    (world, bodies): (&World, &[PlacedBody]),
    sensor: &Sensor,
    noise: &ScanNoise,
    (origin, rotation): (V3, &[[f32; 3]; 3]),
    beam: usize,
    dir: V3,
    key: u64,
) -> Option<(f32, f32)> {
    let dir = noise.beam_errors.true_direction(beam, dir);
    let world_dir = V3::new(
        rotation[0][0] * dir.x + rotation[0][1] * dir.y + rotation[0][2] * dir.z,
        rotation[1][0] * dir.x + rotation[1][1] * dir.y + rotation[1][2] * dir.z,
        rotation[2][0] * dir.x + rotation[2][1] * dir.y + rotation[2][2] * dir.z,
    );
    let ray = Ray::new(origin, world_dir);
    let surface = world.cast(&ray, sensor.max_range_m as f32);
    let limit = surface
        .as_ref()
        .map_or(sensor.max_range_m as f32, |hit| hit.range_m);
    let hit = match cast_bodies(bodies, &ray, limit) {
        Some((range_m, normal)) => Hit {
            range_m,
            normal,
            material: Material::Metal,
        },
        None => surface?,
    };
    let range = f64::from(hit.range_m);
    if range < sensor.min_range_m {
        return None;
    }
    let mut rng = Rng::new(key);
    let cos_incidence = f64::from(hit.normal.dot(world_dir).abs());
    let albedo = f64::from(hit.material.albedo());
    let snr = snr(sensor, albedo * cos_incidence * (10.0 / range).powi(2));
    if rng.chance(noise.dropout_rate)
        || cos_incidence < 0.05 && rng.chance(0.9)
        || !rng.chance(detection_probability(snr))
    {
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
    range += range_sigma_m(sensor, snr) * noise.range_noise_scale * rng.gaussian();
    (range >= sensor.min_range_m && range <= sensor.max_range_m)
        .then_some((range as f32, intensity.clamp(0.0, 1.0) as f32))
}

/// Simulates one sweep starting at `sweep_start_s`, with `world_from_sensor(t)` giving the sensor pose
/// at absolute time t. Points are in the sensor frame of their own firing instant, in firing order.
/// `key` seeds the noise; `parallel` spreads the groups over the current rayon pool. No other robot is
/// in the world: see [`simulate_sweep_among`].
pub fn simulate_sweep(
    world: &World,
    sensor: &Sensor,
    world_from_sensor: &(dyn Fn(f64) -> Pose + Sync),
    sweep_start_s: f64,
    noise: &ScanNoise,
    key: u64,
    parallel: bool,
) -> Vec<RawPoint> {
    let nobody = Peers::default();
    simulate_sweep_among(
        (world, &nobody),
        sensor,
        world_from_sensor,
        sweep_start_s,
        noise,
        key,
        parallel,
    )
}

/// [`simulate_sweep`] in a world shared with `peers`: the other robots' bodies, each where its own
/// trajectory has it at the instant a ray is fired.
pub fn simulate_sweep_among(
    (world, peers): (&World, &Peers),
    sensor: &Sensor,
    world_from_sensor: &(dyn Fn(f64) -> Pose + Sync),
    sweep_start_s: f64,
    noise: &ScanNoise,
    key: u64,
    parallel: bool,
) -> Vec<RawPoint> {
    let per_group = sensor.rays_per_group();
    let start = world_from_sensor(sweep_start_s).translation.vector;
    let nearby = peers.within(
        V3::from_f64(start.x, start.y, start.z),
        sweep_start_s,
        sweep_start_s + SWEEP_PERIOD_S,
        sensor.max_range_m as f32,
    );
    let group_points = |group: usize, out: &mut [Option<(f32, f32)>]| {
        let offset_s = sensor.group_time_offset_s(group);
        let pose = world_from_sensor(sweep_start_s + offset_s);
        let bodies = Peers::placed(&nearby, sweep_start_s + offset_s);
        let t = pose.translation.vector;
        let origin = V3::from_f64(t.x, t.y, t.z);
        let m = pose.rotation.to_rotation_matrix();
        let rotation: [[f32; 3]; 3] = std::array::from_fn(|r| std::array::from_fn(|c| m[(r, c)] as f32));
        for (ray, slot) in out.iter_mut().enumerate() {
            let dir = sensor.direction(group, ray, sweep_start_s);
            let ray_key = combine(key, (group * per_group + ray) as u64);
            *slot = cast_ray(
                (world, &bodies),
                sensor,
                noise,
                (origin, &rotation),
                ray,
                dir,
                ray_key,
            );
        }
    };
    let mut slots: Vec<Option<(f32, f32)>> = vec![None; sensor.rays_per_sweep()];
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
    if noise.mixed_returns {
        mix_depth_edges(sensor, &mut slots, combine(key, 0x3d9e));
    }
    slots
        .into_iter()
        .enumerate()
        .filter_map(|(index, slot)| {
            let (range, intensity) = slot?;
            let (group, ray) = (index / per_group, index % per_group);
            let p = sensor.direction(group, ray, sweep_start_s) * range;
            let offset_s = sensor.group_time_offset_s(group) as f32;
            Some(RawPoint::new(p.x, p.y, p.z, intensity, offset_s, ray as u16))
        })
        .collect()
}
