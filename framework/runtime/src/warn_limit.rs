//! Rate-limited warnings: a problem that repeats on every scan (a skipped scan, a late message) is
//! logged the first few times and then only at each power of ten, each line saying how many there have
//! been, so a long run's log stays readable and the full count still reaches the summary.

/// Counts occurrences of one kind of warning and says which of them to log.
#[derive(Clone, Debug)]
pub struct WarnLimiter {
    logged_in_full: u64,
    count: u64,
}

impl WarnLimiter {
    /// Logs the first `logged_in_full` occurrences, then the 10th, 100th, 1000th, ….
    pub const fn new(logged_in_full: u64) -> Self {
        Self {
            logged_in_full,
            count: 0,
        }
    }

    /// Counts one occurrence; returns its number (from 1) when it should be logged.
    pub fn occurrence(&mut self) -> Option<u64> {
        self.count += 1;
        let power_of_ten = {
            let mut n = self.count;
            while n.is_multiple_of(10) {
                n /= 10;
            }
            n == 1
        };
        (self.count <= self.logged_in_full || power_of_ten).then_some(self.count)
    }

    /// Occurrences so far.
    pub fn count(&self) -> u64 {
        self.count
    }

    /// Whether some occurrences were counted but not logged.
    pub fn suppressed_any(&self) -> bool {
        self.count > self.logged_in_full
    }
}

impl Default for WarnLimiter {
    fn default() -> Self {
        Self::new(3)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn logs_the_first_few_then_powers_of_ten() {
        let mut limiter = WarnLimiter::new(3);
        let logged: Vec<u64> = (0..2000).filter_map(|_| limiter.occurrence()).collect();
        assert_eq!(logged, vec![1, 2, 3, 10, 100, 1000]);
        assert_eq!(limiter.count(), 2000);
        assert!(limiter.suppressed_any());
    }
}
