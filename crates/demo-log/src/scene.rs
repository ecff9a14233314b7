//! The complete scene of a demo, from one place: the robot (for the UR3, tile-sim's arm capsules
//! locked to the URDF links; other models, cylinders between the links' origins), and the task's
//! table, pad, target, end effector (locked to `tool0`) and object (locked to [`TILE_FRAME`])
//! taken from tile-sim's geometry. The writer publishes it on `/scene` with the
//! first step of every demo; the bindings hand the same entities, as Foxglove `SceneEntity` JSON,
//! to anything else that draws the scene (the live server).

use crate::DemoError;
use crate::writer::{
    BASE_FRAME, Pose, Primitive, SceneEntity, Shape, TILE_FRAME, foxglove_entity, robot_link_entities,
};
use serde_json::Value;
use std::collections::BTreeMap;
use tile_sim::{SceneFrame, Task};
use ur3_kin::UrModel;
use ur3_kin::nalgebra::{Point3, UnitQuaternion, Vector3};

/// An `f32` constant as the decimal it was written as (0.075, not 0.07500000298023224).
fn dec(x: f32) -> f64 {
    format!("{x}").parse().unwrap_or(x as f64)
}

/// tile-sim's scene of episode `seed` of `task` as demo entities (no arm: the robot is drawn by
/// [`robot_entities`]). Frames: tile-sim's world → `base`, its tool frame → `tool0`, its
/// object → [`TILE_FRAME`] (the object frame of every task: tile, block or nut). Ids are the
/// items' names, numbered when a name repeats (`cup_0` … `cup_3`).
pub fn task_scene(task: Task, seed: u64) -> Vec<SceneEntity> {
    task_scene_at(task, &tile_sim::Variation::default().start(task, seed))
}

/// [`task_scene`] of an episode that began at `start` (its pad, target and plate where it put them).
pub fn task_scene_at(task: Task, start: &tile_sim::Start) -> Vec<SceneEntity> {
    let scene = tile_sim::world::scene(task, start);
    let count = |n: &str| scene.items.iter().filter(|i| i.name == n).count();
    let mut seen = std::collections::BTreeMap::<&str, usize>::new();
    let mut out = Vec::new();
    for it in &scene.items {
        let frame_id = match it.frame {
            SceneFrame::World => BASE_FRAME,
            SceneFrame::Link(6) => "tool0",
            SceneFrame::Link(_) => continue,
            SceneFrame::Object => TILE_FRAME,
        };
        let (kind, size) = match it.shape {
            tile_sim::Shape::Box { half } => (Shape::Cube, half.map(|h| dec(2.0 * h))),
            tile_sim::Shape::Cylinder { radius, half_height } => {
                (Shape::Cylinder, [dec(2.0 * radius), dec(2.0 * radius), dec(2.0 * half_height)])
            }
            tile_sim::Shape::Capsule { .. } => continue,
        };
        let k = seen.entry(it.name).or_insert(0);
        let id = if count(it.name) > 1 { format!("{}_{}", it.name, k) } else { it.name.to_string() };
        *k += 1;
        out.push(SceneEntity {
            id,
            frame_id: frame_id.to_string(),
            kind,
            size,
            pose: Pose { position: it.translation.map(dec), orientation: it.rotation.map(dec) },
            color: it.rgba,
            extra: Vec::new(),
        });
    }
    out
}

/// tile-sim's arm (the UR3 as capsules: a cylinder and its two end spheres each) as entities
/// `robot/<capsule name>`, each locked to the URDF link its DH frame rides on
/// (`ur3_kin::urdf::dh_frames_in_links`), so `/tf` moves it as tile-sim moves its links.
pub fn arm_capsule_entities() -> Vec<SceneEntity> {
    let links = ur3_kin::urdf::dh_frames_in_links(&ur3_kin::UR3);
    let scene = tile_sim::world::scene(Task::TileSuction, &tile_sim::Start::default());
    let mut out = Vec::new();
    for it in &scene.items {
        let (SceneFrame::Link(i @ 1..=6), tile_sim::Shape::Capsule { a, b, radius }) = (it.frame, it.shape)
        else {
            continue;
        };
        let (link, offset) = links[usize::from(i) - 1];
        // the item's pose in its DH frame, then the DH frame's pose in the URDF link
        let q = it.rotation.map(dec);
        let item = ur3_kin::Pose::from_parts(
            Vector3::from(it.translation.map(dec)).into(),
            UnitQuaternion::new_normalize(ur3_kin::nalgebra::Quaternion::new(q[3], q[0], q[1], q[2])),
        );
        let place = |p: [f32; 3]| offset * item * Point3::from(p.map(dec));
        let (pa, pb, d) = (place(a), place(b), 2.0 * dec(radius));
        let sphere = |c: Point3<f64>| Primitive {
            kind: Shape::Sphere,
            size: [d; 3],
            pose: Pose { position: [c.x, c.y, c.z], orientation: [0.0, 0.0, 0.0, 1.0] },
            color: it.rgba,
        };
        let axis = pb - pa;
        let rot = UnitQuaternion::rotation_between(&Vector3::z(), &axis)
            .unwrap_or_else(|| UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI));
        let (mid, r) = (pa + axis / 2.0, rot.quaternion());
        out.push(SceneEntity {
            id: format!("robot/{}", it.name),
            frame_id: link.to_string(),
            kind: Shape::Cylinder,
            size: [d, d, axis.norm()],
            pose: Pose { position: [mid.x, mid.y, mid.z], orientation: [r.i, r.j, r.k, r.w] },
            color: it.rgba,
            extra: vec![sphere(pa), sphere(pb)],
        });
    }
    out
}

/// The robot `/scene` draws: [`arm_capsule_entities`] for the UR3 (the arm tile-sim simulates),
/// [`robot_link_entities`] for any other model.
pub fn robot_entities(model: &UrModel) -> Vec<SceneEntity> {
    match model.name == ur3_kin::UR3.name {
        true => arm_capsule_entities(),
        false => robot_link_entities(model),
    }
}

/// Everything `/scene` draws for episode `seed` of `task`: [`robot_entities`] then
/// [`task_scene`].
pub fn episode_scene(model: &UrModel, task: Task, seed: u64) -> Vec<SceneEntity> {
    let mut v = robot_entities(model);
    v.extend(task_scene(task, seed));
    v
}

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

/// [`episode_scene`] of the model named `model_name`, each entity as the Foxglove `SceneEntity`
/// JSON object `/scene` carries (stamped 0): what the live page draws.
///
/// # Errors
/// [`DemoError::Invalid`] for an unknown model.
pub fn episode_scene_json(model_name: &str, task: Task, seed: u64) -> Result<Vec<Value>, DemoError> {
    scene_json_at(model_name, task, &tile_sim::Variation::default().start(task, seed))
}

/// [`episode_scene_json`] of an episode that began at `start`.
///
/// # Errors
/// [`DemoError::Invalid`] for an unknown model.
pub fn scene_json_at(model_name: &str, task: Task, start: &tile_sim::Start) -> Result<Vec<Value>, DemoError> {
    let mut v = robot_entities(model(model_name)?);
    v.extend(task_scene_at(task, start));
    Ok(v.iter().map(|e| foxglove_entity(e, 0)).collect())
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
