//! A LiDAR's measurement errors at its data sheet's values: range precision that grows as the return's
//! signal-to-noise ratio falls, detection that fails below the data sheet's range, per-beam angle errors
//! of the unit's intrinsic calibration, and mixed returns at depth edges from the beam's divergence.
//!
//! - **Signal-to-noise ratio.** A return's strength is `albedo · cos θ · (10 m / r)²` (Lambertian
//!   target, inverse-square falloff). The data sheets rate their range on an 80 % Lambertian target at
//!   the detection threshold; SKiD takes that threshold as an SNR of 12, the lowest row of the Ouster OS1
//!   data sheet's repeatability table (which also makes its second range figure, 40 m on a 10 % target,
//!   come out at SNR 13). So `SNR = 12 · strength / (0.8 · (10 m / max range)²)`.
//! - **Detection.** Returns below SNR 9 are lost, above SNR 15 kept, with a linear ramp between.
//! - **Range precision.** The Ouster OS1 data sheet (rev. 2019, "Range Repeatability, 1σ") gives
//!   ±1.5 cm above SNR 250, ±3 cm at SNR 100 and ±10 cm at SNR 12: σ is interpolated in log–log
//!   between those rows and held beyond them. Other sensors publish only their best figure (VLP-16
//!   "±3 cm typical", HDL-64E S2 "< 2 cm, 1σ", Livox Avia "2 cm, 1σ at 20 m"), so the OS1's curve is
//!   scaled to that figure.
//! - **Beam angles.** Each unit's beams leave at angles its intrinsic calibration table gets slightly
//!   wrong. Ouster states ±0.01° of angular sampling accuracy and Livox < 0.05° for the Avia; Velodyne
//!   states none for the VLP-16 and the HDL-64E, for which 0.05° is assumed. Each beam (ring, or Avia
//!   emitter) gets a fixed elevation and azimuth error of that 1σ, drawn once per unit: the ray is cast
//!   along the true direction, and the point is reported along the table's.
//! - **Mixed returns.** A beam of divergence δ (FWHM) that straddles a depth edge returns a range
//!   between the two surfaces (the "veil" between a foreground object and its background). A point next
//!   to an edge in its ring (the neighbouring column's range differs by more than 0.3 m) becomes mixed
//!   with probability `δ / 2 / Δ`, `Δ` the column spacing, its range uniform between the two.
//!   Divergences: OS1 0.13° (data sheet, FWHM), Velodyne 3.0 mrad horizontal (VLP-16 and VLS-128
//!   manuals; assumed for the HDL-64E). The Avia's rosette has no columns and is left without.

use crate::geometry::V3;
use crate::rng::{Rng, combine};
use crate::sensor::Sensor;

/// The SNR at which a data sheet's rated range is reached (80 % Lambertian target).
pub const SNR_AT_RATED_RANGE: f64 = 12.0;
/// The reflectivity the data sheets rate their range on.
const RATED_ALBEDO: f64 = 0.8;
/// Below this SNR no return is reported; above [`DETECTED_SNR`] every one is.
const LOST_SNR: f64 = 9.0;
const DETECTED_SNR: f64 = 15.0;
/// The OS1 data sheet's repeatability rows: (SNR, 1σ in metres), ascending SNR.
const OS1_REPEATABILITY: [(f64, f64); 3] = [(12.0, 0.10), (100.0, 0.03), (250.0, 0.015)];
/// Neighbouring returns further apart than this in range form a depth edge.
const DEPTH_EDGE_M: f32 = 0.3;

/// The SNR of a return of `strength` (`albedo · cos θ · (10 m / r)²`) for `sensor`.
pub fn snr(sensor: &Sensor, strength: f64) -> f64 {
    let rated_strength = RATED_ALBEDO * (10.0 / sensor.max_range_m).powi(2);
    SNR_AT_RATED_RANGE * strength / rated_strength
}

/// The probability that a return of SNR `snr` is reported.
pub fn detection_probability(snr: f64) -> f64 {
    ((snr - LOST_SNR) / (DETECTED_SNR - LOST_SNR)).clamp(0.0, 1.0)
}

/// The 1σ range precision of `sensor` for a return of SNR `snr`.
pub fn range_sigma_m(sensor: &Sensor, snr: f64) -> f64 {
    let [(snr_low, sigma_low), _, (snr_high, sigma_high)] = OS1_REPEATABILITY;
    let os1_sigma = if snr <= snr_low {
        sigma_low
    } else if snr >= snr_high {
        sigma_high
    } else {
        let [low, middle, high] = OS1_REPEATABILITY;
        let [(s0, e0), (s1, e1)] = if snr <= middle.0 {
            [low, middle]
        } else {
            [middle, high]
        };
        let f = (snr.ln() - s0.ln()) / (s1.ln() - s0.ln());
        (e0.ln() + f * (e1.ln() - e0.ln())).exp()
    };
    os1_sigma * sensor.range_precision_m / sigma_high
}

/// A unit's fixed beam-angle errors: `(elevation, azimuth)` in radians per beam.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BeamErrors {
    per_beam_rad: Vec<(f64, f64)>,
}

impl BeamErrors {
    /// No errors: rays leave along the calibration table.
    pub const fn none() -> Self {
        Self {
            per_beam_rad: Vec::new(),
        }
    }

    /// Errors of `sensor`'s data-sheet 1σ times `scale` for each of its `beams`, drawn from `seed`.
    pub fn drawn(sensor: &Sensor, scale: f64, seed: u64) -> Self {
        let mut rng = Rng::new(combine(seed, 0xbea7));
        let sigma = sensor.angular_accuracy_rad * scale;
        let per_beam_rad = (0..sensor.rays_per_group())
            .map(|_| (rng.gaussian() * sigma, rng.gaussian() * sigma))
            .collect();
        Self { per_beam_rad }
    }

    /// The direction beam `beam` really leaves along when its table says `direction`.
    pub fn true_direction(&self, beam: usize, direction: V3) -> V3 {
        let Some(&(elevation_error, azimuth_error)) = self.per_beam_rad.get(beam) else {
            return direction;
        };
        let (x, y, z) = (
            f64::from(direction.x),
            f64::from(direction.y),
            f64::from(direction.z),
        );
        let elevation = z.clamp(-1.0, 1.0).asin() + elevation_error;
        let azimuth = y.atan2(x) + azimuth_error;
        V3::from_f64(
            elevation.cos() * azimuth.cos(),
            elevation.cos() * azimuth.sin(),
            elevation.sin(),
        )
    }
}

/// Turns returns next to depth edges into mixed returns, in place. `returns` holds one sweep's
/// `(range, intensity)` in firing order (`column * beams + beam`, `None` for no return) of a spinning
/// sensor; `key` seeds the draws. Returns how many returns were mixed.
pub fn mix_depth_edges(sensor: &Sensor, returns: &mut [Option<(f32, f32)>], key: u64) -> usize {
    let (beams, columns) = (sensor.rays_per_group(), sensor.groups());
    if sensor.elevations_rad().is_empty() || columns < 2 || returns.len() != beams * columns {
        return 0;
    }
    let spacing_rad = std::f64::consts::TAU / columns as f64;
    let probability = (sensor.beam_divergence_rad / 2.0 / spacing_rad).min(1.0);
    // Neighbours are judged by their ranges before any mixing.
    let original: Vec<Option<f32>> = returns.iter().map(|r| r.map(|(range, _)| range)).collect();
    let mut changed = 0;
    for column in 0..columns {
        for beam in 0..beams {
            let index = column * beams + beam;
            let Some(own) = original[index] else { continue };
            let mut rng = Rng::new(combine(key, index as u64 ^ 0x7e11));
            for neighbour_column in [column.wrapping_sub(1), column + 1] {
                let Some(Some(other)) =
                    (neighbour_column < columns).then(|| original[neighbour_column * beams + beam])
                else {
                    continue;
                };
                if (other - own).abs() > DEPTH_EDGE_M && rng.chance(probability) {
                    let (near, far) = (own.min(other), own.max(other));
                    if let Some((range, _)) = &mut returns[index] {
                        *range = near + (far - near) * rng.uniform() as f32;
                    }
                    changed += 1;
                    break;
                }
            }
        }
    }
    changed
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn precision_follows_the_os1_table_and_scales_to_each_sensor() {
        let os1 = Sensor::by_name("os1-64").unwrap();
        assert!((range_sigma_m(&os1, 1000.0) - 0.015).abs() < 1e-12);
        assert!((range_sigma_m(&os1, 100.0) - 0.03).abs() < 1e-12);
        assert!((range_sigma_m(&os1, 12.0) - 0.10).abs() < 1e-12);
        assert!((range_sigma_m(&os1, 3.0) - 0.10).abs() < 1e-12);
        let between = range_sigma_m(&os1, 40.0);
        assert!(between > 0.03 && between < 0.10, "{between}");
        let vlp = Sensor::by_name("vlp16").unwrap();
        assert!((range_sigma_m(&vlp, 1000.0) - 0.03).abs() < 1e-12);
        assert!((range_sigma_m(&vlp, 12.0) - 0.20).abs() < 1e-12);
    }

    #[test]
    fn the_rated_ranges_sit_at_the_detection_threshold() {
        let os1 = Sensor::by_name("os1-64").unwrap();
        // 120 m on an 80 % target, head on: the threshold SNR.
        let rated = snr(&os1, 0.8 * (10.0f64 / 120.0).powi(2));
        assert!((rated - SNR_AT_RATED_RANGE).abs() < 1e-9);
        // The data sheet's second figure, 40 m on a 10 % target, is detected too.
        assert!(detection_probability(snr(&os1, 0.1 * (10.0f64 / 40.0).powi(2))) > 0.5);
        // A 10 % target at 80 m is not.
        assert_eq!(
            detection_probability(snr(&os1, 0.1 * (10.0f64 / 80.0).powi(2))),
            0.0
        );
    }

    #[test]
    fn beam_errors_have_the_data_sheet_size_and_are_fixed_per_unit() {
        let os1 = Sensor::by_name("os1-64").unwrap();
        let errors = BeamErrors::drawn(&os1, 1.0, 5);
        assert_eq!(errors, BeamErrors::drawn(&os1, 1.0, 5));
        let direction = os1.direction(100, 10, 0.0);
        let moved = errors.true_direction(10, direction);
        let angle_deg = f64::from(direction.cross(moved).norm()).asin().to_degrees();
        assert!(angle_deg > 0.0 && angle_deg < 0.06, "{angle_deg}");
        assert_eq!(BeamErrors::none().true_direction(10, direction), direction);
    }

    #[test]
    fn only_points_at_depth_edges_mix_and_stay_between_the_surfaces() {
        let vlp = Sensor::by_name("vlp16").unwrap();
        let (beams, columns) = (vlp.rays_per_group(), vlp.groups());
        // A wall at 5 m over half the columns, 20 m behind it elsewhere.
        let wall = |column: usize| if column < columns / 2 { 5.0 } else { 20.0 };
        let mut returns: Vec<Option<(f32, f32)>> = (0..beams * columns)
            .map(|i| Some((wall(i / beams), 0.5)))
            .collect();
        let changed = mix_depth_edges(&vlp, &mut returns, 1);
        assert!(changed > 0 && changed <= 4 * beams, "{changed}");
        for (index, mixed) in returns.iter().enumerate() {
            let column = index / beams;
            let at_edge = [columns / 2 - 1, columns / 2, 0, columns - 1].contains(&column);
            let (range, intensity) = mixed.unwrap();
            assert_eq!(intensity, 0.5);
            if !at_edge {
                assert_eq!(range, wall(column));
            }
            assert!((5.0..=20.0).contains(&range));
        }
    }
}
