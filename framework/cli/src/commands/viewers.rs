//! What watches a run while it happens, attached to the fleet before it starts: the live ROS 2 output
//! (`output.ros2`, built with the `zenoh` feature) and the Rerun view (`--rerun`, `--rerun-save`, built
//! with the `rerun` feature). What `attach` returns keeps their sessions open until the run's end.

use std::path::PathBuf;

use anyhow::Result;

/// The viewers the command line asked for.
#[derive(Clone, Debug, Default)]
pub struct Viewers {
    /// Stream to a running Rerun viewer at this URL.
    pub rerun_url: Option<String>,
    /// Save a Rerun recording here.
    pub rerun_save: Option<PathBuf>,
}

/// Sessions to keep alive for the run.
pub struct Attached {
    #[cfg(feature = "zenoh")]
    _ros2: Option<skid_ros2_live::SharedSession>,
    #[cfg(feature = "rerun")]
    _rerun: Option<rerun_stream::Stream>,
}

impl Viewers {
    /// Attaches the asked-for viewers (and the configuration's live ROS 2 output) to `fleet`.
    pub fn attach(&self, fleet: &mut skid_runtime::Fleet) -> Result<Attached> {
        #[cfg(feature = "zenoh")]
        let ros2 = live_ros2(fleet)?;
        #[cfg(not(feature = "zenoh"))]
        refuse_live_ros2(fleet)?;
        #[cfg(feature = "rerun")]
        let rerun = rerun_stream::attach(self, fleet)?;
        #[cfg(not(feature = "rerun"))]
        if self.rerun_url.is_some() || self.rerun_save.is_some() {
            anyhow::bail!(
                "this skid was built without Rerun: build it with `cargo build --release -p skid --features rerun` (the viewer itself: `pip install rerun-sdk==0.36.3`)"
            );
        }
        Ok(Attached {
            #[cfg(feature = "zenoh")]
            _ros2: ros2,
            #[cfg(feature = "rerun")]
            _rerun: rerun,
        })
    }
}

/// Without the `zenoh` feature, `output.ros2` is refused with how to build it in.
#[cfg(not(feature = "zenoh"))]
fn refuse_live_ros2(fleet: &skid_runtime::Fleet) -> Result<()> {
    if fleet.config.output.ros2 {
        anyhow::bail!(
            "output.ros2 = true: this skid was built without zenoh, which the live ROS 2 output speaks; \
             build it with `cargo build --release -p skid --features zenoh`"
        );
    }
    Ok(())
}

/// With `output.ros2`, publishes every robot of `fleet` live as ROS 2 topics over zenoh.
#[cfg(feature = "zenoh")]
fn live_ros2(fleet: &mut skid_runtime::Fleet) -> Result<Option<skid_ros2_live::SharedSession>> {
    let output = &fleet.config.output;
    if !output.ros2 {
        return Ok(None);
    }
    let settings = skid_ros2_live::LiveSettings {
        connect: output.ros2_connect.clone(),
        listen: output.ros2_listen.clone(),
        domain_id: output.ros2_domain_id,
        map_every: output.ros2_map_every,
        voxel_m: output.ros2_voxel_m,
        prior: fleet.config.prior.path.is_some(),
    };
    Ok(Some(skid_ros2_live::attach(fleet, &settings)?))
}

#[cfg(feature = "rerun")]
mod rerun_stream {
    use crate::rerun_view::RerunTarget;
    use anyhow::Result;

    pub type Stream = crate::rerun_view::Stream;

    pub fn attach(viewers: &super::Viewers, fleet: &mut skid_runtime::Fleet) -> Result<Option<Stream>> {
        let target = match (&viewers.rerun_url, &viewers.rerun_save) {
            (Some(url), _) => RerunTarget::Viewer(url.clone()),
            (None, Some(path)) => RerunTarget::Save(path.clone()),
            (None, None) => return Ok(None),
        };
        let map_every = fleet.config.output.ros2_map_every;
        Ok(Some(crate::rerun_view::attach(fleet, &target, map_every)?))
    }
}
