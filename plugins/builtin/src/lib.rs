//! The built-in plugins, registered into an explicit [`Registry`] by [`register_all`] (in the manner of
//! bevy's `DefaultPlugins`). Each plugin crate sits behind a cargo feature so a lean host can leave
//! plugins out.

use skid_core::{PluginError, Registry};

/// Registers every built-in plugin enabled at compile time.
pub fn register_all(registry: &mut Registry) -> Result<(), PluginError> {
    #[cfg(feature = "source-files")]
    skid_source_files::register(registry)?;
    #[cfg(feature = "odometry-gt")]
    skid_odometry_gt::register(registry)?;
    // Keep the binding used when every feature is off.
    let _ = &registry;
    Ok(())
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
