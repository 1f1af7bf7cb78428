//! Stopping a run: SIGINT or SIGTERM to `skid run --set deploy.mode=processes` stops its front-end
//! processes, exits with 128 + the signal, and leaves `<name>.incomplete/` (with its `INCOMPLETE`
//! marker and the reason, and the outputs as they were at the stop, the summary marked interrupted)
//! beside an earlier complete run of the same name, which stays intact; a run that
//! finishes replaces the earlier one whole (no stale `robot2/` from a larger fleet), keeping it aside as
//! `<name>.previous/` with a warning. `skid sim export`
//! refuses a non-empty folder unless `--overwrite`, and then replaces it whole.

#![cfg(target_os = "linux")]

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn skid_run(out: &Path, robots: u32, max_scans: u32, mode: &str) -> Command {
    let mut command = Command::new(env!("CARGO_BIN_EXE_skid"));
    command.current_dir(repo()).env_remove("RUST_LOG");
    command.args(["run"]);
    for set in [
        format!("run.robots={robots}"),
        format!("run.max_scans={max_scans}"),
        "source.sim.sensor=vlp16".into(),
        "odometry.plugin=kiss_icp".into(),
        format!("run.output_dir={}", out.display()),
        "run.name=stopped".into(),
        format!("deploy.mode={mode}"),
    ] {
        command.args(["--set", &set]);
    }
    command
}

/// The process's state letter from `/proc/PID/stat` (`None` once it is gone).
fn state(pid: u32) -> Option<char> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // The command name is in parentheses and may hold spaces: the state follows the last `)`.
    stat.rsplit_once(')')?.1.trim_start().chars().next()
}

fn alive(pid: u32) -> bool {
    state(pid).is_some_and(|s| s != 'Z' && s != 'X')
}

/// The `skid stage` processes whose parent is `parent`.
fn stage_children(parent: u32) -> Vec<u32> {
    let mut children = Vec::new();
    for entry in std::fs::read_dir("/proc").unwrap().flatten() {
        let Ok(pid) = entry.file_name().to_string_lossy().parse::<u32>() else {
            continue;
        };
        let Ok(stat) = std::fs::read_to_string(format!("/proc/{pid}/stat")) else {
            continue;
        };
        let Some((_, rest)) = stat.rsplit_once(')') else {
            continue;
        };
        let ppid: Option<u32> = rest.split_whitespace().nth(1).and_then(|p| p.parse().ok());
        let cmdline = std::fs::read(format!("/proc/{pid}/cmdline")).unwrap_or_default();
        if ppid == Some(parent) && String::from_utf8_lossy(&cmdline).contains("stage") {
            children.push(pid);
        }
    }
    children
}

fn wait_with_deadline(child: &mut Child, limit: Duration) -> std::process::ExitStatus {
    let deadline = Instant::now() + limit;
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            return status;
        }
        if Instant::now() > deadline {
            let _ = child.kill();
            panic!("skid run did not stop within {limit:?} of the signal");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

fn interrupt_with(signal: &str, number: i32) {
    let out = tempfile::tempdir().unwrap();
    // An earlier, complete run of the same name, which the interrupted one must leave alone.
    let earlier = skid_run(out.path(), 2, 3, "lockstep").output().unwrap();
    assert!(
        earlier.status.success(),
        "{}",
        String::from_utf8_lossy(&earlier.stderr)
    );
    let complete = out.path().join("stopped");
    let earlier_metrics = std::fs::read_to_string(complete.join("metrics.json")).unwrap();

    let mut host = skid_run(out.path(), 2, 100_000, "processes")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let deadline = Instant::now() + Duration::from_secs(120);
    let children = loop {
        let children = stage_children(host.id());
        if children.len() == 2 {
            break children;
        }
        assert!(
            host.try_wait().unwrap().is_none(),
            "skid run ended before its front-ends started"
        );
        assert!(Instant::now() < deadline, "the front-end processes never started");
        std::thread::sleep(Duration::from_millis(100));
    };
    // Let the front-ends get to work.
    std::thread::sleep(Duration::from_secs(2));
    let killed = Command::new("kill")
        .args([&format!("-{signal}"), &host.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    let status = wait_with_deadline(&mut host, Duration::from_secs(30));
    let mut stderr = String::new();
    std::io::Read::read_to_string(host.stderr.as_mut().unwrap(), &mut stderr).unwrap();
    assert_eq!(status.code(), Some(128 + number), "{signal}: {stderr}");
    assert!(
        stderr.contains(".incomplete"),
        "{signal}: the error does not say where the partial run is: {stderr}"
    );

    let deadline = Instant::now() + Duration::from_secs(10);
    while children.iter().any(|&pid| alive(pid)) && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(50));
    }
    let survivors: Vec<_> = children.iter().filter(|&&pid| alive(pid)).collect();
    assert!(
        survivors.is_empty(),
        "{signal}: front-end processes outlived the run: {survivors:?}"
    );

    let partial = out.path().join("stopped.incomplete");
    let marker = std::fs::read_to_string(partial.join("INCOMPLETE")).unwrap();
    assert!(marker.contains(&format!("signal {number}")), "{marker}");
    // What existed at the stop is kept: the configuration, the graphs and trajectories so far, and a
    // summary that says the run was interrupted and why.
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(partial.join("summary.json")).unwrap()).unwrap();
    let why = summary["interrupted"].as_str().unwrap_or_default();
    assert!(why.contains(&format!("signal {number}")), "{summary}");
    assert!(partial.join("config.toml").is_file());
    for robot in ["robot0", "robot1"] {
        assert!(partial.join(robot).join("pose_graph.g2o").is_file(), "{robot}");
    }
    assert!(
        !partial.join("stages").exists(),
        "the stage files were left behind"
    );
    assert_eq!(
        std::fs::read_to_string(complete.join("metrics.json")).unwrap(),
        earlier_metrics,
        "the interrupted run touched the earlier complete run"
    );
}

#[test]
fn an_interrupted_one_robot_process_keeps_what_it_has() {
    let out = tempfile::tempdir().unwrap();
    let mut robot = skid_run(out.path(), 1, 100_000, "lockstep")
        .args(["--set", "deploy.robot=0"])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Once the run has started (its folder exists), let it make keyframes (real time: a scan every 0.1 s).
    let incomplete = || {
        std::fs::read_dir(out.path())
            .unwrap()
            .map(|entry| entry.unwrap().path())
            .find(|path| path.to_string_lossy().ends_with(".incomplete"))
    };
    let deadline = Instant::now() + Duration::from_secs(120);
    while incomplete().is_none() {
        assert!(
            robot.try_wait().unwrap().is_none(),
            "the robot ended before it started"
        );
        assert!(Instant::now() < deadline, "the run folder never appeared");
        std::thread::sleep(Duration::from_millis(100));
    }
    std::thread::sleep(Duration::from_secs(4));
    let killed = Command::new("kill")
        .args(["-INT", &robot.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    let status = wait_with_deadline(&mut robot, Duration::from_secs(30));
    let mut stderr = String::new();
    std::io::Read::read_to_string(robot.stderr.as_mut().unwrap(), &mut stderr).unwrap();
    assert!(!status.success(), "{stderr}");
    let partial = incomplete().unwrap_or_else(|| panic!("no incomplete folder: {stderr}"));
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(partial.join("summary.json")).unwrap()).unwrap();
    assert!(
        summary["interrupted"]
            .as_str()
            .unwrap_or_default()
            .contains("signal 2"),
        "{summary}"
    );
    assert!(summary["robots"][0]["scans"].as_u64().unwrap() > 0, "{summary}");
    assert!(partial.join("robot0").join("pose_graph.g2o").is_file());
}

#[test]
fn sigint_stops_the_front_end_processes_and_leaves_an_incomplete_folder() {
    interrupt_with("INT", 2);
}

#[test]
fn sigterm_stops_the_front_end_processes_and_leaves_an_incomplete_folder() {
    interrupt_with("TERM", 15);
}

#[test]
fn a_rerun_replaces_the_earlier_run_whole() {
    let out = tempfile::tempdir().unwrap();
    let three = skid_run(out.path(), 3, 2, "lockstep").output().unwrap();
    assert!(
        three.status.success(),
        "{}",
        String::from_utf8_lossy(&three.stderr)
    );
    // The log says when the scans are done, before the work that follows them.
    let log = String::from_utf8_lossy(&three.stderr);
    assert!(log.contains("all 6 scans read"), "{log}");
    let folder = out.path().join("stopped");
    assert!(folder.join("robot2").is_dir());
    let two = skid_run(out.path(), 2, 2, "lockstep").output().unwrap();
    assert!(two.status.success(), "{}", String::from_utf8_lossy(&two.stderr));
    assert!(folder.join("robot1").is_dir());
    assert!(
        !folder.join("robot2").exists(),
        "the 2-robot rerun kept the old robot2/"
    );
    // The earlier run is kept aside, whole, and nothing else is left beside the run.
    let previous = out.path().join("stopped.previous");
    assert!(previous.join("robot2").is_dir() && previous.join("summary.json").is_file());
    let mut names: Vec<_> = std::fs::read_dir(out.path())
        .unwrap()
        .map(|entry| entry.unwrap().file_name().into_string().unwrap())
        .collect();
    names.sort();
    assert_eq!(
        names,
        vec!["stopped".to_string(), "stopped.previous".to_string()],
        "leftovers beside the run"
    );
    let said = String::from_utf8_lossy(&two.stderr);
    assert!(said.contains("kept as the previous run"), "{said}");
    // Two scans per robot: the robots never met, and the run says so rather than leaving a bare dash.
    assert!(said.contains("no inter-robot loop candidate"), "{said}");
    assert!(said.contains("no α/β error"), "{said}");
}

#[test]
fn a_folder_that_is_not_a_run_is_never_replaced() {
    let out = tempfile::tempdir().unwrap();
    let folder = out.path().join("stopped");
    std::fs::create_dir_all(&folder).unwrap();
    std::fs::write(folder.join("thesis.tex"), "mine").unwrap();
    let run = skid_run(out.path(), 2, 2, "lockstep").output().unwrap();
    assert!(!run.status.success());
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(stderr.contains("not a SKiD run"), "{stderr}");
    assert_eq!(
        std::fs::read_to_string(folder.join("thesis.tex")).unwrap(),
        "mine"
    );
}

fn sim_export(out: &Path, frames: u32, overwrite: bool) -> std::process::Output {
    let mut command = Command::new(env!("CARGO_BIN_EXE_skid"));
    command.args([
        "-q", "sim", "export", "--robots", "1", "--sensor", "vlp16", "--frames",
    ]);
    command.arg(frames.to_string()).arg(out);
    if overwrite {
        command.arg("--overwrite");
    }
    command.output().unwrap()
}

#[test]
fn sim_export_never_mixes_with_an_earlier_export() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("export");
    let first = sim_export(&out, 3, false);
    assert!(
        first.status.success(),
        "{}",
        String::from_utf8_lossy(&first.stderr)
    );
    let stdout = String::from_utf8_lossy(&first.stdout);
    assert!(
        stdout.contains(&out.join("robot0").display().to_string()),
        "{stdout}"
    );
    let scans = || std::fs::read_dir(out.join("robot0/velodyne")).unwrap().count();
    assert_eq!(scans(), 3);
    let refused = sim_export(&out, 2, false);
    assert!(!refused.status.success());
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert!(
        stderr.contains("--overwrite") && stderr.contains("export"),
        "{stderr}"
    );
    assert_eq!(scans(), 3, "a refused export touched the folder");
    let replaced = sim_export(&out, 2, true);
    assert!(
        replaced.status.success(),
        "{}",
        String::from_utf8_lossy(&replaced.stderr)
    );
    assert_eq!(scans(), 2, "old scans survived the overwrite");
    let times = std::fs::read_to_string(out.join("robot0/times.txt")).unwrap();
    assert_eq!(times.lines().count(), 2, "{times}");
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names, vec![std::ffi::OsString::from("export")]);
}
