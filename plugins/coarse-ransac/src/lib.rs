//! SKiD coarse registration baseline: FPFH features with RANSAC.
