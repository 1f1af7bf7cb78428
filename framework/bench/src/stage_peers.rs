//! The Python peers of the stage benchmarks (`python/stage_peers.py`: small_gicp's GICP, GTSAM's
//! Levenberg-Marquardt and GNC), run under `$SKID_PYTHON`, which `cargo xtask bench` points at the
//! benchmark venv; used by the `stages` and `pgo` profiles.

use std::ffi::{OsStr, OsString};
use std::path::Path;
use std::process::Command;

use anyhow::{Context, Result, bail};
use serde::de::DeserializeOwned;

/// The peers' interpreter, or `None` (and a word on stderr) when `$SKID_PYTHON` is not set.
pub fn python() -> Option<OsString> {
    let python = std::env::var_os("SKID_PYTHON");
    if python.is_none() {
        eprintln!("SKID_PYTHON is not set (cargo xtask bench sets it): the Python peers are skipped");
    }
    python
}

/// Runs one mode of the peer script with `args` and parses the JSON it prints.
pub fn run<T: DeserializeOwned>(python: &OsStr, mode: &str, args: &[&OsStr]) -> Result<T> {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("python/stage_peers.py");
    let output = Command::new(python)
        .arg(&script)
        .arg(mode)
        .args(args)
        .output()
        .with_context(|| format!("running {}", script.display()))?;
    if !output.status.success() {
        bail!(
            "stage_peers.py {mode} failed ({}): {}",
            output.status,
            String::from_utf8_lossy(&output.stderr)
        );
    }
    let text = String::from_utf8_lossy(&output.stdout);
    serde_json::from_str(text.trim()).with_context(|| format!("stage_peers.py {mode} printed `{text}`"))
}
