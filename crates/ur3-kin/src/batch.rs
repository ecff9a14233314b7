//! Many configurations, targets or hand frames in one call, with the per-row failure policy the
//! bindings expose: a row that cannot be solved (unreachable, not converged, not a rigid
//! transform, degenerate hand) is an `Err` in its slot and never stops the other rows.

use crate::{
    Calibration, HandPoints, Handedness, IkOptions, Joints, KinError, Pose, UrModel, fk, ik_batch,
    pose_from_matrix,
};
use nalgebra::{Matrix4, Vector3};

/// [`fk`] of every configuration.
pub fn fk_batch(model: &UrModel, qs: &[Joints]) -> Vec<Pose> {
    qs.iter().map(|q| fk(model, q)).collect()
}

/// [`ik_batch`] on homogeneous matrices: a matrix that is not a rigid transform fails its own
/// row (the error of [`pose_from_matrix`]) like an unreachable target.
///
/// # Errors
/// [`KinError::NonFinite`] when a seed holds a NaN or an infinity (the whole call: a bad seed
/// is the caller's mistake, not a property of one target).
pub fn ik_batch_matrices(
    model: &UrModel,
    targets: &[Matrix4<f64>],
    seeds: Option<&[Joints]>,
    opts: &IkOptions,
    threads: usize,
) -> Result<Vec<Result<Joints, KinError>>, KinError> {
    if seeds.is_some_and(|s| s.iter().flatten().any(|x| !x.is_finite())) {
        return Err(KinError::NonFinite("seeds"));
    }
    let poses: Vec<Result<Pose, KinError>> = targets.iter().map(pose_from_matrix).collect();
    let valid: Vec<Pose> = poses.iter().map(|p| p.clone().unwrap_or_else(|_| Pose::identity())).collect();
    let solved = ik_batch(model, &valid, seeds, opts, threads);
    Ok(poses.into_iter().zip(solved).map(|(p, s)| p.and(s)).collect())
}

/// [`crate::hand_to_target`] of every frame; a degenerate or non-finite frame fails its own row.
pub fn hand_to_target_batch(
    hands: &[HandPoints],
    handedness: Handedness,
    calib: &Calibration,
) -> Vec<Result<Pose, KinError>> {
    hands.iter().map(|h| crate::hand_to_target(h, handedness, calib)).collect()
}

/// A batch's per-row results as the bindings return them: every row's value (`fill` for a
/// failed row) and whether it succeeded.
pub fn split_failures<T: Clone>(rows: &[Result<T, KinError>], fill: T) -> (Vec<T>, Vec<bool>) {
    rows.iter().map(|r| r.as_ref().map_or((fill.clone(), false), |v| (v.clone(), true))).unzip()
}

impl Calibration {
    /// [`Calibration::point_to_base`] of every point.
    pub fn points_to_base(&self, points: &[Vector3<f64>]) -> Vec<Vector3<f64>> {
        points.iter().map(|p| self.point_to_base(p)).collect()
    }
}
