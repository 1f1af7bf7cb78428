//! Tests of the `scan_context` plugin (Kim & Kim, IROS 2018): a grid worked out by hand, the edge-case
//! choices, the distance and yaw convention, degenerate clouds and the conformance suite.

use skid_core::slots::{Descriptor, DescriptorBuf};
use skid_core::{Cloud, KeyframeId, Params, PluginContext, Point, Registry};
use skid_testkit::descriptor::{DescriptorExpectations, check_descriptor};

use super::*;
use crate::index::{Prepared, distance, sector_key_alignment};

/// 2 rings of 5 m, 4 sectors of 90°, sensor 2 m above the ground.
fn small_config() -> ScanContextConfig {
    ScanContextConfig {
        num_rings: 2,
        num_sectors: 4,
        max_range_m: 10.0,
        search_ratio: 1.0,
        ..ScanContextConfig::default()
    }
}

fn small_cloud() -> Cloud {
    Cloud::new(vec![
        Point::new(1.0, 0.5, -1.5),   // ring 0, sector 0, 0.5
        Point::new(2.0, 1.0, 0.5),    // ring 0, sector 0, 2.5 (the maximum)
        Point::new(-3.0, 1.0, 1.0),   // ring 0, sector 1, 3.0
        Point::new(-6.0, -1.0, -2.5), // ring 1, sector 2, −0.5 → 0 by default
        Point::new(1.0, -7.0, 4.0),   // ring 1, sector 3, 6.0
        Point::new(12.0, 1.0, 9.0),   // beyond 10 m
        Point::new(0.0, 0.0, 3.0),    // on the axis: no azimuth
    ])
}

#[test]
fn grid_computed_by_hand() {
    let descriptor = ScanContextDescriptor::new(small_config()).unwrap();
    let grid = descriptor.grid(small_cloud().view()).unwrap();
    assert_eq!(grid.values, vec![2.5, 3.0, 0.0, 0.0, 0.0, 0.0, 0.0, 6.0]);
    assert_eq!((grid.points_used, grid.points_out_of_range), (5, 2));
    assert_eq!(extract::ring_key(&grid.values, 4), vec![5.5 / 4.0, 6.0 / 4.0]);
    assert_eq!(extract::sector_key(&grid.values, 4), vec![1.25, 1.5, 0.0, 3.0]);
}

#[test]
fn edge_choices_are_configurable() {
    let kept = ScanContextConfig {
        keep_negative_heights: true,
        clamp_beyond_max_range: true,
        ..small_config()
    };
    let grid = ScanContextDescriptor::new(kept)
        .unwrap()
        .grid(small_cloud().view())
        .unwrap();
    // The cell below the ground offset keeps −0.5; the far point lands in ring 1, sector 0 at 11.
    assert_eq!(grid.values, vec![2.5, 3.0, 0.0, 0.0, 11.0, 0.0, -0.5, 6.0]);
    assert_eq!((grid.points_used, grid.points_out_of_range), (6, 1));
}

#[test]
fn distance_and_yaw_convention() {
    let shape = ScanContextShape {
        num_rings: 2,
        num_sectors: 4,
        num_candidates: 10,
        search_radius: 0,
    };
    let candidate = [1.0f32, 2.0, 0.0, 0.0, 3.0, 0.0, 0.5, 0.0];
    // The query sees in sector j + 1 what the candidate sees in sector j: it is turned by +90°.
    let query = [0.0f32, 1.0, 2.0, 0.0, 0.0, 3.0, 0.0, 0.5];
    let (q, c) = (Prepared::new(&query, &shape), Prepared::new(&candidate, &shape));
    let (self_distance, self_shift) = distance(&c, &c, &shape);
    assert!(self_distance < 1e-12 && self_shift == 0);
    let (d, shift) = distance(&q, &c, &shape);
    assert_eq!(shift, 1);
    assert!(d < 1e-12);
    assert_eq!(
        sector_key_alignment(&[0.0, 1.0, 0.0, 0.0], &[1.0, 0.0, 0.0, 0.0]),
        1
    );

    let mut index = ScanContextDescriptor::new(small_config()).unwrap().new_index();
    index
        .insert(
            KeyframeId::new(0, 0),
            DescriptorBuf {
                kind: NAME.into(),
                values: candidate.to_vec(),
            },
        )
        .unwrap();
    let found = index
        .query(
            &DescriptorBuf {
                kind: NAME.into(),
                values: query.to_vec(),
            },
            1,
            &|_| false,
        )
        .unwrap();
    assert!((found[0].yaw_hint_rad.unwrap().to_degrees() + 90.0).abs() < 1e-9);
    // No pair of non-empty columns: the largest distance, not NaN.
    let disjoint = [0.0f32, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    assert_eq!(distance(&Prepared::new(&disjoint, &shape), &c, &shape).0, 1.0);
}

#[test]
fn degenerate_clouds() {
    let mut descriptor = ScanContextDescriptor::new(ScanContextConfig::default()).unwrap();
    assert!(
        descriptor
            .describe(Cloud::default().view())
            .unwrap_err()
            .to_string()
            .contains("empty")
    );
    let below = Cloud::new(
        (0..300)
            .map(|i| Point::new((i as f32).cos() * 20.0, (i as f32).sin() * 20.0, -60.0))
            .collect(),
    );
    assert!(descriptor.describe(below.view()).is_err());
    let mut keeping = ScanContextDescriptor::new(ScanContextConfig {
        keep_negative_heights: true,
        ..ScanContextConfig::default()
    })
    .unwrap();
    let buf = keeping.describe(below.view()).unwrap();
    assert!(buf.values.iter().all(|v| v.is_finite() && *v <= 0.0));
    let mut index = keeping.new_index();
    index.insert(KeyframeId::new(0, 0), buf.clone()).unwrap();
    assert!(index.query(&buf, 1, &|_| false).unwrap()[0].distance.abs() < 1e-9);
    let bad = Cloud::new(vec![Point::new(1.0, 0.0, f32::INFINITY)]);
    assert!(
        descriptor
            .describe(bad.view())
            .unwrap_err()
            .to_string()
            .contains("point 0")
    );
    let foreign = DescriptorBuf {
        kind: "solid".into(),
        values: vec![1.0; 1200],
    };
    assert!(
        descriptor
            .new_index()
            .insert(KeyframeId::new(0, 0), foreign)
            .is_err()
    );
}

#[test]
fn config_checks_and_registration() {
    assert!(
        ScanContextDescriptor::new(ScanContextConfig {
            num_sectors: 0,
            ..ScanContextConfig::default()
        })
        .is_err()
    );
    assert!(
        ScanContextDescriptor::new(ScanContextConfig {
            search_ratio: 1.5,
            ..ScanContextConfig::default()
        })
        .is_err()
    );
    assert_eq!(ScanContextConfig::default().search_radius(), 3);
    assert_eq!(ScanContextConfig::default().wire_size_bytes(), 4800);
    let mut registry = Registry::new();
    register(&mut registry).unwrap();
    let made = registry
        .descriptor
        .create(NAME, &Params::default(), &PluginContext::default())
        .unwrap();
    assert_eq!(made.kind(), NAME);
    let typo = Params::from_toml_str("num_ring = 20").unwrap();
    assert!(
        registry
            .validate(skid_core::Slot::Descriptor, NAME, &typo)
            .is_err()
    );
}

#[test]
fn conformance_default() {
    check_descriptor(
        || Box::new(ScanContextDescriptor::new(ScanContextConfig::default()).unwrap()),
        &DescriptorExpectations::default(),
    );
}

#[test]
fn instances_on_two_threads_agree_with_each_alone() {
    skid_testkit::threads::descriptor_instances_agree_under_threads(|| {
        Box::new(ScanContextDescriptor::new(ScanContextConfig::default()).unwrap())
    });
}
