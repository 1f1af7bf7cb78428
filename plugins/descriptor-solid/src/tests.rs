//! Tests of the `solid` plugin: SOLiD (Kim et al., RA-L 2024) values pinned on a cloud computed by hand,
//! the documented edge cases, the quantised encodings and the descriptor conformance suite.

use skid_core::slots::{Descriptor, DescriptorBuf};
use skid_core::{Cloud, KeyframeId, Params, PluginContext, Point, Registry};
use skid_testkit::descriptor::{DescriptorExpectations, angle_difference_deg, check_descriptor};

use super::*;

/// 4 range bins of 2 m, 4 azimuth bins of 90°, 3 elevation bins of 8° over [−12°, 12°], no voxels.
fn small_config() -> SolidConfig {
    SolidConfig {
        num_range_bins: 4,
        num_azimuth_bins: 4,
        num_elevation_bins: 3,
        min_range_m: 1.0,
        max_range_m: 8.0,
        lower_fov_deg: -12.0,
        upper_fov_deg: 12.0,
        voxel_size_m: 0.0,
        ..SolidConfig::default()
    }
}

/// Eight points whose bins are easy to work out by hand, and four that must be dropped.
fn small_cloud() -> Cloud {
    Cloud::new(vec![
        Point::new(3.0, 0.5, 0.1),   // r 3.04 → range 1; az 9.5° → 0; el 1.9° → 1
        Point::new(0.5, 5.0, -0.3),  // r 5.02 → 2; az 84.3° → 0; el −3.4° → 1
        Point::new(-5.0, 1.0, -0.2), // r 5.10 → 2; az 168.7° → 1; el −2.2° → 1
        Point::new(-1.0, -7.0, 0.7), // r 7.07 → 3; az 261.9° → 2; el 5.7° → 2
        Point::new(6.0, -0.5, 0.2),  // r 6.02 → 3; az 355.2° → 3; el 1.9° → 1
        Point::new(3.0, -3.0, -0.1), // r 4.24 → 2; az 315° → 3; el −1.4° → 1
        Point::new(0.3, -3.5, 0.3),  // r 3.51 → 1; az 274.9° → 3; el 4.9° → 2
        Point::new(4.0, 1.0, -0.6),  // r 4.12 → 2; az 14.0° → 0; el −8.3° → 0
        Point::new(3.0, 0.0, -2.0),  // el −33.7°: below the FOV
        Point::new(2.0, 2.0, 1.0),   // el 19.5°: above the FOV
        Point::new(0.5, 0.2, 0.0),   // r 0.54 < 1 m
        Point::new(9.0, 0.0, 0.0),   // r 9 > 8 m
    ])
}

#[test]
fn values_computed_by_hand() {
    let solid = SolidDescriptor::new(small_config()).unwrap();
    let parts = solid.parts(small_cloud().view()).unwrap();
    assert_eq!(
        (
            parts.points_used,
            parts.points_out_of_range,
            parts.points_outside_fov
        ),
        (8, 2, 2)
    );
    #[rustfmt::skip]
    let rec = vec![
        0, 0, 0,
        0, 1, 1,
        1, 3, 0,
        0, 1, 1,
    ];
    assert_eq!(parts.range_elevation_counts, rec);
    #[rustfmt::skip]
    let aec = vec![
        1, 2, 0,
        0, 1, 0,
        0, 0, 1,
        0, 2, 1,
    ];
    assert_eq!(parts.azimuth_elevation_counts, aec);
    // Points per elevation bin 1, 5, 2; min-max normalised.
    assert_eq!(parts.elevation_weights, vec![0.0, 1.0, 0.25]);
    assert_eq!(parts.r_solid, vec![0.0, 1.25, 3.0, 1.25]);
    assert_eq!(parts.a_solid, vec![2.0, 1.0, 0.25, 2.25]);
    let buf = SolidDescriptor::new(small_config())
        .unwrap()
        .describe(small_cloud().view())
        .unwrap();
    assert_eq!(buf.values, vec![0.0, 1.25, 3.0, 1.25, 2.0, 1.0, 0.25, 2.25]);
    assert_eq!(buf.kind, "solid");
}

#[test]
fn equal_elevation_counts_give_uniform_weights_not_nan() {
    // Two points in each of the three elevation bins: min-max normalisation would divide by zero.
    let cloud = Cloud::new(vec![
        Point::new(3.0, 0.5, -0.6),
        Point::new(5.0, 0.5, -0.8),
        Point::new(3.0, 0.5, 0.0),
        Point::new(5.0, -0.5, 0.0),
        Point::new(3.0, 0.5, 0.5),
        Point::new(-5.0, 0.5, 0.6),
    ]);
    let parts = SolidDescriptor::new(small_config())
        .unwrap()
        .parts(cloud.view())
        .unwrap();
    assert_eq!(parts.elevation_weights, vec![1.0, 1.0, 1.0]);
    assert_eq!(parts.r_solid, vec![0.0, 3.0, 3.0, 0.0]);
}

#[test]
fn degenerate_clouds() {
    let mut solid = SolidDescriptor::new(SolidConfig::default()).unwrap();
    let error = solid.describe(Cloud::default().view()).unwrap_err().to_string();
    assert!(error.contains("no point of 0"), "{error}");
    // Everything below the lower FOV edge: dropped and said so, not wrapped or clamped into a bin.
    let below = Cloud::new(
        (0..200)
            .map(|i| Point::new((i as f32).cos() * 20.0, (i as f32).sin() * 20.0, -60.0))
            .collect(),
    );
    let error = solid.describe(below.view()).unwrap_err().to_string();
    assert!(
        error.contains("200 outside the FOV") || error.contains("outside the FOV"),
        "{error}"
    );
    let parts = SolidDescriptor::new(SolidConfig {
        voxel_size_m: 0.0,
        ..SolidConfig::default()
    })
    .unwrap()
    .parts(below.view())
    .unwrap();
    assert_eq!((parts.points_used, parts.points_outside_fov), (0, 200));
    // Every point at one range: one range bin, finite values.
    let one_range = Cloud::new(vec![Point::new(10.0, 0.0, 0.0); 500]);
    let buf = solid.describe(one_range.view()).unwrap();
    assert!(buf.values.iter().all(|v| v.is_finite()));
    assert!(
        buf.values[..40]
            .iter()
            .enumerate()
            .all(|(i, &v)| (v > 0.0) == (i == 5)),
        "{:?}",
        &buf.values[..40]
    );
    let mut index = solid.new_index();
    index.insert(KeyframeId::new(0, 0), buf.clone()).unwrap();
    let found = index.query(&buf, 1, &|_| false).unwrap();
    assert_eq!(found[0].distance, 0.0);
    // A non-finite point is refused with its position.
    let bad = Cloud::new(vec![Point::new(5.0, 0.0, 0.0), Point::new(f32::NAN, 0.0, 0.0)]);
    assert!(
        solid
            .describe(bad.view())
            .unwrap_err()
            .to_string()
            .contains("point 1")
    );
}

#[test]
fn index_refuses_foreign_and_malformed_descriptors() {
    let solid = SolidDescriptor::new(SolidConfig::default()).unwrap();
    let mut index = solid.new_index();
    let foreign = DescriptorBuf {
        kind: "scan_context".into(),
        values: vec![1.0; 100],
    };
    assert!(index.insert(KeyframeId::new(0, 0), foreign).is_err());
    let short = DescriptorBuf {
        kind: "solid".into(),
        values: vec![1.0; 99],
    };
    assert!(index.insert(KeyframeId::new(0, 0), short).is_err());
    let zero = DescriptorBuf {
        kind: "solid".into(),
        values: vec![0.0; 100],
    };
    assert!(
        index
            .insert(KeyframeId::new(0, 0), zero)
            .unwrap_err()
            .to_string()
            .contains("all zero")
    );
    let nan = DescriptorBuf {
        kind: "solid".into(),
        values: vec![f32::NAN; 100],
    };
    assert!(index.insert(KeyframeId::new(0, 0), nan).is_err());
    assert!(index.is_empty());
}

#[test]
fn config_checks() {
    let swapped = SolidConfig {
        lower_fov_deg: 2.0,
        upper_fov_deg: -24.8,
        ..SolidConfig::default()
    };
    assert!(
        SolidDescriptor::new(swapped)
            .err()
            .unwrap()
            .to_string()
            .contains("signs")
    );
    assert!(
        SolidDescriptor::new(SolidConfig {
            num_elevation_bins: 0,
            ..SolidConfig::default()
        })
        .is_err()
    );
    assert!(
        SolidDescriptor::new(SolidConfig {
            num_range_bins: 129,
            ..SolidConfig::default()
        })
        .is_err()
    );
    assert!(
        SolidDescriptor::new(SolidConfig {
            min_range_m: 90.0,
            ..SolidConfig::default()
        })
        .is_err()
    );
    assert!(
        SolidDescriptor::new(SolidConfig {
            voxel_size_m: f64::NAN,
            ..SolidConfig::default()
        })
        .is_err()
    );
    assert_eq!(SolidConfig::default().wire_size_bytes(), 400);
    assert_eq!(
        SolidConfig {
            quantization: Quantization::U8,
            ..SolidConfig::default()
        }
        .wire_size_bytes(),
        108
    );
}

#[test]
fn registers_with_defaults_and_validates_parameters() {
    let mut registry = Registry::new();
    register(&mut registry).unwrap();
    assert_eq!(registry.names(skid_core::Slot::Descriptor), vec!["solid"]);
    let context = PluginContext::default();
    let made = registry
        .descriptor
        .create("solid", &Params::default(), &context)
        .unwrap();
    assert_eq!(made.kind(), "solid");
    let typo = Params::from_toml_str("num_sectorz = 3").unwrap();
    assert!(
        registry
            .validate(skid_core::Slot::Descriptor, "solid", &typo)
            .is_err()
    );
    let quantized = Params::from_toml_str("quantization = \"u16\"\nnum_elevation_bins = 64").unwrap();
    assert!(registry.descriptor.create("solid", &quantized, &context).is_ok());
}

/// The hint must be right to half a sector when the yaw is a whole number of sectors, which the
/// conformance suite's one-sector tolerance cannot tell from the public C++ off-by-one.
#[test]
fn yaw_hint_has_no_off_by_one() {
    let scene = skid_testkit::scene::Scene::new(3, 120.0);
    let here = scene.sample(
        &skid_testkit::scene::planar_pose(0.0, 0.0, 1.8, 0.0),
        30_000,
        80.0,
        5,
    );
    let mut solid = SolidDescriptor::new(SolidConfig::default()).unwrap();
    let mut index = solid.new_index();
    index
        .insert(KeyframeId::new(1, 0), solid.describe(here.view()).unwrap())
        .unwrap();
    for yaw_deg in [30.0f64, 90.0, 150.0, 180.0, 270.0] {
        let rotation =
            nalgebra::Rotation3::from_axis_angle(&nalgebra::Vector3::z_axis(), yaw_deg.to_radians());
        let turned = Cloud::new(
            here.points
                .iter()
                .map(|p| {
                    let q = rotation * nalgebra::Point3::new(f64::from(p.x), f64::from(p.y), f64::from(p.z));
                    Point::new(q.x as f32, q.y as f32, q.z as f32)
                })
                .collect(),
        );
        let found = index
            .query(&solid.describe(turned.view()).unwrap(), 1, &|_| false)
            .unwrap();
        let hint_deg = found[0].yaw_hint_rad.unwrap().to_degrees();
        assert!(
            angle_difference_deg(hint_deg, -yaw_deg) < 3.0,
            "yaw {yaw_deg}: hint {hint_deg}"
        );
    }
}

#[test]
fn conformance_default() {
    check_descriptor(
        || Box::new(SolidDescriptor::new(SolidConfig::default()).unwrap()),
        &DescriptorExpectations::default(),
    );
}

#[test]
fn conformance_quantized_u8() {
    let config = SolidConfig {
        quantization: Quantization::U8,
        ..SolidConfig::default()
    };
    check_descriptor(
        move || Box::new(SolidDescriptor::new(config.clone()).unwrap()),
        &DescriptorExpectations::default(),
    );
}

#[test]
fn conformance_narrow_vertical_fov() {
    // Livox MID-360 values: −7° to +52°, 40 m.
    let config = SolidConfig {
        lower_fov_deg: -7.0,
        upper_fov_deg: 52.0,
        max_range_m: 40.0,
        ..SolidConfig::default()
    };
    check_descriptor(
        move || Box::new(SolidDescriptor::new(config.clone()).unwrap()),
        &DescriptorExpectations::default(),
    );
}

#[test]
fn instances_on_two_threads_agree_with_each_alone() {
    skid_testkit::threads::descriptor_instances_agree_under_threads(|| {
        Box::new(SolidDescriptor::new(SolidConfig::default()).unwrap())
    });
}
