//! SKiD in-process transport with a link model: bandwidth, latency, loss, reordering, range-dependent degradation.
