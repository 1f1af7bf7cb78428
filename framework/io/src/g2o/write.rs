//! Writing pose graphs as g2o text: vertices (ascending id), `FIX` lines, then edges in order.
//! Numbers are printed in their shortest exact decimal form, so a graph read back is equal up to the
//! normalisation of quaternions.

use std::fmt::Write as _;
use std::path::Path;

use nalgebra::{Isometry2, Isometry3};

use super::read::G2oPose;
use super::{AnyPoseGraph, PoseGraph};
use crate::error::{IoError, write_file};

/// The g2o text of a graph of pose type `P`.
fn graph_text<P: G2oPose>(graph: &PoseGraph<P>) -> String {
    let mut text = String::with_capacity(64 * graph.vertices.len() + 160 * graph.edges.len());
    for (id, pose) in &graph.vertices {
        let _ = writeln!(text, "{} {id} {}", P::VERTEX_TAG, pose.format_vertex());
    }
    for id in &graph.fixed {
        let _ = writeln!(text, "FIX {id}");
    }
    for edge in &graph.edges {
        let measurement = edge.from_from_to.format_edge(&edge.information);
        let _ = writeln!(text, "{} {} {} {measurement}", P::EDGE_TAG, edge.from, edge.to);
    }
    text
}

/// The g2o text of a 3D graph.
pub fn g2o_text_3d(graph: &PoseGraph<Isometry3<f64>>) -> String {
    graph_text(graph)
}

/// The g2o text of a 2D graph.
pub fn g2o_text_2d(graph: &PoseGraph<Isometry2<f64>>) -> String {
    graph_text(graph)
}

/// Writes a 3D graph as g2o.
pub fn write_g2o_3d(path: impl AsRef<Path>, graph: &PoseGraph<Isometry3<f64>>) -> Result<(), IoError> {
    write_file(path.as_ref(), g2o_text_3d(graph).as_bytes())
}

/// Writes a 2D graph as g2o.
pub fn write_g2o_2d(path: impl AsRef<Path>, graph: &PoseGraph<Isometry2<f64>>) -> Result<(), IoError> {
    write_file(path.as_ref(), g2o_text_2d(graph).as_bytes())
}

/// Writes a graph of either dimension as g2o.
pub fn write_g2o(path: impl AsRef<Path>, graph: &AnyPoseGraph) -> Result<(), IoError> {
    match graph {
        AnyPoseGraph::TwoD(g) => write_g2o_2d(path, g),
        AnyPoseGraph::ThreeD(g) => write_g2o_3d(path, g),
    }
}
