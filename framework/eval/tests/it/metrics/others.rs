//! Registration statistics, descriptor memory and latency against distance.

use skid_core::slots::DescriptorBuf;
use skid_eval::{
    EvalError, LatencySample, RegistrationPair, RegistrationThresholds, descriptor_memory,
    descriptor_memory_of, latency_vs_distance, registration_stats,
};

use super::{close, pose};

#[test]
fn registration_success_rte_and_rre_over_successes_only() {
    let truth = pose(10.0, -2.0, 0.5, [0.0, 0.0, 1.0]);
    let yaw = |deg: f64| pose(0.0, 0.0, 0.0, [0.0, 0.0, deg.to_radians()]);
    let shift = |x: f64| pose(x, 0.0, 0.0, [0.0; 3]);
    // Estimates (errors relative to the truth): 1.0 m / 0°, 0.5 m / 4°, 2.0 m / 0° (not below 2 m),
    // 0.1 m / 6° (not below 5°), no result. Successes: the first two → rate 2/5;
    // RTE = (1.0 + 0.5)/2 = 0.75 m = 75 cm, RRE = (0 + 4)/2 = 2°.
    // The shifts are applied on the left (in the target frame) so the translation error is exactly
    // the shift; the 4° yaw is applied on the right, so it leaves the translation untouched.
    let pairs = [
        Some(shift(1.0) * truth),
        Some(shift(0.5) * truth * yaw(4.0)),
        Some(shift(2.0) * truth),
        Some(shift(0.1) * truth * yaw(6.0)),
        None,
    ]
    .map(|estimated| RegistrationPair {
        estimated,
        ground_truth: truth,
    });
    let stats = registration_stats(&pairs, &RegistrationThresholds::default()).unwrap();
    assert_eq!((stats.pairs, stats.successes), (5, 2));
    close(stats.success_rate, 0.4, 1e-15);
    close(stats.rte_m.unwrap(), 0.75, 1e-12);
    close(stats.rte_cm.unwrap(), 75.0, 1e-10);
    close(stats.rre_deg.unwrap(), 2.0, 1e-9);
    close(stats.errors[3].unwrap().rotation_deg, 6.0, 1e-9);
    assert!(stats.errors[4].is_none());

    // Looser thresholds (3 m, 10°) make the third and fourth succeed too:
    // RTE = (1 + 0.5 + 2 + 0.1)/4 = 0.9, RRE = (0 + 4 + 0 + 6)/4 = 2.5.
    let loose = RegistrationThresholds {
        max_translation_m: 3.0,
        max_rotation_deg: 10.0,
    };
    let stats = registration_stats(&pairs, &loose).unwrap();
    assert_eq!(stats.successes, 4);
    close(stats.rte_m.unwrap(), 0.9, 1e-12);
    close(stats.rre_deg.unwrap(), 2.5, 1e-9);

    // No success: RTE/RRE undefined rather than NaN.
    let none = registration_stats(&pairs[4..], &RegistrationThresholds::default()).unwrap();
    assert_eq!((none.success_rate, none.rte_m, none.rre_deg), (0.0, None, None));
}

#[test]
fn registration_bad_input() {
    assert!(matches!(
        registration_stats(&[], &RegistrationThresholds::default()),
        Err(EvalError::TooFew { .. })
    ));
    let mut nan = pose(0.0, 0.0, 0.0, [0.0; 3]);
    nan.translation.vector.z = f64::NAN;
    let pair = RegistrationPair {
        estimated: Some(nan),
        ground_truth: pose(0.0, 0.0, 0.0, [0.0; 3]),
    };
    assert!(matches!(
        registration_stats(&[pair], &RegistrationThresholds::default()),
        Err(EvalError::NonFinite { index: 0, .. })
    ));
    let zero = RegistrationThresholds {
        max_translation_m: 0.0,
        ..RegistrationThresholds::default()
    };
    assert!(matches!(
        registration_stats(&[pair], &zero),
        Err(EvalError::InvalidOption { .. })
    ));
}

#[test]
fn descriptor_memory_sums_sizes() {
    let m = descriptor_memory([100, 200, 300]);
    assert_eq!((m.descriptors, m.total_bytes), (3, 600));
    close(m.mean_bytes, 200.0, 0.0);
    close(m.total_mib, 600.0 / 1_048_576.0, 1e-18);
    // f32 descriptors: 10 and 30 values → 40 + 120 bytes.
    let bufs = [10, 30].map(|n| DescriptorBuf {
        kind: "solid".into(),
        values: vec![0.0; n],
    });
    assert_eq!(descriptor_memory_of(&bufs).total_bytes, 160);
    assert_eq!(descriptor_memory(std::iter::empty()).mean_bytes, 0.0);
}

#[test]
fn latency_is_binned_by_distance() {
    // Bins of 10 m: [0,10) holds the 5 m message (50 ms); [10,20) holds a lost 15 m message and a
    // 12 m one of 70 ms → delivery 1/2; [40,50) one 60 ms message.
    let samples = [
        LatencySample::from_stamps(5.0, 1_000_000_000, Some(1_050_000_000)),
        LatencySample::from_stamps(15.0, 0, None),
        LatencySample::from_stamps(12.0, 2_000_000_000, Some(2_070_000_000)),
        LatencySample {
            distance_m: 45.0,
            latency_s: Some(0.06),
        },
    ];
    let bins = latency_vs_distance(&samples, 10.0).unwrap();
    assert_eq!(bins.len(), 3);
    assert_eq!(
        (bins[0].distance_min_m, bins[0].distance_max_m, bins[0].sent),
        (0.0, 10.0, 1)
    );
    close(bins[0].latency_s.unwrap().mean, 0.05, 1e-12);
    assert_eq!((bins[1].sent, bins[1].delivered), (2, 1));
    close(bins[1].delivery_rate, 0.5, 0.0);
    close(bins[1].latency_s.unwrap().max, 0.07, 1e-12);
    assert_eq!(bins[2].distance_min_m, 40.0);

    assert!(latency_vs_distance(&samples, 0.0).is_err());
    assert!(latency_vs_distance(&[], 10.0).is_err());
    let negative = [LatencySample::from_stamps(1.0, 10, Some(5))];
    assert!(matches!(
        latency_vs_distance(&negative, 1.0),
        Err(EvalError::NonFinite { .. })
    ));
}
