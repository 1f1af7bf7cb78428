//! `cargo xtask`: the project's own automation.
//!
//! - `ci`: format check, the house rules, then one build of every test target with clippy linting the
//!   workspace's crates as they compile (warnings denied), and the test suite, with `skid`'s `rerun`
//!   feature on (what `.ci/run` calls), with `SKID_PYTHON` pointing at a venv of the pinned Python
//!   packages the tests use as independent writers and readers; it ends with each phase's time;
//! - `tidy`: the house rules (module docs, file length, no `unwrap` in library code, no import loops, no
//!   documentation example in a crate that skips its doc tests);
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
    /// Format check, tidy, one build of the tests with clippy (warnings denied), and the tests.
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
fn run(mut command: Command) -> Result<f64> {
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
    Ok(seconds)
}

/// The phases of `cargo xtask ci` and how long each took, printed at the end (also when one fails).
#[derive(Default)]
struct Phases {
    done: Vec<(&'static str, f64)>,
}

impl Phases {
    fn time<T>(&mut self, name: &'static str, phase: impl FnOnce() -> Result<T>) -> Result<T> {
        let started = Instant::now();
        let result = phase();
        self.done.push((name, started.elapsed().as_secs_f64()));
        result
    }

    fn print(&self, outcome: &str) {
        eprintln!("xtask: ci {outcome}; phase times:");
        for (name, seconds) in &self.done {
            eprintln!("xtask:   {seconds:>7.0} s  {name}");
        }
        let total: f64 = self.done.iter().map(|(_, seconds)| seconds).sum();
        eprintln!("xtask:   {total:>7.0} s  in all");
    }
}

fn ci() -> Result<()> {
    let mut phases = Phases::default();
    let result = ci_phases(&mut phases);
    phases.print(if result.is_ok() { "passed" } else { "failed" });
    result
}

/// The tests, with clippy: one build serves both. clippy-driver compiles the workspace's own crates in
/// place of rustc (`RUSTC_WORKSPACE_WRAPPER`, as `cargo clippy` does for `cargo check`), so every library,
/// binary, example and test target is linted while it is built for the tests, with warnings denied
/// (`unwrap` and `expect` are allowed in tests by `clippy.toml` and each test binary's root); the
/// dependencies are built once, by rustc, instead of once more for a separate clippy pass.
fn test_build(python: &std::path::Path) -> Result<Command> {
    let mut command = cargo();
    command.args(["test", "--workspace", "--features", "skid/rerun,skid/zenoh"]);
    command.env(xtask::python::PYTHON_VAR, python);
    command.env("RUSTC_WORKSPACE_WRAPPER", clippy_driver()?);
    command.env("CLIPPY_ARGS", "-D__CLIPPY_HACKERY__warnings__CLIPPY_HACKERY__");
    Ok(command)
}

/// clippy-driver from the toolchain cargo uses (`rustup component add clippy` installs it there).
fn clippy_driver() -> Result<std::path::PathBuf> {
    let rustc = std::env::var("RUSTC").unwrap_or_else(|_| "rustc".to_owned());
    let output = Command::new(&rustc)
        .args(["--print", "sysroot"])
        .output()
        .with_context(|| format!("running {rustc} --print sysroot"))?;
    let sysroot = String::from_utf8_lossy(&output.stdout).trim().to_owned();
    let driver = std::path::Path::new(&sysroot)
        .join("bin")
        .join(format!("clippy-driver{}", std::env::consts::EXE_SUFFIX));
    if !driver.is_file() {
        bail!(
            "{} not found: install clippy with `rustup component add clippy`",
            driver.display()
        );
    }
    Ok(driver)
}

fn ci_phases(phases: &mut Phases) -> Result<()> {
    phases.time("format check", || {
        let mut fmt = cargo();
        fmt.args(["fmt", "--all", "--", "--check"]);
        run(fmt)
    })?;
    phases.time("tidy and the C header", || {
        tidy()?;
        xtask::header::run(&xtask::workspace_root(), true)
    })?;
    // The bag tests write their fixtures with independent Python libraries (rosbags, mcap).
    let python = phases.time("Python venv", || {
        xtask::python::ensure_python(&xtask::workspace_root())
    })?;
    // With `skid`'s `rerun` and `zenoh` features (both off by default): one build whose features serve every
    // test, so the crates the SDK shares with the rest are not built twice.
    phases.time("build: tests and clippy", || {
        let mut build = test_build(&python)?;
        build.arg("--no-run");
        run(build)
    })?;
    // Every test binary runs, so one failure does not hide the others.
    phases.time("test run", || {
        let mut test = test_build(&python)?;
        test.arg("--no-fail-fast");
        run(test)
    })?;
    Ok(())
}

fn tidy() -> Result<()> {
    let root = xtask::workspace_root();
    let mut violations: Vec<String> = xtask::tidy::check(&root)?
        .iter()
        .chain(&xtask::doctests::check(&root)?)
        .map(ToString::to_string)
        .collect();
    for crate_dir in xtask::imports::workspace_crates(&root)? {
        let name = crate_dir
            .strip_prefix(&root)
            .unwrap_or(&crate_dir)
            .display()
            .to_string();
        for found in xtask::imports::crate_loops(&crate_dir)? {
            violations.push(format!(
                "{name}/{found}: these modules import each other in a loop"
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
    run(command).map(drop)
}
