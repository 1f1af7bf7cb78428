//! Tests of the `iris` plugin (LiDAR-Iris, Wang et al., IROS 2020): an image worked out by hand, the
//! filters' shift equivariance and masks, the shift estimate, degenerate clouds and the conformance suite.

use skid_core::slots::{Descriptor, DescriptorBuf};
use skid_core::{Cloud, KeyframeId, Params, PluginContext, Point, Registry};
use skid_testkit::descriptor::{DescriptorExpectations, check_descriptor};

use super::*;
use crate::features::hamming_distance;

/// 3 rings of 2 m, 4 columns of 90°, 2 slices of 1 m from −1 m.
fn small_config() -> IrisConfig {
    IrisConfig {
        num_rings: 3,
        ring_width_m: 2.0,
        num_columns: 4,
        min_height_m: -1.0,
        num_slices: 2,
        ..IrisConfig::default()
    }
}

/// A code image with structure at several scales, and the same image turned by `shift` columns.
fn textured_image(rows: usize, columns: usize, shift: usize) -> Vec<u8> {
    let mut codes = vec![0u8; rows * columns];
    for row in 0..rows {
        for column in 0..columns {
            let c = (column + columns - shift) % columns;
            let value = ((c * 7 + row * 13) % 23) as u32
                + if (c / 30 + row / 10).is_multiple_of(2) {
                    100
                } else {
                    0
                };
            codes[row * columns + column] = value.min(255) as u8;
        }
    }
    codes
}

#[test]
fn image_computed_by_hand() {
    let cloud = Cloud::new(vec![
        Point::new(1.0, 0.2, -0.5),   // row 0, column 0, slice 0
        Point::new(1.5, 0.1, 0.5),    // row 0, column 0, slice 1
        Point::new(-3.0, 0.5, 0.2),   // row 1, column 1, slice 1
        Point::new(-0.5, -5.0, -0.9), // row 2, column 2, slice 0
        Point::new(0.5, -5.0, 3.0),   // above the slices
        Point::new(7.0, 0.0, 0.0),    // beyond 6 m
    ]);
    let image = IrisDescriptor::new(small_config())
        .unwrap()
        .image(cloud.view())
        .unwrap();
    assert_eq!(image.codes, vec![0b11, 0, 0, 0, 0, 0b10, 0, 0, 0, 0, 0b01, 0]);
    assert_eq!(
        (
            image.points_used,
            image.points_out_of_range,
            image.points_outside_heights
        ),
        (4, 1, 1)
    );
    assert_eq!(
        image::row_key(&image.codes, 4, 2),
        vec![2.0 / 8.0, 1.0 / 8.0, 1.0 / 8.0]
    );
}

#[test]
fn features_turn_with_the_image_and_mask_flat_rows() {
    let config = IrisConfig::default();
    let bank = config.filter_bank();
    let (rows, columns) = (config.num_rings, config.num_columns);
    let base = bank.features(&bank.spectra(&textured_image(rows, columns, 0)));
    let turned = bank.features(&bank.spectra(&textured_image(rows, columns, 37)));
    assert_eq!(hamming_distance(&base, &base, columns, 0), 0.0);
    assert!(hamming_distance(&turned, &base, columns, 37) < 0.01);
    assert!(hamming_distance(&turned, &base, columns, 0) > 0.2);
    let turned_spectra = bank.spectra(&textured_image(rows, columns, 37));
    assert_eq!(
        bank.estimate_shift(&turned_spectra, &bank.spectra(&textured_image(rows, columns, 0))),
        Some(37)
    );
    // A constant row has only a DC term, which every log-Gabor filter removes: all its bits are masked,
    // and an image of such rows has nothing to compare.
    let flat = bank.features(&bank.spectra(&vec![9u8; rows * columns]));
    assert!(flat.mask.iter().all(|&m| m == 0xff));
    assert_eq!(hamming_distance(&flat, &flat, columns, 0), 1.0);
    assert_eq!(
        bank.estimate_shift(&bank.spectra(&vec![0u8; rows * columns]), &turned_spectra),
        None
    );
}

#[test]
fn unused_scales_are_masked() {
    let config = IrisConfig {
        num_scales: 2,
        ..IrisConfig::default()
    };
    let bank = config.filter_bank();
    let features = bank.features(&bank.spectra(&textured_image(config.num_rings, config.num_columns, 0)));
    assert!(features.mask.iter().all(|&m| m & 0xf0 == 0xf0));
    assert!(features.template.iter().all(|&t| t & 0xf0 == 0));
}

#[test]
fn degenerate_clouds() {
    let mut iris = IrisDescriptor::new(IrisConfig::default()).unwrap();
    assert!(iris.describe(Cloud::default().view()).is_err());
    let below = Cloud::new(
        (0..300)
            .map(|i| Point::new((i as f32).cos() * 20.0, (i as f32).sin() * 20.0, -60.0))
            .collect(),
    );
    assert!(
        iris.describe(below.view())
            .unwrap_err()
            .to_string()
            .contains("300 outside the height slices")
    );
    let one_range = Cloud::new(vec![Point::new(10.0, 0.0, 0.0); 500]);
    let buf = iris.describe(one_range.view()).unwrap();
    let mut index = iris.new_index();
    index.insert(KeyframeId::new(0, 0), buf.clone()).unwrap();
    let found = index.query(&buf, 1, &|_| false).unwrap();
    assert!(found[0].distance.is_finite());
    assert!(
        iris.describe(Cloud::new(vec![Point::new(f32::NAN, 1.0, 0.0)]).view())
            .is_err()
    );
    let not_codes = DescriptorBuf {
        kind: NAME.into(),
        values: vec![0.5; 28_800],
    };
    assert!(index.insert(KeyframeId::new(0, 1), not_codes).is_err());
}

#[test]
fn config_checks_and_registration() {
    assert!(
        IrisDescriptor::new(IrisConfig {
            num_slices: 9,
            ..IrisConfig::default()
        })
        .is_err()
    );
    assert!(
        IrisDescriptor::new(IrisConfig {
            num_scales: 5,
            ..IrisConfig::default()
        })
        .is_err()
    );
    assert!(
        IrisDescriptor::new(IrisConfig {
            sigma_on_f: 1.5,
            ..IrisConfig::default()
        })
        .is_err()
    );
    assert_eq!(IrisConfig::default().wire_size_bytes(), 115_200);
    assert_eq!(IrisConfig::default().packed_size_bytes(), 28_800);
    let mut registry = Registry::new();
    register(&mut registry).unwrap();
    let made = registry
        .descriptor
        .create(NAME, &Params::default(), &PluginContext::default())
        .unwrap();
    assert_eq!(made.kind(), NAME);
    let typo = Params::from_toml_str("num_ringz = 80").unwrap();
    assert!(
        registry
            .validate(skid_core::Slot::Descriptor, NAME, &typo)
            .is_err()
    );
}

#[test]
fn conformance_default() {
    check_descriptor(
        || Box::new(IrisDescriptor::new(IrisConfig::default()).unwrap()),
        &DescriptorExpectations::default(),
    );
}

#[test]
fn instances_on_two_threads_agree_with_each_alone() {
    skid_testkit::threads::descriptor_instances_agree_under_threads(|| {
        Box::new(IrisDescriptor::new(IrisConfig::default()).unwrap())
    });
}
