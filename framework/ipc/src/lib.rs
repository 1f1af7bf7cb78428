//! SKiD zero-copy local IPC over iceoryx2: typed keyframe, descriptor and graph-update ports.
