//! `skid sim export` output read back through the `kitti` source (issue 3): a short two-robot sequence
//! from the simulator (the same `skid_sim::export_fleet_kitti` the command calls) is written to a
//! temporary folder and loaded robot by robot with `path = ".../robot{robot}"`. The ground truth must
//! round-trip to the precision of the text files (poses with 10 significant digits; the stamps, multiples
//! of the 0.1 s sweep written with 7, exactly), and every point must come back bit for bit (the `.bin`
//! records are the sensor's f32 values).

use skid_core::slots::Source;
use skid_core::{PluginContext, Pose, RobotId, Scan};
use skid_sim::{SimConfig, SimSource, export_fleet_kitti};
use skid_source_files::{KittiConfig, KittiSource};

/// Relative precision of a number written with `{:.9e}` (10 significant digits), with headroom for the
/// arithmetic of composing poses.
const POSE_TEXT_PRECISION: f64 = 1e-9;

fn small_fleet() -> SimConfig {
    SimConfig {
        world: "urban".to_owned(),
        sensor: "vlp16".to_owned(),
        robots: 2,
        frames: 4,
        ..SimConfig::default()
    }
}

/// Largest translation (m) and rotation (rad) between two poses.
fn difference(a: &Pose, b: &Pose) -> (f64, f64) {
    let delta = a.inverse() * b;
    (delta.translation.vector.norm(), delta.rotation.angle())
}

fn read_all(source: &mut KittiSource) -> Vec<Scan> {
    let mut scans = Vec::new();
    while let Some(scan) = source.next_scan().unwrap() {
        scans.push(scan);
    }
    scans
}

#[test]
fn exported_fleet_loads_through_the_kitti_source_with_ground_truth_round_tripped() {
    let config = small_fleet();
    let dir = tempfile::tempdir().unwrap();
    let summaries = export_fleet_kitti(dir.path(), &config, 2).unwrap();
    assert_eq!(summaries.len(), 2);

    for robot in 0..config.robots {
        let expected: Vec<Scan> = SimSource::new(&config, robot, 2).unwrap().collect();
        assert_eq!(expected.len(), config.frames as usize, "robot {robot}");
        assert_eq!(summaries[robot as usize].scans, expected.len());

        // One folder per robot, as a multi-robot run configures it.
        let kitti = KittiConfig {
            path: dir.path().join("robot{robot}"),
            ..KittiConfig::default()
        };
        let context = PluginContext {
            robot: RobotId(robot),
            fleet_size: config.robots,
            ..PluginContext::default()
        };
        let mut source = KittiSource::open(kitti, &context).unwrap();
        assert_eq!(source.remaining_hint(), Some(expected.len()));
        let loaded = read_all(&mut source);
        assert_eq!(loaded.len(), expected.len(), "robot {robot}");

        // poses.txt is relative to the first scan; world_from_first.txt puts the robot in the shared
        // simulation frame.
        let world_from_first = skid_io::trajectory::read_kitti_poses(
            dir.path().join(format!("robot{robot}/world_from_first.txt")),
        )
        .unwrap()[0];
        let sim_world_from_first = expected[0].ground_truth_world_from_sensor.unwrap();
        let (t, r) = difference(&world_from_first, &sim_world_from_first);
        let scale = 1.0 + sim_world_from_first.translation.vector.norm();
        assert!(
            t < POSE_TEXT_PRECISION * scale && r < POSE_TEXT_PRECISION,
            "robot {robot}: {t} m, {r} rad"
        );

        for (index, (scan, truth)) in loaded.iter().zip(&expected).enumerate() {
            let what = format!("robot {robot} scan {index}");
            assert_eq!(scan.robot, RobotId(robot), "{what}");
            assert_eq!(scan.sequence as usize, index, "{what}");

            // Stamps are written with 7 significant digits (KITTI's `%e`), which holds the simulator's
            // 0.1 s sweep stamps exactly for sequences of up to a million scans.
            assert_eq!(scan.stamp_nanos, truth.stamp_nanos, "{what}: stamp");

            let loaded_pose = scan.ground_truth_world_from_sensor.expect("ground truth");
            let sim_pose = truth.ground_truth_world_from_sensor.unwrap();
            let relative = sim_world_from_first.inverse() * sim_pose;
            let (t, r) = difference(&relative, &loaded_pose);
            let scale = 1.0 + relative.translation.vector.norm();
            assert!(
                t < POSE_TEXT_PRECISION * scale && r < POSE_TEXT_PRECISION,
                "{what}: ground truth off by {t} m, {r} rad"
            );
            let (t, r) = difference(&sim_pose, &(world_from_first * loaded_pose));
            assert!(
                t < 2.0 * POSE_TEXT_PRECISION * (scale + sim_pose.translation.vector.norm())
                    && r < 2.0 * POSE_TEXT_PRECISION,
                "{what}: world pose off by {t} m, {r} rad"
            );

            // The same points, in the same order, bit for bit; the format keeps no time offsets or rings.
            assert!(!truth.points.is_empty(), "{what}: empty simulated scan");
            assert_eq!(scan.points.len(), truth.points.len(), "{what}: point count");
            for (i, (got, want)) in scan.points.iter().zip(&truth.points).enumerate() {
                assert_eq!(
                    [got.x, got.y, got.z, got.intensity].map(f32::to_bits),
                    [want.x, want.y, want.z, want.intensity].map(f32::to_bits),
                    "{what}: point {i}"
                );
            }
        }
    }
}
