//! The pose-graph file harnesses: g2o (2D and 3D, decided by the file) and TORO, read with missing
//! vertices refused, then guessed; and JRL datasets (collaborative problems with outlier labels).

use skid_io::g2o::{AnyPoseGraph, G2oReadOptions, GraphPose, MissingVertices, PoseGraph, read_g2o};
use skid_io::jrl::{JrlFactor, parse_jrl};
use skid_io::toro::{InformationConvention, read_toro};

use crate::scratch::with_file;

/// With missing vertices refused, every edge joins two vertices the graph has.
fn check_edges<P: GraphPose>(graph: &PoseGraph<P>) {
    for edge in &graph.edges {
        assert!(
            graph.vertices.contains_key(&edge.from) && graph.vertices.contains_key(&edge.to),
            "edge {} -> {} names a vertex the graph lacks",
            edge.from,
            edge.to
        );
    }
}

fn check_any(graph: &AnyPoseGraph) {
    match graph {
        AnyPoseGraph::TwoD(graph) => check_edges(graph),
        AnyPoseGraph::ThreeD(graph) => check_edges(graph),
    }
}

fn options(missing_vertices: MissingVertices) -> G2oReadOptions {
    G2oReadOptions {
        missing_vertices,
        skip_malformed: false,
    }
}

pub fn g2o(data: &[u8]) {
    let strict = options(MissingVertices::Error);
    if let Some(Ok((graph, _))) = with_file("fuzz.g2o", data, |path| read_g2o(path, &strict)) {
        check_any(&graph);
    }
    let guessing = options(MissingVertices::Guess);
    let _ = with_file("fuzz.g2o", data, |path| read_g2o(path, &guessing));
}

pub fn toro(data: &[u8]) {
    let strict = options(MissingVertices::Error);
    for convention in [InformationConvention::Toro, InformationConvention::IsamSquareRoot] {
        if let Some(Ok(file)) = with_file("fuzz.graph", data, |path| read_toro(path, convention, &strict)) {
            check_any(&file.graph);
        }
    }
}

/// A JRL dataset that parses names only robots it lists, and every covariance is positive definite.
pub fn jrl(data: &[u8]) {
    let Ok(dataset) = parse_jrl(std::path::Path::new("fuzz.jrl"), data) else {
        return;
    };
    let listed = |letter: char| dataset.robot(letter).is_some();
    for (_, _, measurement) in dataset.measurements() {
        let (keys, covariance) = match &measurement.factor {
            JrlFactor::Prior { key, covariance, .. } => (vec![*key], covariance),
            JrlFactor::Between {
                target,
                source,
                covariance,
                ..
            } => (vec![*target, *source], covariance),
        };
        assert!(
            keys.iter().all(|key| listed(key.robot())),
            "a key of an unlisted robot"
        );
        assert!(
            covariance.cholesky().is_some(),
            "a covariance that is not positive definite"
        );
        assert!(!measurement.outlier || measurement.potential_outlier);
    }
}
