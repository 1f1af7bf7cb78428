//! The kd-tree over a prepared cloud (kiddo's immutable tree, built in parallel on the plugin's pool):
//! exact nearest-neighbour and k-nearest-neighbour queries returning point indices.

use std::num::NonZeroUsize;

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use nalgebra::Vector3;

/// An exact kd-tree over 3-D points; items are indices into the cloud it was built from.
pub struct PointTree {
    tree: Option<ImmutableKdTree<f64, 3>>,
}

impl PointTree {
    /// Builds the tree (in parallel on the current rayon pool for large clouds). An empty cloud gives a
    /// tree that finds nothing.
    pub fn build(points: &[Vector3<f64>]) -> Self {
        if points.is_empty() {
            return Self { tree: None };
        }
        let coords: Vec<[f64; 3]> = points.iter().map(|p| [p.x, p.y, p.z]).collect();
        let tree = ImmutableKdTree::<f64, 3>::new_from_slice_parallel(&coords).ok();
        Self { tree }
    }

    /// Index and squared distance of the nearest point.
    #[inline]
    pub fn nearest(&self, query: &Vector3<f64>) -> Option<(usize, f64)> {
        let tree = self.tree.as_ref()?;
        let found = tree
            .query(&[query.x, query.y, query.z])
            .nearest_one::<SquaredEuclidean<f64>>()
            .execute();
        let distance = found.distance;
        distance.is_finite().then_some((found.item as usize, distance))
    }

    /// Indices of the `k` nearest points (fewer when the cloud is smaller), appended to `out`.
    #[inline]
    pub fn knn(&self, query: &Vector3<f64>, k: usize, out: &mut Vec<usize>) {
        out.clear();
        let (Some(tree), Some(k)) = (self.tree.as_ref(), NonZeroUsize::new(k)) else {
            return;
        };
        let found = tree
            .query(&[query.x, query.y, query.z])
            .nearest_n::<SquaredEuclidean<f64>>(k)
            .execute();
        out.extend(found.iter().map(|item| item.item as usize));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_nearest_and_k_nearest() {
        let points: Vec<Vector3<f64>> = (0..100).map(|i| Vector3::new(f64::from(i), 0.0, 0.0)).collect();
        let tree = PointTree::build(&points);
        let (index, distance) = tree.nearest(&Vector3::new(41.2, 0.0, 0.0)).unwrap();
        assert_eq!(index, 41);
        assert!((distance - 0.04).abs() < 1e-9);
        let mut out = Vec::new();
        tree.knn(&Vector3::new(10.1, 0.0, 0.0), 3, &mut out);
        out.sort_unstable();
        assert_eq!(out, vec![9, 10, 11]);
        tree.knn(&Vector3::zeros(), 500, &mut out);
        assert_eq!(out.len(), 100);
    }

    #[test]
    fn empty_tree_finds_nothing() {
        let tree = PointTree::build(&[]);
        assert!(tree.nearest(&Vector3::zeros()).is_none());
        let mut out = vec![1];
        tree.knn(&Vector3::zeros(), 5, &mut out);
        assert!(out.is_empty());
    }
}
