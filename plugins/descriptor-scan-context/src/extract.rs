//! Scan Context extraction (Kim & Kim, "Scan Context: Egocentric Spatial Descriptor for Place Recognition
//! within 3D Point Cloud Map", IROS 2018): a rings × sectors polar grid holding the highest point of
//! each cell.
//!
//! Definitions, as this plugin implements them:
//! - A point (x, y, z) has horizontal range r = √(x² + y²) and azimuth θ = atan2(y, x) in [0°, 360°).
//! - Ring ⌊r / max_range · N_rings⌋, sector ⌊θ / 360° · N_sectors⌋. A point at exactly max_range is in
//!   the last ring. A point beyond max_range is dropped, or put in the last ring when
//!   `clamp_beyond_max_range` is set (the two choices of the public versions). Points with r below
//!   `min_range_m` (and any point on the z axis) are dropped.
//! - Cell value: the largest z + sensor_height of its points; 0 for an empty cell. A cell whose points are
//!   all lower than −sensor_height has a negative maximum: it is raised to 0 (the default, so every value
//!   is ≥ 0 and column cosine similarities lie in [0, 1]) or kept negative with `keep_negative_heights`.

use skid_core::{PluginError, PluginResult, Point};

use crate::ScanContextConfig;

/// A scan context and what was dropped while building it.
#[derive(Clone, Debug, PartialEq)]
pub struct ScanContextGrid {
    /// Row-major by ring: `values[ring * num_sectors + sector]`.
    pub values: Vec<f32>,
    /// Points that entered a cell.
    pub points_used: usize,
    /// Points dropped for their range.
    pub points_out_of_range: usize,
}

/// Builds the scan context of `points`; a non-finite point is an error.
pub fn scan_context(points: &[Point], config: &ScanContextConfig) -> PluginResult<ScanContextGrid> {
    let (rings, sectors) = (config.num_rings, config.num_sectors);
    let height = config.sensor_height_m as f32;
    let max_range = config.max_range_m as f32;
    let min_range_sq = (config.min_range_m * config.min_range_m) as f32;
    let ring_scale = rings as f32 / max_range;
    let sector_scale = sectors as f32 / std::f32::consts::TAU;
    // The highest value per cell; NaN marks an empty cell until the end.
    let mut cells = vec![f32::NAN; rings * sectors];
    let (mut used, mut out_of_range) = (0usize, 0usize);
    for (index, p) in points.iter().enumerate() {
        if !p.is_finite() {
            return Err(PluginError::InvalidInput(format!(
                "point {index} of {} is not finite",
                points.len()
            )));
        }
        let range_sq = p.x * p.x + p.y * p.y;
        let range = range_sq.sqrt();
        if range_sq == 0.0 || range_sq < min_range_sq || (range > max_range && !config.clamp_beyond_max_range)
        {
            out_of_range += 1;
            continue;
        }
        let ring = ((range * ring_scale) as usize).min(rings - 1);
        let mut azimuth = p.y.atan2(p.x);
        if azimuth < 0.0 {
            azimuth += std::f32::consts::TAU;
        }
        let sector = (azimuth * sector_scale) as usize % sectors;
        let cell = &mut cells[ring * sectors + sector];
        let value = p.z + height;
        // `f32::max` takes the number when the other side is NaN, so the first point fills an empty cell.
        *cell = cell.max(value);
        used += 1;
    }
    let values = cells
        .into_iter()
        .map(|v| {
            if v.is_nan() {
                0.0
            } else if config.keep_negative_heights {
                v
            } else {
                v.max(0.0)
            }
        })
        .collect();
    Ok(ScanContextGrid {
        values,
        points_used: used,
        points_out_of_range: out_of_range,
    })
}

/// Row means: one value per ring, invariant to yaw.
pub fn ring_key(values: &[f32], num_sectors: usize) -> Vec<f32> {
    values
        .chunks_exact(num_sectors)
        .map(|row| row.iter().sum::<f32>() / num_sectors as f32)
        .collect()
}

/// Column means: one value per sector, shifted by a yaw.
pub fn sector_key(values: &[f32], num_sectors: usize) -> Vec<f32> {
    let rings = values.len() / num_sectors;
    let mut key = vec![0.0f32; num_sectors];
    for row in values.chunks_exact(num_sectors) {
        for (k, &v) in key.iter_mut().zip(row) {
            *k += v;
        }
    }
    let scale = if rings > 0 { 1.0 / rings as f32 } else { 0.0 };
    key.iter_mut().for_each(|k| *k *= scale);
    key
}
