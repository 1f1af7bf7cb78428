//! SKiD's Rerun view (`skid run --rerun` / `--rerun-save FILE.rrd`, built with the `rerun` feature): every
//! robot's run on one timeline, `scan_time` (the scans' stamps, seconds), streamed to a running Rerun
//! viewer over gRPC or saved as a `.rrd` recording. Entities are in [`view`]. The viewer is the user's
//! (`pip install rerun-sdk==0.36.3` or `cargo install rerun-cli --version 0.36.3`, the SDK's version);
//! SKiD never downloads it. A module of the binary rather than a crate of its own, so that building the
//! workspace never builds the SDK unless the feature asks for it.

mod view;

use anyhow::{Context, Result};
use skid_runtime::Fleet;

pub use view::RerunView;

/// The recording stream (kept alive for the run).
pub type Stream = rerun::RecordingStream;

/// Where the recording goes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum RerunTarget {
    /// A running viewer's gRPC proxy, e.g. `rerun+http://127.0.0.1:9876/proxy`.
    Viewer(String),
    /// A `.rrd` file.
    Save(std::path::PathBuf),
}

/// Opens the recording and attaches a [`RerunView`] to every robot of `fleet`. Publish every
/// `map_every` optimisations a robot's map (it is also logged at the end). The recording is flushed
/// and closed when the returned stream and the observers are dropped.
pub fn attach(fleet: &mut Fleet, target: &RerunTarget, map_every: u32) -> Result<Stream> {
    let builder = rerun::RecordingStreamBuilder::new("skid");
    let stream = match target {
        RerunTarget::Viewer(url) => builder.connect_grpc_opts(url.clone()),
        RerunTarget::Save(path) => builder.save(path),
    }
    .with_context(|| format!("opening the Rerun recording ({target:?})"))?;
    for robot in &fleet.robots {
        let view = RerunView::new(stream.clone(), robot.robot(), map_every);
        fleet.observers.attach(robot.robot(), Box::new(view));
    }
    tracing::info!(?target, robots = fleet.robots.len(), "logging the run to Rerun");
    Ok(stream)
}
