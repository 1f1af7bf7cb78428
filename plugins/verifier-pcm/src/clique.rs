//! Maximum clique of an undirected graph: an exact branch and bound with greedy-colouring bounds over
//! bitsets (Tomita & Seki's MCQ, DMTCS 2003, with the bit-parallel sets of San Segundo, Rodríguez-Losada
//! & Jiménez, "An exact bit-parallel algorithm for the maximum clique problem", 2011), a search budget,
//! and a greedy heuristic (degree-ordered construction as in Rossi et al.'s PMC, 2015) for graphs too
//! large for the budget.

/// A fixed-size set of vertex indices.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct BitSet {
    words: Vec<u64>,
}

impl BitSet {
    /// The empty set over `n` vertices.
    pub fn new(n: usize) -> Self {
        Self {
            words: vec![0; n.div_ceil(64)],
        }
    }

    /// Grows the universe to `n` vertices.
    pub fn resize(&mut self, n: usize) {
        self.words.resize(n.div_ceil(64), 0);
    }

    pub fn insert(&mut self, k: usize) {
        self.words[k / 64] |= 1 << (k % 64);
    }

    pub fn remove(&mut self, k: usize) {
        self.words[k / 64] &= !(1 << (k % 64));
    }

    pub fn contains(&self, k: usize) -> bool {
        self.words.get(k / 64).is_some_and(|w| w & (1 << (k % 64)) != 0)
    }

    pub fn count(&self) -> usize {
        self.words.iter().map(|w| w.count_ones() as usize).sum()
    }

    pub fn is_empty(&self) -> bool {
        self.words.iter().all(|w| *w == 0)
    }

    /// `self ∩ other`.
    pub fn and(&self, other: &BitSet) -> BitSet {
        BitSet {
            words: self.words.iter().zip(&other.words).map(|(a, b)| a & b).collect(),
        }
    }

    /// `self ∖ other`, in place.
    pub fn remove_all(&mut self, other: &BitSet) {
        for (a, b) in self.words.iter_mut().zip(&other.words) {
            *a &= !b;
        }
    }

    /// The smallest member.
    pub fn first(&self) -> Option<usize> {
        self.words
            .iter()
            .enumerate()
            .find(|(_, w)| **w != 0)
            .map(|(k, w)| k * 64 + w.trailing_zeros() as usize)
    }

    /// The members, ascending.
    pub fn iter(&self) -> impl Iterator<Item = usize> + '_ {
        self.words.iter().enumerate().flat_map(|(w, &word)| {
            let mut bits = word;
            std::iter::from_fn(move || {
                (bits != 0).then(|| {
                    let b = bits.trailing_zeros() as usize;
                    bits &= bits - 1;
                    w * 64 + b
                })
            })
        })
    }
}

/// An undirected graph as adjacency bitsets.
#[derive(Clone, Debug, Default)]
pub struct Graph {
    adjacency: Vec<BitSet>,
}

impl Graph {
    /// `n` vertices, no edges.
    pub fn new(n: usize) -> Self {
        Self {
            adjacency: vec![BitSet::new(n); n],
        }
    }

    pub fn len(&self) -> usize {
        self.adjacency.len()
    }

    pub fn is_empty(&self) -> bool {
        self.adjacency.is_empty()
    }

    /// Adds a vertex without edges; returns its index.
    pub fn add_vertex(&mut self) -> usize {
        let n = self.adjacency.len() + 1;
        for row in &mut self.adjacency {
            row.resize(n);
        }
        self.adjacency.push(BitSet::new(n));
        n - 1
    }

    pub fn add_edge(&mut self, a: usize, b: usize) {
        if a != b {
            self.adjacency[a].insert(b);
            self.adjacency[b].insert(a);
        }
    }

    pub fn neighbours(&self, v: usize) -> &BitSet {
        &self.adjacency[v]
    }

    pub fn degree(&self, v: usize) -> usize {
        self.adjacency[v].count()
    }

    /// True when every two members of `vertices` are adjacent.
    pub fn is_clique(&self, vertices: &[usize]) -> bool {
        vertices
            .iter()
            .enumerate()
            .all(|(k, &a)| vertices[k + 1..].iter().all(|&b| self.adjacency[a].contains(b)))
    }
}

/// The search ran out of budget.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BudgetExceeded;

/// Branch-and-bound state.
struct Search<'a> {
    graph: &'a Graph,
    best: Vec<usize>,
    current: Vec<usize>,
    nodes: u64,
    budget: u64,
}

impl Search<'_> {
    /// Greedy sequential colouring of `candidates`: returns the vertices in colour order and, for each,
    /// an upper bound (its colour number) on the size of a clique it can start among the candidates.
    fn colour_sort(&self, candidates: &BitSet) -> (Vec<usize>, Vec<usize>) {
        let mut uncoloured = candidates.clone();
        let (mut order, mut bounds) = (Vec::new(), Vec::new());
        let mut colour = 0;
        while !uncoloured.is_empty() {
            colour += 1;
            let mut available = uncoloured.clone();
            while let Some(v) = available.first() {
                available.remove(v);
                uncoloured.remove(v);
                // Vertices of one colour are pairwise non-adjacent.
                available.remove_all(self.graph.neighbours(v));
                order.push(v);
                bounds.push(colour);
            }
        }
        (order, bounds)
    }

    fn expand(&mut self, mut candidates: BitSet) -> Result<(), BudgetExceeded> {
        self.nodes += 1;
        if self.nodes > self.budget {
            return Err(BudgetExceeded);
        }
        let (order, bounds) = self.colour_sort(&candidates);
        for k in (0..order.len()).rev() {
            if self.current.len() + bounds[k] <= self.best.len() {
                return Ok(());
            }
            let v = order[k];
            self.current.push(v);
            let next = candidates.and(self.graph.neighbours(v));
            if next.is_empty() {
                if self.current.len() > self.best.len() {
                    self.best = self.current.clone();
                }
            } else {
                self.expand(next)?;
            }
            self.current.pop();
            candidates.remove(v);
        }
        Ok(())
    }
}

/// The largest clique among `candidates` that is larger than `at_least` vertices, or `None` when there
/// is none; exact within `budget` search nodes.
pub fn max_clique_within(
    graph: &Graph,
    candidates: &BitSet,
    at_least: usize,
    budget: u64,
) -> Result<Option<Vec<usize>>, BudgetExceeded> {
    // Seed the bound with `at_least` placeholder vertices so that only larger cliques are recorded.
    let mut search = Search {
        graph,
        best: vec![usize::MAX; at_least],
        current: Vec::new(),
        nodes: 0,
        budget,
    };
    search.expand(candidates.clone())?;
    let mut best = search.best;
    if best.contains(&usize::MAX) {
        return Ok(None);
    }
    best.sort_unstable();
    Ok(Some(best))
}

/// The subgraph of `graph` on `vertices`: vertex `i` of the result is `vertices[i]`.
pub fn induced(graph: &Graph, vertices: &[usize]) -> Graph {
    let mut sub = Graph::new(vertices.len());
    for (i, &a) in vertices.iter().enumerate() {
        for (j, &b) in vertices.iter().enumerate().skip(i + 1) {
            if graph.neighbours(a).contains(b) {
                sub.add_edge(i, j);
            }
        }
    }
    sub
}

/// An exact maximum clique of the whole graph within `budget` search nodes.
pub fn max_clique(graph: &Graph, budget: u64) -> Result<Vec<usize>, BudgetExceeded> {
    let mut all = BitSet::new(graph.len());
    for v in 0..graph.len() {
        all.insert(v);
    }
    // A heuristic clique tightens the bound from the start.
    let seed = heuristic_clique(graph);
    let found = max_clique_within(graph, &all, seed.len(), budget)?;
    Ok(found.unwrap_or(seed))
}

/// A large clique by greedy construction: from each of the 16 highest-degree vertices, add vertices in
/// decreasing degree order whenever they are adjacent to every member so far. O(16 n ⌈n/64⌉).
pub fn heuristic_clique(graph: &Graph) -> Vec<usize> {
    let mut order: Vec<usize> = (0..graph.len()).collect();
    order.sort_by_key(|&v| (std::cmp::Reverse(graph.degree(v)), v));
    let mut best: Vec<usize> = Vec::new();
    for &start in order.iter().take(16) {
        if graph.degree(start) < best.len() {
            break;
        }
        let clique = extend_greedily(graph, vec![start], &order);
        if clique.len() > best.len() {
            best = clique;
        }
    }
    best.sort_unstable();
    best
}

/// Extends the clique `members` with the vertices of `order` adjacent to every member so far.
pub fn extend_greedily(graph: &Graph, mut members: Vec<usize>, order: &[usize]) -> Vec<usize> {
    let mut candidates = BitSet::new(graph.len());
    for v in 0..graph.len() {
        candidates.insert(v);
    }
    for &m in &members {
        candidates = candidates.and(graph.neighbours(m));
    }
    for &u in order {
        if candidates.contains(u) {
            members.push(u);
            candidates = candidates.and(graph.neighbours(u));
        }
    }
    members
}

#[cfg(test)]
mod tests {
    use super::*;

    fn graph(n: usize, edges: &[(usize, usize)]) -> Graph {
        let mut g = Graph::new(n);
        for &(a, b) in edges {
            g.add_edge(a, b);
        }
        g
    }

    /// Every clique size by brute force over subsets.
    fn brute_force(g: &Graph) -> usize {
        let n = g.len();
        (0u32..1 << n)
            .filter_map(|mask| {
                let members: Vec<usize> = (0..n).filter(|k| mask & (1 << k) != 0).collect();
                g.is_clique(&members).then_some(members.len())
            })
            .max()
            .unwrap_or(0)
    }

    #[test]
    fn finds_known_cliques() {
        // Two triangles sharing a vertex, plus a 4-clique {5, 6, 7, 8}.
        let g = graph(
            9,
            &[
                (0, 1),
                (1, 2),
                (0, 2),
                (2, 3),
                (3, 4),
                (2, 4),
                (5, 6),
                (5, 7),
                (5, 8),
                (6, 7),
                (6, 8),
                (7, 8),
                (4, 5),
            ],
        );
        assert_eq!(max_clique(&g, 1_000_000).unwrap(), vec![5, 6, 7, 8]);
        // The complement of a perfect matching on 8 vertices: maximum clique 4 (one of each pair).
        let mut edges = Vec::new();
        for a in 0..8 {
            for b in a + 1..8 {
                if b != a + 4 {
                    edges.push((a, b));
                }
            }
        }
        assert_eq!(max_clique(&graph(8, &edges), 1_000_000).unwrap().len(), 4);
        assert!(max_clique(&Graph::new(0), 10).unwrap().is_empty());
    }

    #[test]
    fn matches_brute_force_on_random_graphs() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        for trial in 0..40 {
            let n = 6 + trial % 9;
            let mut g = Graph::new(n);
            for a in 0..n {
                for b in a + 1..n {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    if state % 100 < 55 {
                        g.add_edge(a, b);
                    }
                }
            }
            let clique = max_clique(&g, 1_000_000).unwrap();
            assert!(g.is_clique(&clique));
            assert_eq!(clique.len(), brute_force(&g), "trial {trial}");
        }
    }

    #[test]
    fn restricted_search_and_budget() {
        let g = graph(5, &[(0, 1), (1, 2), (0, 2), (3, 4)]);
        let mut candidates = BitSet::new(5);
        for v in [0, 1, 2] {
            candidates.insert(v);
        }
        assert_eq!(
            max_clique_within(&g, &candidates, 2, 1000).unwrap(),
            Some(vec![0, 1, 2])
        );
        assert_eq!(max_clique_within(&g, &candidates, 3, 1000).unwrap(), None);
        assert_eq!(max_clique_within(&g, &candidates, 0, 0), Err(BudgetExceeded));
    }
}
