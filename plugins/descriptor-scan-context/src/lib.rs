//! SKiD Scan Context descriptor (Kim and Kim, IROS 2018) with its ring-key KD-tree index.
