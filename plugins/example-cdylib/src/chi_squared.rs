//! The ring histogram's own retrieval index: the chi-squared distance between histograms,
//! `Σ (a − b)² / (a + b)` over the cells where `a + b > 0`, which weighs a difference in a sparse cell
//! more than the same difference in a full one. A linear scan, exact.

use skid_abi::ffi::AbiKeyframeId;
use skid_abi::{IndexCandidate, IndexPlugin};

/// Stored histograms of one length.
#[derive(Debug, Default)]
pub struct ChiSquaredIndex {
    len: usize,
    entries: Vec<(AbiKeyframeId, Vec<f32>)>,
}

impl ChiSquaredIndex {
    /// An empty index for histograms of `len` cells.
    pub fn new(len: usize) -> Self {
        Self {
            len,
            entries: Vec::new(),
        }
    }
}

/// The chi-squared distance of two histograms of one length.
pub fn chi_squared(a: &[f32], b: &[f32]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(&a, &b)| (f64::from(a), f64::from(b)))
        .filter(|(a, b)| a + b > 0.0)
        .map(|(a, b)| (a - b).powi(2) / (a + b))
        .sum()
}

impl IndexPlugin for ChiSquaredIndex {
    fn insert(&mut self, id: AbiKeyframeId, values: &[f32]) -> Result<(), String> {
        if values.len() != self.len {
            return Err(format!(
                "a histogram of {} cells for an index of {}",
                values.len(),
                self.len
            ));
        }
        self.entries.push((id, values.to_vec()));
        Ok(())
    }

    fn query(
        &mut self,
        values: &[f32],
        k: usize,
        exclude: &dyn Fn(AbiKeyframeId) -> bool,
    ) -> Result<Vec<IndexCandidate>, String> {
        if values.len() != self.len {
            return Err(format!(
                "a histogram of {} cells for an index of {}",
                values.len(),
                self.len
            ));
        }
        let mut found: Vec<IndexCandidate> = self
            .entries
            .iter()
            .filter(|(id, _)| !exclude(*id))
            .map(|(id, stored)| IndexCandidate {
                id: *id,
                distance: chi_squared(values, stored),
                yaw_hint_rad: None,
            })
            .collect();
        found.sort_by(|a, b| a.distance.total_cmp(&b.distance));
        found.truncate(k);
        Ok(found)
    }

    fn len(&self) -> usize {
        self.entries.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_first_with_exclusion_and_lengths_checked() {
        let id = |index| AbiKeyframeId { robot: 0, index };
        let mut index = ChiSquaredIndex::new(2);
        index.insert(id(0), &[0.5, 0.5]).unwrap();
        index.insert(id(1), &[0.9, 0.1]).unwrap();
        assert!(index.insert(id(2), &[1.0]).is_err());
        let found = index.query(&[0.8, 0.2], 2, &|_| false).unwrap();
        assert_eq!(found[0].id, id(1));
        assert!((found[0].distance - chi_squared(&[0.8, 0.2], &[0.9, 0.1])).abs() < 1e-12);
        let found = index
            .query(&[0.8, 0.2], 2, &|candidate| candidate == id(1))
            .unwrap();
        assert_eq!(found.len(), 1);
        assert_eq!(found[0].id, id(0));
    }
}
