//! Conversions between the ABI's row-major 4×4 transforms and nalgebra isometries (feature `nalgebra`,
//! on with `host`): the host converts every pose that crosses, and a Rust plugin built on nalgebra can
//! use the same functions.

use nalgebra::{Isometry3, Matrix3, Matrix4, Rotation3, Translation3, UnitQuaternion};

use crate::ffi::AbiTransform;

/// Rotation blocks further than this from orthonormal (largest entry of `RᵀR − I`) are refused.
const ORTHONORMAL_TOLERANCE: f64 = 1e-6;

/// The transform as the ABI carries it.
pub fn abi_from_pose(pose: &Isometry3<f64>) -> AbiTransform {
    let homogeneous = pose.to_homogeneous();
    let mut matrix = [0.0; 16];
    for row in 0..4 {
        for column in 0..4 {
            matrix[row * 4 + column] = homogeneous[(row, column)];
        }
    }
    AbiTransform { matrix }
}

/// The pose a plugin returned, or why it is not a rigid motion.
pub fn pose_from_abi(transform: &AbiTransform) -> Result<Isometry3<f64>, String> {
    if transform.matrix.iter().any(|value| !value.is_finite()) {
        return Err(format!(
            "the transform has non-finite entries: {:?}",
            transform.matrix
        ));
    }
    let matrix = Matrix4::from_row_slice(&transform.matrix);
    let last_row = [matrix[(3, 0)], matrix[(3, 1)], matrix[(3, 2)], matrix[(3, 3)]];
    if last_row != [0.0, 0.0, 0.0, 1.0] {
        return Err(format!(
            "the transform's last row is {last_row:?}, not [0, 0, 0, 1]"
        ));
    }
    let rotation: Matrix3<f64> = matrix.fixed_view::<3, 3>(0, 0).into_owned();
    let deviation = (rotation.transpose() * rotation - Matrix3::identity())
        .abs()
        .max();
    if deviation > ORTHONORMAL_TOLERANCE || rotation.determinant() <= 0.0 {
        return Err(format!(
            "the transform's rotation block is not a rotation (RᵀR − I off by {deviation:.2e}, det {:.3})",
            rotation.determinant()
        ));
    }
    let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(rotation));
    let translation = Translation3::new(matrix[(0, 3)], matrix[(1, 3)], matrix[(2, 3)]);
    Ok(Isometry3::from_parts(translation, rotation))
}

#[cfg(test)]
mod tests {
    use super::*;

    type Pose = Isometry3<f64>;

    #[test]
    fn poses_round_trip_and_non_rigid_matrices_are_refused() {
        let pose = Pose::new(
            nalgebra::Vector3::new(1.0, -2.0, 0.5),
            nalgebra::Vector3::new(0.1, 0.2, -0.3),
        );
        let back = pose_from_abi(&abi_from_pose(&pose)).unwrap();
        assert!((back.to_homogeneous() - pose.to_homogeneous()).abs().max() < 1e-12);
        let mut scaled = abi_from_pose(&pose);
        scaled.matrix[0] *= 2.0;
        assert!(pose_from_abi(&scaled).unwrap_err().contains("not a rotation"));
        let mut nan = AbiTransform::IDENTITY;
        nan.matrix[3] = f64::NAN;
        assert!(pose_from_abi(&nan).unwrap_err().contains("non-finite"));
        let mut skewed = AbiTransform::IDENTITY;
        skewed.matrix[12] = 0.5;
        assert!(pose_from_abi(&skewed).unwrap_err().contains("last row"));
        let mut mirrored = AbiTransform::IDENTITY;
        mirrored.matrix[0] = -1.0;
        assert!(pose_from_abi(&mirrored).unwrap_err().contains("not a rotation"));
    }
}
