//! The merge itself: each later session localised in the session built so far, placed or reported,
//! and the placed ones written as one session with its map and report.

use std::path::{Path, PathBuf};
use std::time::Instant;

use skid_config::ConfigSources;
use skid_core::{Registry, RobotId};
use skid_runtime::FrontEndFeed;
use skid_session::{
    JoinPart, PartClouds, RobotStanding, Session, SessionPlacement, place_session, read_session, write_joined,
};

use crate::feed::SessionFeed;
use crate::report::{MergeReport, RobotOutcome, SessionOutcome};
use crate::{MergeError, MergeRequest};

fn read(path: &Path) -> Result<(PathBuf, Session), MergeError> {
    let dir = skid_session::session_folder(path);
    let session = read_session(&dir).map_err(|source| MergeError::Session {
        path: dir.clone(),
        source,
    })?;
    Ok((dir, session))
}

fn io_error(path: &Path) -> impl FnOnce(std::io::Error) -> MergeError + '_ {
    move |source| MergeError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// What localising one session's robots in `prior_dir` found, per robot, with the seconds it took.
struct Localised {
    standings: Vec<RobotStanding>,
    through: Vec<Option<u32>>,
    seconds: f64,
}

/// Runs `session`'s robots, fed from `dir`, as a fleet localising in the prior `prior_dir`, with the
/// session's own configuration under `sets` and the settings a merge needs.
fn localise(
    dir: &Path,
    session: &Session,
    prior_dir: &Path,
    work: &Path,
    step: usize,
    sets: &[String],
    registry: &Registry,
) -> Result<Localised, MergeError> {
    let started = Instant::now();
    let overlay = work.join(format!("config-{step}.toml"));
    std::fs::write(&overlay, &session.config_toml).map_err(io_error(&overlay))?;
    let mut all_sets = sets.to_vec();
    all_sets.extend([
        format!("prior.path={:?}", prior_dir.display().to_string()),
        "prior.mode=\"localise\"".to_owned(),
        "prior.own_loops=false".to_owned(),
        "prior.hints=[]".to_owned(),
        format!("run.robots={}", session.robots.len()),
        format!("run.name=\"localise-{step}\""),
        format!("run.output_dir={:?}", work.display().to_string()),
        "run.max_scans=0".to_owned(),
        "output.record=false".to_owned(),
        "output.session=false".to_owned(),
        "output.ros2=false".to_owned(),
        "deploy.mode=\"lockstep\"".to_owned(),
        "transport.plugin=\"loopback\"".to_owned(),
    ]);
    let sources = ConfigSources {
        config_dir: None,
        profile: None,
        overlays: vec![overlay],
        sets: all_sets,
        use_env: false,
    };
    let config = sources.load(registry).map_err(|source| MergeError::Config {
        path: dir.to_path_buf(),
        source,
    })?;
    let feeds: Vec<Box<dyn FrontEndFeed>> = session
        .robots
        .iter()
        .enumerate()
        .map(|(position, robot)| {
            Box::new(SessionFeed::new(
                dir.to_path_buf(),
                robot.clone(),
                RobotId(position as u32),
            )) as Box<dyn FrontEndFeed>
        })
        .collect();
    let localise_error = |source| MergeError::Localise {
        path: dir.to_path_buf(),
        source,
    };
    let mut fleet = skid_runtime::Fleet::build_fed(config, registry, feeds).map_err(localise_error)?;
    fleet.run_lockstep(|_| {}).map_err(localise_error)?;
    let mut standings = Vec::new();
    let mut through = Vec::new();
    for (robot, host) in session.robots.iter().zip(&fleet.robots) {
        let placed = host.localisation();
        standings.push(RobotStanding {
            session_from_robot: robot.map_from_robot,
            base_from_robot: placed.map(|p| p.prior_from_map),
            loops: placed.map_or(0, |p| p.loops),
        });
        through.push(placed.and_then(|p| p.session_robot));
    }
    skid_runtime::abandon_run(&fleet.config, "a merge's localisation, not a run");
    Ok(Localised {
        standings,
        through,
        seconds: started.elapsed().as_secs_f64(),
    })
}

/// Refuses an output folder that holds anything.
fn check_out(out: &Path) -> Result<(), MergeError> {
    let occupied = std::fs::read_dir(out).is_ok_and(|mut entries| entries.next().is_some());
    if occupied {
        return Err(MergeError::Invalid(format!(
            "{}: the merged session's folder exists and is not empty; choose another",
            out.display()
        )));
    }
    Ok(())
}

/// Merges `request.sessions` into one session in the first one's map frame, written to `request.out`.
pub fn merge_sessions(request: &MergeRequest, registry: &Registry) -> Result<MergeReport, MergeError> {
    let started = Instant::now();
    if request.sessions.len() < 2 {
        return Err(MergeError::Invalid(
            "a merge needs at least two sessions: the base and one to place in it".into(),
        ));
    }
    check_out(&request.out)?;
    let work = request.out.with_extension("merging");
    std::fs::create_dir_all(&work).map_err(io_error(&work))?;
    let result = merge_in(request, registry, &work, started);
    let _ = std::fs::remove_dir_all(&work);
    result
}

fn merge_in(
    request: &MergeRequest,
    registry: &Registry,
    work: &Path,
    started: Instant,
) -> Result<MergeReport, MergeError> {
    let (base_dir, base) = read(&request.sessions[0])?;
    let world_from_base = base.world_from_map();
    let (mut current_dir, mut current) = (base_dir.clone(), base);
    let mut outcomes = Vec::new();
    for (step, path) in request.sessions.iter().enumerate().skip(1) {
        let (dir, session) = read(path)?;
        tracing::info!(session = %dir.display(), "localising in the sessions before it");
        let localised = localise(&dir, &session, &current_dir, work, step, &request.sets, registry)?;
        let placement = place_session(&localised.standings);
        let mut outcome = SessionOutcome {
            path: dir.display().to_string(),
            name: session.name.clone(),
            placed: false,
            reason: None,
            merged_from_session: None,
            error_m: None,
            error_deg: None,
            keyframes: session.robots.iter().map(|r| r.keyframes.len()).sum(),
            robots: session
                .robots
                .iter()
                .zip(&localised.standings)
                .zip(&localised.through)
                .map(|((robot, standing), through)| RobotOutcome {
                    robot: robot.robot,
                    merged_robot: None,
                    localised: standing.base_from_robot.is_some(),
                    loops: standing.loops,
                    through_robot: *through,
                    placed: false,
                })
                .collect(),
            localise_s: localised.seconds,
        };
        match placement {
            SessionPlacement::NotPlaced { reason } => {
                tracing::warn!(session = %dir.display(), %reason, "not placed; left out of the merge");
                outcome.reason = Some(reason);
            }
            SessionPlacement::Placed {
                base_from_session,
                robots,
            } => {
                // The last session placed goes straight into the output; earlier steps are the priors
                // of later ones.
                let joined_dir = if step + 1 == request.sessions.len() {
                    request.out.clone()
                } else {
                    work.join(format!("step-{step}"))
                };
                let parts = [
                    JoinPart::as_saved(&current, &current_dir),
                    JoinPart {
                        session: &session,
                        placements: robots.clone(),
                        clouds: PartClouds::Folder(&dir),
                        foreign_vertices: Default::default(),
                    },
                ];
                let name = format!("{}+{}", current.name, session.name);
                let joined =
                    write_joined(&joined_dir, &name, &parts).map_err(|source| MergeError::Session {
                        path: joined_dir.clone(),
                        source,
                    })?;
                outcome.placed = true;
                outcome.merged_from_session = base_from_session
                    .as_ref()
                    .map(skid_session::PoseRecord::from_pose);
                if let Some((metres, degrees)) = world_from_base
                    .as_ref()
                    .and_then(|world| session.placement_error(world, &robots))
                {
                    outcome.error_m = Some(metres);
                    outcome.error_deg = Some(degrees);
                }
                for (robot_outcome, placement) in outcome.robots.iter_mut().zip(&robots) {
                    robot_outcome.placed = placement.is_some();
                    robot_outcome.merged_robot = joined.ids[1].get(&robot_outcome.robot).copied();
                }
                (current_dir, current) = (joined_dir, joined.session);
            }
        }
        outcomes.push(outcome);
    }
    finish(request, &current_dir, &current, outcomes, started)
}

/// Completes `request.out` with the merged session (when the last step did not write it there), its map
/// and the report.
fn finish(
    request: &MergeRequest,
    current_dir: &Path,
    current: &Session,
    sessions: Vec<SessionOutcome>,
    started: Instant,
) -> Result<MergeReport, MergeError> {
    let out = &request.out;
    let session_error = |source| MergeError::Session {
        path: out.clone(),
        source,
    };
    // Unless the last session was placed (and written there), the output is the session built so far.
    if current_dir != out.as_path() {
        write_joined(out, &current.name, &[JoinPart::as_saved(current, current_dir)])
            .map_err(session_error)?;
    }
    let map = crate::map::session_map(out, current, skid_runtime::MAP_VOXEL_M).map_err(session_error)?;
    let map_path = out.join("map.ply");
    skid_io::ply::write_ply(&map_path, &map, skid_io::ply::PlyFormat::BinaryLittleEndian)
        .map_err(|e| session_error(e.into()))?;
    let report = MergeReport {
        base: request.sessions[0].display().to_string(),
        out: out.display().to_string(),
        sessions,
        robots: current.robots.len(),
        keyframes: current.robots.iter().map(|r| r.keyframes.len()).sum(),
        map_points: map.len(),
        wall_s: started.elapsed().as_secs_f64(),
    };
    let report_path = out.join("merge.json");
    let text = serde_json::to_string_pretty(&report)
        .map_err(|e| MergeError::Invalid(format!("the report cannot be encoded: {e}")))?;
    std::fs::write(&report_path, text).map_err(io_error(&report_path))?;
    Ok(report)
}
