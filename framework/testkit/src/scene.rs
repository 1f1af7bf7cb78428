//! A deterministic synthetic outdoor scene (ground with gentle relief, building walls, boxes, poles and
//! rocks) that can be sampled from any sensor pose like a 360° LiDAR would see it: points on the
//! surfaces within range, with fresh random samples per scan.

use nalgebra::{Point3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use skid_core::{Cloud, Point, Pose, RawPoint};

/// An axis-aligned box obstacle.
#[derive(Clone, Copy, Debug)]
struct Block {
    min: Point3<f64>,
    max: Point3<f64>,
}

/// The scene: a set of boxes and vertical cylinders on a rolling ground.
#[derive(Clone, Debug)]
pub struct Scene {
    blocks: Vec<Block>,
    poles: Vec<(Point3<f64>, f64, f64)>,
    extent_m: f64,
}

impl Scene {
    /// A scene of `extent_m` half-width with objects placed from `seed`.
    pub fn new(seed: u64, extent_m: f64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut blocks = Vec::new();
        for _ in 0..40 {
            let centre = Point3::new(
                rng.random_range(-extent_m..extent_m),
                rng.random_range(-extent_m..extent_m),
                0.0,
            );
            if centre.coords.xy().norm() < 6.0 {
                continue;
            }
            let half = Vector3::new(
                rng.random_range(0.5..6.0),
                rng.random_range(0.5..6.0),
                rng.random_range(0.5..4.0),
            );
            blocks.push(Block {
                min: centre - Vector3::new(half.x, half.y, 0.0),
                max: centre + Vector3::new(half.x, half.y, 2.0 * half.z),
            });
        }
        let poles = (0..30)
            .map(|_| {
                let base = Point3::new(
                    rng.random_range(-extent_m..extent_m),
                    rng.random_range(-extent_m..extent_m),
                    0.0,
                );
                (base, rng.random_range(0.1..0.4), rng.random_range(2.0..8.0))
            })
            .collect();
        Self {
            blocks,
            poles,
            extent_m,
        }
    }

    /// Ground height at (x, y).
    pub fn ground_z(&self, x: f64, y: f64) -> f64 {
        0.3 * (x * 0.05).sin() + 0.2 * (y * 0.07).cos()
    }

    /// Samples about `count` surface points visible within `range_m` of `world_from_sensor`, returned in the
    /// sensor frame. Visibility is approximated by range only (no occlusion), which is enough for the
    /// registration and odometry contracts.
    pub fn sample(&self, world_from_sensor: &Pose, count: usize, range_m: f64, seed: u64) -> Cloud {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let centre = world_from_sensor.translation.vector;
        let sensor_from_world = world_from_sensor.inverse();
        let mut points = Vec::with_capacity(count);
        let mut attempts = 0;
        while points.len() < count && attempts < count * 20 {
            attempts += 1;
            let world = match rng.random_range(0..10) {
                0..=4 => {
                    // Ground, denser near the sensor as a spinning LiDAR's rings are.
                    let r = range_m * rng.random::<f64>().powf(1.5);
                    let a = rng.random_range(0.0..std::f64::consts::TAU);
                    let (x, y) = (centre.x + r * a.cos(), centre.y + r * a.sin());
                    Point3::new(x, y, self.ground_z(x, y))
                }
                5..=8 => {
                    let Some(block) = self.blocks.get(rng.random_range(0..self.blocks.len().max(1))) else {
                        continue;
                    };
                    sample_block(block, &mut rng)
                }
                _ => {
                    let Some(&(base, radius, height)) =
                        self.poles.get(rng.random_range(0..self.poles.len().max(1)))
                    else {
                        continue;
                    };
                    let a = rng.random_range(0.0..std::f64::consts::TAU);
                    Point3::new(
                        base.x + radius * a.cos(),
                        base.y + radius * a.sin(),
                        rng.random_range(0.0..height),
                    )
                }
            };
            if (world.coords - centre).norm() > range_m || world.x.abs() > self.extent_m * 1.2 {
                continue;
            }
            let local = sensor_from_world * world;
            points.push(Point::with_intensity(
                local.x as f32,
                local.y as f32,
                local.z as f32,
                0.5,
            ));
        }
        Cloud::new(points)
    }

    /// Like [`Scene::sample`], as raw scan points with zero time offsets.
    pub fn sample_raw(
        &self,
        world_from_sensor: &Pose,
        count: usize,
        range_m: f64,
        seed: u64,
    ) -> Vec<RawPoint> {
        self.sample(world_from_sensor, count, range_m, seed)
            .points
            .iter()
            .map(|p| RawPoint::new(p.x, p.y, p.z, p.intensity, 0.0, RawPoint::UNKNOWN_RING))
            .collect()
    }
}

fn sample_block(block: &Block, rng: &mut ChaCha8Rng) -> Point3<f64> {
    let (min, max) = (block.min, block.max);
    let face = rng.random_range(0..5);
    let (u, v) = (rng.random::<f64>(), rng.random::<f64>());
    let lerp = |a: f64, b: f64, t: f64| a + (b - a) * t;
    match face {
        0 => Point3::new(min.x, lerp(min.y, max.y, u), lerp(min.z, max.z, v)),
        1 => Point3::new(max.x, lerp(min.y, max.y, u), lerp(min.z, max.z, v)),
        2 => Point3::new(lerp(min.x, max.x, u), min.y, lerp(min.z, max.z, v)),
        3 => Point3::new(lerp(min.x, max.x, u), max.y, lerp(min.z, max.z, v)),
        _ => Point3::new(lerp(min.x, max.x, u), lerp(min.y, max.y, v), max.z),
    }
}

/// A pose on the ground plane: position (x, y, z) and yaw in radians.
pub fn planar_pose(x: f64, y: f64, z: f64, yaw_rad: f64) -> Pose {
    Pose::new(Vector3::new(x, y, z), Vector3::new(0.0, 0.0, yaw_rad))
}

/// A pose `x_m` along the x axis, turned `yaw_deg` degrees about z: the frames of tests that place one
/// robot in another's.
pub fn x_yaw_pose(x_m: f64, yaw_deg: f64) -> Pose {
    planar_pose(x_m, 0.0, 0.0, yaw_deg.to_radians())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_are_deterministic_finite_and_within_range() {
        let scene = Scene::new(1, 60.0);
        let pose = planar_pose(3.0, -2.0, 1.8, 0.4);
        let a = scene.sample(&pose, 5_000, 40.0, 9);
        let b = scene.sample(&pose, 5_000, 40.0, 9);
        assert_eq!(a, b);
        assert_eq!(a.len(), 5_000);
        assert!(a.points.iter().all(|p| p.is_finite() && p.range_m() <= 40.01));
        let c = scene.sample(&pose, 5_000, 40.0, 10);
        assert_ne!(a, c);
    }
}
