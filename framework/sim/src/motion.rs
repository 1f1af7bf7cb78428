//! From a route's centre line to a smooth, physically plausible trajectory.
//!
//! Ground robots: the centre line is smoothed (corners become arcs of a few metres' radius), the speed
//! is limited by lateral acceleration in turns and by longitudinal acceleration at the ends (a
//! trapezoid-like profile), and the body follows the ground: height from a downward ray, roll and pitch
//! from four contact points about the footprint, low-pass filtered like a suspension. Aerial robots
//! hold an altitude above the ground (10 m outdoors, 2.2 m in caves), bank into turns (coordinated turn,
//! bank = atan(v·ψ̇ / g)) and pitch with acceleration. Legged, handheld and fast-turning carriers add
//! their body motion ([`crate::gait`]) on a finer control spacing.

use nalgebra::{Translation3, UnitQuaternion, Vector3};
use skid_core::Pose;

use crate::gait::{self, Profile};
use crate::route::Route;
use crate::trajectory::Trajectory;
use crate::world::{World, WorldKind};

/// Gravity used by motion and IMU models.
pub const GRAVITY_MPS2: f64 = 9.80665;
/// Spacing of the trajectory's control poses.
pub const CONTROL_DT_S: f64 = 0.1;

/// Motion parameters.
#[derive(Clone, Copy, Debug)]
pub struct MotionSpec {
    pub speed_mps: f64,
    pub profile: Profile,
    /// Sensor height above the ground contact (ground robots).
    pub mount_height_m: f64,
    /// Standing time before the robot starts and after it stops.
    pub still_s: f64,
    /// The robot drives this far to the right of the route's centre line (negative: to the left), as a
    /// vehicle keeps to its side of a road. Two robots driving one route in opposite directions then
    /// pass each other `2 × keep_right_m` apart: a reverse traverse is a different viewpoint, not the
    /// same scan turned around.
    pub keep_right_m: f64,
}

impl MotionSpec {
    /// How far a robot keeps to the right of the centre line in a world of `kind` by default: half a
    /// lane in a city (1.75 m), a rover's offset from a planned traverse (1 m), a little in a tunnel.
    pub fn default_keep_right_m(kind: WorldKind) -> f64 {
        match kind {
            WorldKind::Urban | WorldKind::Blocks => 1.75,
            WorldKind::Planetary => 1.0,
            WorldKind::Cave => 0.3,
        }
    }
}

impl Default for MotionSpec {
    fn default() -> Self {
        Self {
            speed_mps: 1.0,
            profile: Profile::Ground,
            mount_height_m: 0.8,
            still_s: 1.0,
            keep_right_m: 0.0,
        }
    }
}

fn resample(line: &[[f64; 3]], spacing_m: f64) -> Vec<[f64; 3]> {
    let mut out = vec![line[0]];
    let mut carry = 0.0;
    for w in line.windows(2) {
        let length =
            ((w[1][0] - w[0][0]).powi(2) + (w[1][1] - w[0][1]).powi(2) + (w[1][2] - w[0][2]).powi(2)).sqrt();
        let mut s = spacing_m - carry;
        while s <= length {
            let t = s / length;
            out.push(std::array::from_fn(|k| w[0][k] + (w[1][k] - w[0][k]) * t));
            s += spacing_m;
        }
        carry = length - (s - spacing_m);
    }
    if let Some(&last) = line.last() {
        out.push(last);
    }
    out
}

fn moving_average(points: &[[f64; 3]], half_window: usize) -> Vec<[f64; 3]> {
    (0..points.len())
        .map(|i| {
            let w = half_window.min(i).min(points.len() - 1 - i);
            let slice = &points[i - w..=i + w];
            std::array::from_fn(|k| slice.iter().map(|p| p[k]).sum::<f64>() / slice.len() as f64)
        })
        .collect()
}

fn smooth_scalar(values: &[f64], half_window: usize) -> Vec<f64> {
    (0..values.len())
        .map(|i| {
            let (lo, hi) = (
                i.saturating_sub(half_window),
                (i + half_window).min(values.len() - 1),
            );
            values[lo..=hi].iter().sum::<f64>() / (hi - lo + 1) as f64
        })
        .collect()
}

fn wrap_pi(a: f64) -> f64 {
    (a + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI
}

/// The heading of a polyline at each point (from its neighbours), unwrapped so it changes smoothly.
fn headings(path: &[[f64; 3]]) -> Vec<f64> {
    let n = path.len();
    let mut heading: Vec<f64> = (0..n)
        .map(|i| {
            let (a, b) = (path[i.saturating_sub(1)], path[(i + 1).min(n - 1)]);
            (b[1] - a[1]).atan2(b[0] - a[0])
        })
        .collect();
    for i in 1..n {
        heading[i] = heading[i - 1] + wrap_pi(heading[i] - heading[i - 1]);
    }
    heading
}

/// The trajectory of the body (= sensor) frame along `route`, starting at t = 0.
pub fn trajectory(world: &World, route: &Route, spec: &MotionSpec) -> Trajectory {
    let ds = 0.25;
    let coarse = resample(&route.centre_line, 1.0);
    // Corners are rounded by two moving averages over ±5 m, which cuts a right-angle turn by a few
    // metres: fine on open ground and streets, but in a tunnel about 3 m in radius it would climb the
    // inside wall, so caves round their corners over ±2 m.
    let half_window = if world.kind() == WorldKind::Cave { 2 } else { 5 };
    let smooth = moving_average(&moving_average(&coarse, half_window), half_window);
    let centre = resample(&smooth, ds);
    // Keep to the right: shift every point along the right-hand normal of the centre line's heading,
    // then sample the shifted line evenly again, so speeds and times below follow the path driven.
    let path = if spec.keep_right_m == 0.0 {
        centre
    } else {
        let centre_heading = headings(&centre);
        let shifted: Vec<[f64; 3]> = centre
            .iter()
            .zip(&centre_heading)
            .map(|(p, yaw)| {
                [
                    p[0] + spec.keep_right_m * yaw.sin(),
                    p[1] - spec.keep_right_m * yaw.cos(),
                    p[2],
                ]
            })
            .collect();
        resample(&shifted, ds)
    };
    let n = path.len();
    let heading = headings(&path);
    let curvature = smooth_scalar(
        &(0..n)
            .map(|i| (heading[(i + 1).min(n - 1)] - heading[i]).abs() / ds)
            .collect::<Vec<_>>(),
        8,
    );
    let (lateral_mps2, longitudinal_mps2) = match spec.profile {
        Profile::Aerial => (1.5, 0.8),
        _ => (0.4, 0.3),
    };
    let mut speed: Vec<f64> = curvature
        .iter()
        .map(|k| spec.speed_mps.min((lateral_mps2 / k.max(1e-9)).sqrt()))
        .collect();
    speed[0] = 0.0;
    speed[n - 1] = 0.0;
    for i in 1..n {
        speed[i] = speed[i].min((speed[i - 1].powi(2) + 2.0 * longitudinal_mps2 * ds).sqrt());
    }
    for i in (0..n - 1).rev() {
        speed[i] = speed[i].min((speed[i + 1].powi(2) + 2.0 * longitudinal_mps2 * ds).sqrt());
    }
    let mut times = vec![spec.still_s; n];
    for i in 1..n {
        times[i] = times[i - 1] + 2.0 * ds / (speed[i - 1] + speed[i]).max(0.02);
    }
    let end_s = times[n - 1] + spec.still_s;
    let control_dt = gait::control_dt_s(spec.profile, CONTROL_DT_S);
    let count = (end_s / control_dt).ceil() as usize + 1;

    // Sample the path at every control time.
    let mut samples = Vec::with_capacity(count);
    let mut cursor = 0;
    for k in 0..count {
        let t = k as f64 * control_dt;
        while cursor + 1 < n - 1 && times[cursor + 1] <= t {
            cursor += 1;
        }
        let (i, j) = (cursor, (cursor + 1).min(n - 1));
        let f = if times[j] > times[i] {
            ((t - times[i]) / (times[j] - times[i])).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let p: [f64; 3] = std::array::from_fn(|c| path[i][c] + (path[j][c] - path[i][c]) * f);
        let yaw = heading[i] + (heading[j] - heading[i]) * f;
        let v = speed[i] + (speed[j] - speed[i]) * f;
        samples.push((p, yaw, v));
    }
    let ground = |x: f64, y: f64, z_reference: f64| {
        world
            .ground_below(x, y, z_reference + 0.5, 30.0)
            .or_else(|| world.terrain_height(x, y))
            .unwrap_or(z_reference - 1.6)
    };
    let (mut z, mut roll, mut pitch) = (
        Vec::with_capacity(count),
        Vec::with_capacity(count),
        Vec::with_capacity(count),
    );
    for &(p, yaw, _) in &samples {
        let (c, s) = (yaw.cos(), yaw.sin());
        let at = |forward: f64, left: f64| {
            ground(p[0] + c * forward - s * left, p[1] + s * forward + c * left, p[2])
        };
        let (front, back, left, right) = (at(0.5, 0.0), at(-0.5, 0.0), at(0.0, 0.4), at(0.0, -0.4));
        z.push(ground(p[0], p[1], p[2]).max((front + back + left + right) / 4.0));
        pitch.push((back - front).atan2(1.0));
        roll.push((left - right).atan2(0.8));
    }
    // The suspension's low-pass spans the same time whatever the control spacing.
    let span = ((2.0 * CONTROL_DT_S / control_dt).round() as usize).max(1);
    let (z, roll, pitch) = match spec.profile {
        Profile::Ground | Profile::Legged | Profile::Handheld | Profile::FastTurn => {
            let mount_m = gait::mount_height_m(spec.profile, spec.mount_height_m);
            let z: Vec<f64> = smooth_scalar(&z, span).iter().map(|g| g + mount_m).collect();
            (z, smooth_scalar(&roll, span), smooth_scalar(&pitch, span))
        }
        Profile::Aerial => {
            let altitude = if world.kind() == WorldKind::Cave {
                2.2
            } else {
                10.0
            };
            let z: Vec<f64> = smooth_scalar(&z, 15).iter().map(|g| g + altitude).collect();
            let bank: Vec<f64> = (0..count)
                .map(|k| {
                    let (a, b) = (samples[k.saturating_sub(1)], samples[(k + 1).min(count - 1)]);
                    let yaw_rate = (b.1 - a.1) / (2.0 * control_dt);
                    (samples[k].2 * yaw_rate / GRAVITY_MPS2).atan()
                })
                .collect();
            let tilt: Vec<f64> = (0..count)
                .map(|k| {
                    let (a, b) = (samples[k.saturating_sub(1)].2, samples[(k + 1).min(count - 1)].2);
                    ((b - a) / (2.0 * control_dt) / GRAVITY_MPS2).atan()
                })
                .collect();
            (
                z,
                smooth_scalar(&bank, 3 * span / 2),
                smooth_scalar(&tilt, 3 * span / 2),
            )
        }
    };
    let controls = (0..count)
        .map(|k| {
            let (p, yaw, v) = samples[k];
            let body = gait::body_offset(spec.profile, k as f64 * control_dt, v / spec.speed_mps.max(1e-9));
            let (x, y) = (p[0] - yaw.sin() * body.left_m, p[1] + yaw.cos() * body.left_m);
            let rotation = UnitQuaternion::from_euler_angles(
                roll[k] + body.roll_rad,
                pitch[k] + body.pitch_rad,
                yaw + body.yaw_rad,
            );
            Pose::from_parts(Translation3::from(Vector3::new(x, y, z[k] + body.up_m)), rotation)
        })
        .collect();
    Trajectory::new(0.0, control_dt, controls)
}
