//! SKiD loop verification: truncated-MSE fitness and pairwise consistency maximisation (PCM).
