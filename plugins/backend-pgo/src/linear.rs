//! The sparse normal equations `H δ = −g` of a pose graph with `D`-dimensional pose blocks, solved by a
//! sparse Cholesky factorisation (faer's supernodal/simplicial `LLᵀ` with an approximate-minimum-degree
//! fill-reducing ordering, Amestoy, Davis & Duff, SIAM J. Matrix Anal. Appl. 1996).
//!
//! The block pattern of `H` (its lower triangle in compressed-column form) depends only on which poses
//! the factors link, so it and the symbolic factorisation are computed once per graph topology and
//! reused by every Levenberg-Marquardt iteration: an iteration only refills the values and runs the
//! numeric factorisation, single-threaded (`Par::Seq`, faster than two threads on small machines).

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, LltRef, SymbolicCholesky, SymmetricOrdering, factorize_symbolic_cholesky,
};
use faer::sparse::linalg::{SupernodalThreshold, amd};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMat, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};
use nalgebra::{SMatrix, SVector};

use crate::error::PgoError;

/// Where the off-diagonal block of one factor lives in the value array.
#[derive(Clone, Copy, Debug)]
pub struct OffDiagonalSlot {
    /// Block column (the smaller internal block index).
    pub column_block: usize,
    /// Position of the row block among the column's off-diagonal blocks.
    pub slot: usize,
    /// True when the factor's first pose is the row block (it has the larger internal block index).
    pub i_is_row: bool,
}

/// A block-sparse symmetric matrix pattern with its symbolic Cholesky factorisation.
pub struct BlockSystem<const D: usize> {
    blocks: usize,
    /// Internal (fill-reducing) position of each of the caller's blocks.
    internal: Vec<usize>,
    /// The lower triangle's pattern in the internal order.
    pattern: SymbolicSparseColMat<usize>,
    /// Position of every diagonal entry of `H` in the value array.
    diagonal: Vec<usize>,
    /// Number of off-diagonal blocks per block column.
    off_diagonal_counts: Vec<usize>,
    symbolic: SymbolicCholesky<usize>,
    factor_values: Vec<f64>,
    factor_scratch: MemBuffer,
    solve_scratch: MemBuffer,
    /// Right-hand sides in the internal order.
    permuted: Vec<f64>,
}

/// How the blocks are ordered for the factorisation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BlockOrdering {
    /// Approximate minimum degree on the block graph (fill-reducing).
    Amd,
    /// The caller's order.
    Natural,
}

/// The pattern of the transpose, rows sorted within each column.
fn transpose_pattern(pattern: &SymbolicSparseColMat<usize>) -> SymbolicSparseColMat<usize> {
    let n = pattern.ncols();
    let mut counts = vec![0usize; n + 1];
    for &r in pattern.row_idx() {
        counts[r + 1] += 1;
    }
    for k in 0..n {
        counts[k + 1] += counts[k];
    }
    let mut next = counts.clone();
    let mut rows = vec![0usize; pattern.row_idx().len()];
    for c in 0..n {
        for &r in pattern.row_idx_of_col_raw(c) {
            rows[next[r]] = c;
            next[r] += 1;
        }
    }
    SymbolicSparseColMat::new_checked(n, n, counts, None, rows)
}

/// An approximate-minimum-degree ordering of the block graph: the internal position of each block.
fn block_amd(blocks: usize, pairs: &[(usize, usize)]) -> Result<Vec<usize>, PgoError> {
    let mut lower: Vec<Vec<usize>> = vec![Vec::new(); blocks];
    for &(a, b) in pairs {
        if a != b {
            lower[a.min(b)].push(a.max(b));
        }
    }
    let mut col_ptr = vec![0usize];
    let mut row_idx = Vec::new();
    for (c, list) in lower.iter_mut().enumerate() {
        list.sort_unstable();
        list.dedup();
        row_idx.push(c);
        row_idx.extend(list.iter().copied());
        col_ptr.push(row_idx.len());
    }
    let pattern = SymbolicSparseColMatRef::new_checked(blocks, blocks, &col_ptr, None, &row_idx);
    let (mut forward, mut inverse) = (vec![0usize; blocks], vec![0usize; blocks]);
    let mut scratch = MemBuffer::try_new(amd::order_scratch::<usize>(blocks, row_idx.len()))
        .map_err(|_| PgoError::Solver("out of memory for the ordering".into()))?;
    amd::order(
        &mut forward,
        &mut inverse,
        pattern,
        amd::Control::default(),
        MemStack::new(&mut scratch),
    )
    .map_err(|e| PgoError::Solver(format!("ordering: {e:?}")))?;
    // `forward[new] = old`, so the internal position of block `old` is `inverse[old]`.
    Ok(inverse)
}

impl<const D: usize> BlockSystem<D> {
    /// The pattern of an `blocks × blocks` block matrix whose off-diagonal blocks are `pairs` (each
    /// unordered pair of distinct block indices; repeats are merged). Returns the system and, for each
    /// pair, where its block lives.
    pub fn new(blocks: usize, pairs: &[(usize, usize)]) -> Result<(Self, Vec<OffDiagonalSlot>), PgoError> {
        // Supernodal: the 6x6 (3x3) blocks make dense supernodes; the simplicial variant would also need
        // the matrix transposed at every factorisation.
        Self::with_ordering(
            blocks,
            pairs,
            BlockOrdering::Amd,
            SupernodalThreshold::FORCE_SUPERNODAL,
        )
    }

    /// [`BlockSystem::new`] with a chosen ordering and supernodal threshold.
    pub fn with_ordering(
        blocks: usize,
        pairs: &[(usize, usize)],
        ordering: BlockOrdering,
        supernodal: SupernodalThreshold,
    ) -> Result<(Self, Vec<OffDiagonalSlot>), PgoError> {
        let internal = match ordering {
            BlockOrdering::Amd => block_amd(blocks, pairs)?,
            BlockOrdering::Natural => (0..blocks).collect(),
        };
        // Lower triangle: block column c holds its diagonal block, then its neighbours of larger index.
        let mut neighbours: Vec<Vec<usize>> = vec![Vec::new(); blocks];
        for &(a, b) in pairs {
            let (a, b) = (internal[a], internal[b]);
            neighbours[a.min(b)].push(a.max(b));
        }
        for list in &mut neighbours {
            list.sort_unstable();
            list.dedup();
        }
        let slots = pairs
            .iter()
            .map(|&(a, b)| {
                let (a, b) = (internal[a], internal[b]);
                let (row, column) = (a.max(b), a.min(b));
                let slot = neighbours[column].binary_search(&row).unwrap_or(0);
                OffDiagonalSlot {
                    column_block: column,
                    slot,
                    i_is_row: a > b,
                }
            })
            .collect();
        let n = blocks * D;
        let mut col_ptr = Vec::with_capacity(n + 1);
        let mut row_idx = Vec::new();
        let mut internal_diagonal = Vec::with_capacity(n);
        col_ptr.push(0);
        for (c, list) in neighbours.iter().enumerate() {
            for k in 0..D {
                internal_diagonal.push(row_idx.len());
                row_idx.extend((k..D).map(|a| c * D + a));
                for &row in list {
                    row_idx.extend((0..D).map(|a| row * D + a));
                }
                col_ptr.push(row_idx.len());
            }
        }
        // Diagonal positions in the caller's (external) order.
        let diagonal = (0..n)
            .map(|k| internal_diagonal[internal[k / D] * D + k % D])
            .collect();
        let pattern = SymbolicSparseColMat::new_checked(n, n, col_ptr, None, row_idx);
        // Without a permutation faer's symbolic analysis reads the upper triangle: give it the transpose.
        let upper = transpose_pattern(&pattern);
        let params = CholeskySymbolicParams {
            supernodal_flop_ratio_threshold: supernodal,
            ..Default::default()
        };
        let symbolic =
            factorize_symbolic_cholesky(upper.as_ref(), Side::Upper, SymmetricOrdering::Identity, params)
                .map_err(|e| PgoError::Solver(format!("symbolic factorisation: {e:?}")))?;
        let factor_scratch =
            MemBuffer::try_new(symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()))
                .map_err(|_| PgoError::Solver("out of memory for the factorisation workspace".into()))?;
        let solve_scratch = MemBuffer::try_new(symbolic.solve_in_place_scratch::<f64>(1, Par::Seq))
            .map_err(|_| PgoError::Solver("out of memory for the solve workspace".into()))?;
        let off_diagonal_counts = neighbours.iter().map(Vec::len).collect();
        let factor_values = vec![0.0; symbolic.len_val()];
        let system = Self {
            blocks,
            internal,
            pattern,
            diagonal,
            off_diagonal_counts,
            symbolic,
            factor_values,
            factor_scratch,
            solve_scratch,
            permuted: Vec::new(),
        };
        Ok((system, slots))
    }

    /// Number of values of the Cholesky factor (a measure of fill-in).
    pub fn factor_len(&self) -> usize {
        self.symbolic.len_val()
    }

    /// Number of scalar unknowns.
    pub fn dimension(&self) -> usize {
        self.blocks * D
    }

    /// Number of stored values (the lower triangle of `H`).
    pub fn value_count(&self) -> usize {
        self.pattern.row_idx().len()
    }

    /// Positions of the diagonal entries of `H` in the value array.
    pub fn diagonal(&self) -> &[usize] {
        &self.diagonal
    }

    /// Adds `block` to the diagonal block `b` (only its lower triangle is stored).
    pub fn add_diagonal(&self, values: &mut [f64], b: usize, block: &SMatrix<f64, D, D>) {
        let b = self.internal[b];
        let col_ptr = self.pattern.col_ptr();
        for k in 0..D {
            let start = col_ptr[b * D + k];
            for a in k..D {
                values[start + a - k] += block[(a, k)];
            }
        }
    }

    /// Adds the block of a factor given by `slot`; `block` is `H[i, j]` of the factor, transposed here
    /// when the factor's `j` is the (larger) row block.
    pub fn add_off_diagonal(&self, values: &mut [f64], slot: &OffDiagonalSlot, block: &SMatrix<f64, D, D>) {
        let c = slot.column_block;
        let col_ptr = self.pattern.col_ptr();
        for k in 0..D {
            let start = col_ptr[c * D + k] + (D - k) + slot.slot * D;
            for a in 0..D {
                values[start + a] += if slot.i_is_row {
                    block[(a, k)]
                } else {
                    block[(k, a)]
                };
            }
        }
    }

    /// Factorises `H` (its lower triangle in `values`) and solves `H x = rhs` in place. Returns false
    /// when `H` is not numerically positive definite (the caller raises the damping).
    pub fn solve(&mut self, values: &[f64], rhs: &mut [f64]) -> Result<bool, PgoError> {
        Ok(self.factorize(values) && self.solve_factorized(rhs, 1)?)
    }

    /// Factorises `H` (its lower triangle in `values`); false when it is not numerically positive
    /// definite.
    pub fn factorize(&mut self, values: &[f64]) -> bool {
        let matrix = SparseColMatRef::new(self.pattern.as_ref(), values);
        // The only error of the numeric factorisation is a non-positive pivot.
        self.symbolic
            .factorize_numeric_llt::<f64>(
                &mut self.factor_values,
                matrix,
                Side::Lower,
                LltRegularization::default(),
                Par::Seq,
                MemStack::new(&mut self.factor_scratch),
                Default::default(),
            )
            .is_ok()
    }

    /// Solves `H X = rhs` in place with the last factorisation, for `columns` right-hand sides stored
    /// column after column. Returns false if the solution is not finite.
    pub fn solve_factorized(&mut self, rhs: &mut [f64], columns: usize) -> Result<bool, PgoError> {
        let n = self.dimension();
        if rhs.len() != n * columns {
            return Err(PgoError::Solver(format!(
                "right-hand side of {} values for {n} x {columns}",
                rhs.len()
            )));
        }
        if columns > 1 {
            self.solve_scratch =
                MemBuffer::try_new(self.symbolic.solve_in_place_scratch::<f64>(columns, Par::Seq))
                    .map_err(|_| PgoError::Solver("out of memory for the solve workspace".into()))?;
        }
        // Into the internal (fill-reducing) order, solve, and back.
        self.permuted.resize(n * columns, 0.0);
        for c in 0..columns {
            for (b, &p) in self.internal.iter().enumerate() {
                for a in 0..D {
                    self.permuted[c * n + p * D + a] = rhs[c * n + b * D + a];
                }
            }
        }
        let factor = LltRef::new(&self.symbolic, &self.factor_values);
        let rhs_matrix = MatMut::from_column_major_slice_mut(&mut self.permuted, n, columns);
        factor.solve_in_place_with_conj(
            Conj::No,
            rhs_matrix,
            Par::Seq,
            MemStack::new(&mut self.solve_scratch),
        );
        for c in 0..columns {
            for (b, &p) in self.internal.iter().enumerate() {
                for a in 0..D {
                    rhs[c * n + b * D + a] = self.permuted[c * n + p * D + a];
                }
            }
        }
        Ok(rhs.iter().all(|v| v.is_finite()))
    }

    /// Number of off-diagonal blocks (distinct linked pairs).
    pub fn off_diagonal_blocks(&self) -> usize {
        self.off_diagonal_counts.iter().sum()
    }
}

/// Adds `v` into block `b` of a flat vector.
pub fn add_block<const D: usize>(flat: &mut [f64], b: usize, v: &SVector<f64, D>) {
    for a in 0..D {
        flat[b * D + a] += v[a];
    }
}

/// Block `b` of a flat vector.
pub fn block<const D: usize>(flat: &[f64], b: usize) -> SVector<f64, D> {
    SVector::<f64, D>::from_fn(|a, _| flat[b * D + a])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solves_a_small_block_system() {
        // A chain of three 2x2 blocks: H = tridiagonal, check H x = b against a dense solve.
        let pairs = [(0, 1), (2, 1)];
        let (mut system, slots) = BlockSystem::<2>::new(3, &pairs).unwrap();
        let mut values = vec![0.0; system.value_count()];
        let diag = SMatrix::<f64, 2, 2>::new(4.0, 1.0, 1.0, 3.0);
        for b in 0..3 {
            system.add_diagonal(&mut values, b, &diag);
        }
        let off = SMatrix::<f64, 2, 2>::new(-1.0, 0.5, 0.2, -0.7);
        for slot in &slots {
            system.add_off_diagonal(&mut values, slot, &off);
        }
        let mut dense = nalgebra::DMatrix::<f64>::zeros(6, 6);
        for b in 0..3 {
            dense.view_mut((2 * b, 2 * b), (2, 2)).copy_from(&diag);
        }
        for &(i, j) in &pairs {
            dense.view_mut((2 * i, 2 * j), (2, 2)).copy_from(&off);
            dense.view_mut((2 * j, 2 * i), (2, 2)).copy_from(&off.transpose());
        }
        let b = nalgebra::DVector::from_vec(vec![1.0, -2.0, 0.5, 3.0, -1.0, 0.25]);
        let expected = dense.clone().cholesky().unwrap().solve(&b);
        let mut rhs: Vec<f64> = b.iter().copied().collect();
        assert!(system.solve(&values, &mut rhs).unwrap());
        for k in 0..6 {
            assert!((rhs[k] - expected[k]).abs() < 1e-12);
        }
        // An indefinite matrix is reported, not a panic.
        let mut bad = values.clone();
        bad[system.diagonal()[0]] = -10.0;
        assert!(!system.solve(&bad, &mut rhs).unwrap());
    }

    #[test]
    fn the_block_ordering_reduces_fill() {
        // A 30 x 30 grid: natural order fills the band, minimum degree far less.
        let side = 30;
        let mut pairs = Vec::new();
        for r in 0..side {
            for c in 0..side {
                let k = r * side + c;
                if c + 1 < side {
                    pairs.push((k, k + 1));
                }
                if r + 1 < side {
                    pairs.push((k, k + side));
                }
            }
        }
        let fill = |ordering| {
            let (system, _) = BlockSystem::<3>::with_ordering(
                side * side,
                &pairs,
                ordering,
                SupernodalThreshold::FORCE_SUPERNODAL,
            )
            .unwrap();
            system.factor_len()
        };
        let (amd, natural) = (fill(BlockOrdering::Amd), fill(BlockOrdering::Natural));
        assert!(amd * 10 < natural * 7, "AMD fill {amd} vs natural {natural}");
    }
}
