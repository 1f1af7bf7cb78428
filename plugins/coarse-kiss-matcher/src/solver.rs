//! The decoupled robust solver of TEASER++ (Yang et al., T-RO 2020) as KISS-Matcher (Lim et al., ICRA
//! 2025) uses it: rotation by graduated non-convexity with a truncated-least-squares cost (GNC-TLS, Yang
//! et al., RA-L 2020) on translation-invariant measurements, then translation by component-wise TLS
//! (adaptive voting, exact in one dimension). [`solve`] composes the two, for the pipeline and for the
//! second-best hypothesis test.

use nalgebra::{Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};
use skid_core::Pose;

use crate::KissMatcherConfig;

/// GNC-TLS settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GncParams {
    /// Residuals (metres) beyond this bound count as outliers.
    pub noise_bound_m: f64,
    /// Factor by which μ grows each iteration (> 1).
    pub gnc_factor: f64,
    pub max_iterations: usize,
    /// Stop when the weighted cost changes by less than this between iterations.
    pub cost_threshold: f64,
}

/// What GNC-TLS found.
#[derive(Clone, Debug)]
pub struct RotationEstimate {
    pub rotation: Rotation3<f64>,
    /// Final weight of every measurement, in [0, 1].
    pub weights: Vec<f64>,
    /// Measurements whose weight is at least 0.5.
    pub inlier_count: usize,
    pub iterations: usize,
}

/// The rotation minimising Σ wᵢ ‖dstᵢ − R srcᵢ‖² (Kabsch/Horn by SVD, without centring: the
/// measurements are translation-free). `None` when the weighted cross-covariance is not finite.
pub fn weighted_rotation(
    src: &[Vector3<f64>],
    dst: &[Vector3<f64>],
    weights: &[f64],
) -> Option<Rotation3<f64>> {
    let mut covariance = Matrix3::zeros();
    for ((s, d), &w) in src.iter().zip(dst).zip(weights) {
        covariance += w * d * s.transpose();
    }
    rotation_from_covariance(&covariance)
}

/// The rotation R maximising trace(Rᵀ H) for a cross-covariance H = Σ d sᵀ, with det R = +1.
pub fn rotation_from_covariance(covariance: &Matrix3<f64>) -> Option<Rotation3<f64>> {
    if !covariance.iter().all(|v| v.is_finite()) {
        return None;
    }
    let svd = covariance.svd(true, true);
    let (u, v_t) = (svd.u?, svd.v_t?);
    let mut correction = Matrix3::identity();
    if (u * v_t).determinant() < 0.0 {
        correction[(2, 2)] = -1.0;
    }
    let rotation = u * correction * v_t;
    rotation
        .iter()
        .all(|v| v.is_finite())
        .then(|| Rotation3::from_matrix_unchecked(rotation))
}

/// GNC-TLS rotation estimation: alternately solve a weighted rotation and update the TLS weights in
/// closed form while μ grows by `gnc_factor`, starting from the least-squares solution. `None` for no
/// measurements or non-finite data.
pub fn gnc_tls_rotation(
    src: &[Vector3<f64>],
    dst: &[Vector3<f64>],
    params: &GncParams,
) -> Option<RotationEstimate> {
    let n = src.len().min(dst.len());
    if n == 0 {
        return None;
    }
    let mut noise_bound_sq = params.noise_bound_m * params.noise_bound_m;
    if noise_bound_sq.is_nan() || noise_bound_sq <= 1e-16 {
        noise_bound_sq = 1e-2;
    }
    let gnc_factor = if params.gnc_factor > 1.0 {
        params.gnc_factor
    } else {
        1.4
    };
    let mut weights = vec![1.0; n];
    let mut residuals_sq = vec![0.0; n];
    let mut rotation = Rotation3::identity();
    let mut mu = 1.0;
    let mut previous_cost = f64::INFINITY;
    let mut iterations = 0;
    for iteration in 0..params.max_iterations.max(1) {
        iterations = iteration + 1;
        rotation = weighted_rotation(&src[..n], &dst[..n], &weights)?;
        for ((r, s), d) in residuals_sq.iter_mut().zip(src).zip(dst) {
            *r = (d - rotation * s).norm_squared();
        }
        if iteration == 0 {
            let max_residual = residuals_sq.iter().copied().fold(0.0, f64::max);
            mu = 1.0 / (2.0 * max_residual / noise_bound_sq - 1.0);
            // Every residual already within the bound: the least-squares solution is the answer.
            if mu <= 0.0 {
                break;
            }
        }
        let upper = (mu + 1.0) / mu * noise_bound_sq;
        let lower = mu / (mu + 1.0) * noise_bound_sq;
        let mut cost = 0.0;
        for (w, &r) in weights.iter_mut().zip(&residuals_sq) {
            cost += *w * r;
            *w = if r >= upper {
                0.0
            } else if r <= lower {
                1.0
            } else {
                ((noise_bound_sq * mu * (mu + 1.0) / r).sqrt() - mu).clamp(0.0, 1.0)
            };
        }
        let change = (cost - previous_cost).abs();
        mu *= gnc_factor;
        previous_cost = cost;
        if change < params.cost_threshold {
            break;
        }
    }
    let inlier_count = weights.iter().filter(|&&w| w >= 0.5).count();
    Some(RotationEstimate {
        rotation,
        weights,
        inlier_count,
        iterations,
    })
}

/// The truncated-least-squares estimate of a scalar: the t minimising Σ min((xᵢ − t)², bound²), found
/// exactly by sweeping the 2n interval ends xᵢ ± bound (between two ends the consensus set is fixed and
/// its mean is the optimum). Returns the estimate and which values lie within `bound` of it; `None` for
/// no values or non-finite data.
pub fn scalar_tls(values: &[f64], bound: f64) -> Option<(f64, Vec<bool>)> {
    if values.is_empty() || !bound.is_finite() || values.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let bound = bound.abs();
    let bound_sq = bound * bound;
    // Entering events sort before leaving ones at the same coordinate, so touching intervals overlap.
    let mut events: Vec<(f64, bool, usize)> = values
        .iter()
        .enumerate()
        .flat_map(|(i, &x)| [(x - bound, true, i), (x + bound, false, i)])
        .collect();
    events.sort_by(|a, b| a.0.total_cmp(&b.0).then(b.1.cmp(&a.1)));
    // Values are centred on their mean so the running sums of squares stay well conditioned.
    let centre = values.iter().sum::<f64>() / values.len() as f64;
    let (mut count, mut sum, mut sum_sq) = (0usize, 0.0, 0.0);
    let mut best = (f64::INFINITY, centre);
    for &(_, entering, i) in &events {
        let x = values[i] - centre;
        if entering {
            count += 1;
            sum += x;
            sum_sq += x * x;
        } else {
            count -= 1;
            sum -= x;
            sum_sq -= x * x;
        }
        if count == 0 {
            continue;
        }
        let mean = sum / count as f64;
        let residual = (sum_sq - sum * mean).max(0.0);
        let cost = residual + (values.len() - count) as f64 * bound_sq;
        if cost < best.0 {
            best = (cost, mean + centre);
        }
    }
    let estimate = best.1;
    let inliers = values.iter().map(|x| (x - estimate).abs() <= bound).collect();
    Some((estimate, inliers))
}

/// Component-wise TLS translation from `differences[i] = qᵢ − R pᵢ`; a correspondence is an inlier when it
/// is one on all three axes.
pub fn component_wise_translation(
    differences: &[Vector3<f64>],
    bound: f64,
) -> Option<(Vector3<f64>, Vec<bool>)> {
    let mut translation = Vector3::zeros();
    let mut inliers = vec![true; differences.len()];
    for axis in 0..3 {
        let values: Vec<f64> = differences.iter().map(|d| d[axis]).collect();
        let (estimate, axis_inliers) = scalar_tls(&values, bound)?;
        translation[axis] = estimate;
        for (a, b) in inliers.iter_mut().zip(axis_inliers) {
            *a &= b;
        }
    }
    Some((translation, inliers))
}

/// GNC-TLS rotation on the chain of translation-invariant measurements (consecutive differences, closed
/// into a loop, as the reference does), then component-wise TLS translation over every pruned
/// correspondence. Returns the pose, the rotation inliers and the final inliers.
pub(crate) fn solve(
    config: &KissMatcherConfig,
    source: &[Vector3<f64>],
    target: &[Vector3<f64>],
) -> Option<(Pose, usize, usize)> {
    let n = source.len();
    let order = chain_order(n);
    let (source_tims, target_tims): (Vec<_>, Vec<_>) = (0..n)
        .map(|k| {
            let (here, next) = (order[k], order[(k + 1) % n]);
            (source[next] - source[here], target[next] - target[here])
        })
        .unzip();
    let translation_bound_m = config.noise_bound_m(config.solver_noise_bound_gain);
    let gnc = GncParams {
        noise_bound_m: 2.0 * translation_bound_m,
        gnc_factor: config.gnc_factor,
        max_iterations: config.gnc_max_iterations,
        cost_threshold: config.gnc_cost_threshold,
    };
    let rotation = gnc_tls_rotation(&source_tims, &target_tims, &gnc)?;
    let differences: Vec<Vector3<f64>> = source
        .iter()
        .zip(target)
        .map(|(p, q)| q - rotation.rotation * p)
        .collect();
    let (translation, inliers) = component_wise_translation(&differences, translation_bound_m)?;
    let pose = Pose::from_parts(
        Translation3::from(translation),
        UnitQuaternion::from_rotation_matrix(&rotation.rotation),
    );
    skid_core::pose::is_finite(&pose).then(|| {
        (
            pose,
            rotation.inlier_count,
            inliers.iter().filter(|&&i| i).count(),
        )
    })
}

/// A fixed pseudo-random order of `n` correspondences (Fisher–Yates driven by SplitMix64 seeded with
/// `n`), so consecutive links of the measurement chain join correspondences far apart in the scan.
fn chain_order(n: usize) -> Vec<usize> {
    let mut order: Vec<usize> = (0..n).collect();
    let mut state = (n as u64) ^ 0x9e37_79b9_7f4a_7c15;
    let mut next = || {
        state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    };
    for i in (1..n).rev() {
        let j = (next() % (i as u64 + 1)) as usize;
        order.swap(i, j);
    }
    order
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn random_unit(rng: &mut ChaCha8Rng) -> Vector3<f64> {
        loop {
            let v = Vector3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            if v.norm() > 0.1 && v.norm() <= 1.0 {
                return v.normalize();
            }
        }
    }

    #[test]
    fn gnc_tls_recovers_a_rotation_with_ninety_percent_outliers() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let truth = Rotation3::from_euler_angles(0.3, -0.2, 2.8);
        let params = GncParams {
            noise_bound_m: 0.45,
            gnc_factor: 1.4,
            max_iterations: 100,
            cost_threshold: 0.005,
        };
        let (mut src, mut dst) = (Vec::new(), Vec::new());
        for k in 0..1000 {
            // Measurements like KISS-Matcher's: differences of points up to ~30 m apart.
            let s = random_unit(&mut rng) * rng.random_range(2.0..30.0);
            let d = if k % 10 == 0 {
                truth * s + random_unit(&mut rng) * rng.random_range(0.0..0.1)
            } else {
                random_unit(&mut rng) * rng.random_range(2.0..30.0)
            };
            src.push(s);
            dst.push(d);
        }
        let estimate = gnc_tls_rotation(&src, &dst, &params).unwrap();
        let error_deg = (estimate.rotation.inverse() * truth).angle().to_degrees();
        assert!(error_deg < 0.5, "rotation off by {error_deg}°");
        let inliers_found = (0..1000)
            .filter(|k| k % 10 == 0 && estimate.weights[*k] >= 0.5)
            .count();
        assert!(inliers_found >= 95, "{inliers_found} of 100 inliers kept");
        assert!(estimate.inlier_count <= 110, "{} inliers", estimate.inlier_count);
        // Least squares alone is pulled off by the outliers.
        let plain = weighted_rotation(&src, &dst, &[1.0; 1000]).unwrap();
        assert!((plain.inverse() * truth).angle().to_degrees() > error_deg);
    }

    #[test]
    fn noise_free_input_stops_at_least_squares() {
        let truth = Rotation3::from_euler_angles(0.0, 0.0, 1.0);
        let src = vec![
            Vector3::x(),
            Vector3::y(),
            Vector3::z(),
            Vector3::new(1.0, 1.0, 0.0),
        ];
        let dst: Vec<_> = src.iter().map(|s| truth * s).collect();
        let params = GncParams {
            noise_bound_m: 0.1,
            gnc_factor: 1.4,
            max_iterations: 100,
            cost_threshold: 0.005,
        };
        let estimate = gnc_tls_rotation(&src, &dst, &params).unwrap();
        assert_eq!(estimate.iterations, 1);
        assert!((estimate.rotation.inverse() * truth).angle() < 1e-9);
        assert!(gnc_tls_rotation(&[], &[], &params).is_none());
    }

    #[test]
    fn translation_tls_ignores_outliers() {
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let truth = Vector3::new(10.0, -4.0, 0.7);
        let differences: Vec<Vector3<f64>> = (0..400)
            .map(|k| {
                if k % 5 < 2 {
                    truth + Vector3::from_fn(|_, _| rng.random_range(-0.1..0.1))
                } else {
                    Vector3::from_fn(|_, _| rng.random_range(-50.0..50.0))
                }
            })
            .collect();
        let (translation, inliers) = component_wise_translation(&differences, 0.225).unwrap();
        assert!((translation - truth).norm() < 0.03, "{translation:?}");
        let planted = (0..400).filter(|k| k % 5 < 2 && inliers[*k]).count();
        assert_eq!(planted, 160);
        assert!(inliers.iter().filter(|&&i| i).count() < 165);
        let mean: Vector3<f64> = differences.iter().sum::<Vector3<f64>>() / 400.0;
        assert!(
            (mean - truth).norm() > 1.0,
            "the plain mean is wrong, so the test means something"
        );
    }

    #[test]
    fn scalar_tls_edge_cases() {
        assert!(scalar_tls(&[], 1.0).is_none());
        assert!(scalar_tls(&[f64::NAN], 1.0).is_none());
        let (estimate, inliers) = scalar_tls(&[3.0], 0.5).unwrap();
        assert_eq!((estimate, inliers), (3.0, vec![true]));
        // Two clusters: the larger wins.
        let (estimate, _) = scalar_tls(&[0.0, 0.1, 0.05, 5.0, 5.1], 0.3).unwrap();
        assert!((estimate - 0.05).abs() < 1e-9);
    }
}
