//! LiDAR models with their real beam patterns.
//!
//! Spinning sensors fire all beams of a column at once and sweep clockwise (seen from above, like
//! Velodyne and Ouster units) starting and ending behind the sensor, so the sweep's seam is at the back.
//! Column `c` of `C` fires at `c / C` of the 0.1 s sweep, which is what makes a moving robot's scan
//! distorted. Vertical angle tables:
//! - `vlp16`: Velodyne VLP-16, −15° to +15° in 2° steps, 1800 columns (0.2° at 10 Hz), 0.5–100 m.
//! - `os1-32` / `os1-64`: Ouster OS1 gen 1, beams spread uniformly over ±16.6° (33.2° vertical FOV;
//!   the gen-2 45° variant is not modelled), 1024 columns, 0.8–120 m.
//! - `hdl64e`: Velodyne HDL-64E S2 as in KITTI: the upper block's 32 beams from +2.0° down to −8.33° in
//!   1/3° steps, the lower block's 32 beams from −8.83° to −24.8° (about 0.515° apart), 2048 columns
//!   (the real unit gives about 2083 at 10 Hz), 0.9–120 m.
//! - `avia`: a Livox-Avia-like solid-state sensor, 70.4° × 77.2° FOV, 24 000 points per 0.1 s frame from
//!   six emitters steered by a Risley-prism pair. Each direction is the sum of two counter-rotating
//!   unit vectors at incommensurate rates, a rosette that never repeats (Liu et al., "Livox Avia
//!   non-repetitive scanning", and Li et al., "Risley prism scanning", 2019); coverage grows with
//!   integration time. 1–190 m.
//!
//! Each model carries its data sheet's range precision, angular accuracy and beam divergence; how they
//! degrade a scan is [`crate::sensor_errors`]'s.

use crate::SimError;
use crate::geometry::V3;

/// Duration of one sweep (10 Hz for every model).
pub const SWEEP_PERIOD_S: f64 = 0.1;

/// How the beams are steered.
#[derive(Clone, Debug)]
pub enum Pattern {
    /// A spinning multi-beam sensor: `elevations_rad[ring]` ascending, `columns` firings per sweep.
    Spinning {
        elevations_rad: Vec<f64>,
        columns: usize,
    },
    /// A non-repetitive rosette: `points` per sweep from `emitters` emitters, within ±`half_h_rad`
    /// horizontally and ±`half_v_rad` vertically about the x axis.
    Rosette {
        points: usize,
        emitters: usize,
        half_h_rad: f64,
        half_v_rad: f64,
    },
}

/// A LiDAR model.
#[derive(Clone, Debug)]
pub struct Sensor {
    pub name: &'static str,
    pub pattern: Pattern,
    pub min_range_m: f64,
    pub max_range_m: f64,
    /// The data sheet's best 1σ range precision (strong returns; weaker ones are noisier).
    pub range_precision_m: f64,
    /// 1σ error of each beam's angles in the unit's calibration table.
    pub angular_accuracy_rad: f64,
    /// Full-width-at-half-maximum beam divergence, in the scan direction.
    pub beam_divergence_rad: f64,
    /// Unit directions of a spinning pattern, column-major (`column * beams + ring`).
    directions: Vec<V3>,
}

/// The canonical names `Sensor::by_name` knows.
pub const SENSOR_NAMES: [&str; 5] = ["vlp16", "os1-32", "os1-64", "hdl64e", "avia"];

/// A spinning model's data-sheet errors (sources in [`crate::sensor_errors`]).
#[derive(Clone, Copy)]
struct SensorErrors {
    range_precision_m: f64,
    angular_accuracy_deg: f64,
    beam_divergence_rad: f64,
}

/// Ouster OS1 (gen 1) data sheet: ±1.5 cm repeatability at high SNR, ±0.01° angular sampling accuracy,
/// 0.13° beam divergence (FWHM).
const OS1_ERRORS: SensorErrors = SensorErrors {
    range_precision_m: 0.015,
    angular_accuracy_deg: 0.01,
    beam_divergence_rad: 0.13 * std::f64::consts::PI / 180.0,
};

/// Velodyne VLP-16 data sheet: ±3 cm typical accuracy; 3.0 mrad horizontal divergence (user manual);
/// no angular accuracy published, 0.05° assumed.
const VELODYNE_ERRORS: SensorErrors = SensorErrors {
    range_precision_m: 0.03,
    angular_accuracy_deg: 0.05,
    beam_divergence_rad: 3.0e-3,
};

/// Angular rates of the two prisms of the rosette model, in revolutions per second.
const PRISM_HZ: [f64; 2] = [97.3, -61.1];

fn uniform_deg(beams: usize, low_deg: f64, high_deg: f64) -> Vec<f64> {
    (0..beams)
        .map(|i| (low_deg + (high_deg - low_deg) * i as f64 / (beams - 1) as f64).to_radians())
        .collect()
}

fn hdl64e_elevations_rad() -> Vec<f64> {
    let mut angles: Vec<f64> = (0..32).map(|i| 2.0 - f64::from(i) / 3.0).collect();
    angles.extend((0..32).map(|i| -8.83 - f64::from(i) * (24.8 - 8.83) / 31.0));
    angles.sort_by(f64::total_cmp);
    angles.into_iter().map(f64::to_radians).collect()
}

impl Sensor {
    /// The sensor called `name` (case, `-`, `_` and spaces ignored: `OS1-64`, `os1_64` and `os164` all
    /// work; `hdl64`, `velodyne16` and `livox_avia` are aliases).
    pub fn by_name(name: &str) -> Result<Self, SimError> {
        let key: String = name
            .chars()
            .filter(|c| c.is_ascii_alphanumeric())
            .collect::<String>()
            .to_ascii_lowercase();
        let sensor = match key.as_str() {
            "vlp16" | "velodyne16" | "puck" => Self::spinning(
                "vlp16",
                uniform_deg(16, -15.0, 15.0),
                1800,
                [0.5, 100.0],
                VELODYNE_ERRORS,
            ),
            "os132" => Self::spinning(
                "os1-32",
                uniform_deg(32, -16.6, 16.6),
                1024,
                [0.8, 120.0],
                OS1_ERRORS,
            ),
            "os164" => Self::spinning(
                "os1-64",
                uniform_deg(64, -16.6, 16.6),
                1024,
                [0.8, 120.0],
                OS1_ERRORS,
            ),
            "hdl64e" | "hdl64" => Self::spinning(
                "hdl64e",
                hdl64e_elevations_rad(),
                2048,
                [0.9, 120.0],
                SensorErrors {
                    range_precision_m: 0.02,
                    ..VELODYNE_ERRORS
                },
            ),
            "avia" | "livoxavia" | "livox" => Self {
                name: "avia",
                pattern: Pattern::Rosette {
                    points: 24_000,
                    emitters: 6,
                    half_h_rad: 35.2f64.to_radians(),
                    half_v_rad: 38.6f64.to_radians(),
                },
                min_range_m: 1.0,
                max_range_m: 190.0,
                range_precision_m: 0.02,
                angular_accuracy_rad: 0.05f64.to_radians(),
                beam_divergence_rad: 0.03f64.to_radians(),
                directions: Vec::new(),
            },
            _ => {
                return Err(SimError::UnknownSensor {
                    name: name.to_owned(),
                    known: SENSOR_NAMES.iter().map(|s| (*s).to_owned()).collect(),
                });
            }
        };
        Ok(sensor)
    }

    fn spinning(
        name: &'static str,
        elevations_rad: Vec<f64>,
        columns: usize,
        [min_range_m, max_range_m]: [f64; 2],
        errors: SensorErrors,
    ) -> Self {
        let mut directions = Vec::with_capacity(columns * elevations_rad.len());
        for column in 0..columns {
            let azimuth = Self::column_azimuth_rad(column, columns);
            for &elevation in &elevations_rad {
                directions.push(V3::from_f64(
                    elevation.cos() * azimuth.cos(),
                    elevation.cos() * azimuth.sin(),
                    elevation.sin(),
                ));
            }
        }
        Self {
            name,
            pattern: Pattern::Spinning {
                elevations_rad,
                columns,
            },
            min_range_m,
            max_range_m,
            range_precision_m: errors.range_precision_m,
            angular_accuracy_rad: errors.angular_accuracy_deg.to_radians(),
            beam_divergence_rad: errors.beam_divergence_rad,
            directions,
        }
    }

    /// Azimuth of column `column`: starts just left of straight behind and decreases (clockwise).
    pub fn column_azimuth_rad(column: usize, columns: usize) -> f64 {
        std::f64::consts::PI - std::f64::consts::TAU * (column as f64 + 0.5) / columns as f64
    }

    /// Number of firing groups per sweep (rays in a group fire at the same instant).
    pub fn groups(&self) -> usize {
        match &self.pattern {
            Pattern::Spinning { columns, .. } => *columns,
            Pattern::Rosette { points, emitters, .. } => points / emitters,
        }
    }

    /// Rays per firing group.
    pub fn rays_per_group(&self) -> usize {
        match &self.pattern {
            Pattern::Spinning { elevations_rad, .. } => elevations_rad.len(),
            Pattern::Rosette { emitters, .. } => *emitters,
        }
    }

    /// Rays per sweep.
    pub fn rays_per_sweep(&self) -> usize {
        self.groups() * self.rays_per_group()
    }

    /// Time of group `group` after the sweep start.
    pub fn group_time_offset_s(&self, group: usize) -> f64 {
        group as f64 / self.groups() as f64 * SWEEP_PERIOD_S
    }

    /// Unit direction in the sensor frame of ray `ray` of group `group` for a sweep starting at
    /// `sweep_start_s` (the rosette depends on absolute time, which is what makes it non-repetitive).
    pub fn direction(&self, group: usize, ray: usize, sweep_start_s: f64) -> V3 {
        match &self.pattern {
            Pattern::Spinning { elevations_rad, .. } => self.directions[group * elevations_rad.len() + ray],
            Pattern::Rosette {
                emitters,
                half_h_rad,
                half_v_rad,
                ..
            } => {
                let t = sweep_start_s + self.group_time_offset_s(group);
                let phase = std::f64::consts::TAU * ray as f64 / *emitters as f64;
                let a = std::f64::consts::TAU * PRISM_HZ[0] * t + phase;
                let b = std::f64::consts::TAU * PRISM_HZ[1] * t + 0.37 * phase;
                let (u, v) = (0.5 * (a.cos() + b.cos()), 0.5 * (a.sin() + b.sin()));
                let (azimuth, elevation) = (half_h_rad * u, half_v_rad * v);
                V3::from_f64(
                    elevation.cos() * azimuth.cos(),
                    elevation.cos() * azimuth.sin(),
                    elevation.sin(),
                )
            }
        }
    }

    /// The vertical angle table of a spinning sensor (ascending; index = ring), empty for the rosette.
    pub fn elevations_rad(&self) -> &[f64] {
        match &self.pattern {
            Pattern::Spinning { elevations_rad, .. } => elevations_rad,
            Pattern::Rosette { .. } => &[],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tables_match_datasheets() {
        let vlp = Sensor::by_name("VLP-16").unwrap();
        assert_eq!(vlp.elevations_rad().len(), 16);
        assert!((vlp.elevations_rad()[0].to_degrees() + 15.0).abs() < 1e-9);
        assert!((vlp.elevations_rad()[1].to_degrees() + 13.0).abs() < 1e-9);
        let hdl = Sensor::by_name("hdl64e").unwrap();
        let e = hdl.elevations_rad();
        assert_eq!(e.len(), 64);
        assert!((e[0].to_degrees() + 24.8).abs() < 1e-9 && (e[63].to_degrees() - 2.0).abs() < 1e-9);
        assert!(e.windows(2).all(|w| w[0] < w[1]));
        assert_eq!(Sensor::by_name("os1_64").unwrap().rays_per_sweep(), 64 * 1024);
        assert_eq!(Sensor::by_name("os1-32").unwrap().rays_per_group(), 32);
        let error = Sensor::by_name("hdl32").unwrap_err().to_string();
        assert!(error.contains("hdl32") && error.contains("os1-64"), "{error}");
    }

    #[test]
    fn rosette_stays_in_fov_and_does_not_repeat() {
        let avia = Sensor::by_name("avia").unwrap();
        let (h, v) = (35.2f64.to_radians() as f32, 38.6f64.to_radians() as f32);
        for group in (0..avia.groups()).step_by(37) {
            for ray in 0..6 {
                let d = avia.direction(group, ray, 0.0);
                assert!(d.y.atan2(d.x).abs() <= h + 1e-4);
                assert!(d.z.asin().abs() <= v + 1e-4);
            }
        }
        assert_ne!(avia.direction(10, 0, 0.0), avia.direction(10, 0, SWEEP_PERIOD_S));
    }
}
