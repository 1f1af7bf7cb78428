//! The FPFH front that KISS-Matcher and the RANSAC baseline share (normals and FPFH descriptors,
//! descriptor matching): one configuration table, `[coarse.<plugin>.fpfh]`, checked and turned into the
//! stages' parameters in one place, so both plugins read and refuse it alike. The two plugins differ
//! only in the matching defaults (KISS-Matcher's reference caps and ratio test; the classic baseline's
//! plain mutual matching), which [`FrontDefaults`] supplies, so a table that sets a few keys keeps its
//! own plugin's defaults for the rest.

use std::marker::PhantomData;

use serde::{Deserialize, Serialize};
use skid_core::ParamError;

use crate::features::FeatureParams;
use crate::matching::MatchParams;

/// The matching defaults that differ between the plugins sharing the front.
pub trait FrontDefaults {
    /// Ratio test on squared descriptor distances; 1.0 disables it.
    const RATIO_TEST: f64;
    /// Largest squared descriptor distance of a match; 0 sets no limit.
    const MAX_FEATURE_SQUARED_DISTANCE: f64;
    /// Matches kept at most; 0 keeps every one.
    const MAX_CORRESPONDENCES: usize;
}

/// KISS-Matcher's reference values: squared-distance cap 900, ratio test 0.9, at most 5,000 matches.
#[derive(Clone, Copy, Debug, PartialEq, schemars::JsonSchema)]
pub struct KissMatcherDefaults;

impl FrontDefaults for KissMatcherDefaults {
    const RATIO_TEST: f64 = 0.9;
    const MAX_FEATURE_SQUARED_DISTANCE: f64 = 900.0;
    const MAX_CORRESPONDENCES: usize = 5000;
}

/// The classic baseline's: mutual nearest neighbours without a ratio test or cap (as Open3D's).
#[derive(Clone, Copy, Debug, PartialEq, schemars::JsonSchema)]
pub struct BaselineDefaults;

impl FrontDefaults for BaselineDefaults {
    const RATIO_TEST: f64 = 1.0;
    const MAX_FEATURE_SQUARED_DISTANCE: f64 = 0.0;
    const MAX_CORRESPONDENCES: usize = 0;
}

/// The front's settings; the radii are multiples of the plugin's voxel size.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields, bound = "D: FrontDefaults")]
#[schemars(bound = "D: FrontDefaults + schemars::JsonSchema")]
pub struct FpfhConfig<D> {
    /// Normal radius as a multiple of the voxel size.
    pub normal_radius_gain: f64,
    /// FPFH radius as a multiple of the voxel size.
    pub fpfh_radius_gain: f64,
    /// Fewest points for a normal, and fewest valid-normal neighbours for a keypoint (both including
    /// the point itself).
    pub min_normal_neighbours: usize,
    /// Neighbourhoods with linearity (λ1 − λ2)/λ1 above this get no normal; 1.0 disables the filter.
    pub linearity_threshold: f64,
    /// Keep only mutual nearest neighbours in descriptor space.
    pub mutual_filter: bool,
    /// Ratio test on squared descriptor distances (nearest / second nearest); 1.0 disables it.
    pub ratio_test: f64,
    /// Largest squared descriptor distance of a match; 0 sets no limit.
    pub max_feature_squared_distance: f64,
    /// Matches kept at most (the most distinctive first); 0 keeps every one.
    pub max_correspondences: usize,
    /// Whose defaults fill the keys a table leaves out; it holds no value (public so that a config can
    /// be written with `..FpfhConfig::default()`).
    #[serde(skip)]
    #[schemars(skip)]
    pub defaults: PhantomData<fn() -> D>,
}

impl<D: FrontDefaults> Default for FpfhConfig<D> {
    fn default() -> Self {
        Self {
            normal_radius_gain: 3.0,
            fpfh_radius_gain: 5.0,
            min_normal_neighbours: 3,
            linearity_threshold: 1.0,
            mutual_filter: true,
            ratio_test: D::RATIO_TEST,
            max_feature_squared_distance: D::MAX_FEATURE_SQUARED_DISTANCE,
            max_correspondences: D::MAX_CORRESPONDENCES,
            defaults: PhantomData,
        }
    }
}

/// Refuses a voxel size below 5 mm (or not a number), as an error at `voxel_size_m`.
pub fn check_voxel_size(voxel_size_m: f64) -> Result<(), ParamError> {
    if voxel_size_m.is_finite() && voxel_size_m >= 5e-3 {
        Ok(())
    } else {
        Err(ParamError::at(
            "voxel_size_m",
            format!("must be at least 0.005, got {voxel_size_m}"),
        ))
    }
}

impl<D> FpfhConfig<D> {
    /// Checks every value; the error's path is the key within this table (the caller places the table).
    pub fn validate(&self) -> Result<(), ParamError> {
        for (value, key) in [
            (self.normal_radius_gain, "normal_radius_gain"),
            (self.fpfh_radius_gain, "fpfh_radius_gain"),
            (self.ratio_test, "ratio_test"),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(ParamError::at(
                    key,
                    format!("must be a positive number, got {value}"),
                ));
            }
        }
        if self.normal_radius_gain > self.fpfh_radius_gain {
            return Err(ParamError::at(
                "normal_radius_gain",
                "must not exceed fpfh_radius_gain (one search serves both)",
            ));
        }
        if !(0.0..=1.0).contains(&self.linearity_threshold) {
            return Err(ParamError::at(
                "linearity_threshold",
                format!("must lie in [0, 1], got {}", self.linearity_threshold),
            ));
        }
        if !(self.max_feature_squared_distance.is_finite() && self.max_feature_squared_distance >= 0.0) {
            return Err(ParamError::at(
                "max_feature_squared_distance",
                format!(
                    "must be 0 (no limit) or positive, got {}",
                    self.max_feature_squared_distance
                ),
            ));
        }
        if self.min_normal_neighbours == 0 {
            return Err(ParamError::at("min_normal_neighbours", "must be at least 1"));
        }
        Ok(())
    }

    /// The feature-extraction settings in metres, for voxels of `voxel_size_m`.
    pub fn feature_params(&self, voxel_size_m: f64) -> FeatureParams {
        FeatureParams {
            normal_radius_m: (self.normal_radius_gain * voxel_size_m) as f32,
            fpfh_radius_m: (self.fpfh_radius_gain * voxel_size_m) as f32,
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
