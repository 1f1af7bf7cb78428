//! LiDAR-Iris features (Wang et al., IROS 2020, after Daugman's and Masek's iris codes): each image row
//! is filtered along azimuth by 1-D log-Gabor filters, whose complex responses are binarised into a
//! template and a mask; and the azimuth shift between two images is estimated by phase correlation.
//!
//! Definitions, as this plugin implements them:
//! - Filter of scale s (0-based): centre frequency f₀ = 1 / (min_wavelength · multiplier^s) cycles per
//!   column; G(f) = exp(−ln(f / f₀)² / (2 ln(σ/f)²)) for the positive frequencies f = u / N,
//!   u = 1..=N/2, and 0 at DC and for negative frequencies (the response is analytic, so its real and
//!   imaginary parts are the even and odd filter outputs).
//! - The row's code values (0..=255, as numbers) are filtered: E_s = IFFT(FFT(row) · G_s).
//! - Template byte of a pixel: bit 2s = (Re E_s > 0), bit 2s + 1 = (Im E_s > 0); mask byte: both bits
//!   of scale s set when |E_s| < mask_epsilon (no signal: those bits are not compared). With 4 scales a
//!   pixel's 8 template bits and 8 mask bits fit one byte each.
//! - Shift estimate: R(u) = Σ_rows Q_row(u) · conj(C_row(u)), normalised to unit modulus where non-zero;
//!   the column of the largest real part of IFFT(R) is the shift s with query column j ≈ candidate
//!   column j − s.

use crate::fft::{C32, Fft};

/// The template and mask of an image, one byte per pixel (row-major).
#[derive(Clone, Debug, PartialEq)]
pub struct Features {
    pub template: Vec<u8>,
    pub mask: Vec<u8>,
}

/// Log-Gabor filters for one image width.
#[derive(Clone, Debug)]
pub struct FilterBank {
    fft: Fft,
    /// One frequency response of `columns` values per scale.
    filters: Vec<Vec<f32>>,
    mask_epsilon: f32,
}

impl FilterBank {
    pub fn new(
        columns: usize,
        num_scales: usize,
        min_wavelength: f64,
        multiplier: f64,
        sigma_on_f: f64,
        mask_epsilon: f64,
    ) -> Self {
        let log_sigma_sq = 2.0 * sigma_on_f.ln().powi(2);
        let filters = (0..num_scales)
            .map(|s| {
                let centre = 1.0 / (min_wavelength * multiplier.powi(s as i32));
                (0..columns)
                    .map(|u| {
                        if u == 0 || 2 * u > columns {
                            return 0.0;
                        }
                        let f = u as f64 / columns as f64;
                        (-(f / centre).ln().powi(2) / log_sigma_sq).exp() as f32
                    })
                    .collect()
            })
            .collect();
        Self {
            fft: Fft::new(columns),
            filters,
            mask_epsilon: mask_epsilon as f32,
        }
    }

    fn columns(&self) -> usize {
        self.fft.len()
    }

    /// The spectrum of every row of a code image, row-major.
    pub fn spectra(&self, codes: &[u8]) -> Vec<C32> {
        let n = self.columns();
        let mut out = vec![C32::new(0.0, 0.0); codes.len()];
        let mut row_in = vec![C32::new(0.0, 0.0); n];
        for (row, spectrum) in codes.chunks_exact(n).zip(out.chunks_exact_mut(n)) {
            for (c, &code) in row_in.iter_mut().zip(row) {
                *c = C32::new(f32::from(code), 0.0);
            }
            self.fft.forward(&row_in, spectrum);
        }
        out
    }

    /// Template and mask of a code image, given its row spectra.
    pub fn features(&self, spectra: &[C32]) -> Features {
        let n = self.columns();
        let mut template = vec![0u8; spectra.len()];
        // The bits of scales beyond the configured ones are never compared.
        let used_bits = ((1u16 << (2 * self.filters.len())) - 1) as u8;
        let mut mask = vec![!used_bits; spectra.len()];
        let mut response = vec![C32::new(0.0, 0.0); n];
        for (row, spectrum) in spectra.chunks_exact(n).enumerate() {
            for (scale, filter) in self.filters.iter().enumerate() {
                for ((r, s), g) in response.iter_mut().zip(spectrum).zip(filter) {
                    *r = s * *g;
                }
                self.fft.inverse_in_place(&mut response);
                let (real_bit, imag_bit) = (1u8 << (2 * scale), 1u8 << (2 * scale + 1));
                for (column, e) in response.iter().enumerate() {
                    let pixel = row * n + column;
                    if e.re > 0.0 {
                        template[pixel] |= real_bit;
                    }
                    if e.im > 0.0 {
                        template[pixel] |= imag_bit;
                    }
                    if e.norm() < self.mask_epsilon {
                        mask[pixel] |= real_bit | imag_bit;
                    }
                }
            }
        }
        Features { template, mask }
    }

    /// The phase-correlation shift s (query column j ≈ candidate column j − s), or `None` when the
    /// images share no frequency content.
    pub fn estimate_shift(&self, query: &[C32], candidate: &[C32]) -> Option<usize> {
        let n = self.columns();
        let mut cross = vec![C32::new(0.0, 0.0); n];
        for (q_row, c_row) in query.chunks_exact(n).zip(candidate.chunks_exact(n)) {
            for ((r, q), c) in cross.iter_mut().zip(q_row).zip(c_row) {
                *r += q * c.conj();
            }
        }
        let mut any = false;
        for r in &mut cross {
            let modulus = r.norm();
            if modulus > 1e-6 {
                *r /= modulus;
                any = true;
            } else {
                *r = C32::new(0.0, 0.0);
            }
        }
        if !any {
            return None;
        }
        self.fft.inverse_in_place(&mut cross);
        cross
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.re.total_cmp(&b.1.re))
            .map(|(shift, _)| shift)
    }
}

/// Masked Hamming distance between query and candidate at shift s (query column j against candidate
/// column j − s): differing unmasked bits over unmasked bits; 1 when no bit can be compared.
pub fn hamming_distance(query: &Features, candidate: &Features, columns: usize, shift: usize) -> f64 {
    let shift = shift % columns;
    let (mut differing, mut compared) = (0u64, 0u64);
    let rows = query.template.len() / columns;
    for row in 0..rows {
        let span = row * columns..(row + 1) * columns;
        let (qt, qm) = (&query.template[span.clone()], &query.mask[span.clone()]);
        let (ct, cm) = (&candidate.template[span.clone()], &candidate.mask[span]);
        // Query columns shift.. pair with candidate columns 0.., and query columns ..shift with the
        // candidate's last `shift` columns.
        let pieces = [
            (shift..columns, 0..columns - shift),
            (0..shift, columns - shift..columns),
        ];
        for (q_range, c_range) in pieces {
            let pairs = qt[q_range.clone()]
                .iter()
                .zip(&qm[q_range])
                .zip(ct[c_range.clone()].iter().zip(&cm[c_range]));
            for ((&qt, &qm), (&ct, &cm)) in pairs {
                let valid = !(qm | cm);
                differing += u64::from(((qt ^ ct) & valid).count_ones());
                compared += u64::from(valid.count_ones());
            }
        }
    }
    if compared == 0 {
        1.0
    } else {
        differing as f64 / compared as f64
    }
}
