//! Tests of the second-best hypothesis test ([`crate::rival`]): a hall with 90° rotational symmetry,
//! scanned by a ray-cast 64-beam sensor, is reported ambiguous; the real HDL-32E pair is not.

use nalgebra::{Point3, Vector3};
use skid_core::slots::CoarseRegistration;
use skid_core::{Cloud, Point, Pose};

use super::{matcher, real_pair};

/// The hall: a 30 m square room, 5 m high, with four identical groups of pillars and crates, each a
/// quarter turn of the last about the room's centre. Nothing in one quarter tells it from the others.
struct Hall {
    /// Vertical cylinders: centre (x, y) and radius, in metres.
    pillars: Vec<(f64, f64, f64)>,
    /// Axis-aligned boxes standing on the floor: centre (x, y), half extents (x, y) and height.
    crates: Vec<(f64, f64, f64, f64, f64)>,
}

const HALF_WIDTH_M: f64 = 15.0;
const FLOOR_Z_M: f64 = -1.5;
const CEILING_Z_M: f64 = 3.5;

impl Hall {
    fn new() -> Self {
        let quarter_pillars = [(6.0, 2.5, 0.4), (9.5, 7.0, 0.6), (3.0, 11.0, 0.3)];
        let quarter_crates = [(11.0, 3.0, 1.0, 0.6, 1.2), (5.0, 7.5, 0.5, 1.5, 0.8)];
        let turn = |k: usize, x: f64, y: f64| match k {
            0 => (x, y),
            1 => (-y, x),
            2 => (-x, -y),
            _ => (y, -x),
        };
        let mut hall = Self {
            pillars: Vec::new(),
            crates: Vec::new(),
        };
        for k in 0..4 {
            for &(x, y, r) in &quarter_pillars {
                let (x, y) = turn(k, x, y);
                hall.pillars.push((x, y, r));
            }
            for &(x, y, hx, hy, h) in &quarter_crates {
                let (x, y) = turn(k, x, y);
                let (hx, hy) = if k % 2 == 0 { (hx, hy) } else { (hy, hx) };
                hall.crates.push((x, y, hx, hy, h));
            }
        }
        hall
    }

    /// The distance along the unit ray from `origin` to the first surface.
    fn cast(&self, origin: &Vector3<f64>, direction: &Vector3<f64>) -> Option<f64> {
        let mut nearest = f64::INFINITY;
        let mut hit = |t: f64| {
            if t > 1e-6 && t < nearest {
                nearest = t;
            }
        };
        // Floor, ceiling and the four walls.
        for (axis, bound) in [
            (2, FLOOR_Z_M),
            (2, CEILING_Z_M),
            (0, HALF_WIDTH_M),
            (0, -HALF_WIDTH_M),
            (1, HALF_WIDTH_M),
            (1, -HALF_WIDTH_M),
        ] {
            if direction[axis].abs() > 1e-12 {
                hit((bound - origin[axis]) / direction[axis]);
            }
        }
        for &(cx, cy, radius) in &self.pillars {
            let (ox, oy) = (origin.x - cx, origin.y - cy);
            let a = direction.x * direction.x + direction.y * direction.y;
            let b = 2.0 * (ox * direction.x + oy * direction.y);
            let c = ox * ox + oy * oy - radius * radius;
            let discriminant = b * b - 4.0 * a * c;
            if a > 1e-12 && discriminant >= 0.0 {
                hit((-b - discriminant.sqrt()) / (2.0 * a));
            }
        }
        for &(cx, cy, hx, hy, height) in &self.crates {
            let low = Vector3::new(cx - hx, cy - hy, FLOOR_Z_M);
            let high = Vector3::new(cx + hx, cy + hy, FLOOR_Z_M + height);
            let (mut enter, mut leave) = (f64::NEG_INFINITY, f64::INFINITY);
            for axis in 0..3 {
                if direction[axis].abs() < 1e-12 {
                    if origin[axis] < low[axis] || origin[axis] > high[axis] {
                        enter = f64::INFINITY;
                    }
                    continue;
                }
                let t1 = (low[axis] - origin[axis]) / direction[axis];
                let t2 = (high[axis] - origin[axis]) / direction[axis];
                enter = enter.max(t1.min(t2));
                leave = leave.min(t1.max(t2));
            }
            if enter <= leave {
                hit(enter);
            }
        }
        nearest.is_finite().then_some(nearest)
    }

    /// A 64-beam, 1024-column scan (±16.6° elevation, like an OS1-64) from `world_from_sensor`, in the
    /// sensor frame, with 1 cm range noise from a fixed-seed generator.
    fn scan(&self, world_from_sensor: &Pose, seed: u64) -> Cloud {
        let mut state = seed | 1;
        let mut noise = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state % 2001) as f64 / 1000.0 - 1.0
        };
        let origin = world_from_sensor.translation.vector;
        let mut points = Vec::with_capacity(64 * 1024);
        for beam in 0..64 {
            let elevation = (-16.6 + 33.2 * f64::from(beam) / 63.0).to_radians();
            for column in 0..1024 {
                let azimuth = std::f64::consts::TAU * f64::from(column) / 1024.0;
                let local = Vector3::new(
                    elevation.cos() * azimuth.cos(),
                    elevation.cos() * azimuth.sin(),
                    elevation.sin(),
                );
                let direction = world_from_sensor.rotation * local;
                if let Some(range) = self.cast(&origin, &direction) {
                    let range = range + 0.01 * noise();
                    let p = Point3::from(local * range);
                    points.push(Point::new(p.x as f32, p.y as f32, p.z as f32));
                }
            }
        }
        Cloud::new(points)
    }
}

#[test]
fn a_hall_with_ninety_degree_symmetry_is_ambiguous() {
    let hall = Hall::new();
    let target_pose = Pose::new(Vector3::new(0.4, -0.3, 0.0), Vector3::z() * 0.2);
    let source_pose = Pose::new(Vector3::new(-0.5, 0.6, 0.0), Vector3::z() * 0.9);
    let target = hall.scan(&target_pose, 11);
    let source = hall.scan(&source_pose, 12);
    let mut matcher = matcher();
    let report = matcher.align_with_report(target.view(), source.view()).unwrap();
    eprintln!(
        "hall: {} inliers, rival {} ({report:?})",
        report.final_inliers, report.rival_inliers
    );
    assert!(report.alignment.valid, "{report:?}");
    assert!(
        report.rival_inliers as f64 >= 0.5 * report.final_inliers as f64,
        "the symmetric hall must show a rival nearly as strong as the best alignment: {report:?}"
    );
    assert_eq!(report.alignment.rival_inlier_count, report.rival_inliers);
}

#[test]
fn the_real_pair_has_no_strong_rival() {
    let (target, source, _) = real_pair();
    let mut matcher = matcher();
    for yaw_deg in [0.0f64, 45.0, 90.0, 135.0, 180.0, 225.0, 270.0, 315.0] {
        let motion = Pose::new(Vector3::new(3.0, -2.0, 0.0), Vector3::z() * yaw_deg.to_radians());
        let moved = target.view().transformed(&motion);
        let alignment = matcher.align(moved.view(), source.view(), None).unwrap();
        eprintln!(
            "real pair, yaw {yaw_deg}: {} inliers, rival {}",
            alignment.inlier_count, alignment.rival_inlier_count
        );
        assert!(
            (alignment.rival_inlier_count as f64) < 0.5 * alignment.inlier_count as f64,
            "yaw {yaw_deg}°: a real, unsymmetric place must not look ambiguous: {alignment:?}"
        );
    }
}
