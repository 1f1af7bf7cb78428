//! One scan as the free-space check reads it: its finite points, a kd-tree over them (for the distance
//! to its surfaces and for its points' normals) and its range image.

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use nalgebra::{Matrix3, Point3, Vector3};
use skid_core::Point;
use std::num::NonZeroUsize;

use super::range_image::RangeImage;

/// Neighbours a point's normal is fitted to.
const NORMAL_NEIGHBOURS: usize = 10;

pub(super) struct IndexedScan {
    pub points: Vec<Point>,
    tree: Option<ImmutableKdTree<f32, 3>>,
    pub image: RangeImage,
}

impl IndexedScan {
    pub(super) fn new(points: &[Point], pixel_deg: f64, min_range_m: f64) -> Self {
        let points: Vec<Point> = points.iter().filter(|p| p.is_finite()).copied().collect();
        let coordinates: Vec<[f32; 3]> = points.iter().map(|p| [p.x, p.y, p.z]).collect();
        // An empty scan has no tree: it saw nothing, and nothing is near its surfaces.
        let tree = ImmutableKdTree::<f32, 3>::new_from_slice(&coordinates).ok();
        let image = RangeImage::new(&points, pixel_deg, min_range_m);
        Self { points, tree, image }
    }

    /// The squared distance from `at` (in this scan's frame) to its nearest point; infinity for an
    /// empty scan.
    pub(super) fn nearest_squared_m2(&self, at: &Point3<f64>) -> f64 {
        self.tree.as_ref().map_or(f64::INFINITY, |tree| {
            let found = tree
                .query(&[at.x as f32, at.y as f32, at.z as f32])
                .nearest_one::<SquaredEuclidean<f32>>()
                .execute();
            f64::from(found.distance)
        })
    }

    /// The unit normal of this scan's surface at `at` (in its frame): the direction of least spread of
    /// its nearest points; `None` where they do not span a surface.
    pub(super) fn normal_at(&self, at: &Point3<f64>) -> Option<Vector3<f64>> {
        let tree = self.tree.as_ref()?;
        let found = tree
            .query(&[at.x as f32, at.y as f32, at.z as f32])
            .nearest_n::<SquaredEuclidean<f32>>(NonZeroUsize::new(NORMAL_NEIGHBOURS)?)
            .execute();
        if found.len() < 5 {
            return None;
        }
        let neighbours: Vec<Vector3<f64>> = found
            .iter()
            .map(|item| {
                let p = self.points[item.item as usize];
                Vector3::new(f64::from(p.x), f64::from(p.y), f64::from(p.z))
            })
            .collect();
        let mean = neighbours.iter().sum::<Vector3<f64>>() / neighbours.len() as f64;
        let scatter: Matrix3<f64> = neighbours
            .iter()
            .map(|p| (p - mean) * (p - mean).transpose())
            .sum();
        let eigen = scatter.symmetric_eigen();
        let (smallest, _) = eigen
            .eigenvalues
            .iter()
            .enumerate()
            .min_by(|a, b| a.1.total_cmp(b.1))?;
        let mut sorted: Vec<f64> = eigen.eigenvalues.iter().copied().collect();
        sorted.sort_by(f64::total_cmp);
        // Points along a line (a pole, one ring) fix no surface.
        (sorted[1] > 4.0 * sorted[0].max(1e-12)).then(|| eigen.eigenvectors.column(smallest).normalize())
    }
}
