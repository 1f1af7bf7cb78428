//! A small mixed-radix FFT for the LiDAR-Iris filters and shift estimation (Wang et al., IROS 2020): the
//! iris image is 360 columns wide (2³·3²·5), which a radix-2 transform cannot take.
//!
//! Recursive decimation-in-time Cooley–Tukey over the prime factors of n, with a naive DFT butterfly per
//! factor, so any length works; the cost is O(n · Σ factors), e.g. 6,120 complex products for n = 360.

use nalgebra::Complex;

pub type C32 = Complex<f32>;

/// A planned transform of one length.
#[derive(Clone, Debug)]
pub struct Fft {
    len: usize,
    factors: Vec<usize>,
    /// e^{−2πik/n} for k in 0..n.
    twiddles: Vec<C32>,
}

impl Fft {
    /// A transform of `len` (≥ 1) points.
    pub fn new(len: usize) -> Self {
        let len = len.max(1);
        let mut factors = Vec::new();
        let mut rest = len;
        let mut p = 2;
        while rest > 1 {
            if p * p > rest {
                factors.push(rest);
                break;
            }
            while rest.is_multiple_of(p) {
                factors.push(p);
                rest /= p;
            }
            p += 1;
        }
        let twiddles = (0..len)
            .map(|k| {
                let angle = -std::f64::consts::TAU * k as f64 / len as f64;
                C32::new(angle.cos() as f32, angle.sin() as f32)
            })
            .collect();
        Self {
            len,
            factors,
            twiddles,
        }
    }

    pub fn len(&self) -> usize {
        self.len
    }

    /// The forward transform X[k] = Σ x[j] e^{−2πijk/n} of `input` into `output` (both of `len()`).
    pub fn forward(&self, input: &[C32], output: &mut [C32]) {
        let mut scratch = Vec::new();
        self.work(output, input, 1, &self.factors, &mut scratch);
    }

    /// The inverse transform x[j] = (1/n) Σ X[k] e^{2πijk/n}, in place.
    pub fn inverse_in_place(&self, data: &mut [C32]) {
        let conjugated: Vec<C32> = data.iter().map(|c| c.conj()).collect();
        self.forward(&conjugated, data);
        let scale = 1.0 / self.len as f32;
        data.iter_mut().for_each(|c| *c = c.conj() * scale);
    }

    fn work(&self, out: &mut [C32], input: &[C32], stride: usize, factors: &[usize], scratch: &mut Vec<C32>) {
        let len = out.len();
        let Some((&p, rest)) = factors.split_first() else {
            if let (Some(o), Some(i)) = (out.first_mut(), input.first()) {
                *o = *i;
            }
            return;
        };
        let m = len / p;
        if m == 1 {
            for (q, o) in out.iter_mut().enumerate() {
                *o = input[q * stride];
            }
        } else {
            for q in 0..p {
                self.work(
                    &mut out[q * m..(q + 1) * m],
                    &input[q * stride..],
                    stride * p,
                    rest,
                    scratch,
                );
            }
        }
        // Combine p interleaved sub-transforms of length m into one of length len = p·m:
        // X[k + q1·m] = Σ_q (sub_q[k] · W_len^{q·k}) · W_p^{q·q1}. The indices below stay under n without
        // a division: q·k·step < p·m·step = n, and W_p^{j} is twiddle j·(n/p) for j = q·q1 mod p.
        let step = self.len / len;
        let p_step = self.len / p;
        scratch.resize(p, C32::new(0.0, 0.0));
        for k in 0..m {
            for (q, s) in scratch.iter_mut().enumerate() {
                *s = out[k + q * m] * self.twiddles[q * k * step];
            }
            for q1 in 0..p {
                let mut sum = C32::new(0.0, 0.0);
                let mut j = 0;
                for s in scratch.iter() {
                    sum += *s * self.twiddles[j * p_step];
                    j += q1;
                    if j >= p {
                        j -= p;
                    }
                }
                out[k + q1 * m] = sum;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn naive(input: &[C32]) -> Vec<C32> {
        let n = input.len();
        (0..n)
            .map(|k| {
                input
                    .iter()
                    .enumerate()
                    .fold(Complex::<f64>::new(0.0, 0.0), |acc, (j, x)| {
                        let angle = -std::f64::consts::TAU * (j * k) as f64 / n as f64;
                        acc + Complex::new(f64::from(x.re), f64::from(x.im))
                            * Complex::new(angle.cos(), angle.sin())
                    })
            })
            .map(|c| C32::new(c.re as f32, c.im as f32))
            .collect()
    }

    #[test]
    fn matches_the_naive_dft_for_many_lengths() {
        for n in [1usize, 2, 3, 7, 8, 12, 30, 49, 97, 360] {
            let input: Vec<C32> = (0..n)
                .map(|j| C32::new((j as f32 * 0.7).sin(), (j as f32 * 0.3).cos() * 0.5))
                .collect();
            let fft = Fft::new(n);
            let mut output = vec![C32::new(0.0, 0.0); n];
            fft.forward(&input, &mut output);
            for (a, b) in output.iter().zip(naive(&input)) {
                assert!((a - b).norm() < 1e-3 * (n as f32).sqrt(), "n = {n}: {a} vs {b}");
            }
            let mut back = output.clone();
            fft.inverse_in_place(&mut back);
            for (a, b) in back.iter().zip(&input) {
                assert!((a - b).norm() < 1e-4, "n = {n} inverse");
            }
        }
    }
}
