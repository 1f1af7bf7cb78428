//! The settings of the FPFH front that KISS-Matcher and the RANSAC baseline share (voxel sampling,
//! normals and FPFH descriptors, descriptor matching), checked and turned into the stages' parameters in
//! one place, so both plugins read and refuse them alike.

use crate::features::FeatureParams;
use crate::matching::MatchParams;

/// The front's settings, in the units of the plugins' configuration.
#[derive(Clone, Copy, Debug)]
pub struct FrontSettings {
    pub voxel_size_m: f64,
    /// Normal search radius over the voxel size.
    pub normal_radius_gain: f64,
    /// FPFH search radius over the voxel size.
    pub fpfh_radius_gain: f64,
    pub min_normal_neighbours: usize,
    pub linearity_threshold: f64,
    pub mutual_filter: bool,
    pub ratio_test: f64,
    /// Largest squared descriptor distance of a match; 0 sets no limit.
    pub max_feature_squared_distance: f64,
    /// Matches kept at most; 0 keeps every one.
    pub max_correspondences: usize,
}

impl FrontSettings {
    /// Checks every value; the message names the offending key.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.voxel_size_m.is_finite() && self.voxel_size_m >= 5e-3) {
            return Err(format!(
                "voxel_size_m must be at least 0.005, got {}",
                self.voxel_size_m
            ));
        }
        for (value, key) in [
            (self.normal_radius_gain, "normal_radius_gain"),
            (self.fpfh_radius_gain, "fpfh_radius_gain"),
            (self.ratio_test, "ratio_test"),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(format!("{key} must be a positive number, got {value}"));
            }
        }
        if self.normal_radius_gain > self.fpfh_radius_gain {
            return Err(
                "normal_radius_gain must not exceed fpfh_radius_gain (one search serves both)".into(),
            );
        }
        if !(0.0..=1.0).contains(&self.linearity_threshold) {
            return Err(format!(
                "linearity_threshold must lie in [0, 1], got {}",
                self.linearity_threshold
            ));
        }
        if !(self.max_feature_squared_distance.is_finite() && self.max_feature_squared_distance >= 0.0) {
            return Err(format!(
                "max_feature_squared_distance must be 0 (no limit) or positive, got {}",
                self.max_feature_squared_distance
            ));
        }
        if self.min_normal_neighbours == 0 {
            return Err("min_normal_neighbours must be at least 1".into());
        }
        Ok(())
    }

    /// The feature-extraction settings in metres.
    pub fn feature_params(&self) -> FeatureParams {
        FeatureParams {
            normal_radius_m: (self.normal_radius_gain * self.voxel_size_m) as f32,
            fpfh_radius_m: (self.fpfh_radius_gain * self.voxel_size_m) as f32,
            min_neighbours: self.min_normal_neighbours,
            linearity_threshold: self.linearity_threshold as f32,
        }
    }

    /// The matching settings.
    pub fn match_params(&self) -> MatchParams {
        let max_squared_distance = if self.max_feature_squared_distance > 0.0 {
            self.max_feature_squared_distance as f32
        } else {
            f32::INFINITY
        };
        MatchParams {
            mutual: self.mutual_filter,
            ratio: self.ratio_test as f32,
            max_squared_distance,
            max_correspondences: self.max_correspondences,
        }
    }
}
