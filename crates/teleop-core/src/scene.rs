//! The simulator's scene as a demo's `/scene`: tile-sim's items (table, pad, target, end
//! effector, object and the arm's capsules) turned into demo-log's entities. demo-log records the
//! scene it is handed; this is where the two meet, so neither crate knows the other.

use demo_log::serde_json::Value;
use demo_log::{
    BASE_FRAME, DemoError, Pose, Primitive, ROW_FRAMES, SceneEntity, Shape, TILE_FRAME, foxglove_entity,
    robot_link_entities,
};
use tile_sim::{Scene, SceneFrame, Task};
use ur3_kin::UrModel;
use ur3_kin::nalgebra::{Point3, Quaternion, UnitQuaternion, Vector3};

// every object of the longest row tile-sim builds has a frame of its own in a demo
const _: () = assert!(tile_sim::spec::MAX_ROW <= ROW_FRAMES.len());

/// An `f32` constant as the decimal it was written as (0.075, not 0.07500000298023224).
fn dec(x: f32) -> f64 {
    format!("{x}").parse().unwrap_or(x as f64)
}

/// The task part of a tile-sim scene as demo entities (no arm: the robot is drawn by
/// [`robot_entities`]). Frames: tile-sim's world → `base`, its tool frame → `tool0`, its
/// object → [`TILE_FRAME`] (the object frame of every task: tile, block or nut), a row's object
/// `i` → [`ROW_FRAMES`]`[i]` (TileRow). Ids are the items' names, numbered when a name repeats
/// (`cup_0` … `cup_3`; a row's `tile_0` … `tile_2`).
pub fn scene_entities(scene: &Scene) -> Vec<SceneEntity> {
    let count = |n: &str| scene.items.iter().filter(|i| i.name == n).count();
    let mut seen = std::collections::BTreeMap::<&str, usize>::new();
    let mut out = Vec::new();
    for it in &scene.items {
        let frame_id = match it.frame {
            SceneFrame::World => BASE_FRAME,
            SceneFrame::Link(6) => "tool0",
            SceneFrame::Link(_) => continue,
            SceneFrame::Object => TILE_FRAME,
            SceneFrame::RowObject(i) => ROW_FRAMES[usize::from(i)],
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

/// [`scene_entities`] of episode `seed` of a built-in `task` (the paper's starts).
pub fn task_scene(task: Task, seed: u64) -> Vec<SceneEntity> {
    scene_entities(&tile_sim::episode_scene(task, seed))
}

/// tile-sim's arm of `model` (capsules: a cylinder and its two end spheres each) as entities
/// `robot/<capsule name>`, each locked to the URDF link its DH frame rides on
/// (`ur3_kin::urdf::dh_frames_in_links`), so `/tf` moves it as tile-sim moves its links.
/// `model` is one tile-sim simulates (`tile_sim::arm::dims` is `Some`).
pub fn arm_capsule_entities(model: &UrModel) -> Vec<SceneEntity> {
    let links = ur3_kin::urdf::dh_frames_in_links(model);
    let mut out = Vec::new();
    for it in &tile_sim::world::arm_items(model) {
        let (SceneFrame::Link(i @ 1..=6), tile_sim::Shape::Capsule { a, b, radius }) = (it.frame, it.shape)
        else {
            continue;
        };
        let (link, offset) = links[usize::from(i) - 1];
        // the item's pose in its DH frame, then the DH frame's pose in the URDF link
        let q = it.rotation.map(dec);
        let item = ur3_kin::Pose::from_parts(
            Vector3::from(it.translation.map(dec)).into(),
            UnitQuaternion::new_normalize(Quaternion::new(q[3], q[0], q[1], q[2])),
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

/// The robot `/scene` draws: [`arm_capsule_entities`] for a model tile-sim simulates (ur3,
/// ur3e, ur5e, ur10e), demo-log's [`robot_link_entities`] for any other model.
pub fn robot_entities(model: &UrModel) -> Vec<SceneEntity> {
    match tile_sim::arm::dims(model).is_some() {
        true => arm_capsule_entities(model),
        false => robot_link_entities(model),
    }
}

/// Everything `/scene` draws for an episode whose scene is `scene`: [`robot_entities`] then
/// [`scene_entities`].
pub fn episode_entities(model: &UrModel, scene: &Scene) -> Vec<SceneEntity> {
    let mut v = robot_entities(model);
    v.extend(scene_entities(scene));
    v
}

/// The scene a demo of `task` (any name tile-sim accepts) and `seed` records: the robot, the
/// task's scene at its paper start for that seed (the robot alone for a task tile-sim does not
/// know), then `given` ([`with_given`]). What a caller without an env hands demo-log's writer as
/// its `EpisodeMeta::scene`.
pub fn demo_scene(model: &UrModel, task: &str, seed: u64, given: &[SceneEntity]) -> Vec<SceneEntity> {
    let mut v = robot_entities(model);
    if let Ok(task) = Task::from_name(task) {
        v.extend(task_scene(task, seed));
    }
    with_given(v, given)
}

/// The scene a demo of an env whose scene is `scene` records (its own start, its own spec):
/// [`episode_entities`], then `given` ([`with_given`]).
pub fn env_demo_scene(model: &UrModel, scene: &Scene, given: &[SceneEntity]) -> Vec<SceneEntity> {
    with_given(episode_entities(model, scene), given)
}

/// `v`, each entity of `given` replacing the one of the same id, the rest appended in order.
pub fn with_given(mut v: Vec<SceneEntity>, given: &[SceneEntity]) -> Vec<SceneEntity> {
    for e in given {
        match v.iter_mut().find(|x| x.id == e.id) {
            Some(slot) => *slot = e.clone(),
            None => v.push(e.clone()),
        }
    }
    v
}

/// The robot model named `name` (`ur3_kin::UrModel::by_name`).
fn model(name: &str) -> Result<&'static UrModel, DemoError> {
    UrModel::by_name(name).map_err(|e| DemoError::Invalid(e.to_string()))
}

/// [`episode_entities`] of the model named `model_name`, each entity as the Foxglove
/// `SceneEntity` JSON object `/scene` carries (stamped 0): what the live page draws.
///
/// # Errors
/// [`DemoError::Invalid`] for an unknown model.
pub fn scene_json(model_name: &str, scene: &Scene) -> Result<Vec<Value>, DemoError> {
    Ok(episode_entities(model(model_name)?, scene).iter().map(|e| foxglove_entity(e, 0)).collect())
}
