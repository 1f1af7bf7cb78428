//! Point types: the processed point every stage uses, the raw scan point a sensor delivers, and IMU samples.

#[cfg(feature = "ipc")]
use iceoryx2::prelude::ZeroCopySend;

use crate::wire_type;

/// A 3D point with intensity, in metres, 16-byte aligned so four of them fill a cache line exactly.
#[repr(C)]
#[repr(align(16))]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "ipc", derive(ZeroCopySend))]
#[cfg_attr(feature = "ipc", type_name("skid/Point@1"))]
pub struct Point {
    pub x: f32,
    pub y: f32,
    pub z: f32,
    pub intensity: f32,
}
wire_type!(Point, "skid/Point@1");

impl Point {
    /// A point at `(x, y, z)` with zero intensity.
    pub const fn new(x: f32, y: f32, z: f32) -> Self {
        Self {
            x,
            y,
            z,
            intensity: 0.0,
        }
    }

    /// A point at `(x, y, z)` with the given intensity.
    pub const fn with_intensity(x: f32, y: f32, z: f32, intensity: f32) -> Self {
        Self { x, y, z, intensity }
    }

    /// The coordinates as an array.
    pub const fn xyz(&self) -> [f32; 3] {
        [self.x, self.y, self.z]
    }

    /// True when every coordinate and the intensity are finite (no NaN, no infinity).
    pub fn is_finite(&self) -> bool {
        self.x.is_finite() && self.y.is_finite() && self.z.is_finite() && self.intensity.is_finite()
    }

    /// Euclidean distance from the origin of the point's frame, in metres.
    pub fn range_m(&self) -> f32 {
        (self.x * self.x + self.y * self.y + self.z * self.z).sqrt()
    }
}

/// A point as the sensor delivers it: position, intensity, the time offset of its firing within the
/// sweep (seconds from the scan stamp, used for deskewing) and the laser ring that produced it.
#[repr(C)]
#[repr(align(16))]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "ipc", derive(ZeroCopySend))]
#[cfg_attr(feature = "ipc", type_name("skid/RawPoint@1"))]
pub struct RawPoint {
    pub x: f32,
    pub y: f32,
    pub z: f32,
    pub intensity: f32,
    /// Seconds after the scan stamp at which this point was measured.
    pub time_offset_s: f32,
    /// Index of the laser (beam) that fired, 0 = lowest elevation; `u16::MAX` when unknown.
    pub ring: u16,
    /// Explicit padding so the layout has no uninitialised bytes.
    pub reserved: [u8; 10],
}
wire_type!(RawPoint, "skid/RawPoint@1");

impl RawPoint {
    /// The ring value meaning "this sensor does not report rings".
    pub const UNKNOWN_RING: u16 = u16::MAX;

    /// A raw point with every field given.
    pub const fn new(x: f32, y: f32, z: f32, intensity: f32, time_offset_s: f32, ring: u16) -> Self {
        Self {
            x,
            y,
            z,
            intensity,
            time_offset_s,
            ring,
            reserved: [0; 10],
        }
    }

    /// The processed point, dropping the timing and ring.
    pub const fn point(&self) -> Point {
        Point::with_intensity(self.x, self.y, self.z, self.intensity)
    }

    /// True when the position, intensity and time offset are all finite.
    pub fn is_finite(&self) -> bool {
        self.point().is_finite() && self.time_offset_s.is_finite()
    }
}

/// One IMU sample in the IMU (= sensor) frame: specific force in m/s² and angular rate in rad/s.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "ipc", derive(ZeroCopySend))]
#[cfg_attr(feature = "ipc", type_name("skid/ImuSample@1"))]
pub struct ImuSample {
    pub stamp_nanos: u64,
    pub accel_mps2: [f64; 3],
    pub gyro_radps: [f64; 3],
}
wire_type!(ImuSample, "skid/ImuSample@1");

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layouts_are_fixed() {
        assert_eq!(std::mem::size_of::<Point>(), 16);
        assert_eq!(std::mem::align_of::<Point>(), 16);
        assert_eq!(std::mem::size_of::<RawPoint>(), 32);
        assert_eq!(std::mem::align_of::<RawPoint>(), 16);
        assert_eq!(std::mem::size_of::<ImuSample>(), 56);
    }

    #[test]
    fn finiteness_checks_every_field() {
        assert!(Point::new(1.0, 2.0, 3.0).is_finite());
        assert!(!Point::new(f32::NAN, 2.0, 3.0).is_finite());
        assert!(!Point::with_intensity(1.0, 2.0, 3.0, f32::INFINITY).is_finite());
        assert!(!RawPoint::new(1.0, 2.0, 3.0, 0.0, f32::NAN, 0).is_finite());
        assert_eq!(Point::new(3.0, 4.0, 0.0).range_m(), 5.0);
    }
}
