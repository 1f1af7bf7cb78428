//! SKiD fine registration in the manner of small_gicp: GICP, VGICP, point-to-point and point-to-plane ICP.
