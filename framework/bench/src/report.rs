//! The report a benchmark profile writes: `results.json` (every row, with the machine it ran on and the
//! wall time of the whole profile) and `results.md` (the same rows as a Markdown table, plus any notes
//! and plots the profile appends), both in the output folder.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Parser;
use serde::Serialize;
use serde_json::{Map, Value};

/// The Markdown file every profile writes next to `results.json`.
pub const RESULTS_MD: &str = "results.md";

/// Options every benchmark binary takes.
#[derive(Parser, Debug)]
pub struct BenchArgs {
    /// Output folder (created if missing).
    #[arg(long, default_value = "target/bench/out")]
    pub out: PathBuf,
    /// The profile's parameter file (profiles with one default to `configs/bench/<profile>.toml`).
    #[arg(long)]
    pub config: Option<PathBuf>,
}

/// Rows of results for one profile.
#[derive(Debug, Serialize)]
pub struct Report {
    pub profile: String,
    pub machine: Map<String, Value>,
    /// Seconds from [`Report::new`] to [`Report::write`].
    pub wall_s: f64,
    pub rows: Vec<Map<String, Value>>,
    #[serde(skip)]
    started: Instant,
}

/// The CPU model named in `/proc/cpuinfo` (Linux), if any.
pub fn cpu_model() -> Option<String> {
    let text = std::fs::read_to_string("/proc/cpuinfo").ok()?;
    text.lines()
        .find(|line| line.starts_with("model name"))
        .and_then(|line| line.split_once(':'))
        .map(|(_, model)| model.trim().to_owned())
}

impl Report {
    pub fn new(profile: &str) -> Self {
        let mut machine = Map::new();
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        machine.insert("cores".into(), Value::from(cores));
        if let Some(model) = cpu_model() {
            machine.insert("cpu".into(), Value::from(model));
        }
        machine.insert("os".into(), Value::from(std::env::consts::OS));
        machine.insert("arch".into(), Value::from(std::env::consts::ARCH));
        Self {
            profile: profile.to_owned(),
            machine,
            wall_s: 0.0,
            rows: Vec::new(),
            started: Instant::now(),
        }
    }

    /// Adds a row from any serialisable struct (its fields become the columns).
    pub fn push(&mut self, row: &impl Serialize) -> Result<()> {
        match serde_json::to_value(row)? {
            Value::Object(map) => self.rows.push(map),
            other => anyhow::bail!("a report row must be an object, got {other}"),
        }
        Ok(())
    }

    /// The rows as a Markdown table, columns in the first row's order.
    pub fn markdown(&self) -> String {
        let Some(first) = self.rows.first() else {
            return format!("# {}\n\n(no rows)\n", self.profile);
        };
        let columns: Vec<&String> = first.keys().collect();
        let mut text = format!(
            "# {}\n\n| {} |\n|{}\n",
            self.profile,
            columns.iter().map(|c| c.as_str()).collect::<Vec<_>>().join(" | "),
            "---|".repeat(columns.len())
        );
        for row in &self.rows {
            let cells: Vec<String> = columns
                .iter()
                .map(|c| row.get(c.as_str()).map(format_cell).unwrap_or_default())
                .collect();
            text.push_str(&format!("| {} |\n", cells.join(" | ")));
        }
        text
    }

    /// Writes `results.json` and `results.md` into `out` and prints the table.
    pub fn write(&mut self, out: &Path) -> Result<()> {
        self.write_with(out, &self.markdown())
    }

    /// Like [`Report::write`], with `markdown` (a table shaped like the paper's, notes, plots) as
    /// `results.md` instead of the plain table of rows.
    pub fn write_with(&mut self, out: &Path, markdown: &str) -> Result<()> {
        self.wall_s = self.started.elapsed().as_secs_f64();
        std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
        let json_path = out.join("results.json");
        std::fs::write(&json_path, serde_json::to_string_pretty(self)?)
            .with_context(|| format!("writing {}", json_path.display()))?;
        let md_path = out.join(RESULTS_MD);
        std::fs::write(&md_path, markdown).with_context(|| format!("writing {}", md_path.display()))?;
        println!("{markdown}");
        println!(
            "wrote {} and {} ({:.1} s)",
            json_path.display(),
            md_path.display(),
            self.wall_s
        );
        Ok(())
    }
}

/// Appends `text` to the `results.md` in `out` (notes and plots after the table).
pub fn append_markdown(out: &Path, text: &str) -> Result<()> {
    let path = out.join(RESULTS_MD);
    let mut table = std::fs::read_to_string(&path).unwrap_or_default();
    table.push_str(text);
    std::fs::write(&path, table).with_context(|| format!("writing {}", path.display()))
}

/// A number as the tables print it (three decimals for floats).
pub fn format_cell(value: &Value) -> String {
    match value {
        Value::Number(n) => match n.as_f64() {
            Some(f) if n.is_f64() => format!("{f:.3}"),
            _ => n.to_string(),
        },
        Value::String(s) => s.clone(),
        Value::Null => "–".to_owned(),
        other => other.to_string(),
    }
}

/// A Markdown table from a header and rows of cells (shorter rows are padded with empty cells).
pub fn markdown_table(header: &[String], rows: &[Vec<String>]) -> String {
    let mut text = format!("| {} |\n|{}\n", header.join(" | "), "---|".repeat(header.len()));
    for row in rows {
        let mut cells = row.clone();
        cells.resize(header.len(), String::new());
        text.push_str(&format!("| {} |\n", cells.join(" | ")));
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tables_pad_short_rows_and_format_numbers() {
        let table = markdown_table(
            &["a".to_owned(), "b".to_owned()],
            &[vec!["1".to_owned()], vec!["2".to_owned(), "3".to_owned()]],
        );
        assert_eq!(table, "| a | b |\n|---|---|\n| 1 |  |\n| 2 | 3 |\n");
        assert_eq!(format_cell(&Value::from(0.5)), "0.500");
        assert_eq!(format_cell(&Value::from(7)), "7");
        assert_eq!(format_cell(&Value::Null), "–");
    }
}
