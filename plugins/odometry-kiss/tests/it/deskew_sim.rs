//! Deskewing with the constant-velocity model (KISS-ICP, Vizzo et al., RA-L 2023) on a simulated sequence
//! with real motion distortion: a 32-beam ground robot accelerating to about 4 m/s in the urban world of `skid-sim`, whose
//! points carry their firing time. The odometry with deskewing must end closer to the ground truth than
//! the same odometry without it.

use skid_core::PluginContext;
use skid_core::slots::Odometry;
use skid_odometry_kiss::{KissIcpConfig, KissIcpOdometry, trajectory_errors};
use skid_sim::{SimConfig, SimSource};

fn run(deskew: bool, scans: &[skid_core::Scan]) -> (f64, f64) {
    let config = KissIcpConfig {
        deskew,
        ..KissIcpConfig::default()
    };
    let mut odometry = KissIcpOdometry::new(
        config,
        &PluginContext {
            threads: 2,
            ..PluginContext::default()
        },
    )
    .unwrap();
    let mut estimate = Vec::new();
    let mut truth = Vec::new();
    for scan in scans {
        estimate.push(odometry.register(scan).unwrap().world_from_sensor);
        truth.push(scan.ground_truth_world_from_sensor.unwrap());
    }
    let errors = trajectory_errors(&estimate, &truth).unwrap();
    (errors.ate_rmse_m, errors.final_translation_error_m)
}

#[test]
fn deskewing_lowers_the_error_of_a_fast_moving_sensor() {
    let config = SimConfig {
        world: "urban".to_owned(),
        sensor: "os1-32".to_owned(),
        robots: 1,
        frames: 120,
        speed_mps: 12.0,
        imu: false,
        ..SimConfig::default()
    };
    let source = SimSource::new(&config, 0, 2).unwrap();
    let scans: Vec<_> = source.collect();
    let path_m: f64 = scans
        .windows(2)
        .map(|w| {
            let (a, b) = (
                w[0].ground_truth_world_from_sensor.unwrap(),
                w[1].ground_truth_world_from_sensor.unwrap(),
            );
            (b.translation.vector - a.translation.vector).norm()
        })
        .sum();
    assert!(
        path_m > 15.0,
        "the sequence must move fast enough to distort its scans ({path_m:.1} m)"
    );
    let (ate_on, end_on) = run(true, &scans);
    let (ate_off, end_off) = run(false, &scans);
    println!(
        "path {path_m:.1} m; deskewed: ATE {ate_on:.3} m, end {end_on:.3} m; raw: ATE {ate_off:.3} m, end {end_off:.3} m"
    );
    assert!(
        ate_on < ate_off,
        "deskewing must lower the ATE ({ate_on:.3} m vs {ate_off:.3} m)"
    );
}
