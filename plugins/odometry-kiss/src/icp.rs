//! Point-to-point ICP of a scan against the voxel-hash local map, as in KISS-ICP (Vizzo et al., RA-L
//! 2023, Sec. III-D): nearest neighbours in the 27 surrounding voxels within a distance gate,
//! Gauss-Newton on SE(3) with a Geman-McClure-style weight, stopping when the update is small.
//!
//! The residual of a source point p (already moved by the current estimate) and its map neighbour q is
//! r = p − q; a left perturbation (δt, δω) moves p to p + δt + δω × p, so the Jacobian is [I, −[p]×].
//! The weight is k² / (k + ‖r‖²)² with k the kernel scale, as in the reference implementation.

use nalgebra::{Matrix6, Point3, Vector6};
use skid_core::Pose;

use crate::parallel::Parallel;
use crate::voxel_map::VoxelHashMap;

/// Source points per parallel chunk: fixed, so sums are formed in the same order on any pool.
const CHUNK_POINTS: usize = 512;

/// The settings of one alignment.
#[derive(Clone, Copy, Debug)]
pub struct IcpSettings {
    /// Largest point-to-neighbour distance of a correspondence, metres.
    pub max_correspondence_m: f64,
    /// Scale k of the robust kernel, metres.
    pub kernel_scale_m: f64,
    pub max_iterations: usize,
    /// Stop when ‖(δt, δω)‖ falls below this.
    pub convergence_criterion: f64,
}

/// The outcome of one alignment.
#[derive(Clone, Copy, Debug)]
pub struct IcpResult {
    pub world_from_sensor: Pose,
    pub iterations: usize,
    /// Correspondences in the last iteration.
    pub correspondences: usize,
    /// The update fell below the convergence criterion before the iteration limit.
    pub converged: bool,
}

/// The normal equations of one chunk (or of the whole scan after the ordered sum).
#[derive(Clone, Copy)]
struct LinearSystem {
    jtj: Matrix6<f64>,
    jtr: Vector6<f64>,
    count: usize,
}

impl LinearSystem {
    fn zero() -> Self {
        Self {
            jtj: Matrix6::zeros(),
            jtr: Vector6::zeros(),
            count: 0,
        }
    }

    fn add(&mut self, other: &Self) {
        self.jtj += other.jtj;
        self.jtr += other.jtr;
        self.count += other.count;
    }
}

/// Builds the weighted normal equations of `source` (world frame) against `map`.
fn build_system(source: &[Point3<f64>], map: &VoxelHashMap, settings: &IcpSettings) -> LinearSystem {
    let max_sq = settings.max_correspondence_m * settings.max_correspondence_m;
    let k = settings.kernel_scale_m;
    // Upper triangle of JᵀJ (row-major) and Jᵀr, accumulated in scalars: with J = [I, −[p]×],
    // JᵀJ = [[I, −[p]×], [[p]×, −[p]×[p]×]] and Jᵀr = [r, p × r].
    let mut h = [0.0f64; 21];
    let mut g = [0.0f64; 6];
    let mut count = 0;
    for p in source {
        let Some((q, distance_sq)) = map.nearest(p) else {
            continue;
        };
        if distance_sq >= max_sq {
            continue;
        }
        let w = k * k / ((k + distance_sq) * (k + distance_sq));
        let (x, y, z) = (p.x, p.y, p.z);
        let (rx, ry, rz) = (x - q.x, y - q.y, z - q.z);
        let row = [
            [1.0, 0.0, 0.0, 0.0, z, -y],
            [0.0, 1.0, 0.0, -z, 0.0, x],
            [0.0, 0.0, 1.0, y, -x, 0.0],
        ];
        let r = [rx, ry, rz];
        let mut index = 0;
        for i in 0..6 {
            for j in i..6 {
                h[index] += w * (row[0][i] * row[0][j] + row[1][i] * row[1][j] + row[2][i] * row[2][j]);
                index += 1;
            }
            g[i] += w * (row[0][i] * r[0] + row[1][i] * r[1] + row[2][i] * r[2]);
        }
        count += 1;
    }
    let mut jtj = Matrix6::zeros();
    let mut index = 0;
    for i in 0..6 {
        for j in i..6 {
            jtj[(i, j)] = h[index];
            jtj[(j, i)] = h[index];
            index += 1;
        }
    }
    LinearSystem {
        jtj,
        jtr: Vector6::from_column_slice(&g),
        count,
    }
}

/// Solves JᵀJ dx = −Jᵀr; when JᵀJ is singular (degenerate geometry such as a single plane), the
/// minimum-norm solution leaves the unobservable directions at the prediction.
fn solve(system: &LinearSystem) -> Option<Vector6<f64>> {
    let rhs = -system.jtr;
    let dx = match system.jtj.cholesky() {
        Some(cholesky) => cholesky.solve(&rhs),
        None => {
            let scale = system.jtj.abs().max().max(f64::MIN_POSITIVE);
            system.jtj.svd(true, true).solve(&rhs, scale * 1e-9).ok()?
        }
    };
    dx.iter().all(|v| v.is_finite()).then_some(dx)
}

/// Aligns `source_sensor` (sensor-frame points) to `map`, starting from `initial_world_from_sensor`.
/// An empty map returns the initial guess.
pub fn align_points_to_map(
    source_sensor: &[Point3<f64>],
    map: &VoxelHashMap,
    initial_world_from_sensor: &Pose,
    settings: &IcpSettings,
    parallel: &Parallel,
) -> IcpResult {
    let mut estimate = *initial_world_from_sensor;
    let mut result = IcpResult {
        world_from_sensor: estimate,
        iterations: 0,
        correspondences: 0,
        converged: false,
    };
    if map.is_empty() {
        result.converged = true;
        return result;
    }
    let mut source: Vec<Point3<f64>> = source_sensor.iter().map(|p| estimate * p).collect();
    for iteration in 1..=settings.max_iterations {
        let chunks = parallel.map_chunks(&source, CHUNK_POINTS, |chunk| build_system(chunk, map, settings));
        let mut system = LinearSystem::zero();
        for chunk in &chunks {
            system.add(chunk);
        }
        result.iterations = iteration;
        result.correspondences = system.count;
        let Some(dx) = (system.count > 0).then(|| solve(&system)).flatten() else {
            break;
        };
        let update = Pose::new(
            dx.fixed_rows::<3>(0).into_owned(),
            dx.fixed_rows::<3>(3).into_owned(),
        );
        for p in &mut source {
            *p = update * *p;
        }
        estimate = update * estimate;
        // Products of unit quaternions drift off the unit sphere by rounding; the odometry composes
        // poses with their inverses scan after scan, which would amplify that drift exponentially.
        estimate.rotation.renormalize();
        if dx.norm() < settings.convergence_criterion {
            result.converged = true;
            break;
        }
    }
    result.world_from_sensor = estimate;
    result
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    /// A box-shaped room's walls, floor and sloped ceiling, sampled every `step_m` from `start_m`.
    fn room(start_m: f64, step_m: f64) -> Vec<Point3<f64>> {
        let mut points = Vec::new();
        let steps: Vec<f64> = (0..)
            .map(|i| start_m + step_m * f64::from(i))
            .take_while(|v| *v <= 5.0)
            .collect();
        for &a in &steps {
            for &b in &steps {
                let h = 1.0 + 0.2 * (b + 5.0);
                points.extend([
                    Point3::new(-5.0, a, h),
                    Point3::new(5.0, a, h),
                    Point3::new(a, -5.0, h),
                    Point3::new(a, 5.0, h),
                ]);
                points.extend([Point3::new(a, b, -1.0), Point3::new(a, b, 3.0 + 0.1 * a)]);
            }
        }
        points
    }

    /// A dense map of the room (5 cm spacing) and a sparse scan of it from `truth`, sampled elsewhere.
    fn map_and_scan(truth: &Pose) -> (VoxelHashMap, Vec<Point3<f64>>) {
        let mut map = VoxelHashMap::new(0.5, 100);
        map.add_points(&room(-5.0, 0.05));
        let scan = room(-4.87, 0.3).iter().map(|p| truth.inverse() * p).collect();
        (map, scan)
    }

    fn settings() -> IcpSettings {
        IcpSettings {
            max_correspondence_m: 1.5,
            kernel_scale_m: 0.3,
            max_iterations: 500,
            convergence_criterion: 1e-4,
        }
    }

    #[test]
    fn recovers_a_small_offset() {
        let truth = Pose::new(Vector3::new(0.3, -0.2, 0.05), Vector3::new(0.0, 0.0, 0.04));
        let (map, source) = map_and_scan(&truth);
        let result = align_points_to_map(
            &source,
            &map,
            &Pose::identity(),
            &settings(),
            &Parallel::new(1).unwrap(),
        );
        let error = truth.inverse() * result.world_from_sensor;
        assert!(result.converged);
        assert!(error.translation.vector.norm() < 0.02, "{error}");
        let stuck = align_points_to_map(
            &source,
            &map,
            &Pose::identity(),
            &IcpSettings {
                max_iterations: 1,
                ..settings()
            },
            &Parallel::new(1).unwrap(),
        );
        assert!(
            (truth.inverse() * stuck.world_from_sensor)
                .translation
                .vector
                .norm()
                > 0.05,
            "one iteration is not enough"
        );
        // Point-to-point ICP stops within about half the map spacing (2.5 cm) at the walls 5 m out.
        assert!(error.rotation.angle() < 0.006, "{error}");
    }

    #[test]
    fn exact_correspondences_converge_exactly() {
        let truth = Pose::new(Vector3::new(0.3, -0.2, 0.05), Vector3::new(0.01, -0.02, 0.04));
        let points = room(-4.87, 0.3);
        let mut map = VoxelHashMap::new(0.5, 1000);
        map.add_points(&points);
        let source: Vec<_> = points.iter().map(|p| truth.inverse() * p).collect();
        let tight = IcpSettings {
            convergence_criterion: 1e-10,
            ..settings()
        };
        let result = align_points_to_map(
            &source,
            &map,
            &Pose::identity(),
            &tight,
            &Parallel::new(1).unwrap(),
        );
        let error = truth.inverse() * result.world_from_sensor;
        assert!(
            error.translation.vector.norm() < 1e-6 && error.rotation.angle() < 1e-6,
            "{error} after {} iterations",
            result.iterations
        );
    }

    #[test]
    fn one_or_two_threads_give_the_same_bits() {
        let truth = Pose::new(Vector3::new(0.2, 0.1, 0.0), Vector3::new(0.0, 0.0, -0.03));
        let (map, source) = map_and_scan(&truth);
        let run = |threads| {
            align_points_to_map(
                &source,
                &map,
                &Pose::identity(),
                &settings(),
                &Parallel::new(threads).unwrap(),
            )
        };
        let (a, b) = (run(1), run(2));
        assert_eq!(
            a.world_from_sensor.to_homogeneous(),
            b.world_from_sensor.to_homogeneous()
        );
        assert_eq!(a.iterations, b.iterations);
    }

    #[test]
    fn a_single_plane_stays_finite() {
        let plane: Vec<_> = (0..400)
            .map(|i| Point3::new(f64::from(i % 20) * 0.3, f64::from(i / 20) * 0.3, 0.0))
            .collect();
        let mut map = VoxelHashMap::new(0.5, 20);
        map.add_points(&plane);
        let shifted: Vec<_> = plane.iter().map(|p| p + Vector3::new(0.0, 0.0, 0.1)).collect();
        let result = align_points_to_map(
            &shifted,
            &map,
            &Pose::identity(),
            &settings(),
            &Parallel::new(1).unwrap(),
        );
        let t = result.world_from_sensor.translation.vector;
        assert!(t.iter().all(|v| v.is_finite()));
        assert!(
            (t.z + 0.1).abs() < 0.01,
            "the observable direction is recovered: {t}"
        );
    }
}
