//! Small geometry helpers shared by the readers: turning a nearly-orthonormal 3x3 matrix read from text
//! into an exact rotation, and building isometries from the numbers a file stores.

use nalgebra::{Isometry3, Matrix3, Quaternion, Rotation3, Translation3, UnitQuaternion};

/// The largest Frobenius distance between a stored rotation matrix and the nearest rotation that is
/// still accepted (and silently corrected). Text files with 6-7 significant digits are around 1e-6 off;
/// anything beyond this bound is not a rotation with rounding noise but a wrong matrix.
pub const MAX_ROTATION_DEVIATION: f64 = 1e-2;

/// The rotation nearest to `m` in the Frobenius norm (the orthogonal polar factor, from the SVD
/// `m = U S V^T` as `U V^T`), with the distance `||m - R||_F`.
///
/// Fails (with a sentence saying why) when `m` is not finite, is a reflection (negative determinant) or
/// is further than [`MAX_ROTATION_DEVIATION`] from every rotation.
pub fn nearest_rotation(m: &Matrix3<f64>) -> Result<(Rotation3<f64>, f64), String> {
    if m.iter().any(|v| !v.is_finite()) {
        return Err("rotation matrix has a non-finite entry".to_owned());
    }
    let determinant = m.determinant();
    if determinant <= 0.0 {
        return Err(format!(
            "rotation matrix has determinant {determinant} (must be +1)"
        ));
    }
    let svd = m.svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Err("SVD of the rotation matrix failed".to_owned());
    };
    let mut rotation = u * v_t;
    if rotation.determinant() < 0.0 {
        let mut u_flipped = u;
        u_flipped.column_mut(2).neg_mut();
        rotation = u_flipped * v_t;
    }
    let deviation = (m - rotation).norm();
    if deviation > MAX_ROTATION_DEVIATION {
        return Err(format!(
            "matrix is {deviation:.3e} (Frobenius) away from the nearest rotation, more than the \
             {MAX_ROTATION_DEVIATION:e} accepted as rounding"
        ));
    }
    Ok((Rotation3::from_matrix_unchecked(rotation), deviation))
}

/// The isometry of a row-major 3x4 `[R | t]` (12 numbers), with `R` re-orthonormalised by
/// [`nearest_rotation`].
pub fn isometry_from_3x4(values: &[f64; 12]) -> Result<Isometry3<f64>, String> {
    let m = Matrix3::new(
        values[0], values[1], values[2], values[4], values[5], values[6], values[8], values[9], values[10],
    );
    let (rotation, _) = nearest_rotation(&m)?;
    Ok(Isometry3::from_parts(
        Translation3::new(values[3], values[7], values[11]),
        UnitQuaternion::from_rotation_matrix(&rotation),
    ))
}

/// The isometry of a row-major 4x4 homogeneous transform (16 numbers) whose last row is `0 0 0 1`, with
/// `R` re-orthonormalised by [`nearest_rotation`].
pub fn isometry_from_4x4(values: &[f64; 16]) -> Result<Isometry3<f64>, String> {
    let last_row = &values[12..16];
    if last_row
        .iter()
        .zip([0.0, 0.0, 0.0, 1.0])
        .any(|(v, e)| (v - e).abs() > 1e-9)
    {
        return Err(format!(
            "the last row of a transform must be 0 0 0 1, found {last_row:?}"
        ));
    }
    let mut upper = [0.0; 12];
    upper.copy_from_slice(&values[..12]);
    isometry_from_3x4(&upper)
}

/// The row-major 3x4 `[R | t]` of an isometry.
pub fn isometry_to_3x4(pose: &Isometry3<f64>) -> [f64; 12] {
    let r = pose.rotation.to_rotation_matrix();
    let r = r.matrix();
    let t = &pose.translation.vector;
    [
        r[(0, 0)],
        r[(0, 1)],
        r[(0, 2)],
        t.x,
        r[(1, 0)],
        r[(1, 1)],
        r[(1, 2)],
        t.y,
        r[(2, 0)],
        r[(2, 1)],
        r[(2, 2)],
        t.z,
    ]
}

/// The unit quaternion of `(qx, qy, qz, qw)`, normalised; fails for a (near-)zero quaternion.
pub fn unit_quaternion(qx: f64, qy: f64, qz: f64, qw: f64) -> Result<UnitQuaternion<f64>, String> {
    let q = Quaternion::new(qw, qx, qy, qz);
    let norm = q.norm();
    if norm.is_nan() || norm <= 1e-9 {
        return Err(format!(
            "quaternion ({qx}, {qy}, {qz}, {qw}) has norm {norm}, cannot be normalised"
        ));
    }
    Ok(UnitQuaternion::new_normalize(q))
}

/// The isometry of a translation and a `(qx, qy, qz, qw)` quaternion (normalised).
pub fn isometry_from_xyz_quat(t: [f64; 3], q: [f64; 4]) -> Result<Isometry3<f64>, String> {
    let rotation = unit_quaternion(q[0], q[1], q[2], q[3])?;
    Ok(Isometry3::from_parts(
        Translation3::new(t[0], t[1], t[2]),
        rotation,
    ))
}

/// The translation and `(qx, qy, qz, qw)` quaternion of an isometry.
pub fn isometry_to_xyz_quat(pose: &Isometry3<f64>) -> ([f64; 3], [f64; 4]) {
    let t = &pose.translation.vector;
    let q = pose.rotation.quaternion();
    ([t.x, t.y, t.z], [q.i, q.j, q.k, q.w])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_rotation_fixes_rounding_and_rejects_garbage() {
        let exact = Rotation3::from_euler_angles(0.1, -0.2, 0.3);
        let noisy = exact.matrix() + Matrix3::from_element(1e-7);
        let (fixed, deviation) = nearest_rotation(&noisy).unwrap();
        assert!(deviation < 1e-6);
        assert!((fixed.matrix() - exact.matrix()).norm() < 1e-6);
        assert!((fixed.matrix().transpose() * fixed.matrix() - Matrix3::identity()).norm() < 1e-14);
        assert!(nearest_rotation(&(Matrix3::identity() * 2.0)).is_err());
        assert!(nearest_rotation(&-Matrix3::<f64>::identity()).is_err());
    }

    #[test]
    fn three_by_four_round_trip() {
        let pose = Isometry3::new(
            nalgebra::Vector3::new(1.0, -2.0, 3.5),
            nalgebra::Vector3::new(0.3, 0.2, -0.1),
        );
        let back = isometry_from_3x4(&isometry_to_3x4(&pose)).unwrap();
        assert!((back.to_homogeneous() - pose.to_homogeneous()).norm() < 1e-14);
        assert!(unit_quaternion(0.0, 0.0, 0.0, 0.0).is_err());
    }
}
