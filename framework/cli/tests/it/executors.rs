//! The three executors give the same run: `lockstep`, `threads` (each robot's front-end on its own
//! thread) and `processes` (each robot's front-end in a child process over iceoryx2 shared memory), and
//! a front-end process that dies mid-run is restarted and the run still ends exactly the same.

use std::path::{Path, PathBuf};
use std::process::Command;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Runs a short two-robot simulated run (KISS-ICP odometry, so the front-end does real work) and
/// returns its output folder.
fn run(out: &Path, name: &str, mode: &str, envs: &[(&str, &str)]) -> (PathBuf, String) {
    let mut command = Command::new(env!("CARGO_BIN_EXE_skid"));
    command.current_dir(repo()).env_remove("RUST_LOG");
    command.args(["-q", "run"]);
    for set in [
        "run.robots=2",
        "run.max_scans=30",
        "source.sim.sensor=vlp16",
        "odometry.plugin=kiss_icp",
        &format!("run.output_dir={}", out.display()),
        &format!("run.name={name}"),
        &format!("deploy.mode={mode}"),
    ] {
        command.args(["--set", set]);
    }
    for (key, value) in envs {
        command.env(key, value);
    }
    let output = command.output().expect("skid runs");
    assert!(
        output.status.success(),
        "{mode}: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    (
        out.join(name),
        String::from_utf8_lossy(&output.stderr).into_owned(),
    )
}

fn read(folder: &Path, file: &str) -> String {
    std::fs::read_to_string(folder.join(file)).unwrap_or_else(|e| panic!("{}/{file}: {e}", folder.display()))
}

fn assert_same_run(expected: &Path, actual: &Path) {
    for robot in ["robot0", "robot1"] {
        for file in ["trajectory.kitti", "pose_graph.g2o"] {
            let path = format!("{robot}/{file}");
            let expected_text = read(expected, &path);
            assert!(!expected_text.is_empty(), "{path} is empty");
            assert_eq!(
                expected_text,
                read(actual, &path),
                "{path} differs in {}",
                actual.display()
            );
        }
    }
}

#[test]
fn threads_and_processes_reproduce_lockstep_even_after_a_front_end_crash() {
    let out = tempfile::tempdir().unwrap();
    let (lockstep, _) = run(out.path(), "lockstep", "lockstep", &[]);
    let (threads, _) = run(out.path(), "threads", "threads", &[]);
    assert_same_run(&lockstep, &threads);
    let (processes, _) = run(out.path(), "processes", "processes", &[]);
    assert_same_run(&lockstep, &processes);
    assert!(
        !processes.join("stages").exists(),
        "the stage processes' configuration is removed when the run completes"
    );

    // Robot 1's front-end process aborts after its 12th output; the host restarts it and the new
    // process resumes after the outputs the host already has.
    let (crashed, log) = run(
        out.path(),
        "crashed",
        "processes",
        &[(skid_runtime::CRASH_AFTER_VAR, "1:12")],
    );
    assert!(log.contains("front-end process died"), "no restart logged: {log}");
    assert_same_run(&lockstep, &crashed);
}
