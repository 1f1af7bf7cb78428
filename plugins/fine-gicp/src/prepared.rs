//! What `prepare` computes for one cloud and caches in `PreparedCloud::cache`: the downsampled points, the
//! kd-tree, per-point covariances and normals, the Gaussian voxel map (VGICP), the cloud's principal
//! extents, the same (without a voxel map) for the coarse level of the coarse-to-fine schedule, and how
//! long each stage took.

use std::sync::Arc;
use std::time::Instant;

use nalgebra::{Matrix3, Vector3};
use serde::Serialize;
use skid_core::slots::PreparedCloud;
use skid_core::{Cloud, CloudView, PluginError, PluginResult, Point};

use crate::PLUGIN_NAME;
use crate::config::{GicpConfig, PreparationKey, Variant};
use crate::features::{self, LocalFeatures};
use crate::tree::PointTree;
use crate::voxel;
use crate::voxelmap::GaussianVoxelMap;

/// Wall-clock time of each preparation stage, in milliseconds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct PrepareTimings {
    pub downsample_ms: f64,
    pub tree_ms: f64,
    /// Covariances or normals (zero for point-to-point ICP).
    pub covariance_ms: f64,
    /// The Gaussian voxel map (VGICP only).
    pub voxel_map_ms: f64,
    /// The coarse level: downsampling, tree and covariances (zero without one).
    pub coarse_ms: f64,
    pub total_ms: f64,
}

/// The plugin-private part of a prepared cloud.
pub struct PreparedData {
    pub(crate) key: PreparationKey,
    pub(crate) points: Vec<Vector3<f64>>,
    pub(crate) tree: PointTree,
    /// Regularised covariances (GICP, VGICP, plane ICP); empty for point-to-point ICP.
    pub(crate) covariances: Vec<Matrix3<f64>>,
    /// Normals (zero where the neighbourhood was too small); empty for point-to-point ICP.
    pub(crate) normals: Vec<Vector3<f64>>,
    pub(crate) voxel_map: Option<GaussianVoxelMap>,
    /// Standard deviations along the principal axes, ascending.
    pub(crate) extents: [f64; 3],
    /// The coarse level (the points downsampled again, with their own tree and covariances but no voxel
    /// map), when the configuration asks for one.
    pub(crate) coarse: Option<Box<PreparedData>>,
    pub(crate) timings: PrepareTimings,
}

impl PreparedData {
    /// Number of points after downsampling.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Standard deviations of the points along their principal axes, ascending, in metres.
    pub fn principal_extents_m(&self) -> [f64; 3] {
        self.extents
    }

    /// How long each preparation stage took.
    pub fn timings(&self) -> PrepareTimings {
        self.timings
    }

    /// Number of points of the coarse level, if there is one.
    pub fn coarse_len(&self) -> Option<usize> {
        self.coarse.as_ref().map(|level| level.len())
    }

    /// Number of Gaussian voxels (VGICP), else 0.
    pub fn voxel_count(&self) -> usize {
        self.voxel_map.as_ref().map_or(0, GaussianVoxelMap::len)
    }
}

fn elapsed_ms(start: Instant) -> f64 {
    start.elapsed().as_secs_f64() * 1e3
}

/// Prepares `cloud` for `config` on the current rayon pool. Non-finite points are an error; tiny or
/// degenerate clouds are prepared anyway and reported by `refine`.
pub(crate) fn prepare(config: &GicpConfig, cloud: CloudView<'_>) -> PluginResult<PreparedCloud> {
    cloud.ensure_usable("cloud to prepare", 0)?;
    let start = Instant::now();
    let raw = cloud
        .points()
        .iter()
        .map(|p| Vector3::new(f64::from(p.x), f64::from(p.y), f64::from(p.z)));
    let points = voxel::downsample(raw, config.downsampling_m);
    if points.len() > u32::MAX as usize {
        return Err(PluginError::InvalidInput(format!(
            "{PLUGIN_NAME}: {} points is too many",
            points.len()
        )));
    }
    let downsample_ms = elapsed_ms(start);
    let mut data = prepare_level(config, points, true);
    data.timings.downsample_ms = downsample_ms;

    if let Some(coarse_m) = config.coarse_level_m() {
        let stage = Instant::now();
        let coarse_points = voxel::downsample(data.points.iter().copied(), coarse_m);
        data.coarse = Some(Box::new(prepare_level(config, coarse_points, false)));
        data.timings.coarse_ms = elapsed_ms(stage);
    }
    data.timings.total_ms = elapsed_ms(start);

    let public = Cloud::new(
        data.points
            .iter()
            .map(|p| Point::new(p.x as f32, p.y as f32, p.z as f32))
            .collect(),
    );
    Ok(PreparedCloud {
        cloud: Arc::new(public),
        cache: Arc::new(data),
    })
}

/// The tree, local features, voxel map (for VGICP when `with_voxel_map`) and extents of one level.
fn prepare_level(config: &GicpConfig, points: Vec<Vector3<f64>>, with_voxel_map: bool) -> PreparedData {
    let mut timings = PrepareTimings::default();
    let stage = Instant::now();
    let tree = PointTree::build(&points);
    timings.tree_ms = elapsed_ms(stage);

    let stage = Instant::now();
    let LocalFeatures { covariances, normals } = if config.variant.needs_local_features() {
        features::estimate(&points, &tree, config.num_neighbors)
    } else {
        LocalFeatures {
            covariances: Vec::new(),
            normals: Vec::new(),
        }
    };
    timings.covariance_ms = elapsed_ms(stage);

    let stage = Instant::now();
    let voxel_map = (with_voxel_map && config.variant == Variant::Vgicp)
        .then(|| GaussianVoxelMap::build(&points, &covariances, config.voxel_resolution_m));
    let extents = features::principal_extents(&points);
    timings.voxel_map_ms = elapsed_ms(stage);
    PreparedData {
        key: config.preparation_key(),
        points,
        tree,
        covariances,
        normals,
        voxel_map,
        extents,
        coarse: None,
        timings,
    }
}

/// The plugin data of a prepared cloud, checked to have been prepared with `config`'s settings.
pub(crate) fn data_of<'a>(
    prepared: &'a PreparedCloud,
    config: &GicpConfig,
    role: &str,
) -> PluginResult<&'a PreparedData> {
    let Some(data) = prepared.cache.downcast_ref::<PreparedData>() else {
        return Err(PluginError::InvalidInput(format!(
            "{PLUGIN_NAME}: the {role} cloud was prepared by another fine-registration plugin; prepare it with \
             this plugin"
        )));
    };
    let expected = config.preparation_key();
    if data.key != expected {
        return Err(PluginError::InvalidInput(format!(
            "{PLUGIN_NAME}: the {role} cloud was prepared with {} but this instance needs {expected}; prepare it \
             with this instance",
            data.key
        )));
    }
    Ok(data)
}

/// The plugin data of a prepared cloud, if this plugin prepared it (for timings and inspection).
pub fn prepared_data(prepared: &PreparedCloud) -> Option<&PreparedData> {
    prepared.cache.downcast_ref::<PreparedData>()
}
