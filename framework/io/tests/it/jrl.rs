//! The JRL reader on the six COSMO-Bench datasets of the shared data folder (McGann, Potokar & Kaess,
//! 2025; `cosmo_bench/PROVENANCE.md`), whose counts it must reproduce, and on broken variants of a small
//! dataset, each a clear error naming the file and the entry.

use std::path::Path;

use skid_io::data_path;
use skid_io::jrl::{JrlFactor, parse_jrl, read_jrl};

/// `(file, factors, inter-robot factors, loop closures, labelled outliers)` from PROVENANCE.md.
const COSMO: [(&str, usize, usize, usize, usize); 6] = [
    ("kth_r3_00_d06_d09_d10_wifi.jrl", 2267, 231, 663, 72),
    ("kth_r3_00_d06_d09_d10_proradio.jrl", 2881, 845, 1276, 119),
    ("ntu_r3_02_d02_n04_n13_wifi.jrl", 2157, 26, 740, 30),
    ("ntu_r3_02_d02_n04_n13_proradio.jrl", 2325, 194, 908, 35),
    ("tuhh_r3_00_day_wifi.jrl", 1783, 384, 741, 73),
    ("tuhh_r3_00_day_proradio.jrl", 2133, 734, 1088, 90),
];

#[test]
fn every_cosmo_file_has_the_counts_its_provenance_states() {
    for (file, factors, inter, loops, outliers) in COSMO {
        let path = data_path(format!("cosmo_bench/{file}")).unwrap_or_else(|e| panic!("{e}"));
        let dataset = read_jrl(&path).unwrap();
        let letters: Vec<char> = dataset.robots.iter().map(|r| r.letter).collect();
        assert_eq!(letters, ['a', 'b', 'c'], "{file}");
        let all: Vec<_> = dataset.measurements().collect();
        let inter_robot = all
            .iter()
            .filter(|(_, _, m)| matches!(m.factor, JrlFactor::Between { target, source, .. } if target.robot() != source.robot()))
            .count();
        let potential = all.iter().filter(|(_, _, m)| m.potential_outlier).count();
        let labelled = all.iter().filter(|(_, _, m)| m.outlier).count();
        let priors = all
            .iter()
            .filter(|(_, _, m)| matches!(m.factor, JrlFactor::Prior { .. }))
            .count();
        assert_eq!(
            (all.len(), inter_robot, potential, labelled, priors),
            (factors, inter, loops, outliers, 3),
            "{file}"
        );
        for robot in &dataset.robots {
            // Stamps never go backwards; the ground truth and the initial estimate cover the same keys,
            // the robot's own among them.
            assert!(
                robot.entries.windows(2).all(|w| w[0].stamp <= w[1].stamp),
                "{file}"
            );
            assert_eq!(
                robot.ground_truth.keys().collect::<Vec<_>>(),
                robot.initialization.keys().collect::<Vec<_>>(),
                "{file} robot {}",
                robot.letter
            );
            assert!(robot.ground_truth.keys().any(|key| key.robot() == robot.letter));
        }
        // Every robot's reference poses agree where their parts of the problem overlap.
        for a in &dataset.robots {
            for b in &dataset.robots {
                for (key, pose) in &a.ground_truth {
                    if let Some(other) = b.ground_truth.get(key) {
                        assert!((pose.translation.vector - other.translation.vector).norm() < 1e-9);
                    }
                }
            }
        }
    }
}

#[test]
fn covariances_arrive_translation_first() {
    let path = data_path("cosmo_bench/tuhh_r3_00_day_wifi.jrl").unwrap_or_else(|e| panic!("{e}"));
    let dataset = read_jrl(&path).unwrap();
    // The priors' file covariance is 1e-8 on the rotation (GTSAM's first block) and 1e-6 on the
    // translation.
    let prior = dataset
        .measurements()
        .find_map(|(_, _, m)| match &m.factor {
            JrlFactor::Prior { covariance, .. } => Some(*covariance),
            JrlFactor::Between { .. } => None,
        })
        .unwrap();
    assert_eq!(prior[(0, 0)], 1e-6);
    assert_eq!(prior[(3, 3)], 1e-8);
}

/// A small valid dataset: robot `a` with a prior and one odometry step, robot `b` with a loop to `a`
/// labelled wrong.
fn small(replace: &[(&str, &str)]) -> String {
    let identity =
        "[1e-4,0,0,0,0,0, 0,1e-4,0,0,0,0, 0,0,1e-4,0,0,0, 0,0,0,1e-2,0,0, 0,0,0,0,1e-2,0, 0,0,0,0,0,1e-2]";
    let mut text = r#"{"name": "small", "robots": [97, 98],
 "groundtruth": {"a": [{"key": 6989586621679009792, "type": "Pose3", "rotation": [1, 0, 0, 0], "translation": [0, 0, 0]}]},
 "measurements": {
  "a": [{"stamp": 10, "measurements": [{"type": "PriorFactorPose3", "key": 6989586621679009792,
           "prior": {"type": "Pose3", "rotation": [1, 0, 0, 0], "translation": [0, 0, 0]}, "covariance": COV}]},
        {"stamp": 20, "measurements": [{"type": "BetweenFactorPose3", "key1": 6989586621679009792, "key2": 6989586621679009793,
           "measurement": {"type": "Pose3", "rotation": [1, 0, 0, 0], "translation": [1, 0, 0]}, "covariance": COV}]}],
  "b": [{"stamp": 30, "measurements": [{"type": "BetweenFactorPose3", "key1": 7061644215716937728, "key2": 6989586621679009793,
           "measurement": {"type": "Pose3", "rotation": [1, 0, 0, 0], "translation": [2, 0, 0]}, "covariance": COV}]}]},
 "potential_outlier_factors": {"b": [[0, 0]]},
 "outlier_factors": {"b": [[0, 0]]}}"#
        .replace("COV", identity);
    for (from, to) in replace {
        assert!(text.contains(from), "the fixture holds {from}");
        text = text.replacen(from, to, 1);
    }
    text
}

fn error_of(text: &str) -> String {
    parse_jrl(Path::new("broken.jrl"), text.as_bytes())
        .unwrap_err()
        .to_string()
}

#[test]
fn the_small_dataset_reads_with_its_labels() {
    let dataset = parse_jrl(Path::new("small.jrl"), small(&[]).as_bytes()).unwrap();
    let b = dataset.robot('b').unwrap();
    assert!(b.entries[0].measurements[0].outlier && b.entries[0].measurements[0].potential_outlier);
    assert!(!dataset.robot('a').unwrap().entries[1].measurements[0].potential_outlier);
}

#[test]
fn broken_datasets_are_errors_naming_the_file_and_the_entry() {
    // Each case: the replacements that break the dataset, and words the error must hold.
    type Case<'a> = (&'a [(&'a str, &'a str)], &'a [&'a str]);
    let cases: [Case; 7] = [
        // A stamp that is not a number.
        (
            &[(r#""stamp": 20"#, r#""stamp": "late""#)],
            &["broken.jrl", "measurements.a[1].stamp"],
        ),
        // A key of a robot the file does not list (`c`).
        (
            &[("7061644215716937728", "7133701809754865664")],
            &["broken.jrl", "measurements.b entry 0, factor 0", "does not list"],
        ),
        // A covariance that is not positive definite.
        (
            &[("[1e-4,0,0,0,0,0,", "[-1e-4,0,0,0,0,0,")],
            &[
                "broken.jrl",
                "measurements.a entry 0, factor 0",
                "not positive definite",
            ],
        ),
        // A covariance of the wrong size.
        (&[(" 0,0,0,0,0,1e-2]", " 0,0,0,0,0]")], &["broken.jrl", "36"]),
        // A label past the robot's entries.
        (
            &[(
                r#""outlier_factors": {"b": [[0, 0]]}"#,
                r#""outlier_factors": {"b": [[3, 0]]}"#,
            )],
            &["outlier_factors.b", "[3, 0]"],
        ),
        // A measurement type SKiD does not read.
        (
            &[(r#""type": "PriorFactorPose3""#, r#""type": "RangeFactorPose3""#)],
            &["broken.jrl", "RangeFactorPose3"],
        ),
        // A zero quaternion.
        (
            &[(
                r#""rotation": [1, 0, 0, 0], "translation": [1, 0, 0]"#,
                r#""rotation": [0, 0, 0, 0], "translation": [1, 0, 0]"#,
            )],
            &["measurements.a entry 1", "rigid"],
        ),
    ];
    for (replace, words) in cases {
        let error = error_of(&small(replace));
        for word in words {
            assert!(error.contains(word), "{replace:?}: `{error}` lacks {word:?}");
        }
    }
    // A file cut short anywhere is an error, never a panic.
    let text = small(&[]);
    for cut in (0..text.len()).step_by(97) {
        assert!(parse_jrl(Path::new("cut.jrl"), &text.as_bytes()[..cut]).is_err());
    }
    let missing = read_jrl(Path::new("/nonexistent/file.jrl"))
        .unwrap_err()
        .to_string();
    assert!(missing.contains("/nonexistent/file.jrl"), "{missing}");
}
