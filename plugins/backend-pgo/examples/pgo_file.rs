//! Optimises one g2o file and prints the JSON report, like `skid pgo FILE.g2o [--robust MODE]
//! [--init chordal] [--out OUT.g2o]` will.

use skid_backend_pgo::{Initialization, PgoOptions, RobustMode, optimize_g2o_file, write_g2o};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let mut options = PgoOptions::default();
    let (mut path, mut out) = (None, None);
    while let Some(arg) = args.next() {
        match arg.as_str() {
            "--robust" => options.robust = RobustMode::parse(&args.next().unwrap_or_default())?,
            "--init" => options.init = Initialization::parse(&args.next().unwrap_or_default())?,
            "--out" => out = args.next(),
            "--tolerance" => {
                options.relative_tolerance = args.next().and_then(|v| v.parse().ok()).unwrap_or(1e-6)
            }
            _ => path = Some(arg),
        }
    }
    let path = path.ok_or("usage: pgo_file FILE.g2o [--robust MODE] [--init chordal] [--out OUT.g2o]")?;
    let (report, graph) = optimize_g2o_file(&path, &options)?;
    println!("{}", serde_json::to_string(&report)?);
    if let Some(out) = out {
        write_g2o(out, &graph)?;
    }
    Ok(())
}
