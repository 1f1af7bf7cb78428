//! The LiDAR-Iris image (Wang et al., "LiDAR Iris for Loop-Closure Detection", IROS 2020): a polar
//! rings × columns image whose pixels are 8-bit codes of the height slices that hold points.
//!
//! Definitions, as this plugin implements them:
//! - A point (x, y, z) has horizontal range r = √(x² + y²) and azimuth θ = atan2(y, x) in [0°, 360°).
//! - Row ⌊r / ring_width⌋ for r in [min_range, num_rings · ring_width); other points are dropped.
//! - Column ⌊θ / 360° · N_columns⌋.
//! - Slice ⌊(z − min_height) / slice_height⌋ for z in [min_height, min_height + num_slices · slice_height);
//!   points outside the height span are dropped (the public code clamps them into the end slices, which
//!   marks every tall structure as reaching the top slice).
//! - Pixel code: bit s is set when slice s holds at least one point of the pixel.

use skid_core::{PluginError, PluginResult, Point};

use crate::IrisConfig;

/// An iris image and what was dropped while building it.
#[derive(Clone, Debug, PartialEq)]
pub struct IrisImage {
    /// Row-major codes: `codes[row * num_columns + column]`.
    pub codes: Vec<u8>,
    pub points_used: usize,
    /// Points dropped for their range.
    pub points_out_of_range: usize,
    /// Points in range but outside the height slices.
    pub points_outside_heights: usize,
}

/// Builds the image of `points`; a non-finite point is an error.
pub fn iris_image(points: &[Point], config: &IrisConfig) -> PluginResult<IrisImage> {
    let (rows, columns) = (config.num_rings, config.num_columns);
    let ring_width = config.ring_width_m as f32;
    let max_range = rows as f32 * ring_width;
    let min_range = config.min_range_m as f32;
    let min_height = config.min_height_m as f32;
    let slice_height = config.slice_height_m as f32;
    let column_scale = columns as f32 / std::f32::consts::TAU;
    let mut codes = vec![0u8; rows * columns];
    let (mut used, mut out_of_range, mut outside_heights) = (0usize, 0usize, 0usize);
    for (index, p) in points.iter().enumerate() {
        if !p.is_finite() {
            return Err(PluginError::InvalidInput(format!(
                "point {index} of {} is not finite",
                points.len()
            )));
        }
        let range = (p.x * p.x + p.y * p.y).sqrt();
        if range == 0.0 || range < min_range || range >= max_range {
            out_of_range += 1;
            continue;
        }
        let slice = (p.z - min_height) / slice_height;
        if !(0.0..config.num_slices as f32).contains(&slice) {
            outside_heights += 1;
            continue;
        }
        let row = ((range / ring_width) as usize).min(rows - 1);
        let mut azimuth = p.y.atan2(p.x);
        if azimuth < 0.0 {
            azimuth += std::f32::consts::TAU;
        }
        let column = (azimuth * column_scale) as usize % columns;
        codes[row * columns + column] |= 1u8 << (slice as u32).min(7);
        used += 1;
    }
    Ok(IrisImage {
        codes,
        points_used: used,
        points_out_of_range: out_of_range,
        points_outside_heights: outside_heights,
    })
}

/// The row key: per ring, the fraction of (column, slice) cells that hold points; invariant to yaw.
pub fn row_key(codes: &[u8], num_columns: usize, num_slices: usize) -> Vec<f32> {
    let cells = (num_columns * num_slices.max(1)) as f32;
    codes
        .chunks_exact(num_columns)
        .map(|row| row.iter().map(|c| c.count_ones()).sum::<u32>() as f32 / cells)
        .collect()
}
