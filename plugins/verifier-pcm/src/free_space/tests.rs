//! Tests of the free-space check on ray-cast streets: walls, ground and parked cars seen by a
//! 32-beam spinning LiDAR, so that the two scans of a test agree or disagree the way real ones do.

use super::*;
use nalgebra::Vector3;
use skid_geometry::voxel_downsample;

use crate::test_scene::{Block, hit};

/// A straight street between two facades 10 m either side of its centre line, on flat ground 1.8 m
/// below the sensor, with parked cars (4.4 m × 1.8 m × 1.5 m) in the slots `cars` names, every 6 m
/// along both kerbs.
fn street(cars: &[bool]) -> Vec<Block> {
    let mut blocks = vec![
        Block {
            min: Vector3::new(-80.0, 10.0, -1.8),
            max: Vector3::new(80.0, 30.0, 20.0),
        },
        Block {
            min: Vector3::new(-80.0, -30.0, -1.8),
            max: Vector3::new(80.0, -10.0, 20.0),
        },
    ];
    for (slot, _) in cars.iter().enumerate().filter(|(_, parked)| **parked) {
        let x = -40.0 + 6.0 * (slot / 2) as f64;
        let y = if slot % 2 == 0 { 3.4 } else { -5.2 };
        blocks.push(Block {
            min: Vector3::new(x, y, -1.8),
            max: Vector3::new(x + 4.4, y + 1.8, -0.3),
        });
    }
    blocks
}

/// A sweep of 32 beams from -16° to +15° in elevation (1° apart) and 0.35° in azimuth, from a sensor at
/// `x` on the centre line facing along the street, in the sensor's frame, thinned to the 0.25 m voxels
/// keyframes are kept at.
fn scan(blocks: &[Block], x: f64) -> Vec<Point> {
    let origin = Vector3::new(x, 0.0, 0.0);
    let mut points = Vec::new();
    for row in 0..32 {
        let elevation = f64::from(row - 16).to_radians();
        for column in 0..1029 {
            let azimuth = (f64::from(column) * 0.35).to_radians();
            let direction = Vector3::new(
                elevation.cos() * azimuth.cos(),
                elevation.cos() * azimuth.sin(),
                elevation.sin(),
            );
            let ground = (direction.z < 0.0).then(|| -1.8 / direction.z);
            let nearest = blocks
                .iter()
                .filter_map(|block| hit(block, &origin, &direction))
                .chain(ground)
                .fold(f64::INFINITY, f64::min);
            if nearest < 80.0 {
                let p = direction * nearest;
                points.push(Point::new(p.x as f32, p.y as f32, p.z as f32));
            }
        }
    }
    voxel_downsample(&points, 0.25)
}

/// Every second slot taken, and its complement: two streets of one look that differ in every car.
fn parked(every: usize, offset: usize) -> Vec<bool> {
    (0..28)
        .map(|slot| (slot / 2 + offset).is_multiple_of(every))
        .collect()
}

#[test]
fn a_revisit_of_the_same_street_agrees() {
    let blocks = street(&parked(2, 0));
    let (target, source) = (scan(&blocks, 0.0), scan(&blocks, 3.0));
    let config = FreeSpaceConfig::default();
    let count = config.count(&target, &source, &Pose::translation(3.0, 0.0, 0.0));
    assert!(count.agreeing > 1000, "{count:?}");
    assert_eq!(count.clustered, 0, "{count:?}");
    assert!(count.violation_fraction() < 0.01, "{count:?}");
    assert_eq!(config.judge(&count), None);
}

#[test]
fn a_look_alike_street_whose_cars_differ_is_refused() {
    let (here, there) = (street(&parked(2, 0)), street(&parked(2, 1)));
    let (target, source) = (scan(&here, 0.0), scan(&there, 3.0));
    let config = FreeSpaceConfig::default();
    // The facades and the ground align exactly: only the cars tell the streets apart.
    let count = config.count(&target, &source, &Pose::translation(3.0, 0.0, 0.0));
    assert!(
        count.clustered_fraction() > 2.0 * config.max_clustered_fraction,
        "{count:?}"
    );
    let reason = config.judge(&count).expect("the look-alike street is refused");
    assert!(reason.starts_with("free space"), "{reason}");
}

#[test]
fn a_misregistered_revisit_sees_through_the_other_scan() {
    // The same street, but the alignment is 3 m off across it: the facades of one scan stand in the
    // street the other scan saw empty.
    let blocks = street(&parked(2, 0));
    let (target, source) = (scan(&blocks, 0.0), scan(&blocks, 0.0));
    let config = FreeSpaceConfig::default();
    let count = config.count(&target, &source, &Pose::translation(0.0, 3.0, 0.0));
    assert!(config.judge(&count).is_some(), "{count:?}");
}

#[test]
fn empty_and_non_finite_clouds_pass_without_evidence() {
    let config = FreeSpaceConfig::default();
    let blocks = street(&parked(2, 0));
    let full = scan(&blocks, 0.0);
    let nan = [Point::new(f32::NAN, 0.0, 0.0); 10];
    for (target, source) in [(&full[..], &[][..]), (&[][..], &full[..]), (&nan[..], &full[..])] {
        let count = config.count(target, source, &Pose::identity());
        assert_eq!(count.violating + count.agreeing, 0, "{count:?}");
        assert_eq!(config.judge(&count), None);
    }
}

#[test]
fn out_of_range_parameters_name_their_key() {
    let cases = [
        (
            FreeSpaceConfig {
                pixel_deg: 0.0,
                ..FreeSpaceConfig::default()
            },
            "pixel_deg",
        ),
        (
            FreeSpaceConfig {
                margin_m: -1.0,
                ..FreeSpaceConfig::default()
            },
            "margin_m",
        ),
        (
            FreeSpaceConfig {
                max_clustered_fraction: 1.5,
                ..FreeSpaceConfig::default()
            },
            "max_clustered_fraction",
        ),
    ];
    for (config, key) in cases {
        let error = config.validate().expect_err(key);
        assert!(error.to_string().contains(key), "{error}");
    }
}
