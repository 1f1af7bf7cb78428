//! The iterated update of the error-state Kalman filter with point-to-plane residuals (FAST-LIO2, Xu et
//! al., T-RO 2022, Sec. IV-D). At each iterate `x̂ⱼ` every scan point `p` (sensor frame) goes to the world
//! as `q = R(R_IS p + t_IS) + t`, its `k` nearest map points give a plane `(n, d)`, and the residual is
//! `zᵢ = nᵀq + d` with the Jacobian `Hᵢ = [−nᵀR[R_IS p + t_IS]×, nᵀ, 0…]` on the error state. The step
//! solves the maximum a posteriori problem around the prior `(x̂, P)`:
//! `(HᵀR⁻¹H + P⁻¹)Δ = −HᵀR⁻¹z − P⁻¹(x̂ⱼ ⊟ x̂)`, `x̂ⱼ₊₁ = x̂ⱼ ⊞ Δ`, which is FAST-LIO2's gain form
//! `K = (HᵀR⁻¹H + P⁻¹)⁻¹HᵀR⁻¹` written without the matrix `K`; the posterior covariance is
//! `(HᵀR⁻¹H + P⁻¹)⁻¹`. A point is used when its plane fits its neighbours within a few centimetres
//! and, as in FAST-LIO2, `1 − 0.9|z|/√‖p‖ > 0.9`.
//!
//! Degeneracy (Zhang, Kaess and Singh, ICRA 2016): the eigenvalues of the pose block of `HᵀH` say how
//! well the scan's planes constrain each direction. Rotation (rad) and translation (m) are judged apart,
//! each with the other marginalised out (the Schur complement), since their units differ by the squared
//! range; a direction below `degeneracy_ratio` of its block's best is reported, and there the prior (the
//! IMU's prediction) carries the estimate, since the update's information adds almost nothing.

use nalgebra::{Matrix6, SMatrix, Vector3, Vector6};
use rayon::prelude::*;
use skid_core::Pose;

use crate::plane_map::{Plane, PlaneMap, fit_plane};
use crate::state::{Covariance, DIM, ErrorVector, POS, ROT, State, skew};

/// The update's settings.
#[derive(Clone, Copy, Debug)]
pub struct UpdateSettings {
    pub point_variance_m2: f64,
    pub plane_neighbours: usize,
    pub max_plane_distance_m: f64,
    pub max_iterations: usize,
    pub degeneracy_ratio: f64,
}

/// What the update did.
#[derive(Clone, Debug, PartialEq)]
pub struct UpdateOutcome {
    pub state: State,
    pub covariance: Covariance,
    pub iterations: usize,
    /// Points with a plane in the last iteration.
    pub correspondences: usize,
    /// Eigenvalues of the pose information `HᵀH`, rotation's three then translation's three (each
    /// ascending, each block with the other marginalised out), and whether a direction is degenerate.
    pub information_eigenvalues: [f64; 6],
    pub degenerate: bool,
}

/// A point in the world frame (with its IMU-frame position) under the state.
fn place(state: &State, imu_from_sensor: &Pose, point: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let in_imu = (imu_from_sensor * nalgebra::Point3::from(*point)).coords;
    (state.rotation * in_imu + state.position, in_imu)
}

/// The plane the map fits around the point under the state, if its neighbours are planar.
fn find_plane(
    state: &State,
    imu_from_sensor: &Pose,
    map: &PlaneMap,
    point: &Vector3<f64>,
    settings: &UpdateSettings,
    scratch: &mut Vec<(f64, Vector3<f64>)>,
) -> Option<Plane> {
    let (world, _) = place(state, imu_from_sensor, point);
    map.nearest(&world, settings.plane_neighbours, scratch);
    if scratch.len() < settings.plane_neighbours {
        return None;
    }
    fit_plane(scratch, settings.max_plane_distance_m)
}

/// One point's contribution against its plane: `Hᵢᵀ Hᵢ` and `Hᵢᵀ zᵢ` on the pose block.
fn point_terms(
    state: &State,
    imu_from_sensor: &Pose,
    plane: &Plane,
    point: &Vector3<f64>,
) -> Option<(Matrix6<f64>, Vector6<f64>)> {
    let (world, in_imu) = place(state, imu_from_sensor, point);
    let residual = plane.distance(&world);
    let range = point.norm();
    // FAST-LIO2's test `1 − 0.9|z|/√‖p‖ > 0.9`: far points may sit a little farther from their plane.
    let score = 1.0 - 0.9 * residual.abs() / range.max(1e-3).sqrt();
    if score <= 0.9 || score.is_nan() {
        return None;
    }
    let rotation = state.rotation.to_rotation_matrix().into_inner();
    let d_rotation = -(plane.normal.transpose() * rotation * skew(&in_imu));
    let mut jacobian = Vector6::zeros();
    jacobian.fixed_rows_mut::<3>(0).copy_from(&d_rotation.transpose());
    jacobian.fixed_rows_mut::<3>(3).copy_from(&plane.normal);
    Some((jacobian * jacobian.transpose(), jacobian * residual))
}

/// Planes are searched again after a step larger than this (metres, radians); smaller steps keep each
/// point's plane and only re-evaluate its residual, as FAST-LIO2 searches only when the estimate moved.
/// At 5 cm / 0.3° the default world's first 100 scans came out 2.1 % long; at 1 cm / 0.1°, 0.6-1.7 %.
const RESEARCH_TRANSLATION_M: f64 = 0.01;
const RESEARCH_ROTATION_RAD: f64 = 0.002;

/// The iterated update of the prior `(prior, covariance)` with the scan `points` (sensor frame, at the
/// state's time) against `map`. `None` when no point found a plane (the prior stands).
pub fn iterated_update(
    prior: &State,
    covariance: &Covariance,
    imu_from_sensor: &Pose,
    points: &[Vector3<f64>],
    map: &PlaneMap,
    settings: &UpdateSettings,
) -> Option<UpdateOutcome> {
    let prior_information = covariance.try_inverse()?;
    let mut estimate = *prior;
    let mut outcome = None;
    let mut planes: Vec<Option<Plane>> = vec![None; points.len()];
    let mut search = true;
    for iteration in 1..=settings.max_iterations {
        // Chunks in a fixed order keep the sum the same whatever the thread count.
        let (information, gradient, count) = points
            .par_chunks(1024)
            .zip(planes.par_chunks_mut(1024))
            .map_init(Vec::new, |scratch, (chunk, chunk_planes)| {
                let mut information = Matrix6::zeros();
                let mut gradient = Vector6::zeros();
                let mut count = 0usize;
                for (point, plane) in chunk.iter().zip(chunk_planes.iter_mut()) {
                    if search {
                        *plane = find_plane(&estimate, imu_from_sensor, map, point, settings, scratch);
                    }
                    if let Some((hth, htz)) = plane
                        .as_ref()
                        .and_then(|plane| point_terms(&estimate, imu_from_sensor, plane, point))
                    {
                        information += hth;
                        gradient += htz;
                        count += 1;
                    }
                }
                (information, gradient, count)
            })
            .collect::<Vec<_>>()
            .into_iter()
            .fold((Matrix6::zeros(), Vector6::zeros(), 0usize), |a, b| {
                (a.0 + b.0, a.1 + b.1, a.2 + b.2)
            });
        if count == 0 {
            return outcome;
        }
        let weight = 1.0 / settings.point_variance_m2;
        let mut system: SMatrix<f64, DIM, DIM> = prior_information;
        let mut pose_block = system.fixed_view_mut::<6, 6>(ROT, ROT);
        pose_block += information * weight;
        let offset = estimate.minus(prior);
        let mut rhs: ErrorVector = -(prior_information * offset);
        let mut pose_rhs = rhs.fixed_rows_mut::<6>(ROT);
        pose_rhs -= gradient * weight;
        let cholesky = system.cholesky()?;
        let step = cholesky.solve(&rhs);
        estimate = estimate.plus(&step);
        if !estimate.is_finite() {
            return None;
        }
        // The pose block is rotation first, then translation.
        let (rotation, translation) = skid_geometry::marginal_spectra(&information);
        let degenerate = rotation.is_degenerate(settings.degeneracy_ratio)
            || translation.is_degenerate(settings.degeneracy_ratio);
        let (rotation, translation) = (rotation.values, translation.values);
        outcome = Some(UpdateOutcome {
            state: estimate,
            covariance: cholesky.inverse(),
            iterations: iteration,
            correspondences: count,
            information_eigenvalues: [
                rotation[0],
                rotation[1],
                rotation[2],
                translation[0],
                translation[1],
                translation[2],
            ],
            degenerate,
        });
        let rotation_step = step.fixed_rows::<3>(ROT).norm();
        let translation_step = step.fixed_rows::<3>(POS).norm();
        if rotation_step < 1e-4 && translation_step < 1e-3 {
            break;
        }
        search = rotation_step > RESEARCH_ROTATION_RAD || translation_step > RESEARCH_TRANSLATION_M;
    }
    outcome
}
