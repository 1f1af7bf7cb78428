//! The planetary world: a 1024 m × 1024 m analogue of lunar or Martian plains.
//!
//! Terrain is fBm value noise over several scales plus ridged multifractal wrinkle ridges (Musgrave
//! 1994). Craters follow a power-law size distribution; their profile is a parabolic bowl with a raised
//! rim decaying as (R/r)³ outside (after Pike 1977 and Melosh, "Impact Cratering", 1989), with depth
//! 0.1–0.3 R as for degraded simple craters. Rocks are jittered icospheres, power-law sized, partly
//! buried. Traverse lanes (the route graph) are kept clear of rocks and of large craters, as a rover
//! planner would; only a few boulders stand tall.

use super::Material;
use super::WorldParts;
use super::graph::{RoadGraph, jittered_grid, segment_distance_xy};
use super::shapes::add_blob;
use crate::bvh::Mesh;
use crate::geometry::V3;
use crate::heightfield::HeightField;
use crate::noise::{fbm2, ridged2, value2};
use crate::rng::{Rng, combine};

const CELLS: usize = 1024;
const CELL_M: f64 = 1.0;
const HALF_M: f64 = 512.0;

struct Crater {
    x: f64,
    y: f64,
    radius_m: f64,
    depth_m: f64,
    rim_m: f64,
}

impl Crater {
    /// Height change at distance `r` from the centre.
    fn profile(&self, r: f64) -> f64 {
        let q = r / self.radius_m;
        if q <= 1.0 {
            self.depth_m * (q * q - 1.0) + self.rim_m
        } else {
            // Fade the ejecta to zero between 2.5 R and 3 R so craters have compact support.
            let fade = ((3.0 - q) / 0.5).clamp(0.0, 1.0);
            self.rim_m * q.powi(-3) * fade
        }
    }
}

fn base_height(seed: u64, x: f64, y: f64) -> f64 {
    let broad = 7.0 * fbm2(combine(seed, 1), x / 260.0, y / 260.0, 4, 0.5);
    let ridges = 3.5 * ridged2(combine(seed, 2), x / 380.0 + 11.0, y / 380.0 - 7.0, 4);
    let hummocks = 0.8 * fbm2(combine(seed, 3), x / 35.0, y / 35.0, 3, 0.5);
    let undulation = 0.15 * fbm2(combine(seed, 5), x / 11.0, y / 11.0, 2, 0.5);
    let roughness = 0.08 * value2(combine(seed, 4), x / 2.3, y / 2.3);
    broad + ridges + hummocks + undulation + roughness
}

pub(crate) fn generate(seed: u64) -> WorldParts {
    let mut rng = Rng::new(combine(seed, 0x91a7));
    let mut graph: RoadGraph = jittered_grid(&mut rng, 7, 7, 125.0, 22.0, |_, _| 0.0);
    graph.prune(&mut rng, 0.25);
    // Two diagonal lanes give crossings at odd angles.
    let n = 7;
    for (a, b) in [(n + 1, 2 * n + 2), (4 * n + 4, 5 * n + 3)] {
        if !graph
            .edges
            .iter()
            .any(|(x, y, _)| (*x == a && *y == b) || (*x == b && *y == a))
        {
            graph.edges.push((a, b, vec![graph.nodes[a], graph.nodes[b]]));
        }
    }
    let lanes: Vec<([f64; 3], [f64; 3])> = graph
        .edges
        .iter()
        .map(|(_, _, l)| (l[0], l[l.len() - 1]))
        .collect();
    let lane_distance = |x: f64, y: f64| {
        lanes
            .iter()
            .map(|&(a, b)| segment_distance_xy(x, y, a, b))
            .fold(f64::INFINITY, f64::min)
    };

    let mut craters = Vec::new();
    while craters.len() < 420 {
        let radius_m = rng.power_law(2.0, 45.0, 2.2);
        let (x, y) = (rng.range(-HALF_M, HALF_M), rng.range(-HALF_M, HALF_M));
        if radius_m > 5.0 && lane_distance(x, y) < radius_m * 1.6 {
            continue;
        }
        let depth_m = radius_m * rng.range(0.1, 0.28);
        craters.push(Crater {
            x,
            y,
            radius_m,
            depth_m,
            rim_m: depth_m * rng.range(0.2, 0.4),
        });
    }

    let origin = -HALF_M;
    let mut heights =
        HeightField::sample_vertices(origin, origin, CELL_M, CELLS, |x, y| base_height(seed, x, y));
    let side = CELLS + 1;
    for crater in &craters {
        let reach = crater.radius_m * 3.0;
        let i0 = (((crater.x - reach - origin) / CELL_M).floor().max(0.0)) as usize;
        let i1 = (((crater.x + reach - origin) / CELL_M).ceil() as usize).min(CELLS);
        let j0 = (((crater.y - reach - origin) / CELL_M).floor().max(0.0)) as usize;
        let j1 = (((crater.y + reach - origin) / CELL_M).ceil() as usize).min(CELLS);
        for j in j0..=j1 {
            for i in i0..=i1 {
                let (x, y) = (origin + i as f64 * CELL_M, origin + j as f64 * CELL_M);
                let r = ((x - crater.x).powi(2) + (y - crater.y).powi(2)).sqrt();
                heights[j * side + i] += crater.profile(r) as f32;
            }
        }
    }
    let terrain = HeightField::new(
        origin,
        origin,
        CELL_M,
        CELLS,
        heights,
        vec![Material::Regolith as u8; CELLS * CELLS],
    );

    let mut objects = Mesh::default();
    let mut placed = 0;
    while placed < 9000 {
        let boulder = placed < 40;
        let radius_m = if boulder {
            rng.range(2.0, 4.5)
        } else {
            rng.power_law(0.15, 2.0, 2.6)
        };
        let (x, y) = (
            rng.range(-HALF_M + 5.0, HALF_M - 5.0),
            rng.range(-HALF_M + 5.0, HALF_M - 5.0),
        );
        if lane_distance(x, y) < radius_m + 3.5 {
            continue;
        }
        let ground = terrain.height_at(x, y);
        let flatten = rng.range(0.5, 0.9);
        let radii = V3::from_f64(
            radius_m * rng.range(0.7, 1.3),
            radius_m * rng.range(0.7, 1.3),
            radius_m * flatten,
        );
        let center = V3::from_f64(x, y, ground + radius_m * flatten * rng.range(0.1, 0.5));
        let subdivisions = if radius_m < 0.5 {
            0
        } else if radius_m < 1.5 {
            1
        } else {
            2
        };
        add_blob(
            &mut objects,
            &mut rng,
            center,
            radii,
            subdivisions,
            0.22,
            Material::Rock as u8,
        );
        placed += 1;
    }

    for node in &mut graph.nodes {
        node[2] = terrain.height_at(node[0], node[1]) + 3.0;
    }
    for (a, b, line) in &mut graph.edges {
        *line = densify(&terrain, graph.nodes[*a], graph.nodes[*b]);
    }
    WorldParts {
        terrain: Some(terrain),
        objects,
        graph,
        extent_m: [-HALF_M, -HALF_M, HALF_M, HALF_M],
    }
}

/// A straight lane from `a` to `b` sampled every 5 m, its reference height 3 m above the terrain.
pub(crate) fn densify(terrain: &HeightField, a: [f64; 3], b: [f64; 3]) -> Vec<[f64; 3]> {
    let length = ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt();
    let steps = (length / 5.0).ceil().max(1.0) as usize;
    (0..=steps)
        .map(|k| {
            let t = k as f64 / steps as f64;
            let (x, y) = (a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t);
            [x, y, terrain.height_at(x, y) + 3.0]
        })
        .collect()
}
