//! An exact nearest-neighbour index under the Euclidean (L2) distance, for dynamic descriptor plugins.
//!
//! A linear scan: fine for the thousands of keyframes of a mapping session; a plugin that needs
//! something faster or another distance is better written as a built-in.

use skid_core::slots::{DescriptorBuf, DescriptorIndex, PlaceCandidate};
use skid_core::{KeyframeId, PluginError, PluginResult};

/// Stores descriptors of one kind and length and returns the nearest ones by L2 distance.
#[derive(Clone, Debug)]
pub struct ExactL2Index {
    kind: String,
    /// The common length, fixed by the first insert.
    len: Option<usize>,
    entries: Vec<(KeyframeId, Vec<f32>)>,
}

impl ExactL2Index {
    /// An empty index for descriptors of kind `kind`.
    pub fn new(kind: &str) -> Self {
        Self {
            kind: kind.to_owned(),
            len: None,
            entries: Vec::new(),
        }
    }

    fn check(&self, descriptor: &DescriptorBuf) -> PluginResult<()> {
        if descriptor.kind != self.kind {
            return Err(PluginError::InvalidInput(format!(
                "a `{}` descriptor given to a `{}` index",
                descriptor.kind, self.kind
            )));
        }
        match self.len {
            Some(len) if len != descriptor.values.len() => Err(PluginError::InvalidInput(format!(
                "a descriptor of length {} given to an index of length {len}",
                descriptor.values.len()
            ))),
            _ => Ok(()),
        }
    }
}

/// The Euclidean distance of two equally long vectors, accumulated in f64.
fn l2(a: &[f32], b: &[f32]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (f64::from(*x) - f64::from(*y)).powi(2))
        .sum::<f64>()
        .sqrt()
}

impl DescriptorIndex for ExactL2Index {
    fn insert(&mut self, id: KeyframeId, descriptor: DescriptorBuf) -> PluginResult<()> {
        self.check(&descriptor)?;
        self.len = Some(descriptor.values.len());
        self.entries.push((id, descriptor.values));
        Ok(())
    }

    fn query(
        &mut self,
        descriptor: &DescriptorBuf,
        k: usize,
        exclude: &dyn Fn(KeyframeId) -> bool,
    ) -> PluginResult<Vec<PlaceCandidate>> {
        self.check(descriptor)?;
        let mut candidates: Vec<PlaceCandidate> = self
            .entries
            .iter()
            .filter(|(id, _)| !exclude(*id))
            .map(|(id, values)| PlaceCandidate {
                id: *id,
                distance: l2(values, &descriptor.values),
                yaw_hint_rad: None,
            })
            .collect();
        candidates.sort_by(|a, b| a.distance.total_cmp(&b.distance).then(a.id.cmp(&b.id)));
        candidates.truncate(k);
        Ok(candidates)
    }

    fn distance_between(&self, a: KeyframeId, b: KeyframeId) -> Option<f64> {
        let values = |id: KeyframeId| {
            self.entries
                .iter()
                .find(|(stored, _)| *stored == id)
                .map(|(_, v)| v)
        };
        Some(l2(values(a)?, values(b)?))
    }

    fn len(&self) -> usize {
        self.entries.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn buf(kind: &str, values: &[f32]) -> DescriptorBuf {
        DescriptorBuf {
            kind: kind.to_owned(),
            values: values.to_vec(),
        }
    }

    #[test]
    fn returns_nearest_first_and_honours_exclusion() {
        let mut index = ExactL2Index::new("rings");
        index
            .insert(KeyframeId::new(0, 0), buf("rings", &[0.0, 0.0]))
            .unwrap();
        index
            .insert(KeyframeId::new(0, 1), buf("rings", &[1.0, 0.0]))
            .unwrap();
        index
            .insert(KeyframeId::new(1, 0), buf("rings", &[3.0, 4.0]))
            .unwrap();
        let found = index.query(&buf("rings", &[0.9, 0.0]), 2, &|_| false).unwrap();
        assert_eq!(
            found.iter().map(|c| c.id).collect::<Vec<_>>(),
            [KeyframeId::new(0, 1), KeyframeId::new(0, 0)]
        );
        assert!((found[0].distance - 0.1).abs() < 1e-6);
        let found = index
            .query(&buf("rings", &[0.9, 0.0]), 5, &|id| id.robot.0 == 0)
            .unwrap();
        assert_eq!(found.len(), 1);
        assert!((found[0].distance - (2.1_f64.powi(2) + 16.0).sqrt()).abs() < 1e-6);
    }

    #[test]
    fn refuses_other_kinds_and_lengths() {
        let mut index = ExactL2Index::new("rings");
        index
            .insert(KeyframeId::new(0, 0), buf("rings", &[0.0, 0.0]))
            .unwrap();
        assert!(
            index
                .insert(KeyframeId::new(0, 1), buf("other", &[0.0, 0.0]))
                .is_err()
        );
        assert!(index.insert(KeyframeId::new(0, 1), buf("rings", &[0.0])).is_err());
        assert!(
            index
                .query(&buf("rings", &[0.0, 0.0, 1.0]), 1, &|_| false)
                .is_err()
        );
    }
}
