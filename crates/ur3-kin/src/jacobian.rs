//! The geometric Jacobian at tool0, in the Base frame.

use crate::fk::{Frame, frames};
use crate::{Joints, UrModel};
use nalgebra::{Matrix6, Vector3};

/// Geometric Jacobian of tool0 in the Base frame: rows 0..3 are the linear velocity of the tool0
/// origin (m/s per rad/s), rows 3..6 the angular velocity (rad/s per rad/s); column `i` belongs to
/// joint `i + 1`: `[z_i × (p_tool0 − p_i); z_i]` with `z_i`, `p_i` the axis and origin of DH
/// frame `i`.
pub fn jacobian(model: &UrModel, q: &Joints) -> Matrix6<f64> {
    jacobian_from_frames(&frames(model, q))
}

#[inline]
pub(crate) fn jacobian_from_frames(f: &[Frame; 7]) -> Matrix6<f64> {
    let pe = f[6].p;
    let mut j = Matrix6::zeros();
    for i in 0..6 {
        let z: Vector3<f64> = f[i].r.column(2).into_owned();
        let v = z.cross(&(pe - f[i].p));
        j[(0, i)] = v.x;
        j[(1, i)] = v.y;
        j[(2, i)] = v.z;
        j[(3, i)] = z.x;
        j[(4, i)] = z.y;
        j[(5, i)] = z.z;
    }
    j
}
