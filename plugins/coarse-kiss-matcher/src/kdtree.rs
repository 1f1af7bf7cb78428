//! An exact kd-tree for nearest-neighbour search in descriptor space (33 dimensions), built the way
//! FLANN's single kd-tree and nanoflann build theirs (Muja & Lowe, VISAPP 2009; Blanco & Rai, 2014):
//! each node splits the dimension along which its points spread most, at the median, and a search keeps
//! the incremental distance from the query to the node's bounding region, so whole subtrees are skipped
//! in high dimension too. (A tree that splits the axes in turn, as general-purpose crates do, only ever
//! splits the first few of 33 axes and degrades to a linear scan; KISS-Matcher matches with FLANN.)

/// Points per leaf.
const LEAF_SIZE: usize = 12;

#[derive(Clone, Copy, Debug)]
enum Node {
    Leaf {
        start: u32,
        end: u32,
    },
    /// Points left have `value[dim] <= low`, points right have `value[dim] >= high`.
    Split {
        dim: u16,
        low: f32,
        high: f32,
        left: u32,
        right: u32,
    },
}

/// An immutable kd-tree over `K`-dimensional f32 points; items are the input indices.
#[derive(Clone, Debug)]
pub struct KdTree<const K: usize> {
    /// The points in tree order (each leaf's points contiguous).
    points: Vec<[f32; K]>,
    /// Input index of each point in tree order.
    items: Vec<u32>,
    nodes: Vec<Node>,
}

/// The nearest and second-nearest item with their squared distances.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NearestTwo {
    pub first: Option<(u32, f32)>,
    pub second: Option<(u32, f32)>,
}

impl<const K: usize> KdTree<K> {
    /// Builds the tree; an empty input gives a tree that finds nothing.
    pub fn build(points: &[[f32; K]]) -> Self {
        let mut order: Vec<u32> = (0..points.len() as u32).collect();
        let mut nodes = Vec::with_capacity(2 * points.len() / LEAF_SIZE + 1);
        if !points.is_empty() {
            build_node(points, &mut order, 0, &mut nodes);
        }
        Self {
            points: order.iter().map(|&i| points[i as usize]).collect(),
            items: order,
            nodes,
        }
    }

    pub fn len(&self) -> usize {
        self.points.len()
    }

    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The two nearest items to `query` (exact; ties keep the earlier-visited item).
    pub fn nearest_two(&self, query: &[f32; K]) -> NearestTwo {
        let mut best = NearestTwo {
            first: None,
            second: None,
        };
        if !self.nodes.is_empty() {
            let mut offsets = [0.0f32; K];
            self.search(0, query, 0.0, &mut offsets, &mut best, true);
        }
        best
    }

    /// The nearest item to `query` (exact).
    pub fn nearest_one(&self, query: &[f32; K]) -> Option<(u32, f32)> {
        let mut best = NearestTwo {
            first: None,
            second: None,
        };
        if !self.nodes.is_empty() {
            let mut offsets = [0.0f32; K];
            self.search(0, query, 0.0, &mut offsets, &mut best, false);
        }
        best.first
    }

    /// Recursive search. `bound` is the squared distance from the query to the node's region, made of
    /// the per-dimension `offsets` (squared) along the dimensions split on the way down.
    fn search(
        &self,
        node: usize,
        query: &[f32; K],
        bound: f32,
        offsets: &mut [f32; K],
        best: &mut NearestTwo,
        two: bool,
    ) {
        let worst = |best: &NearestTwo| {
            let slot = if two { best.second } else { best.first };
            slot.map_or(f32::INFINITY, |(_, d)| d)
        };
        match self.nodes[node] {
            Node::Leaf { start, end } => {
                for k in start as usize..end as usize {
                    let distance = squared_distance(query, &self.points[k]);
                    if distance < worst(best) {
                        let item = (self.items[k], distance);
                        match best.first {
                            Some((_, d)) if d <= distance => best.second = Some(item),
                            _ => {
                                if two {
                                    best.second = best.first;
                                }
                                best.first = Some(item);
                            }
                        }
                    }
                }
            }
            Node::Split {
                dim,
                low,
                high,
                left,
                right,
            } => {
                let dim = dim as usize;
                let value = query[dim];
                let (near, far, gap) = if (value - low) + (value - high) < 0.0 {
                    (left, right, high - value)
                } else {
                    (right, left, value - low)
                };
                self.search(near as usize, query, bound, offsets, best, two);
                let gap_sq = if gap > 0.0 { gap * gap } else { 0.0 };
                let far_bound = bound - offsets[dim] + gap_sq;
                if far_bound < worst(best) {
                    let saved = offsets[dim];
                    offsets[dim] = gap_sq;
                    self.search(far as usize, query, far_bound, offsets, best, two);
                    offsets[dim] = saved;
                }
            }
        }
    }
}

/// Squared Euclidean distance, summed in eight independent lanes so the compiler can vectorise it (a
/// single running f32 sum must stay sequential).
#[inline]
fn squared_distance<const K: usize>(a: &[f32; K], b: &[f32; K]) -> f32 {
    let mut lanes = [0.0f32; 8];
    let (a_chunks, a_rest) = a.as_chunks::<8>();
    let (b_chunks, b_rest) = b.as_chunks::<8>();
    for (x, y) in a_chunks.iter().zip(b_chunks) {
        for lane in 0..8 {
            let d = x[lane] - y[lane];
            lanes[lane] += d * d;
        }
    }
    for (lane, (x, y)) in a_rest.iter().zip(b_rest).enumerate() {
        let d = x - y;
        lanes[lane] += d * d;
    }
    lanes.iter().sum()
}

/// Builds the subtree over `order[..]` (indices whose positions start at `offset` in tree order) and
/// returns its node index.
fn build_node<const K: usize>(
    points: &[[f32; K]],
    order: &mut [u32],
    offset: usize,
    nodes: &mut Vec<Node>,
) -> u32 {
    let index = nodes.len() as u32;
    if order.len() <= LEAF_SIZE {
        nodes.push(Node::Leaf {
            start: offset as u32,
            end: (offset + order.len()) as u32,
        });
        return index;
    }
    // The dimension of largest spread.
    let mut lowest = [f32::INFINITY; K];
    let mut highest = [f32::NEG_INFINITY; K];
    for &i in order.iter() {
        for (d, &v) in points[i as usize].iter().enumerate() {
            lowest[d] = lowest[d].min(v);
            highest[d] = highest[d].max(v);
        }
    }
    let dim = (0..K)
        .max_by(|&a, &b| (highest[a] - lowest[a]).total_cmp(&(highest[b] - lowest[b])))
        .unwrap_or(0);
    if highest[dim].partial_cmp(&lowest[dim]) != Some(std::cmp::Ordering::Greater) {
        // All points coincide: one (large) leaf.
        nodes.push(Node::Leaf {
            start: offset as u32,
            end: (offset + order.len()) as u32,
        });
        return index;
    }
    let middle = order.len() / 2;
    order.select_nth_unstable_by(middle, |&a, &b| {
        points[a as usize][dim].total_cmp(&points[b as usize][dim])
    });
    let (left_part, right_part) = order.split_at_mut(middle);
    let low = left_part
        .iter()
        .map(|&i| points[i as usize][dim])
        .fold(f32::NEG_INFINITY, f32::max);
    let high = right_part
        .iter()
        .map(|&i| points[i as usize][dim])
        .fold(f32::INFINITY, f32::min);
    nodes.push(Node::Leaf { start: 0, end: 0 });
    let left = build_node(points, left_part, offset, nodes);
    let right = build_node(points, right_part, offset + middle, nodes);
    nodes[index as usize] = Node::Split {
        dim: dim as u16,
        low,
        high,
        left,
        right,
    };
    index
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn brute_force<const K: usize>(points: &[[f32; K]], query: &[f32; K]) -> Vec<(u32, f32)> {
        let mut all: Vec<(u32, f32)> = points
            .iter()
            .enumerate()
            .map(|(i, p)| (i as u32, squared_distance(query, p)))
            .collect();
        all.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
        all
    }

    #[test]
    fn agrees_with_brute_force_in_33_dimensions() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        // Clustered data, like descriptors: a few centres with spread.
        let centres: Vec<[f32; 33]> = (0..20)
            .map(|_| std::array::from_fn(|_| rng.random_range(0.0..50.0)))
            .collect();
        let points: Vec<[f32; 33]> = (0..3000)
            .map(|i| {
                let c = &centres[i % 20];
                std::array::from_fn(|d| c[d] + rng.random_range(-5.0..5.0))
            })
            .collect();
        let tree = KdTree::build(&points);
        assert_eq!(tree.len(), 3000);
        for q in 0..200 {
            let query: [f32; 33] = if q % 2 == 0 {
                points[q * 7]
            } else {
                std::array::from_fn(|_| rng.random_range(0.0..50.0))
            };
            let truth = brute_force(&points, &query);
            let found = tree.nearest_two(&query);
            let (first, second) = (found.first.unwrap(), found.second.unwrap());
            assert_eq!(first.1, truth[0].1, "query {q}");
            assert_eq!(second.1, truth[1].1, "query {q}");
            assert_eq!(tree.nearest_one(&query).unwrap().1, truth[0].1);
        }
    }

    #[test]
    fn small_degenerate_and_empty_trees() {
        let empty = KdTree::<3>::build(&[]);
        assert!(empty.nearest_one(&[0.0; 3]).is_none());
        let same = KdTree::build(&[[1.0f32; 3]; 40]);
        assert_eq!(same.nearest_two(&[1.0; 3]).second.map(|s| s.1), Some(0.0));
        let one = KdTree::build(&[[1.0f32, 2.0, 3.0]]);
        let found = one.nearest_two(&[0.0; 3]);
        assert_eq!(found.first, Some((0, 14.0)));
        assert_eq!(found.second, None);
    }
}
