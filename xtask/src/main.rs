//! `cargo xtask`: the project's own automation.
//!
//! - `ci`: format check, clippy with warnings denied, and the test suite with `skid`'s `rerun` feature on
//!   (what `.ci/run` calls), with `SKID_PYTHON` pointing at a venv of the pinned Python packages the tests
//!   use as independent writers and readers;
//! - `tidy`: the house rules (module docs, file length, no `unwrap` in library code, no import loops);
//! - `c-header [--check]`: the plugins' C header, generated from skid-abi with cbindgen (CI checks it);
//! - `bench <profile>`: runs a benchmark profile in release mode, writing `target/bench/<profile>/`
//!   (with `--config configs/bench/<profile>.toml` when that file exists);
//! - `bench-compare A B`: per-row numeric differences of two result folders' `results.json`;
//! - `bench-readme`: regenerates README.md's "Results" section from `target/bench/*/results.md`.

use std::process::{Command, ExitCode};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(name = "cargo xtask")]
struct Cli {
    #[command(subcommand)]
    command: Task,
}

#[derive(Subcommand)]
enum Task {
    /// Format check, clippy (warnings denied), tidy and the tests.
    Ci,
    /// Check the house rules on every Rust file.
    Tidy,
    /// Run a benchmark profile in release mode (`cargo xtask bench list` shows them).
    Bench {
        profile: String,
        /// Extra arguments passed to the benchmark.
        #[arg(trailing_var_arg = true)]
        args: Vec<String>,
    },
    /// Print the per-row numeric differences of two result folders (paths, or profile names under
    /// `target/bench/`).
    BenchCompare { a: String, b: String },
    /// Regenerate the "Results" section of README.md from `target/bench/*/results.md`.
    BenchReadme,
    /// Generate the C header for out-of-tree plugins (`framework/abi/include/skid_plugin.h`).
    CHeader {
        /// Only check that the checked-in header is current.
        #[arg(long)]
        check: bool,
    },
}

fn main() -> ExitCode {
    let result = match Cli::parse().command {
        Task::Ci => ci(),
        Task::Tidy => tidy(),
        Task::Bench { profile, args } => bench(&profile, &args),
        Task::BenchCompare { a, b } => {
            xtask::results::compare(&xtask::workspace_root(), &a, &b).map(|text| print!("{text}"))
        }
        Task::CHeader { check } => xtask::header::run(&xtask::workspace_root(), check),
        Task::BenchReadme => {
            let names: Vec<&str> = xtask::bench::PROFILES.iter().map(|p| p.name).collect();
            xtask::results::readme(&xtask::workspace_root(), &names).map(|text| println!("{text}"))
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("xtask: {error:#}");
            ExitCode::FAILURE
        }
    }
}

fn cargo() -> Command {
    let mut command = Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".to_owned()));
    command.current_dir(xtask::workspace_root());
    command
}

/// Runs `command` to the end and says how long it took, so a CI log shows where its time goes.
fn run(mut command: Command) -> Result<()> {
    eprintln!("xtask: running {command:?}");
    let started = Instant::now();
    let status = command
        .status()
        .with_context(|| format!("starting {command:?}"))?;
    let seconds = started.elapsed().as_secs_f64();
    if !status.success() {
        bail!("{command:?} failed with {status} after {seconds:.0} s");
    }
    eprintln!("xtask: finished in {seconds:.0} s: {command:?}");
    Ok(())
}

fn ci() -> Result<()> {
    let started = Instant::now();
    let mut fmt = cargo();
    fmt.args(["fmt", "--all", "--", "--check"]);
    run(fmt)?;
    tidy()?;
    xtask::header::run(&xtask::workspace_root(), true)?;
    // Library and binary code: every warning denied, `unwrap` included.
    let mut clippy = cargo();
    clippy.args([
        "clippy",
        "--workspace",
        "--features",
        "skid/rerun",
        "--lib",
        "--bins",
        "--examples",
        "--",
        "-D",
        "warnings",
    ]);
    run(clippy)?;
    // Tests: the same, except that tests (and their helper functions) may unwrap and expect.
    let mut clippy_tests = cargo();
    clippy_tests.args([
        "clippy",
        "--workspace",
        "--features",
        "skid/rerun",
        "--tests",
        "--benches",
        "--",
        "-D",
        "warnings",
    ]);
    clippy_tests.args(["-A", "clippy::unwrap_used", "-A", "clippy::expect_used"]);
    run(clippy_tests)?;
    // The bag tests write their fixtures with independent Python libraries (rosbags, mcap).
    let python = xtask::python::ensure_python(&xtask::workspace_root())?;
    // With `skid`'s `rerun` feature (the Rerun SDK, off by default): one build whose features serve every
    // test, so the crates the SDK shares with the rest are not built twice.
    let mut test = cargo();
    test.args(["test", "--workspace", "--features", "skid/rerun"]);
    test.env(xtask::python::PYTHON_VAR, &python);
    run(test)?;
    eprintln!("xtask: ci passed in {:.0} s", started.elapsed().as_secs_f64());
    Ok(())
}

fn tidy() -> Result<()> {
    let root = xtask::workspace_root();
    let mut violations: Vec<String> = xtask::tidy::check(&root)?
        .iter()
        .map(ToString::to_string)
        .collect();
    for crate_dir in xtask::imports::CHECKED_CRATES {
        let graph = xtask::imports::import_graph(&root.join(crate_dir))?;
        for members in xtask::imports::loops(&graph) {
            violations.push(format!(
                "{crate_dir}: these modules import each other in a loop: {}",
                members.join(", ")
            ));
        }
    }
    if violations.is_empty() {
        eprintln!("xtask: tidy ok");
        return Ok(());
    }
    for violation in &violations {
        eprintln!("{violation}");
    }
    bail!("{} tidy violations", violations.len())
}

fn bench(profile: &str, args: &[String]) -> Result<()> {
    let profiles = xtask::bench::PROFILES;
    if profile == "list" {
        for entry in profiles {
            println!("{:<26} {}", entry.name, entry.summary);
        }
        return Ok(());
    }
    let Some(entry) = profiles.iter().find(|entry| entry.name == profile) else {
        let names: Vec<_> = profiles.iter().map(|entry| entry.name).collect();
        bail!(
            "unknown bench profile `{profile}`; profiles: {}",
            names.join(", ")
        );
    };
    let out = xtask::workspace_root().join("target/bench").join(profile);
    let mut command = cargo();
    command.args([
        "run",
        "--release",
        "--package",
        entry.package,
        "--bin",
        entry.binary,
        "--",
    ]);
    command.arg("--out").arg(&out);
    // Benchmarks measure the Python peers (rosbags, kiss-icp, ...) in the same run.
    command.env(
        xtask::python::PYTHON_VAR,
        xtask::python::ensure_bench_python(&xtask::workspace_root())?,
    );
    let parameters = xtask::workspace_root()
        .join("configs/bench")
        .join(format!("{profile}.toml"));
    if parameters.is_file() && !args.iter().any(|arg| arg == "--config") {
        command.arg("--config").arg(parameters);
    }
    command.args(args);
    // `run` says how long the build and the profile took together.
    run(command)
}
