//! SKiD back-end: SE(3)/SE(2) pose-graph optimisation (Levenberg-Marquardt on faer sparse Cholesky).
