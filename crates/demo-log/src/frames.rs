//! The frames a demo's scene is drawn in: the URDF links at given joint angles, the object frame
//! [`TILE_FRAME`] and a row's object frames [`ROW_FRAMES`], the transforms `/tf` publishes,
//! composed from `base`. The scene itself
//! is the caller's ([`crate::EpisodeMeta::scene`]; the simulator's, turned into entities by
//! teleop-core's `scene` module): demo-log records what it is handed.

use crate::DemoError;
use crate::writer::{Pose, ROW_FRAMES, TILE_FRAME};
use std::collections::BTreeMap;
use ur3_kin::UrModel;

/// Pose in `base` of every frame the scene's entities are locked to, at joint angles `joints`
/// with the object at `tile_pose` and a row's objects at `row` (empty for one object): the URDF
/// links (`shoulder_link` … `tool0`), then [`TILE_FRAME`], then [`ROW_FRAMES`] (as many as
/// `row` has, at most all of them). The same transforms `/tf` publishes, composed from `base`.
pub fn frame_poses(
    model: &UrModel,
    joints: &[f64; 6],
    tile_pose: &Pose,
    row: &[Pose],
) -> Vec<(&'static str, Pose)> {
    let mut v: Vec<(&'static str, Pose)> = ur3_kin::urdf::link_poses(model, joints)
        .into_iter()
        .map(|(name, p)| (name, Pose::from_isometry(&p)))
        .collect();
    v.push((TILE_FRAME, *tile_pose));
    v.extend(ROW_FRAMES.into_iter().zip(row.iter().copied()));
    v
}

/// The robot model named `name` (`ur3_kin::UrModel::by_name`).
fn model(name: &str) -> Result<&'static UrModel, DemoError> {
    UrModel::by_name(name).map_err(|e| DemoError::Invalid(e.to_string()))
}

/// [`frame_poses`] of the model named `model_name` as `{frame: [x, y, z, qx, qy, qz, qw]}`.
///
/// # Errors
/// [`DemoError::Invalid`] for an unknown model or a row longer than [`ROW_FRAMES`].
pub fn frame_numbers(
    model_name: &str,
    joints: &[f64; 6],
    tile_pose: &Pose,
    row: &[Pose],
) -> Result<BTreeMap<&'static str, [f64; 7]>, DemoError> {
    if row.len() > ROW_FRAMES.len() {
        return Err(DemoError::Invalid(format!(
            "{} row objects, a demo has frames for at most {}",
            row.len(),
            ROW_FRAMES.len()
        )));
    }
    let poses = frame_poses(model(model_name)?, joints, tile_pose, row);
    Ok(poses.into_iter().map(|(k, p)| (k, p.to_numbers())).collect())
}
