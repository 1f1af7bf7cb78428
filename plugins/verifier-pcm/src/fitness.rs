//! The first verification stage of SKiD-SLAM (Kim et al., "SKiD-SLAM", §IV-D, truncated MSE): after
//! fine registration, judge each loop on how well the two clouds overlap where they overlap.
//!
//! ## Definition
//!
//! Let `P_s` be the finite source points (voxel-downsampled at `source_voxel_m` when positive), `T` the
//! loop's `target_from_source`, and `d_i` the distance from `T p_i` to its nearest finite target
//! point. With the truncation distance `τ = max_correspondence_m`, the inliers are
//! `I = { i : d_i ≤ τ }` and
//!
//! * the **truncated MSE** is `s = (1/|I|) Σ_{i∈I} d_i²` (square metres), and
//! * the **overlap** is `o = |I| / |P_s|`.
//!
//! The defaults (`τ` = 1 m, `s` ≤ 0.25 m², i.e. an RMS of half the truncation distance, overlap ≥ 0.3)
//! make this a gate against registrations that diverged or matched unrelated places; how tight `s` can
//! be depends on the point density (two independent samplings of a surface at 0.7 m spacing already
//! give `s` ≈ 0.2 m²), and the consistency stage is the main outlier filter.
//!
//! A loop passes when `|I| ≥ min_inliers`, `s ≤ max_truncated_mse_m2` and `o ≥ min_overlap`. Points
//! outside the overlap (the part of a reverse or partial revisit the other scan never saw) do not enter
//! `s`, so a correct partial overlap is not penalised for its size, only for its quality; `o` guards
//! against judging a loop on a handful of accidental matches. Note that `s` compares squared distances
//! with the squared bound `τ²`, unlike PCL's fitness score, which mixes the two.

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use nalgebra::Point3;
use serde::{Deserialize, Serialize};
use skid_core::{ParamError, Point, Pose};
use skid_geometry::voxel_downsample;

/// Parameters of the truncated-MSE check.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct FitnessConfig {
    /// Run the check (off: every loop goes straight to the consistency stage).
    pub enabled: bool,
    /// Truncation distance τ of the nearest-neighbour pairs, in metres.
    pub max_correspondence_m: f64,
    /// Largest truncated MSE accepted, in square metres.
    pub max_truncated_mse_m2: f64,
    /// Smallest overlap fraction accepted, in [0, 1].
    pub min_overlap: f64,
    /// Fewest inlier pairs accepted.
    pub min_inliers: usize,
    /// Voxel size for thinning the source cloud before the check, in metres; 0 keeps every point.
    pub source_voxel_m: f64,
}

impl Default for FitnessConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            max_correspondence_m: 1.0,
            max_truncated_mse_m2: 0.25,
            min_overlap: 0.3,
            min_inliers: 30,
            source_voxel_m: 0.5,
        }
    }
}

/// The measured fitness of one loop.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fitness {
    pub truncated_mse_m2: f64,
    pub overlap: f64,
    pub inliers: usize,
    pub source_points: usize,
}

impl FitnessConfig {
    /// Checks that every value is usable; the error is at the offending key.
    pub fn validate(&self) -> Result<(), ParamError> {
        let positive = |v: f64| v.is_finite() && v > 0.0;
        for (value, key) in [
            (self.max_correspondence_m, "max_correspondence_m"),
            (self.max_truncated_mse_m2, "max_truncated_mse_m2"),
        ] {
            if !positive(value) {
                return Err(ParamError::at(key, format!("must be positive, got {value}")));
            }
        }
        if !(0.0..=1.0).contains(&self.min_overlap) {
            return Err(ParamError::at(
                "min_overlap",
                format!("must lie in [0, 1], got {}", self.min_overlap),
            ));
        }
        if !(self.source_voxel_m.is_finite() && self.source_voxel_m >= 0.0) {
            return Err(ParamError::at(
                "source_voxel_m",
                format!("must be finite and not negative, got {}", self.source_voxel_m),
            ));
        }
        Ok(())
    }

    /// Measures the fitness of `target_from_source` between two clouds; an error explains clouds that
    /// cannot be judged (no finite points).
    pub fn measure(
        &self,
        target: &[Point],
        source: &[Point],
        target_from_source: &Pose,
    ) -> Result<Fitness, String> {
        let target_points: Vec<[f32; 3]> = target
            .iter()
            .filter(|p| p.is_finite())
            .map(|p| [p.x, p.y, p.z])
            .collect();
        let finite_source: Vec<Point> = source.iter().filter(|p| p.is_finite()).copied().collect();
        let source_points = if self.source_voxel_m > 0.0 {
            voxel_downsample(&finite_source, self.source_voxel_m as f32)
        } else {
            finite_source
        };
        if target_points.is_empty() || source_points.is_empty() {
            return Err(format!(
                "no finite points to judge the loop ({} target, {} source)",
                target_points.len(),
                source_points.len()
            ));
        }
        let tree = ImmutableKdTree::<f32, 3>::new_from_slice(&target_points)
            .map_err(|e| format!("building the kd-tree: {e:?}"))?;
        let bound_m2 = self.max_correspondence_m * self.max_correspondence_m;
        let (mut inliers, mut sum_m2) = (0usize, 0.0f64);
        for p in &source_points {
            let q = target_from_source * Point3::new(f64::from(p.x), f64::from(p.y), f64::from(p.z));
            let query = [q.x as f32, q.y as f32, q.z as f32];
            let found = tree
                .query(&query)
                .nearest_one::<SquaredEuclidean<f32>>()
                .execute();
            let d2 = f64::from(found.distance);
            if d2.is_finite() && d2 <= bound_m2 {
                inliers += 1;
                sum_m2 += d2;
            }
        }
        Ok(Fitness {
            truncated_mse_m2: if inliers > 0 {
                sum_m2 / inliers as f64
            } else {
                f64::INFINITY
            },
            overlap: inliers as f64 / source_points.len() as f64,
            inliers,
            source_points: source_points.len(),
        })
    }

    /// `None` when `fitness` passes, else the reason it fails (always beginning `truncated MSE`, which is
    /// how the host tells this check's refusals from the others).
    pub fn judge(&self, fitness: &Fitness) -> Option<String> {
        if fitness.inliers < self.min_inliers {
            return Some(format!(
                "truncated MSE: {} inlier pairs < {}",
                fitness.inliers, self.min_inliers
            ));
        }
        if fitness.truncated_mse_m2 > self.max_truncated_mse_m2 {
            return Some(format!(
                "truncated MSE {:.4} m² > {:.4} m² (overlap {:.2})",
                fitness.truncated_mse_m2, self.max_truncated_mse_m2, fitness.overlap
            ));
        }
        if fitness.overlap < self.min_overlap {
            return Some(format!(
                "truncated MSE: overlap {:.3} < {:.3} (truncated MSE {:.4} m²)",
                fitness.overlap, self.min_overlap, fitness.truncated_mse_m2
            ));
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_refusal_names_the_check() {
        let config = FitnessConfig::default();
        let cases = [
            (0.01, 0.9, 10),  // too few pairs
            (0.40, 0.9, 500), // a poor fit
            (0.01, 0.1, 500), // too little overlap
        ];
        for (truncated_mse_m2, overlap, inliers) in cases {
            let fitness = Fitness {
                truncated_mse_m2,
                overlap,
                inliers,
                source_points: 1000,
            };
            let reason = config.judge(&fitness).expect("refused");
            assert!(reason.starts_with("truncated MSE"), "{reason}");
        }
        let good = Fitness {
            truncated_mse_m2: 0.01,
            overlap: 0.9,
            inliers: 500,
            source_points: 1000,
        };
        assert_eq!(config.judge(&good), None);
    }
}
