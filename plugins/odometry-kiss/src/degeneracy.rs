//! Degeneracy of a `kiss_icp` registration, and leaning on the motion model where the scan says nothing.
//!
//! Point-to-point ICP's own `JᵀJ` has the identity in its translation block whatever the scene, so it
//! cannot tell that smooth ground leaves horizontal translation free. The test therefore uses the
//! point-to-plane information of the registered scan (Zhang, Kaess and Singh, ICRA 2016): each source
//! point whose map neighbour's voxel is planar gives `J = [nᵀ, (p × n)ᵀ]` with the voxel's plane normal
//! `n`, and [`skid_geometry::marginal_spectra`] judges translation and rotation apart.
//!
//! Where translation is degenerate, the registration's departure from the constant-velocity prediction
//! is kept only in proportion to how well that direction is constrained (a direction with a `ratio` of
//! the best direction's information or more keeps all of it, one with none keeps nothing), in the
//! manner of Zhang et al.'s solution remapping: the motion model carries what the scan cannot see.

use nalgebra::{Matrix3, Matrix6, Point3, Vector3, Vector6};
use skid_core::Pose;
use skid_geometry::BlockSpectrum;

use crate::voxel_map::VoxelHashMap;

/// Source points used for the test at most (evenly strided): enough for a stable 6×6 information.
const MAX_TEST_POINTS: usize = 4096;
/// Fewest points of a voxel for a plane fit.
const MIN_PLANE_POINTS: usize = 5;
/// A voxel is planar when its smallest spread is below this fraction of its middle one.
const MAX_PLANE_THICKNESS_RATIO: f64 = 0.1;

/// The spectra of a registration's point-to-plane information, translation and rotation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Degeneracy {
    pub translation: BlockSpectrum,
    pub rotation: BlockSpectrum,
    /// Source points that found a planar map voxel.
    pub planar_points: usize,
}

/// The unit normal of the points' best-fit plane, when they are planar enough.
fn plane_normal(points: &[Point3<f64>]) -> Option<Vector3<f64>> {
    if points.len() < MIN_PLANE_POINTS {
        return None;
    }
    let count = points.len() as f64;
    let mean = points.iter().fold(Vector3::zeros(), |sum, p| sum + p.coords) / count;
    let scatter = points.iter().fold(Matrix3::zeros(), |sum, p| {
        let d = p.coords - mean;
        sum + d * d.transpose()
    });
    let eigen = scatter.symmetric_eigen();
    let mut order = [0usize, 1, 2];
    order.sort_by(|&a, &b| eigen.eigenvalues[a].total_cmp(&eigen.eigenvalues[b]));
    let (thinnest, middle) = (eigen.eigenvalues[order[0]], eigen.eigenvalues[order[1]]);
    (middle > 0.0 && thinnest < MAX_PLANE_THICKNESS_RATIO * middle)
        .then(|| eigen.eigenvectors.column(order[0]).into_owned())
}

/// The point-to-plane information (translation first) of `source_world` against `map`.
pub fn assess(source_world: &[Point3<f64>], map: &VoxelHashMap, max_correspondence_m: f64) -> Degeneracy {
    let stride = source_world.len().div_ceil(MAX_TEST_POINTS).max(1);
    let max_sq = max_correspondence_m * max_correspondence_m;
    let mut information = Matrix6::zeros();
    let mut planar_points = 0;
    for p in source_world.iter().step_by(stride) {
        let Some((q, distance_sq)) = map.nearest(p) else {
            continue;
        };
        if distance_sq >= max_sq {
            continue;
        }
        let Some(n) = plane_normal(map.voxel_points_at(&q)) else {
            continue;
        };
        let moment = p.coords.cross(&n);
        let j = Vector6::new(n.x, n.y, n.z, moment.x, moment.y, moment.z);
        information += j * j.transpose();
        planar_points += 1;
    }
    let (translation, rotation) = skid_geometry::marginal_spectra(&information);
    Degeneracy {
        translation,
        rotation,
        planar_points,
    }
}

/// `registered` with its translational departure from `prediction` scaled down in the weakly
/// constrained directions (each by its information ratio over `ratio`, capped at 1).
pub fn lean_on_prediction(
    registered: &Pose,
    prediction: &Pose,
    translation: &BlockSpectrum,
    ratio: f64,
) -> Pose {
    let departure = registered.translation.vector - prediction.translation.vector;
    let mut kept = departure;
    for (direction, direction_ratio) in translation.ratios().iter().enumerate() {
        let keep = (direction_ratio / ratio).min(1.0);
        let axis = translation.vectors.column(direction);
        kept -= (1.0 - keep) * axis.dot(&departure) * axis;
    }
    let mut leaned = *registered;
    leaned.translation.vector = prediction.translation.vector + kept;
    leaned
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ground_map() -> VoxelHashMap {
        let mut map = VoxelHashMap::new(1.0, 20);
        let mut points = Vec::new();
        for x in -200..=200 {
            for y in -200..=200 {
                points.push(Point3::new(f64::from(x) * 0.1, f64::from(y) * 0.1, -1.5));
            }
        }
        map.add_points(&points);
        map
    }

    #[test]
    fn smooth_ground_is_degenerate_in_horizontal_translation_and_the_prediction_carries_it() {
        let map = ground_map();
        let scan: Vec<Point3<f64>> = (0..2000)
            .map(|i| {
                let angle = f64::from(i) * 0.0031;
                let range = 3.0 + f64::from(i % 50) * 0.3;
                Point3::new(range * angle.cos(), range * angle.sin(), -1.5)
            })
            .collect();
        let degeneracy = assess(&scan, &map, 1.0);
        assert!(degeneracy.planar_points > 1000);
        assert!(degeneracy.translation.is_degenerate(0.05));
        // The registration slid 0.5 m along the ground and 0.02 m up; the slide goes, the vertical stays.
        let prediction = Pose::identity();
        let registered = Pose::new(Vector3::new(0.5, 0.0, 0.02), Vector3::zeros());
        let leaned = lean_on_prediction(&registered, &prediction, &degeneracy.translation, 0.05);
        assert!(leaned.translation.vector.xy().norm() < 1e-6, "{leaned:?}");
        assert!((leaned.translation.vector.z - 0.02).abs() < 1e-6);
    }

    #[test]
    fn a_well_constrained_registration_is_kept_whole() {
        let mut map = ground_map();
        let mut walls = Vec::new();
        for a in -100..=100 {
            for h in 0..30 {
                let (t, z) = (f64::from(a) * 0.1, f64::from(h) * 0.1 - 1.5);
                walls.extend([
                    Point3::new(10.0, t, z),
                    Point3::new(-10.0, t, z),
                    Point3::new(t, 10.0, z),
                    Point3::new(t, -10.0, z),
                ]);
            }
        }
        map.add_points(&walls);
        let degeneracy = assess(
            &walls.iter().chain(map.points()).copied().collect::<Vec<_>>(),
            &map,
            1.0,
        );
        assert!(
            !degeneracy.translation.is_degenerate(0.05),
            "{:?}",
            degeneracy.translation
        );
        let registered = Pose::new(Vector3::new(0.3, -0.2, 0.1), Vector3::zeros());
        let leaned = lean_on_prediction(&registered, &Pose::identity(), &degeneracy.translation, 0.05);
        assert!((leaned.translation.vector - registered.translation.vector).norm() < 1e-12);
    }
}
