//! Evaluates an estimated trajectory file against ground truth and prints the report as JSON, until
//! `skid eval` is wired into the CLI: `cargo run -p skid-eval --example eval_files -- GT EST [OPTIONS_JSON]`,
//! where OPTIONS_JSON is an [`skid_eval::EvalOptions`] in JSON, e.g. `{"alignment":"sim3"}`.

use std::path::PathBuf;

use skid_eval::{EvalOptions, evaluate_files};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (Some(gt), Some(est)) = (args.first(), args.get(1)) else {
        return Err("usage: eval_files GT EST [OPTIONS_JSON]".into());
    };
    let options: EvalOptions = match args.get(2) {
        Some(json) => serde_json::from_str(json)?,
        None => EvalOptions::default(),
    };
    let report = evaluate_files(&PathBuf::from(gt), &PathBuf::from(est), &options)?;
    println!("{}", serde_json::to_string_pretty(&report)?);
    Ok(())
}
