//! Conformance of sources: scans come in order with non-decreasing stamps and finite points, ground truth
//! (when present) is a valid pose, and an ended source stays ended.

use skid_core::slots::Source;

/// Drains `source` (at most `max_scans`) and checks the contract; returns the number of scans read.
pub fn check_source(source: &mut dyn Source, max_scans: usize) -> usize {
    let mut count = 0usize;
    let mut last_stamp = 0u64;
    while count < max_scans {
        let Some(scan) = source.next_scan().expect("a healthy source reads without error") else {
            break;
        };
        assert_eq!(
            scan.sequence as usize, count,
            "scan sequence numbers count up from 0"
        );
        assert!(
            scan.stamp_nanos >= last_stamp,
            "scan {count}: stamp went backwards"
        );
        last_stamp = scan.stamp_nanos;
        assert!(!scan.points.is_empty(), "scan {count} is empty");
        assert!(
            scan.points.iter().all(|p| p.is_finite()),
            "scan {count} has non-finite points"
        );
        if let Some(truth) = scan.ground_truth_world_from_sensor {
            assert!(
                truth.translation.vector.iter().all(|v| v.is_finite()),
                "scan {count}: bad ground truth"
            );
        }
        for pair in scan.imu.windows(2) {
            assert!(
                pair[1].stamp_nanos >= pair[0].stamp_nanos,
                "scan {count}: IMU stamps go backwards"
            );
        }
        count += 1;
    }
    if count < max_scans {
        assert!(
            source
                .next_scan()
                .expect("an ended source keeps answering")
                .is_none(),
            "an ended source stays ended"
        );
    }
    count
}
