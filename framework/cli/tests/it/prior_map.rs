//! A robot localises in the prior map an earlier run left (`[prior]`), with another LiDAR than the one
//! that mapped it, and a robot whose route the prior does not hold stays "not localised", as does one
//! whose start hint points elsewhere; a prior whose descriptors were made with other parameters is
//! refused, naming the key. The second run's session merges into the first one's map, and a run that
//! extends the map leaves it grown.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn skid_run(out: &Path, name: &str, sets: &[&str]) -> Output {
    let mut command = Command::new(env!("CARGO_BIN_EXE_skid"));
    command.current_dir(repo()).env_remove("RUST_LOG");
    command.args(["-q", "run"]);
    for set in [
        "run.robots=2",
        "run.max_scans=200",
        "output.record=false",
        &format!("run.output_dir={}", out.display()),
        &format!("run.name={name}"),
    ]
    .iter()
    .chain(sets)
    {
        command.args(["--set", set]);
    }
    command.output().expect("skid runs")
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

#[test]
fn a_robot_localises_in_a_prior_map_and_a_robot_outside_it_does_not() {
    let out = tempfile::tempdir().unwrap();
    // The map: 20 s of two robots that do not meet, so only robot 0's track is placed in its frame.
    let mapped = skid_run(out.path(), "mapped", &[]);
    assert!(mapped.status.success(), "{}", text(&mapped.stderr));
    let prior = format!("prior.path={}", out.path().join("mapped").display());

    // The same routes with a 32-beam LiDAR instead of the 64-beam one that made the map.
    let run = skid_run(out.path(), "localise", &[&prior, "source.sim.sensor=os1-32"]);
    assert!(run.status.success(), "{}", text(&run.stderr));
    let summary: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    let on_map = &summary["robots"][0]["localisation"];
    assert_eq!(on_map["localised"], true, "{on_map}");
    assert_eq!(on_map["through_session_robot"], 0, "{on_map}");
    let error_m = on_map["error_m"].as_f64().unwrap();
    let error_deg = on_map["error_deg"].as_f64().unwrap();
    assert!(error_m < 0.3 && error_deg < 1.0, "{on_map}");
    assert!(
        on_map["first_fix_distance_m"].as_f64().unwrap() < 20.0,
        "{on_map}"
    );
    // Robot 1 drives a sector 80 m away that the prior does not hold.
    let off_map = &summary["robots"][1]["localisation"];
    assert_eq!(off_map["localised"], false, "{off_map}");

    // The second run's session merged into the map: its robot 0 is placed in the map's frame by its
    // own loops, within 0.5 m and 1° of the truth; its robot 1, on the unmapped sector, is reported
    // and kept unplaced.
    let merged_dir = out.path().join("merged");
    let merge = Command::new(env!("CARGO_BIN_EXE_skid"))
        .current_dir(repo())
        .env_remove("RUST_LOG")
        .args(["-q", "session", "merge", "--json", "--out"])
        .arg(&merged_dir)
        .arg(out.path().join("mapped"))
        .arg(out.path().join("localise"))
        .output()
        .unwrap();
    assert!(merge.status.success(), "{}", text(&merge.stderr));
    let report: serde_json::Value = serde_json::from_slice(&merge.stdout).unwrap();
    let placed = &report["sessions"][0];
    assert_eq!(placed["placed"], true, "{report}");
    assert!(
        placed["error_m"].as_f64().unwrap() < 0.5 && placed["error_deg"].as_f64().unwrap() < 1.0,
        "{report}"
    );
    assert_eq!(placed["robots"][0]["merged_robot"], 2, "{report}");
    assert_eq!(placed["robots"][1]["placed"], false, "{report}");
    let info = Command::new(env!("CARGO_BIN_EXE_skid"))
        .args(["session", "info", "--json"])
        .arg(&merged_dir)
        .output()
        .unwrap();
    let info: serde_json::Value = serde_json::from_slice(&info.stdout).unwrap();
    let placed: Vec<bool> = info["robots"]
        .as_array()
        .unwrap()
        .iter()
        .map(|robot| robot["placed"].as_bool().unwrap())
        .collect();
    assert_eq!(placed, [true, false, true, false], "{info}");
    assert!(merged_dir.join("map.ply").exists());
    // Extending the map: robot 0 localises as before and runs full SLAM beside; the run's session is
    // the prior grown by it, its loops with the prior's robot 0 kept in its graph under that robot's id.
    let extend = skid_run(
        out.path(),
        "extend",
        &[
            &prior,
            "prior.mode=extend",
            "source.sim.sensor=os1-32",
            "run.robots=1",
        ],
    );
    assert!(extend.status.success(), "{}", text(&extend.stderr));
    let summary: serde_json::Value = serde_json::from_slice(&extend.stdout).unwrap();
    assert_eq!(
        summary["robots"][0]["localisation"]["localised"], true,
        "{summary}"
    );
    let info = Command::new(env!("CARGO_BIN_EXE_skid"))
        .args(["session", "info", "--json"])
        .arg(out.path().join("extend"))
        .output()
        .unwrap();
    let info: serde_json::Value = serde_json::from_slice(&info.stdout).unwrap();
    let robots = info["robots"].as_array().unwrap();
    let placed: Vec<bool> = robots.iter().map(|r| r["placed"].as_bool().unwrap()).collect();
    assert_eq!(placed, [true, false, true], "{info}");
    assert_eq!(robots[2]["peers_in_graph"], serde_json::json!([0]), "{info}");

    // A merge never writes over a folder that holds something.
    let again = Command::new(env!("CARGO_BIN_EXE_skid"))
        .args(["session", "merge", "--out"])
        .arg(&merged_dir)
        .arg(out.path().join("mapped"))
        .arg(out.path().join("localise"))
        .output()
        .unwrap();
    assert!(!again.status.success() && text(&again.stderr).contains("not empty"));

    // A hint that puts robot 0 300 m from where it starts keeps every candidate out of reach.
    let misled = skid_run(
        out.path(),
        "misled",
        &[
            &prior,
            "source.sim.sensor=os1-32",
            "prior.hints=[[300.0, 0.0, 0.0, 90.0]]",
        ],
    );
    assert!(misled.status.success(), "{}", text(&misled.stderr));
    let summary: serde_json::Value = serde_json::from_slice(&misled.stdout).unwrap();
    let misled = &summary["robots"][0]["localisation"];
    assert_eq!(misled["localised"], false, "{misled}");

    let mismatched = skid_run(
        out.path(),
        "mismatched",
        &[&prior, "descriptor.solid.num_range_bins=20", "run.max_scans=1"],
    );
    assert!(!mismatched.status.success());
    let error = text(&mismatched.stderr);
    assert!(
        error.contains("prior.path") && error.contains("descriptor.solid.num_range_bins"),
        "{error}"
    );
}
