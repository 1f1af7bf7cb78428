//! The local map of KISS-ICP (Vizzo et al., RA-L 2023): a hash map from integer voxel coordinates to the
//! points that fell into the voxel, at most `max_points_per_voxel` of them and no two closer than
//! `√(v² / max_points_per_voxel)`. Nearest neighbours are searched in the 27 voxels around a query, and
//! voxels farther than the maximum range from the robot are dropped after every update.
//!
//! The hash is our own (a multiply-and-mix of the packed coordinates) and carries no random state, so
//! the map behaves identically from run to run.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hash, Hasher};

use nalgebra::Point3;
use skid_core::Pose;

/// Integer coordinates of a voxel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct VoxelKey(pub [i32; 3]);

impl VoxelKey {
    /// The voxel of `point` in a grid of `voxel_size_m`.
    pub fn of(point: &Point3<f64>, voxel_size_m: f64) -> Self {
        Self([
            (point.x / voxel_size_m).floor() as i32,
            (point.y / voxel_size_m).floor() as i32,
            (point.z / voxel_size_m).floor() as i32,
        ])
    }
}

impl Hash for VoxelKey {
    fn hash<H: Hasher>(&self, state: &mut H) {
        let [x, y, z] = self.0.map(|c| u64::from(c as u32));
        // Large odd multipliers spread neighbouring voxels over the whole 64-bit range.
        let packed = x.wrapping_mul(0x9e37_79b9_7f4a_7c15)
            ^ y.wrapping_mul(0xc2b2_ae3d_27d4_eb4f)
            ^ z.wrapping_mul(0x1656_67b1_9e37_79f9);
        state.write_u64(packed);
    }
}

/// A deterministic hasher for [`VoxelKey`]: the splitmix64 finaliser of the written words.
#[derive(Clone, Copy, Debug, Default)]
pub struct VoxelHasher(u64);

impl Hasher for VoxelHasher {
    fn finish(&self) -> u64 {
        self.0
    }

    fn write(&mut self, bytes: &[u8]) {
        for &byte in bytes {
            self.write_u64(u64::from(byte));
        }
    }

    fn write_u64(&mut self, value: u64) {
        let mut z = (self.0 ^ value).wrapping_add(0x9e37_79b9_7f4a_7c15);
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        self.0 = z ^ (z >> 31);
    }
}

type Voxels = HashMap<VoxelKey, Vec<Point3<f64>>, BuildHasherDefault<VoxelHasher>>;

/// The voxel-hash local map, in the odometry world frame.
#[derive(Clone, Debug)]
pub struct VoxelHashMap {
    voxel_size_m: f64,
    max_points_per_voxel: usize,
    /// Squared spacing below which a new point is redundant with one already in its voxel.
    min_spacing_sq_m2: f64,
    voxels: Voxels,
}

impl VoxelHashMap {
    /// An empty map of `voxel_size_m` voxels holding up to `max_points_per_voxel` points each.
    pub fn new(voxel_size_m: f64, max_points_per_voxel: usize) -> Self {
        let max_points_per_voxel = max_points_per_voxel.max(1);
        Self {
            voxel_size_m,
            max_points_per_voxel,
            min_spacing_sq_m2: voxel_size_m * voxel_size_m / max_points_per_voxel as f64,
            voxels: Voxels::default(),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.voxels.is_empty()
    }

    pub fn voxel_count(&self) -> usize {
        self.voxels.len()
    }

    pub fn point_count(&self) -> usize {
        self.voxels.values().map(Vec::len).sum()
    }

    /// The points of the voxel that holds `point` (empty when that voxel is).
    pub fn voxel_points_at(&self, point: &Point3<f64>) -> &[Point3<f64>] {
        self.voxels
            .get(&VoxelKey::of(point, self.voxel_size_m))
            .map_or(&[], Vec::as_slice)
    }

    /// Every map point (in no particular order).
    pub fn points(&self) -> impl Iterator<Item = &Point3<f64>> {
        self.voxels.values().flatten()
    }

    /// Adds world-frame points: a point enters its voxel unless the voxel is full or already holds a
    /// point within the minimum spacing. Non-finite points are ignored.
    pub fn add_points(&mut self, points: &[Point3<f64>]) {
        for point in points.iter().filter(|p| p.coords.iter().all(|c| c.is_finite())) {
            let key = VoxelKey::of(point, self.voxel_size_m);
            let voxel = self
                .voxels
                .entry(key)
                .or_insert_with(|| Vec::with_capacity(self.max_points_per_voxel));
            let redundant = voxel.len() >= self.max_points_per_voxel
                || voxel
                    .iter()
                    .any(|q| (q - point).norm_squared() < self.min_spacing_sq_m2);
            if !redundant {
                voxel.push(*point);
            }
        }
    }

    /// Removes the voxels whose first point lies `max_distance_m` or farther from `origin`.
    pub fn remove_far_from(&mut self, origin: &Point3<f64>, max_distance_m: f64) {
        let max_sq = max_distance_m * max_distance_m;
        self.voxels.retain(|_, points| {
            points
                .first()
                .is_some_and(|p| (p - origin).norm_squared() < max_sq)
        });
    }

    /// Moves sensor-frame points into the world with `world_from_sensor`, adds them, and prunes voxels
    /// beyond `max_range_m` of the sensor position.
    pub fn update(&mut self, points_sensor: &[Point3<f64>], world_from_sensor: &Pose, max_range_m: f64) {
        let world: Vec<Point3<f64>> = points_sensor.iter().map(|p| world_from_sensor * p).collect();
        self.add_points(&world);
        self.remove_far_from(&Point3::from(world_from_sensor.translation.vector), max_range_m);
    }

    /// The map point nearest to `query` among the 27 voxels around it, with its squared distance.
    pub fn nearest(&self, query: &Point3<f64>) -> Option<(Point3<f64>, f64)> {
        let [kx, ky, kz] = VoxelKey::of(query, self.voxel_size_m).0;
        let (qx, qy, qz) = (query.x, query.y, query.z);
        let mut best: Option<&Point3<f64>> = None;
        let mut best_sq = f64::INFINITY;
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let key = VoxelKey([kx.wrapping_add(dx), ky.wrapping_add(dy), kz.wrapping_add(dz)]);
                    let Some(points) = self.voxels.get(&key) else {
                        continue;
                    };
                    for point in points {
                        // Written out in scalars: this loop is the odometry's hot spot.
                        let (ex, ey, ez) = (point.x - qx, point.y - qy, point.z - qz);
                        let distance_sq = ex * ex + ey * ey + ez * ez;
                        if distance_sq < best_sq {
                            best_sq = distance_sq;
                            best = Some(point);
                        }
                    }
                }
            }
        }
        best.map(|point| (*point, best_sq))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn voxels_cap_their_points_and_respect_the_spacing() {
        let mut map = VoxelHashMap::new(1.0, 4);
        // Spacing is √(1/4) = 0.5 m: the second point is too close, the third is kept.
        map.add_points(&[
            Point3::new(0.1, 0.1, 0.1),
            Point3::new(0.2, 0.1, 0.1),
            Point3::new(0.9, 0.9, 0.1),
        ]);
        assert_eq!(map.point_count(), 2);
        let many: Vec<_> = (0..10)
            .map(|i| Point3::new(0.05 + 0.09 * f64::from(i), 0.95, 0.95 - 0.09 * f64::from(i)))
            .collect();
        map.add_points(&many);
        assert_eq!(map.point_count(), 4, "a voxel never holds more than its cap");
        assert_eq!(map.voxel_count(), 1);
    }

    #[test]
    fn nearest_searches_the_neighbouring_voxels_only() {
        let mut map = VoxelHashMap::new(1.0, 20);
        map.add_points(&[Point3::new(1.2, 0.5, 0.5), Point3::new(3.5, 0.5, 0.5)]);
        let (found, distance_sq) = map.nearest(&Point3::new(0.9, 0.5, 0.5)).unwrap();
        assert_eq!(found, Point3::new(1.2, 0.5, 0.5));
        assert!((distance_sq - 0.09).abs() < 1e-12);
        // Two voxels away: not found even though it is the only candidate.
        assert!(map.nearest(&Point3::new(5.5, 0.5, 0.5)).is_none());
        assert!(map.nearest(&Point3::new(-0.5, -0.5, -0.5)).is_none());
    }

    #[test]
    fn far_voxels_are_pruned_and_nan_is_ignored() {
        let mut map = VoxelHashMap::new(1.0, 20);
        map.add_points(&[
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(50.0, 0.0, 0.0),
            Point3::new(f64::NAN, 0.0, 0.0),
        ]);
        assert_eq!(map.point_count(), 2);
        map.remove_far_from(&Point3::origin(), 10.0);
        assert_eq!(map.point_count(), 1);
        let mut moved = map.clone();
        moved.update(
            &[Point3::new(0.0, 0.0, 0.0)],
            &Pose::translation(100.0, 0.0, 0.0),
            10.0,
        );
        assert_eq!(
            moved.points().copied().collect::<Vec<_>>(),
            vec![Point3::new(100.0, 0.0, 0.0)]
        );
    }
}
