//! TORO pose graphs and the closely related iSAM text format, read into the same [`PoseGraph`] types
//! as g2o (reading only).
//!
//! ## TORO (`.graph`, `.toro`)
//!
//! * `VERTEX2 id x y theta`, `EDGE2 from to dx dy dtheta Ixx Ixy Iyy Itt Ixt Iyt` (TORO's own order of
//!   the information entries).
//! * `VERTEX3 id x y z roll pitch yaw`, `EDGE3 from to dx dy dz roll pitch yaw` optionally followed by
//!   the 21 upper-triangular information entries in the order `x y z roll pitch yaw` (identity when
//!   absent). The rotation is `Rz(yaw) * Ry(pitch) * Rx(roll)`.
//! * `EQUIV i j`: vertices `i` and `j` are the same place; returned in [`ToroFile::equivalences`].
//!
//! ## iSAM (`isam/data/*.txt`)
//!
//! `EDGE2`/`ODOMETRY`/`LANDMARK`... with the same numbers as TORO's `EDGE2`/`EDGE3`, but the trailing
//! entries are the **upper-triangular square root** `R` of the information matrix (row by row; in
//! 2D order `x y theta`, in 3D `x y z roll pitch yaw`), so the information is `R^T R`. Choose with
//! [`InformationConvention`].
//!
//! ## Conversion to the g2o conventions
//!
//! Measurements become `from_from_to` isometries exactly. 3D information matrices are converted from
//! the roll-pitch-yaw parameterisation to g2o's (rotation = vector part of the error quaternion) with
//! the small-angle Jacobian: the rotation rows and columns are multiplied by 2 (`dq = dtheta / 2`), and
//! roll/pitch/yaw increments are taken as rotations about x/y/z (exact at zero angle).
//! Missing vertices are guessed as for g2o (see [`crate::g2o`]), and `LANDMARK` lines are skipped and
//! counted.

use std::path::Path;

use nalgebra::{Isometry2, Isometry3, Matrix3, Matrix6, Rotation3, Translation3, UnitQuaternion, Vector2};

use crate::error::IoError;
use crate::g2o::guess::guess_missing;
use crate::g2o::{AnyPoseGraph, Edge, G2oReadOptions, G2oReport, GraphPose, MissingVertices, PoseGraph};
use crate::text::{Tokens, numbered_lines, read_text};

/// How the trailing numbers of an edge line encode its information matrix.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum InformationConvention {
    /// TORO: the information itself (2D order `Ixx Ixy Iyy Itt Ixt Iyt`, 3D upper triangle).
    #[default]
    Toro,
    /// iSAM: the upper-triangular square root `R` (row by row), information = `R^T R`.
    IsamSquareRoot,
}

/// A TORO or iSAM file as read.
#[derive(Clone, Debug, PartialEq)]
pub struct ToroFile {
    /// The graph, 2D or 3D by the tags used.
    pub graph: AnyPoseGraph,
    /// Line counts, guessed and unresolved vertices, as for g2o.
    pub report: G2oReport,
    /// `EQUIV i j` pairs, in file order.
    pub equivalences: Vec<(u64, u64)>,
}

/// Reads a TORO or iSAM pose graph.
pub fn read_toro(
    path: impl AsRef<Path>,
    convention: InformationConvention,
    options: &G2oReadOptions,
) -> Result<ToroFile, IoError> {
    let path = path.as_ref();
    let text = read_text(path)?;
    let three_d = text
        .lines()
        .find_map(|line| match line.split_whitespace().next() {
            Some("VERTEX2" | "EDGE2" | "ODOMETRY") => Some(false),
            Some("VERTEX3" | "EDGE3") => Some(true),
            _ => None,
        });
    let mut report = G2oReport::default();
    let mut equivalences = Vec::new();
    let graph = if three_d == Some(true) {
        let graph: PoseGraph<Isometry3<f64>> = parse(
            path,
            &text,
            convention,
            options,
            &mut report,
            &mut equivalences,
            three_d_line,
        )?;
        AnyPoseGraph::ThreeD(graph)
    } else {
        AnyPoseGraph::TwoD(parse(
            path,
            &text,
            convention,
            options,
            &mut report,
            &mut equivalences,
            two_d_line,
        )?)
    };
    Ok(ToroFile {
        graph,
        report,
        equivalences,
    })
}

/// What one line contributes.
enum Element<P: GraphPose> {
    Vertex(u64, P),
    Edge(Edge<P>),
    Equiv(u64, u64),
    Skipped(String),
}

/// Information matrix `R^T R` of an upper-triangular square root given row by row.
fn from_square_root<const N: usize>(upper: &[f64]) -> nalgebra::SMatrix<f64, N, N> {
    let mut r = nalgebra::SMatrix::<f64, N, N>::zeros();
    let mut k = 0;
    for row in 0..N {
        for col in row..N {
            r[(row, col)] = upper[k];
            k += 1;
        }
    }
    r.transpose() * r
}

/// Parses one 2D line (tag already known not to be blank or a comment).
fn two_d_line(
    tokens: &mut Tokens<'_>,
    tag: &str,
    convention: InformationConvention,
) -> Result<Option<Element<Isometry2<f64>>>, IoError> {
    let pose = |v: [f64; 3]| Isometry2::new(Vector2::new(v[0], v[1]), v[2]);
    Ok(Some(match tag {
        "VERTEX2" => Element::Vertex(
            tokens.next_u64("vertex id")?,
            pose(tokens.next_f64s::<3>("x y theta")?),
        ),
        "EDGE2" | "ODOMETRY" => {
            let from = tokens.next_u64("edge source id")?;
            let to = tokens.next_u64("edge target id")?;
            let measurement = pose(tokens.next_f64s::<3>("dx dy dtheta")?);
            let v = tokens.next_f64s::<6>("information entry (6 values)")?;
            let information = match convention {
                InformationConvention::Toro => {
                    Matrix3::new(v[0], v[1], v[4], v[1], v[2], v[5], v[4], v[5], v[3])
                }
                InformationConvention::IsamSquareRoot => from_square_root::<3>(&v),
            };
            Element::Edge(Edge {
                from,
                to,
                from_from_to: measurement,
                information,
            })
        }
        "EQUIV" => Element::Equiv(tokens.next_u64("first id")?, tokens.next_u64("second id")?),
        "LANDMARK" => return Ok(Some(Element::Skipped(tag.to_owned()))),
        _ => return Ok(None),
    }))
}

/// The isometry of `x y z roll pitch yaw`.
fn pose_rpy(v: [f64; 6]) -> Isometry3<f64> {
    let rotation = Rotation3::from_euler_angles(v[3], v[4], v[5]);
    Isometry3::from_parts(
        Translation3::new(v[0], v[1], v[2]),
        UnitQuaternion::from_rotation_matrix(&rotation),
    )
}

/// Parses one 3D line.
fn three_d_line(
    tokens: &mut Tokens<'_>,
    tag: &str,
    convention: InformationConvention,
) -> Result<Option<Element<Isometry3<f64>>>, IoError> {
    Ok(Some(match tag {
        "VERTEX3" => {
            let id = tokens.next_u64("vertex id")?;
            Element::Vertex(id, pose_rpy(tokens.next_f64s::<6>("x y z roll pitch yaw")?))
        }
        "EDGE3" => {
            let from = tokens.next_u64("edge source id")?;
            let to = tokens.next_u64("edge target id")?;
            let measurement = pose_rpy(tokens.next_f64s::<6>("dx dy dz roll pitch yaw")?);
            let mut upper = Vec::with_capacity(21);
            while let Ok(token) = tokens.next_str("") {
                let value: f64 = token
                    .parse()
                    .map_err(|_| tokens.error(format!("bad information entry \"{token}\"")))?;
                upper.push(value);
            }
            let rpy_information = match (upper.len(), convention) {
                (0, _) => Matrix6::identity(),
                (21, InformationConvention::Toro) => crate::g2o::symmetric_from_upper::<6>(&upper),
                (21, InformationConvention::IsamSquareRoot) => from_square_root::<6>(&upper),
                (n, _) => {
                    return Err(tokens.error(format!("EDGE3 needs 0 or 21 information entries, found {n}")));
                }
            };
            // Rotation increments in g2o's quaternion-vector units are half the angles.
            let scale = Matrix6::from_diagonal(&nalgebra::Vector6::new(1.0, 1.0, 1.0, 2.0, 2.0, 2.0));
            let information = scale * rpy_information * scale;
            Element::Edge(Edge {
                from,
                to,
                from_from_to: measurement,
                information,
            })
        }
        "EQUIV" => Element::Equiv(tokens.next_u64("first id")?, tokens.next_u64("second id")?),
        "LANDMARK" => return Ok(Some(Element::Skipped(tag.to_owned()))),
        _ => return Ok(None),
    }))
}

/// Parses the fields after the tag of one line; `None` for a tag of neither this dimension nor common.
type LineParser<P> = fn(&mut Tokens<'_>, &str, InformationConvention) -> Result<Option<Element<P>>, IoError>;

/// The line loop shared by both dimensions.
fn parse<P: GraphPose>(
    path: &Path,
    text: &str,
    convention: InformationConvention,
    options: &G2oReadOptions,
    report: &mut G2oReport,
    equivalences: &mut Vec<(u64, u64)>,
    line_parser: LineParser<P>,
) -> Result<PoseGraph<P>, IoError> {
    let mut graph = PoseGraph::<P>::default();
    let mut edge_lines = Vec::new();
    for (line, content) in numbered_lines(text) {
        let content = content.trim();
        if content.is_empty() || content.starts_with('#') {
            continue;
        }
        let mut tokens = Tokens::new(path, line, content);
        let parsed = tokens.next_str("tag").and_then(|tag| {
            let element = line_parser(&mut tokens, tag, convention)?
                .ok_or_else(|| tokens.error(format!("unknown or wrong-dimension TORO/iSAM tag \"{tag}\"")))?;
            if !matches!(element, Element::Skipped(_)) {
                tokens.finish()?;
            }
            Ok(element)
        });
        match parsed {
            Ok(Element::Vertex(id, pose)) => {
                if graph.vertices.insert(id, pose).is_some() && !options.skip_malformed {
                    return Err(IoError::at_line(
                        path,
                        line,
                        format!("vertex {id} is listed twice"),
                    ));
                }
                report.vertex_lines += 1;
            }
            Ok(Element::Edge(edge)) => {
                graph.edges.push(edge);
                edge_lines.push(line);
            }
            Ok(Element::Equiv(a, b)) => equivalences.push((a, b)),
            Ok(Element::Skipped(tag)) => *report.skipped.entry(tag).or_insert(0) += 1,
            Err(_) if options.skip_malformed => report.malformed_lines.push(line),
            Err(error) => return Err(error),
        }
    }
    match options.missing_vertices {
        MissingVertices::Error => {
            for (edge, line) in graph.edges.iter().zip(&edge_lines) {
                if let Some(id) = [edge.from, edge.to]
                    .into_iter()
                    .find(|id| !graph.vertices.contains_key(id))
                {
                    return Err(IoError::at_line(
                        path,
                        *line,
                        format!("edge names vertex {id}, which has no vertex line"),
                    ));
                }
            }
        }
        MissingVertices::Guess => {
            let result = guess_missing(&mut graph, report.vertex_lines == 0);
            report.guessed = result.guessed;
            report.unresolved = result.unresolved;
        }
    }
    Ok(graph)
}
