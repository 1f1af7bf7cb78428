//! Optimising the small benchmark graphs of the shared data folder.

use skid_backend_pgo::{Initialization, PgoOptions, optimize_g2o_file};

fn data(path: &str) -> std::path::PathBuf {
    skid_io::data_dir().join("pose_graph_benchmarks").join(path)
}

#[test]
fn small_graphs_converge() {
    for file in [
        "se_sync/tinyGrid3D.g2o",
        "gtsam_small/pose3example.txt",
        "gtsam_small/pose2example.txt",
        "se_sync/smallGrid3D.g2o",
        "se_sync/intel.g2o",
        "se_sync/sphere2500.g2o",
        "se_sync/parking-garage.g2o",
    ] {
        for init in [Initialization::File, Initialization::Chordal] {
            let options = PgoOptions {
                init,
                ..PgoOptions::default()
            };
            let (report, _) = optimize_g2o_file(data(file), &options).unwrap();
            println!("{}", serde_json::to_string(&report).unwrap());
        }
    }
}
