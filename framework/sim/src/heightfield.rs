//! Terrain as a regular height field with a min/max mip-map: an implicit quadtree whose nodes are the
//! z-ranges of 2^k × 2^k cell blocks, so rays skip whole blocks they pass over ("maximum mipmaps",
//! Tevs, Ihrke and Seidel, I3D 2008). Each cell is two triangles split along its (0,0)–(1,1) diagonal,
//! exactly the surface [`HeightField::height_at`] interpolates, so rays and queries agree.

use crate::geometry::{Ray, Tri, V3, fast_max, fast_min};

/// A square height field of `cells` × `cells` cells (a power of two), `cell_m` metres each.
#[derive(Clone, Debug)]
pub struct HeightField {
    origin_x_m: f32,
    origin_y_m: f32,
    cell_m: f32,
    cells: usize,
    /// `(cells + 1)²` vertex heights, row-major in y.
    heights: Vec<f32>,
    /// One material per cell.
    materials: Vec<u8>,
    /// `levels[k]` holds (min, max) z of each 2^k × 2^k block, row-major.
    levels: Vec<Vec<[f32; 2]>>,
}

impl HeightField {
    /// Evaluates `height(x, y)` at every vertex of a `cells` × `cells` grid with lower corner `origin`,
    /// in parallel; the result is the `heights` argument of [`HeightField::new`].
    pub fn sample_vertices(
        origin_x_m: f64,
        origin_y_m: f64,
        cell_m: f64,
        cells: usize,
        height: impl Fn(f64, f64) -> f64 + Sync,
    ) -> Vec<f32> {
        use rayon::prelude::*;
        let side = cells + 1;
        (0..side * side)
            .into_par_iter()
            .map(|i| {
                height(
                    origin_x_m + (i % side) as f64 * cell_m,
                    origin_y_m + (i / side) as f64 * cell_m,
                ) as f32
            })
            .collect()
    }

    /// A height field whose lower corner is at `origin`, from `(cells + 1)²` row-major vertex heights and
    /// `cells²` cell materials. `cells` must be a power of two.
    pub fn new(
        origin_x_m: f64,
        origin_y_m: f64,
        cell_m: f64,
        cells: usize,
        heights: Vec<f32>,
        materials: Vec<u8>,
    ) -> Self {
        assert!(
            cells.is_power_of_two(),
            "height field size must be a power of two"
        );
        assert_eq!(heights.len(), (cells + 1) * (cells + 1), "one height per vertex");
        assert_eq!(materials.len(), cells * cells, "one material per cell");
        let side = cells + 1;
        let mut base = vec![[0.0f32; 2]; cells * cells];
        for j in 0..cells {
            for i in 0..cells {
                let h = [
                    heights[j * side + i],
                    heights[j * side + i + 1],
                    heights[(j + 1) * side + i],
                    heights[(j + 1) * side + i + 1],
                ];
                base[j * cells + i] = [
                    h.iter().copied().fold(f32::INFINITY, f32::min),
                    h.iter().copied().fold(f32::NEG_INFINITY, f32::max),
                ];
            }
        }
        let mut levels = vec![base];
        let mut size = cells;
        while size > 1 {
            let half = size / 2;
            let below = levels.last().map(Vec::as_slice).unwrap_or_default();
            let mut next = vec![[0.0f32; 2]; half * half];
            for j in 0..half {
                for i in 0..half {
                    let quads = [
                        below[2 * j * size + 2 * i],
                        below[2 * j * size + 2 * i + 1],
                        below[(2 * j + 1) * size + 2 * i],
                        below[(2 * j + 1) * size + 2 * i + 1],
                    ];
                    next[j * half + i] = [
                        quads.iter().map(|q| q[0]).fold(f32::INFINITY, f32::min),
                        quads.iter().map(|q| q[1]).fold(f32::NEG_INFINITY, f32::max),
                    ];
                }
            }
            levels.push(next);
            size = half;
        }
        Self {
            origin_x_m: origin_x_m as f32,
            origin_y_m: origin_y_m as f32,
            cell_m: cell_m as f32,
            cells,
            heights,
            materials,
            levels,
        }
    }

    /// Side length in metres.
    pub fn size_m(&self) -> f64 {
        f64::from(self.cell_m) * self.cells as f64
    }

    /// Lower x/y corner.
    pub fn origin_m(&self) -> (f64, f64) {
        (f64::from(self.origin_x_m), f64::from(self.origin_y_m))
    }

    /// Lowest and highest terrain height.
    pub fn z_range_m(&self) -> (f32, f32) {
        let top = self
            .levels
            .last()
            .and_then(|l| l.first())
            .copied()
            .unwrap_or([0.0, 0.0]);
        (top[0], top[1])
    }

    fn vertex(&self, i: usize, j: usize) -> V3 {
        V3::new(
            self.origin_x_m + i as f32 * self.cell_m,
            self.origin_y_m + j as f32 * self.cell_m,
            self.heights[j * (self.cells + 1) + i],
        )
    }

    /// The two triangles of cell (i, j).
    pub fn cell_triangles(&self, i: usize, j: usize) -> [Tri; 2] {
        let (p00, p10, p01, p11) = (
            self.vertex(i, j),
            self.vertex(i + 1, j),
            self.vertex(i, j + 1),
            self.vertex(i + 1, j + 1),
        );
        [Tri::new(p00, p10, p11), Tri::new(p00, p11, p01)]
    }

    /// The material of the cell containing (x, y), clamped to the field.
    pub fn material_at(&self, x: f32, y: f32) -> u8 {
        let (i, j) = self.cell_of(x, y);
        self.materials[j * self.cells + i]
    }

    fn cell_of(&self, x: f32, y: f32) -> (usize, usize) {
        let clamp = |v: f32| (v.max(0.0) as usize).min(self.cells - 1);
        (
            clamp((x - self.origin_x_m) / self.cell_m),
            clamp((y - self.origin_y_m) / self.cell_m),
        )
    }

    /// The surface height at (x, y), clamped to the field.
    pub fn height_at(&self, x: f64, y: f64) -> f64 {
        let (i, j) = self.cell_of(x as f32, y as f32);
        let fx = ((x - f64::from(self.origin_x_m)) / f64::from(self.cell_m) - i as f64).clamp(0.0, 1.0);
        let fy = ((y - f64::from(self.origin_y_m)) / f64::from(self.cell_m) - j as f64).clamp(0.0, 1.0);
        let side = self.cells + 1;
        let h = |a: usize, b: usize| f64::from(self.heights[b * side + a]);
        let (h00, h10, h01, h11) = (h(i, j), h(i + 1, j), h(i, j + 1), h(i + 1, j + 1));
        if fx >= fy {
            h00 + (h10 - h00) * fx + (h11 - h10) * fy
        } else {
            h00 + (h11 - h01) * fx + (h01 - h00) * fy
        }
    }

    /// Closest hit along `ray` before `t_max`: distance and the triangle hit.
    ///
    /// Maximum-mipmap traversal: walk the ray across the nodes of the current level in x/y order; a node
    /// whose highest point lies below the ray over the node's stretch of the ray is skipped whole (and
    /// the walk climbs a level when it leaves the parent), otherwise the walk descends; at the finest
    /// level the cell's two triangles are tested, and the first cell with a hit holds the closest hit.
    pub fn cast(&self, ray: &Ray, t_max: f32) -> Option<(f32, Tri)> {
        let size_m = self.cell_m * self.cells as f32;
        let (x0, y0) = (self.origin_x_m, self.origin_y_m);
        let clip = |o: f32, inv: f32, low: f32| {
            let (a, b) = ((low - o) * inv, (low + size_m - o) * inv);
            (a.min(b), a.max(b))
        };
        let (ax, bx) = clip(ray.origin.x, ray.inv_dir.x, x0);
        let (ay, by) = clip(ray.origin.y, ray.inv_dir.y, y0);
        let mut t = ax.max(ay).max(0.0);
        let mut t_end = bx.min(by).min(t_max);
        // Clip to the slab between the field's lowest and highest point as well: no surface lies above
        // or below it, and a ray the sensor casts upwards leaves it soon after it starts.
        let (z_low, z_high) = self.z_range_m();
        if ray.dir.z != 0.0 {
            let (az, bz) = (
                (z_low - ray.origin.z) * ray.inv_dir.z,
                (z_high - ray.origin.z) * ray.inv_dir.z,
            );
            t = t.max(az.min(bz));
            t_end = t_end.min(az.max(bz));
        } else if ray.origin.z > z_high || ray.origin.z < z_low {
            return None;
        }
        let top = self.levels.len() - 1;
        // Start a few levels up: sensors sit just above the ground, so the coarse nodes around the
        // origin always need descending; climbing on the way out restores the large skips.
        let mut level = top.min(3);
        const NUDGE: f32 = 1e-4;
        while t < t_end {
            let size = self.cell_m * (1u32 << level) as f32;
            let inv_size = 1.0 / size;
            let per_row = self.cells >> level;
            let p = ray.at(t + NUDGE);
            let i = (((p.x - x0) * inv_size).max(0.0) as usize).min(per_row - 1);
            let j = (((p.y - y0) * inv_size).max(0.0) as usize).min(per_row - 1);
            let next_x = x0
                + if ray.dir.x >= 0.0 {
                    (i + 1) as f32
                } else {
                    i as f32
                } * size;
            let next_y = y0
                + if ray.dir.y >= 0.0 {
                    (j + 1) as f32
                } else {
                    j as f32
                } * size;
            let tx = (next_x - ray.origin.x) * ray.inv_dir.x;
            let ty = (next_y - ray.origin.y) * ray.inv_dir.y;
            let t_exit = fast_max(fast_min(fast_min(tx, ty), t_end), t + NUDGE);
            let z_max = self.levels[level][j * per_row + i][1];
            let (z_in, z_out) = (ray.origin.z + ray.dir.z * t, ray.origin.z + ray.dir.z * t_exit);
            if fast_min(z_in, z_out) > z_max {
                // Leave the node; climb when the step also leaves the parent node.
                let crossing_x = tx <= ty;
                let (index, forward) = if crossing_x {
                    (i, ray.dir.x >= 0.0)
                } else {
                    (j, ray.dir.y >= 0.0)
                };
                let next = if forward { index + 1 } else { index.wrapping_sub(1) };
                if level < top && next >> 1 != index >> 1 {
                    level += 1;
                }
                t = t_exit;
            } else if level > 0 {
                level -= 1;
            } else {
                let mut best: Option<(f32, Tri)> = None;
                for tri in self.cell_triangles(i, j) {
                    if let Some(hit) = tri.intersect(ray, best.map_or(t_max, |b| b.0)) {
                        best = Some((hit, tri));
                    }
                }
                if best.is_some() {
                    return best;
                }
                t = t_exit;
            }
        }
        None
    }

    /// Closest hit by a plain stack traversal of the quadtree (the reference for tests).
    pub fn cast_reference(&self, ray: &Ray, t_max: f32) -> Option<(f32, Tri)> {
        let mut best: Option<(f32, Tri)> = None;
        let mut t_best = t_max;
        let top = self.levels.len() - 1;
        let mut stack = [(0u8, 0u16, 0u16); 96];
        stack[0] = (top as u8, 0, 0);
        let mut depth = 1;
        // Children are pushed far-first so the one nearest along the ray is popped first.
        let near_x = u16::from(ray.dir.x < 0.0);
        let near_y = u16::from(ray.dir.y < 0.0);
        let order = [
            (1 - near_x, 1 - near_y),
            (near_x, 1 - near_y),
            (1 - near_x, near_y),
            (near_x, near_y),
        ];
        while depth > 0 {
            depth -= 1;
            let (level, i, j) = stack[depth];
            let level = level as usize;
            let size = self.cell_m * (1u32 << level) as f32;
            let per_row = self.cells >> level;
            let [z_min, z_max] = self.levels[level][j as usize * per_row + i as usize];
            let min = V3::new(
                self.origin_x_m + f32::from(i) * size,
                self.origin_y_m + f32::from(j) * size,
                z_min,
            );
            let max = V3::new(min.x + size, min.y + size, z_max);
            if ray.slab(min, max, t_best).is_none() {
                continue;
            }
            if level == 0 {
                for tri in self.cell_triangles(i as usize, j as usize) {
                    if let Some(t) = tri.intersect(ray, t_best) {
                        t_best = t;
                        best = Some((t, tri));
                    }
                }
                continue;
            }
            for (di, dj) in order {
                stack[depth] = ((level - 1) as u8, 2 * i + di, 2 * j + dj);
                depth += 1;
            }
        }
        best
    }

    /// Distance from `p` to the terrain surface, searching cells within `radius_cells` of p's cell.
    pub fn distance_to_surface(&self, p: V3, radius_cells: usize) -> f32 {
        let (ci, cj) = self.cell_of(p.x, p.y);
        let mut best = f32::INFINITY;
        for j in cj.saturating_sub(radius_cells)..(cj + radius_cells + 1).min(self.cells) {
            for i in ci.saturating_sub(radius_cells)..(ci + radius_cells + 1).min(self.cells) {
                for tri in self.cell_triangles(i, j) {
                    best = best.min((tri.closest_point(p) - p).norm());
                }
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    #[test]
    fn cast_matches_brute_force_and_height() {
        let heights = HeightField::sample_vertices(-32.0, -32.0, 1.0, 64, |x, y| {
            (x * 0.3).sin() * 2.0 + (y * 0.17).cos() * 3.0
        });
        let field = HeightField::new(-32.0, -32.0, 1.0, 64, heights, vec![1; 64 * 64]);
        let mut rng = Rng::new(2);
        for _ in 0..300 {
            let origin = V3::from_f64(
                rng.range(-40.0, 40.0),
                rng.range(-40.0, 40.0),
                rng.range(3.0, 10.0),
            );
            let dir = V3::from_f64(rng.gaussian(), rng.gaussian(), rng.gaussian() - 0.5).normalized();
            let ray = Ray::new(origin, dir);
            let mut brute = f32::INFINITY;
            for j in 0..64 {
                for i in 0..64 {
                    for tri in field.cell_triangles(i, j) {
                        if let Some(t) = tri.intersect(&ray, 200.0) {
                            brute = brute.min(t);
                        }
                    }
                }
            }
            let fast = field.cast(&ray, 200.0).map_or(f32::INFINITY, |h| h.0);
            let reference = field.cast_reference(&ray, 200.0).map_or(f32::INFINITY, |h| h.0);
            assert_eq!(brute, reference);
            assert_eq!(brute, fast);
            if fast.is_finite() {
                let p = ray.at(fast);
                assert!((field.height_at(f64::from(p.x), f64::from(p.y)) - f64::from(p.z)).abs() < 1e-3);
            }
        }
    }
}
