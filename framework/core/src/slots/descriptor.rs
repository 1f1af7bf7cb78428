//! Place recognition slot: a global descriptor per keyframe and the index that retrieves candidates.

use crate::{CloudView, KeyframeId, PluginResult};

/// A global descriptor: a fixed-length vector of f32 values of one kind.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DescriptorBuf {
    /// The descriptor plugin that produced it (`solid`, `scan_context`, …).
    pub kind: String,
    pub values: Vec<f32>,
}

impl DescriptorBuf {
    /// Size in bytes when sent as f32 values.
    pub fn byte_len(&self) -> usize {
        self.values.len() * std::mem::size_of::<f32>()
    }
}

/// A keyframe retrieved from the index for a query.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlaceCandidate {
    pub id: KeyframeId,
    /// Descriptor distance as the plugin defines it; smaller is more similar.
    pub distance: f64,
    /// Yaw of `candidate_from_query` in radians, when the descriptor can tell: the rotation about the
    /// sensor's z axis that takes query points into the candidate's frame, i.e. the initial guess of a
    /// registration with the candidate as target and the query as source.
    pub yaw_hint_rad: Option<f64>,
}

/// Computes global descriptors from keyframe clouds (in the sensor frame).
pub trait Descriptor: Send {
    /// The descriptor kind, equal to the plugin's registry name.
    fn kind(&self) -> &str;

    /// Describes one keyframe cloud.
    fn describe(&mut self, cloud: CloudView<'_>) -> PluginResult<DescriptorBuf>;

    /// A new, empty retrieval index for this descriptor kind and these parameters.
    fn new_index(&self) -> Box<dyn DescriptorIndex>;

    /// The largest distance (as the index reports it) at which two descriptors are taken to show the
    /// same place; the runtime passes only candidates below it to registration. The default accepts
    /// every candidate and leaves the decision to verification.
    fn match_threshold(&self) -> f64 {
        f64::INFINITY
    }
}

/// Stores descriptors and retrieves the nearest ones.
pub trait DescriptorIndex: Send {
    /// Adds a descriptor; a descriptor of another kind or length is an error.
    fn insert(&mut self, id: KeyframeId, descriptor: DescriptorBuf) -> PluginResult<()>;

    /// The up to `k` most similar stored keyframes for which `exclude` is false, best first.
    fn query(
        &mut self,
        descriptor: &DescriptorBuf,
        k: usize,
        exclude: &dyn Fn(KeyframeId) -> bool,
    ) -> PluginResult<Vec<PlaceCandidate>>;

    /// The distance (as [`DescriptorIndex::query`] reports it) between two stored keyframes, for a
    /// verifier that asks whether two keyframes look like one place; `None` when either is not stored
    /// or the index cannot say (the default).
    fn distance_between(&self, a: KeyframeId, b: KeyframeId) -> Option<f64> {
        let _ = (a, b);
        None
    }

    /// Number of stored descriptors.
    fn len(&self) -> usize;

    fn is_empty(&self) -> bool {
        self.len() == 0
    }
}
