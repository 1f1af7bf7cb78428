//! Tests of the `kiss_matcher` plugin as a whole: the coarse conformance suite on synthetic scenes, the
//! real HDL-32E pair (fast_gicp's unit-test data) yawed all around and moved 10 m, and bad input; the
//! second-best hypothesis test in [`rival`].

use nalgebra::Vector3;
use skid_core::slots::CoarseRegistration;
use skid_core::{Cloud, Params, PluginContext, Point, Pose, Registry, Slot};
use skid_testkit::pose_error;
use skid_testkit::registration::{RegistrationExpectations, check_coarse};

use super::*;
use crate::front::FpfhConfig;

mod rival;

pub(crate) fn matcher() -> KissMatcher {
    KissMatcher::new(
        KissMatcherConfig::default(),
        &PluginContext {
            threads: 2,
            ..PluginContext::default()
        },
    )
    .unwrap()
}

/// The real scan pair and the reference `target_from_source`.
pub(crate) fn real_pair() -> (Cloud, Cloud, Pose) {
    let pair = skid_io::scan_pair::read_scan_pair().unwrap();
    (
        Cloud::new(pair.target),
        Cloud::new(pair.source),
        pair.target_from_source,
    )
}

/// The conformance scene has 20,000 random surface samples over a 60 m radius (about one per m², each
/// scan sampled afresh), far sparser than a LiDAR keyframe: 0.3 m voxels leave ~18 points per 1.5 m
/// FPFH neighbourhood and single-digit true matches. KISS-Matcher's radii and bounds scale with the voxel
/// size, which is meant to follow the data's density, so the suite runs with 1 m voxels (the real-pair
/// test below runs the defaults).
fn synthetic_config() -> KissMatcherConfig {
    KissMatcherConfig {
        voxel_size_m: 1.0,
        ..KissMatcherConfig::default()
    }
}

#[test]
fn conformance() {
    let mut matcher = KissMatcher::new(
        synthetic_config(),
        &PluginContext {
            threads: 2,
            ..PluginContext::default()
        },
    )
    .unwrap();
    check_coarse(
        &mut matcher,
        &[0.0, 45.0, 180.0, 270.0],
        10.0,
        RegistrationExpectations {
            max_translation_error_m: 0.5,
            max_rotation_error_deg: 2.0,
        },
    );
}

#[test]
fn conformance_with_the_exact_max_clique() {
    let config = KissMatcherConfig {
        pruning: PruningMode::MaxClique,
        ..synthetic_config()
    };
    let mut matcher = KissMatcher::new(config, &PluginContext::default()).unwrap();
    check_coarse(
        &mut matcher,
        &[135.0],
        10.0,
        RegistrationExpectations {
            max_translation_error_m: 0.5,
            max_rotation_error_deg: 2.0,
        },
    );
    let (target, source, _) = skid_testkit::registration::synthetic_pair(
        &skid_testkit::scene::planar_pose(10.0, 0.0, 1.8, 1.0),
        20_000,
    );
    let report = matcher.align_with_report(target.view(), source.view()).unwrap();
    assert_eq!(report.clique_proven, Some(true), "{report:?}");
    assert!(report.alignment.valid);
}

#[test]
fn recovers_any_yaw_with_a_ten_metre_offset_on_the_real_pair() {
    let (target, source, truth) = real_pair();
    let mut matcher = matcher();
    for yaw_deg in [0.0f64, 90.0, 180.0, 270.0] {
        // The target is yawed and moved 10 m (in a direction that turns with the yaw, so the offset is not
        // always along one axis); the truth moves with it.
        let yaw = yaw_deg.to_radians();
        let motion = Pose::new(
            Vector3::new(10.0 * (yaw / 2.0).cos(), 10.0 * (yaw / 2.0).sin(), 0.0),
            Vector3::z() * yaw,
        );
        let moved_target = target.view().transformed(&motion);
        let report = matcher
            .align_with_report(moved_target.view(), source.view())
            .unwrap();
        let (translation_m, rotation_deg) =
            pose_error(&(motion * truth), &report.alignment.target_from_source);
        assert!(report.alignment.valid, "yaw {yaw_deg}°: {report:?}");
        assert!(
            translation_m < 0.5 && rotation_deg < 2.0,
            "yaw {yaw_deg}°: off by {translation_m:.3} m, {rotation_deg:.3}° ({report:?})"
        );
        assert!(report.alignment.inlier_count >= 5 && report.alignment.correspondence_count >= report.pruned);
    }
}

#[test]
fn featureless_and_tiny_inputs_are_invalid_with_a_reason() {
    let mut matcher = matcher();
    let plane = Cloud::new(
        (0..4000)
            .map(|i| Point::new((i % 80) as f32 * 0.25 - 10.0, (i / 80) as f32 * 0.25 - 6.0, -1.8))
            .collect(),
    );
    let empty = Cloud::default();
    let line = Cloud::new((0..500).map(|i| Point::new(i as f32 * 0.1, 2.0, 0.0)).collect());
    for (name, target, source) in [
        ("plane", &plane, &plane),
        ("empty", &empty, &plane),
        ("line", &line, &line),
        ("empty both", &empty, &empty),
    ] {
        let report = matcher.align_with_report(target.view(), source.view()).unwrap();
        assert!(!report.alignment.valid, "{name}: {report:?}");
        let reason = report.invalid_reason.clone().unwrap_or_default();
        assert!(!reason.is_empty(), "{name}: a reason is given");
        let pose = report.alignment.target_from_source;
        assert!(skid_core::pose::is_finite(&pose), "{name}");
    }
    let report = matcher.align_with_report(empty.view(), plane.view()).unwrap();
    assert!(
        report
            .invalid_reason
            .unwrap_or_default()
            .contains("target cloud: 0 points")
    );
}

#[test]
fn non_finite_points_are_an_error() {
    let mut cloud = Cloud::new((0..100).map(|i| Point::new(i as f32, 1.0, 0.0)).collect());
    cloud.points[7].y = f32::NAN;
    let error = matcher()
        .align(cloud.view(), cloud.view(), None)
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("target cloud") && error.contains("point 7"),
        "{error}"
    );
}

#[test]
fn registers_with_defaults_and_refuses_bad_parameters() {
    let mut registry = Registry::new();
    register(&mut registry).unwrap();
    assert_eq!(registry.names(Slot::Coarse), vec![PLUGIN_NAME.to_owned()]);
    let context = PluginContext::default();
    assert!(
        registry
            .coarse
            .create(PLUGIN_NAME, &Params::default(), &context)
            .is_ok()
    );
    let typo = Params::from_toml_str("voxel_size = 0.3").unwrap();
    assert!(registry.validate(Slot::Coarse, PLUGIN_NAME, &typo).is_err());
    let nested = Params::from_toml_str("[fpfh]\nratio_test = -1.0").unwrap();
    let error = registry
        .validate(Slot::Coarse, PLUGIN_NAME, &nested)
        .unwrap_err()
        .to_string();
    assert!(error.contains("fpfh.ratio_test"), "{error}");
    let mode = Params::from_toml_str("pruning = \"max_clique\"").unwrap();
    assert!(registry.validate(Slot::Coarse, PLUGIN_NAME, &mode).is_ok());
    for bad in [
        KissMatcherConfig {
            voxel_size_m: 0.0,
            ..KissMatcherConfig::default()
        },
        KissMatcherConfig {
            gnc_factor: 1.0,
            ..KissMatcherConfig::default()
        },
        KissMatcherConfig {
            fpfh: FpfhConfig {
                normal_radius_gain: 6.0,
                ..FpfhConfig::default()
            },
            ..KissMatcherConfig::default()
        },
        KissMatcherConfig {
            fpfh: FpfhConfig {
                ratio_test: f64::NAN,
                ..FpfhConfig::default()
            },
            ..KissMatcherConfig::default()
        },
    ] {
        let error = KissMatcher::new(bad, &context)
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(error.contains(PLUGIN_NAME), "{error}");
    }
}

#[test]
fn noise_bounds_scale_with_the_voxel_and_are_clamped() {
    let config = KissMatcherConfig::default();
    assert!((config.noise_bound_m(config.pruning_noise_bound_gain) - 0.3).abs() < 1e-12);
    assert!((config.noise_bound_m(config.solver_noise_bound_gain) - 0.225).abs() < 1e-12);
    let coarse = KissMatcherConfig {
        voxel_size_m: 2.0,
        ..config
    };
    assert_eq!(coarse.noise_bound_m(1.0), 1.0);
    let unclamped = KissMatcherConfig {
        max_noise_bound_m: 0.0,
        ..coarse
    };
    assert_eq!(unclamped.noise_bound_m(1.0), 2.0);
}

#[test]
fn instances_on_two_threads_agree_with_each_alone() {
    skid_testkit::threads::coarse_instances_agree_under_threads(|| Box::new(matcher()));
}
