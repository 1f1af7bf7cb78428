//! Voxel-grid downsampling, two ways: [`voxel_downsample`] keeps the first point falling into each voxel
//! (as KISS-ICP does), so the output is a subset of real measurements; [`voxel_centroids`] keeps each
//! voxel's centroid (as KISS-Matcher's sampling does), which averages the range noise out of the
//! positions that normals and features are computed from. Both are deterministic, in the order voxels
//! are first met.

use std::collections::HashMap;

use skid_core::Point;

/// Integer voxel coordinates of a point for a grid of `voxel_size_m`.
pub fn voxel_key(point: &Point, voxel_size_m: f32) -> [i32; 3] {
    [
        (point.x / voxel_size_m).floor() as i32,
        (point.y / voxel_size_m).floor() as i32,
        (point.z / voxel_size_m).floor() as i32,
    ]
}

/// Keeps the first point of every occupied voxel, in input order. Non-finite points are dropped.
/// A non-positive or non-finite voxel size returns the finite points unchanged.
pub fn voxel_downsample(points: &[Point], voxel_size_m: f32) -> Vec<Point> {
    let finite = points.iter().filter(|p| p.is_finite());
    if !(voxel_size_m.is_finite() && voxel_size_m > 0.0) {
        return finite.copied().collect();
    }
    let mut seen: HashMap<[i32; 3], ()> = HashMap::with_capacity(points.len() / 4);
    finite
        .filter(|p| seen.insert(voxel_key(p, voxel_size_m), ()).is_none())
        .copied()
        .collect()
}

/// The centroid of the finite points in every occupied voxel (intensity averaged too), one point per
/// voxel in the order voxels are first met. A non-positive or non-finite voxel size returns the finite
/// points unchanged.
pub fn voxel_centroids(points: &[Point], voxel_size_m: f32) -> Vec<Point> {
    let finite = points.iter().filter(|p| p.is_finite());
    if !(voxel_size_m.is_finite() && voxel_size_m > 0.0) {
        return finite.copied().collect();
    }
    let mut slot_of: HashMap<[i32; 3], usize> = HashMap::with_capacity(points.len() / 4);
    // Per voxel: sums of x, y, z and intensity in f64, and the count.
    let mut sums: Vec<([f64; 4], u32)> = Vec::with_capacity(points.len() / 4);
    for p in finite {
        let slot = *slot_of.entry(voxel_key(p, voxel_size_m)).or_insert_with(|| {
            sums.push(([0.0; 4], 0));
            sums.len() - 1
        });
        let (sum, count) = &mut sums[slot];
        for (s, v) in sum.iter_mut().zip([p.x, p.y, p.z, p.intensity]) {
            *s += f64::from(v);
        }
        *count += 1;
    }
    sums.iter()
        .map(|(sum, count)| {
            let n = f64::from(*count);
            Point::with_intensity(
                (sum[0] / n) as f32,
                (sum[1] / n) as f32,
                (sum[2] / n) as f32,
                (sum[3] / n) as f32,
            )
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn centroids_average_each_voxel_in_order_of_first_appearance() {
        let points = vec![
            Point::with_intensity(0.1, 0.1, 0.1, 1.0),
            Point::with_intensity(1.5, 0.1, 0.1, 5.0),
            Point::with_intensity(0.3, 0.5, 0.9, 3.0),
            Point::new(f32::NAN, 0.0, 0.0),
            Point::with_intensity(-0.5, 0.1, 0.1, 2.0),
        ];
        let kept = voxel_centroids(&points, 1.0);
        assert_eq!(kept.len(), 3);
        assert_eq!(kept[0], Point::with_intensity(0.2, 0.3, 0.5, 2.0));
        assert_eq!(kept[1], points[1]);
        assert_eq!(kept[2], points[4]);
        assert_eq!(voxel_centroids(&points, 0.0).len(), 4);
    }

    #[test]
    fn keeps_one_point_per_voxel_in_order() {
        let points = vec![
            Point::new(0.1, 0.1, 0.1),
            Point::new(0.2, 0.2, 0.2),
            Point::new(1.5, 0.1, 0.1),
            Point::new(-0.1, 0.1, 0.1),
            Point::new(f32::NAN, 0.0, 0.0),
        ];
        let kept = voxel_downsample(&points, 1.0);
        assert_eq!(kept, vec![points[0], points[2], points[3]]);
    }

    #[test]
    fn bad_voxel_size_keeps_finite_points() {
        let points = vec![
            Point::new(0.1, 0.1, 0.1),
            Point::new(0.2, 0.2, 0.2),
            Point::new(f32::INFINITY, 0.0, 0.0),
        ];
        assert_eq!(voxel_downsample(&points, 0.0).len(), 2);
        assert_eq!(voxel_downsample(&points, f32::NAN).len(), 2);
    }

    #[test]
    fn output_has_at_most_one_point_per_voxel() {
        let points: Vec<Point> = (0..1000)
            .map(|i| {
                let t = i as f32 * 0.37;
                Point::new(t.sin() * 10.0, t.cos() * 10.0, (t * 0.1).sin())
            })
            .collect();
        let kept = voxel_downsample(&points, 0.5);
        let mut keys: Vec<_> = kept.iter().map(|p| voxel_key(p, 0.5)).collect();
        let before = keys.len();
        keys.sort();
        keys.dedup();
        assert_eq!(keys.len(), before);
        assert!(kept.len() < points.len());
    }
}
