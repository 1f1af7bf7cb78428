//! The cave world: a branching tunnel network with irregular walls, flat-ish floors, junctions and
//! chambers, about 450 m × 450 m with 3 km of passages.
//!
//! The cave is a signed distance field: the union of tunnel pieces (capsules around meandering centre
//! lines) and chambers (flattened ellipsoids at some junctions), cut by one floor that blends the
//! pieces' floor heights where they overlap (so it ramps where a sloping tunnel enters a chamber), with
//! walls roughened by 3D fBm. It is meshed with naive surface nets (Gibson, "Constrained elastic surface
//! nets", 1998) on a sparse grid of 8³ blocks that only covers the tunnels, so junctions merge into one
//! watertight surface with no internal walls.

use std::collections::HashMap;

use rayon::prelude::*;

use super::Material;
use super::WorldParts;
use super::graph::{RoadGraph, jittered_grid};
use crate::bvh::Mesh;
use crate::geometry::V3;
use crate::noise::{fbm3, value2, value3};
use crate::rng::{Rng, combine};

/// Lattice spacing of the distance field.
const VOXEL_M: f64 = 0.6;
/// Lattice points per block side.
const BLOCK: i32 = 8;
/// Depth of the floor below a tunnel's axis.
const FLOOR_BELOW_AXIS_M: f64 = 1.6;

enum Piece {
    Tunnel { a: [f64; 3], b: [f64; 3], radius_m: f64 },
    Chamber { center: [f64; 3], radius_m: f64 },
}

impl Piece {
    fn reach_m(&self) -> f64 {
        match self {
            Piece::Tunnel { radius_m, .. } | Piece::Chamber { radius_m, .. } => {
                radius_m * 1.3 + 0.2 + VOXEL_M
            }
        }
    }

    fn bounds(&self) -> ([f64; 3], [f64; 3]) {
        let r = self.reach_m();
        let (lo, hi) = match self {
            Piece::Tunnel { a, b, .. } => (
                [a[0].min(b[0]), a[1].min(b[1]), a[2].min(b[2])],
                [a[0].max(b[0]), a[1].max(b[1]), a[2].max(b[2])],
            ),
            Piece::Chamber { center, .. } => (*center, *center),
        };
        (
            [lo[0] - r, lo[1] - r, lo[2] - r],
            [hi[0] + r, hi[1] + r, hi[2] + r],
        )
    }

    /// The signed distance to the piece's walls (negative inside) given the wall noise `coarse` and `fine`
    /// at q, and the height of its floor there.
    fn wall_and_floor(&self, q: [f64; 3], coarse: f64, fine: f64) -> (f64, f64) {
        match self {
            Piece::Tunnel { a, b, radius_m } => {
                let ab = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
                let aq = [q[0] - a[0], q[1] - a[1], q[2] - a[2]];
                let len2 = ab[0] * ab[0] + ab[1] * ab[1] + ab[2] * ab[2];
                let t = ((aq[0] * ab[0] + aq[1] * ab[1] + aq[2] * ab[2]) / len2.max(1e-9)).clamp(0.0, 1.0);
                let c = [a[0] + t * ab[0], a[1] + t * ab[1], a[2] + t * ab[2]];
                let d = ((q[0] - c[0]).powi(2) + (q[1] - c[1]).powi(2) + (q[2] - c[2]).powi(2)).sqrt();
                let wall = d - radius_m * (1.0 + 0.25 * coarse) - 0.15 * fine;
                (wall, c[2] - FLOOR_BELOW_AXIS_M)
            }
            Piece::Chamber { center, radius_m } => {
                let d = ((q[0] - center[0]).powi(2)
                    + (q[1] - center[1]).powi(2)
                    + ((q[2] - center[2] - 1.0) / 0.6).powi(2))
                .sqrt();
                let wall = d - radius_m * (1.0 + 0.25 * coarse) - 0.15 * fine;
                (wall, center[2] - FLOOR_BELOW_AXIS_M)
            }
        }
    }
}

/// Signed distance (negative inside) of the union of `pieces` at q. The walls are the union of the
/// pieces' walls; the floor is one surface, each piece's floor height weighted by how deep inside it q
/// lies (full weight from 1.5 m inside its wall), so where a sloping tunnel enters a chamber or another
/// tunnel the floor ramps from one height to the other instead of dropping in a step no robot could
/// drive.
fn union_distance(pieces: &[Piece], list: &[u32], q: [f64; 3], coarse: f64, fine: f64) -> f64 {
    let (mut wall, mut weights, mut heights) = (4.0f64, 0.0, 0.0);
    for &index in list {
        let (piece_wall, floor_m) = pieces[index as usize].wall_and_floor(q, coarse, fine);
        wall = wall.min(piece_wall);
        let depth = (-piece_wall / 1.5).clamp(0.0, 1.0);
        let weight = depth * depth * (3.0 - 2.0 * depth) + if piece_wall < 0.0 { 1e-6 } else { 0.0 };
        weights += weight;
        heights += weight * floor_m;
    }
    if weights > 0.0 {
        let floor = heights / weights + 0.08 * fine - q[2];
        wall.max(floor)
    } else {
        wall
    }
}

pub(crate) fn generate(seed: u64) -> WorldParts {
    let mut rng = Rng::new(combine(seed, 0xca5e));
    let mut graph: RoadGraph = jittered_grid(&mut rng, 6, 6, 75.0, 15.0, |x, y| {
        12.0 * value2(combine(seed, 21), x / 150.0, y / 150.0)
    });
    graph.prune(&mut rng, 0.35);
    // Meander every tunnel: lateral and vertical offsets that vanish at the junctions.
    for (e, (a, b, line)) in graph.edges.iter_mut().enumerate() {
        let (pa, pb) = (graph.nodes[*a], graph.nodes[*b]);
        let length = ((pb[0] - pa[0]).powi(2) + (pb[1] - pa[1]).powi(2)).sqrt();
        let (nx, ny) = (-(pb[1] - pa[1]) / length, (pb[0] - pa[0]) / length);
        let steps = (length / 4.0).ceil() as usize;
        let key = combine(seed, 100 + e as u64);
        *line = (0..=steps)
            .map(|k| {
                let t = k as f64 / steps as f64;
                let envelope = (std::f64::consts::PI * t).sin();
                let lateral = 9.0 * envelope * value2(key, t * 3.0, 0.5);
                let vertical = 2.0 * envelope * value2(key, t * 2.0, 7.5);
                [
                    pa[0] + (pb[0] - pa[0]) * t + nx * lateral,
                    pa[1] + (pb[1] - pa[1]) * t + ny * lateral,
                    pa[2] + (pb[2] - pa[2]) * t + vertical,
                ]
            })
            .collect();
    }
    let mut pieces = Vec::new();
    for (_, _, line) in &graph.edges {
        let radius_m = rng.range(2.8, 4.2);
        for w in line.windows(2) {
            pieces.push(Piece::Tunnel {
                a: w[0],
                b: w[1],
                radius_m,
            });
        }
    }
    for (n, adjacency) in graph.adjacency().iter().enumerate() {
        if adjacency.len() >= 3 && rng.chance(0.5) {
            pieces.push(Piece::Chamber {
                center: graph.nodes[n],
                radius_m: rng.range(6.5, 11.0),
            });
        }
    }
    let objects = surface_nets(seed, &pieces);
    let (mut x0, mut y0, mut x1, mut y1) =
        (f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY);
    for (_, _, line) in &graph.edges {
        for p in line {
            (x0, y0, x1, y1) = (x0.min(p[0]), y0.min(p[1]), x1.max(p[0]), y1.max(p[1]));
        }
    }
    WorldParts {
        terrain: None,
        objects,
        graph,
        extent_m: [x0 - 30.0, y0 - 30.0, x1 + 30.0, y1 + 30.0],
    }
}

type Key = (i32, i32, i32);

/// Meshes the union of `pieces` with naive surface nets on a sparse block grid.
fn surface_nets(seed: u64, pieces: &[Piece]) -> Mesh {
    let block_m = VOXEL_M * f64::from(BLOCK);
    let mut candidates: HashMap<Key, Vec<u32>> = HashMap::new();
    for (index, piece) in pieces.iter().enumerate() {
        let (lo, hi) = piece.bounds();
        // A block also samples the first lattice plane of its upper neighbours, hence the extra block.
        let range =
            |axis: usize| ((lo[axis] / block_m).floor() as i32 - 1)..=((hi[axis] / block_m).floor() as i32);
        for bz in range(2) {
            for by in range(1) {
                for bx in range(0) {
                    candidates.entry((bx, by, bz)).or_default().push(index as u32);
                }
            }
        }
    }
    let side = (BLOCK + 1) as usize;
    let coarse_seed = combine(seed, 31);
    let fine_seed = combine(seed, 32);
    // Distance values of each block on its (BLOCK + 1)³ lattice points, padded by one upper plane.
    let mut blocks: Vec<(Key, Vec<f32>)> = candidates
        .into_par_iter()
        .map(|(key, list)| {
            let mut values = vec![0.0f32; side * side * side];
            for (i, value) in values.iter_mut().enumerate() {
                let (lx, ly, lz) = (
                    (i % side) as i32,
                    ((i / side) % side) as i32,
                    (i / (side * side)) as i32,
                );
                let q = [
                    f64::from(key.0 * BLOCK + lx) * VOXEL_M,
                    f64::from(key.1 * BLOCK + ly) * VOXEL_M,
                    f64::from(key.2 * BLOCK + lz) * VOXEL_M,
                ];
                let coarse = fbm3(coarse_seed, q[0] / 7.0, q[1] / 7.0, q[2] / 7.0, 2, 0.5);
                let fine = value3(fine_seed, q[0] / 1.3, q[1] / 1.3, q[2] / 1.3);
                *value = union_distance(pieces, &list, q, coarse, fine) as f32;
            }
            (key, values)
        })
        .collect();
    blocks.sort_by_key(|(key, _)| *key);

    // One vertex per cell that the surface crosses, at the mean of its edge crossings.
    let corner = |c: usize| (c & 1, (c >> 1) & 1, (c >> 2) & 1);
    const EDGES: [(usize, usize); 12] = [
        (0, 1),
        (2, 3),
        (4, 5),
        (6, 7),
        (0, 2),
        (1, 3),
        (4, 6),
        (5, 7),
        (0, 4),
        (1, 5),
        (2, 6),
        (3, 7),
    ];
    let mut vertex_of: HashMap<Key, u32> = HashMap::new();
    let mut vertices: Vec<V3> = Vec::new();
    for (key, values) in &blocks {
        let at = |x: usize, y: usize, z: usize| values[(z * side + y) * side + x];
        for lz in 0..BLOCK as usize {
            for ly in 0..BLOCK as usize {
                for lx in 0..BLOCK as usize {
                    let v: [f32; 8] = std::array::from_fn(|c| {
                        let (dx, dy, dz) = corner(c);
                        at(lx + dx, ly + dy, lz + dz)
                    });
                    let inside = v.iter().filter(|&&x| x < 0.0).count();
                    if inside == 0 || inside == 8 {
                        continue;
                    }
                    let (mut sum, mut n) = (V3::default(), 0.0f32);
                    for (a, b) in EDGES {
                        if (v[a] < 0.0) != (v[b] < 0.0) {
                            let t = v[a] / (v[a] - v[b]);
                            let (ax, ay, az) = corner(a);
                            let (bx, by, bz) = corner(b);
                            let lerp = |p: usize, q: usize| p as f32 + t * (q as f32 - p as f32);
                            sum = sum + V3::new(lerp(ax, bx), lerp(ay, by), lerp(az, bz));
                            n += 1.0;
                        }
                    }
                    let cell = (
                        key.0 * BLOCK + lx as i32,
                        key.1 * BLOCK + ly as i32,
                        key.2 * BLOCK + lz as i32,
                    );
                    let local = sum * (1.0 / n);
                    let h = VOXEL_M as f32;
                    vertices.push(V3::new(
                        (cell.0 as f32 + local.x) * h,
                        (cell.1 as f32 + local.y) * h,
                        (cell.2 as f32 + local.z) * h,
                    ));
                    vertex_of.insert(cell, (vertices.len() - 1) as u32);
                }
            }
        }
    }

    // One quad per lattice edge with a sign change, joining the four cells around that edge.
    let mut mesh = Mesh::default();
    let material = Material::CaveRock as u8;
    for (key, values) in &blocks {
        let at = |x: usize, y: usize, z: usize| values[(z * side + y) * side + x];
        for lz in 0..BLOCK as usize {
            for ly in 0..BLOCK as usize {
                for lx in 0..BLOCK as usize {
                    let here = at(lx, ly, lz) < 0.0;
                    let p = (
                        key.0 * BLOCK + lx as i32,
                        key.1 * BLOCK + ly as i32,
                        key.2 * BLOCK + lz as i32,
                    );
                    let neighbours = [
                        (
                            at(lx + 1, ly, lz),
                            [(0, 0, 0), (0, -1, 0), (0, -1, -1), (0, 0, -1)],
                        ),
                        (
                            at(lx, ly + 1, lz),
                            [(0, 0, 0), (-1, 0, 0), (-1, 0, -1), (0, 0, -1)],
                        ),
                        (
                            at(lx, ly, lz + 1),
                            [(0, 0, 0), (-1, 0, 0), (-1, -1, 0), (0, -1, 0)],
                        ),
                    ];
                    for (value, cells) in neighbours {
                        if (value < 0.0) == here {
                            continue;
                        }
                        let quad: Option<Vec<V3>> = cells
                            .iter()
                            .map(|d| {
                                vertex_of
                                    .get(&(p.0 + d.0, p.1 + d.1, p.2 + d.2))
                                    .map(|&i| vertices[i as usize])
                            })
                            .collect();
                        if let Some(q) = quad {
                            mesh.push(q[0], q[1], q[2], material);
                            mesh.push(q[0], q[2], q[3], material);
                        }
                    }
                }
            }
        }
    }
    mesh
}
