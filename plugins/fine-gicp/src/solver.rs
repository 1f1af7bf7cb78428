//! The registration problem and its Levenberg-Marquardt solver on SE(3), after small_gicp.
//!
//! Each linearisation finds every source point's correspondence (nearest target point, or the Gaussian
//! voxel holding it for VGICP), rejects those beyond the maximum distance, and reduces the 6x6 normal
//! equations in parallel. The damping loop then evaluates candidate steps on those fixed correspondences.
//! Perturbations are applied on the right, `T ← T · exp(δ)`, with δ = (ω, v) rotation first as in
//! small_gicp. Every reduction runs over fixed chunks of source points summed in chunk order, so the
//! result does not depend on the thread count.

use nalgebra::{
    Cholesky, Isometry3, Matrix3, Matrix3x6, Matrix6, Translation3, UnitQuaternion, Vector3, Vector6,
};
use rayon::prelude::*;

use crate::config::{GicpConfig, Variant};
use crate::features::REDUCTION_CHUNK;
use crate::prepared::PreparedData;

/// A source point's correspondence fixed at the last linearisation.
#[derive(Clone, Copy)]
struct Link {
    /// Target point (or voxel) index; `NONE` when the point is not an inlier.
    target: u32,
    /// Mahalanobis weight of the residual (GICP, VGICP); unused otherwise.
    weight: Matrix3<f64>,
}

impl Link {
    const NONE: Link = Link {
        target: u32::MAX,
        weight: Matrix3::new(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
    };
}

/// A partial sum of the normal equations over some source points.
#[derive(Clone, Copy)]
struct System {
    h: Matrix6<f64>,
    b: Vector6<f64>,
    error: f64,
    inliers: usize,
}

impl System {
    fn zero() -> Self {
        Self {
            h: Matrix6::zeros(),
            b: Vector6::zeros(),
            error: 0.0,
            inliers: 0,
        }
    }

    fn add(mut self, other: &System) -> Self {
        self.h += other.h;
        self.b += other.b;
        self.error += other.error;
        self.inliers += other.inliers;
        self
    }
}

/// The skew-symmetric matrix of `v` (`skew(v) * w == v × w`).
#[inline]
fn skew(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// The SE(3) exponential of δ = (ω, v).
pub fn se3_exp(delta: &Vector6<f64>) -> Isometry3<f64> {
    let omega = Vector3::new(delta[0], delta[1], delta[2]);
    let v = Vector3::new(delta[3], delta[4], delta[5]);
    let rotation = UnitQuaternion::from_scaled_axis(omega);
    let theta_sq = omega.norm_squared();
    let translation = if theta_sq < 1e-20 {
        rotation * v
    } else {
        let theta = theta_sq.sqrt();
        let w = skew(&omega);
        let jacobian = Matrix3::identity()
            + w * ((1.0 - theta.cos()) / theta_sq)
            + w * w * ((theta - theta.sin()) / (theta_sq * theta));
        jacobian * v
    };
    Isometry3::from_parts(Translation3::from(translation), rotation)
}

/// One registration: a target, a source, the cost, and the rejection distance.
pub(crate) struct Problem<'a> {
    pub variant: Variant,
    pub target: &'a PreparedData,
    pub source: &'a PreparedData,
    pub max_sq_distance: f64,
    /// Voxel offsets searched for a VGICP correspondence.
    pub voxel_offsets: &'a [[i32; 3]],
}

impl Problem<'_> {
    /// Finds correspondences at `pose`, stores them in `links`, and returns the reduced normal equations.
    fn linearize(&self, pose: &Isometry3<f64>, links: &mut [Link]) -> System {
        let r = *pose.rotation.to_rotation_matrix().matrix();
        let t = pose.translation.vector;
        let partials: Vec<System> = links
            .par_chunks_mut(REDUCTION_CHUNK)
            .enumerate()
            .map(|(chunk_index, chunk)| {
                let mut system = System::zero();
                for (offset, link) in chunk.iter_mut().enumerate() {
                    let i = chunk_index * REDUCTION_CHUNK + offset;
                    *link = self.linearize_point(i, &r, &t, &mut system).unwrap_or(Link::NONE);
                }
                system
            })
            .collect();
        partials.iter().fold(System::zero(), System::add)
    }

    /// Adds source point `i`'s factor to `system` and returns its link, or `None` for an outlier.
    #[inline]
    fn linearize_point(
        &self,
        i: usize,
        r: &Matrix3<f64>,
        t: &Vector3<f64>,
        system: &mut System,
    ) -> Option<Link> {
        let p = self.source.points[i];
        let q = r * p + t;
        let (target, target_point) = match &self.target.voxel_map {
            Some(map) if self.variant == Variant::Vgicp => {
                let (j, d2) = map.nearest(&q, self.voxel_offsets)?;
                (d2 <= self.max_sq_distance).then_some((j, map.means[j]))?
            }
            _ => {
                let (j, d2) = self.target.tree.nearest(&q)?;
                (d2 <= self.max_sq_distance).then_some((j, self.target.points[j]))?
            }
        };
        let residual = target_point - q;
        let mut jacobian = Matrix3x6::zeros();
        jacobian.fixed_view_mut::<3, 3>(0, 0).copy_from(&(r * skew(&p)));
        jacobian.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-r));
        let mut weight = Matrix3::zeros();
        match self.variant {
            Variant::Icp => {
                system.h += jacobian.transpose() * jacobian;
                system.b += jacobian.transpose() * residual;
                system.error += 0.5 * residual.norm_squared();
            }
            Variant::PlaneIcp => {
                let normal = self.target.normals[target];
                if normal == Vector3::zeros() {
                    return None;
                }
                let row = normal.transpose() * jacobian;
                let error = normal.dot(&residual);
                system.h += row.transpose() * row;
                system.b += row.transpose() * error;
                system.error += 0.5 * error * error;
            }
            Variant::Gicp | Variant::Vgicp => {
                let target_cov = match &self.target.voxel_map {
                    Some(map) if self.variant == Variant::Vgicp => map.covariances[target],
                    _ => self.target.covariances[target],
                };
                let combined = target_cov + r * self.source.covariances[i] * r.transpose();
                weight = combined
                    .try_inverse()
                    .filter(|m| m.iter().all(|v| v.is_finite()))?;
                let weighted = weight * jacobian;
                system.h += jacobian.transpose() * weighted;
                system.b += weighted.transpose() * residual;
                system.error += 0.5 * residual.dot(&(weight * residual));
            }
        }
        system.inliers += 1;
        Some(Link {
            target: target as u32,
            weight,
        })
    }

    /// The cost at `pose` with the correspondences fixed at the last linearisation.
    fn error(&self, pose: &Isometry3<f64>, links: &[Link]) -> f64 {
        let r = *pose.rotation.to_rotation_matrix().matrix();
        let t = pose.translation.vector;
        let partials: Vec<f64> = links
            .par_chunks(REDUCTION_CHUNK)
            .enumerate()
            .map(|(chunk_index, chunk)| {
                let mut sum = 0.0;
                for (offset, link) in chunk.iter().enumerate() {
                    if link.target == u32::MAX {
                        continue;
                    }
                    let i = chunk_index * REDUCTION_CHUNK + offset;
                    let j = link.target as usize;
                    let q = r * self.source.points[i] + t;
                    sum += match (self.variant, &self.target.voxel_map) {
                        (Variant::Vgicp, Some(map)) => {
                            let residual = map.means[j] - q;
                            0.5 * residual.dot(&(link.weight * residual))
                        }
                        (Variant::Gicp | Variant::Vgicp, _) => {
                            let residual = self.target.points[j] - q;
                            0.5 * residual.dot(&(link.weight * residual))
                        }
                        (Variant::Icp, _) => 0.5 * (self.target.points[j] - q).norm_squared(),
                        (Variant::PlaneIcp, _) => {
                            let error = self.target.normals[j].dot(&(self.target.points[j] - q));
                            0.5 * error * error
                        }
                    };
                }
                sum
            })
            .collect();
        partials.iter().sum()
    }
}

/// Where the optimisation ended.
#[derive(Clone, Debug)]
pub(crate) struct Solution {
    pub pose: Isometry3<f64>,
    /// Hessian of the last linearisation, ordered (ω, v).
    pub hessian: Matrix6<f64>,
    /// Cost at `pose` on the last correspondences.
    pub error: f64,
    /// Linearisations done.
    pub iterations: usize,
    /// Inliers at the last linearisation.
    pub inliers: usize,
    /// The last accepted step was below both epsilons.
    pub converged: bool,
}

/// Minimises the problem's cost from `guess` with Levenberg-Marquardt, in at most `max_iterations`
/// linearisations.
pub(crate) fn solve(
    problem: &Problem<'_>,
    guess: &Isometry3<f64>,
    config: &GicpConfig,
    max_iterations: usize,
) -> Solution {
    let rotation_eps = config.rotation_eps_deg.to_radians();
    let mut links = vec![Link::NONE; problem.source.points.len()];
    let mut lambda = config.lambda_init;
    let mut solution = Solution {
        pose: *guess,
        hessian: Matrix6::zeros(),
        error: 0.0,
        iterations: 0,
        inliers: 0,
        converged: false,
    };
    while solution.iterations < max_iterations && !solution.converged {
        let system = problem.linearize(&solution.pose, &mut links);
        solution.iterations += 1;
        solution.hessian = system.h;
        solution.error = system.error;
        solution.inliers = system.inliers;
        if system.inliers == 0 {
            break;
        }
        for _ in 0..config.max_inner_iterations {
            let damped = system.h + Matrix6::identity() * lambda;
            let delta = Cholesky::new(damped).map(|c| c.solve(&-system.b));
            let Some(delta) = delta.filter(|d| d.iter().all(|v| v.is_finite())) else {
                lambda *= config.lambda_factor;
                continue;
            };
            let mut candidate = solution.pose * se3_exp(&delta);
            candidate.rotation.renormalize();
            let error = problem.error(&candidate, &links);
            if error.is_finite() && error <= system.error {
                solution.converged = delta.fixed_rows::<3>(0).norm() < rotation_eps
                    && delta.fixed_rows::<3>(3).norm() < config.translation_eps_m;
                solution.pose = candidate;
                solution.error = error;
                lambda /= config.lambda_factor;
                break;
            }
            lambda *= config.lambda_factor;
        }
    }
    solution
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exp_of_pure_translation_and_rotation() {
        let t = se3_exp(&Vector6::new(0.0, 0.0, 0.0, 1.0, 2.0, 3.0));
        assert!((t.translation.vector - Vector3::new(1.0, 2.0, 3.0)).norm() < 1e-12);
        let r = se3_exp(&Vector6::new(
            0.0,
            0.0,
            std::f64::consts::FRAC_PI_2,
            0.0,
            0.0,
            0.0,
        ));
        assert!(
            (r * nalgebra::Point3::new(1.0, 0.0, 0.0) - nalgebra::Point3::new(0.0, 1.0, 0.0)).norm() < 1e-12
        );
    }

    #[test]
    fn exp_matches_the_composition_of_small_steps() {
        let delta = Vector6::new(0.3, -0.2, 0.5, 1.0, -2.0, 0.5);
        let steps = 100_000;
        let step = se3_exp(&(delta / f64::from(steps)));
        let mut composed = Isometry3::identity();
        for _ in 0..steps {
            composed *= step;
        }
        let exact = se3_exp(&delta);
        assert!((composed.translation.vector - exact.translation.vector).norm() < 1e-6);
        assert!(composed.rotation.angle_to(&exact.rotation) < 1e-6);
    }
}
