//! The report a benchmark profile writes: `results.json` (every row, with the machine it ran on) and
//! `table.md` (the same rows as a Markdown table), both in the output folder.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Parser;
use serde::Serialize;
use serde_json::{Map, Value};

/// Options every benchmark binary takes.
#[derive(Parser, Debug)]
pub struct BenchArgs {
    /// Output folder (created if missing).
    #[arg(long, default_value = "target/bench/out")]
    pub out: PathBuf,
}

/// Rows of results for one profile.
#[derive(Debug, Serialize)]
pub struct Report {
    pub profile: String,
    pub machine: Map<String, Value>,
    pub rows: Vec<Map<String, Value>>,
}

impl Report {
    pub fn new(profile: &str) -> Self {
        let mut machine = Map::new();
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        machine.insert("cores".into(), Value::from(cores));
        machine.insert("os".into(), Value::from(std::env::consts::OS));
        machine.insert("arch".into(), Value::from(std::env::consts::ARCH));
        Self {
            profile: profile.to_owned(),
            machine,
            rows: Vec::new(),
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

    /// Writes `results.json` and `table.md` into `out` and prints the table.
    pub fn write(&self, out: &std::path::Path) -> Result<()> {
        std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
        let json_path = out.join("results.json");
        std::fs::write(&json_path, serde_json::to_string_pretty(self)?)
            .with_context(|| format!("writing {}", json_path.display()))?;
        let table = self.markdown();
        let md_path = out.join("table.md");
        std::fs::write(&md_path, &table).with_context(|| format!("writing {}", md_path.display()))?;
        println!("{table}");
        println!("wrote {} and {}", json_path.display(), md_path.display());
        Ok(())
    }
}

fn format_cell(value: &Value) -> String {
    match value {
        Value::Number(n) => match n.as_f64() {
            Some(f) if n.is_f64() => format!("{f:.3}"),
            _ => n.to_string(),
        },
        Value::String(s) => s.clone(),
        other => other.to_string(),
    }
}
