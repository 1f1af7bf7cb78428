//! SKiD SOLiD descriptor (Kim et al., RA-L 2024) with its kiddo KD-tree retrieval index.
