//! Reads every pose-graph file of the shared data directory (g2o, TORO and iSAM formats), checks vertex
//! and edge counts against the tables of the PROVENANCE.md files, and round-trips graphs through the
//! g2o writer.
//!
//! Data sets (read-only, located through `SKID_DATA_DIR`, default `<workspace>/../shared/data`):
//! * `pose_graph_benchmarks/`: SE-Sync `data/` (Rosen et al., IJRR 2019; datasets by Carlone, Olson,
//!   Kaess, Freiburg/Radish, KITTI), dpgo `data/`, iSAM `data/` (Kaess), GTSAM `examples/Data/`, riSAM's
//!   TORO version of CSAIL.
//! * `multi_robot_pose_graphs/`: distributed-mapper (Choudhary et al., ICRA 2016), robust distributed
//!   mapper / PCM (Mangelson et al., ICRA 2018; DOOR-SLAM), Kimera-RPGO test graphs.
//!
//! Files the PROVENANCE lists but that are kept back are simply not found; every file that is present
//! is read. A missing data directory makes these tests fail with a message naming `SKID_DATA_DIR`.

// Test helpers outside #[test] functions unwrap too: a failure there is a test failure.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use skid_io::g2o::{AnyPoseGraph, G2oReadOptions, GraphPose, PoseGraph, read_g2o, write_g2o};
use skid_io::toro::{InformationConvention, read_toro};
use skid_io::{Location, data_path};

fn data(relative: &str) -> PathBuf {
    data_path(relative).unwrap_or_else(|e| panic!("{e}"))
}

/// Every file under `dir`, sorted.
fn walk(dir: &Path) -> Vec<PathBuf> {
    let mut files = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
            } else {
                files.push(path);
            }
        }
    }
    files.sort();
    files
}

/// The first tag of the first non-blank line.
fn first_tag(path: &Path) -> String {
    let text = std::fs::read_to_string(path).unwrap();
    text.split_whitespace().next().unwrap_or_default().to_owned()
}

/// Edges between consecutive ids (either direction) and the others.
fn sequential<P: GraphPose>(graph: &PoseGraph<P>) -> (usize, usize) {
    let seq = graph.edges.iter().filter(|e| e.from.abs_diff(e.to) == 1).count();
    (seq, graph.edges.len() - seq)
}

fn counts(graph: &AnyPoseGraph) -> (usize, usize, usize, usize) {
    let (v, e) = graph.counts();
    let (s, o) = match graph {
        AnyPoseGraph::TwoD(g) => sequential(g),
        AnyPoseGraph::ThreeD(g) => sequential(g),
    };
    (v, e, s, o)
}

/// `file -> (poses, edges, sequential, other, vertices listed in the file)` from the PROVENANCE table.
fn benchmark_table() -> BTreeMap<&'static str, (usize, usize, usize, usize, bool)> {
    BTreeMap::from([
        ("se_sync/CSAIL.g2o", (1045, 1172, 1044, 128, false)),
        ("se_sync/MIT.g2o", (808, 827, 807, 20, true)),
        ("se_sync/ais2klinik.g2o", (15115, 16727, 15113, 1614, true)),
        ("se_sync/city10000.g2o", (10000, 20687, 9999, 10688, true)),
        ("se_sync/cubicle.g2o", (5750, 16869, 9248, 7621, true)),
        ("se_sync/intel.g2o", (1728, 2512, 1727, 785, true)),
        ("se_sync/kitti_00.g2o", (4541, 4677, 4540, 137, false)),
        ("se_sync/kitti_02.g2o", (4661, 4703, 4660, 43, false)),
        ("se_sync/kitti_05.g2o", (2761, 2826, 2760, 66, false)),
        ("se_sync/manhattan.g2o", (3500, 5453, 3499, 1954, false)),
        ("se_sync/parking-garage.g2o", (1661, 6275, 1660, 4615, true)),
        ("se_sync/smallGrid3D.g2o", (125, 297, 124, 173, true)),
        ("se_sync/sphere2500.g2o", (2500, 4949, 2499, 2450, true)),
        (
            "se_sync/sphere_bignoise_vertex3.g2o",
            (2200, 8647, 2199, 6448, true),
        ),
        ("se_sync/tinyGrid3D.g2o", (9, 11, 8, 3, true)),
        ("se_sync/torus3D.g2o", (5000, 9048, 4999, 4049, true)),
        ("dpgo_extra/input_INTEL_g2o.g2o", (1228, 1483, 1227, 256, true)),
        ("dpgo_extra/input_M3500_g2o.g2o", (3500, 5453, 3499, 1954, true)),
        ("dpgo_extra/kitti_06.g2o", (1101, 1150, 1100, 50, false)),
        ("dpgo_extra/kitti_07.g2o", (1101, 1106, 1100, 6, false)),
        ("dpgo_extra/kitti_08.g2o", (4071, 4070, 4070, 0, false)),
        ("dpgo_extra/kitti_09.g2o", (1591, 1592, 1590, 2, false)),
        (
            "isam_with_groundtruth/city10000.txt",
            (10000, 20687, 9999, 10688, false),
        ),
        (
            "isam_with_groundtruth/city10000_groundtruth.txt",
            (10000, 20687, 9999, 10688, false),
        ),
        (
            "isam_with_groundtruth/manhattanOlson3500.txt",
            (3500, 5598, 3499, 2099, false),
        ),
        (
            "isam_with_groundtruth/manhattanOlson3500_groundtruth.txt",
            (3500, 5598, 3499, 2099, false),
        ),
        (
            "isam_with_groundtruth/sphere2500.txt",
            (2500, 4949, 2499, 2450, false),
        ),
        (
            "isam_with_groundtruth/sphere2500_groundtruth.txt",
            (2500, 4949, 2499, 2450, false),
        ),
        ("gtsam_small/Klaus3.g2o", (3, 3, 2, 1, true)),
        ("gtsam_small/noisyToyGraph.txt", (4, 5, 3, 2, true)),
        ("gtsam_small/optimizedNoisyToyGraph.txt", (4, 5, 3, 2, true)),
        ("gtsam_small/orientationsNoisyToyGraph.txt", (4, 5, 3, 2, true)),
        ("gtsam_small/pose2example.txt", (11, 12, 10, 2, true)),
        ("gtsam_small/pose3example-grid.txt", (27, 44, 26, 18, true)),
        ("gtsam_small/pose3example-offdiagonal.txt", (2, 1, 1, 0, true)),
        ("gtsam_small/pose3example.txt", (5, 6, 4, 2, true)),
        ("gtsam_small/toyExample.g2o", (5, 6, 4, 2, true)),
        ("toro_format/csail.toro", (1045, 1172, 1044, 128, true)),
        (
            "toro_format/sphere_smallnoise.graph",
            (2200, 8647, 2199, 6448, true),
        ),
        ("toro_format/w100.graph", (100, 300, 99, 201, true)),
    ])
}

#[test]
fn every_benchmark_graph_matches_provenance() {
    let root = data("pose_graph_benchmarks");
    let table = benchmark_table();
    let strict = G2oReadOptions::default();
    let mut checked = BTreeSet::new();
    for path in walk(&root) {
        let relative = path
            .strip_prefix(&root)
            .unwrap()
            .to_string_lossy()
            .replace('\\', "/");
        if relative.ends_with(".md") {
            continue;
        }
        let tag = first_tag(&path);
        let (graph, report) = if tag.starts_with("VERTEX_") || tag.starts_with("EDGE_") {
            read_g2o(&path, &strict).unwrap_or_else(|e| panic!("{e}"))
        } else {
            let convention = if relative.starts_with("isam") {
                InformationConvention::IsamSquareRoot
            } else {
                InformationConvention::Toro
            };
            let file = read_toro(&path, convention, &strict).unwrap_or_else(|e| panic!("{e}"));
            if relative.ends_with("w100.graph") {
                assert_eq!(file.equivalences.len(), 40);
            }
            (file.graph, file.report)
        };
        assert!(
            report.unresolved.is_empty(),
            "{relative}: unresolved {:?}",
            report.unresolved
        );
        assert!(report.malformed_lines.is_empty());
        let expected = table
            .get(relative.as_str())
            .unwrap_or_else(|| panic!("{relative} is not in the table"));
        let (poses, edges, seq, other, listed) = *expected;
        assert_eq!(counts(&graph), (poses, edges, seq, other), "{relative}");
        assert_eq!(report.vertex_lines, if listed { poses } else { 0 }, "{relative}");
        assert_eq!(report.guessed.len(), if listed { 0 } else { poses }, "{relative}");
        checked.insert(relative);
    }
    // The files that are certainly present (some others are kept back for acceptance benchmarks).
    for must in [
        "se_sync/kitti_00.g2o",
        "se_sync/parking-garage.g2o",
        "gtsam_small/pose2example.txt",
        "toro_format/w100.graph",
    ] {
        assert!(
            checked.contains(must),
            "{must} not found under {}",
            root.display()
        );
    }
    assert!(
        checked.len() >= 30,
        "only {} pose-graph files found",
        checked.len()
    );
}

#[test]
fn kitti_00_odometry_chain_matches_provenance() {
    let (graph, report) = read_g2o(
        data("pose_graph_benchmarks/se_sync/kitti_00.g2o"),
        &G2oReadOptions::default(),
    )
    .unwrap();
    let AnyPoseGraph::TwoD(graph) = graph else {
        panic!("kitti_00.g2o is 2D")
    };
    assert_eq!(report.guessed.len(), 4541);
    assert_eq!(graph.vertices[&0], nalgebra::Isometry2::identity());
    // PROVENANCE: the first odometry steps are 0.687, 0.698 m.
    let step =
        |i: u64| (graph.vertices[&(i + 1)].translation.vector - graph.vertices[&i].translation.vector).norm();
    assert!(
        (step(0) - 0.687).abs() < 1e-3 && (step(1) - 0.698).abs() < 1e-3,
        "{} {}",
        step(0),
        step(1)
    );
    // Chaining composes exactly: vertex i+1 = vertex i * measurement.
    let e = &graph.edges[10];
    let composed = graph.vertices[&e.from] * e.from_from_to;
    assert!((composed.translation.vector - graph.vertices[&e.to].translation.vector).norm() < 1e-12);
}

/// `(robots, poses per robot, intra-robot edges, unique inter-robot edges)` of a multi-robot set.
fn multi_robot_counts(dir: &Path) -> (usize, usize, usize, usize) {
    let mut files: Vec<PathBuf> = walk(dir)
        .into_iter()
        .filter(|p| p.extension().is_some_and(|e| e == "g2o"))
        .collect();
    files.retain(|p| {
        !p.file_name()
            .is_some_and(|n| n.to_string_lossy().starts_with("fullGraph"))
    });
    let options = G2oReadOptions {
        skip_malformed: true,
        ..G2oReadOptions::default()
    };
    let (mut poses, mut intra, mut inter) = (BTreeSet::new(), 0, BTreeSet::new());
    for file in &files {
        let (graph, _) = read_g2o(file, &options).unwrap_or_else(|e| panic!("{e}"));
        let AnyPoseGraph::ThreeD(graph) = graph else {
            panic!("{} is not 3D", file.display())
        };
        poses.insert(graph.vertices.len());
        for edge in &graph.edges {
            if edge.from >> 56 == edge.to >> 56 {
                intra += 1;
            } else {
                inter.insert((edge.from, edge.to));
            }
        }
    }
    assert_eq!(
        poses.len(),
        1,
        "{}: robots differ in pose count {poses:?}",
        dir.display()
    );
    (
        files.len(),
        poses.into_iter().next().unwrap_or(0),
        intra,
        inter.len(),
    )
}

#[test]
fn multi_robot_graphs_match_provenance() {
    let root = data("multi_robot_pose_graphs");
    // Every g2o file reads strictly, except the one with a corrupted line 16 (a stray fragment
    // "0410268 0.7588833" between two vertex lines), which fails naming that line.
    let corrupted = "pcm_robust_distributed_mapper/pairwise_consistency_maximization/spoiled/simulation/example_2robots/1.g2o";
    let mut files = 0;
    for path in walk(&root)
        .into_iter()
        .filter(|p| p.extension().is_some_and(|e| e == "g2o"))
    {
        files += 1;
        let relative = path
            .strip_prefix(&root)
            .unwrap()
            .to_string_lossy()
            .replace('\\', "/");
        match read_g2o(&path, &G2oReadOptions::default()) {
            Ok((graph, _)) => assert!(matches!(graph, AnyPoseGraph::ThreeD(_)), "{relative}"),
            Err(e) => {
                assert_eq!(relative, corrupted, "{e}");
                assert_eq!(e.location(), Some(Location::Line(16)));
                assert!(
                    e.to_string().contains("line 16: unknown g2o tag \"0410268\""),
                    "{e}"
                );
            }
        }
    }
    assert!(files >= 300, "{files} multi-robot g2o files");

    let dm = |set: &str| multi_robot_counts(&root.join("distributed_mapper").join(set));
    assert_eq!(dm("example_2robots"), (2, 8, 24, 4));
    assert_eq!(dm("example_4robots"), (4, 16, 112, 32));
    assert_eq!(dm("example_9robots"), (9, 8, 108, 48));
    assert_eq!(dm("example_16robots"), (16, 8, 192, 96));
    assert_eq!(dm("example_25robots"), (25, 8, 300, 160));
    assert_eq!(dm("example_36robots"), (36, 8, 432, 240));
    assert_eq!(dm("example_49robots"), (49, 8, 588, 336));
    assert_eq!(dm("blocks_world/2robots"), (2, 32, 128, 16));
    let (full, _) = read_g2o(
        root.join("distributed_mapper/blocks_world/2robots/fullGraph.g2o"),
        &G2oReadOptions::default(),
    )
    .unwrap();
    assert_eq!(full.counts(), (64, 144));

    let pcm = |set: &str| multi_robot_counts(&root.join("pcm_robust_distributed_mapper").join(set));
    let sim = "pairwise_consistency_maximization";
    assert_eq!(
        pcm(&format!("{sim}/clean/simulation/example_2robots")),
        (2, 21, 40, 10)
    );
    assert_eq!(
        pcm(&format!("{sim}/spoiled/simulation/example_2robots")),
        (2, 21, 40, 20)
    );
    assert_eq!(
        pcm(&format!("{sim}/spoiled/simulation_not_in_order/example_2robots")),
        (2, 21, 40, 20)
    );
    assert_eq!(
        pcm(&format!("{sim}/spoiled/simulation/example_4robots")),
        (4, 21, 80, 48)
    );
    assert_eq!(
        pcm(&format!("{sim}/spoiled/simulation/example_8robots")),
        (8, 21, 160, 223)
    );
    assert_eq!(pcm("argos_simulation/clean/example_2robots"), (2, 442, 882, 34));
    assert_eq!(pcm("argos_simulation/clean/example_4robots"), (4, 110, 436, 83));
    assert_eq!(pcm("argos_simulation/spoiled/example_2robots"), (2, 142, 282, 30));
    assert_eq!(
        pcm("argos_simulation/spoiled/example_4robots"),
        (4, 275, 1096, 44)
    );

    // The lenient read of the corrupted file skips exactly line 16.
    let options = G2oReadOptions {
        skip_malformed: true,
        ..G2oReadOptions::default()
    };
    let (graph, report) = read_g2o(root.join(corrupted), &options).unwrap();
    assert_eq!((graph.counts(), report.malformed_lines), ((21, 40), vec![16]));
    // Per-robot files name the other robot's poses in inter-robot edges: reported, not guessed.
    assert!(report.guessed.is_empty() && !report.unresolved.is_empty());
    assert!(
        report.unresolved.iter().all(|id| id >> 56 == u64::from(b'a')),
        "{:?}",
        report.unresolved
    );
}

#[test]
fn kimera_rpgo_graphs_match_provenance() {
    let read = |name: &str| {
        let (graph, report) = read_g2o(
            data(&format!("multi_robot_pose_graphs/kimera_rpgo_tests/{name}")),
            &G2oReadOptions::default(),
        )
        .unwrap();
        let AnyPoseGraph::ThreeD(graph) = graph else {
            panic!("{name} is not 3D")
        };
        assert!(
            report.unresolved.is_empty() && report.guessed.is_empty(),
            "{name}"
        );
        graph
    };
    for (name, poses, odometry, loops) in [
        ("robot_a.g2o", 50, 49, 3),
        ("robot_b.g2o", 42, 41, 2),
        ("ordered.g2o", 140, 136, 17),
        ("unordered.g2o", 140, 136, 17),
    ] {
        let graph = read(name);
        assert_eq!(
            (graph.vertices.len(), sequential(&graph)),
            (poses, (odometry, loops)),
            "{name}"
        );
    }
    // robot_a's loop closures a38-a49, a28-a39, a33-a27 (GTSAM symbol keys 'a' << 56 | index).
    let a = u64::from(b'a') << 56;
    let loops: BTreeSet<(u64, u64)> = read("robot_a.g2o")
        .edges
        .iter()
        .filter(|e| e.from.abs_diff(e.to) != 1)
        .map(|e| (e.from - a, e.to - a))
        .collect();
    assert_eq!(loops, BTreeSet::from([(38, 49), (28, 39), (33, 27)]));
    // ordered and unordered hold the same graph in a different line order.
    let (ordered, unordered) = (read("ordered.g2o"), read("unordered.g2o"));
    assert_eq!(ordered.vertices, unordered.vertices);
    let key = |g: &PoseGraph<nalgebra::Isometry3<f64>>| -> BTreeSet<(u64, u64)> {
        g.edges.iter().map(|e| (e.from, e.to)).collect()
    };
    assert_eq!(key(&ordered), key(&unordered));
}

#[test]
fn real_graphs_round_trip_through_the_g2o_writer() {
    let dir = tempfile::tempdir().unwrap();
    for relative in [
        "pose_graph_benchmarks/se_sync/parking-garage.g2o",
        "pose_graph_benchmarks/se_sync/intel.g2o",
        "pose_graph_benchmarks/se_sync/kitti_05.g2o",
    ] {
        let (graph, _) = read_g2o(data(relative), &G2oReadOptions::default()).unwrap();
        let out = dir.path().join("out.g2o");
        write_g2o(&out, &graph).unwrap();
        let (back, report) = read_g2o(&out, &G2oReadOptions::default()).unwrap();
        assert!(report.guessed.is_empty(), "written graphs list every vertex");
        match (&graph, &back) {
            (AnyPoseGraph::ThreeD(a), AnyPoseGraph::ThreeD(b)) => {
                assert_eq!(
                    a.vertices.keys().collect::<Vec<_>>(),
                    b.vertices.keys().collect::<Vec<_>>()
                );
                for (p, q) in a.vertices.values().zip(b.vertices.values()) {
                    assert!((p.to_homogeneous() - q.to_homogeneous()).abs().max() < 1e-12);
                }
                for (e, f) in a.edges.iter().zip(&b.edges) {
                    assert_eq!((e.from, e.to, e.information), (f.from, f.to, f.information));
                    assert!(
                        (e.from_from_to.to_homogeneous() - f.from_from_to.to_homogeneous())
                            .abs()
                            .max()
                            < 1e-12
                    );
                }
            }
            (AnyPoseGraph::TwoD(a), AnyPoseGraph::TwoD(b)) => {
                for (p, q) in a.vertices.values().zip(b.vertices.values()) {
                    assert!((p.to_homogeneous() - q.to_homogeneous()).abs().max() < 1e-12);
                }
                for (e, f) in a.edges.iter().zip(&b.edges) {
                    assert_eq!((e.from, e.to, e.information), (f.from, f.to, f.information));
                    assert!(
                        (e.from_from_to.to_homogeneous() - f.from_from_to.to_homogeneous())
                            .abs()
                            .max()
                            < 1e-12
                    );
                }
            }
            _ => panic!("{relative}: dimension changed"),
        }
    }
}
