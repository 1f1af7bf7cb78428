//! A bounding volume hierarchy over triangles, built with binned SAH (Wald, "On fast construction of
//! SAH-based bounding volume hierarchies", 2007) and traversed near-child-first with an explicit stack.
//!
//! Used for every object of every world (rocks, buildings, poles, cars, trees) and for the whole cave
//! mesh. A closest-point query serves tests that check simulated points lie on surfaces.

use crate::geometry::{Aabb, Ray, Tri, V3};

/// Number of SAH bins per axis.
const BINS: usize = 16;
/// Leaves hold at most this many triangles.
const MAX_LEAF: usize = 4;

/// A triangle soup with one material index per triangle.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    pub tris: Vec<Tri>,
    pub materials: Vec<u8>,
}

impl Mesh {
    pub fn push(&mut self, a: V3, b: V3, c: V3, material: u8) {
        self.tris.push(Tri::new(a, b, c));
        self.materials.push(material);
    }

    /// Appends another mesh.
    pub fn extend(&mut self, other: Mesh) {
        self.tris.extend(other.tris);
        self.materials.extend(other.materials);
    }

    pub fn len(&self) -> usize {
        self.tris.len()
    }

    pub fn is_empty(&self) -> bool {
        self.tris.is_empty()
    }
}

#[derive(Clone, Copy, Debug)]
struct Node {
    bounds: Aabb,
    /// First triangle of a leaf, or index of the left child (the right child follows it).
    first: u32,
    /// Triangle count of a leaf; 0 for an inner node.
    count: u32,
}

/// The closest intersection of a ray with a mesh.
#[derive(Clone, Copy, Debug)]
pub struct MeshHit {
    pub t: f32,
    pub triangle: u32,
}

/// A BVH owning its (reordered) triangles.
#[derive(Clone, Debug)]
pub struct Bvh {
    nodes: Vec<Node>,
    mesh: Mesh,
}

impl Bvh {
    /// Builds the hierarchy; triangles are reordered so every leaf is a contiguous range.
    pub fn build(mesh: Mesh) -> Self {
        let n = mesh.tris.len();
        let mut bounds: Vec<Aabb> = mesh
            .tris
            .iter()
            .map(|t| {
                let mut b = Aabb::EMPTY;
                t.vertices().into_iter().for_each(|v| b.grow(v));
                b
            })
            .collect();
        let mut centroids: Vec<V3> = bounds.iter().map(|b| (b.min + b.max) * 0.5).collect();
        let mut order: Vec<u32> = (0..n as u32).collect();
        let mut nodes = vec![Node {
            bounds: Aabb::EMPTY,
            first: 0,
            count: n as u32,
        }];
        let mut stack = vec![0usize];
        while let Some(index) = stack.pop() {
            let (first, count) = (nodes[index].first as usize, nodes[index].count as usize);
            let range = first..first + count;
            let node_bounds = order[range.clone()]
                .iter()
                .fold(Aabb::EMPTY, |acc, &i| acc.union(&bounds[i as usize]));
            nodes[index].bounds = node_bounds;
            if count <= MAX_LEAF {
                continue;
            }
            let Some(mid) = split(&mut order[range], &bounds, &centroids, node_bounds.half_area()) else {
                continue;
            };
            let left = nodes.len();
            nodes.push(Node {
                bounds: Aabb::EMPTY,
                first: first as u32,
                count: mid as u32,
            });
            nodes.push(Node {
                bounds: Aabb::EMPTY,
                first: (first + mid) as u32,
                count: (count - mid) as u32,
            });
            nodes[index] = Node {
                bounds: node_bounds,
                first: left as u32,
                count: 0,
            };
            stack.push(left);
            stack.push(left + 1);
        }
        let tris = order.iter().map(|&i| mesh.tris[i as usize]).collect();
        let materials = order.iter().map(|&i| mesh.materials[i as usize]).collect();
        bounds.clear();
        centroids.clear();
        Self {
            nodes,
            mesh: Mesh { tris, materials },
        }
    }

    /// The triangles, in BVH order (triangle indices of hits refer to this order).
    pub fn mesh(&self) -> &Mesh {
        &self.mesh
    }

    /// Bounds of everything, or `None` for an empty mesh.
    pub fn bounds(&self) -> Option<Aabb> {
        (!self.mesh.is_empty()).then(|| self.nodes[0].bounds)
    }

    /// The closest hit along `ray` before `t_max`.
    pub fn cast(&self, ray: &Ray, t_max: f32) -> Option<MeshHit> {
        if self.mesh.is_empty() {
            return None;
        }
        let mut best: Option<MeshHit> = None;
        let mut t_best = t_max;
        // Pending subtrees with the distance at which the ray enters them.
        let mut stack = [(0u32, 0.0f32); 64];
        let mut depth = 0usize;
        let mut node = &self.nodes[0];
        ray.slab(node.bounds.min, node.bounds.max, t_best)?;
        loop {
            if node.count > 0 {
                let first = node.first as usize;
                for (offset, tri) in self.mesh.tris[first..first + node.count as usize]
                    .iter()
                    .enumerate()
                {
                    if let Some(t) = tri.intersect(ray, t_best) {
                        t_best = t;
                        best = Some(MeshHit {
                            t,
                            triangle: (first + offset) as u32,
                        });
                    }
                }
            } else {
                let (a, b) = (node.first as usize, node.first as usize + 1);
                let ta = ray.slab(self.nodes[a].bounds.min, self.nodes[a].bounds.max, t_best);
                let tb = ray.slab(self.nodes[b].bounds.min, self.nodes[b].bounds.max, t_best);
                let next = match (ta, tb) {
                    (Some(ta), Some(tb)) => {
                        let (near, far, t_far) = if ta <= tb { (a, b, tb) } else { (b, a, ta) };
                        if depth < stack.len() {
                            stack[depth] = (far as u32, t_far);
                            depth += 1;
                        }
                        Some(near)
                    }
                    (Some(_), None) => Some(a),
                    (None, Some(_)) => Some(b),
                    (None, None) => None,
                };
                if let Some(next) = next {
                    node = &self.nodes[next];
                    continue;
                }
            }
            // Pop the next subtree the ray enters before the closest hit so far.
            loop {
                if depth == 0 {
                    return best;
                }
                depth -= 1;
                let (index, t_entry) = stack[depth];
                if t_entry <= t_best {
                    node = &self.nodes[index as usize];
                    break;
                }
            }
        }
    }

    /// The closest surface point to `p` within `max_distance`, as (distance, triangle).
    pub fn nearest(&self, p: V3, max_distance: f32) -> Option<(f32, u32)> {
        if self.mesh.is_empty() {
            return None;
        }
        let mut best_d2 = max_distance * max_distance;
        let mut best = None;
        let mut stack = vec![0u32];
        while let Some(index) = stack.pop() {
            let node = &self.nodes[index as usize];
            if node.bounds.distance_squared(p) > best_d2 {
                continue;
            }
            if node.count > 0 {
                for i in node.first..node.first + node.count {
                    let q = self.mesh.tris[i as usize].closest_point(p);
                    let d2 = (q - p).dot(q - p);
                    if d2 <= best_d2 {
                        best_d2 = d2;
                        best = Some((d2.sqrt(), i));
                    }
                }
            } else {
                stack.push(node.first);
                stack.push(node.first + 1);
            }
        }
        best
    }
}

/// Partitions `order` by the cheapest binned-SAH plane; returns the size of the left part, or `None`
/// when no split beats a leaf.
fn split(order: &mut [u32], bounds: &[Aabb], centroids: &[V3], parent_half_area: f32) -> Option<usize> {
    let mut centroid_bounds = Aabb::EMPTY;
    order
        .iter()
        .for_each(|&i| centroid_bounds.grow(centroids[i as usize]));
    let extent = centroid_bounds.max - centroid_bounds.min;
    let mut best: Option<(f32, usize, f32)> = None;
    for axis in 0..3 {
        let (low, size) = (centroid_bounds.min.axis(axis), extent.axis(axis));
        if size <= 1e-9 {
            continue;
        }
        let scale = BINS as f32 / size;
        let bin_of = |c: V3| (((c.axis(axis) - low) * scale) as usize).min(BINS - 1);
        let mut bin_bounds = [Aabb::EMPTY; BINS];
        let mut bin_counts = [0usize; BINS];
        for &i in order.iter() {
            let b = bin_of(centroids[i as usize]);
            bin_bounds[b] = bin_bounds[b].union(&bounds[i as usize]);
            bin_counts[b] += 1;
        }
        let mut right_area = [0.0f32; BINS];
        let mut right_count = [0usize; BINS];
        let (mut acc, mut n) = (Aabb::EMPTY, 0);
        for b in (1..BINS).rev() {
            acc = acc.union(&bin_bounds[b]);
            n += bin_counts[b];
            right_area[b] = acc.half_area();
            right_count[b] = n;
        }
        let (mut acc, mut n) = (Aabb::EMPTY, 0);
        for b in 0..BINS - 1 {
            acc = acc.union(&bin_bounds[b]);
            n += bin_counts[b];
            if n == 0 || right_count[b + 1] == 0 {
                continue;
            }
            let cost = acc.half_area() * n as f32 + right_area[b + 1] * right_count[b + 1] as f32;
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, low + (b + 1) as f32 / scale));
            }
        }
    }
    let (cost, axis, plane) = best?;
    // A leaf costs one intersection per triangle; an inner node one traversal step plus its children.
    if order.len() <= 16 && cost / parent_half_area.max(1e-12) + 0.5 >= order.len() as f32 {
        return None;
    }
    let mut left = 0;
    for i in 0..order.len() {
        if centroids[order[i] as usize].axis(axis) < plane {
            order.swap(i, left);
            left += 1;
        }
    }
    (left > 0 && left < order.len()).then_some(left)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    fn random_mesh(n: usize) -> Mesh {
        let mut rng = Rng::new(4);
        let mut mesh = Mesh::default();
        for _ in 0..n {
            let c = V3::from_f64(
                rng.range(-50.0, 50.0),
                rng.range(-50.0, 50.0),
                rng.range(-5.0, 5.0),
            );
            let a = c + V3::from_f64(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0));
            let b = c + V3::from_f64(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0));
            mesh.push(c, a, b, 0);
        }
        mesh
    }

    #[test]
    fn bvh_matches_brute_force() {
        let mesh = random_mesh(3000);
        let bvh = Bvh::build(mesh.clone());
        let mut rng = Rng::new(9);
        for _ in 0..500 {
            let origin = V3::from_f64(
                rng.range(-60.0, 60.0),
                rng.range(-60.0, 60.0),
                rng.range(-8.0, 8.0),
            );
            let dir = V3::from_f64(rng.gaussian(), rng.gaussian(), rng.gaussian()).normalized();
            let ray = Ray::new(origin, dir);
            let brute = mesh
                .tris
                .iter()
                .filter_map(|t| t.intersect(&ray, 200.0))
                .fold(f32::INFINITY, f32::min);
            let fast = bvh.cast(&ray, 200.0).map_or(f32::INFINITY, |h| h.t);
            assert_eq!(brute, fast);
            let (d, _) = bvh.nearest(origin, 1e4).unwrap_or((f32::NAN, 0));
            let brute_d = mesh
                .tris
                .iter()
                .map(|t| (t.closest_point(origin) - origin).norm())
                .fold(f32::INFINITY, f32::min);
            assert!((d - brute_d).abs() < 1e-4);
        }
    }
}
