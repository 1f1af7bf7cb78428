//! Body motion on top of a ground path for the carriers whose motion LiDAR-only odometry struggles with:
//! a trotting quadruped (the paper's Unitree GO-2), a handheld sensor carried by a walking person, and a
//! base that swings its heading fast. Each is a sum of periodic terms scaled by how fast the carrier
//! moves (so it stands still when stopped, which the static IMU initialisation needs):
//!
//! - legged: a trot at 2.5 Hz — body bounce of ±2.5 cm, pitch ±5° at the step rate, roll ±5° at half of
//!   it (the diagonal pairs), and a 1 cm dip of 30 ms at each foot strike (the jolt an IMU feels);
//! - handheld: a walk at 2 Hz steps — bob of ±3 cm, sideways sway of ±3 cm and roll ±3° at the stride rate
//!   (1 Hz), pitch ±4° at the step rate, and the carrier looking around, ±8° of yaw at 0.4 Hz;
//! - fast turn: the heading swings ±30° at 0.7 Hz, peaking at 132°/s.
//!
//! Figures for the gait follow the locomotion literature for dogs and small quadrupeds (trot
//! 2–3 Hz) and human walking (step frequency about 2 Hz, vertical excursion about 3–5 cm).

use std::f64::consts::TAU;

use serde::{Deserialize, Serialize};

/// The carrier: a ground vehicle, a multirotor, a trotting quadruped, a person carrying the sensor, or a
/// ground base swinging its heading fast; the last three move their body as this module describes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Profile {
    #[default]
    Ground,
    Aerial,
    Legged,
    Handheld,
    FastTurn,
}

/// Offsets added to a control pose: height and sideways shift in metres, roll, pitch and yaw in radians.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BodyOffset {
    pub up_m: f64,
    pub left_m: f64,
    pub roll_rad: f64,
    pub pitch_rad: f64,
    pub yaw_rad: f64,
}

/// Control-pose spacing that resolves the profile's fastest motion (a foot strike lasts 30 ms).
pub fn control_dt_s(profile: Profile, default_s: f64) -> f64 {
    match profile {
        Profile::Legged => 0.01,
        Profile::Handheld | Profile::FastTurn => 0.02,
        Profile::Ground | Profile::Aerial => default_s,
    }
}

/// Height above the ground of the sensor for each carrier, in metres.
pub fn mount_height_m(profile: Profile, ground_default_m: f64) -> f64 {
    match profile {
        Profile::Legged => 0.45,
        Profile::Handheld => 1.3,
        _ => ground_default_m,
    }
}

/// The body offset at time `t_s` for a carrier moving at `moving` (0 standing, 1 at cruise speed).
pub fn body_offset(profile: Profile, t_s: f64, moving: f64) -> BodyOffset {
    let m = moving.clamp(0.0, 1.0);
    let wave = |hz: f64, phase: f64| (TAU * hz * t_s + phase).sin();
    match profile {
        Profile::Legged => {
            let step_hz = 2.5;
            // Distance in seconds to the nearest foot strike.
            let period = 1.0 / step_hz;
            let phase = (t_s + 0.5 * period).rem_euclid(period) - 0.5 * period;
            let jolt = (-(phase / 0.03).powi(2)).exp();
            BodyOffset {
                up_m: m * (0.025 * wave(step_hz, 0.0) - 0.01 * jolt),
                left_m: 0.0,
                roll_rad: m * 5f64.to_radians() * wave(0.5 * step_hz, 0.0),
                pitch_rad: m * 5f64.to_radians() * wave(step_hz, TAU / 6.0),
                yaw_rad: 0.0,
            }
        }
        Profile::Handheld => BodyOffset {
            up_m: m * 0.03 * wave(2.0, 0.0),
            left_m: m * 0.03 * wave(1.0, 0.0),
            roll_rad: m * 3f64.to_radians() * wave(1.0, 0.3),
            pitch_rad: m * 4f64.to_radians() * wave(2.0, 0.5),
            yaw_rad: m * 8f64.to_radians() * wave(0.4, 0.0),
        },
        Profile::FastTurn => BodyOffset {
            yaw_rad: m * 30f64.to_radians() * wave(0.7, 0.0),
            ..BodyOffset::default()
        },
        Profile::Ground | Profile::Aerial => BodyOffset::default(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn carriers_stand_still_when_stopped_and_the_fast_turn_peaks_above_120_deg_per_s() {
        for profile in [Profile::Legged, Profile::Handheld, Profile::FastTurn] {
            assert_eq!(
                body_offset(profile, 1.234, 0.0),
                BodyOffset::default(),
                "{profile:?}"
            );
        }
        let dt = 1e-4;
        let peak_deg_per_s = (0..20_000)
            .map(|i| {
                let t = i as f64 * dt;
                let a = body_offset(Profile::FastTurn, t, 1.0).yaw_rad;
                let b = body_offset(Profile::FastTurn, t + dt, 1.0).yaw_rad;
                ((b - a) / dt).abs().to_degrees()
            })
            .fold(0.0, f64::max);
        assert!(peak_deg_per_s >= 120.0, "{peak_deg_per_s}");
        // The legged body bounces and rolls by the stated amounts.
        let legged: Vec<BodyOffset> = (0..2000)
            .map(|i| body_offset(Profile::Legged, i as f64 * 1e-3, 1.0))
            .collect();
        let max_roll = legged
            .iter()
            .map(|o| o.roll_rad.abs())
            .fold(0.0, f64::max)
            .to_degrees();
        assert!((max_roll - 5.0).abs() < 0.1, "{max_roll}");
    }
}
