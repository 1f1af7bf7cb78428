//! JSON Robot Log (JRL) datasets: collaborative SLAM problems with time-ordered measurements per robot,
//! ground truth, an initial estimate and outlier labels, as specified in `DanMcGann/jrl`
//! (`format/DATASET_FORMAT.md`, `VALUE_FORMAT.md`, `MEASUREMENT_FORMAT.md`) and written by its library:
//! COSMO-Bench (McGann, Potokar & Kaess, 2025) ships its problems in it.
//!
//! ## Format
//!
//! One JSON object: `name`; `robots`, the robot letters as ASCII codes; `measurements`, per robot letter
//! a list of entries `{stamp, measurements: [factor, …]}` in time order; optional `groundtruth` and
//! `initialization`, per robot a list of values `{key, type: "Pose3", rotation: [w, x, y, z],
//! translation: [x, y, z]}` covering that robot's part of the problem (its own poses and the peers'
//! poses its factors name: COSMO-Bench's initial values of a peer's pose are the robot's own view of
//! it); optional `potential_outlier_factors` and `outlier_factors`, per robot a list of
//! `[entry index, factor index]` pairs into that robot's entries.
//!
//! Keys are GTSAM symbols: the robot letter in the top 8 bits, the pose index below. This reader takes
//! the 3D pose-graph factors: `PriorFactorPose3` (`key`, `prior`) and `BetweenFactorPose3` (`key1`,
//! `key2`, `measurement`: the pose of `key2` in `key1`'s frame), each with a row-major 6x6 `covariance`
//! in GTSAM's tangent order, rotation first. [`JrlFactor`] holds it translation first, as every SKiD
//! pose graph does (the blocks swapped).
//!
//! Fields the specification does not name are ignored. Anything else is an error naming the file and the
//! entry: another measurement type, a key of a robot
//! the file does not list or of another robot than the list it stands in, a quaternion of zero length,
//! a covariance of another size, not symmetric or not positive definite, a label pointing past the
//! entries, a value given twice.

use std::collections::BTreeMap;
use std::path::Path;

use nalgebra::{Isometry3, Matrix6, Quaternion, SMatrix, Translation3, UnitQuaternion};
use serde::Deserialize;

use crate::error::{IoError, read_file};

/// A pose-graph key: a GTSAM symbol with the robot's letter in its top 8 bits.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct JrlKey(pub u64);

impl JrlKey {
    /// The robot letter (`key >> 56` as ASCII).
    pub fn robot(self) -> char {
        char::from((self.0 >> 56) as u8)
    }

    /// The pose index within the robot.
    pub fn index(self) -> u64 {
        self.0 & ((1 << 56) - 1)
    }
}

impl std::fmt::Display for JrlKey {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}{}", self.robot(), self.index())
    }
}

/// One factor of the problem. Covariances are 6x6, translation first, symmetric positive definite.
#[derive(Clone, Debug, PartialEq)]
pub enum JrlFactor {
    /// The pose of `key` in the world frame.
    Prior {
        key: JrlKey,
        world_from_pose: Isometry3<f64>,
        covariance: Matrix6<f64>,
    },
    /// The pose of `source` in `target`'s frame.
    Between {
        target: JrlKey,
        source: JrlKey,
        target_from_source: Isometry3<f64>,
        covariance: Matrix6<f64>,
    },
}

/// A factor with its labels.
#[derive(Clone, Debug, PartialEq)]
pub struct JrlMeasurement {
    pub factor: JrlFactor,
    /// A loop closure: the file says it may be wrong.
    pub potential_outlier: bool,
    /// The file's label says it is wrong.
    pub outlier: bool,
}

/// The measurements one robot made at one time.
#[derive(Clone, Debug, PartialEq)]
pub struct JrlEntry {
    pub stamp: u64,
    pub measurements: Vec<JrlMeasurement>,
}

/// One robot's part of the dataset.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct JrlRobot {
    pub letter: char,
    /// Time-ordered (by the file's order; stamps are checked not to go backwards).
    pub entries: Vec<JrlEntry>,
    /// The reference poses of this robot's part of the problem (its own, and the peers' its factors name),
    /// by key.
    pub ground_truth: BTreeMap<JrlKey, Isometry3<f64>>,
    /// This robot's initial estimate of the same poses, by key.
    pub initialization: BTreeMap<JrlKey, Isometry3<f64>>,
}

/// A whole JRL dataset.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct JrlDataset {
    pub name: String,
    /// In the order of the file's `robots` list.
    pub robots: Vec<JrlRobot>,
}

impl JrlDataset {
    /// The robot with letter `letter`.
    pub fn robot(&self, letter: char) -> Option<&JrlRobot> {
        self.robots.iter().find(|robot| robot.letter == letter)
    }

    /// Every measurement of every robot, with the robot that holds it.
    pub fn measurements(&self) -> impl Iterator<Item = (char, &JrlEntry, &JrlMeasurement)> {
        self.robots.iter().flat_map(|robot| {
            robot
                .entries
                .iter()
                .flat_map(move |entry| entry.measurements.iter().map(move |m| (robot.letter, entry, m)))
        })
    }
}

#[derive(Deserialize)]
struct RawDataset {
    name: String,
    robots: Vec<u32>,
    measurements: BTreeMap<String, Vec<RawEntry>>,
    #[serde(default)]
    groundtruth: BTreeMap<String, Vec<RawValue>>,
    #[serde(default)]
    initialization: BTreeMap<String, Vec<RawValue>>,
    #[serde(default)]
    potential_outlier_factors: BTreeMap<String, Vec<(usize, usize)>>,
    #[serde(default)]
    outlier_factors: BTreeMap<String, Vec<(usize, usize)>>,
}

#[derive(Deserialize)]
struct RawEntry {
    stamp: u64,
    #[serde(default)]
    measurements: Vec<RawFactor>,
}

#[derive(Deserialize)]
#[serde(tag = "type")]
enum RawFactor {
    PriorFactorPose3 {
        key: u64,
        prior: RawPose,
        covariance: Vec<f64>,
    },
    BetweenFactorPose3 {
        key1: u64,
        key2: u64,
        measurement: RawPose,
        covariance: Vec<f64>,
    },
}

#[derive(Deserialize)]
#[serde(tag = "type")]
enum RawPose {
    Pose3 {
        rotation: [f64; 4],
        translation: [f64; 3],
    },
}

#[derive(Deserialize)]
struct RawValue {
    key: u64,
    #[serde(flatten)]
    pose: RawPose,
}

/// Reads a JRL dataset; see the module documentation for what is checked.
pub fn read_jrl(path: &Path) -> Result<JrlDataset, IoError> {
    let bytes = read_file(path)?;
    parse_jrl(path, &bytes)
}

/// Parses the bytes of a JRL file (`path` names it in errors).
pub fn parse_jrl(path: &Path, bytes: &[u8]) -> Result<JrlDataset, IoError> {
    let mut deserializer = serde_json::Deserializer::from_slice(bytes);
    let raw: RawDataset = serde_path_to_error::deserialize(&mut deserializer).map_err(|error| {
        let at = error.path().to_string();
        IoError::invalid(path, format!("at `{at}`: {}", error.into_inner()))
    })?;
    deserializer
        .end()
        .map_err(|error| IoError::invalid(path, format!("after the dataset: {error}")))?;
    Converter { path }.dataset(raw)
}

/// Turns the raw JSON into checked types, naming `path` in errors.
struct Converter<'a> {
    path: &'a Path,
}

impl Converter<'_> {
    fn error(&self, message: String) -> IoError {
        IoError::invalid(self.path, message)
    }

    fn dataset(&self, raw: RawDataset) -> Result<JrlDataset, IoError> {
        let mut letters = Vec::new();
        for &code in &raw.robots {
            let letter = u8::try_from(code)
                .ok()
                .filter(u8::is_ascii_graphic)
                .map(char::from)
                .ok_or_else(|| self.error(format!("robots: {code} is not the ASCII code of a letter")))?;
            if letters.contains(&letter) {
                return Err(self.error(format!("robots: `{letter}` is listed twice")));
            }
            letters.push(letter);
        }
        let sections = [
            ("measurements", raw.measurements.keys().collect::<Vec<_>>()),
            ("groundtruth", raw.groundtruth.keys().collect()),
            ("initialization", raw.initialization.keys().collect()),
            (
                "potential_outlier_factors",
                raw.potential_outlier_factors.keys().collect(),
            ),
            ("outlier_factors", raw.outlier_factors.keys().collect()),
        ];
        for (section, keys) in sections {
            if let Some(unknown) = keys
                .into_iter()
                .find(|key| self.letter_of(key, &letters).is_none())
            {
                return Err(self.error(format!(
                    "{section}: `{unknown}` is not one of the robots the file lists ({})",
                    letters.iter().collect::<String>()
                )));
            }
        }
        let mut raw = raw;
        let mut robots = Vec::new();
        for &letter in &letters {
            let name = letter.to_string();
            let entries = raw.measurements.remove(&name).unwrap_or_default();
            let potential = raw.potential_outlier_factors.remove(&name).unwrap_or_default();
            let outliers = raw.outlier_factors.remove(&name).unwrap_or_default();
            robots.push(JrlRobot {
                letter,
                entries: self.entries(letter, entries, &letters, &potential, &outliers)?,
                ground_truth: self.values("groundtruth", letter, &letters, raw.groundtruth.remove(&name))?,
                initialization: self.values(
                    "initialization",
                    letter,
                    &letters,
                    raw.initialization.remove(&name),
                )?,
            });
        }
        Ok(JrlDataset {
            name: raw.name,
            robots,
        })
    }

    fn letter_of(&self, key: &str, letters: &[char]) -> Option<char> {
        let mut chars = key.chars();
        let letter = chars.next()?;
        (chars.next().is_none() && letters.contains(&letter)).then_some(letter)
    }

    fn entries(
        &self,
        letter: char,
        raw: Vec<RawEntry>,
        letters: &[char],
        potential: &[(usize, usize)],
        outliers: &[(usize, usize)],
    ) -> Result<Vec<JrlEntry>, IoError> {
        let mut entries = Vec::with_capacity(raw.len());
        let mut last_stamp = 0;
        for (index, entry) in raw.into_iter().enumerate() {
            let at = |factor: Option<usize>| match factor {
                Some(factor) => format!("measurements.{letter} entry {index}, factor {factor}"),
                None => format!("measurements.{letter} entry {index}"),
            };
            if entry.stamp < last_stamp {
                return Err(self.error(format!(
                    "{}: stamp {} is before the previous entry's {last_stamp}",
                    at(None),
                    entry.stamp
                )));
            }
            last_stamp = entry.stamp;
            let mut measurements = Vec::with_capacity(entry.measurements.len());
            for (factor_index, factor) in entry.measurements.into_iter().enumerate() {
                let factor = self
                    .factor(factor, letters)
                    .map_err(|reason| self.error(format!("{}: {reason}", at(Some(factor_index)))))?;
                measurements.push(JrlMeasurement {
                    factor,
                    potential_outlier: false,
                    outlier: false,
                });
            }
            entries.push(JrlEntry {
                stamp: entry.stamp,
                measurements,
            });
        }
        for (section, labels, is_outlier) in [
            ("potential_outlier_factors", potential, false),
            ("outlier_factors", outliers, true),
        ] {
            for &(entry, factor) in labels {
                let measurement = entries
                    .get_mut(entry)
                    .and_then(|e| e.measurements.get_mut(factor))
                    .ok_or_else(|| {
                        self.error(format!(
                            "{section}.{letter}: [{entry}, {factor}] points past robot {letter}'s measurements"
                        ))
                    })?;
                // An outlier is a potential outlier by definition, whether or not the file lists it so.
                measurement.potential_outlier = true;
                measurement.outlier |= is_outlier;
            }
        }
        Ok(entries)
    }

    fn factor(&self, raw: RawFactor, letters: &[char]) -> Result<JrlFactor, String> {
        let key = |value: u64| {
            let key = JrlKey(value);
            if letters.contains(&key.robot()) {
                Ok(key)
            } else {
                Err(format!(
                    "key {value} belongs to robot {:?}, which the file does not list",
                    key.robot()
                ))
            }
        };
        Ok(match raw {
            RawFactor::PriorFactorPose3 {
                key: k,
                prior,
                covariance,
            } => JrlFactor::Prior {
                key: key(k)?,
                world_from_pose: pose(&prior)?,
                covariance: covariance_translation_first(&covariance)?,
            },
            RawFactor::BetweenFactorPose3 {
                key1,
                key2,
                measurement,
                covariance,
            } => {
                let (target, source) = (key(key1)?, key(key2)?);
                if target == source {
                    return Err(format!("the factor links key {target} to itself"));
                }
                JrlFactor::Between {
                    target,
                    source,
                    target_from_source: pose(&measurement)?,
                    covariance: covariance_translation_first(&covariance)?,
                }
            }
        })
    }

    fn values(
        &self,
        section: &str,
        letter: char,
        letters: &[char],
        raw: Option<Vec<RawValue>>,
    ) -> Result<BTreeMap<JrlKey, Isometry3<f64>>, IoError> {
        let mut values = BTreeMap::new();
        for (index, value) in raw.unwrap_or_default().into_iter().enumerate() {
            let key = JrlKey(value.key);
            let at = format!("{section}.{letter} value {index} (key {})", value.key);
            if !letters.contains(&key.robot()) {
                return Err(self.error(format!(
                    "{at}: the key belongs to robot {:?}, which the file does not list",
                    key.robot()
                )));
            }
            let pose = pose(&value.pose).map_err(|reason| self.error(format!("{at}: {reason}")))?;
            if values.insert(key, pose).is_some() {
                return Err(self.error(format!("{at}: the key is given twice")));
            }
        }
        Ok(values)
    }
}

/// A pose from `[w, x, y, z]` and `[x, y, z]`, the quaternion normalised.
fn pose(raw: &RawPose) -> Result<Isometry3<f64>, String> {
    let RawPose::Pose3 {
        rotation: [w, x, y, z],
        translation,
    } = *raw;
    let quaternion = Quaternion::new(w, x, y, z);
    let norm = quaternion.norm();
    if !(norm.is_finite() && norm > 1e-9) || translation.iter().any(|v| !v.is_finite()) {
        return Err(format!(
            "the pose (rotation {:?}, translation {translation:?}) is not a rigid transform",
            [w, x, y, z]
        ));
    }
    Ok(Isometry3::from_parts(
        Translation3::new(translation[0], translation[1], translation[2]),
        UnitQuaternion::from_quaternion(quaternion),
    ))
}

/// GTSAM's rotation-first 6x6 covariance (36 values, row-major) as a translation-first one, checked
/// symmetric and positive definite.
fn covariance_translation_first(values: &[f64]) -> Result<Matrix6<f64>, String> {
    if values.len() != 36 {
        return Err(format!(
            "a covariance of {} values; a 6x6 one has 36",
            values.len()
        ));
    }
    let rotation_first = SMatrix::<f64, 6, 6>::from_row_slice(values);
    // Row and column k of the result are row and column (k + 3) mod 6 of GTSAM's.
    let swapped = Matrix6::from_fn(|r, c| rotation_first[((r + 3) % 6, (c + 3) % 6)]);
    let scale = swapped.amax();
    if !(scale.is_finite() && scale > 0.0) {
        return Err("the covariance is zero or not finite".to_owned());
    }
    if (swapped - swapped.transpose()).amax() > 1e-9 * scale {
        return Err("the covariance is not symmetric".to_owned());
    }
    let symmetric = (swapped + swapped.transpose()) * 0.5;
    if symmetric.cholesky().is_none() {
        return Err("the covariance is not positive definite".to_owned());
    }
    Ok(symmetric)
}
