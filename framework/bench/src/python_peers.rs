//! The Python peers the benchmarks run beside SKiD (`python/stage_peers.py`: small_gicp's GICP, GTSAM's
//! Levenberg-Marquardt and GNC, for the `stages` and `pgo` profiles; `python/kiss_matcher_pairs.py`: the
//! reference KISS-Matcher), under `$SKID_PYTHON`, which `cargo xtask bench` points at the benchmark venv.

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

/// Runs one mode of `python/stage_peers.py` with `args` and parses the JSON it prints.
pub fn run<T: DeserializeOwned>(python: &OsStr, mode: &str, args: &[&OsStr]) -> Result<T> {
    let mut all: Vec<&OsStr> = vec![mode.as_ref()];
    all.extend_from_slice(args);
    let stdout = script_stdout(python, "stage_peers.py", &all)?;
    let text = String::from_utf8_lossy(&stdout);
    serde_json::from_str(text.trim()).with_context(|| format!("stage_peers.py {mode} printed `{text}`"))
}

/// Runs `python/<script>` with `args` and returns what it printed; a failed run is an error holding
/// its standard error.
pub fn script_stdout(python: &OsStr, script: &str, args: &[&OsStr]) -> Result<Vec<u8>> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("python").join(script);
    let output = Command::new(python)
        .arg(&path)
        .args(args)
        .output()
        .with_context(|| format!("running {}", path.display()))?;
    if !output.status.success() {
        bail!(
            "{script} {} failed ({}): {}",
            args.iter()
                .map(|a| a.to_string_lossy())
                .collect::<Vec<_>>()
                .join(" "),
            output.status,
            String::from_utf8_lossy(&output.stderr)
        );
    }
    Ok(output.stdout)
}
