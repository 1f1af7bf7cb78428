//! SKiD coarse registration: KISS-Matcher (Lim et al., ICRA 2025) with Faster-PFH, k-core pruning and GNC-TLS.
