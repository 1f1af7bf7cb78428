//! The urban world: an irregular street grid over gently sloping ground, crowned carriageways (2 % cross
//! slope), raised sidewalks, blocks of box buildings (some with set-back upper storeys), street poles,
//! parked cars and trees. Street spacing and building heights are drawn per seed; intersections stay
//! clear of clutter.
//!
//! Its `blocks` variant is the self-similar city the trust benchmark needs: streets every 100 m both
//! ways, every block built from the same draw (the same lots, heights and set-backs) and every street
//! lined with the same poles and trees, so one block or street is told from another only by the
//! ground's gentle slope and by where cars happen to be parked (drawn afresh per street).

use super::Material;
use super::WorldParts;
use super::graph::RoadGraph;
use super::planetary::densify;
use super::shapes::{add_blob, add_box, add_prism};
use crate::bvh::Mesh;
use crate::geometry::V3;
use crate::heightfield::HeightField;
use crate::noise::fbm2;
use crate::rng::{Rng, combine};

const CELLS: usize = 1024;
const CELL_M: f64 = 1.0;
const HALF_M: f64 = 512.0;
/// Half-width of the carriageway and outer edge of the sidewalk, from the centre line.
const ROAD_HALF_M: f64 = 6.0;
const SIDEWALK_OUTER_M: f64 = 9.5;
/// Cross slope of a carriageway's crown (rise per metre towards the centre line).
const CROSS_SLOPE: f64 = 0.02;

/// Street spacing of the `blocks` variant, metres.
const BLOCK_PITCH_M: f64 = 100.0;

/// Whether every block and street repeats the same draw.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Layout {
    /// Irregular streets, each block and street drawn afresh.
    Irregular,
    /// Regular streets; identical blocks and street furniture.
    IdenticalBlocks,
}

impl Layout {
    /// The stream a block's or a street side's draws come from: the world's own, in turn, or a fresh
    /// copy of the repeated one.
    fn stream<'a>(self, world: &'a mut Rng, copy: &'a mut Rng) -> &'a mut Rng {
        match self {
            Layout::Irregular => world,
            Layout::IdenticalBlocks => copy,
        }
    }
}

/// Street positions along one axis for `layout`.
fn street_positions(rng: &mut Rng, layout: Layout) -> Vec<f64> {
    match layout {
        Layout::Irregular => street_lines(rng),
        Layout::IdenticalBlocks => (0..=8).map(|i| -400.0 + BLOCK_PITCH_M * f64::from(i)).collect(),
    }
}

/// Street positions along one axis: irregular spacing 70–130 m.
fn street_lines(rng: &mut Rng) -> Vec<f64> {
    let mut lines = vec![-420.0];
    while let Some(&last) = lines.last() {
        let next = last + rng.range(70.0, 130.0);
        if next > 420.0 {
            break;
        }
        lines.push(next);
    }
    lines
}

pub(crate) fn generate(seed: u64, layout: Layout) -> WorldParts {
    let mut rng = Rng::new(combine(seed, 0x0b5a));
    let xs = street_positions(&mut rng, layout);
    let ys = street_positions(&mut rng, layout);
    // Identical blocks draw each block's buildings and each street side's poles and trees from a copy of
    // this one stream; irregular layouts draw everything from the world's own stream, in turn.
    let repeated = Rng::new(combine(seed, 0xb10c));
    let ground = |x: f64, y: f64| 2.5 * fbm2(combine(seed, 7), x / 400.0, y / 400.0, 3, 0.5);
    // Distance to the nearest street centre line (streets run the full grid).
    let street_distance = |x: f64, y: f64| {
        let dx = xs.iter().map(|s| (x - s).abs()).fold(f64::INFINITY, f64::min);
        let dy = ys.iter().map(|s| (y - s).abs()).fold(f64::INFINITY, f64::min);
        let inside =
            x > xs[0] - 1.0 && x < xs[xs.len() - 1] + 1.0 && y > ys[0] - 1.0 && y < ys[ys.len() - 1] + 1.0;
        if inside { dx.min(dy) } else { f64::INFINITY }
    };
    let origin = -HALF_M;
    // Carriageways are crowned for drainage: a 2 % cross slope from the centre line down to the kerb,
    // so a vehicle keeping to its lane rolls by about a degree and no two scans of a road are mirror
    // images of each other. Sidewalks stand 15 cm above the kerb.
    let heights = HeightField::sample_vertices(origin, origin, CELL_M, CELLS, |x, y| {
        let d = street_distance(x, y);
        ground(x, y)
            + if d > ROAD_HALF_M {
                0.15
            } else {
                CROSS_SLOPE * (ROAD_HALF_M - d)
            }
    });
    let materials = (0..CELLS * CELLS)
        .map(|i| {
            let (x, y) = (
                origin + ((i % CELLS) as f64 + 0.5) * CELL_M,
                origin + ((i / CELLS) as f64 + 0.5) * CELL_M,
            );
            let d = street_distance(x, y);
            (if d <= ROAD_HALF_M {
                Material::Asphalt
            } else if d <= SIDEWALK_OUTER_M {
                Material::Concrete
            } else {
                Material::Grass
            }) as u8
        })
        .collect();
    let terrain = HeightField::new(origin, origin, CELL_M, CELLS, heights, materials);

    let mut graph = RoadGraph::default();
    for &y in &ys {
        for &x in &xs {
            graph.nodes.push([x, y, 0.0]);
        }
    }
    let nx = xs.len();
    for j in 0..ys.len() {
        for i in 0..nx {
            let n = j * nx + i;
            if i + 1 < nx {
                graph.edges.push((n, n + 1, Vec::new()));
            }
            if j + 1 < ys.len() {
                graph.edges.push((n, n + nx, Vec::new()));
            }
        }
    }
    for node in &mut graph.nodes {
        node[2] = terrain.height_at(node[0], node[1]) + 3.0;
    }
    for (a, b, line) in &mut graph.edges {
        *line = densify(&terrain, graph.nodes[*a], graph.nodes[*b]);
    }

    let mut objects = Mesh::default();
    // Buildings: each block is cut into lots along x; each lot gets a box, sometimes with a set-back.
    for bj in 0..ys.len() - 1 {
        for bi in 0..nx - 1 {
            let mut copy = repeated.clone();
            let rng = layout.stream(&mut rng, &mut copy);
            let (x0, x1) = (
                xs[bi] + SIDEWALK_OUTER_M + 1.0,
                xs[bi + 1] - SIDEWALK_OUTER_M - 1.0,
            );
            let (y0, y1) = (
                ys[bj] + SIDEWALK_OUTER_M + 1.0,
                ys[bj + 1] - SIDEWALK_OUTER_M - 1.0,
            );
            if rng.chance(0.08) {
                continue; // An open lot or park.
            }
            let mut x = x0;
            while x1 - x > 8.0 {
                let width = rng.range(12.0, 35.0).min(x1 - x);
                for (ya, yb) in [(y0, y0 + (y1 - y0) * 0.5 - 2.0), (y0 + (y1 - y0) * 0.5 + 2.0, y1)] {
                    let inset = rng.range(0.0, 3.0);
                    let (cx, cy) = (x + width / 2.0, (ya + yb) / 2.0);
                    let (hx, hy) = (width / 2.0 - 1.0, (yb - ya) / 2.0 - inset);
                    if hx < 2.0 || hy < 2.0 {
                        continue;
                    }
                    let base = ground(cx, cy) - 2.0;
                    let height = rng.power_law(6.0, 60.0, 2.0);
                    add_box(
                        &mut objects,
                        V3::from_f64(cx, cy, base + height / 2.0 + 1.0),
                        V3::from_f64(hx, hy, height / 2.0 + 1.0),
                        0.0,
                        Material::Facade as u8,
                    );
                    if height > 15.0 && rng.chance(0.5) {
                        let upper = rng.range(4.0, 20.0);
                        let top = base + height + 2.0;
                        add_box(
                            &mut objects,
                            V3::from_f64(cx, cy, top + upper / 2.0),
                            V3::from_f64(hx * 0.6, hy * 0.6, upper / 2.0),
                            0.0,
                            Material::Facade as u8,
                        );
                    }
                }
                x += width + rng.range(1.0, 6.0);
            }
        }
    }
    // Street furniture along each edge, both sides, away from intersections.
    for (a, b, _) in &graph.edges {
        let (pa, pb) = (graph.nodes[*a], graph.nodes[*b]);
        let length = ((pb[0] - pa[0]).powi(2) + (pb[1] - pa[1]).powi(2)).sqrt();
        let (ux, uy) = ((pb[0] - pa[0]) / length, (pb[1] - pa[1]) / length);
        let yaw = uy.atan2(ux) as f32;
        for side in [-1.0, 1.0] {
            let (nx_, ny_) = (-uy * side, ux * side);
            let at = |s: f64, offset: f64| (pa[0] + ux * s + nx_ * offset, pa[1] + uy * s + ny_ * offset);
            let mut copy = repeated.clone();
            let furniture = layout.stream(&mut rng, &mut copy);
            let mut s = 14.0 + furniture.range(0.0, 10.0);
            while s < length - 14.0 {
                let (x, y) = at(s, 7.0);
                add_prism(
                    &mut objects,
                    V3::from_f64(x, y, ground(x, y)),
                    0.12,
                    furniture.range(6.0, 8.5) as f32,
                    8,
                    Material::Metal as u8,
                );
                s += furniture.range(22.0, 32.0);
            }
            let mut s = 18.0 + furniture.range(0.0, 10.0);
            while s < length - 18.0 {
                let (x, y) = at(s, 8.3);
                let z = ground(x, y) + 0.15;
                add_prism(
                    &mut objects,
                    V3::from_f64(x, y, z),
                    0.18,
                    3.2,
                    6,
                    Material::Bark as u8,
                );
                let r = furniture.range(1.6, 2.6);
                add_blob(
                    &mut objects,
                    furniture,
                    V3::from_f64(x, y, z + 3.0 + r * 0.8),
                    V3::from_f64(r, r, r * 0.85),
                    1,
                    0.25,
                    Material::Foliage as u8,
                );
                s += furniture.range(15.0, 30.0);
            }
            let mut s = 15.0;
            while s < length - 19.0 {
                if rng.chance(0.55) {
                    let (x, y) = at(s + 2.3, 4.3);
                    let z = ground(x, y);
                    let car_yaw = yaw + rng.range(-0.04, 0.04) as f32;
                    add_box(
                        &mut objects,
                        V3::from_f64(x, y, z + 0.7),
                        V3::new(2.2, 0.9, 0.4),
                        car_yaw,
                        Material::CarPaint as u8,
                    );
                    add_box(
                        &mut objects,
                        V3::from_f64(x, y, z + 1.35),
                        V3::new(1.2, 0.8, 0.3),
                        car_yaw,
                        Material::CarPaint as u8,
                    );
                }
                s += rng.range(5.2, 7.0);
            }
        }
    }
    let extent = [
        xs[0] - 60.0,
        ys[0] - 60.0,
        xs[nx - 1] + 60.0,
        ys[ys.len() - 1] + 60.0,
    ];
    WorldParts {
        terrain: Some(terrain),
        objects,
        graph,
        extent_m: extent,
    }
}
