//! Faster-PFH features (Lim et al., "KISS-Matcher", ICRA 2025), the fast variant of FPFH (Rusu et al.,
//! "Fast Point Feature Histograms", ICRA 2009). Shared by the KISS-Matcher and RANSAC plugins.
//!
//! Per point, one radius search at the FPFH radius serves every stage:
//! 1. The normal is the smallest-eigenvalue direction of the covariance of the neighbours within the
//!    (smaller) normal radius, itself included. Fewer than `min_neighbours` such points, a degenerate
//!    covariance, or a linearity (λ1 − λ2)/λ1 above `linearity_threshold` make the normal invalid. Normals
//!    are oriented towards the viewpoint (the sensor, the cloud frame's origin for a keyframe).
//! 2. A point is a keypoint when its normal is valid and at least `min_neighbours` points with valid
//!    normals (itself included) lie within the FPFH radius.
//! 3. SPFH: the Darboux-frame angles (α, φ, θ) between the keypoint and each valid neighbour, binned into
//!    11 + 11 + 11 bins, each pair adding 100 / (valid neighbours) to its bins.
//! 4. FPFH: the keypoint's SPFH (weight 1) plus the valid neighbours' SPFHs weighted by the inverse
//!    squared distance (the KISS-Matcher choice; the FPFH paper uses the inverse distance), then each
//!    11-bin block scaled to sum to 100. A descriptor therefore sums to 300.
//!
//! The reference implementation also bins the angle features of neighbours whose normal is invalid (their
//! NaN angles land in bin 0); here such neighbours are skipped, as the FPFH definition intends.

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use nalgebra::{Matrix3, SymmetricEigen, Vector3};
use rayon::prelude::*;
use skid_core::CloudView;
use skid_geometry::{voxel_centroids, voxel_downsample};

/// Bins per angle feature.
pub const BINS_PER_FEATURE: usize = 11;
/// Length of a descriptor: three 11-bin histograms.
pub const DESCRIPTOR_LEN: usize = 3 * BINS_PER_FEATURE;
/// One Faster-PFH descriptor.
pub type Descriptor = [f32; DESCRIPTOR_LEN];

/// What the feature extraction needs to know (radii already in metres).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FeatureParams {
    /// Radius of the neighbourhood used for the normal, in metres.
    pub normal_radius_m: f32,
    /// Radius of the neighbourhood used for the histogram (and searched once per point), in metres.
    pub fpfh_radius_m: f32,
    /// Fewest points (the query point included) for a normal, and fewest valid-normal points within the
    /// FPFH radius for a keypoint.
    pub min_neighbours: usize,
    /// Normals of neighbourhoods more linear than this are invalid; 1.0 disables the test.
    pub linearity_threshold: f32,
}

/// Keypoints and their descriptors; `points[i]` has `descriptors[i]`.
#[derive(Clone, Debug, Default)]
pub struct Features {
    pub points: Vec<Vector3<f32>>,
    pub descriptors: Vec<Descriptor>,
    /// Index of each keypoint in the input point list.
    pub input_indices: Vec<u32>,
}

impl Features {
    pub fn len(&self) -> usize {
        self.points.len()
    }

    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }
}

/// How a voxel grid picks the point that stands for each voxel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum VoxelSampling {
    /// The centroid of the voxel's points, as the reference KISS-Matcher samples: averaging takes the
    /// range noise out of the positions, so normals, features and correspondences are more precise.
    Centroid,
    /// The first point met in each voxel (a real measurement, as KISS-ICP keeps).
    FirstPoint,
}

/// The cloud voxel-sampled as `sampling` says (non-finite points dropped, voxels in the order first met)
/// as f32 vectors; a non-positive voxel size keeps every finite point.
pub fn voxel_sample(cloud: CloudView<'_>, voxel_size_m: f32, sampling: VoxelSampling) -> Vec<Vector3<f32>> {
    let sampled = match sampling {
        VoxelSampling::Centroid => voxel_centroids(cloud.points(), voxel_size_m),
        VoxelSampling::FirstPoint => voxel_downsample(cloud.points(), voxel_size_m),
    };
    sampled.iter().map(|p| Vector3::new(p.x, p.y, p.z)).collect()
}

/// A 3-D kd-tree over points, items being their indices.
pub type PointTree = ImmutableKdTree<f32, 3>;

/// Builds the 3-D tree; `None` for an empty input or when kiddo refuses the points.
pub fn build_point_tree(points: &[Vector3<f32>]) -> Option<PointTree> {
    if points.is_empty() {
        return None;
    }
    let coords: Vec<[f32; 3]> = points.iter().map(|p| [p.x, p.y, p.z]).collect();
    PointTree::new_from_slice(&coords).ok()
}

/// Computes the Faster-PFH keypoints and descriptors of `points` (already voxel-sampled), with normals
/// oriented towards `viewpoint`. Runs on the current rayon pool; the result does not depend on it.
pub fn compute_features(
    points: &[Vector3<f32>],
    viewpoint: &Vector3<f32>,
    params: &FeatureParams,
) -> Features {
    let Some(tree) = build_point_tree(points) else {
        return Features::default();
    };
    let fpfh_radius_sq = params.fpfh_radius_m * params.fpfh_radius_m;
    let normal_radius_sq = params.normal_radius_m * params.normal_radius_m;
    let min_neighbours = params.min_neighbours.max(1);

    // One radius search per point; neighbours sorted by index so every sum below runs in a fixed order.
    let neighbourhoods: Vec<Vec<(u32, f32)>> = points
        .par_iter()
        .map_init(
            || tree.create_scratch::<SquaredEuclidean<f32>>(),
            |scratch, p| {
                let mut found = Vec::new();
                tree.query(&[p.x, p.y, p.z])
                    .within::<SquaredEuclidean<f32>>(fpfh_radius_sq)
                    .unsorted()
                    .with_scratch(scratch)
                    .visit(|item| found.push((item.item, item.distance)));
                found.sort_unstable_by_key(|&(index, _)| index);
                found
            },
        )
        .collect();

    let normals: Vec<Option<Vector3<f32>>> = points
        .par_iter()
        .zip(&neighbourhoods)
        .map(|(p, neighbours)| {
            estimate_normal(
                points,
                neighbours,
                normal_radius_sq,
                min_neighbours,
                params.linearity_threshold,
            )
            .map(|n| if n.dot(&(viewpoint - p)) < 0.0 { -n } else { n })
        })
        .collect();

    let is_keypoint: Vec<bool> = neighbourhoods
        .par_iter()
        .zip(&normals)
        .map(|(neighbours, normal)| {
            normal.is_some()
                && neighbours
                    .iter()
                    .filter(|&&(j, _)| normals[j as usize].is_some())
                    .count()
                    >= min_neighbours
        })
        .collect();

    // SPFH of every point with a valid normal (keypoints' neighbours need theirs too).
    let spfh: Vec<Option<Descriptor>> = (0..points.len())
        .into_par_iter()
        .map(|i| {
            let normal = normals[i]?;
            Some(point_spfh(points, &normals, i, &normal, &neighbourhoods[i]))
        })
        .collect();

    let keypoints: Vec<u32> = (0..points.len() as u32)
        .filter(|&i| is_keypoint[i as usize])
        .collect();
    let descriptors: Vec<Descriptor> = keypoints
        .par_iter()
        .map(|&i| weighted_fpfh(&spfh, &neighbourhoods[i as usize]))
        .collect();
    Features {
        points: keypoints.iter().map(|&i| points[i as usize]).collect(),
        descriptors,
        input_indices: keypoints,
    }
}

/// PCA normal of the neighbours within the normal radius, or `None` when it is not trustworthy: too few
/// neighbours, collinear neighbours, or a neighbourhood more linear than `linearity_threshold`.
fn estimate_normal(
    points: &[Vector3<f32>],
    neighbours: &[(u32, f32)],
    normal_radius_sq: f32,
    min_neighbours: usize,
    linearity_threshold: f32,
) -> Option<Vector3<f32>> {
    let near = || {
        neighbours
            .iter()
            .filter(move |&&(_, d2)| d2 < normal_radius_sq)
            .map(|&(j, _)| points[j as usize].cast::<f64>())
    };
    let count = near().count();
    if count < min_neighbours.max(3) {
        return None;
    }
    let mean = near().sum::<Vector3<f64>>() / count as f64;
    let covariance = near().fold(Matrix3::zeros(), |acc, p| {
        let d = p - mean;
        acc + d * d.transpose()
    }) / (count - 1) as f64;
    let eigen = SymmetricEigen::new(covariance);
    let mut order = [0usize, 1, 2];
    order.sort_by(|&a, &b| eigen.eigenvalues[b].total_cmp(&eigen.eigenvalues[a]));
    let (largest, middle) = (eigen.eigenvalues[order[0]], eigen.eigenvalues[order[1]]);
    // Collinear (or coincident) neighbours leave the normal undefined, whatever the linearity test says.
    if !(largest.is_finite() && largest > 1e-12 && middle > 1e-6 * largest) {
        return None;
    }
    let linearity = (largest - middle) / largest;
    if linearity > f64::from(linearity_threshold) {
        return None;
    }
    let normal = eigen.eigenvectors.column(order[2]).into_owned();
    let norm = normal.norm();
    (norm.is_finite() && norm > 1e-9).then(|| (normal / norm).cast::<f32>())
}

/// The simplified point feature histogram of point `i` against its neighbours with valid normals.
fn point_spfh(
    points: &[Vector3<f32>],
    normals: &[Option<Vector3<f32>>],
    i: usize,
    normal: &Vector3<f32>,
    neighbours: &[(u32, f32)],
) -> Descriptor {
    let mut histogram = [0.0f32; DESCRIPTOR_LEN];
    let valid = neighbours
        .iter()
        .filter(|&&(j, _)| j as usize != i && normals[j as usize].is_some())
        .count();
    if valid == 0 {
        return histogram;
    }
    let increment = 100.0 / valid as f32;
    for &(j, _) in neighbours {
        let j = j as usize;
        let Some(other_normal) = normals[j].filter(|_| j != i) else {
            continue;
        };
        let Some([theta, alpha, phi]) = pair_features(&points[i], normal, &points[j], &other_normal) else {
            continue;
        };
        histogram[bin(theta, -std::f32::consts::PI, std::f32::consts::PI)] += increment;
        histogram[BINS_PER_FEATURE + bin(alpha, -1.0, 1.0)] += increment;
        histogram[2 * BINS_PER_FEATURE + bin(phi, -1.0, 1.0)] += increment;
    }
    histogram
}

/// The bin of `value` in [`low`, `high`] split into [`BINS_PER_FEATURE`] bins, clamped at the ends.
fn bin(value: f32, low: f32, high: f32) -> usize {
    let scaled = (value - low) / (high - low) * BINS_PER_FEATURE as f32;
    if scaled.is_nan() {
        return 0;
    }
    (scaled.floor().max(0.0) as usize).min(BINS_PER_FEATURE - 1)
}

/// The PFH pair features (θ, α, φ) of two oriented points: θ = atan2(w·n₂, u·n₂) ∈ [−π, π], α = v·n₂ and
/// φ = u·d/‖d‖ ∈ [−1, 1] in the Darboux frame u = n₁, v = d × u / ‖d × u‖, w = u × v, where the source of
/// the frame is the point whose normal makes the smaller angle with the connecting line (so the result
/// does not depend on the order of the two points). `None` for coincident points or when the line is
/// parallel to the normal.
pub fn pair_features(
    p1: &Vector3<f32>,
    n1: &Vector3<f32>,
    p2: &Vector3<f32>,
    n2: &Vector3<f32>,
) -> Option<[f32; 3]> {
    let mut delta = p2 - p1;
    let distance = delta.norm();
    if distance == 0.0 {
        return None;
    }
    let angle1 = n1.dot(&delta) / distance;
    let angle2 = n2.dot(&delta) / distance;
    let (u, n_other, phi) = if angle1.abs() < angle2.abs() {
        delta = -delta;
        (n2, n1, -angle2)
    } else {
        (n1, n2, angle1)
    };
    let v = delta.cross(u);
    let v_norm = v.norm();
    if v_norm == 0.0 {
        return None;
    }
    let v = v / v_norm;
    let w = u.cross(&v);
    let alpha = v.dot(n_other);
    let theta = w.dot(n_other).atan2(u.dot(n_other));
    Some([theta, alpha, phi])
}

/// FPFH of one keypoint: its SPFH plus its neighbours' weighted by 1/d², each block scaled to sum to 100.
fn weighted_fpfh(spfh: &[Option<Descriptor>], neighbours: &[(u32, f32)]) -> Descriptor {
    let mut histogram = [0.0f32; DESCRIPTOR_LEN];
    for &(j, d2) in neighbours {
        let Some(other) = &spfh[j as usize] else {
            continue;
        };
        let weight = if d2 > 0.0 { 1.0 / d2 } else { 1.0 };
        for (h, o) in histogram.iter_mut().zip(other) {
            *h += weight * o;
        }
    }
    for block in histogram.chunks_exact_mut(BINS_PER_FEATURE) {
        let sum: f32 = block.iter().sum();
        if sum > 0.0 && sum.is_finite() {
            let scale = 100.0 / sum;
            block.iter_mut().for_each(|h| *h *= scale);
        }
    }
    histogram
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Rotation3, Translation3};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    pub(crate) fn params() -> FeatureParams {
        FeatureParams {
            normal_radius_m: 0.9,
            fpfh_radius_m: 1.5,
            min_neighbours: 3,
            linearity_threshold: 1.0,
        }
    }

    /// A corner of walls and a rolling floor with a box, sampled on a jittered grid (so no two points sit
    /// exactly one radius apart, where rounding would decide membership).
    pub(crate) fn structured_scene() -> Vec<Vector3<f32>> {
        let mut rng = ChaCha8Rng::seed_from_u64(17);
        let mut jitter = |v: Vector3<f32>| v + Vector3::from_fn(|_, _| rng.random_range(-0.04f32..0.04));
        let mut points = Vec::new();
        let step = 0.3f32;
        for i in 0..40 {
            for j in 0..40 {
                let (a, b) = (i as f32 * step, j as f32 * step);
                points.push(jitter(Vector3::new(a - 6.0, b - 6.0, 0.1 * (a * 0.7).sin())));
                if j < 15 {
                    points.push(jitter(Vector3::new(a - 6.0, 6.0, b)));
                    points.push(jitter(Vector3::new(6.0, a - 6.0, b * (1.0 + 0.02 * a))));
                }
            }
        }
        for i in 0..8 {
            for j in 0..8 {
                let (a, b) = (i as f32 * step, j as f32 * step);
                points.push(jitter(Vector3::new(1.0 + a, -2.0 + b, 1.2)));
                points.push(jitter(Vector3::new(1.0 + a, -2.0, b * 0.5)));
                points.push(jitter(Vector3::new(1.0, -2.0 + b, a * 0.5)));
            }
        }
        points
    }

    #[test]
    fn pair_features_do_not_depend_on_the_order_of_the_points() {
        let (p1, n1) = (Vector3::new(0.0, 0.0, 0.0), Vector3::new(0.0, 0.0, 1.0));
        let (p2, n2) = (
            Vector3::new(1.0, 0.2, 0.1),
            Vector3::new(0.3, 0.1, 0.9).normalize(),
        );
        let a = pair_features(&p1, &n1, &p2, &n2).unwrap();
        let b = pair_features(&p2, &n2, &p1, &n1).unwrap();
        for (x, y) in a.iter().zip(&b) {
            assert!((x - y).abs() < 1e-5, "{a:?} vs {b:?}");
        }
        assert!(pair_features(&p1, &n1, &p1, &n1).is_none());
    }

    #[test]
    fn descriptors_are_invariant_to_rigid_motion() {
        let points = structured_scene();
        let viewpoint = Vector3::new(0.5, 0.3, 1.8);
        let before = compute_features(&points, &viewpoint, &params());
        assert!(before.len() > points.len() / 2, "{} keypoints", before.len());
        let motion = Translation3::new(12.0, -7.0, 0.5) * Rotation3::from_euler_angles(0.1, -0.05, 2.3);
        let moved: Vec<Vector3<f32>> = points
            .iter()
            .map(|p| {
                motion
                    .transform_point(&p.cast::<f64>().into())
                    .coords
                    .cast::<f32>()
            })
            .collect();
        let moved_viewpoint = motion
            .transform_point(&viewpoint.cast::<f64>().into())
            .coords
            .cast::<f32>();
        let after = compute_features(&moved, &moved_viewpoint, &params());
        assert_eq!(before.input_indices, after.input_indices);
        let changes: Vec<f32> = before
            .descriptors
            .iter()
            .zip(&after.descriptors)
            .map(|(a, b)| a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum())
            .collect();
        // Rounding can flip a pair across a bin edge or the normal of a point whose two smallest
        // eigenvalues nearly tie (a corner); nearly every descriptor must stay put all the same.
        let unchanged = changes.iter().filter(|&&c| c < 1e-2).count();
        assert!(
            unchanged * 100 >= changes.len() * 95,
            "{unchanged} of {} unchanged",
            changes.len()
        );
        // Against that, descriptors of different points do differ.
        let distinct = before.descriptors.windows(2).filter(|w| {
            w[0].iter()
                .zip(&w[1])
                .map(|(x, y)| (x - y) * (x - y))
                .sum::<f32>()
                > 1e-2
        });
        assert!(distinct.count() * 2 > before.len());
    }

    #[test]
    fn descriptor_blocks_sum_to_one_hundred() {
        let features = compute_features(&structured_scene(), &Vector3::new(0.0, 0.0, 2.0), &params());
        for descriptor in &features.descriptors {
            for block in descriptor.chunks_exact(BINS_PER_FEATURE) {
                let sum: f32 = block.iter().sum();
                assert!((sum - 100.0).abs() < 1e-2 || sum == 0.0, "block sums to {sum}");
            }
            assert!(descriptor.iter().all(|v| v.is_finite()));
        }
    }

    #[test]
    fn lines_and_tiny_inputs_give_no_keypoints() {
        let line: Vec<Vector3<f32>> = (0..50).map(|i| Vector3::new(i as f32 * 0.3, 0.0, 0.0)).collect();
        assert!(compute_features(&line, &Vector3::zeros(), &params()).is_empty());
        assert!(compute_features(&[], &Vector3::zeros(), &params()).is_empty());
        let two = [Vector3::new(0.0, 0.0, 0.0), Vector3::new(0.1, 0.0, 0.0)];
        assert!(compute_features(&two, &Vector3::zeros(), &params()).is_empty());
    }
}
