//! Several sessions written as one: what `skid session merge` writes once it has placed each session in
//! the first one's map frame, and what a run that extends its prior (`[prior] mode = "extend"`) leaves.
//!
//! The first part's robots keep their ids; each later part's robots take the next free ids, in order.
//! Each robot keeps its keyframes, descriptors and pose graph as they were, in its own map frame (only
//! the vertex ids of its graph are renumbered); what changes is where its map frame sits in the joined
//! session's, given per robot by the caller. A robot the caller could not place is kept, unplaced, so
//! nothing of a session is lost. Cloud files of a session on disk are copied as they are.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use skid_core::{Point, Pose};
use skid_io::g2o::PoseGraph;
use skid_io::ply::{PlyFormat, write_ply};

use crate::write::{write_manifest, write_robot};
use crate::{DescriptorSpec, Session, SessionError, SessionKeyframe, SessionRobot};

/// Where a part's keyframe clouds come from.
pub enum PartClouds<'a> {
    /// The session's folder on disk: each cloud file is copied as it is.
    Folder(&'a Path),
    /// Clouds in memory, by robot id and keyframe index (a keyframe without one is written empty), each
    /// handed over as a copy for the time its file is written.
    Memory(&'a dyn Fn(u32, u32) -> Option<Vec<Point>>),
}

/// One session of a join.
pub struct JoinPart<'a> {
    pub session: &'a Session,
    /// Where each of the session's robots (in the order of `session.robots`) has its map frame in the
    /// joined session's map frame; `None` keeps a robot unplaced. Missing entries count as `None`.
    pub placements: Vec<Option<Pose>>,
    pub clouds: PartClouds<'a>,
    /// Vertices of other robots that the session's pose graphs name, and the joined vertex each stands
    /// for (a run's prior keyframes stand for the prior session's keyframes). Vertices not listed keep
    /// their ids.
    pub foreign_vertices: BTreeMap<u64, u64>,
}

impl<'a> JoinPart<'a> {
    /// A session saved in `dir`, joined as it is: each robot where the session placed it.
    pub fn as_saved(session: &'a Session, dir: &'a Path) -> Self {
        Self {
            session,
            placements: session.robots.iter().map(|robot| robot.map_from_robot).collect(),
            clouds: PartClouds::Folder(dir),
            foreign_vertices: BTreeMap::new(),
        }
    }
}

/// The joined session, and for each part which joined id each of its robots took.
pub struct Joined {
    pub session: Session,
    pub ids: Vec<BTreeMap<u32, u32>>,
}

/// The joined ids of every part's robots: the first part's keep theirs, later parts' take the next
/// free ids in order.
fn assign_ids(parts: &[JoinPart<'_>]) -> Vec<BTreeMap<u32, u32>> {
    let mut ids: Vec<BTreeMap<u32, u32>> = Vec::with_capacity(parts.len());
    let mut next = 0;
    for (position, part) in parts.iter().enumerate() {
        let mut map = BTreeMap::new();
        for robot in &part.session.robots {
            let id = if position == 0 { robot.robot } else { next };
            next = next.max(id + 1);
            map.insert(robot.robot, id);
        }
        ids.push(map);
    }
    ids
}

/// The graph with every vertex renamed: a listed foreign vertex as `foreign` says, any other with its
/// robot renamed by `rename` (vertex id = robot · 10⁶ + keyframe index).
fn renumbered(
    graph: &PoseGraph<Pose>,
    foreign: &BTreeMap<u64, u64>,
    rename: impl Fn(u32) -> u32,
) -> PoseGraph<Pose> {
    let vertex = |id: u64| {
        if let Some(&joined) = foreign.get(&id) {
            return joined;
        }
        let robot = u32::try_from(id / 1_000_000).map_or(id / 1_000_000, |robot| u64::from(rename(robot)));
        robot * 1_000_000 + id % 1_000_000
    };
    let mut renamed = graph.clone();
    renamed.vertices = graph
        .vertices
        .iter()
        .map(|(&id, &pose)| (vertex(id), pose))
        .collect();
    for edge in &mut renamed.edges {
        edge.from = vertex(edge.from);
        edge.to = vertex(edge.to);
    }
    for id in &mut renamed.fixed {
        *id = vertex(*id);
    }
    renamed
}

/// The descriptor every part shares; parts that disagree cannot be joined (their keyframes could not
/// be compared with one another again).
fn shared_descriptor(dir: &Path, parts: &[JoinPart<'_>]) -> Result<Option<DescriptorSpec>, SessionError> {
    let mut shared: Option<&DescriptorSpec> = None;
    for part in parts {
        let Some(spec) = &part.session.descriptor else {
            continue;
        };
        match shared {
            None => shared = Some(spec),
            Some(first) if first == spec => {}
            Some(first) => {
                return Err(SessionError::invalid(
                    dir,
                    format!(
                        "session `{}` was described with `{}` ({} values, parameters {}), the joined one with `{}` ({} values, parameters {}): they cannot be joined",
                        part.session.name,
                        spec.kind,
                        spec.length,
                        spec.params,
                        first.kind,
                        first.length,
                        first.params
                    ),
                ));
            }
        }
    }
    Ok(shared.cloned())
}

fn same_folder(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    }
}

/// Writes `parts` as one session named `name` into `dir` (created if needed; it must not be one of the
/// parts' folders). The configuration is the first part's.
pub fn write_joined(dir: &Path, name: &str, parts: &[JoinPart<'_>]) -> Result<Joined, SessionError> {
    for part in parts {
        if let PartClouds::Folder(folder) = part.clouds
            && same_folder(folder, dir)
        {
            return Err(SessionError::invalid(
                dir,
                "the joined session would overwrite one of the sessions it joins; write it elsewhere",
            ));
        }
    }
    let descriptor = shared_descriptor(dir, parts)?;
    let length = descriptor.as_ref().map_or(0, |spec| spec.length);
    std::fs::create_dir_all(dir).map_err(|e| SessionError::io(dir, e))?;
    let ids = assign_ids(parts);
    let mut robots = Vec::new();
    for (part, own_ids) in parts.iter().zip(&ids) {
        let rename = |robot: u32| own_ids.get(&robot).copied().unwrap_or(robot);
        for (position, robot) in part.session.robots.iter().enumerate() {
            let joined = SessionRobot {
                robot: rename(robot.robot),
                map_from_robot: part.placements.get(position).copied().flatten(),
                keyframes: robot.keyframes.clone(),
                graph: renumbered(&robot.graph, &part.foreign_vertices, rename),
            };
            let folder = dir.join(crate::robot_folder(joined.robot));
            let mut write_cloud = |keyframe: &SessionKeyframe, path: &Path| match &part.clouds {
                PartClouds::Folder(source) => {
                    let from: PathBuf = source
                        .join(crate::robot_folder(robot.robot))
                        .join(crate::cloud_file(keyframe.index));
                    std::fs::copy(&from, path).map_err(|e| SessionError::io(&from, e))?;
                    Ok(keyframe.point_count)
                }
                PartClouds::Memory(cloud_of) => {
                    let points = cloud_of(robot.robot, keyframe.index).unwrap_or_default();
                    write_ply(path, &points, PlyFormat::BinaryLittleEndian)?;
                    Ok(points.len())
                }
            };
            write_robot(&folder, &joined, length, &mut write_cloud)?;
            robots.push(joined);
        }
    }
    robots.sort_by_key(|robot| robot.robot);
    let session = Session {
        name: name.to_string(),
        skid_version: env!("CARGO_PKG_VERSION").to_string(),
        descriptor,
        config_toml: parts
            .first()
            .map_or_else(String::new, |part| part.session.config_toml.clone()),
        robots,
    };
    write_manifest(dir, &session)?;
    Ok(Joined { session, ids })
}
