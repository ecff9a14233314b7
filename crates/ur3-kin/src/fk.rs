//! Forward kinematics: joint angles → link frames, by the standard DH product.

use crate::model::ALPHA;
use crate::{Joints, Pose, UrModel};
use nalgebra::{Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};

/// One DH link transform `Rz(θ)·Tz(d)·Tx(a)·Rx(α)`, written out in closed form.
#[inline]
fn dh_link(theta: f64, d: f64, a: f64, alpha: f64) -> Pose {
    let (st, ct) = theta.sin_cos();
    let (sa, ca) = alpha.sin_cos();
    let r = Matrix3::new(ct, -st * ca, st * sa, st, ct * ca, -ct * sa, 0.0, sa, ca);
    let t = Vector3::new(a * ct, a * st, d);
    Pose::from_parts(
        Translation3::from(t),
        UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r)),
    )
}

/// Pose of tool0 (flange, zero TCP) in the Base frame.
///
/// ```
/// let t = ur3_kin::fk(&ur3_kin::UR3, &[0.0; 6]);
/// // At zero the UR3 lies stretched along −X of Base with the flange pointing along −Y.
/// assert!((t.translation.x - (-0.24365 - 0.21325)).abs() < 1e-12);
/// ```
pub fn fk(model: &UrModel, q: &Joints) -> Pose {
    fk_all(model, q)[6]
}

/// Every DH frame in the Base frame: index 0 is Base itself (identity), index i (1..=6) is the
/// frame after joint i; index 6 is tool0.
pub fn fk_all(model: &UrModel, q: &Joints) -> [Pose; 7] {
    let a = model.a();
    let d = model.d();
    let mut out = [Pose::identity(); 7];
    for i in 0..6 {
        out[i + 1] = out[i] * dh_link(q[i], d[i], a[i], ALPHA[i]);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::UR3;

    #[test]
    fn ur3_zero_pose_matches_published_geometry() {
        // Zero pose: upper arm and forearm along −X, tool0 at
        // (a2 + a3, −(d4 + d6), d1 − d5) with the flange's Z axis pointing along −Y.
        let t = fk(&UR3, &[0.0; 6]);
        let p = t.translation.vector;
        assert!((p.x - (-0.24365 - 0.21325)).abs() < 1e-12);
        assert!((p.y - (-(0.11235 + 0.0819))).abs() < 1e-12);
        assert!((p.z - (0.1519 - 0.08535)).abs() < 1e-12);
        let z = t.rotation * Vector3::z();
        assert!((z - Vector3::new(0.0, -1.0, 0.0)).norm() < 1e-12);
    }
}
