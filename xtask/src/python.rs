//! The Python environment tests and benchmarks use as an independent party (bag fixtures written by
//! `rosbags` and `mcap`, peers' reference implementations): a venv under `target/py-venv` with the pinned
//! packages of `xtask/python-requirements.txt`, created on first use and refreshed when that file
//! changes; benchmarks use `target/py-bench-venv`, which adds the peers of
//! `xtask/python-bench-requirements.txt`. `SKID_PYTHON` set by the caller wins.

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{Context, Result, bail};

/// The environment variable that names the interpreter the tests run.
pub const PYTHON_VAR: &str = "SKID_PYTHON";

/// The interpreter to hand the tests: `$SKID_PYTHON`, else the project's venv (created if needed).
pub fn ensure_python(root: &Path) -> Result<PathBuf> {
    ensure_venv(root, "target/py-venv", &["xtask/python-requirements.txt"])
}

/// The interpreter for benchmarks: `$SKID_PYTHON`, else a venv with the tests' packages and the peers
/// the benchmarks measure beside SKiD (`xtask/python-bench-requirements.txt`: kiss-icp, …), kept apart
/// so `cargo xtask ci` does not install them.
pub fn ensure_bench_python(root: &Path) -> Result<PathBuf> {
    ensure_venv(
        root,
        "target/py-bench-venv",
        &[
            "xtask/python-requirements.txt",
            "xtask/python-bench-requirements.txt",
        ],
    )
}

fn ensure_venv(root: &Path, folder: &str, requirement_files: &[&str]) -> Result<PathBuf> {
    if let Some(python) = std::env::var_os(PYTHON_VAR).filter(|p| !p.is_empty()) {
        return Ok(PathBuf::from(python));
    }
    let venv = root.join(folder);
    let python = venv.join("bin/python");
    let mut requirements = String::new();
    for file in requirement_files {
        let path = root.join(file);
        requirements.push_str(
            &std::fs::read_to_string(&path).with_context(|| format!("reading {}", path.display()))?,
        );
    }
    let stamp = venv.join("installed-requirements.txt");
    if python.is_file() && std::fs::read_to_string(&stamp).is_ok_and(|installed| installed == requirements) {
        return Ok(python);
    }
    eprintln!(
        "xtask: creating the Python venv {} (pip install -r {})",
        venv.display(),
        requirement_files.join(" -r ")
    );
    let system = std::env::var("PYTHON3").unwrap_or_else(|_| "python3".to_owned());
    run(
        Command::new(&system).args(["-m", "venv"]).arg(&venv),
        "creating the venv (is python3 installed?)",
    )?;
    let mut install = Command::new(&python);
    install.args(["-m", "pip", "install", "--quiet", "--disable-pip-version-check"]);
    for file in requirement_files {
        install.arg("-r").arg(root.join(file));
    }
    run(&mut install, "installing the pinned Python packages")?;
    std::fs::write(&stamp, requirements).with_context(|| format!("writing {}", stamp.display()))?;
    Ok(python)
}

fn run(command: &mut Command, what: &str) -> Result<()> {
    let status = command
        .status()
        .with_context(|| format!("{what}: starting {command:?}"))?;
    if !status.success() {
        bail!("{what}: {command:?} failed with {status}");
    }
    Ok(())
}
