//! A nearest-neighbour index over fixed-length f32 keys that grows as keyframes arrive: a kiddo
//! `ImmutableKdTree` over the keys present at the last rebuild, plus a brute-force scan of the keys
//! inserted since. The descriptor plugins propose candidates from their keys with it: SOLiD its R-SOLiD
//! keys (Kim et al., RA-L 2024), Scan Context its ring keys (Kim & Kim, IROS 2018), LiDAR-Iris its row
//! keys (Wang et al., IROS 2020).
//!
//! Cost: an `ImmutableKdTree` cannot take insertions, so the tree is rebuilt (O(n log n), serial) on the
//! first query after the pending keys exceed `max(rebuild_min_pending, rebuild_pending_fraction · n)`.
//! With the defaults (32 and 0.1) a stream of n insertions, each followed by a query, rebuilds
//! O(log n) times in total and each query scans at most 10% of the keys linearly, so the amortised
//! cost per keyframe stays O(log n) tree work plus a bounded linear tail.
//!
//! The key length is chosen at run time (it is a configurable bin count) while kiddo's dimension is a
//! const generic: keys are zero-padded to the next supported dimension (10, 16, 20, 32, 40, 64, 80 or
//! 128: the key lengths of the three descriptors' reference parameters and their common variants), which
//! leaves every Euclidean distance unchanged. Longer keys are only ever scanned linearly.

use std::num::NonZero;

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use skid_core::{PluginError, PluginResult};

/// Longest key the index supports.
pub const MAX_KEY_LEN: usize = 128;

macro_rules! trees {
    ($($variant:ident = $k:literal),* $(,)?) => {
        /// The tree over padded keys of one supported dimension.
        enum Tree {
            $($variant(ImmutableKdTree<f32, $k>),)*
        }

        impl Tree {
            fn build(keys: &[f32], key_len: usize, owner: &str) -> PluginResult<Option<Self>> {
                if key_len == 0 {
                    return Ok(None);
                }
                $(
                    if key_len <= $k {
                        let padded: Vec<[f32; $k]> = keys
                            .chunks_exact(key_len)
                            .map(|key| {
                                let mut row = [0.0f32; $k];
                                row[..key_len].copy_from_slice(key);
                                row
                            })
                            .collect();
                        return ImmutableKdTree::<f32, $k>::builder()
                            .with_serial_construction()
                            .build_from_slice(&padded)
                            .map(|tree| Some(Self::$variant(tree)))
                            .map_err(|e| PluginError::failed(owner, format!("KD-tree construction: {e:?}")));
                    }
                )*
                Ok(None)
            }

            /// The `n` nearest stored positions to `key` with squared distances, nearest first.
            fn nearest(&self, key: &[f32], n: NonZero<usize>) -> Vec<(usize, f32)> {
                match self {
                    $(Self::$variant(tree) => {
                        let mut query = [0.0f32; $k];
                        query[..key.len()].copy_from_slice(key);
                        tree.query(&query)
                            .nearest_n::<SquaredEuclidean<f32>>(n)
                            .execute()
                            .into_iter()
                            .map(|found| (found.item as usize, found.distance))
                            .collect()
                    })*
                }
            }
        }
    };
}

trees!(
    K10 = 10,
    K16 = 16,
    K20 = 20,
    K32 = 32,
    K40 = 40,
    K64 = 64,
    K80 = 80,
    K128 = 128
);

/// Rebuild policy of the tree.
#[derive(Clone, Copy, Debug)]
pub struct RebuildPolicy {
    /// Pending keys always tolerated before a rebuild.
    pub min_pending: usize,
    /// Pending keys tolerated as a fraction of the stored keys.
    pub pending_fraction: f64,
}

/// Keys, stored by insertion position, and the tree over the first `built` of them.
pub struct KeyTree {
    /// The plugin whose keys these are, named in errors.
    owner: &'static str,
    key_len: usize,
    keys: Vec<f32>,
    count: usize,
    tree: Option<Tree>,
    built: usize,
    policy: RebuildPolicy,
}

impl KeyTree {
    /// An empty index of `owner`'s keys of `key_len` values. Keys longer than [`MAX_KEY_LEN`] (or empty)
    /// get no tree: they are always scanned linearly.
    pub fn new(owner: &'static str, key_len: usize, policy: RebuildPolicy) -> Self {
        Self {
            owner,
            key_len,
            keys: Vec::new(),
            count: 0,
            tree: None,
            built: 0,
            policy,
        }
    }

    pub fn len(&self) -> usize {
        self.count
    }

    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// The stored key at `position`.
    pub fn key(&self, position: usize) -> &[f32] {
        &self.keys[position * self.key_len..(position + 1) * self.key_len]
    }

    /// Appends a key; its position is the previous `len()`.
    pub fn push(&mut self, key: &[f32]) -> PluginResult<()> {
        if key.len() != self.key_len || key.iter().any(|v| !v.is_finite()) {
            return Err(PluginError::InvalidInput(format!(
                "a key of {} finite values was expected, got {} values",
                self.key_len,
                key.len()
            )));
        }
        self.keys.extend_from_slice(key);
        self.count += 1;
        Ok(())
    }

    /// Rebuilds the tree when too many keys are pending.
    fn refresh(&mut self) -> PluginResult<()> {
        let pending = self.len() - self.built;
        let tolerated = self
            .policy
            .min_pending
            .max((self.policy.pending_fraction * self.len() as f64) as usize);
        if pending > tolerated {
            self.tree = Tree::build(&self.keys, self.key_len, self.owner)?;
            // Without a tree (keys too long) every key stays in the linearly scanned tail.
            self.built = if self.tree.is_some() { self.len() } else { 0 };
        }
        Ok(())
    }

    /// Up to `k` positions nearest to `key` (squared Euclidean distance) among those `accept` takes,
    /// nearest first.
    pub fn nearest(
        &mut self,
        key: &[f32],
        k: usize,
        accept: &dyn Fn(usize) -> bool,
    ) -> PluginResult<Vec<(usize, f32)>> {
        if key.len() != self.key_len {
            return Err(PluginError::InvalidInput(format!(
                "query key of {} values, {} expected",
                key.len(),
                self.key_len
            )));
        }
        if k == 0 || self.is_empty() {
            return Ok(Vec::new());
        }
        self.refresh()?;
        let squared = |stored: &[f32]| {
            stored
                .iter()
                .zip(key)
                .map(|(a, b)| (a - b) * (a - b))
                .sum::<f32>()
        };
        let mut found: Vec<(usize, f32)> = (self.built..self.len())
            .filter(|&p| accept(p))
            .map(|p| (p, squared(self.key(p))))
            .collect();
        if let Some(tree) = &self.tree {
            // Excluded keys are often the nearest ones (a robot's own recent keyframes): widen the search
            // until k accepted keys are found or the whole tree has been seen.
            let mut n = k.min(self.built);
            while let Some(want) = NonZero::new(n) {
                let hits = tree.nearest(key, want);
                let accepted: Vec<(usize, f32)> = hits.into_iter().filter(|&(p, _)| accept(p)).collect();
                if accepted.len() >= k || n >= self.built {
                    found.extend(accepted);
                    break;
                }
                n = (n * 4).min(self.built);
            }
        }
        found.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
        found.truncate(k);
        Ok(found)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn policy() -> RebuildPolicy {
        RebuildPolicy {
            min_pending: 4,
            pending_fraction: 0.1,
        }
    }

    fn brute_force(tree: &KeyTree, key: &[f32], k: usize, accept: &dyn Fn(usize) -> bool) -> Vec<usize> {
        let mut all: Vec<(usize, f32)> = (0..tree.len())
            .filter(|&p| accept(p))
            .map(|p| {
                (
                    p,
                    tree.key(p).iter().zip(key).map(|(a, b)| (a - b) * (a - b)).sum(),
                )
            })
            .collect();
        all.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
        all.into_iter().take(k).map(|(p, _)| p).collect()
    }

    #[test]
    fn agrees_with_brute_force_while_growing() {
        let mut tree = KeyTree::new("test", 40, policy());
        let key_of =
            |i: usize| -> Vec<f32> { (0..40).map(|d| ((i * 7 + d * 13) % 29) as f32 * 0.1).collect() };
        for i in 0..300 {
            tree.push(&key_of(i)).unwrap();
            if i % 17 == 0 {
                let query = key_of(i * 3 + 1);
                let accept = |p: usize| !p.is_multiple_of(5);
                let got: Vec<usize> = tree
                    .nearest(&query, 7, &accept)
                    .unwrap()
                    .into_iter()
                    .map(|(p, _)| p)
                    .collect();
                let want = brute_force(&tree, &query, 7, &accept);
                assert_eq!(got.len(), want.len());
                // Ties may come in another order; compare the distances.
                for (g, w) in got.iter().zip(&want) {
                    let d = |p: usize| {
                        tree.key(p)
                            .iter()
                            .zip(&query)
                            .map(|(a, b)| (a - b) * (a - b))
                            .sum::<f32>()
                    };
                    assert!((d(*g) - d(*w)).abs() < 1e-4, "{g} vs {w}");
                    assert!(accept(*g));
                }
            }
        }
    }

    #[test]
    fn exclusion_of_all_nearest_keys_widens_the_search() {
        let mut tree = KeyTree::new("test", 3, policy());
        for i in 0..200 {
            tree.push(&[i as f32, 0.0, 0.0]).unwrap();
        }
        let found = tree.nearest(&[0.0, 0.0, 0.0], 2, &|p| p >= 150).unwrap();
        assert_eq!(found.iter().map(|f| f.0).collect::<Vec<_>>(), vec![150, 151]);
    }

    #[test]
    fn many_identical_keys_are_fine() {
        let mut tree = KeyTree::new("test", 16, policy());
        for _ in 0..500 {
            tree.push(&[1.0; 16]).unwrap();
        }
        assert_eq!(tree.nearest(&[1.0; 16], 3, &|_| true).unwrap().len(), 3);
    }

    #[test]
    fn wrong_lengths_and_non_finite_keys_are_refused() {
        let mut tree = KeyTree::new("test", 3, policy());
        assert!(tree.push(&[1.0, 2.0]).is_err());
        assert!(tree.push(&[1.0, f32::NAN, 0.0]).is_err());
        assert!(tree.nearest(&[1.0], 1, &|_| true).is_err());
    }

    #[test]
    fn keys_too_long_for_a_tree_are_scanned() {
        let mut tree = KeyTree::new("test", MAX_KEY_LEN + 1, policy());
        for i in 0..50 {
            tree.push(&vec![i as f32; MAX_KEY_LEN + 1]).unwrap();
        }
        let found = tree.nearest(&vec![10.2; MAX_KEY_LEN + 1], 2, &|_| true).unwrap();
        assert_eq!(found.iter().map(|f| f.0).collect::<Vec<_>>(), vec![10, 11]);
    }
}
