//! A top-down PNG preview of a world with robot paths: the world is rendered by casting one vertical ray
//! per pixel (so it shows exactly what the sensors see), coloured by height and hill-shaded with a light
//! from the north-west; each robot's path is drawn in its own colour, with a square at its start.

use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

use rayon::prelude::*;

use crate::SimError;
use crate::geometry::{Ray, V3};
use crate::motion::trajectory;
use crate::source::SimConfig;
use crate::world::World;

/// Distinct colours for up to 16 robots.
const PALETTE: [[u8; 3]; 16] = [
    [230, 25, 75],
    [60, 180, 75],
    [0, 130, 200],
    [245, 130, 48],
    [145, 30, 180],
    [70, 240, 240],
    [240, 50, 230],
    [210, 245, 60],
    [250, 190, 212],
    [0, 128, 128],
    [220, 190, 255],
    [170, 110, 40],
    [255, 250, 200],
    [128, 0, 0],
    [170, 255, 195],
    [255, 215, 180],
];

/// Renders `world` from above into a `size_px` × `size_px` PNG at `path`, with `paths` (x/y points in
/// metres, one list per robot) drawn on top.
pub fn preview_png(
    path: impl AsRef<Path>,
    world: &World,
    paths: &[Vec<[f64; 2]>],
    size_px: u32,
) -> Result<(), SimError> {
    let path = path.as_ref();
    let size = size_px.clamp(16, 8192) as usize;
    let [x0, y0, x1, y1] = world.extent_m();
    let span = (x1 - x0).max(y1 - y0);
    let metres_per_px = span / size as f64;
    let top = 500.0;
    let samples: Vec<Option<(f32, V3)>> = (0..size * size)
        .into_par_iter()
        .map(|i| {
            let (px, py) = (i % size, i / size);
            let x = x0 + (px as f64 + 0.5) * metres_per_px;
            let y = y0 + span - (py as f64 + 0.5) * metres_per_px;
            let ray = Ray::new(V3::from_f64(x, y, top), V3::new(0.0, 0.0, -1.0));
            world
                .cast(&ray, 1000.0)
                .map(|hit| (top as f32 - hit.range_m, hit.normal))
        })
        .collect();
    let (z_low, z_high) = samples
        .iter()
        .flatten()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), (z, _)| {
            (lo.min(*z), hi.max(*z))
        });
    let light = V3::new(-0.5, 0.5, 0.7).normalized();
    let mut rgb: Vec<u8> = samples
        .iter()
        .flat_map(|sample| match sample {
            Some((z, normal)) => {
                let h = ((z - z_low) / (z_high - z_low).max(1e-3)).clamp(0.0, 1.0);
                let normal = if normal.z < 0.0 { *normal * -1.0 } else { *normal };
                let shade = 0.35 + 0.65 * normal.dot(light).max(0.0);
                let base = [90.0 + 150.0 * h, 80.0 + 140.0 * h, 70.0 + 120.0 * h];
                base.map(|c| (c * shade).clamp(0.0, 255.0) as u8)
            }
            None => [12, 12, 20],
        })
        .collect();
    let mut plot = |x: f64, y: f64, radius: i64, color: [u8; 3]| {
        let px = ((x - x0) / metres_per_px) as i64;
        let py = ((y0 + span - y) / metres_per_px) as i64;
        for dy in -radius..=radius {
            for dx in -radius..=radius {
                let (u, v) = (px + dx, py + dy);
                if u >= 0 && v >= 0 && (u as usize) < size && (v as usize) < size {
                    let k = 3 * (v as usize * size + u as usize);
                    rgb[k..k + 3].copy_from_slice(&color);
                }
            }
        }
    };
    for (robot, points) in paths.iter().enumerate() {
        let color = PALETTE[robot % PALETTE.len()];
        for w in points.windows(2) {
            let steps = ((w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]) / (metres_per_px * 0.5))
                .ceil()
                .max(1.0) as usize;
            for s in 0..=steps {
                let t = s as f64 / steps as f64;
                plot(
                    w[0][0] + (w[1][0] - w[0][0]) * t,
                    w[0][1] + (w[1][1] - w[0][1]) * t,
                    1,
                    color,
                );
            }
        }
        if let Some(start) = points.first() {
            plot(start[0], start[1], 4, color);
        }
    }
    let file = File::create(path).map_err(|e| SimError::io(path, e))?;
    let mut encoder = png::Encoder::new(BufWriter::new(file), size as u32, size as u32);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let png_error = |e: png::EncodingError| SimError::Png {
        path: path.to_owned(),
        message: e.to_string(),
    };
    let mut writer = encoder.write_header().map_err(png_error)?;
    writer.write_image_data(&rgb).map_err(png_error)?;
    writer.finish().map_err(png_error)
}

/// Renders the world of `config` with the paths of all its robots.
pub fn preview_fleet_png(path: impl AsRef<Path>, config: &SimConfig, size_px: u32) -> Result<(), SimError> {
    let (kind, _) = config.validate()?;
    let (world, routes) = config.world_and_routes(kind);
    let paths: Vec<Vec<[f64; 2]>> = routes
        .iter()
        .map(|route| {
            let trajectory = trajectory(&world, route, &config.motion());
            let steps = ((trajectory.end_s() - trajectory.start_s()) / 0.5).ceil() as usize;
            (0..=steps)
                .map(|k| {
                    let p = trajectory
                        .pose_at(trajectory.start_s() + k as f64 * 0.5)
                        .translation
                        .vector;
                    [p.x, p.y]
                })
                .collect()
        })
        .collect();
    preview_png(path, &world, &paths, size_px)
}
