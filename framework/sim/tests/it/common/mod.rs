//! Shared test helpers: worlds generated once per test binary, deskewing with ground truth, and a
//! plain point-to-plane ICP (Chen and Medioni 1992; linearised as in Low, "Linear least-squares
//! optimization for point-to-plane ICP surface registration", 2004) on a hashed voxel grid.

#![allow(dead_code)]

use std::collections::HashMap;
use std::sync::{Arc, OnceLock};

use nalgebra::{Matrix3, Matrix6, Point3, SymmetricEigen, UnitQuaternion, Vector3, Vector6};
use skid_core::{Pose, Scan};
use skid_sim::{Trajectory, World, WorldKind};

/// The world of `kind` with seed 7, built once per test binary (each on first use).
pub fn world(kind: WorldKind) -> Arc<World> {
    const KINDS: usize = WorldKind::ALL.len();
    static WORLDS: [OnceLock<Arc<World>>; KINDS] = [const { OnceLock::new() }; KINDS];
    let index = WorldKind::ALL.iter().position(|&k| k == kind).unwrap_or(0);
    Arc::clone(WORLDS[index].get_or_init(|| World::shared(kind, 7)))
}

/// Points of `scan` moved into the sensor frame at the scan stamp, using the true trajectory.
pub fn deskew(scan: &Scan, trajectory: &Trajectory) -> Vec<Point3<f64>> {
    let start_s = scan.stamp_nanos as f64 * 1e-9;
    let stamp_from_world = trajectory.pose_at(start_s).inverse();
    scan.points
        .iter()
        .map(|p| {
            let at = trajectory.pose_at(start_s + f64::from(p.time_offset_s));
            stamp_from_world * at * Point3::new(f64::from(p.x), f64::from(p.y), f64::from(p.z))
        })
        .collect()
}

/// A hashed grid of points with `cell_m` cells.
pub struct Grid {
    cell_m: f64,
    cells: HashMap<(i64, i64, i64), Vec<usize>>,
    pub points: Vec<Point3<f64>>,
}

impl Grid {
    pub fn new(points: Vec<Point3<f64>>, cell_m: f64) -> Self {
        let mut cells: HashMap<(i64, i64, i64), Vec<usize>> = HashMap::new();
        for (i, p) in points.iter().enumerate() {
            cells.entry(Self::key(p, cell_m)).or_default().push(i);
        }
        Self {
            cell_m,
            cells,
            points,
        }
    }

    fn key(p: &Point3<f64>, cell_m: f64) -> (i64, i64, i64) {
        (
            (p.x / cell_m).floor() as i64,
            (p.y / cell_m).floor() as i64,
            (p.z / cell_m).floor() as i64,
        )
    }

    /// Indices of points within `radius_m` (≤ cell size) of `p`.
    pub fn within(&self, p: &Point3<f64>, radius_m: f64) -> Vec<usize> {
        let (x, y, z) = Self::key(p, self.cell_m);
        let mut found = Vec::new();
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    if let Some(list) = self.cells.get(&(x + dx, y + dy, z + dz)) {
                        found.extend(
                            list.iter()
                                .copied()
                                .filter(|&i| (self.points[i] - p).norm() <= radius_m),
                        );
                    }
                }
            }
        }
        found
    }
}

/// One point per `voxel_m` voxel.
pub fn downsample(points: &[Point3<f64>], voxel_m: f64) -> Vec<Point3<f64>> {
    let mut seen = HashMap::new();
    for p in points {
        seen.entry((
            (p.x / voxel_m).floor() as i64,
            (p.y / voxel_m).floor() as i64,
            (p.z / voxel_m).floor() as i64,
        ))
        .or_insert(*p);
    }
    let mut out: Vec<Point3<f64>> = seen.into_values().collect();
    out.sort_by(|a, b| {
        a.x.total_cmp(&b.x)
            .then(a.y.total_cmp(&b.y))
            .then(a.z.total_cmp(&b.z))
    });
    out
}

/// Point-to-plane ICP: the pose `target_from_source` that aligns `source` to `target`, from identity.
pub fn point_to_plane(target: &[Point3<f64>], source: &[Point3<f64>]) -> Pose {
    point_to_plane_with(target, source, 0.25, 1.5)
}

/// [`point_to_plane`] with the target voxel size and the normal-estimation radius given.
pub fn point_to_plane_with(
    target: &[Point3<f64>],
    source: &[Point3<f64>],
    voxel_m: f64,
    normal_radius_m: f64,
) -> Pose {
    let target = downsample(target, voxel_m);
    let source = downsample(source, 0.4);
    let grid = Grid::new(target, normal_radius_m.max(1.0));
    // Normals from the neighbourhood covariance; keep only planar neighbourhoods.
    let normals: Vec<Option<Vector3<f64>>> = grid
        .points
        .iter()
        .map(|p| {
            let near = grid.within(p, normal_radius_m);
            if near.len() < 8 {
                return None;
            }
            let mean = near.iter().map(|&i| grid.points[i].coords).sum::<Vector3<f64>>() / near.len() as f64;
            let cov = near
                .iter()
                .map(|&i| (grid.points[i].coords - mean) * (grid.points[i].coords - mean).transpose())
                .sum::<Matrix3<f64>>();
            let eig = SymmetricEigen::new(cov / near.len() as f64);
            let k = eig.eigenvalues.imin();
            let mut sorted: Vec<f64> = eig.eigenvalues.iter().copied().collect();
            sorted.sort_by(f64::total_cmp);
            // Planar (thin) but not linear: neighbourhoods from a single scan ring give no normal.
            (sorted[0] < 0.15 * sorted[1] && sorted[1] > 0.1 * sorted[2])
                .then(|| eig.eigenvectors.column(k).into_owned())
        })
        .collect();
    let mut estimate = Pose::identity();
    for iteration in 0..60 {
        let max_distance = if iteration < 10 {
            1.0
        } else if iteration < 20 {
            0.5
        } else {
            0.25
        };
        let (mut h, mut g) = (Matrix6::zeros(), Vector6::zeros());
        for p in &source {
            let moved = estimate * p;
            let Some((q, n)) = grid
                .within(&moved, max_distance)
                .into_iter()
                .filter_map(|i| normals[i].map(|n| (grid.points[i], n)))
                .min_by(|a, b| (a.0 - moved).norm().total_cmp(&(b.0 - moved).norm()))
            else {
                continue;
            };
            let residual = n.dot(&(moved - q));
            let j = Vector6::new(n.x, n.y, n.z, 0.0, 0.0, 0.0);
            let w = moved.coords.cross(&n);
            let j = Vector6::new(j[0], j[1], j[2], w.x, w.y, w.z);
            h += j * j.transpose();
            g += j * residual;
        }
        let Some(step) = h.cholesky().map(|c| c.solve(&(-g))) else {
            break;
        };
        let delta = Pose::from_parts(
            Vector3::new(step[0], step[1], step[2]).into(),
            UnitQuaternion::from_scaled_axis(Vector3::new(step[3], step[4], step[5])),
        );
        estimate = delta * estimate;
        if step.norm() < 1e-6 {
            break;
        }
    }
    estimate
}

/// Translation (m) and rotation (rad) difference of two poses.
pub fn pose_error(a: &Pose, b: &Pose) -> (f64, f64) {
    let d = a.inverse() * b;
    (d.translation.vector.norm(), d.rotation.angle())
}
