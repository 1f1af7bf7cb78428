//! Small single-precision geometry for the ray caster: vectors, rays, boxes, the Möller–Trumbore
//! ray–triangle test (Möller and Trumbore, "Fast, minimum storage ray-triangle intersection", 1997) and
//! the closest point on a triangle (Ericson, "Real-Time Collision Detection", §5.1.5).
//!
//! World coordinates stay within a few kilometres of the origin, where f32 resolves 0.1 mm, far below
//! any sensor's range noise; poses and trajectories stay in f64.

use std::ops::{Add, Mul, Sub};

/// A 3-vector of f32.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct V3 {
    pub x: f32,
    pub y: f32,
    pub z: f32,
}

impl V3 {
    pub const fn new(x: f32, y: f32, z: f32) -> Self {
        Self { x, y, z }
    }

    /// From f64 coordinates.
    pub fn from_f64(x: f64, y: f64, z: f64) -> Self {
        Self::new(x as f32, y as f32, z as f32)
    }

    pub fn dot(self, o: Self) -> f32 {
        self.x * o.x + self.y * o.y + self.z * o.z
    }

    pub fn cross(self, o: Self) -> Self {
        Self::new(
            self.y * o.z - self.z * o.y,
            self.z * o.x - self.x * o.z,
            self.x * o.y - self.y * o.x,
        )
    }

    pub fn norm(self) -> f32 {
        self.dot(self).sqrt()
    }

    /// The unit vector along `self`, or `self` when it is zero.
    pub fn normalized(self) -> Self {
        let n = self.norm();
        if n > 0.0 { self * (1.0 / n) } else { self }
    }

    pub fn min(self, o: Self) -> Self {
        Self::new(self.x.min(o.x), self.y.min(o.y), self.z.min(o.z))
    }

    pub fn max(self, o: Self) -> Self {
        Self::new(self.x.max(o.x), self.y.max(o.y), self.z.max(o.z))
    }

    /// Component `axis` (0 = x, 1 = y, 2 = z).
    pub fn axis(self, axis: usize) -> f32 {
        match axis {
            0 => self.x,
            1 => self.y,
            _ => self.z,
        }
    }
}

impl Add for V3 {
    type Output = Self;
    fn add(self, o: Self) -> Self {
        Self::new(self.x + o.x, self.y + o.y, self.z + o.z)
    }
}

impl Sub for V3 {
    type Output = Self;
    fn sub(self, o: Self) -> Self {
        Self::new(self.x - o.x, self.y - o.y, self.z - o.z)
    }
}

impl Mul<f32> for V3 {
    type Output = Self;
    fn mul(self, s: f32) -> Self {
        Self::new(self.x * s, self.y * s, self.z * s)
    }
}

/// A ray with its precomputed reciprocal direction for slab tests.
#[derive(Clone, Copy, Debug)]
pub struct Ray {
    pub origin: V3,
    /// Unit direction.
    pub dir: V3,
    pub inv_dir: V3,
}

impl Ray {
    /// A ray from `origin` along the unit vector `dir`.
    pub fn new(origin: V3, dir: V3) -> Self {
        let inv = |d: f32| {
            if d.abs() > 1e-12 {
                1.0 / d
            } else {
                1e12_f32.copysign(d)
            }
        };
        Self {
            origin,
            dir,
            inv_dir: V3::new(inv(dir.x), inv(dir.y), inv(dir.z)),
        }
    }

    pub fn at(&self, t: f32) -> V3 {
        self.origin + self.dir * t
    }

    /// Entry distance of the ray into the box `[min, max]` within `[0, t_max]`, if it enters.
    #[inline]
    pub fn slab(&self, min: V3, max: V3, t_max: f32) -> Option<f32> {
        let tx1 = (min.x - self.origin.x) * self.inv_dir.x;
        let tx2 = (max.x - self.origin.x) * self.inv_dir.x;
        let ty1 = (min.y - self.origin.y) * self.inv_dir.y;
        let ty2 = (max.y - self.origin.y) * self.inv_dir.y;
        let tz1 = (min.z - self.origin.z) * self.inv_dir.z;
        let tz2 = (max.z - self.origin.z) * self.inv_dir.z;
        let t_near = fast_max(
            fast_max(fast_min(tx1, tx2), fast_min(ty1, ty2)),
            fast_max(fast_min(tz1, tz2), 0.0),
        );
        let t_far = fast_min(
            fast_min(fast_max(tx1, tx2), fast_max(ty1, ty2)),
            fast_min(fast_max(tz1, tz2), t_max),
        );
        (t_near <= t_far).then_some(t_near)
    }
}

/// Minimum without NaN handling, which compiles to a single `minss` (f32::min's NaN rules cost several
/// instructions in the ray caster's innermost loop; ray arithmetic never produces NaN here).
#[inline(always)]
pub fn fast_min(a: f32, b: f32) -> f32 {
    if a < b { a } else { b }
}

/// Maximum without NaN handling (see [`fast_min`]).
#[inline(always)]
pub fn fast_max(a: f32, b: f32) -> f32 {
    if a > b { a } else { b }
}

/// An axis-aligned box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    pub min: V3,
    pub max: V3,
}

impl Aabb {
    /// The empty box (grows from nothing).
    pub const EMPTY: Self = Self {
        min: V3::new(f32::INFINITY, f32::INFINITY, f32::INFINITY),
        max: V3::new(f32::NEG_INFINITY, f32::NEG_INFINITY, f32::NEG_INFINITY),
    };

    pub fn grow(&mut self, p: V3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }

    pub fn union(&self, o: &Self) -> Self {
        Self {
            min: self.min.min(o.min),
            max: self.max.max(o.max),
        }
    }

    /// Half the surface area (the SAH only needs ratios); 0 for an empty box.
    pub fn half_area(&self) -> f32 {
        let d = self.max - self.min;
        if d.x < 0.0 {
            0.0
        } else {
            d.x * d.y + d.y * d.z + d.z * d.x
        }
    }

    /// Squared distance from `p` to the box (0 inside).
    pub fn distance_squared(&self, p: V3) -> f32 {
        let d = (self.min - p).max(p - self.max).max(V3::default());
        d.dot(d)
    }
}

/// A triangle stored for Möller–Trumbore: a vertex and the two edges from it.
#[derive(Clone, Copy, Debug)]
pub struct Tri {
    pub v0: V3,
    pub e1: V3,
    pub e2: V3,
}

impl Tri {
    pub fn new(a: V3, b: V3, c: V3) -> Self {
        Self {
            v0: a,
            e1: b - a,
            e2: c - a,
        }
    }

    pub fn vertices(&self) -> [V3; 3] {
        [self.v0, self.v0 + self.e1, self.v0 + self.e2]
    }

    /// The unit normal (right-handed in vertex order).
    pub fn normal(&self) -> V3 {
        self.e1.cross(self.e2).normalized()
    }

    /// Distance along the ray to the triangle, if hit within (`1e-5`, `t_max`). Both sides count.
    #[inline]
    pub fn intersect(&self, ray: &Ray, t_max: f32) -> Option<f32> {
        let p = ray.dir.cross(self.e2);
        let det = self.e1.dot(p);
        if det.abs() < 1e-12 {
            return None;
        }
        let inv_det = 1.0 / det;
        let s = ray.origin - self.v0;
        let u = s.dot(p) * inv_det;
        if !(0.0..=1.0).contains(&u) {
            return None;
        }
        let q = s.cross(self.e1);
        let v = ray.dir.dot(q) * inv_det;
        if v < 0.0 || u + v > 1.0 {
            return None;
        }
        let t = self.e2.dot(q) * inv_det;
        (t > 1e-5 && t < t_max).then_some(t)
    }

    /// The closest point of the triangle to `p`.
    pub fn closest_point(&self, p: V3) -> V3 {
        let [a, b, c] = self.vertices();
        let (ab, ac, ap) = (b - a, c - a, p - a);
        let (d1, d2) = (ab.dot(ap), ac.dot(ap));
        if d1 <= 0.0 && d2 <= 0.0 {
            return a;
        }
        let bp = p - b;
        let (d3, d4) = (ab.dot(bp), ac.dot(bp));
        if d3 >= 0.0 && d4 <= d3 {
            return b;
        }
        let vc = d1 * d4 - d3 * d2;
        if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
            return a + ab * (d1 / (d1 - d3));
        }
        let cp = p - c;
        let (d5, d6) = (ab.dot(cp), ac.dot(cp));
        if d6 >= 0.0 && d5 <= d6 {
            return c;
        }
        let vb = d5 * d2 - d1 * d6;
        if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
            return a + ac * (d2 / (d2 - d6));
        }
        let va = d3 * d6 - d5 * d4;
        if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
            return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
        }
        let denom = 1.0 / (va + vb + vc);
        a + ab * (vb * denom) + ac * (vc * denom)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ray_hits_triangle_from_both_sides() {
        let tri = Tri::new(
            V3::new(0.0, -1.0, -1.0),
            V3::new(0.0, 1.0, -1.0),
            V3::new(0.0, 0.0, 1.0),
        );
        let front = Ray::new(V3::new(-2.0, 0.0, 0.0), V3::new(1.0, 0.0, 0.0));
        let back = Ray::new(V3::new(2.0, 0.0, 0.0), V3::new(-1.0, 0.0, 0.0));
        assert!((tri.intersect(&front, 10.0).unwrap_or(0.0) - 2.0).abs() < 1e-6);
        assert!((tri.intersect(&back, 10.0).unwrap_or(0.0) - 2.0).abs() < 1e-6);
        assert!(tri.intersect(&front, 1.5).is_none());
        let miss = Ray::new(V3::new(-2.0, 3.0, 0.0), V3::new(1.0, 0.0, 0.0));
        assert!(tri.intersect(&miss, 10.0).is_none());
    }

    #[test]
    fn closest_point_regions() {
        let tri = Tri::new(
            V3::new(0.0, 0.0, 0.0),
            V3::new(1.0, 0.0, 0.0),
            V3::new(0.0, 1.0, 0.0),
        );
        let inner = tri.closest_point(V3::new(0.2, 0.2, 5.0));
        assert!((inner - V3::new(0.2, 0.2, 0.0)).norm() < 1e-6);
        assert_eq!(
            tri.closest_point(V3::new(-1.0, -1.0, 0.0)),
            V3::new(0.0, 0.0, 0.0)
        );
        let edge = tri.closest_point(V3::new(1.0, 1.0, 0.0));
        assert!((edge.x - 0.5).abs() < 1e-6 && (edge.y - 0.5).abs() < 1e-6);
    }

    #[test]
    fn slab_enters_and_misses() {
        let ray = Ray::new(V3::new(-5.0, 0.5, 0.5), V3::new(1.0, 0.0, 0.0));
        let (min, max) = (V3::new(0.0, 0.0, 0.0), V3::new(1.0, 1.0, 1.0));
        assert_eq!(ray.slab(min, max, 100.0), Some(5.0));
        assert_eq!(ray.slab(min, max, 4.0), None);
        let up = Ray::new(V3::new(-5.0, 0.5, 0.5), V3::new(0.0, 0.0, 1.0));
        assert_eq!(up.slab(min, max, 100.0), None);
    }
}
