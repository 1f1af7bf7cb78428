//! Parsing g2o files line by line into a [`PoseGraph`], then completing missing vertices.

use std::collections::HashMap;
use std::path::Path;

use nalgebra::{Isometry2, Isometry3, Matrix3, Matrix6, Vector2};

use super::guess::guess_missing;
use super::{AnyPoseGraph, Edge, G2oReadOptions, G2oReport, GraphPose, MissingVertices, PoseGraph};
use super::{symmetric_from_upper, upper_of};
use crate::error::IoError;
use crate::geometry::{isometry_from_xyz_quat, isometry_to_xyz_quat};
use crate::text::{Tokens, fmt_f64, numbered_lines, read_text};

/// Tags skipped (and counted) because a pose graph does not use them; see the module documentation.
pub(crate) const TOLERATED_TAGS: &[&str] = &[
    "VERTEX_XY",
    "VERTEX_XYZ",
    "VERTEX_TRACKXYZ",
    "VERTEX_POINTXYZ",
    "VERTEX_SE3:EXPMAP",
    "VERTEX_CAM",
    "VERTEX_INTRINSICS",
    "EDGE_SE2_XY",
    "EDGE_SE2_POINT_XY",
    "EDGE_BEARING_SE2_XY",
    "EDGE_SE2_PRIOR",
    "EDGE_SE2_XYPRIOR",
    "EDGE_SE2_OFFSET",
    "EDGE_SE3_XYZ",
    "EDGE_SE3_POINTXYZ",
    "EDGE_SE3_TRACKXYZ",
    "EDGE_SE3_PRIOR",
    "EDGE_SE3_OFFSET",
    "EDGE_PROJECT_XYZ2UV:EXPMAP",
    "PARAMS_SE3OFFSET",
    "PARAMS_CAMERACALIB",
    "PARAMS_STEREOCAMERACALIB",
    "CACHE_SE3_OFFSET",
];

/// The per-dimension part of the g2o syntax.
pub(crate) trait G2oPose: GraphPose {
    /// Tag of a vertex line.
    const VERTEX_TAG: &'static str;
    /// Tag of an edge line.
    const EDGE_TAG: &'static str;
    /// The pose tags of the other dimension (errors in a file of this dimension).
    const OTHER_TAGS: [&'static str; 2];
    /// Parses the numbers of a vertex after its id.
    fn parse_vertex(tokens: &mut Tokens<'_>) -> Result<Self, IoError>;
    /// Parses the measurement and information of an edge after its two ids.
    fn parse_edge(tokens: &mut Tokens<'_>) -> Result<(Self, Self::Information), IoError>;
    /// Formats the numbers of a vertex (after the id).
    fn format_vertex(&self) -> String;
    /// Formats the measurement and information of an edge (after the ids).
    fn format_edge(&self, information: &Self::Information) -> String;
}

/// Joins numbers with single spaces in their shortest exact form.
fn join(values: &[f64]) -> String {
    values.iter().map(|v| fmt_f64(*v)).collect::<Vec<_>>().join(" ")
}

impl G2oPose for Isometry3<f64> {
    const VERTEX_TAG: &'static str = "VERTEX_SE3:QUAT";
    const EDGE_TAG: &'static str = "EDGE_SE3:QUAT";
    const OTHER_TAGS: [&'static str; 2] = ["VERTEX_SE2", "EDGE_SE2"];

    fn parse_vertex(tokens: &mut Tokens<'_>) -> Result<Self, IoError> {
        let t = tokens.next_f64s::<3>("position x y z")?;
        let q = tokens.next_f64s::<4>("quaternion qx qy qz qw")?;
        isometry_from_xyz_quat(t, q).map_err(|m| tokens.error(m))
    }

    fn parse_edge(tokens: &mut Tokens<'_>) -> Result<(Self, Matrix6<f64>), IoError> {
        let pose = Self::parse_vertex(tokens)?;
        let upper = tokens.next_f64s::<21>("information matrix entry (21 upper-triangular values)")?;
        Ok((pose, symmetric_from_upper::<6>(&upper)))
    }

    fn format_vertex(&self) -> String {
        let (t, q) = isometry_to_xyz_quat(self);
        join(&[t[0], t[1], t[2], q[0], q[1], q[2], q[3]])
    }

    fn format_edge(&self, information: &Matrix6<f64>) -> String {
        format!("{} {}", self.format_vertex(), join(&upper_of::<6>(information)))
    }
}

impl G2oPose for Isometry2<f64> {
    const VERTEX_TAG: &'static str = "VERTEX_SE2";
    const EDGE_TAG: &'static str = "EDGE_SE2";
    const OTHER_TAGS: [&'static str; 2] = ["VERTEX_SE3:QUAT", "EDGE_SE3:QUAT"];

    fn parse_vertex(tokens: &mut Tokens<'_>) -> Result<Self, IoError> {
        let [x, y, theta] = tokens.next_f64s::<3>("x y theta")?;
        Ok(Isometry2::new(Vector2::new(x, y), theta))
    }

    fn parse_edge(tokens: &mut Tokens<'_>) -> Result<(Self, Matrix3<f64>), IoError> {
        let pose = Self::parse_vertex(tokens)?;
        let upper = tokens.next_f64s::<6>("information matrix entry (6 upper-triangular values)")?;
        Ok((pose, symmetric_from_upper::<3>(&upper)))
    }

    fn format_vertex(&self) -> String {
        let t = &self.translation.vector;
        join(&[t.x, t.y, self.rotation.angle()])
    }

    fn format_edge(&self, information: &Matrix3<f64>) -> String {
        format!("{} {}", self.format_vertex(), join(&upper_of::<3>(information)))
    }
}

/// Reads a 3D g2o graph (`VERTEX_SE3:QUAT`, `EDGE_SE3:QUAT`, `FIX`).
pub fn read_g2o_3d(
    path: impl AsRef<Path>,
    options: &G2oReadOptions,
) -> Result<(PoseGraph<Isometry3<f64>>, G2oReport), IoError> {
    let path = path.as_ref();
    read_graph(path, &read_text(path)?, options)
}

/// Reads a 2D g2o graph (`VERTEX_SE2`, `EDGE_SE2`, `FIX`).
pub fn read_g2o_2d(
    path: impl AsRef<Path>,
    options: &G2oReadOptions,
) -> Result<(PoseGraph<Isometry2<f64>>, G2oReport), IoError> {
    let path = path.as_ref();
    read_graph(path, &read_text(path)?, options)
}

/// Reads a g2o graph of either dimension, decided by the first pose tag in the file.
pub fn read_g2o(
    path: impl AsRef<Path>,
    options: &G2oReadOptions,
) -> Result<(AnyPoseGraph, G2oReport), IoError> {
    let path = path.as_ref();
    let text = read_text(path)?;
    let two_d = text
        .lines()
        .find_map(|line| match line.split_whitespace().next() {
            Some("VERTEX_SE2" | "EDGE_SE2") => Some(true),
            Some("VERTEX_SE3:QUAT" | "EDGE_SE3:QUAT") => Some(false),
            _ => None,
        });
    if two_d == Some(true) {
        let (graph, report) = read_graph(path, &text, options)?;
        Ok((AnyPoseGraph::TwoD(graph), report))
    } else {
        let (graph, report) = read_graph(path, &text, options)?;
        Ok((AnyPoseGraph::ThreeD(graph), report))
    }
}

/// Parses `text` (the content of `path`) as a graph of pose type `P`.
pub(crate) fn read_graph<P: G2oPose>(
    path: &Path,
    text: &str,
    options: &G2oReadOptions,
) -> Result<(PoseGraph<P>, G2oReport), IoError> {
    let mut graph = PoseGraph::<P>::default();
    let mut report = G2oReport::default();
    let mut vertex_line: HashMap<u64, usize> = HashMap::new();
    let mut edge_lines = Vec::new();
    for (line, content) in numbered_lines(text) {
        let content = content.trim();
        if content.is_empty() || content.starts_with('#') {
            continue;
        }
        let mut tokens = Tokens::new(path, line, content);
        let parsed = parse_line(&mut tokens, &mut graph, &mut report, &mut vertex_line);
        match parsed {
            Ok(is_edge) => {
                if is_edge {
                    edge_lines.push(line);
                }
            }
            Err(_) if options.skip_malformed => report.malformed_lines.push(line),
            Err(error) => return Err(error),
        }
    }
    match options.missing_vertices {
        MissingVertices::Error => {
            for (edge, line) in graph.edges.iter().zip(&edge_lines) {
                for id in [edge.from, edge.to] {
                    if !graph.vertices.contains_key(&id) {
                        return Err(IoError::at_line(
                            path,
                            *line,
                            format!(
                                "edge {} -> {} names vertex {id}, which has no {} line",
                                edge.from,
                                edge.to,
                                P::VERTEX_TAG
                            ),
                        ));
                    }
                }
            }
        }
        MissingVertices::Guess => {
            let result = guess_missing(&mut graph, report.vertex_lines == 0);
            report.guessed = result.guessed;
            report.unresolved = result.unresolved;
        }
    }
    Ok((graph, report))
}

/// Parses one non-blank line into the graph; returns whether it was an edge.
fn parse_line<P: G2oPose>(
    tokens: &mut Tokens<'_>,
    graph: &mut PoseGraph<P>,
    report: &mut G2oReport,
    vertex_line: &mut HashMap<u64, usize>,
) -> Result<bool, IoError> {
    let tag = tokens.next_str("tag")?;
    if tag == P::VERTEX_TAG {
        let id = tokens.next_u64("vertex id")?;
        let pose = P::parse_vertex(tokens)?;
        if let Some(first) = vertex_line.get(&id) {
            return Err(tokens.error(format!("vertex {id} is listed twice (first at line {first})")));
        }
        tokens.finish()?;
        vertex_line.insert(id, tokens.line());
        graph.vertices.insert(id, pose);
        report.vertex_lines += 1;
        Ok(false)
    } else if tag == P::EDGE_TAG {
        let from = tokens.next_u64("edge source id")?;
        let to = tokens.next_u64("edge target id")?;
        let (from_from_to, information) = P::parse_edge(tokens)?;
        tokens.finish()?;
        graph.edges.push(Edge {
            from,
            to,
            from_from_to,
            information,
        });
        Ok(true)
    } else if tag == "FIX" {
        let mut ids = Vec::new();
        while let Ok(token) = tokens.next_str("") {
            let id = token
                .parse::<u64>()
                .map_err(|_| tokens.error(format!("FIX: bad vertex id \"{token}\"")))?;
            ids.push(id);
        }
        graph.fixed.extend(ids);
        Ok(false)
    } else if P::OTHER_TAGS.contains(&tag) {
        Err(tokens.error(format!(
            "{tag} does not belong in a graph of {} / {} (2D and 3D poses are mixed)",
            P::VERTEX_TAG,
            P::EDGE_TAG
        )))
    } else if TOLERATED_TAGS.contains(&tag) {
        *report.skipped.entry(tag.to_owned()).or_insert(0) += 1;
        Ok(false)
    } else {
        let hint = if ["VERTEX2", "EDGE2", "VERTEX3", "EDGE3", "EQUIV"].contains(&tag) {
            " (a TORO tag: this is a TORO graph; name the file .graph or .toro, or read it with skid_io::toro)"
        } else {
            ""
        };
        Err(tokens.error(format!("unknown g2o tag \"{tag}\"{hint}")))
    }
}
