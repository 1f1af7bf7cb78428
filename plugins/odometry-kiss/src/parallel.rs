//! Deterministic data parallelism for the odometry (KISS-ICP, Vizzo et al., RA-L 2023, runs its
//! correspondence search and reductions in parallel): work is cut into chunks of a fixed size, the
//! chunks run on the plugin's own rayon pool, and their results come back in chunk order, so any
//! reduction over them is the same, bit for bit, whatever the number of threads.

use rayon::prelude::*;
use skid_core::PluginError;

/// The plugin's thread budget: a rayon pool built once, or nothing when one thread is allowed.
pub struct Parallel {
    pool: Option<rayon::ThreadPool>,
}

impl std::fmt::Debug for Parallel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Parallel")
            .field("threads", &self.threads())
            .finish()
    }
}

impl Parallel {
    /// A pool of `threads` workers; with one thread (or zero) work runs on the caller's thread.
    pub fn new(threads: usize) -> Result<Self, PluginError> {
        if threads <= 1 {
            return Ok(Self { pool: None });
        }
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .thread_name(|index| format!("kiss-icp-{index}"))
            .build()
            .map_err(|e| {
                PluginError::failed(
                    "kiss_icp",
                    format!("cannot build a pool of {threads} threads: {e}"),
                )
            })?;
        Ok(Self { pool: Some(pool) })
    }

    pub fn threads(&self) -> usize {
        self.pool
            .as_ref()
            .map_or(1, rayon::ThreadPool::current_num_threads)
    }

    /// Applies `work` to consecutive chunks of `chunk_len` items and returns the results in order.
    pub fn map_chunks<T, R>(
        &self,
        items: &[T],
        chunk_len: usize,
        work: impl Fn(&[T]) -> R + Sync + Send,
    ) -> Vec<R>
    where
        T: Sync,
        R: Send,
    {
        let chunk_len = chunk_len.max(1);
        match &self.pool {
            Some(pool) => pool.install(|| items.par_chunks(chunk_len).map(&work).collect()),
            None => items.chunks(chunk_len).map(work).collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chunk_results_come_back_in_order_whatever_the_threads() {
        let items: Vec<f64> = (0..10_000).map(|i| (f64::from(i) * 0.37).sin()).collect();
        let sum = |parallel: &Parallel| {
            parallel
                .map_chunks(&items, 97, |c| c.iter().sum::<f64>())
                .iter()
                .sum::<f64>()
        };
        let one = sum(&Parallel::new(1).unwrap());
        let two = sum(&Parallel::new(2).unwrap());
        assert_eq!(one.to_bits(), two.to_bits());
    }
}
