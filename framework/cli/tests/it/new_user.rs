//! What a new user hits (issue "safe outputs, honest exit codes, checked config, readable errors and
//! logs"), each with the input that exposed it: out-of-range values refused by `config check` with the
//! file and key said once, profiles that work outside a checkout, failures that exit non-zero
//! (a fine registration that does not converge, a run whose every scan was skipped), `skid odometry`
//! skipping an empty scan as `run` does, the ARE flagged on a straight path, errors that name
//! `SKID_DATA_DIR` and never print a file's control bytes, a PCD whose header under-counts its points,
//! an empty `SKID_PLUGIN_LIBS` entry, help that offers only accepted values, `-v` that adds detail,
//! plain logs when redirected, rate-limited warnings, and the human summary tables.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn data(relative: &str) -> PathBuf {
    skid_io::data_path(relative).expect("the shared data folder (SKID_DATA_DIR)")
}

fn skid_in(cwd: &Path, args: &[&str], envs: &[(&str, &str)]) -> Output {
    let mut command = Command::new(env!("CARGO_BIN_EXE_skid"));
    command
        .current_dir(cwd)
        .args(args)
        .env_remove("RUST_LOG")
        .env_remove("SKID_CONFIG_DIR")
        .env_remove("SKID_PLUGIN_LIBS");
    for (key, value) in envs {
        command.env(key, value);
    }
    command.output().expect("skid runs")
}

fn skid(args: &[&str]) -> Output {
    skid_in(&repo(), args, &[])
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

fn fails_with(output: &Output, words: &[&str]) -> String {
    let stderr = text(&output.stderr);
    assert!(!output.status.success(), "should fail:\n{stderr}");
    for word in words {
        assert!(stderr.contains(word), "`{word}` missing from:\n{stderr}");
    }
    stderr
}

/// A binary PCD of x, y, z floats whose header announces `announced` points.
fn write_pcd(path: &Path, points: &[[f32; 3]], announced: usize) {
    let mut bytes = format!(
        "VERSION .7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH {announced}\nHEIGHT 1\n\
         VIEWPOINT 0 0 0 1 0 0 0\nPOINTS {announced}\nDATA binary\n"
    )
    .into_bytes();
    for point in points {
        for value in point {
            bytes.extend_from_slice(&value.to_le_bytes());
        }
    }
    std::fs::write(path, bytes).unwrap();
}

#[test]
fn config_check_refuses_an_out_of_range_value_naming_file_and_key_once() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("mine.toml");
    std::fs::write(&file, "[odometry.kiss_icp]\nvoxel_size_m = -1.0\n").unwrap();
    let output = skid(&["config", "check", file.to_str().unwrap()]);
    let stderr = fails_with(
        &output,
        &["mine.toml", "odometry.kiss_icp.voxel_size_m", "positive"],
    );
    assert_eq!(
        stderr.matches("positive").count(),
        1,
        "said more than once:\n{stderr}"
    );
    for (set, key) in [
        ("source.sim.world=mars", "source.sim.world"),
        (
            "verifier.pcm.fitness.min_overlap=2",
            "verifier.pcm.fitness.min_overlap",
        ),
        (
            "descriptor.scan_context.num_sectors=0",
            "descriptor.scan_context.num_sectors",
        ),
    ] {
        let output = skid(&["config", "show", "--set", set]);
        fails_with(&output, &[&format!("--set {set}"), key]);
    }
}

#[test]
fn config_check_refuses_files_that_do_not_exist_naming_file_and_key() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("no-such-sequence");
    let file = dir.path().join("robot.toml");
    std::fs::write(
        &file,
        format!(
            "[source]\nplugin = \"kitti\"\n[source.kitti]\npath = \"{}\"\n",
            missing.display()
        ),
    )
    .unwrap();
    let output = skid(&["config", "check", file.to_str().unwrap()]);
    fails_with(
        &output,
        &[
            "robot.toml",
            "source.kitti.path",
            "no-such-sequence",
            "does not exist",
        ],
    );
    // Zenoh's mutual TLS without its files, and with a certificate file that is not there.
    let zenoh = dir.path().join("zenoh.toml");
    std::fs::write(&zenoh, "[transport]\nplugin = \"zenoh\"\n").unwrap();
    let output = skid(&["config", "check", zenoh.to_str().unwrap()]);
    fails_with(&output, &["zenoh.toml", "tls.ca_certificate", "not set"]);
    let ca = dir.path().join("ca.pem");
    std::fs::write(&ca, "not checked here").unwrap();
    std::fs::write(
        &zenoh,
        format!(
            "[transport]\nplugin = \"zenoh\"\n[transport.zenoh.tls]\nca_certificate = \"{}\"\n\
             certificate = \"{}\"\nprivate_key = \"{}\"\n",
            ca.display(),
            dir.path().join("robot-0.pem").display(),
            ca.display()
        ),
    )
    .unwrap();
    let output = skid(&["config", "check", zenoh.to_str().unwrap()]);
    fails_with(
        &output,
        &["zenoh.toml", "tls.certificate", "robot-0.pem", "no such file"],
    );
    // A configuration whose files exist passes, and says what is left to the run.
    let output = skid(&["config", "check", "configs/profiles/kitti.toml"]);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        stdout.contains("ok") && stdout.contains("when it opens"),
        "{stdout}"
    );
}

#[test]
fn profiles_work_outside_a_checkout() {
    let elsewhere = tempfile::tempdir().unwrap();
    let output = skid_in(
        elsewhere.path(),
        &["config", "show", "--profile", "scan_context"],
        &[],
    );
    assert!(output.status.success(), "{}", text(&output.stderr));
    assert!(text(&output.stdout).contains("scan_context"));
    let output = skid_in(elsewhere.path(), &["config", "show", "--profile", "nope"], &[]);
    fails_with(&output, &["nope", "kitti", "scan_context"]);
}

#[test]
fn a_fine_registration_that_does_not_converge_exits_non_zero_with_the_reason() {
    let pair = data("lidar_scan_pair_fast_gicp");
    let (target, source) = (pair.join("251370668.pcd"), pair.join("251371071.pcd"));
    let output = skid(&[
        "register",
        target.to_str().unwrap(),
        source.to_str().unwrap(),
        "--fine",
        "gicp",
        "--set",
        "fine.gicp.max_iterations=1",
        "--set",
        "fine.gicp.coarse_correspondence_m=0",
    ]);
    fails_with(&output, &["did not converge"]);
    // Scripts still get the JSON line with the last estimate.
    let line: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    assert_eq!(line["converged"], false);
}

#[test]
fn a_missing_bag_is_named_with_what_is_wrong() {
    let output = skid(&["bag", "info", "/nonexistent/missing.bag"]);
    let stderr = fails_with(&output, &["/nonexistent/missing.bag", "no such file or folder"]);
    assert!(!stderr.contains("entity not found"), "{stderr}");
}

#[test]
fn an_unknown_plugin_flag_is_named_as_the_flag_with_the_known_names() {
    let pair = data("lidar_scan_pair_fast_gicp");
    let (target, source) = (pair.join("251370668.pcd"), pair.join("251371071.pcd"));
    let output = skid(&[
        "register",
        target.to_str().unwrap(),
        source.to_str().unwrap(),
        "--fine",
        "nope",
    ]);
    let stderr = fails_with(&output, &["--fine nope", "gicp", "icp"]);
    assert!(!stderr.contains("--set"), "{stderr}");
    let output = skid(&[
        "register",
        target.to_str().unwrap(),
        source.to_str().unwrap(),
        "--coarse",
        "nope",
    ]);
    fails_with(&output, &["--coarse nope", "kiss_matcher", "ransac"]);
}

#[test]
fn a_run_whose_every_scan_is_skipped_fails_and_warns_at_a_limited_rate() {
    let dir = tempfile::tempdir().unwrap();
    let clouds = dir.path().join("clouds");
    std::fs::create_dir(&clouds).unwrap();
    // Five points a scan: fewer than any odometry can register.
    let points: Vec<[f32; 3]> = (0..5).map(|i| [1.0 + i as f32, 2.0, 0.5]).collect();
    for index in 0..40 {
        write_pcd(&clouds.join(format!("{index:03}.pcd")), &points, points.len());
    }
    let output = skid_in(
        &repo(),
        &[
            "run",
            "--set",
            "run.robots=1",
            "--set",
            &format!("run.output_dir={}", dir.path().join("runs").display()),
            "--set",
            "source.plugin=cloud_dir",
            "--set",
            &format!("source.cloud_dir.path={:?}", clouds.display().to_string()),
        ],
        &[],
    );
    let stderr = fails_with(&output, &["registered no scan", "skipped every one"]);
    let warnings = stderr.lines().filter(|l| l.contains("scan skipped")).count();
    // The first three and the 10th: not one line per scan.
    assert_eq!(warnings, 4, "{stderr}");
    assert!(
        !stderr.contains('\u{1b}'),
        "colour codes in a redirected log:\n{stderr}"
    );
    // Redirected, the log says what stage the run is in, and the summary table still comes out.
    assert!(stderr.contains("plugins built; running"), "{stderr}");
    assert!(stderr.contains("writing outputs"), "{stderr}");
    assert!(stderr.contains("loops acc/rej/undecided"), "{stderr}");
}

#[test]
fn odometry_skips_an_empty_scan_as_run_does_and_prints_a_table() {
    let dir = tempfile::tempdir().unwrap();
    let velodyne = dir.path().join("velodyne");
    std::fs::create_dir(&velodyne).unwrap();
    let shared = data("kitti_00_lidar_frames_0000_0015/velodyne");
    for index in 0..4 {
        let name = format!("{index:06}.bin");
        if index == 2 {
            std::fs::write(velodyne.join(&name), []).unwrap();
        } else {
            std::fs::copy(shared.join(&name), velodyne.join(&name)).unwrap();
        }
    }
    let out = dir.path().join("out");
    let output = skid(&[
        "-v",
        "odometry",
        dir.path().to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    let stderr = text(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    let line: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    assert_eq!(line["frames"], 3, "{line}");
    assert_eq!(line["scans_skipped"], 1, "{line}");
    assert!(stderr.contains("scan skipped"), "{stderr}");
    // `-v` adds the per-scan detail; the table closes the output.
    assert!(stderr.contains("DEBUG"), "{stderr}");
    assert!(stderr.contains("ms/frame median"), "{stderr}");
    assert!(!stderr.contains('\u{1b}'), "{stderr}");
}

#[test]
fn eval_flags_an_ill_conditioned_alignment_on_a_straight_path() {
    // KITTI 00's first 16 frames drive nearly straight: the rotation about the path is unobservable.
    let truth = data("kitti_00_lidar_frames_0000_0015/poses_velodyne.txt");
    let dir = tempfile::tempdir().unwrap();
    // The estimate: the truth rolled 30° about the direction of travel, which positions cannot see.
    let rolled: String = std::fs::read_to_string(&truth)
        .unwrap()
        .lines()
        .map(|line| {
            let v: Vec<f64> = line.split_whitespace().map(|t| t.parse().unwrap()).collect();
            let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
            // Post-multiply the rotation by a roll about the sensor's x axis.
            let row = |r: usize| {
                let (a, b, d) = (v[4 * r], v[4 * r + 1], v[4 * r + 2]);
                format!("{a} {} {} {}", b * c + d * s, -b * s + d * c, v[4 * r + 3])
            };
            format!("{} {} {}\n", row(0), row(1), row(2))
        })
        .collect();
    let estimate = dir.path().join("rolled.kitti");
    std::fs::write(&estimate, rolled).unwrap();
    let output = skid(&[
        "eval",
        "--gt",
        truth.to_str().unwrap(),
        "--est",
        estimate.to_str().unwrap(),
    ]);
    let stderr = text(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    let report: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    assert_eq!(
        report["alignment_conditioning"]["ill_conditioned"], true,
        "{report}"
    );
    assert!(stderr.contains("not observable"), "{stderr}");
    assert!(stderr.contains("RPE rotation"), "{stderr}");
}

#[test]
fn a_missing_data_path_names_skid_data_dir() {
    let output = skid(&[
        "run",
        "--set",
        "source.plugin=kitti",
        "--set",
        "source.kitti.path=no_such_sequence",
    ]);
    fails_with(&output, &["no_such_sequence", "SKID_DATA_DIR"]);
}

#[test]
fn file_errors_never_print_control_bytes_and_under_counted_headers_warn() {
    let dir = tempfile::tempdir().unwrap();
    let hostile = dir.path().join("hostile.pcd");
    std::fs::write(&hostile, b"VERSION .7\nFIELDS x\x1b[2J\x07 y z\nSIZE 4 4 4\n").unwrap();
    let output = skid(&["register", hostile.to_str().unwrap(), hostile.to_str().unwrap()]);
    let stderr = fails_with(&output, &["hostile.pcd"]);
    assert!(
        !stderr.contains('\u{1b}') && !stderr.contains('\u{7}'),
        "{stderr:?}"
    );

    let short = dir.path().join("short.pcd");
    let points: Vec<[f32; 3]> = (0..400)
        .map(|i| {
            let a = i as f32 * 0.05;
            [10.0 * a.cos(), 10.0 * a.sin(), (i % 7) as f32 * 0.3]
        })
        .collect();
    write_pcd(&short, &points, 100);
    let output = skid(&["describe", "--descriptor", "solid", short.to_str().unwrap()]);
    let stderr = text(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    assert!(stderr.contains("under-counts"), "{stderr}");
}

#[test]
fn an_empty_plugin_library_entry_is_ignored() {
    let output = skid_in(
        &repo(),
        &["plugins", "--slot", "fine"],
        &[("SKID_PLUGIN_LIBS", ":")],
    );
    assert!(output.status.success(), "{}", text(&output.stderr));
}

#[test]
fn help_offers_only_accepted_values_and_explains_every_argument() {
    let output = skid(&["pgo", "--help"]);
    let help = text(&output.stdout);
    assert!(!help.contains("odometry"), "{help}");
    assert!(help.contains("chordal") && help.contains("gnc"), "{help}");
    let refused = skid(&["pgo", "x.g2o", "--init", "odometry"]);
    fails_with(&refused, &["odometry", "chordal"]);
    for command in [
        &["pgo", "--help"][..],
        &["eval", "--help"],
        &["register", "--help"],
        &["sim", "export", "--help"],
        &["sim", "preview", "--help"],
    ] {
        let help = text(&skid(command).stdout);
        // clap prints an argument without help text as its bare name: every one should say something.
        for line in help
            .lines()
            .filter(|l| l.starts_with("  ") && !l.trim().is_empty())
        {
            let trimmed = line.trim();
            let has_text = trimmed.split("  ").filter(|part| !part.trim().is_empty()).count() > 1;
            let continuation = line.starts_with("          ");
            assert!(
                has_text || continuation,
                "{command:?}: no help for `{trimmed}`\n{help}"
            );
        }
    }
}

#[test]
fn plugins_say_what_each_parameter_means() {
    let output = skid(&["plugins", "--slot", "odometry"]);
    let listing = text(&output.stdout);
    assert!(output.status.success());
    // The doc comment of `translation_noise_m`, of a nested key, and an enumeration's values.
    assert!(
        listing.contains("noise added to each inter-scan translation"),
        "{listing}"
    );
    assert!(
        listing.contains("Distance travelled since the last keyframe"),
        "{listing}"
    );
    let listing = text(&skid(&["plugins", "--slot", "backend"]).stdout);
    assert!(
        listing.contains("one of:") && listing.contains("gnc"),
        "{listing}"
    );
}

#[test]
fn pgo_logs_and_prints_a_table_and_a_missing_file_fails() {
    let graph = data("pose_graph_benchmarks/se_sync/intel.g2o");
    let output = skid(&["pgo", graph.to_str().unwrap(), "--init", "chordal"]);
    let stderr = text(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    assert!(
        stderr.contains("optimising") && stderr.contains("optimised"),
        "{stderr}"
    );
    assert!(stderr.contains("cost start → final"), "{stderr}");
    let report: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    assert_eq!(report["converged"], true, "{report}");
    let missing = skid(&["pgo", "no_such_graph.g2o"]);
    let stderr = fails_with(&missing, &["no_such_graph.g2o"]);
    // The operating system's reason appears once, not once per layer of the error.
    assert_eq!(stderr.matches("No such file").count(), 1, "{stderr}");
}
