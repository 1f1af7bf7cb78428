//! Scan Context retrieval (Kim & Kim, IROS 2018): ring keys in a KD-tree propose candidates, which are
//! re-ranked by the column-shift cosine distance of the full scan contexts.
//!
//! Distance, as this plugin defines it: for a shift s (in sectors) the candidate's column j − s is
//! compared with the query's column j by cosine similarity, over the columns where both are non-zero;
//! the distance at s is 1 − the mean similarity (1 when no column pair is non-zero, which also covers an
//! all-empty context). The reported distance is the smallest over the shifts searched: those within
//! `round(search_ratio · N / 2)` sectors of the pre-alignment s₀, the shift of the candidate's sector key
//! that best matches (least squares) the query's. With cells ≥ 0 the distance lies in [0, 1];
//! the public threshold is about 0.13 (0.1–0.2 rarely gives a false match).
//!
//! Yaw hint: the query sees in sector j what the candidate sees in sector j − s, so the query is the
//! candidate turned by +s sectors and the yaw of candidate_from_query is −s · 360° / N, in (−180°, 180°].

use std::collections::BTreeMap;

use skid_core::slots::{DescriptorBuf, DescriptorIndex, PlaceCandidate};
use skid_core::{KeyframeId, PluginError, PluginResult};

use crate::extract::{ring_key, sector_key};
use skid_keytree::{KeyTree, RebuildPolicy};

/// Shape and search parameters of an index.
#[derive(Clone, Copy, Debug)]
pub struct ScanContextShape {
    pub num_rings: usize,
    pub num_sectors: usize,
    /// Ring-key neighbours re-ranked per query (at least k).
    pub num_candidates: usize,
    /// Shifts searched on each side of the sector-key pre-alignment.
    pub search_radius: usize,
}

/// A scan context prepared for comparison: columns contiguous, their norms, and the sector key.
#[derive(Clone, Debug)]
pub struct Prepared {
    /// Column-major: `columns[sector * num_rings + ring]`.
    columns: Vec<f32>,
    column_norms: Vec<f64>,
    sector_key: Vec<f32>,
}

impl Prepared {
    pub fn new(values: &[f32], shape: &ScanContextShape) -> Self {
        let (rings, sectors) = (shape.num_rings, shape.num_sectors);
        let mut columns = vec![0.0f32; rings * sectors];
        for ring in 0..rings {
            for sector in 0..sectors {
                columns[sector * rings + ring] = values[ring * sectors + sector];
            }
        }
        let column_norms = columns
            .chunks_exact(rings)
            .map(|c| c.iter().map(|&v| f64::from(v) * f64::from(v)).sum::<f64>().sqrt())
            .collect();
        Self {
            columns,
            column_norms,
            sector_key: sector_key(values, sectors),
        }
    }
}

/// Distance at one shift: 1 − mean cosine similarity of the column pairs that are both non-zero.
fn shifted_distance(query: &Prepared, candidate: &Prepared, shape: &ScanContextShape, shift: usize) -> f64 {
    let (rings, sectors) = (shape.num_rings, shape.num_sectors);
    let (mut sum, mut count) = (0.0f64, 0usize);
    for j in 0..sectors {
        let c = (j + sectors - shift) % sectors;
        let (qn, cn) = (query.column_norms[j], candidate.column_norms[c]);
        if qn == 0.0 || cn == 0.0 {
            continue;
        }
        let qc = &query.columns[j * rings..(j + 1) * rings];
        let cc = &candidate.columns[c * rings..(c + 1) * rings];
        let dot: f64 = qc
            .iter()
            .zip(cc)
            .map(|(&a, &b)| f64::from(a) * f64::from(b))
            .sum();
        sum += dot / (qn * cn);
        count += 1;
    }
    if count == 0 {
        1.0
    } else {
        (1.0 - sum / count as f64).max(0.0)
    }
}

/// The shift s₀ minimising Σ_j (query[j] − candidate[j − s])².
pub fn sector_key_alignment(query: &[f32], candidate: &[f32]) -> usize {
    let n = query.len();
    let mut best = (f32::INFINITY, 0);
    for shift in 0..n {
        let cost: f32 = (0..n)
            .map(|j| (query[j] - candidate[(j + n - shift) % n]).powi(2))
            .sum();
        if cost < best.0 {
            best = (cost, shift);
        }
    }
    best.1
}

/// The smallest distance over the searched shifts, and its shift.
pub fn distance(query: &Prepared, candidate: &Prepared, shape: &ScanContextShape) -> (f64, usize) {
    let sectors = shape.num_sectors;
    let shifts: Vec<usize> = if 2 * shape.search_radius + 1 >= sectors {
        (0..sectors).collect()
    } else {
        let center = sector_key_alignment(&query.sector_key, &candidate.sector_key);
        (0..=2 * shape.search_radius)
            .map(|i| (center + sectors + i - shape.search_radius) % sectors)
            .collect()
    };
    shifts
        .into_iter()
        .map(|shift| (shifted_distance(query, candidate, shape, shift), shift))
        .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)))
        .unwrap_or((1.0, 0))
}

/// An angle in degrees wrapped to (−180, 180].
pub fn wrap_deg(angle_deg: f64) -> f64 {
    let wrapped = angle_deg.rem_euclid(360.0);
    if wrapped > 180.0 { wrapped - 360.0 } else { wrapped }
}

/// The index of one Scan Context configuration.
pub struct ScanContextIndex {
    shape: ScanContextShape,
    ids: Vec<KeyframeId>,
    /// Where each keyframe sits in `ids`.
    positions: BTreeMap<KeyframeId, usize>,
    contexts: Vec<Prepared>,
    tree: KeyTree,
}

impl ScanContextIndex {
    pub fn new(shape: ScanContextShape, policy: RebuildPolicy) -> Self {
        Self {
            shape,
            ids: Vec::new(),
            positions: BTreeMap::new(),
            contexts: Vec::new(),
            tree: KeyTree::new("scan_context", shape.num_rings, policy),
        }
    }

    fn check(&self, descriptor: &DescriptorBuf) -> PluginResult<()> {
        let expected = self.shape.num_rings * self.shape.num_sectors;
        if descriptor.kind != crate::NAME || descriptor.values.len() != expected {
            return Err(PluginError::InvalidInput(format!(
                "the scan_context index takes `scan_context` descriptors of {expected} values, got `{}` with {}",
                descriptor.kind,
                descriptor.values.len()
            )));
        }
        if let Some(bad) = descriptor.values.iter().find(|v| !v.is_finite()) {
            return Err(PluginError::InvalidInput(format!(
                "scan context values are finite, got {bad}"
            )));
        }
        Ok(())
    }
}

impl DescriptorIndex for ScanContextIndex {
    fn insert(&mut self, id: KeyframeId, descriptor: DescriptorBuf) -> PluginResult<()> {
        self.check(&descriptor)?;
        self.tree
            .push(&ring_key(&descriptor.values, self.shape.num_sectors))?;
        self.contexts.push(Prepared::new(&descriptor.values, &self.shape));
        self.positions.insert(id, self.ids.len());
        self.ids.push(id);
        Ok(())
    }

    fn query(
        &mut self,
        descriptor: &DescriptorBuf,
        k: usize,
        exclude: &dyn Fn(KeyframeId) -> bool,
    ) -> PluginResult<Vec<PlaceCandidate>> {
        self.check(descriptor)?;
        if k == 0 {
            return Ok(Vec::new());
        }
        let key = ring_key(&descriptor.values, self.shape.num_sectors);
        let ids = &self.ids;
        let proposals = self
            .tree
            .nearest(&key, k.max(self.shape.num_candidates), &|p| !exclude(ids[p]))?;
        let query = Prepared::new(&descriptor.values, &self.shape);
        let sector_deg = 360.0 / self.shape.num_sectors as f64;
        let mut candidates: Vec<PlaceCandidate> = proposals
            .into_iter()
            .map(|(position, _)| {
                let (distance, shift) = distance(&query, &self.contexts[position], &self.shape);
                PlaceCandidate {
                    id: self.ids[position],
                    distance,
                    yaw_hint_rad: Some(wrap_deg(-(shift as f64) * sector_deg).to_radians()),
                }
            })
            .collect();
        candidates.sort_by(|a, b| a.distance.total_cmp(&b.distance));
        candidates.truncate(k);
        Ok(candidates)
    }

    fn distance_between(&self, a: KeyframeId, b: KeyframeId) -> Option<f64> {
        let (a, b) = (self.positions.get(&a)?, self.positions.get(&b)?);
        Some(distance(&self.contexts[*a], &self.contexts[*b], &self.shape).0)
    }

    fn len(&self) -> usize {
        self.ids.len()
    }
}
