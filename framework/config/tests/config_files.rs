//! The configuration layers against real files: the repository's `configs/` and the deliberately broken
//! files in `tests/bad/`. Every error must name the file (or layer), the full key path and what was
//! expected.

#![allow(clippy::unwrap_used, clippy::expect_used)] // Test helpers fail loudly by design.

use std::path::PathBuf;

use skid_config::{ConfigError, ConfigSources};
use skid_core::{Registry, Slot};

fn registry() -> Registry {
    skid_builtin::registry().unwrap()
}

fn repo_configs() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../configs")
}

fn bad(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/bad")
        .join(name)
}

fn sources() -> ConfigSources {
    ConfigSources {
        config_dir: Some(repo_configs()),
        ..ConfigSources::default()
    }
}

fn load_with_overlay(name: &str) -> Result<skid_config::ResolvedConfig, ConfigError> {
    ConfigSources {
        overlays: vec![bad(name)],
        ..sources()
    }
    .load(&registry())
}

#[test]
fn default_profile_loads_and_fills_plugin_defaults() {
    let config = sources().load(&registry()).unwrap();
    assert_eq!(config.slot(Slot::Source).plugin, "sim");
    assert_eq!(config.slot(Slot::Odometry).plugin, "auto");
    // `auto` carries both candidates' complete parameters.
    let params = config.slot(Slot::Odometry).params.table();
    assert!(params["kiss_icp"].as_table().unwrap().contains_key("keyframe"));
    assert!(params["lio"].as_table().unwrap().contains_key("map_voxel_m"));
    let shown = config.to_toml_string();
    assert!(shown.contains("[odometry.kiss_icp.keyframe]"), "{shown}");
    assert!(shown.contains("[odometry.lio]"), "{shown}");
    assert!(shown.contains("robots = 3"), "{shown}");
}

#[test]
fn embedded_default_equals_the_file() {
    let from_file = sources().load(&registry()).unwrap();
    let embedded = ConfigSources::default().load(&registry()).unwrap();
    assert_eq!(from_file, embedded);
}

#[test]
fn every_profile_in_the_repository_validates() {
    let profiles = sources().available_profiles();
    for profile in profiles {
        let config = ConfigSources {
            profile: Some(profile.clone()),
            ..sources()
        }
        .load(&registry());
        assert!(
            config.is_ok(),
            "profile {profile}: {}",
            config.err().map(|e| e.to_string()).unwrap_or_default()
        );
    }
}

fn assert_invalid(error: ConfigError, file: &str, key: &str, expected: &[&str]) {
    let text = error.to_string();
    match &error {
        ConfigError::Invalid { origin, key: got, .. } => {
            assert!(
                origin.ends_with(file),
                "origin `{origin}` should name {file}: {text}"
            );
            assert_eq!(got, key, "{text}");
        }
        other => panic!("expected an invalid-key error, got {other:?}"),
    }
    for word in expected {
        assert!(text.contains(word), "`{text}` should mention `{word}`");
    }
}

#[test]
fn typo_in_plugin_key_names_file_key_and_expected_keys() {
    let error = load_with_overlay("typo_key.toml").unwrap_err();
    assert_invalid(
        error,
        "typo_key.toml",
        "odometry.ground_truth.translation_noize_m",
        &["translation_noise_m", "rotation_noise_deg"],
    );
}

#[test]
fn wrong_type_names_the_nested_key_and_the_expected_type() {
    let error = load_with_overlay("wrong_type.toml").unwrap_err();
    assert_invalid(
        error,
        "wrong_type.toml",
        "odometry.ground_truth.keyframe.distance_m",
        &["f64"],
    );
}

#[test]
fn unknown_plugin_lists_the_known_ones() {
    let error = load_with_overlay("unknown_plugin.toml").unwrap_err();
    assert_invalid(
        error,
        "unknown_plugin.toml",
        "odometry.plugin",
        &["kiss_icq", "ground_truth", "none"],
    );
}

#[test]
fn an_unknown_choice_lists_the_choices_once_quoted() {
    let error = ConfigSources {
        sets: vec!["deploy.mode=process".to_owned()],
        ..sources()
    }
    .load(&registry())
    .unwrap_err();
    assert_invalid(
        error,
        "--set deploy.mode=process",
        "deploy.mode",
        &["unknown value `process`; expected one of: `lockstep`, `threads`, `processes`"],
    );
}

#[test]
fn a_plugin_this_build_leaves_out_says_how_to_build_it_in() {
    let mut registry = registry();
    registry.note_left_out(
        Slot::Transport,
        "carrier_pigeon",
        "build with the `pigeon` feature",
    );
    let with = |sets: &[&str]| ConfigSources {
        sets: sets.iter().map(|set| (*set).to_owned()).collect(),
        ..sources()
    };
    let error = with(&["transport.plugin=carrier_pigeon"])
        .load(&registry)
        .unwrap_err();
    assert_invalid(
        error,
        "--set transport.plugin=carrier_pigeon",
        "transport.plugin",
        &["`carrier_pigeon` is not in this build", "the `pigeon` feature"],
    );
    // Its parameters, kept in a file shared with builds that have it, do not stop this one.
    with(&["transport.carrier_pigeon.birds=3"])
        .load(&registry)
        .unwrap();
}

#[test]
fn unknown_section_lists_the_expected_sections() {
    let error = load_with_overlay("unknown_section.toml").unwrap_err();
    assert_invalid(error, "unknown_section.toml", "runn", &["run", "descriptor"]);
}

#[test]
fn parameters_for_a_plugin_of_another_name_are_refused() {
    let error = load_with_overlay("unknown_plugin_table.toml").unwrap_err();
    assert_invalid(
        error,
        "unknown_plugin_table.toml",
        "odometry.ground_truht",
        &["ground_truth"],
    );
}

#[test]
fn robot_count_out_of_range() {
    let error = load_with_overlay("robots_out_of_range.toml").unwrap_err();
    assert_invalid(error, "robots_out_of_range.toml", "run.robots", &["1 to 16"]);
}

#[test]
fn source_cannot_be_none() {
    let error = load_with_overlay("source_none.toml").unwrap_err();
    assert_invalid(error, "source_none.toml", "source.plugin", &["kitti"]);
}

#[test]
fn syntax_error_names_file_and_line() {
    let error = load_with_overlay("syntax.toml").unwrap_err();
    let text = error.to_string();
    assert!(matches!(error, ConfigError::Syntax { .. }), "{text}");
    assert!(text.contains("syntax.toml") && text.contains("line 3"), "{text}");
}

#[test]
fn missing_file_and_unknown_profile_are_errors() {
    let error = load_with_overlay("does_not_exist.toml").unwrap_err();
    assert!(matches!(error, ConfigError::MissingFile { .. }));
    assert!(error.to_string().contains("does_not_exist.toml"));
    let error = ConfigSources {
        profile: Some("nope".into()),
        ..sources()
    }
    .load(&registry())
    .unwrap_err();
    assert!(matches!(error, ConfigError::UnknownProfile { .. }), "{error}");
}

#[test]
fn set_overrides_win_and_errors_name_the_argument() {
    let sets = vec![
        "odometry.plugin=ground_truth".to_owned(),
        "odometry.ground_truth.scale_drift_percent=2.5".to_owned(),
        "run.name=trial".to_owned(),
    ];
    let config = ConfigSources { sets, ..sources() }.load(&registry()).unwrap();
    assert_eq!(config.run.name, "trial");
    let drift = config.slot(Slot::Odometry).params.table()["scale_drift_percent"].as_float();
    assert_eq!(drift, Some(2.5));

    let sets = vec!["odometry.ground_truth.scale_drift_percent=lots".to_owned()];
    let error = ConfigSources { sets, ..sources() }.load(&registry()).unwrap_err();
    assert_invalid(
        error,
        "--set odometry.ground_truth.scale_drift_percent=lots",
        "odometry.ground_truth.scale_drift_percent",
        &["f64"],
    );

    let error = ConfigSources {
        sets: vec!["novalue".into()],
        ..sources()
    }
    .load(&registry())
    .unwrap_err();
    assert!(matches!(error, ConfigError::BadSetArgument { .. }), "{error}");
}

#[test]
fn a_deploy_robot_outside_the_fleet_names_the_key_and_its_layer() {
    let sets = vec!["run.robots=3".to_owned(), "deploy.robot=3".to_owned()];
    let error = ConfigSources { sets, ..sources() }.load(&registry()).unwrap_err();
    assert_invalid(
        error,
        "--set deploy.robot=3",
        "deploy.robot",
        &["expected 0 to 2"],
    );
    let sets = vec!["deploy.robot=2".to_owned()];
    let config = ConfigSources { sets, ..sources() }.load(&registry()).unwrap();
    assert_eq!(config.deploy.robot, Some(2));
}

#[test]
fn a_negative_robot_count_names_the_range() {
    let sets = vec!["run.robots=-3".to_owned()];
    let error = ConfigSources { sets, ..sources() }.load(&registry()).unwrap_err();
    assert_invalid(error, "--set run.robots=-3", "run.robots", &["1 to 16"]);
}

#[test]
fn switching_plugins_does_not_inherit_the_old_plugin_keys() {
    // The overlay selects `none`, so the default's ground_truth table stays valid but unused.
    let sets = vec!["odometry.plugin=none".to_owned()];
    let config = ConfigSources { sets, ..sources() }.load(&registry()).unwrap();
    assert!(config.slot(Slot::Odometry).is_none());
    assert!(config.slot(Slot::Odometry).params.table().is_empty());
}

#[test]
fn an_out_of_range_value_in_a_file_names_the_file_and_the_key_once() {
    let error = load_with_overlay("out_of_range.toml").unwrap_err();
    let text = error.to_string();
    assert_invalid(
        error,
        "out_of_range.toml",
        "odometry.kiss_icp.voxel_size_m",
        &["-1", "positive"],
    );
    // The reason is said once, without the plugin repeating it.
    assert_eq!(text.matches("positive").count(), 1, "{text}");
}

/// Values of the right type that no plugin can use, from `--set`, each refused at load time with the key
/// it was given under (the ranges every plugin's `check` enforces).
#[test]
fn out_of_range_values_are_refused_at_load_time_naming_the_key() {
    let cases: &[(&str, &str)] = &[
        (
            "odometry.kiss_icp.voxel_size_m=0",
            "odometry.kiss_icp.voxel_size_m",
        ),
        (
            "odometry.kiss_icp.voxel_size_m=nan",
            "odometry.kiss_icp.voxel_size_m",
        ),
        (
            "odometry.kiss_icp.max_range_m=inf",
            "odometry.kiss_icp.max_range_m",
        ),
        (
            "odometry.kiss_icp.keyframe.distance_m=-2",
            "odometry.kiss_icp.keyframe.distance_m",
        ),
        (
            "odometry.ground_truth.translation_noise_m=-0.1",
            "odometry.ground_truth.translation_noise_m",
        ),
        (
            "descriptor.solid.num_range_bins=0",
            "descriptor.solid.num_range_bins",
        ),
        (
            "descriptor.scan_context.num_rings=0",
            "descriptor.scan_context.num_rings",
        ),
        (
            "coarse.kiss_matcher.voxel_size_m=-0.3",
            "coarse.kiss_matcher.voxel_size_m",
        ),
        ("coarse.ransac.voxel_size_m=0", "coarse.ransac.voxel_size_m"),
        ("loops.inter_robot_budget=0", "loops.inter_robot_budget"),
        ("loops.candidate_queue=0", "loops.candidate_queue"),
        ("loops.budget_period_s=0", "loops.budget_period_s"),
        ("loops.candidate_expiry_s=nan", "loops.candidate_expiry_s"),
        ("loops.cloud_grid_m=2", "loops.cloud_grid_m"),
        ("loops.cloud_resend_after_s=-1", "loops.cloud_resend_after_s"),
        ("loops.loop_sigma_rotation_deg=0", "loops.loop_sigma_rotation_deg"),
        (
            "loops.backend_loop_sigma_rotation_deg=-0.25",
            "loops.backend_loop_sigma_rotation_deg",
        ),
        (
            "fine.gicp.max_correspondence_m=0",
            "fine.gicp.max_correspondence_m",
        ),
        (
            "verifier.pcm.fitness.min_overlap=1.5",
            "verifier.pcm.fitness.min_overlap",
        ),
        (
            "verifier.pcm.free_space.max_clustered_fraction=-0.1",
            "verifier.pcm.free_space.max_clustered_fraction",
        ),
        (
            "verifier.pcm.odometry.max_drift_fraction=0",
            "verifier.pcm.odometry.max_drift_fraction",
        ),
        (
            "verifier.pcm.peer_seen.max_through_fraction=2",
            "verifier.pcm.peer_seen.max_through_fraction",
        ),
        (
            "verifier.pcm.consistency.consistency_probability=2",
            "verifier.pcm.consistency.consistency_probability",
        ),
        (
            "backend.pgo.inlier_probability=2",
            "backend.pgo.inlier_probability",
        ),
        ("transport.loopback.link.loss=1.5", "transport.loopback.link.loss"),
        ("source.sim.world=mars", "source.sim.world"),
        ("source.sim.speed_mps=-1", "source.sim.speed_mps"),
        ("source.sim.mission=orbit", "source.sim.mission"),
        ("source.sim.keep_right_m=9", "source.sim.keep_right_m"),
        ("output.ros2_domain_id=300", "output.ros2_domain_id"),
        ("output.ros2_voxel_m=0", "output.ros2_voxel_m"),
        ("output.ros2_connect=[\"nowhere\"]", "output.ros2_connect"),
    ];
    for (set, key) in cases {
        let error = ConfigSources {
            sets: vec![(*set).to_owned()],
            ..sources()
        }
        .load(&registry())
        .expect_err(set);
        assert_invalid(error, &format!("--set {set}"), key, &[]);
    }
}

#[test]
fn profiles_are_embedded_and_match_the_files() {
    let folder = repo_configs().join("profiles");
    let mut on_disk = skid_config::profile_names_in(&folder);
    on_disk.sort();
    let embedded: Vec<String> = skid_config::EMBEDDED_PROFILES
        .iter()
        .map(|(name, _)| (*name).to_owned())
        .collect();
    assert_eq!(on_disk, embedded, "add new profiles to EMBEDDED_PROFILES");
    for (name, text) in skid_config::EMBEDDED_PROFILES {
        let file = std::fs::read_to_string(folder.join(format!("{name}.toml"))).unwrap();
        assert_eq!(&file, text, "{name}");
        // Without a configuration folder (outside a checkout) the embedded copy is used.
        let outside = ConfigSources {
            profile: Some((*name).to_owned()),
            ..ConfigSources::default()
        }
        .load(&registry())
        .unwrap();
        let inside = ConfigSources {
            profile: Some((*name).to_owned()),
            ..sources()
        }
        .load(&registry())
        .unwrap();
        assert_eq!(outside, inside, "{name}");
    }
    let error = ConfigSources {
        profile: Some("nope".into()),
        ..ConfigSources::default()
    }
    .load(&registry())
    .unwrap_err()
    .to_string();
    assert!(
        error.contains("kitti") && error.contains("scan_context"),
        "{error}"
    );
}

#[test]
fn the_fleet_size_has_one_key() {
    // `run.robots` is the fleet size; the simulator has no key of its own to disagree with it.
    let error = ConfigSources {
        sets: vec!["source.sim.robots=2".to_owned()],
        ..sources()
    }
    .load(&registry())
    .unwrap_err();
    assert_invalid(
        error,
        "--set source.sim.robots=2",
        "source.sim.robots",
        &["unknown field `robots`"],
    );
}

#[test]
fn auto_odometry_takes_each_candidates_own_table_and_refuses_one_of_its_own() {
    let sets = vec![
        "odometry.kiss_icp.deskew=false".to_owned(),
        "odometry.lio.map_voxel_m=0.8".to_owned(),
    ];
    let config = ConfigSources { sets, ..sources() }.load(&registry()).unwrap();
    let params = config.slot(Slot::Odometry).params.table().clone();
    assert_eq!(params["kiss_icp"]["deskew"].as_bool(), Some(false));
    assert_eq!(params["lio"]["map_voxel_m"].as_float(), Some(0.8));
    // Unset keys keep the candidate's defaults.
    assert_eq!(params["kiss_icp"]["voxel_size_m"].as_float(), Some(1.0));
    // What `config show` prints loads back to the same configuration.
    let dir = tempfile::tempdir().unwrap();
    let shown = dir.path().join("shown.toml");
    std::fs::write(&shown, config.to_toml_string()).unwrap();
    let again = ConfigSources {
        overlays: vec![shown],
        ..sources()
    }
    .load(&registry())
    .unwrap();
    assert_eq!(again.slot(Slot::Odometry), config.slot(Slot::Odometry));

    let sets = vec!["odometry.auto.lio.map_voxel_m=0.8".to_owned()];
    let error = ConfigSources { sets, ..sources() }.load(&registry()).unwrap_err();
    assert_invalid(
        error,
        "--set odometry.auto.lio.map_voxel_m=0.8",
        "odometry.auto",
        &["odometry.kiss_icp", "odometry.lio"],
    );
    // A bad value in a candidate's table is named with that table's key.
    let sets = vec!["odometry.lio.map_voxel_m=-1".to_owned()];
    let error = ConfigSources { sets, ..sources() }.load(&registry()).unwrap_err();
    assert_invalid(
        error,
        "--set odometry.lio.map_voxel_m=-1",
        "odometry.lio.map_voxel_m",
        &["outside"],
    );
}
