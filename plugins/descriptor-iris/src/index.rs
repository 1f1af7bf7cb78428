//! LiDAR-Iris retrieval (Wang et al., IROS 2020): row keys in a KD-tree propose candidates, which are
//! re-ranked by the masked Hamming distance of their binary templates at the best azimuth shift.
//!
//! Distance, as this plugin defines it: the smallest masked Hamming distance (differing unmasked template
//! bits over unmasked bits, in [0, 1]; 1 when nothing can be compared) over the shifts within
//! `shift_search_radius` columns of the phase-correlation estimate s, and, with `match_flipped`, of
//! s + 180° (a reverse-direction revisit can make the correlation peak land half a turn off). The
//! public threshold is about 0.35.
//!
//! Yaw hint: at the best shift s, query column j matches candidate column j − s, so the query is the
//! candidate turned by +s columns and the yaw of candidate_from_query is −s · 360° / N.
//!
//! Memory: each stored keyframe keeps its code image, template and mask, one byte per pixel each
//! (3 × 28,800 bytes with the defaults).

use std::collections::BTreeMap;

use skid_core::slots::{DescriptorBuf, DescriptorIndex, PlaceCandidate};
use skid_core::{KeyframeId, PluginError, PluginResult};

use crate::features::{Features, FilterBank, hamming_distance};
use crate::fft::C32;
use crate::image::row_key;
use skid_keytree::{KeyTree, RebuildPolicy};

/// Shape and search parameters of an index.
#[derive(Clone, Copy, Debug)]
pub struct IrisShape {
    pub num_rings: usize,
    pub num_columns: usize,
    pub num_slices: usize,
    /// Row-key neighbours re-ranked per query (at least k).
    pub num_candidates: usize,
    pub shift_search_radius: usize,
    pub match_flipped: bool,
}

/// A stored keyframe.
struct Entry {
    id: KeyframeId,
    codes: Vec<u8>,
    features: Features,
}

/// The index of one LiDAR-Iris configuration.
pub struct IrisIndex {
    shape: IrisShape,
    bank: FilterBank,
    entries: Vec<Entry>,
    /// Where each keyframe sits in `entries`.
    positions: BTreeMap<KeyframeId, usize>,
    tree: KeyTree,
}

/// The best (distance, shift) of a query (its row spectra and features) against a candidate (its code
/// image and features).
pub fn compare(
    bank: &FilterBank,
    shape: &IrisShape,
    query: (&[C32], &Features),
    candidate: (&[u8], &Features),
) -> (f64, usize) {
    let n = shape.num_columns;
    let estimate = bank
        .estimate_shift(query.0, &bank.spectra(candidate.0))
        .unwrap_or(0);
    let mut centres = vec![estimate];
    if shape.match_flipped {
        centres.push((estimate + n / 2) % n);
    }
    let radius = shape.shift_search_radius.min(n / 2);
    let mut shifts: Vec<usize> = centres
        .iter()
        .flat_map(|&c| (0..=2 * radius).map(move |i| (c + n + i - radius) % n))
        .collect();
    shifts.sort_unstable();
    shifts.dedup();
    shifts
        .into_iter()
        .map(|shift| (hamming_distance(query.1, candidate.1, n, shift), shift))
        .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)))
        .unwrap_or((1.0, 0))
}

/// An angle in degrees wrapped to (−180, 180].
pub fn wrap_deg(angle_deg: f64) -> f64 {
    let wrapped = angle_deg.rem_euclid(360.0);
    if wrapped > 180.0 { wrapped - 360.0 } else { wrapped }
}

impl IrisIndex {
    pub fn new(shape: IrisShape, bank: FilterBank, policy: RebuildPolicy) -> Self {
        Self {
            shape,
            bank,
            entries: Vec::new(),
            positions: BTreeMap::new(),
            tree: KeyTree::new("iris", shape.num_rings, policy),
        }
    }

    /// The code image of a descriptor, after checking it.
    fn codes(&self, descriptor: &DescriptorBuf) -> PluginResult<Vec<u8>> {
        let expected = self.shape.num_rings * self.shape.num_columns;
        if descriptor.kind != crate::NAME || descriptor.values.len() != expected {
            return Err(PluginError::InvalidInput(format!(
                "the iris index takes `iris` descriptors of {expected} values, got `{}` with {}",
                descriptor.kind,
                descriptor.values.len()
            )));
        }
        descriptor
            .values
            .iter()
            .map(|&v| {
                if v.fract() == 0.0 && (0.0..=255.0).contains(&v) {
                    Ok(v as u8)
                } else {
                    Err(PluginError::InvalidInput(format!(
                        "iris pixel codes are integers in 0..=255, got {v}"
                    )))
                }
            })
            .collect()
    }
}

impl DescriptorIndex for IrisIndex {
    fn insert(&mut self, id: KeyframeId, descriptor: DescriptorBuf) -> PluginResult<()> {
        let codes = self.codes(&descriptor)?;
        self.tree
            .push(&row_key(&codes, self.shape.num_columns, self.shape.num_slices))?;
        let features = self.bank.features(&self.bank.spectra(&codes));
        self.positions.insert(id, self.entries.len());
        self.entries.push(Entry { id, codes, features });
        Ok(())
    }

    fn query(
        &mut self,
        descriptor: &DescriptorBuf,
        k: usize,
        exclude: &dyn Fn(KeyframeId) -> bool,
    ) -> PluginResult<Vec<PlaceCandidate>> {
        let codes = self.codes(descriptor)?;
        if k == 0 {
            return Ok(Vec::new());
        }
        let key = row_key(&codes, self.shape.num_columns, self.shape.num_slices);
        let entries = &self.entries;
        let proposals = self.tree.nearest(&key, k.max(self.shape.num_candidates), &|p| {
            !exclude(entries[p].id)
        })?;
        let spectra = self.bank.spectra(&codes);
        let features = self.bank.features(&spectra);
        let column_deg = 360.0 / self.shape.num_columns as f64;
        let mut candidates: Vec<PlaceCandidate> = proposals
            .into_iter()
            .map(|(position, _)| {
                let entry = &self.entries[position];
                let (distance, shift) = compare(
                    &self.bank,
                    &self.shape,
                    (&spectra, &features),
                    (&entry.codes, &entry.features),
                );
                PlaceCandidate {
                    id: entry.id,
                    distance,
                    yaw_hint_rad: Some(wrap_deg(-(shift as f64) * column_deg).to_radians()),
                }
            })
            .collect();
        candidates.sort_by(|a, b| a.distance.total_cmp(&b.distance));
        candidates.truncate(k);
        Ok(candidates)
    }

    fn distance_between(&self, a: KeyframeId, b: KeyframeId) -> Option<f64> {
        let (a, b) = (
            &self.entries[*self.positions.get(&a)?],
            &self.entries[*self.positions.get(&b)?],
        );
        let spectra = self.bank.spectra(&a.codes);
        Some(
            compare(
                &self.bank,
                &self.shape,
                (&spectra, &a.features),
                (&b.codes, &b.features),
            )
            .0,
        )
    }

    fn len(&self) -> usize {
        self.entries.len()
    }
}
