//! The local map: points in a voxel hash, in the manner of Faster-LIO's iVox (Bai et al., "Faster-LIO:
//! Lightweight Tightly Coupled Lidar-Inertial Odometry Using Parallel Sparse Incremental Voxels", RA-L
//! 2022). Each voxel keeps a few points; a query gathers the points of its voxel and the 26 around it,
//! keeps the nearest `k`, and fits a plane to them by principal components (the smallest eigenvector of
//! their covariance), which unlike FAST-LIO2's `A·n = −1` least squares has no trouble with planes
//! through the origin. Voxels farther than the sensor range from the robot are dropped.

use nalgebra::{Matrix3, Vector3};
use rustc_hash::FxHashMap;

type VoxelKey = [i32; 3];

/// A plane `normal · x + offset = 0` with a unit normal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plane {
    pub normal: Vector3<f64>,
    pub offset: f64,
}

impl Plane {
    /// Signed distance of `point` to the plane.
    pub fn distance(&self, point: &Vector3<f64>) -> f64 {
        self.normal.dot(point) + self.offset
    }
}

/// Points of the map by voxel.
#[derive(Clone, Debug)]
pub struct PlaneMap {
    voxel_m: f64,
    max_points_per_voxel: usize,
    /// Fx hashing: the keys are small integer triples, and SipHash cost a tenth of the odometry.
    voxels: FxHashMap<VoxelKey, Vec<Vector3<f32>>>,
}

impl PlaneMap {
    pub fn new(voxel_m: f64, max_points_per_voxel: usize) -> Self {
        Self {
            voxel_m,
            max_points_per_voxel,
            voxels: FxHashMap::default(),
        }
    }

    fn key(&self, point: &Vector3<f64>) -> VoxelKey {
        [
            (point.x / self.voxel_m).floor() as i32,
            (point.y / self.voxel_m).floor() as i32,
            (point.z / self.voxel_m).floor() as i32,
        ]
    }

    pub fn is_empty(&self) -> bool {
        self.voxels.is_empty()
    }

    pub fn point_count(&self) -> usize {
        self.voxels.values().map(Vec::len).sum()
    }

    /// Adds world points; a full voxel keeps what it has (its points already describe the surface).
    pub fn add(&mut self, points: &[Vector3<f64>]) {
        let min_spacing_sq = (0.1 * self.voxel_m).powi(2) as f32;
        for point in points {
            let key = self.key(point);
            let voxel = self.voxels.entry(key).or_default();
            if voxel.len() >= self.max_points_per_voxel {
                continue;
            }
            let stored = point.cast::<f32>();
            // A point on top of one the voxel holds adds nothing to a plane fit.
            if voxel
                .iter()
                .all(|p| (p - stored).norm_squared() >= min_spacing_sq)
            {
                voxel.push(stored);
            }
        }
    }

    /// Drops voxels farther than `max_range_m` from `center`.
    pub fn prune(&mut self, center: &Vector3<f64>, max_range_m: f64) {
        let reach = max_range_m + self.voxel_m;
        let limit_sq = reach * reach;
        self.voxels.retain(|key, _| {
            let voxel_center = Vector3::new(
                (f64::from(key[0]) + 0.5) * self.voxel_m,
                (f64::from(key[1]) + 0.5) * self.voxel_m,
                (f64::from(key[2]) + 0.5) * self.voxel_m,
            );
            (voxel_center - center).norm_squared() <= limit_sq
        });
    }

    /// The `k` map points nearest to `query` within the query's voxel and its neighbours, nearest first.
    pub fn nearest(&self, query: &Vector3<f64>, k: usize, out: &mut Vec<(f64, Vector3<f64>)>) {
        out.clear();
        if k == 0 {
            return;
        }
        let center = self.key(query);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let key = [center[0] + dx, center[1] + dy, center[2] + dz];
                    let Some(points) = self.voxels.get(&key) else {
                        continue;
                    };
                    for point in points {
                        let point = point.cast::<f64>();
                        let distance_sq = (point - query).norm_squared();
                        if out.len() == k && distance_sq >= out[k - 1].0 {
                            continue;
                        }
                        // Insertion into the short sorted list.
                        let at = out.partition_point(|(d, _)| *d <= distance_sq);
                        if out.len() == k {
                            out.pop();
                        }
                        out.insert(at, (distance_sq, point));
                    }
                }
            }
        }
    }
}

/// The plane through `points` by principal components, when every point lies within
/// `max_distance_m` of it.
pub fn fit_plane(points: &[(f64, Vector3<f64>)], max_distance_m: f64) -> Option<Plane> {
    if points.len() < 3 {
        return None;
    }
    let count = points.len() as f64;
    let centroid = points.iter().map(|(_, p)| p).sum::<Vector3<f64>>() / count;
    let covariance = points
        .iter()
        .map(|(_, p)| (p - centroid) * (p - centroid).transpose())
        .sum::<Matrix3<f64>>()
        / count;
    let eigen = covariance.symmetric_eigen();
    let (smallest, _) = eigen
        .eigenvalues
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(b.1))?;
    let normal: Vector3<f64> = eigen.eigenvectors.column(smallest).into();
    let norm = normal.norm();
    if !(norm.is_finite() && norm > 0.5) {
        return None;
    }
    let normal = normal / norm;
    let plane = Plane {
        normal,
        offset: -normal.dot(&centroid),
    };
    points
        .iter()
        .all(|(_, p)| plane.distance(p).abs() <= max_distance_m)
        .then_some(plane)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_neighbours_and_fits_planes_through_the_origin() {
        let mut map = PlaneMap::new(0.5, 20);
        // The plane x = 0 (through the origin), sampled every 0.2 m.
        let wall: Vec<Vector3<f64>> = (0..20)
            .flat_map(|i| (0..20).map(move |j| Vector3::new(0.0, 0.2 * f64::from(i), 0.2 * f64::from(j))))
            .collect();
        map.add(&wall);
        assert!(map.point_count() > 100);
        let mut near = Vec::new();
        map.nearest(&Vector3::new(0.3, 1.0, 1.0), 5, &mut near);
        assert_eq!(near.len(), 5);
        assert!(near.windows(2).all(|w| w[0].0 <= w[1].0));
        let plane = fit_plane(&near, 0.1).expect("a plane");
        assert!((plane.normal.x.abs() - 1.0).abs() < 1e-9 && plane.offset.abs() < 1e-9);
        assert!((plane.distance(&Vector3::new(0.3, 1.0, 1.0)).abs() - 0.3).abs() < 1e-9);
        // Points that are not on one plane give none.
        let scattered = vec![
            (0.0, Vector3::new(0.0, 0.0, 0.0)),
            (0.0, Vector3::new(1.0, 0.0, 0.0)),
            (0.0, Vector3::new(0.0, 1.0, 0.0)),
            (0.0, Vector3::new(0.0, 0.0, 1.0)),
            (0.0, Vector3::new(1.0, 1.0, 1.0)),
        ];
        assert!(fit_plane(&scattered, 0.1).is_none());
        map.prune(&Vector3::new(100.0, 0.0, 0.0), 10.0);
        assert!(map.is_empty());
    }
}
