//! The one font the plots use for text, found at run time. plotters' `ab_glyph` feature renders text
//! from font bytes we register, so no system font library is linked; the bytes come from the file named
//! by `SKID_PLOT_FONT` or from a few usual DejaVu/Liberation locations. Without any of them, plots are
//! drawn without text and their callers put the labels next to the image (see `PlotOutput::legend`).

use std::sync::OnceLock;

use plotters::style::{FontStyle, register_font};

/// Environment variable naming a TrueType/OpenType font file to use for plot text.
pub const FONT_VAR: &str = "SKID_PLOT_FONT";

/// The family name the plots ask plotters for.
pub(crate) const FAMILY: &str = "sans-serif";

const CANDIDATES: &[&str] = &[
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu-sans-fonts/DejaVuSans.ttf",
    "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
    "/usr/share/fonts/liberation-sans/LiberationSans-Regular.ttf",
];

static FONT_READY: OnceLock<bool> = OnceLock::new();

fn load() -> bool {
    let from_env = std::env::var_os(FONT_VAR).map(std::path::PathBuf::from);
    let paths = from_env
        .into_iter()
        .chain(CANDIDATES.iter().map(std::path::PathBuf::from));
    for path in paths {
        let Ok(bytes) = std::fs::read(&path) else {
            continue;
        };
        // plotters keeps `&'static` font bytes; this happens once per process.
        let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
        if register_font(FAMILY, FontStyle::Normal, bytes).is_ok() {
            return true;
        }
    }
    false
}

/// True when a font was found and registered, so plots can draw text.
pub fn font_available() -> bool {
    *FONT_READY.get_or_init(load)
}
