//! SKiD KISS-ICP-style LiDAR odometry (Vizzo et al., RA-L 2023) with keyframing.
