//! Which scans of a sequence a robot reads, when one sequence is split among several robots.

use serde::{Deserialize, Serialize};

/// Splitting options shared by the file sources.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct SplitConfig {
    /// Split the sequence into one consecutive segment per robot.
    pub enabled: bool,
    /// Scans of the previous segment a robot also reads, so neighbouring robots overlap.
    pub overlap_scans: usize,
}

/// The half-open range of scan indices robot `robot` of `robots` reads out of `total` scans.
pub fn segment(total: usize, robot: usize, robots: usize, split: &SplitConfig) -> std::ops::Range<usize> {
    if !split.enabled || robots <= 1 {
        return 0..total;
    }
    let length = total.div_ceil(robots);
    let start = (robot * length).min(total);
    let end = ((robot + 1) * length).min(total);
    start.saturating_sub(split.overlap_scans)..end
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn segments_cover_the_sequence_with_overlap() {
        let split = SplitConfig {
            enabled: true,
            overlap_scans: 2,
        };
        assert_eq!(segment(10, 0, 3, &split), 0..4);
        assert_eq!(segment(10, 1, 3, &split), 2..8);
        assert_eq!(segment(10, 2, 3, &split), 6..10);
        assert_eq!(segment(10, 1, 1, &split), 0..10);
        assert_eq!(segment(10, 1, 3, &SplitConfig::default()), 0..10);
    }

    #[test]
    fn more_robots_than_scans_gives_empty_tails() {
        let split = SplitConfig {
            enabled: true,
            overlap_scans: 0,
        };
        assert_eq!(segment(2, 3, 4, &split), 2..2);
    }
}
