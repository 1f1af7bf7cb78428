//! Fast single-precision arctangents for binning points by azimuth and elevation (SOLiD, Kim et al., RA-L
//! 2024, bins every point by both angles, so the library `atan2f` would dominate extraction time).
//!
//! The polynomial is a minimax fit of atan on [0, 1] with range reduction; its error is below 2e-5 rad
//! (0.001°), far below any bin width the descriptor uses (0.1° at the very least), so only points within
//! that margin of a bin edge can fall on the other side of it.

use std::f32::consts::{FRAC_PI_2, PI};

/// atan(x) for x in [0, 1].
#[inline]
fn atan_unit(x: f32) -> f32 {
    let x2 = x * x;
    x * (0.999_977_26
        + x2 * (-0.332_623_47
            + x2 * (0.193_543_46 + x2 * (-0.116_432_87 + x2 * (0.052_653_32 - x2 * 0.011_721_2)))))
}

/// atan2(y, x) in (−π, π]; 0 for the origin.
#[inline]
pub fn atan2_fast(y: f32, x: f32) -> f32 {
    let (ax, ay) = (x.abs(), y.abs());
    let (small, large) = if ay > ax { (ax, ay) } else { (ay, ax) };
    if large == 0.0 {
        return 0.0;
    }
    let mut angle = atan_unit(small / large);
    if ay > ax {
        angle = FRAC_PI_2 - angle;
    }
    if x < 0.0 {
        angle = PI - angle;
    }
    if y < 0.0 { -angle } else { angle }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_the_library_atan2() {
        let mut worst = 0.0f32;
        for i in 0..20_000 {
            let t = i as f32 * 0.000_314_2;
            for radius in [0.01f32, 1.0, 75.0] {
                let (y, x) = (
                    (t * 1.3).sin() * radius * (1.0 + (t * 7.0).cos()),
                    (t * 1.3).cos() * radius,
                );
                worst = worst.max((atan2_fast(y, x) - y.atan2(x)).abs());
            }
        }
        assert!(worst < 2e-5, "worst error {worst} rad");
    }

    #[test]
    fn axes_and_origin() {
        assert_eq!(atan2_fast(0.0, 0.0), 0.0);
        assert_eq!(atan2_fast(0.0, 2.0), 0.0);
        assert!((atan2_fast(3.0, 0.0) - FRAC_PI_2).abs() < 1e-6);
        assert!((atan2_fast(0.0, -1.0) - PI).abs() < 1e-6);
        assert!((atan2_fast(-1.0, 0.0) + FRAC_PI_2).abs() < 1e-6);
    }
}
