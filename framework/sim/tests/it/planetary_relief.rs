//! The planetary world has the field relief the SKiD-SLAM paper's registration claim needs (issue #19):
//! an RMS slope of about 10–12° at a metre's baseline where robots drive, boulders standing beside the
//! traverses, and the traverses themselves free of rock.

use crate::common;

use skid_sim::geometry::{Ray, V3};
use skid_sim::{Material, WorldKind};

#[test]
fn the_terrain_where_robots_drive_has_an_rms_slope_of_about_ten_degrees() {
    let world = common::world(WorldKind::Planetary);
    let slope = world.rms_slope_deg(20.0, 1.0).unwrap();
    assert!((9.0..13.0).contains(&slope), "RMS slope {slope:.1}°");
    // The urban ground is far smoother: the figure tells terrains apart.
    let urban = common::world(WorldKind::Urban).rms_slope_deg(20.0, 1.0).unwrap();
    assert!(urban < 4.0, "urban RMS slope {urban:.1}°");
}

#[test]
fn boulders_stand_beside_the_traverses_and_none_on_them() {
    let world = common::world(WorldKind::Planetary);
    // Look straight down on a 1 m grid across every lane, 15 m either side, and count where rock stands
    // more than half a metre above the terrain.
    let (mut band, mut band_rock, mut corridor, mut corridor_rock) = (0usize, 0usize, 0usize, 0usize);
    for (_, _, line) in &world.graph().edges {
        for w in line.windows(2) {
            let (dx, dy) = (w[1][0] - w[0][0], w[1][1] - w[0][1]);
            let length = dx.hypot(dy);
            if length < 1e-6 {
                continue;
            }
            let (nx, ny) = (-dy / length, dx / length);
            for along in 0..length.floor() as usize {
                let t = along as f64 / length;
                let (x0, y0) = (w[0][0] + dx * t, w[0][1] + dy * t);
                for lateral in -15i32..=15 {
                    let (x, y) = (x0 + nx * f64::from(lateral), y0 + ny * f64::from(lateral));
                    let rock = rock_above_terrain(&world, x, y);
                    if lateral.abs() <= 1 {
                        corridor += 1;
                        corridor_rock += usize::from(rock);
                    } else if lateral.abs() >= 3 && world.graph().distance_xy_m(x, y) >= 3.0 {
                        band += 1;
                        band_rock += usize::from(rock);
                    }
                }
            }
        }
    }
    let coverage = band_rock as f64 / band as f64;
    assert!(
        coverage > 0.004,
        "rock covers {:.2} % of the band beside the lanes",
        100.0 * coverage
    );
    assert_eq!(
        corridor_rock, 0,
        "{corridor_rock} of {corridor} metres on the lanes are rock"
    );
}

/// Whether a rock surface stands more than 0.5 m above the terrain at (x, y).
fn rock_above_terrain(world: &skid_sim::World, x: f64, y: f64) -> bool {
    let Some(ground) = world.terrain_height(x, y) else {
        return false;
    };
    let top = ground + 8.0;
    let ray = Ray::new(V3::from_f64(x, y, top), V3::new(0.0, 0.0, -1.0));
    world
        .cast(&ray, 8.0)
        .is_some_and(|hit| hit.material == Material::Rock && top - f64::from(hit.range_m) > ground + 0.5)
}

/// Counts the places on a 2 m grid within 15 m of the traverses where rock stands above the terrain.
fn rocky_places(world: &skid_sim::World) -> std::collections::BTreeSet<(i64, i64)> {
    let mut places = std::collections::BTreeSet::new();
    for (_, _, line) in &world.graph().edges {
        for point in line.iter().step_by(2) {
            for dx in (-15i64..=15).step_by(2) {
                for dy in (-15i64..=15).step_by(2) {
                    let (x, y) = ((point[0] as i64 + dx) / 2 * 2, (point[1] as i64 + dy) / 2 * 2);
                    if rock_above_terrain(world, x as f64, y as f64) {
                        places.insert((x, y));
                    }
                }
            }
        }
    }
    places
}

#[test]
fn a_later_season_moves_and_removes_rocks_and_keeps_the_terrain_and_the_roads() {
    let world = common::world(WorldKind::Planetary);
    let same = skid_sim::World::generate_in_season(WorldKind::Planetary, world.seed(), 0);
    assert_eq!(same.triangle_count(), world.triangle_count());
    let later = skid_sim::World::generate_in_season(WorldKind::Planetary, world.seed(), 1);
    assert_eq!(later.graph().nodes, world.graph().nodes);
    assert_eq!(
        later.terrain_height(10.0, -20.0),
        world.terrain_height(10.0, -20.0)
    );
    assert!(
        later.triangle_count() < world.triangle_count(),
        "some rocks are gone"
    );
    let (before, after) = (rocky_places(&world), rocky_places(&later));
    let kept = before.intersection(&after).count() as f64;
    // Most rock stays where it was, but not all of it.
    let share = kept / before.len() as f64;
    assert!(
        (0.5..0.95).contains(&share),
        "{share:.2} of the rocky places kept ({} before)",
        before.len()
    );
}
