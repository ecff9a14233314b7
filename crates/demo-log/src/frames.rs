//! The frames a demo's scene is drawn in: the URDF links at given joint angles and the object
//! frame [`TILE_FRAME`], the transforms `/tf` publishes, composed from `base`. The scene itself
//! is the caller's ([`crate::EpisodeMeta::scene`]; the simulator's, turned into entities by
//! teleop-core's `scene` module): demo-log records what it is handed.

use crate::DemoError;
use crate::writer::{Pose, TILE_FRAME};
use std::collections::BTreeMap;
use ur3_kin::UrModel;

/// Pose in `base` of every frame the scene's entities are locked to, at joint angles `joints`
/// with the object at `tile_pose`: the URDF links (`shoulder_link` … `tool0`), then
/// [`TILE_FRAME`]. The same transforms `/tf` publishes, composed from `base`.
pub fn frame_poses(model: &UrModel, joints: &[f64; 6], tile_pose: &Pose) -> Vec<(&'static str, Pose)> {
    let mut v: Vec<(&'static str, Pose)> = ur3_kin::urdf::link_poses(model, joints)
        .into_iter()
        .map(|(name, p)| (name, Pose::from_isometry(&p)))
        .collect();
    v.push((TILE_FRAME, *tile_pose));
    v
}

/// The robot model named `name` (`ur3_kin::UrModel::by_name`).
fn model(name: &str) -> Result<&'static UrModel, DemoError> {
    UrModel::by_name(name).map_err(|e| DemoError::Invalid(e.to_string()))
}

/// [`frame_poses`] of the model named `model_name` as `{frame: [x, y, z, qx, qy, qz, qw]}`.
///
/// # Errors
/// [`DemoError::Invalid`] for an unknown model.
pub fn frame_numbers(
    model_name: &str,
    joints: &[f64; 6],
    tile_pose: &Pose,
) -> Result<BTreeMap<&'static str, [f64; 7]>, DemoError> {
    let poses = frame_poses(model(model_name)?, joints, tile_pose);
    Ok(poses.into_iter().map(|(k, p)| (k, p.to_numbers())).collect())
}
