//! Forward kinematics: joint angles → link frames, by the standard DH product.
//!
//! The public functions return [`Pose`]s (isometries with a unit quaternion). Internally the solver
//! works on plain rotation matrices ([`Frame`]), which is cheaper per evaluation and exact in the
//! twist angles (cos/sin of α ∈ {0, ±π/2} are taken as exact 0/±1).

use crate::{Joints, Pose, UrModel};
use nalgebra::{Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};

/// sin α_i and cos α_i of the UR twist angles α = [π/2, 0, 0, π/2, −π/2, 0], exact.
const SIN_ALPHA: [f64; 6] = [1.0, 0.0, 0.0, 1.0, -1.0, 0.0];
const COS_ALPHA: [f64; 6] = [0.0, 1.0, 1.0, 0.0, 0.0, 1.0];

/// A rigid frame as a rotation matrix and a translation (internal fast path).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Frame {
    pub r: Matrix3<f64>,
    pub p: Vector3<f64>,
}

impl Frame {
    pub(crate) const IDENTITY: Frame = Frame {
        r: Matrix3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0),
        p: Vector3::new(0.0, 0.0, 0.0),
    };

    #[inline]
    pub(crate) fn mul(&self, o: &Frame) -> Frame {
        Frame { r: self.r * o.r, p: self.r * o.p + self.p }
    }

    #[inline]
    pub(crate) fn inverse(&self) -> Frame {
        let rt = self.r.transpose();
        Frame { r: rt, p: -(rt * self.p) }
    }

    pub(crate) fn to_pose(self) -> Pose {
        Pose::from_parts(
            Translation3::from(self.p),
            UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(self.r)),
        )
    }

    pub(crate) fn from_pose(p: &Pose) -> Frame {
        Frame { r: p.rotation.to_rotation_matrix().into_inner(), p: p.translation.vector }
    }
}

/// DH link `i` (0-based) transform `Rz(θ)·Tz(d)·Tx(a)·Rx(α)` in closed form.
#[inline]
pub(crate) fn dh_frame(model: &UrModel, i: usize, theta: f64) -> Frame {
    let (st, ct) = theta.sin_cos();
    let (sa, ca) = (SIN_ALPHA[i], COS_ALPHA[i]);
    let a = model.a()[i];
    let d = model.d()[i];
    Frame {
        r: Matrix3::new(ct, -st * ca, st * sa, st, ct * ca, -ct * sa, 0.0, sa, ca),
        p: Vector3::new(a * ct, a * st, d),
    }
}

/// Every DH frame (0 = Base … 6 = tool0) as matrices.
#[inline]
pub(crate) fn frames(model: &UrModel, q: &Joints) -> [Frame; 7] {
    let mut out = [Frame::IDENTITY; 7];
    for i in 0..6 {
        out[i + 1] = out[i].mul(&dh_frame(model, i, q[i]));
    }
    out
}

/// tool0 in Base as matrices.
#[inline]
pub(crate) fn fk_frame(model: &UrModel, q: &Joints) -> Frame {
    frames(model, q)[6]
}

/// Pose of tool0 (flange, zero TCP) in the Base frame.
///
/// ```
/// let t = ur3_kin::fk(&ur3_kin::UR3, &[0.0; 6]);
/// // At zero the UR3 lies stretched along −X of Base with the flange pointing along −Y.
/// assert!((t.translation.x - (-0.24365 - 0.21325)).abs() < 1e-12);
/// ```
pub fn fk(model: &UrModel, q: &Joints) -> Pose {
    fk_frame(model, q).to_pose()
}

/// Every DH frame in the Base frame: index 0 is Base itself (identity), index i (1..=6) is the
/// frame after joint i; index 6 is tool0.
pub fn fk_all(model: &UrModel, q: &Joints) -> [Pose; 7] {
    let f = frames(model, q);
    let mut out = [Pose::identity(); 7];
    for (o, fr) in out.iter_mut().zip(f.iter()).skip(1) {
        *o = fr.to_pose();
    }
    out
}

/// tool0 in Base as a homogeneous 4×4 matrix (row-major meaning, nalgebra storage).
pub fn fk_matrix(model: &UrModel, q: &Joints) -> nalgebra::Matrix4<f64> {
    let f = fk_frame(model, q);
    let mut m = nalgebra::Matrix4::identity();
    m.fixed_view_mut::<3, 3>(0, 0).copy_from(&f.r);
    m.fixed_view_mut::<3, 1>(0, 3).copy_from(&f.p);
    m
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

    #[test]
    #[allow(clippy::needless_range_loop)]
    fn matrix_fk_equals_generic_dh_product() {
        // Independent path: the textbook DH product with α taken through sin/cos.
        let q: crate::Joints = [0.3, -1.1, 0.7, 2.0, -0.4, 1.3];
        for m in crate::MODELS {
            let mut t = nalgebra::Matrix4::<f64>::identity();
            for i in 0..6 {
                let (st, ct) = q[i].sin_cos();
                let (sa, ca) = crate::model::ALPHA[i].sin_cos();
                let (a, d) = (m.a()[i], m.d()[i]);
                #[rustfmt::skip]
                let li = nalgebra::Matrix4::new(
                    ct, -st * ca, st * sa, a * ct,
                    st, ct * ca, -ct * sa, a * st,
                    0.0, sa, ca, d,
                    0.0, 0.0, 0.0, 1.0);
                t *= li;
            }
            let f = fk_matrix(&m, &q);
            assert!((f - t).abs().max() < 1e-14, "{}", m.name);
            let p = fk(&m, &q).to_homogeneous();
            assert!((p - t).abs().max() < 1e-14, "{}", m.name);
        }
    }
}
