//! Drawing a [`Chart`] with plotters into an RGB buffer, and the ready-made plots built on it: line
//! plots, PR curves, top-down trajectories and top-down point maps.

use std::path::Path;

use plotters::prelude::*;

use super::font::{FAMILY, font_available};
use super::{Chart, LegendEntry, PALETTE, PlotOptions, PlotOutput, Series, SeriesStyle, write_png};
use crate::error::EvalError;
use crate::pr::PrCurve;
use skid_core::Pose;

const MARGIN_PX: u32 = 16;
const CAPTION_PX: u32 = 28;
const X_LABEL_AREA_PX: u32 = 48;
const Y_LABEL_AREA_PX: u32 = 72;

/// The data extent of all series, padded by 5 % (or ±1 when flat).
fn fit_range(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
        (lo.min(v), hi.max(v))
    });
    if lo > hi {
        return None;
    }
    let pad = if hi > lo { 0.05 * (hi - lo) } else { 1.0 };
    Some((lo - pad, hi + pad))
}

/// Widens the narrower range so one unit has the same length in pixels on both axes.
fn equalise(x: (f64, f64), y: (f64, f64), plot_w: f64, plot_h: f64) -> ((f64, f64), (f64, f64)) {
    let (x_span, y_span) = (x.1 - x.0, y.1 - y.0);
    let units_per_px = (x_span / plot_w).max(y_span / plot_h);
    let grow = |r: (f64, f64), span_px: f64| {
        let half = 0.5 * units_per_px * span_px;
        let mid = 0.5 * (r.0 + r.1);
        (mid - half, mid + half)
    };
    (grow(x, plot_w), grow(y, plot_h))
}

fn color_of(series: &Series, index: usize) -> RGBColor {
    let [r, g, b] = series.color.unwrap_or(PALETTE[index % PALETTE.len()]);
    RGBColor(r, g, b)
}

/// Draws `chart` into a PNG at `path`.
pub fn draw_chart(path: &Path, chart: &Chart, options: &PlotOptions) -> Result<PlotOutput, EvalError> {
    let fail = |reason: String| EvalError::Plot {
        path: path.to_path_buf(),
        reason,
    };
    let (w, h) = (options.width_px, options.height_px);
    if !(200..=8192).contains(&w) || !(150..=8192).contains(&h) {
        return Err(fail(format!("size {w}x{h} px is outside 200x150 ..= 8192x8192")));
    }
    for (index, series) in chart.series.iter().enumerate() {
        if let Some(k) = series
            .points
            .iter()
            .position(|(x, y)| !(x.is_finite() && y.is_finite()))
        {
            return Err(fail(format!(
                "series {index} has a non-finite point at index {k}"
            )));
        }
    }
    for (name, range) in [("x_range", chart.x_range), ("y_range", chart.y_range)] {
        if let Some((lo, hi)) = range
            && !(lo.is_finite() && hi.is_finite() && lo < hi)
        {
            return Err(fail(format!(
                "{name} ({lo}, {hi}) is not an increasing finite interval"
            )));
        }
    }
    let points = || chart.series.iter().flat_map(|s| s.points.iter());
    let text = options.text && font_available();
    let (Some(mut x_range), Some(mut y_range)) = (
        chart.x_range.or_else(|| fit_range(points().map(|p| p.0))),
        chart.y_range.or_else(|| fit_range(points().map(|p| p.1))),
    ) else {
        return Err(fail("no point to plot and no axis ranges given".into()));
    };
    if chart.equal_aspect {
        let (label_w, label_h, caption) = if text {
            (Y_LABEL_AREA_PX, X_LABEL_AREA_PX, CAPTION_PX)
        } else {
            (0, 0, 0)
        };
        let plot_w = f64::from(w.saturating_sub(2 * MARGIN_PX + label_w).max(1));
        let plot_h = f64::from(h.saturating_sub(2 * MARGIN_PX + label_h + caption).max(1));
        (x_range, y_range) = equalise(x_range, y_range, plot_w, plot_h);
    }

    let mut buffer = vec![255u8; w as usize * h as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut buffer, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| fail(e.to_string()))?;
        let mut builder = ChartBuilder::on(&root);
        builder.margin(MARGIN_PX);
        if text {
            builder
                .caption(&chart.title, (FAMILY, 22))
                .x_label_area_size(X_LABEL_AREA_PX)
                .y_label_area_size(Y_LABEL_AREA_PX);
        }
        let mut context = builder
            .build_cartesian_2d(x_range.0..x_range.1, y_range.0..y_range.1)
            .map_err(|e| fail(e.to_string()))?;
        let mut mesh = context.configure_mesh();
        mesh.light_line_style(RGBColor(235, 235, 235));
        if text {
            mesh.x_desc(&chart.x_label)
                .y_desc(&chart.y_label)
                .label_style((FAMILY, 14));
        } else {
            mesh.x_labels(10).y_labels(10);
        }
        mesh.draw().map_err(|e| fail(e.to_string()))?;

        let mut any_named = false;
        for (index, series) in chart.series.iter().enumerate() {
            let color = color_of(series, index);
            let data = series.points.iter().copied();
            let annotation = match series.style {
                SeriesStyle::Line | SeriesStyle::LineWithMarkers => context
                    .draw_series(LineSeries::new(data.clone(), color.stroke_width(2)))
                    .map_err(|e| fail(e.to_string()))?,
                SeriesStyle::Points => context
                    .draw_series(data.map(|p| Circle::new(p, 2, color.filled())))
                    .map_err(|e| fail(e.to_string()))?,
                SeriesStyle::Pixels => context
                    .draw_series(data.map(|p| Pixel::new(p, color)))
                    .map_err(|e| fail(e.to_string()))?,
                SeriesStyle::DashedLine => context
                    .draw_series(DashedLineSeries::new(data, 6, 4, color.stroke_width(2)))
                    .map_err(|e| fail(e.to_string()))?,
                SeriesStyle::Segments => context
                    .draw_series(
                        series
                            .points
                            .chunks_exact(2)
                            .map(|pair| PathElement::new(vec![pair[0], pair[1]], color.stroke_width(1))),
                    )
                    .map_err(|e| fail(e.to_string()))?,
                SeriesStyle::Rings => context
                    .draw_series(data.map(|p| Circle::new(p, 7, color.stroke_width(3))))
                    .map_err(|e| fail(e.to_string()))?,
            };
            if let (Some(name), true) = (&series.name, text) {
                any_named = true;
                let style = series.style;
                annotation.label(name.as_str()).legend(move |(x, y)| {
                    let swatch = Swatch::of(style, color);
                    let piece = |(from, to, style): (i32, i32, ShapeStyle)| {
                        PathElement::new(vec![(from, 0), (to, 0)], style)
                    };
                    EmptyElement::at((x, y))
                        + piece(swatch.first)
                        + piece(swatch.second)
                        + Circle::new((10, 0), swatch.circle.0, swatch.circle.1)
                });
            }
            if series.style == SeriesStyle::LineWithMarkers {
                context
                    .draw_series(series.points.iter().map(|&p| Circle::new(p, 3, color.filled())))
                    .map_err(|e| fail(e.to_string()))?;
            }
        }
        if any_named {
            context
                .configure_series_labels()
                .label_font((FAMILY, 14))
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .position(SeriesLabelPosition::UpperRight)
                .draw()
                .map_err(|e| fail(e.to_string()))?;
        }
        root.present().map_err(|e| fail(e.to_string()))?;
    }
    write_png(path, w, h, &buffer)?;

    let legend = chart
        .series
        .iter()
        .enumerate()
        .filter_map(|(index, s)| {
            let RGBColor(r, g, b) = color_of(s, index);
            s.name.as_ref().map(|name| LegendEntry {
                name: name.clone(),
                color_hex: format!("#{r:02x}{g:02x}{b:02x}"),
                style: s.style,
            })
        })
        .collect();
    Ok(PlotOutput {
        path: path.to_path_buf(),
        width_px: w,
        height_px: h,
        text_rendered: text,
        title: chart.title.clone(),
        x_label: chart.x_label.clone(),
        y_label: chart.y_label.clone(),
        legend,
    })
}

/// The legend's sample of a series, drawn as the series is: a dashed line for ground truth, a dot for
/// points and pixels, a ring for rings, a solid line otherwise. It is two line pieces and a circle, in
/// pixels from the legend's anchor and 20 px wide like plotters' own; the parts a style has no use for
/// are transparent, so every style is one element type.
struct Swatch {
    first: (i32, i32, ShapeStyle),
    second: (i32, i32, ShapeStyle),
    circle: (u32, ShapeStyle),
}

impl Swatch {
    fn of(style: SeriesStyle, color: RGBColor) -> Self {
        let line = color.stroke_width(3);
        let none = TRANSPARENT.stroke_width(0);
        let (first, second) = match style {
            SeriesStyle::DashedLine => ((0, 6, line), (13, 19, line)),
            SeriesStyle::Points | SeriesStyle::Pixels | SeriesStyle::Rings => ((0, 0, none), (0, 0, none)),
            SeriesStyle::Line | SeriesStyle::LineWithMarkers | SeriesStyle::Segments => {
                ((0, 10, line), (10, 20, line))
            }
        };
        let circle = match style {
            SeriesStyle::Points | SeriesStyle::Pixels | SeriesStyle::LineWithMarkers => (3, color.filled()),
            SeriesStyle::Rings => (5, color.stroke_width(2)),
            SeriesStyle::DashedLine | SeriesStyle::Line | SeriesStyle::Segments => (0, none),
        };
        Self {
            first,
            second,
            circle,
        }
    }
}

/// A line plot of named series (e.g. success rate against yaw), axes fitted to the data unless given.
pub fn line_plot(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: Vec<Series>,
    options: &PlotOptions,
) -> Result<PlotOutput, EvalError> {
    let chart = Chart {
        title: title.into(),
        x_label: x_label.into(),
        y_label: y_label.into(),
        series,
        ..Chart::default()
    };
    draw_chart(path, &chart, options)
}

/// PR curves (recall on x, precision on y, both in `[0, 1]`), one line per named curve.
pub fn pr_curve_plot(
    path: &Path,
    title: &str,
    curves: &[(&str, &PrCurve)],
    options: &PlotOptions,
) -> Result<PlotOutput, EvalError> {
    let series = curves
        .iter()
        .map(|(name, curve)| {
            Series::line(
                *name,
                curve.points.iter().map(|p| (p.recall, p.precision)).collect(),
            )
        })
        .collect();
    let chart = Chart {
        title: title.into(),
        x_label: "recall".into(),
        y_label: "precision".into(),
        series,
        x_range: Some((0.0, 1.02)),
        y_range: Some((0.0, 1.02)),
        equal_aspect: false,
    };
    draw_chart(path, &chart, options)
}

/// Top-down (x, y) view of named trajectories with equal axis scales; pass the ground truth first to
/// draw it in grey below the estimates.
pub fn trajectory_plot(
    path: &Path,
    title: &str,
    trajectories: &[(&str, &[Pose])],
    ground_truth_first: bool,
    options: &PlotOptions,
) -> Result<PlotOutput, EvalError> {
    let series = trajectories
        .iter()
        .enumerate()
        .map(|(index, (name, poses))| {
            let mut s = Series::line(
                *name,
                poses.iter().map(|p| (p.translation.x, p.translation.y)).collect(),
            );
            if ground_truth_first && index == 0 {
                s.color = Some([90, 90, 90]);
            } else {
                s.color = Some(PALETTE[index % PALETTE.len()]);
            }
            s
        })
        .collect();
    let chart = Chart {
        title: title.into(),
        x_label: "x (m)".into(),
        y_label: "y (m)".into(),
        series,
        equal_aspect: true,
        ..Chart::default()
    };
    draw_chart(path, &chart, options)
}

/// Top-down point map: `points` as `(x, y, z)`, coloured from blue (low z) to red (high z) in eight
/// height bands, with optional trajectories drawn over it.
pub fn point_map(
    path: &Path,
    title: &str,
    points: &[[f64; 3]],
    trajectories: &[(&str, &[Pose])],
    options: &PlotOptions,
) -> Result<PlotOutput, EvalError> {
    const BANDS: usize = 8;
    let fail = |reason: String| EvalError::Plot {
        path: path.to_path_buf(),
        reason,
    };
    if let Some(k) = points.iter().position(|p| !p.iter().all(|v| v.is_finite())) {
        return Err(fail(format!("map point {k} is not finite")));
    }
    let (z_lo, z_hi) = points
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(p[2]), hi.max(p[2]))
        });
    let z_span = (z_hi - z_lo).max(f64::MIN_POSITIVE);
    let mut bands: Vec<Vec<(f64, f64)>> = vec![Vec::new(); BANDS];
    for p in points {
        let band = (((p[2] - z_lo) / z_span) * BANDS as f64).floor() as usize;
        bands[band.min(BANDS - 1)].push((p[0], p[1]));
    }
    let mut series: Vec<Series> = bands
        .into_iter()
        .enumerate()
        .map(|(k, band)| {
            let t = k as f64 / (BANDS - 1) as f64;
            Series {
                name: None,
                points: band,
                color: Some([(40.0 + 200.0 * t) as u8, 90, (240.0 - 200.0 * t) as u8]),
                style: SeriesStyle::Pixels,
            }
        })
        .collect();
    for (index, (name, poses)) in trajectories.iter().enumerate() {
        let mut s = Series::line(
            *name,
            poses.iter().map(|p| (p.translation.x, p.translation.y)).collect(),
        );
        s.color = Some(PALETTE[(index + 2) % PALETTE.len()]);
        series.push(s);
    }
    let chart = Chart {
        title: title.into(),
        x_label: "x (m)".into(),
        y_label: "y (m)".into(),
        series,
        equal_aspect: true,
        ..Chart::default()
    };
    draw_chart(path, &chart, options)
}
