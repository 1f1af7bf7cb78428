//! SKiD Zenoh transport for real networks: peer mode, explicit endpoints, slim features.
