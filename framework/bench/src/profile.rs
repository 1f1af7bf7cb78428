//! A profile's parameter file: `configs/bench/<profile>.toml` (or `--config FILE`), read into the
//! profile's own serde type (unknown keys refused, missing keys take the type's defaults), and written
//! back into the output folder as `config.toml` — the effective parameters the results came from.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde::Serialize;
use serde::de::DeserializeOwned;

use crate::BenchArgs;

/// The workspace's `configs/bench/` folder (where the profiles' parameter files live).
pub fn bench_config_dir() -> PathBuf {
    workspace_root().join("configs").join("bench")
}

/// The workspace root, two folders above this crate.
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .ancestors()
        .nth(2)
        .map_or_else(|| PathBuf::from("."), Path::to_path_buf)
}

/// Reads the parameters of `profile` from `--config` or `configs/bench/<profile>.toml`, falling back to
/// `T::default()` when neither exists, and writes the effective parameters to `<out>/config.toml`.
pub fn load_profile<T>(args: &BenchArgs, profile: &str) -> Result<T>
where
    T: DeserializeOwned + Serialize + Default,
{
    let path = args
        .config
        .clone()
        .unwrap_or_else(|| bench_config_dir().join(format!("{profile}.toml")));
    let parameters: T = if path.is_file() {
        let text = std::fs::read_to_string(&path).with_context(|| format!("reading {}", path.display()))?;
        toml::from_str(&text).with_context(|| format!("parsing {}", path.display()))?
    } else if args.config.is_some() {
        anyhow::bail!("{}: no such file", path.display());
    } else {
        eprintln!("{}: not found, using the built-in defaults", path.display());
        T::default()
    };
    write_effective(&args.out, &parameters, &path)?;
    Ok(parameters)
}

fn write_effective<T: Serialize>(out: &Path, parameters: &T, source: &Path) -> Result<()> {
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let text = format!(
        "# Effective parameters of this run (from {}, defaults filled in).\n{}",
        source.display(),
        toml::to_string_pretty(parameters).context("serialising the parameters")?
    );
    let path = out.join("config.toml");
    std::fs::write(&path, text).with_context(|| format!("writing {}", path.display()))
}

/// The whole `main` of a paper profile: parses `--out`/`--config`, loads the parameters, runs `body`
/// (which pushes rows into the report and returns the profile's Markdown) and writes the report.
pub fn run_profile<T, F>(profile: &str, body: F) -> Result<()>
where
    T: DeserializeOwned + Serialize + Default,
    F: FnOnce(&T, &mut crate::Report, &Path) -> Result<String>,
{
    let args = <BenchArgs as clap::Parser>::parse();
    let settings: T = load_profile(&args, profile)?;
    let mut report = crate::Report::new(profile);
    let markdown = body(&settings, &mut report, &args.out)?;
    report.write_with(&args.out, &markdown)
}
