//! Options and the report shared by every point-cloud reader (KITTI `.bin`, PCD, PLY): what to do with
//! non-finite points and with `(0, 0, 0)` "no return" points, and how many of each were seen and dropped.
//!
//! Non-finite points (a NaN or infinite coordinate or intensity) are never passed through silently:
//! depending on [`NonFinitePolicy`] they are dropped and counted (the default), kept and counted (to
//! preserve the row/column structure of an organised cloud), or make the read fail with the point's
//! position in the file.

use std::path::Path;

use skid_msgs::{Point, RawPoint};

use crate::error::{IoError, Location};

/// What a cloud reader does with a point whose coordinates or intensity are NaN or infinite.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum NonFinitePolicy {
    /// Leave the point out of the result and count it in [`CloudReport::dropped_non_finite`].
    #[default]
    Drop,
    /// Keep the point (so an organised cloud keeps its `width x height` layout); it is still counted in
    /// [`CloudReport::non_finite`].
    Keep,
    /// Fail with an error naming the point index and its line or byte offset.
    Error,
}

/// Options of the point-cloud readers.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CloudReadOptions {
    /// What to do with non-finite points.
    pub non_finite: NonFinitePolicy,
    /// Drop points at exactly `(0, 0, 0)`, which many drivers write for "no return" (e.g. the
    /// organised HDL-32E scans of fast_gicp). Off by default: such points are kept and counted.
    pub drop_zero: bool,
}

impl CloudReadOptions {
    /// Keep every point, finite or not (organised clouds keep their layout); counts are still reported.
    pub const KEEP_ALL: Self = Self {
        non_finite: NonFinitePolicy::Keep,
        drop_zero: false,
    };
    /// Drop non-finite and `(0, 0, 0)` points: only real returns are left.
    pub const VALID_ONLY: Self = Self {
        non_finite: NonFinitePolicy::Drop,
        drop_zero: true,
    };
}

/// What a cloud reader saw while reading.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CloudReport {
    /// Number of points stored in the file.
    pub points_in_file: usize,
    /// Points with a NaN or infinite coordinate or intensity, whether kept or dropped.
    pub non_finite: usize,
    /// Non-finite points left out of the result ([`NonFinitePolicy::Drop`]).
    pub dropped_non_finite: usize,
    /// Finite points at exactly `(0, 0, 0)`, whether kept or dropped.
    pub zero: usize,
    /// Zero points left out of the result ([`CloudReadOptions::drop_zero`]).
    pub dropped_zero: usize,
    /// Binary data left after the points the header announces: a header that under-counts its points
    /// (readers should warn; the file was cut short by its writer or its count is wrong).
    pub unread_trailing_bytes: u64,
}

impl CloudReport {
    /// A warning when the header under-counted the points (data left unread after them).
    pub fn under_count_warning(&self, path: &Path) -> Option<String> {
        (self.unread_trailing_bytes > 0).then(|| {
            format!(
                "{}: {} bytes of point data follow the {} points its header announces; the header \
                 under-counts its points, which were not read",
                path.display(),
                self.unread_trailing_bytes,
                self.points_in_file
            )
        })
    }

    /// Number of points in the result.
    pub fn kept(&self) -> usize {
        self.points_in_file - self.dropped_non_finite - self.dropped_zero
    }
}

/// A point cloud read from a file, with the report of what was kept and dropped.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Cloud<P = Point> {
    /// The points, in file order, after the filtering asked for in [`CloudReadOptions`].
    pub points: Vec<P>,
    /// Counts of non-finite and zero points.
    pub report: CloudReport,
}

/// Applies the read options point by point and accumulates the report.
pub(crate) struct CloudFilter<'a> {
    path: &'a Path,
    options: CloudReadOptions,
    pub(crate) report: CloudReport,
}

impl<'a> CloudFilter<'a> {
    /// A filter for a file at `path` with the given options.
    pub(crate) fn new(path: &'a Path, options: CloudReadOptions) -> Self {
        Self {
            path,
            options,
            report: CloudReport::default(),
        }
    }

    /// Decides whether the point numbered `index` (0-based, found at `at`) is kept; errors under
    /// [`NonFinitePolicy::Error`].
    pub(crate) fn keep(&mut self, index: usize, point: &RawPoint, at: Location) -> Result<bool, IoError> {
        self.report.points_in_file += 1;
        if !point.is_finite() {
            self.report.non_finite += 1;
            return match self.options.non_finite {
                NonFinitePolicy::Keep => Ok(true),
                NonFinitePolicy::Drop => {
                    self.report.dropped_non_finite += 1;
                    Ok(false)
                }
                NonFinitePolicy::Error => Err(IoError::parse(
                    self.path,
                    at,
                    format!(
                        "point {index} is not finite (x={}, y={}, z={}, intensity={}, time={})",
                        point.x, point.y, point.z, point.intensity, point.time_offset_s
                    ),
                )),
            };
        }
        if point.x == 0.0 && point.y == 0.0 && point.z == 0.0 {
            self.report.zero += 1;
            if self.options.drop_zero {
                self.report.dropped_zero += 1;
                return Ok(false);
            }
        }
        Ok(true)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn filter_counts_and_drops() {
        let path = Path::new("c.pcd");
        let mut filter = CloudFilter::new(path, CloudReadOptions::VALID_ONLY);
        let nan = RawPoint::new(f32::NAN, 0.0, 0.0, 0.0, 0.0, 0);
        let zero = RawPoint::new(0.0, 0.0, 0.0, 5.0, 0.0, 0);
        let good = RawPoint::new(1.0, 0.0, 0.0, 5.0, 0.0, 0);
        assert!(!filter.keep(0, &nan, Location::Line(12)).unwrap());
        assert!(!filter.keep(1, &zero, Location::Line(13)).unwrap());
        assert!(filter.keep(2, &good, Location::Line(14)).unwrap());
        let report = filter.report;
        assert_eq!(
            (
                report.points_in_file,
                report.non_finite,
                report.zero,
                report.kept()
            ),
            (3, 1, 1, 1)
        );

        let mut strict = CloudFilter::new(
            path,
            CloudReadOptions {
                non_finite: NonFinitePolicy::Error,
                drop_zero: false,
            },
        );
        let err = strict
            .keep(7, &nan, Location::Offset(112))
            .unwrap_err()
            .to_string();
        assert!(
            err.starts_with("c.pcd: byte offset 112: point 7 is not finite"),
            "{err}"
        );
    }
}
