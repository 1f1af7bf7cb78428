//! Local features of a prepared cloud: per-point covariances from the k nearest neighbours, regularised to
//! be plane-like (eigenvalues replaced by 1e-3, 1, 1 as in small_gicp), the matching normals (the
//! least-spread direction, turned towards the sensor), and the principal extents of the whole cloud that
//! tell collinear and coplanar input apart.

use nalgebra::{Matrix3, SymmetricEigen, Vector3};
use rayon::prelude::*;

use crate::tree::PointTree;

/// Fewest neighbours a covariance is estimated from; points with fewer get an isotropic covariance and no
/// normal (small_gicp's threshold).
pub const MIN_NEIGHBORS: usize = 5;

/// Eigenvalue given to the normal direction of a regularised covariance (the others are 1).
pub const PLANE_EPSILON: f64 = 1e-3;

/// Per-point covariances and normals; a zero normal marks a point whose neighbourhood was too small.
pub struct LocalFeatures {
    pub covariances: Vec<Matrix3<f64>>,
    pub normals: Vec<Vector3<f64>>,
}

/// Estimates the features of every point in parallel; the result does not depend on the thread count.
pub fn estimate(points: &[Vector3<f64>], tree: &PointTree, num_neighbors: usize) -> LocalFeatures {
    let (covariances, normals) = points
        .par_iter()
        .with_min_len(256)
        .map_init(
            || Vec::with_capacity(num_neighbors),
            |neighbors, point| {
                tree.knn(point, num_neighbors, neighbors);
                local_feature(points, point, neighbors)
            },
        )
        .unzip();
    LocalFeatures { covariances, normals }
}

/// The regularised covariance and normal of one point from its neighbours.
fn local_feature(
    points: &[Vector3<f64>],
    point: &Vector3<f64>,
    neighbors: &[usize],
) -> (Matrix3<f64>, Vector3<f64>) {
    if neighbors.len() < MIN_NEIGHBORS {
        return (Matrix3::identity(), Vector3::zeros());
    }
    // Centred on the query point so the sums do not cancel far from the origin.
    let mut sum = Vector3::zeros();
    let mut sum_outer = Matrix3::zeros();
    for &j in neighbors {
        let d = points[j] - point;
        sum += d;
        sum_outer += d * d.transpose();
    }
    let n = neighbors.len() as f64;
    let mean = sum / n;
    let covariance = (sum_outer - mean * sum.transpose()) / n;
    let mut normal = smallest_eigenvector(&covariance);
    let regularised = Matrix3::identity() + (normal * normal.transpose()) * (PLANE_EPSILON - 1.0);
    if normal.dot(point) > 0.0 {
        normal = -normal;
    }
    (regularised, normal)
}

/// Unit eigenvector of the smallest eigenvalue of a symmetric 3x3 matrix, in closed form (the
/// trigonometric roots of the characteristic polynomial and a kernel by cross products, as Eigen's
/// `computeDirect`). Any unit vector of the eigenspace when that eigenvalue is repeated.
pub fn smallest_eigenvector(matrix: &Matrix3<f64>) -> Vector3<f64> {
    let scale = matrix.amax();
    if !(scale.is_finite() && scale > 0.0) {
        return Vector3::z();
    }
    let shift = matrix.trace() / 3.0;
    let scaled = (matrix - Matrix3::identity() * shift) / scale;
    let roots = eigenvalues_ascending(&scaled);
    let spread = roots[2] - roots[0];
    if spread <= 4.0 * f64::EPSILON {
        return Vector3::z();
    }
    if roots[1] - roots[0] > 1e-6 * spread {
        kernel(&(scaled - Matrix3::identity() * roots[0]))
    } else {
        // The smallest eigenvalue is (numerically) double: any vector orthogonal to the largest
        // eigenvalue's eigenvector will do.
        any_orthogonal(&kernel(&(scaled - Matrix3::identity() * roots[2])))
    }
}

/// The eigenvalues of a symmetric 3x3 matrix in ascending order.
fn eigenvalues_ascending(m: &Matrix3<f64>) -> [f64; 3] {
    let (m00, m01, m02, m11, m12, m22) = (m[(0, 0)], m[(0, 1)], m[(0, 2)], m[(1, 1)], m[(1, 2)], m[(2, 2)]);
    let c0 = m00 * m11 * m22 + 2.0 * m01 * m02 * m12 - m00 * m12 * m12 - m11 * m02 * m02 - m22 * m01 * m01;
    let c1 = m00 * m11 - m01 * m01 + m00 * m22 - m02 * m02 + m11 * m22 - m12 * m12;
    let c2 = m00 + m11 + m22;
    let c2_over_3 = c2 / 3.0;
    let a_over_3 = ((c2 * c2_over_3 - c1) / 3.0).max(0.0);
    let half_b = 0.5 * (c0 + c2_over_3 * (2.0 * c2_over_3 * c2_over_3 - c1));
    let q = (a_over_3 * a_over_3 * a_over_3 - half_b * half_b).max(0.0);
    let rho = a_over_3.sqrt();
    let theta = q.sqrt().atan2(half_b) / 3.0;
    let (sin, cos) = theta.sin_cos();
    let sqrt3 = 3f64.sqrt();
    let mut roots = [
        c2_over_3 - rho * (cos + sqrt3 * sin),
        c2_over_3 - rho * (cos - sqrt3 * sin),
        c2_over_3 + 2.0 * rho * cos,
    ];
    roots.sort_by(f64::total_cmp);
    roots
}

/// A unit vector in the kernel of a rank-2 symmetric matrix: the longest cross product of its columns.
fn kernel(m: &Matrix3<f64>) -> Vector3<f64> {
    let (c0, c1, c2) = (
        m.column(0).into_owned(),
        m.column(1).into_owned(),
        m.column(2).into_owned(),
    );
    let candidates = [c0.cross(&c1), c0.cross(&c2), c1.cross(&c2)];
    let best = candidates
        .iter()
        .max_by(|a, b| a.norm_squared().total_cmp(&b.norm_squared()))
        .copied()
        .unwrap_or_else(Vector3::z);
    let norm = best.norm();
    if norm > 0.0 && norm.is_finite() {
        best / norm
    } else {
        // Rank below 2: any vector orthogonal to the longest column.
        let longest = [c0, c1, c2]
            .into_iter()
            .max_by(|a, b| a.norm_squared().total_cmp(&b.norm_squared()));
        any_orthogonal(&longest.unwrap_or_else(Vector3::x))
    }
}

/// A unit vector orthogonal to `v` (the z axis for a zero `v`).
fn any_orthogonal(v: &Vector3<f64>) -> Vector3<f64> {
    let axis = if v.x.abs() <= v.y.abs() && v.x.abs() <= v.z.abs() {
        Vector3::x()
    } else if v.y.abs() <= v.z.abs() {
        Vector3::y()
    } else {
        Vector3::z()
    };
    let orthogonal = v.cross(&axis);
    let norm = orthogonal.norm();
    if norm > 0.0 && norm.is_finite() {
        orthogonal / norm
    } else {
        Vector3::z()
    }
}

/// Points per chunk of every deterministic parallel reduction.
pub const REDUCTION_CHUNK: usize = 256;

/// Standard deviations of the cloud along its three principal axes, ascending (zeros when empty).
pub fn principal_extents(points: &[Vector3<f64>]) -> [f64; 3] {
    if points.is_empty() {
        return [0.0; 3];
    }
    let origin = points[0];
    let partials: Vec<(Vector3<f64>, Matrix3<f64>)> = points
        .par_chunks(REDUCTION_CHUNK)
        .map(|chunk| {
            chunk
                .iter()
                .fold((Vector3::zeros(), Matrix3::zeros()), |(s, o), p| {
                    let d = p - origin;
                    (s + d, o + d * d.transpose())
                })
        })
        .collect();
    let (sum, outer) = partials
        .into_iter()
        .fold((Vector3::zeros(), Matrix3::zeros()), |(s, o), (ps, po)| {
            (s + ps, o + po)
        });
    let n = points.len() as f64;
    let mean = sum / n;
    let covariance = outer / n - mean * mean.transpose();
    let mut values: Vec<f64> = SymmetricEigen::new(covariance)
        .eigenvalues
        .iter()
        .map(|v| if v.is_finite() { v.max(0.0).sqrt() } else { 0.0 })
        .collect();
    values.sort_by(f64::total_cmp);
    [values[0], values[1], values[2]]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check_against_nalgebra(matrix: Matrix3<f64>) {
        let eig = SymmetricEigen::new(matrix);
        let (index, _) = eig.eigenvalues.argmin();
        let expected = eig.eigenvectors.column(index).into_owned();
        let got = smallest_eigenvector(&matrix);
        assert!((got.norm() - 1.0).abs() < 1e-9);
        assert!(
            got.dot(&expected).abs() > 1.0 - 1e-6,
            "{matrix} -> {got} vs {expected}"
        );
    }

    #[test]
    fn closed_form_matches_the_iterative_solver() {
        let a = Matrix3::new(2.0, 0.3, 0.1, 0.3, 1.0, -0.2, 0.1, -0.2, 0.05);
        check_against_nalgebra(a);
        let plane = Matrix3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1e-7);
        check_against_nalgebra(plane);
        let rotation = nalgebra::Rotation3::from_euler_angles(0.3, -0.7, 1.1).into_inner();
        check_against_nalgebra(
            rotation * Matrix3::from_diagonal(&Vector3::new(4.0, 1e-5, 2.0)) * rotation.transpose(),
        );
        check_against_nalgebra(Matrix3::new(1e6, 5.0, 0.0, 5.0, 2e6, 0.0, 0.0, 0.0, 3.0));
    }

    #[test]
    fn repeated_and_zero_eigenvalues_give_a_unit_vector() {
        let line = Vector3::new(1.0, 2.0, 3.0).normalize();
        let v = smallest_eigenvector(&(line * line.transpose()));
        assert!((v.norm() - 1.0).abs() < 1e-9 && v.dot(&line).abs() < 1e-6);
        for m in [
            Matrix3::zeros(),
            Matrix3::identity(),
            Matrix3::from_element(f64::NAN),
        ] {
            assert!((smallest_eigenvector(&m).norm() - 1.0).abs() < 1e-9);
        }
    }

    #[test]
    fn plane_points_get_a_flat_covariance_and_a_normal_towards_the_sensor() {
        let points: Vec<Vector3<f64>> = (0..400)
            .map(|i| Vector3::new(f64::from(i % 20) * 0.1, f64::from(i / 20) * 0.1, -1.5))
            .collect();
        let tree = PointTree::build(&points);
        let features = estimate(&points, &tree, 10);
        for (cov, normal) in features.covariances.iter().zip(&features.normals) {
            assert!((normal - Vector3::z()).norm() < 1e-6, "{normal}");
            assert!((cov - Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, PLANE_EPSILON))).amax() < 1e-6);
        }
        let extents = principal_extents(&points);
        assert!(extents[0] < 1e-9 && extents[1] > 0.5, "{extents:?}");
    }
}
