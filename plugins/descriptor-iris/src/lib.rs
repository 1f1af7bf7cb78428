//! SKiD LiDAR-Iris descriptor (Wang et al., IROS 2020) with its row-key index.
