//! PNG plots for evaluation reports, drawn with plotters' bitmap backend into memory and encoded with the
//! `png` crate (no image-encoder or system-font dependencies): line plots (PR curves, success rate
//! against yaw), top-down trajectory plots (estimates against ground truth) and top-down point maps.
//!
//! Text (title, axis names, tick labels, legend) is drawn when a font file is found at run time
//! (see [`font_available`]); otherwise the plot is drawn without text, and the returned
//! [`PlotOutput`] still names every series and its colour so the caller can write the legend and the
//! axis names in the Markdown next to the image.

mod chart;
mod font;
mod run;

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

pub use chart::{draw_chart, line_plot, point_map, pr_curve_plot, trajectory_plot};
pub use font::{FONT_VAR, font_available};
pub use run::{LoopClass, LoopLine, RobotTrack, RunPlotData, write_run_plots};

use crate::error::EvalError;

/// Size and text switches of a plot.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PlotOptions {
    pub width_px: u32,
    pub height_px: u32,
    /// Draw text when a font is available (set `false` to force text-free plots).
    pub text: bool,
}

impl Default for PlotOptions {
    fn default() -> Self {
        Self {
            width_px: 1024,
            height_px: 768,
            text: true,
        }
    }
}

/// How a series is drawn.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SeriesStyle {
    /// A polyline through the points in order.
    #[default]
    Line,
    /// A polyline with a dot at every point.
    LineWithMarkers,
    /// A small dot per point.
    Points,
    /// One pixel per point (dense point maps).
    Pixels,
    /// A dashed polyline (ground truth under estimates).
    DashedLine,
    /// A thin line per consecutive pair of points, `(p0, p1), (p2, p3), …` (loop closures).
    Segments,
    /// A large ring per point (where a robot started).
    Rings,
}

/// One named series of `(x, y)` points.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Series {
    /// Legend entry; `None` keeps the series out of the legend.
    pub name: Option<String>,
    pub points: Vec<(f64, f64)>,
    /// RGB colour; `None` takes the next palette colour.
    pub color: Option<[u8; 3]>,
    pub style: SeriesStyle,
}

impl Series {
    /// A named line series in the next palette colour.
    pub fn line(name: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        Self {
            name: Some(name.into()),
            points,
            color: None,
            style: SeriesStyle::Line,
        }
    }
}

/// A chart: series in a common frame with a title and axis names.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Chart {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub series: Vec<Series>,
    /// Fixed axis ranges; `None` fits the data with a 5 % margin.
    pub x_range: Option<(f64, f64)>,
    pub y_range: Option<(f64, f64)>,
    /// Same scale on both axes (maps and trajectories).
    pub equal_aspect: bool,
}

/// A legend entry as text, for captions when the image has no text.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LegendEntry {
    pub name: String,
    /// `#rrggbb`.
    pub color_hex: String,
    /// How the series is drawn; the legend's swatch is drawn the same way (dashed for ground truth).
    pub style: SeriesStyle,
}

/// What was written.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PlotOutput {
    pub path: PathBuf,
    pub width_px: u32,
    pub height_px: u32,
    /// Whether title, axes and legend were drawn into the image.
    pub text_rendered: bool,
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub legend: Vec<LegendEntry>,
}

impl PlotOutput {
    /// A Markdown image line with a caption naming the axes and the series colours, so the plot reads
    /// the same whether or not its text was drawn.
    pub fn markdown(&self) -> String {
        let file = self.path.file_name().map_or_else(
            || self.path.display().to_string(),
            |f| f.to_string_lossy().into_owned(),
        );
        let legend: Vec<String> = self
            .legend
            .iter()
            .map(|e| match e.style {
                SeriesStyle::DashedLine => format!("{} = {} (dashed)", e.name, e.color_hex),
                _ => format!("{} = {}", e.name, e.color_hex),
            })
            .collect();
        format!(
            "![{}]({file})\n\n*{}* — x: {}, y: {}; {}\n",
            self.title,
            self.title,
            self.x_label,
            self.y_label,
            legend.join(", ")
        )
    }
}

/// Tableau-10 colours, used in order for series without a colour.
pub const PALETTE: [[u8; 3]; 10] = [
    [31, 119, 180],
    [214, 39, 40],
    [44, 160, 44],
    [255, 127, 14],
    [148, 103, 189],
    [23, 190, 207],
    [140, 86, 75],
    [227, 119, 194],
    [188, 189, 34],
    [127, 127, 127],
];

/// Writes an RGB buffer as a PNG file.
pub(crate) fn write_png(path: &Path, width: u32, height: u32, rgb: &[u8]) -> Result<(), EvalError> {
    let fail = |reason: String| EvalError::Plot {
        path: path.to_path_buf(),
        reason,
    };
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent).map_err(|e| fail(format!("creating {}: {e}", parent.display())))?;
    }
    let file = std::fs::File::create(path).map_err(|e| fail(e.to_string()))?;
    let mut encoder = png::Encoder::new(std::io::BufWriter::new(file), width, height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header().map_err(|e| fail(e.to_string()))?;
    writer.write_image_data(rgb).map_err(|e| fail(e.to_string()))?;
    writer.finish().map_err(|e| fail(e.to_string()))
}
