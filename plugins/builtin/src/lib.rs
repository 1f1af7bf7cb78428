//! The built-in plugins, registered into an explicit [`Registry`] by [`register_all`] (in the manner of
//! bevy's `DefaultPlugins`). Each plugin crate sits behind a cargo feature so a lean host can leave
//! plugins out.

use skid_core::{PluginError, Registry};

#[cfg(all(feature = "odometry-kiss", feature = "odometry-lio"))]
pub mod auto_odometry;

/// Registers every built-in plugin enabled at compile time.
pub fn register_all(registry: &mut Registry) -> Result<(), PluginError> {
    #[cfg(feature = "source-files")]
    skid_source_files::register(registry)?;
    #[cfg(feature = "source-sim")]
    skid_source_sim::register(registry)?;
    #[cfg(feature = "source-ros2")]
    skid_source_ros2::register(registry)?;
    #[cfg(feature = "odometry-gt")]
    skid_odometry_gt::register(registry)?;
    #[cfg(feature = "odometry-kiss")]
    skid_odometry_kiss::register(registry)?;
    #[cfg(feature = "odometry-lio")]
    skid_odometry_lio::register(registry)?;
    #[cfg(all(feature = "odometry-kiss", feature = "odometry-lio"))]
    auto_odometry::register(registry)?;
    #[cfg(feature = "descriptor-solid")]
    skid_descriptor_solid::register(registry)?;
    #[cfg(feature = "descriptor-scan-context")]
    skid_descriptor_scan_context::register(registry)?;
    #[cfg(feature = "descriptor-iris")]
    skid_descriptor_iris::register(registry)?;
    #[cfg(feature = "coarse-kiss-matcher")]
    skid_coarse_kiss_matcher::register(registry)?;
    #[cfg(feature = "coarse-ransac")]
    skid_coarse_ransac::register(registry)?;
    #[cfg(feature = "fine-gicp")]
    skid_fine_gicp::register(registry)?;
    #[cfg(feature = "verifier-pcm")]
    skid_verifier_pcm::register(registry)?;
    #[cfg(feature = "backend-pgo")]
    skid_backend_pgo::register(registry)?;
    #[cfg(feature = "transport-loopback")]
    skid_transport_loopback::register(registry)?;
    #[cfg(feature = "transport-zenoh")]
    skid_transport_zenoh::register(registry)?;
    note_left_out(registry);
    Ok(())
}

/// How a binary without the network plugins gets them: the `skid` command line builds them in with its
/// `zenoh` feature.
const WITH_ZENOH: &str =
    "build SKiD with its `zenoh` feature (`cargo build --release -p skid --features zenoh`)";

/// Notes the plugins that exist but that this build's features leave out, so selecting one says how
/// to build it in.
fn note_left_out(registry: &mut Registry) {
    #[cfg(not(feature = "transport-zenoh"))]
    registry.note_left_out(skid_core::Slot::Transport, "zenoh", WITH_ZENOH);
    #[cfg(not(feature = "source-ros2"))]
    registry.note_left_out(skid_core::Slot::Source, "ros2", WITH_ZENOH);
    // Keep the names used when every feature is on.
    let _ = (&registry, WITH_ZENOH);
}

/// A registry holding every enabled built-in plugin.
pub fn registry() -> Result<Registry, PluginError> {
    let mut registry = Registry::new();
    register_all(&mut registry)?;
    Ok(registry)
}

#[cfg(test)]
mod tests {
    use skid_core::Slot;

    #[test]
    fn every_builtin_registers_once_with_parsable_defaults() {
        let registry = super::registry().unwrap();
        for info in registry.catalogue() {
            registry.validate(info.slot, &info.name, &info.defaults).unwrap();
        }
        assert!(
            registry
                .names(Slot::Odometry)
                .contains(&"ground_truth".to_owned())
        );
        assert!(registry.names(Slot::Source).contains(&"kitti".to_owned()));
    }
}
