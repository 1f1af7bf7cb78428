//! Mesh builders for world objects: oriented boxes (buildings, cars), prisms (poles, trunks) and
//! irregular rocks made from jittered icospheres (an icosahedron refined by edge midpoints).

use std::collections::HashMap;

use crate::bvh::Mesh;
use crate::geometry::V3;
use crate::rng::Rng;

/// Adds a box with centre `center`, half extents `half` (before the yaw) and yaw `yaw_rad` about z.
pub fn add_box(mesh: &mut Mesh, center: V3, half: V3, yaw_rad: f32, material: u8) {
    let (s, c) = yaw_rad.sin_cos();
    let corner = |sx: f32, sy: f32, sz: f32| {
        let (x, y) = (sx * half.x, sy * half.y);
        center + V3::new(c * x - s * y, s * x + c * y, sz * half.z)
    };
    let v: Vec<V3> = (0..8)
        .map(|i| {
            corner(
                if i & 1 == 0 { -1.0 } else { 1.0 },
                if i & 2 == 0 { -1.0 } else { 1.0 },
                if i & 4 == 0 { -1.0 } else { 1.0 },
            )
        })
        .collect();
    let faces = [
        [0, 1, 3, 2],
        [4, 6, 7, 5],
        [0, 4, 5, 1],
        [2, 3, 7, 6],
        [0, 2, 6, 4],
        [1, 5, 7, 3],
    ];
    for [a, b, c, d] in faces {
        mesh.push(v[a], v[b], v[c], material);
        mesh.push(v[a], v[c], v[d], material);
    }
}

/// Adds a closed vertical prism with `sides` sides: radius `radius_m`, from `base` up `height_m`.
pub fn add_prism(mesh: &mut Mesh, base: V3, radius_m: f32, height_m: f32, sides: usize, material: u8) {
    let ring = |k: usize, z: f32| {
        let a = k as f32 / sides as f32 * std::f32::consts::TAU;
        base + V3::new(radius_m * a.cos(), radius_m * a.sin(), z)
    };
    let top = base + V3::new(0.0, 0.0, height_m);
    for k in 0..sides {
        let (a0, a1, b0, b1) = (
            ring(k, 0.0),
            ring(k + 1, 0.0),
            ring(k, height_m),
            ring(k + 1, height_m),
        );
        mesh.push(a0, a1, b1, material);
        mesh.push(a0, b1, b0, material);
        mesh.push(b0, b1, top, material);
    }
}

/// Unit icosphere: vertices and triangles after `subdivisions` midpoint refinements.
pub fn icosphere(subdivisions: u32) -> (Vec<V3>, Vec<[usize; 3]>) {
    let t = (1.0 + 5.0f32.sqrt()) / 2.0;
    let mut vertices: Vec<V3> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| V3::new(x, y, z).normalized())
    .collect();
    let mut faces = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut midpoints: HashMap<(usize, usize), usize> = HashMap::new();
        let mut midpoint = |a: usize, b: usize, vertices: &mut Vec<V3>| {
            *midpoints.entry((a.min(b), a.max(b))).or_insert_with(|| {
                vertices.push(((vertices[a] + vertices[b]) * 0.5).normalized());
                vertices.len() - 1
            })
        };
        let mut next = Vec::with_capacity(faces.len() * 4);
        for [a, b, c] in faces {
            let ab = midpoint(a, b, &mut vertices);
            let bc = midpoint(b, c, &mut vertices);
            let ca = midpoint(c, a, &mut vertices);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        faces = next;
    }
    (vertices, faces)
}

/// Adds an irregular rock or blob: an icosphere with radii `radii`, each vertex pushed in or out by up
/// to `roughness` of its radius, turned by a random yaw.
pub fn add_blob(
    mesh: &mut Mesh,
    rng: &mut Rng,
    center: V3,
    radii: V3,
    subdivisions: u32,
    roughness: f32,
    material: u8,
) {
    let (vertices, faces) = icosphere(subdivisions);
    let yaw = rng.range(0.0, std::f64::consts::TAU) as f32;
    let (s, c) = yaw.sin_cos();
    let placed: Vec<V3> = vertices
        .iter()
        .map(|v| {
            let k = 1.0 + roughness * rng.range(-1.0, 1.0) as f32;
            let (x, y, z) = (v.x * radii.x * k, v.y * radii.y * k, v.z * radii.z * k);
            center + V3::new(c * x - s * y, s * x + c * y, z)
        })
        .collect();
    for [a, b, cc] in faces {
        mesh.push(placed[a], placed[b], placed[cc], material);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shapes_have_expected_triangle_counts() {
        let mut mesh = Mesh::default();
        add_box(&mut mesh, V3::default(), V3::new(1.0, 2.0, 3.0), 0.3, 0);
        assert_eq!(mesh.len(), 12);
        add_prism(&mut mesh, V3::default(), 0.2, 5.0, 8, 0);
        assert_eq!(mesh.len(), 12 + 24);
        let (v, f) = icosphere(1);
        assert_eq!((v.len(), f.len()), (42, 80));
    }
}
