//! SKiD inter-robot protocol: message kinds, a versioned envelope with size limits, postcard encoding, byte counters.
