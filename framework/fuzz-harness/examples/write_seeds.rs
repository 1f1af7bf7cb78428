//! Writes every fuzz target's seeds into `<folder>/<target>/seed-<n>` (default folder: `fuzz/corpus`),
//! where `cargo xtask fuzz` starts the fuzzer from.

use std::path::PathBuf;

fn main() -> std::io::Result<()> {
    let folder = std::env::args().nth(1).map_or_else(
        || PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fuzz/corpus"),
        PathBuf::from,
    );
    for (target, _) in skid_fuzz_harness::TARGETS {
        let target_folder = folder.join(target);
        std::fs::create_dir_all(&target_folder)?;
        for (index, seed) in skid_fuzz_harness::seeds::seeds(target).iter().enumerate() {
            std::fs::write(target_folder.join(format!("seed-{index}")), seed)?;
        }
    }
    Ok(())
}
