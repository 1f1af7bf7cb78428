//! SOLiD extraction (Kim et al., "Narrowing your FOV with SOLiD", RA-L 2024): the two point-count
//! matrices, the implicit elevation vector and the R-SOLiD / A-SOLiD vectors they give.
//!
//! Definitions, as this plugin implements them:
//! - A point (x, y, z) in the sensor frame has horizontal range r = √(x² + y²), azimuth θ = atan2(y, x)
//!   in [0°, 360°) and elevation φ = atan2(z, r).
//! - Range bin ⌊r / max_range · N_r⌋ over [0, max_range] (a point at exactly max_range goes to the last
//!   bin); points with r < min_range or r > max_range are dropped.
//! - Azimuth bin ⌊θ / 360° · N_a⌋.
//! - Elevation bin ⌊(φ − lower_fov) / (upper_fov − lower_fov) · N_e⌋; a point outside
//!   [lower_fov, upper_fov] is dropped and counted as outside the FOV. (The public versions either wrap
//!   such a point into the top bin or clamp it into bin 0; both invent a measurement.)
//! - REC[r][e] and AEC[a][e] count points per (range, elevation) and (azimuth, elevation) bin.
//! - IEV[e] = Σ_r REC[r][e], min-max normalised to [0, 1]. When every elevation bin holds the same count
//!   (including no points at all) min-max normalisation would divide by zero; the IEV is then all ones,
//!   i.e. every elevation bin weighs the same.
//! - R-SOLiD[r] = Σ_e REC[r][e] · IEV[e] (rotation invariant); A-SOLiD[a] = Σ_e AEC[a][e] · IEV[e].

use serde::Serialize;
use skid_core::{PluginError, PluginResult, Point};

use crate::SolidConfig;
use crate::angle::atan2_fast;

/// Everything SOLiD computes for one cloud, for inspection and for comparison with other implementations.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SolidParts {
    /// Range × elevation counts (REC), row-major by range bin.
    pub range_elevation_counts: Vec<u32>,
    /// Azimuth × elevation counts, row-major by azimuth bin.
    pub azimuth_elevation_counts: Vec<u32>,
    /// The implicit elevation vector, min-max normalised.
    pub elevation_weights: Vec<f32>,
    /// R-SOLiD: one value per range bin.
    pub r_solid: Vec<f32>,
    /// A-SOLiD: one value per azimuth bin.
    pub a_solid: Vec<f32>,
    /// Points that entered the descriptor (after voxel downsampling).
    pub points_used: usize,
    /// Points dropped because their range was outside [min_range, max_range].
    pub points_out_of_range: usize,
    /// Points in range but outside the vertical field of view.
    pub points_outside_fov: usize,
}

/// Precomputed scale factors of the three binnings.
#[derive(Clone, Debug)]
pub struct Binning {
    num_range: usize,
    num_azimuth: usize,
    num_elevation: usize,
    min_range_sq: f32,
    max_range_sq: f32,
    range_scale: f32,
    azimuth_scale: f32,
    lower_fov_rad: f32,
    upper_fov_rad: f32,
    elevation_scale: f32,
}

impl Binning {
    /// The binning of a validated config.
    pub fn new(config: &SolidConfig) -> Self {
        let lower = config.lower_fov_deg.to_radians() as f32;
        let upper = config.upper_fov_deg.to_radians() as f32;
        Self {
            num_range: config.num_range_bins,
            num_azimuth: config.num_azimuth_bins,
            num_elevation: config.num_elevation_bins,
            min_range_sq: (config.min_range_m * config.min_range_m) as f32,
            max_range_sq: (config.max_range_m * config.max_range_m) as f32,
            range_scale: (config.num_range_bins as f64 / config.max_range_m) as f32,
            azimuth_scale: (config.num_azimuth_bins as f64 / std::f64::consts::TAU) as f32,
            lower_fov_rad: lower,
            upper_fov_rad: upper,
            elevation_scale: config.num_elevation_bins as f32 / (upper - lower),
        }
    }

    /// Counts the points into REC and the azimuth × elevation matrix and derives the descriptor.
    /// A non-finite point is an error.
    pub fn parts(&self, points: &[Point]) -> PluginResult<SolidParts> {
        if let Some(index) = points.iter().position(|p| !p.is_finite()) {
            return Err(PluginError::InvalidInput(format!(
                "point {index} of {} is not finite",
                points.len()
            )));
        }
        Ok(self.parts_of_finite(points.iter()))
    }

    /// As [`Binning::parts`] for points known to be finite (the voxel downsampling's kept points).
    pub fn parts_of_finite<'a>(&self, points: impl Iterator<Item = &'a Point>) -> SolidParts {
        let (nr, na, ne) = (self.num_range, self.num_azimuth, self.num_elevation);
        let mut rec = vec![0u32; nr * ne];
        let mut aec = vec![0u32; na * ne];
        let (mut used, mut out_of_range, mut outside_fov) = (0usize, 0usize, 0usize);
        for p in points {
            let range_sq = p.x * p.x + p.y * p.y;
            // A point on the z axis (r = 0) has no azimuth; it is out of range for any min_range > 0 and
            // dropped as out of range for min_range = 0 too.
            if range_sq < self.min_range_sq || range_sq > self.max_range_sq || range_sq == 0.0 {
                out_of_range += 1;
                continue;
            }
            let range = range_sq.sqrt();
            let elevation = atan2_fast(p.z, range);
            if elevation < self.lower_fov_rad || elevation > self.upper_fov_rad {
                outside_fov += 1;
                continue;
            }
            let e = (((elevation - self.lower_fov_rad) * self.elevation_scale) as usize).min(ne - 1);
            let r = ((range * self.range_scale) as usize).min(nr - 1);
            let mut azimuth = atan2_fast(p.y, p.x);
            if azimuth < 0.0 {
                azimuth += std::f32::consts::TAU;
            }
            // An azimuth a hair below 0 rounds to 2π after the shift: that is azimuth 0, bin 0.
            let a = (azimuth * self.azimuth_scale) as usize % na;
            rec[r * ne + e] += 1;
            aec[a * ne + e] += 1;
            used += 1;
        }
        let weights = elevation_weights(&rec, ne);
        let weigh = |counts: &[u32], rows: usize| -> Vec<f32> {
            (0..rows)
                .map(|row| {
                    let cells = &counts[row * ne..(row + 1) * ne];
                    cells.iter().zip(&weights).map(|(&c, &w)| c as f32 * w).sum()
                })
                .collect()
        };
        SolidParts {
            r_solid: weigh(&rec, nr),
            a_solid: weigh(&aec, na),
            range_elevation_counts: rec,
            azimuth_elevation_counts: aec,
            elevation_weights: weights,
            points_used: used,
            points_out_of_range: out_of_range,
            points_outside_fov: outside_fov,
        }
    }
}

/// The implicit elevation vector: points per elevation bin, min-max normalised; all ones when every bin
/// holds the same count (the normalisation's division by zero).
fn elevation_weights(rec: &[u32], num_elevation: usize) -> Vec<f32> {
    let mut sums = vec![0u64; num_elevation];
    for row in rec.chunks_exact(num_elevation) {
        for (sum, &count) in sums.iter_mut().zip(row) {
            *sum += u64::from(count);
        }
    }
    let min = sums.iter().copied().min().unwrap_or(0);
    let max = sums.iter().copied().max().unwrap_or(0);
    if max == min {
        return vec![1.0; num_elevation];
    }
    let span = (max - min) as f64;
    sums.iter().map(|&s| ((s - min) as f64 / span) as f32).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equal_elevation_counts_weigh_the_same() {
        assert_eq!(elevation_weights(&[2, 2, 0, 0], 2), vec![1.0, 1.0]);
        assert_eq!(elevation_weights(&[0, 0, 0, 0], 2), vec![1.0, 1.0]);
        assert_eq!(elevation_weights(&[1, 3, 0, 1], 2), vec![0.0, 1.0]);
    }
}
