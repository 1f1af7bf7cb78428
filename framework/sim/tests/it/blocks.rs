//! The `blocks` world is the self-similar city it claims to be: from the same spot of two different
//! blocks a sensor sees the same facades, where the irregular urban world shows different ones.

use skid_sim::geometry::{Ray, V3};
use skid_sim::{World, WorldKind};

use crate::common;

/// Horizontal ranges, 10° above the horizon so that they meet facades rather than cars or the ground,
/// in 720 directions from (x, y) at 2 m above the ground.
fn facade_ranges(world: &World, x: f64, y: f64) -> Vec<Option<f32>> {
    let ground = world.ground_below(x, y, 200.0, 400.0).unwrap();
    let origin = V3::from_f64(x, y, ground + 2.0);
    (0..720)
        .map(|i| {
            let yaw = f64::from(i) * 0.5f64.to_radians();
            let (cos_up, sin_up) = (10f64.to_radians().cos(), 10f64.to_radians().sin());
            let direction = V3::from_f64(cos_up * yaw.cos(), cos_up * yaw.sin(), sin_up);
            world
                .cast(&Ray::new(origin, direction), 120.0)
                .map(|hit| hit.range_m)
        })
        .collect()
}

/// Fraction of directions whose ranges agree within 10 cm (both missing counts as agreeing).
fn agreement(a: &[Option<f32>], b: &[Option<f32>]) -> f64 {
    let same = a
        .iter()
        .zip(b)
        .filter(|(x, y)| match (x, y) {
            (Some(x), Some(y)) => (x - y).abs() < 0.1,
            (None, None) => true,
            _ => false,
        })
        .count();
    same as f64 / a.len() as f64
}

#[test]
fn every_block_looks_like_the_next_and_urban_blocks_do_not() {
    // On the street along y = 0 (streets run every 100 m from -400 m), 30 m past a junction, in the
    // kerb-side lane; then the same spot one and two blocks east.
    let blocks = common::world(WorldKind::Blocks);
    let here = facade_ranges(&blocks, 30.0, 1.75);
    for blocks_east in [1.0, 2.0] {
        let there = facade_ranges(&blocks, 30.0 + 100.0 * blocks_east, 1.75);
        let agree = agreement(&here, &there);
        assert!(
            agree > 0.9,
            "{blocks_east} blocks east: {agree:.2} of the directions agree"
        );
    }
    // The irregular city from two spots 100 m apart along a street: mostly different.
    let urban = common::world(WorldKind::Urban);
    let street_y = urban.graph().nodes[0][1];
    let (a, b) = (
        facade_ranges(&urban, urban.graph().nodes[0][0] + 30.0, street_y + 1.75),
        facade_ranges(&urban, urban.graph().nodes[0][0] + 130.0, street_y + 1.75),
    );
    assert!(agreement(&a, &b) < 0.5, "urban: {:.2} agree", agreement(&a, &b));
}
