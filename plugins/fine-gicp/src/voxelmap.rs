//! The Gaussian voxel map VGICP registers against (small_gicp's `GaussianVoxelMap`): each occupied voxel
//! holds the mean of its points and the mean of their regularised covariances; a query finds the voxel
//! holding the query point.

use std::collections::HashMap;

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use crate::voxel::{group_by_voxel, voxel_key};

/// Neighbour offsets searched for 1, 7 and 27 voxels, the voxel itself first.
pub fn search_offsets(count: usize) -> Vec<[i32; 3]> {
    let mut offsets = vec![[0, 0, 0]];
    if count >= 7 {
        offsets.extend([
            [1, 0, 0],
            [-1, 0, 0],
            [0, 1, 0],
            [0, -1, 0],
            [0, 0, 1],
            [0, 0, -1],
        ]);
    }
    if count >= 27 {
        for x in -1..=1 {
            for y in -1..=1 {
                for z in -1..=1 {
                    let offset = [x, y, z];
                    if offset.iter().map(|v: &i32| v.abs()).sum::<i32>() >= 2 {
                        offsets.push(offset);
                    }
                }
            }
        }
    }
    offsets
}

/// Gaussian voxels keyed by their packed voxel coordinates.
pub struct GaussianVoxelMap {
    inv_resolution: f64,
    index: HashMap<u64, u32>,
    pub means: Vec<Vector3<f64>>,
    pub covariances: Vec<Matrix3<f64>>,
}

impl GaussianVoxelMap {
    /// Builds the map of voxels of `resolution` metres (positive) from points and their covariances. The
    /// sums run over each voxel's points in index order, so the map does not depend on the thread count.
    pub fn build(points: &[Vector3<f64>], covariances: &[Matrix3<f64>], resolution: f64) -> Self {
        let groups = group_by_voxel(points, resolution);
        let (means, covariances): (Vec<_>, Vec<_>) = groups
            .runs
            .par_iter()
            .with_min_len(256)
            .map(|(_, range)| {
                let members = &groups.order[range.clone()];
                let (sum, cov) = members
                    .iter()
                    .fold((Vector3::zeros(), Matrix3::zeros()), |(s, c), &i| {
                        (s + points[i as usize], c + covariances[i as usize])
                    });
                let n = members.len() as f64;
                (sum / n, cov / n)
            })
            .unzip();
        let index = groups
            .runs
            .iter()
            .enumerate()
            .map(|(i, (key, _))| (*key, i as u32))
            .collect();
        Self {
            inv_resolution: 1.0 / resolution,
            index,
            means,
            covariances,
        }
    }

    /// Among the voxel holding `point` and its `offsets` neighbours (1: none, 7: the faces, 27: the whole
    /// 3x3x3 block), the one whose mean is nearest to `point`, with that squared distance. Ties go to
    /// the first in a fixed offset order.
    #[inline]
    pub fn nearest(&self, point: &Vector3<f64>, offsets: &[[i32; 3]]) -> Option<(usize, f64)> {
        let mut best: Option<(usize, f64)> = None;
        let scaled = point * self.inv_resolution;
        for offset in offsets {
            let shifted = Vector3::new(
                (scaled.x.floor() + f64::from(offset[0]) + 0.5) / self.inv_resolution,
                (scaled.y.floor() + f64::from(offset[1]) + 0.5) / self.inv_resolution,
                (scaled.z.floor() + f64::from(offset[2]) + 0.5) / self.inv_resolution,
            );
            let Some(key) = voxel_key(&shifted, self.inv_resolution) else {
                continue;
            };
            let Some(&index) = self.index.get(&key) else {
                continue;
            };
            let index = index as usize;
            let distance = (self.means[index] - point).norm_squared();
            if best.is_none_or(|(_, d)| distance < d) {
                best = Some((index, distance));
            }
        }
        best
    }

    /// Number of occupied voxels.
    pub fn len(&self) -> usize {
        self.means.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn voxels_average_points_and_covariances() {
        let points = vec![
            Vector3::new(0.2, 0.2, 0.2),
            Vector3::new(0.4, 0.6, 0.8),
            Vector3::new(2.5, 0.5, 0.5),
        ];
        let covariances = vec![
            Matrix3::identity(),
            Matrix3::identity() * 3.0,
            Matrix3::identity(),
        ];
        let map = GaussianVoxelMap::build(&points, &covariances, 1.0);
        assert_eq!(map.len(), 2);
        let (index, distance) = map
            .nearest(&Vector3::new(0.9, 0.9, 0.9), &search_offsets(1))
            .unwrap();
        assert!((map.means[index] - Vector3::new(0.3, 0.4, 0.5)).norm() < 1e-12);
        assert!((map.covariances[index] - Matrix3::identity() * 2.0).amax() < 1e-12);
        assert!((distance - (0.36 + 0.25 + 0.16)).abs() < 1e-12);
        assert!(
            map.nearest(&Vector3::new(1.5, 0.5, 0.5), &search_offsets(1))
                .is_none()
        );
        let (index, _) = map
            .nearest(&Vector3::new(1.5, 0.5, 0.5), &search_offsets(7))
            .unwrap();
        assert!(
            (map.means[index] - points[2]).norm() < 1e-12,
            "the nearer neighbour voxel wins"
        );
        assert_eq!(search_offsets(27).len(), 27);
        assert_eq!(search_offsets(7).len(), 7);
    }
}
