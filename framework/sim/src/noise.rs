//! Procedural noise: lattice value noise with quintic interpolation, fractal Brownian motion (fBm) and
//! ridged multifractal noise (Musgrave, "Texturing and Modeling: A Procedural Approach", ch. 16).
//!
//! Lattice values come from hashing integer coordinates with the seed, so noise needs no tables and is
//! identical on every machine.

use crate::rng::{combine, mix};

/// Quintic fade 6t⁵ − 15t⁴ + 10t³ (Perlin 2002), C2-continuous across lattice cells.
fn fade(t: f64) -> f64 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

fn lattice2(seed: u64, x: i64, y: i64) -> f64 {
    let h = combine(combine(seed, x as u64), y as u64);
    (h >> 11) as f64 * (2.0 / (1u64 << 53) as f64) - 1.0
}

fn lattice3(seed: u64, x: i64, y: i64, z: i64) -> f64 {
    let h = mix(combine(combine(seed, x as u64), y as u64) ^ (z as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15));
    (h >> 11) as f64 * (2.0 / (1u64 << 53) as f64) - 1.0
}

/// 2D value noise in [-1, 1].
pub fn value2(seed: u64, x: f64, y: f64) -> f64 {
    let (x0, y0) = (x.floor(), y.floor());
    let (ix, iy) = (x0 as i64, y0 as i64);
    let (u, v) = (fade(x - x0), fade(y - y0));
    let a = lattice2(seed, ix, iy);
    let b = lattice2(seed, ix + 1, iy);
    let c = lattice2(seed, ix, iy + 1);
    let d = lattice2(seed, ix + 1, iy + 1);
    let top = a + (b - a) * u;
    let bottom = c + (d - c) * u;
    top + (bottom - top) * v
}

/// 3D value noise in [-1, 1].
pub fn value3(seed: u64, x: f64, y: f64, z: f64) -> f64 {
    let (x0, y0, z0) = (x.floor(), y.floor(), z.floor());
    let (ix, iy, iz) = (x0 as i64, y0 as i64, z0 as i64);
    let (u, v, w) = (fade(x - x0), fade(y - y0), fade(z - z0));
    let mut layers = [0.0; 2];
    for (dz, layer) in layers.iter_mut().enumerate() {
        let z = iz + dz as i64;
        let a = lattice3(seed, ix, iy, z);
        let b = lattice3(seed, ix + 1, iy, z);
        let c = lattice3(seed, ix, iy + 1, z);
        let d = lattice3(seed, ix + 1, iy + 1, z);
        let top = a + (b - a) * u;
        let bottom = c + (d - c) * u;
        *layer = top + (bottom - top) * v;
    }
    layers[0] + (layers[1] - layers[0]) * w
}

/// 2D fBm: `octaves` layers of value noise, each at twice the frequency and `gain` times the amplitude
/// of the previous one. The result is roughly in [-1, 1].
pub fn fbm2(seed: u64, x: f64, y: f64, octaves: u32, gain: f64) -> f64 {
    let (mut sum, mut amplitude, mut frequency, mut norm) = (0.0, 1.0, 1.0, 0.0);
    for octave in 0..octaves {
        sum += amplitude * value2(combine(seed, u64::from(octave)), x * frequency, y * frequency);
        norm += amplitude;
        amplitude *= gain;
        frequency *= 2.0;
    }
    sum / norm
}

/// 3D fBm, as [`fbm2`].
pub fn fbm3(seed: u64, x: f64, y: f64, z: f64, octaves: u32, gain: f64) -> f64 {
    let (mut sum, mut amplitude, mut frequency, mut norm) = (0.0, 1.0, 1.0, 0.0);
    for octave in 0..octaves {
        let s = combine(seed, u64::from(octave));
        sum += amplitude * value3(s, x * frequency, y * frequency, z * frequency);
        norm += amplitude;
        amplitude *= gain;
        frequency *= 2.0;
    }
    sum / norm
}

/// 2D ridged multifractal in [0, 1]: sharp crests where the underlying noise crosses zero, giving
/// ridge lines such as wrinkle ridges on planetary plains.
pub fn ridged2(seed: u64, x: f64, y: f64, octaves: u32) -> f64 {
    let (mut sum, mut amplitude, mut frequency, mut norm, mut weight) = (0.0, 1.0, 1.0, 0.0, 1.0);
    for octave in 0..octaves {
        let n = 1.0 - value2(combine(seed, u64::from(octave)), x * frequency, y * frequency).abs();
        let signal = n * n * weight;
        weight = (signal * 2.0).clamp(0.0, 1.0);
        sum += signal * amplitude;
        norm += amplitude;
        amplitude *= 0.5;
        frequency *= 2.0;
    }
    sum / norm
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noise_is_bounded_continuous_and_seeded() {
        for i in 0..500 {
            let x = i as f64 * 0.37;
            let v = fbm2(5, x, -x * 0.5, 5, 0.5);
            assert!((-1.0..=1.0).contains(&v));
            let near = fbm2(5, x + 1e-4, -x * 0.5, 5, 0.5);
            assert!((v - near).abs() < 1e-2);
            assert!((0.0..=1.0).contains(&ridged2(5, x, x, 4)));
            assert!((-1.0..=1.0).contains(&fbm3(5, x, 1.0, -x, 3, 0.5)));
        }
        assert_ne!(value2(1, 0.5, 0.5), value2(2, 0.5, 0.5));
        assert_eq!(value2(1, 0.5, 0.5), value2(1, 0.5, 0.5));
    }
}
