//! The free-space check on real scans of one place (`shared/data`): KITTI 00's first sweeps (HDL-64E,
//! Geiger et al. 2012) and the HDL-32E scan pair of fast_gicp, each pair registered by GICP from its
//! reference, must pass; the same pairs moved off their alignment must not.

#![allow(clippy::unwrap_used, clippy::expect_used)] // Test code fails loudly by design.

use skid_core::slots::FineRegistration;
use skid_core::{CloudView, PluginContext, Point, Pose};
use skid_fine_gicp::{GicpConfig, GicpRegistration};
use skid_io::{CloudReadOptions, kitti, trajectory};
use skid_verifier_pcm::free_space::FreeSpaceConfig;

/// A KITTI sweep at the 0.25 m voxels SKiD keeps keyframes at.
fn kitti_sweep(index: usize) -> Vec<Point> {
    let folder = skid_io::data_dir().join("kitti_00_lidar_frames_0000_0015");
    let cloud = kitti::read_kitti_bin(
        folder.join(format!("velodyne/{index:06}.bin")),
        CloudReadOptions::default(),
    )
    .unwrap();
    skid_geometry::voxel_downsample(&cloud.points, 0.25)
}

/// GICP from `guess`, as a loop is refined before it is verified.
fn refined(target: &[Point], source: &[Point], guess: &Pose) -> Pose {
    let mut gicp = GicpRegistration::new(GicpConfig::default(), &PluginContext::default()).unwrap();
    let (target, source) = (
        gicp.prepare(CloudView::new(target)).unwrap(),
        gicp.prepare(CloudView::new(source)).unwrap(),
    );
    let result = gicp.refine(&target, &source, guess).unwrap();
    assert!(result.converged);
    result.target_from_source
}

#[test]
fn real_scans_of_one_place_pass_and_fail_once_moved_off_it() {
    let config = FreeSpaceConfig::default();
    let folder = skid_io::data_dir().join("kitti_00_lidar_frames_0000_0015");
    let truth = trajectory::read_kitti_poses(folder.join("poses_velodyne.txt")).unwrap();
    // Up to 11.7 m apart, the longest baseline these sweeps hold.
    for (i, j) in [(0, 5), (0, 10), (3, 14), (0, 15)] {
        let (target, source) = (kitti_sweep(i), kitti_sweep(j));
        let aligned = refined(&target, &source, &(truth[i].inverse() * truth[j]));
        let count = config.count(&target, &source, &aligned);
        println!(
            "KITTI {i}-{j}: {count:?}, clustered {:.4}",
            count.clustered_fraction()
        );
        assert_eq!(config.judge(&count), None, "KITTI {i}-{j}: {count:?}");
        // Two metres across the street: one scan's kerbs, cars and facades stand in the other's road.
        let moved = Pose::translation(0.0, 2.0, 0.0) * aligned;
        let count = config.count(&target, &source, &moved);
        println!(
            "KITTI {i}-{j} moved 2 m: {count:?}, clustered {:.4}",
            count.clustered_fraction()
        );
        assert!(config.judge(&count).is_some(), "KITTI {i}-{j} moved: {count:?}");
    }
    let pair = skid_io::scan_pair::read_scan_pair().unwrap();
    let (target, source) = (
        skid_geometry::voxel_downsample(&pair.target, 0.25),
        skid_geometry::voxel_downsample(&pair.source, 0.25),
    );
    let count = config.count(&target, &source, &pair.target_from_source);
    println!(
        "HDL-32E pair: {count:?}, clustered {:.4}",
        count.clustered_fraction()
    );
    assert_eq!(config.judge(&count), None, "HDL-32E pair: {count:?}");
}
