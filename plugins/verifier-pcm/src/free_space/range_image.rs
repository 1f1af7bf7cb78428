//! The free-space check's geometry: a scan's nearest return per direction (its range image) and the
//! clusters its violations form.

use std::collections::HashMap;

use nalgebra::Point3;
use skid_core::Point;

/// The nearest return per pixel of the sphere around a scan's sensor.
pub(super) struct RangeImage {
    pixel_rad: f64,
    columns: usize,
    rows: usize,
    min_range_m: f64,
    /// Nearest range per pixel, row-major; infinity where the scan holds no return.
    nearest_m: Vec<f32>,
}

/// A pixel of a [`RangeImage`]: its column (azimuth) and row (elevation).
#[derive(Clone, Copy, Debug)]
pub(super) struct Pixel {
    column: usize,
    row: usize,
}

impl RangeImage {
    /// The image of `points` (finite, in their sensor's frame), pixels `pixel_deg` on a side, leaving
    /// out the points within `min_range_m` of the sensor.
    pub(super) fn new(points: &[Point], pixel_deg: f64, min_range_m: f64) -> Self {
        let pixel_rad = pixel_deg.to_radians();
        let columns = (std::f64::consts::TAU / pixel_rad).ceil() as usize;
        let rows = (std::f64::consts::PI / pixel_rad).ceil() as usize + 1;
        let mut image = Self {
            pixel_rad,
            columns,
            rows,
            min_range_m,
            nearest_m: vec![f32::INFINITY; columns * rows],
        };
        for point in points {
            let at = Point3::new(f64::from(point.x), f64::from(point.y), f64::from(point.z));
            if let Some((pixel, range_m)) = image.pixel_of(&at) {
                let nearest = &mut image.nearest_m[pixel.row * columns + pixel.column];
                *nearest = nearest.min(range_m as f32);
            }
        }
        image
    }

    /// The pixel of a point's direction (in the image's sensor frame) and the point's range; `None` for
    /// points within the image's minimum range of the sensor, or not finite.
    pub(super) fn pixel_of(&self, at: &Point3<f64>) -> Option<(Pixel, f64)> {
        let range_m = at.coords.norm();
        if !range_m.is_finite() || range_m < self.min_range_m.max(f64::EPSILON) {
            return None;
        }
        let azimuth = at.y.atan2(at.x) + std::f64::consts::PI;
        let elevation = (at.z / range_m).clamp(-1.0, 1.0).asin() + std::f64::consts::FRAC_PI_2;
        let pixel = Pixel {
            column: ((azimuth / self.pixel_rad) as usize).min(self.columns - 1),
            row: ((elevation / self.pixel_rad) as usize).min(self.rows - 1),
        };
        Some((pixel, range_m))
    }

    /// The nearest and the farthest return around a pixel, when the scan's rays surround it: in the
    /// pixel's column and in the columns on either side (azimuth wraps around), the nearest ray at or
    /// above the pixel and the nearest at or below, each within `reach` rows (a sensor's beams may be
    /// spaced wider than a pixel). A direction the rays do not surround lies on the silhouette of what
    /// the scan saw (an object's top edge, the edge of its field of view), where rays that passed just
    /// beside the object say nothing about it.
    pub(super) fn around(&self, pixel: Pixel, reach: usize) -> Option<Around> {
        let (mut nearest, mut farthest) = (f32::INFINITY, 0.0_f32);
        for step in [self.columns - 1, 0, 1] {
            let column = (pixel.column + step) % self.columns;
            let at = |row: usize| self.nearest_m[row * self.columns + column];
            let highest = (pixel.row + reach).min(self.rows - 1);
            let above = (pixel.row..=highest).map(at).find(|range| range.is_finite())?;
            let lowest = pixel.row.saturating_sub(reach);
            let below = (lowest..=pixel.row)
                .rev()
                .map(at)
                .find(|range| range.is_finite())?;
            nearest = nearest.min(above).min(below);
            farthest = farthest.max(above).max(below);
        }
        Some(Around {
            nearest_m: f64::from(nearest),
            farthest_m: f64::from(farthest),
        })
    }
}

/// The returns that surround a direction.
#[derive(Clone, Copy, Debug)]
pub(super) struct Around {
    pub nearest_m: f64,
    pub farthest_m: f64,
}

/// How many of `points` have at least `neighbours` others within `radius_m` (found through a hash grid
/// of `radius_m` cells).
pub(super) fn clustered(points: &[Point3<f64>], radius_m: f64, neighbours: usize) -> usize {
    if neighbours == 0 {
        return points.len();
    }
    let cell = |p: &Point3<f64>| {
        [
            (p.x / radius_m).floor() as i64,
            (p.y / radius_m).floor() as i64,
            (p.z / radius_m).floor() as i64,
        ]
    };
    let mut grid: HashMap<[i64; 3], Vec<usize>> = HashMap::new();
    for (index, p) in points.iter().enumerate() {
        grid.entry(cell(p)).or_default().push(index);
    }
    let radius_m2 = radius_m * radius_m;
    let neighbours_of = |index: usize, p: &Point3<f64>| {
        let [x, y, z] = cell(p);
        let mut found = 0;
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let others = grid.get(&[x + dx, y + dy, z + dz]).into_iter().flatten();
                    found += others
                        .filter(|&&other| other != index && (points[other] - p).norm_squared() <= radius_m2)
                        .count();
                }
            }
        }
        found
    };
    points
        .iter()
        .enumerate()
        .filter(|(index, p)| neighbours_of(*index, p) >= neighbours)
        .count()
}
