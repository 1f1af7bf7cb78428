//! SOLiD retrieval (Kim et al., RA-L 2024): a KD-tree over L2-normalised R-SOLiD and a yaw hint from the
//! best circular shift of A-SOLiD.
//!
//! Distance: the cosine distance of the two R-SOLiD vectors, 1 − cos(a, b), computed as ½‖â − b̂‖² of the
//! unit vectors (equal for unit vectors, and exactly 0 for a descriptor and itself). It lies in [0, 1]
//! because R-SOLiD is non-negative. Public systems accept a match below about 0.002 to 0.05.
//!
//! Yaw hint: A-SOLiD of both keyframes is scaled to unit sum (so that scans with different point counts
//! compare), and the circular shift s (in azimuth bins) minimising Σ_a |query[a + s] − candidate[a]| is
//! found. The query then sees at azimuth θ + s·w what the candidate sees at θ (w = 360° / N_a), so the
//! yaw of candidate_from_query is −s·w, reported in (−180°, 180°]. (The public C++ version reports
//! (argmin + 1) sectors, one sector off.) A keyframe with an all-zero A-SOLiD gives no hint.

use std::collections::BTreeMap;

use skid_core::slots::{DescriptorBuf, DescriptorIndex, PlaceCandidate};
use skid_core::{KeyframeId, PluginError, PluginResult};

use skid_keytree::{KeyTree, RebuildPolicy};

/// The index of one SOLiD configuration.
pub struct SolidIndex {
    num_range: usize,
    num_azimuth: usize,
    ids: Vec<KeyframeId>,
    /// Where each keyframe sits in `ids`.
    positions: BTreeMap<KeyframeId, usize>,
    /// A-SOLiD of every entry scaled to unit sum (all zero when it has no points), flattened.
    azimuth: Vec<f32>,
    tree: KeyTree,
}

impl SolidIndex {
    pub fn new(num_range: usize, num_azimuth: usize, policy: RebuildPolicy) -> Self {
        Self {
            num_range,
            num_azimuth,
            ids: Vec::new(),
            positions: BTreeMap::new(),
            azimuth: Vec::new(),
            tree: KeyTree::new("solid", num_range, policy),
        }
    }

    /// The unit R-SOLiD key and the unit-sum A-SOLiD of a descriptor, after checking it.
    fn split(&self, descriptor: &DescriptorBuf) -> PluginResult<(Vec<f32>, Vec<f32>)> {
        let expected = self.num_range + self.num_azimuth;
        if descriptor.kind != crate::NAME || descriptor.values.len() != expected {
            return Err(PluginError::InvalidInput(format!(
                "the solid index takes `solid` descriptors of {expected} values, got `{}` with {}",
                descriptor.kind,
                descriptor.values.len()
            )));
        }
        if let Some(bad) = descriptor.values.iter().find(|v| !(v.is_finite() && **v >= 0.0)) {
            return Err(PluginError::InvalidInput(format!(
                "SOLiD values are finite and non-negative, got {bad}"
            )));
        }
        let (range, azimuth) = descriptor.values.split_at(self.num_range);
        let norm = range
            .iter()
            .map(|&v| f64::from(v) * f64::from(v))
            .sum::<f64>()
            .sqrt();
        if norm == 0.0 {
            return Err(PluginError::InvalidInput(
                "R-SOLiD is all zero: the keyframe had no usable points".into(),
            ));
        }
        let key = range.iter().map(|&v| (f64::from(v) / norm) as f32).collect();
        let sum = azimuth.iter().map(|&v| f64::from(v)).sum::<f64>();
        let scale = if sum > 0.0 { 1.0 / sum } else { 0.0 };
        let azimuth = azimuth.iter().map(|&v| (f64::from(v) * scale) as f32).collect();
        Ok((key, azimuth))
    }

    /// Yaw of candidate_from_query from the stored A-SOLiD at `position`, in radians.
    fn yaw_hint(&self, query: &[f32], position: usize) -> Option<f64> {
        let n = self.num_azimuth;
        let candidate = &self.azimuth[position * n..(position + 1) * n];
        if query.iter().all(|&v| v == 0.0) || candidate.iter().all(|&v| v == 0.0) {
            return None;
        }
        let best_shift = best_circular_shift(query, candidate);
        let yaw_deg = -(best_shift as f64) * 360.0 / n as f64;
        Some(wrap_deg(yaw_deg).to_radians())
    }
}

/// The shift s minimising Σ_a |query[(a + s) mod n] − candidate[a]|; the smallest such s on ties.
pub fn best_circular_shift(query: &[f32], candidate: &[f32]) -> usize {
    let n = query.len();
    let mut best = (f32::INFINITY, 0);
    for shift in 0..n {
        let (head, tail) = query.split_at(shift);
        let shifted = tail.iter().chain(head);
        let cost: f32 = shifted.zip(candidate).map(|(q, c)| (q - c).abs()).sum();
        if cost < best.0 {
            best = (cost, shift);
        }
    }
    best.1
}

/// An angle in degrees wrapped to (−180, 180].
pub fn wrap_deg(angle_deg: f64) -> f64 {
    let wrapped = angle_deg.rem_euclid(360.0);
    if wrapped > 180.0 { wrapped - 360.0 } else { wrapped }
}

impl DescriptorIndex for SolidIndex {
    fn insert(&mut self, id: KeyframeId, descriptor: DescriptorBuf) -> PluginResult<()> {
        let (key, azimuth) = self.split(&descriptor)?;
        self.tree.push(&key)?;
        self.positions.insert(id, self.ids.len());
        self.ids.push(id);
        self.azimuth.extend(azimuth);
        Ok(())
    }

    fn query(
        &mut self,
        descriptor: &DescriptorBuf,
        k: usize,
        exclude: &dyn Fn(KeyframeId) -> bool,
    ) -> PluginResult<Vec<PlaceCandidate>> {
        let (key, azimuth) = self.split(descriptor)?;
        let ids = &self.ids;
        let nearest = self.tree.nearest(&key, k, &|position| !exclude(ids[position]))?;
        let mut candidates: Vec<PlaceCandidate> = nearest
            .into_iter()
            .map(|(position, _)| PlaceCandidate {
                id: self.ids[position],
                distance: cosine_distance(self.tree.key(position), &key),
                yaw_hint_rad: self.yaw_hint(&azimuth, position),
            })
            .collect();
        candidates.sort_by(|a, b| a.distance.total_cmp(&b.distance));
        Ok(candidates)
    }

    fn distance_between(&self, a: KeyframeId, b: KeyframeId) -> Option<f64> {
        let (a, b) = (self.positions.get(&a)?, self.positions.get(&b)?);
        Some(cosine_distance(self.tree.key(*a), self.tree.key(*b)))
    }

    fn len(&self) -> usize {
        self.ids.len()
    }
}

/// 1 − cos of two unit R-SOLiD keys, as ½‖a − b‖².
fn cosine_distance(a: &[f32], b: &[f32]) -> f64 {
    let squared: f64 = a
        .iter()
        .zip(b)
        .map(|(&x, &y)| (f64::from(x) - f64::from(y)).powi(2))
        .sum();
    0.5 * squared
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shift_and_yaw_sign() {
        let candidate = [0.5f32, 0.3, 0.2, 0.0, 0.0, 0.0];
        // The query sees the candidate's bins two bins further on: it is the candidate yawed by +2 bins.
        let query = [0.0f32, 0.0, 0.5, 0.3, 0.2, 0.0];
        assert_eq!(best_circular_shift(&query, &candidate), 2);
        assert_eq!(wrap_deg(-120.0), -120.0);
        assert_eq!(wrap_deg(270.0), -90.0);
        assert_eq!(wrap_deg(-180.0), 180.0);
    }
}
