//! World geometry: table, arm link shapes, end effectors, task objects, and the static scene
//! description for visualisation. All lengths in metres, Base frame, Z up. The world builder and
//! the scene read the task's numbers from its [`TaskSpec`]; the constants below are the built-in
//! tasks' values (`tasks/*.toml`), kept for tests and tools (a test checks that they agree).

use crate::spec::{EffectorSpec, TargetSpec, TaskSpec};
use crate::{CONTROL_DT, PHYSICS_SUBSTEPS, Start, Task};
use rapier3d::prelude::*;
use std::collections::HashSet;
use std::f32::consts::FRAC_PI_2;
use std::sync::Mutex;

// ---- table and layout (Base frame) ----
/// Table top plane height (the UR3 base stands on it).
pub const TABLE_TOP: f32 = 0.0;
/// Table half extents (x, y, z): 1.4 m × 1.4 m, 4 cm thick, centred under the base.
pub const TABLE_HALF: [f32; 3] = [0.7, 0.7, 0.02];
/// Object y coordinate (in front of the base) and x range of the randomised object position.
pub const OBJECT_Y: f32 = 0.32;
/// Object x is uniform in `[OBJECT_X_MIN, OBJECT_X_MAX]` (paper: x randomised in [0, 0.15] m).
pub const OBJECT_X_MIN: f32 = 0.0;
pub const OBJECT_X_MAX: f32 = 0.15;
/// Install pad: a fixed box the tile/block is placed on; centre (x, y) and half extents.
pub const PAD_XY: [f32; 2] = [-0.22, 0.28];
pub const PAD_HALF: [f32; 3] = [0.1, 0.1, 0.02];

// ---- tile (ceramic floor tile) ----
/// Tile half extents: 0.15 × 0.15 × 0.01 m (glazed ceramic).
pub const TILE_HALF: [f32; 3] = [0.075, 0.075, 0.005];
/// Tile mass, kg (ceramic ≈ 2,200 kg/m³ × 0.000225 m³ ≈ 0.5 kg).
pub const TILE_MASS: f32 = 0.5;
/// Friction coefficient of tile, table, pad (glazed ceramic on wood/laminate).
pub const FRICTION: f32 = 0.6;

// ---- block (BlockGrip) ----
/// Block half extent (a 4 cm wooden cube, 0.045 kg).
pub const BLOCK_HALF: f32 = 0.02;
pub const BLOCK_MASS: f32 = 0.045;

// ---- screw task ----
/// Half extent (x and y) of the 1 cm steel plate the bolt stands on.
pub const SCREW_PLATE_HALF: f32 = 0.04;
/// Bolt: M12, radius 6 mm, standing on a 1 cm steel plate; its top is at `BOLT_TOP` above the table.
pub const BOLT_RADIUS: f32 = 0.006;
pub const BOLT_TOP: f32 = 0.08;
/// Nut: hex M12 approximated by a cylinder of 19 mm across flats (radius 9.5 mm), 10 mm high.
pub const NUT_RADIUS: f32 = 0.0095;
pub const NUT_HALF_HEIGHT: f32 = 0.005;
/// Thread pitch of M12 coarse, m per turn.
pub const THREAD_PITCH: f32 = 0.00175;
/// Nut centre height when it has just caught the thread (turns = 0).
pub const NUT_START_Z: f32 = BOLT_TOP - NUT_HALF_HEIGHT - 0.002;

// ---- suction head (on tool0; tool0 Z points out of the flange) ----
/// Suction plate: half extents, centre at z = 0.01 in tool0.
pub const PLATE_HALF: [f32; 3] = [0.05, 0.05, 0.01];
/// Four cups at (±CUP_OFFSET, ±CUP_OFFSET) in tool0, radius CUP_RADIUS, spanning z 0.02 … 0.05.
pub const CUP_OFFSET: f32 = 0.045;
pub const CUP_RADIUS: f32 = 0.015;
/// The cup centre (TCP of the suction head): centre of the four cup lips, tool0 z = 0.05.
pub const CUP_TCP_Z: f32 = 0.05;

// ---- parallel gripper (on tool0) ----
/// Gripper body half extents, centre at tool0 z = 0.03.
pub const GRIPPER_BODY_HALF: [f32; 3] = [0.03, 0.055, 0.03];
/// Finger half extents (x, y, z); fingers slide along tool0 Y, centre at z = 0.085.
pub const FINGER_HALF: [f32; 3] = [0.01, 0.006, 0.025];
pub const FINGER_Z: f32 = 0.085;
/// Gripper TCP: centre between the fingers, tool0 z = 0.085.
pub const GRIP_TCP_Z: f32 = FINGER_Z;
/// Finger gap limits (m) and closing/opening speed (m/s, constant).
pub const GRIP_MAX_WIDTH: f32 = 0.085;
pub const GRIP_SPEED: f32 = 0.1;
/// Spin rate of the screwing end effector, turns per second.
pub const SPIN_RATE: f32 = 1.0;

/// Shape of a scene item. Cylinders and capsules are along the item's local **Z** axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Shape {
    /// Box with half extents (x, y, z).
    Box { half: [f32; 3] },
    /// Cylinder along local Z.
    Cylinder { radius: f32, half_height: f32 },
    /// Capsule between two points (in the item's frame), with radius.
    Capsule { a: [f32; 3], b: [f32; 3], radius: f32 },
}

/// The frame a scene item's pose is expressed in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SceneFrame {
    /// Base/world frame (static item).
    World,
    /// DH frame `i` (1..=6) of the arm as given by `ur3_kin::fk_all`; 6 = tool0.
    Link(u8),
    /// Attached to the task object (tile/block/nut); pose relative to the object's centre.
    Object,
    /// Attached to object `i` of a row (TileRow's tile `i`, a snapshot's `row[i].object`); pose
    /// relative to its centre. Serialized as `"object<i>"`.
    RowObject(u8),
}

/// One visual/collision item of the scene.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneItem {
    pub name: &'static str,
    pub frame: SceneFrame,
    pub shape: Shape,
    /// Translation (m) of the item in `frame`.
    pub translation: [f32; 3],
    /// Rotation quaternion `[x, y, z, w]` of the item in `frame`.
    pub rotation: [f32; 4],
    /// Colour, RGBA in [0, 1].
    pub rgba: [f32; 4],
}

/// Static description of a task's scene (for visualisation and demo files).
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    pub task: Task,
    pub items: Vec<SceneItem>,
}

const ID: [f32; 4] = [0.0, 0.0, 0.0, 1.0];

fn item(name: &'static str, frame: SceneFrame, shape: Shape, t: [f32; 3], rgba: [f32; 4]) -> SceneItem {
    SceneItem { name, frame, shape, translation: t, rotation: ID, rgba }
}

/// The grey pad and the translucent green target marker (half-size `marker_half_xy`, drawn
/// `marker_dz` above the task's target point) of the tasks that place an object on a pad.
fn push_pad_and_target(
    items: &mut Vec<SceneItem>,
    spec: &TaskSpec,
    start: &Start,
    marker_half_xy: [f32; 2],
    marker_dz: f32,
) {
    for i in 0..spec.row_len() {
        push_pad_and_target_i(items, spec, start, marker_half_xy, marker_dz, i);
    }
}

/// [`push_pad_and_target`] of pad `i` of a row (the one pad of the other tasks: `i = 0`).
fn push_pad_and_target_i(
    items: &mut Vec<SceneItem>,
    spec: &TaskSpec,
    start: &Start,
    marker_half_xy: [f32; 2],
    marker_dz: f32,
    i: usize,
) {
    let TargetSpec::Pad { half_extents: pad_half, .. } = &spec.target else { return };
    let pad = start.row_pad_xy(spec, i);
    items.push(item(
        "pad",
        SceneFrame::World,
        Shape::Box { half: *pad_half },
        [pad[0], pad[1], spec.table.top_z + pad_half[2]],
        [0.5, 0.5, 0.5, 1.0],
    ));
    let t = start.row_target(spec, i);
    items.push(item(
        "target",
        SceneFrame::World,
        Shape::Box { half: [marker_half_xy[0], marker_half_xy[1], 0.0005] },
        [t.x, t.y, t.z + marker_dz],
        [0.1, 0.8, 0.1, 0.4],
    ));
    if start.pad_yaw != 0.0 {
        // The pad and its target marker, turned about their centres.
        let (h, c) = ((0.5 * start.pad_yaw).sin(), (0.5 * start.pad_yaw).cos());
        let n = items.len();
        for it in &mut items[n - 2..] {
            it.rotation = [0.0, 0.0, h, c];
        }
    }
}

/// A spec's object name as the `&'static str` a [`SceneItem`] holds (each distinct name is
/// kept once for the life of the process).
fn intern(name: &str) -> &'static str {
    static NAMES: Mutex<Option<HashSet<&'static str>>> = Mutex::new(None);
    let mut names = NAMES.lock().unwrap_or_else(|e| e.into_inner());
    let set = names.get_or_insert_with(HashSet::new);
    if let Some(n) = set.get(name) {
        return n;
    }
    let leaked: &'static str = Box::leak(name.to_string().into_boxed_str());
    set.insert(leaked);
    leaked
}

/// The object's collision / scene shape (a cylinder along its local z).
fn object_shape(spec: &TaskSpec) -> Shape {
    let o = &spec.object;
    match (o.half_extents, o.radius, o.half_height) {
        (Some(half), _, _) => Shape::Box { half },
        (None, Some(radius), Some(half_height)) => Shape::Cylinder { radius, half_height },
        _ => unreachable!("invariant: TaskSpec::check gives the object a box or a cylinder"),
    }
}

/// Arm link capsules of the UR3 in DH frame i (frame index, a, b, radius):
/// [`crate::arm::capsules`] of the UR3, for tests and tools.
pub fn arm_capsules() -> Vec<(u8, [f32; 3], [f32; 3], f32)> {
    crate::arm::capsules(&ur3_kin::UR3)
}

const G_ARM: Group = Group::GROUP_1;
const G_OBJECT: Group = Group::GROUP_2;
const G_STATIC: Group = Group::GROUP_3;

fn arm_groups() -> InteractionGroups {
    InteractionGroups::new(G_ARM, G_OBJECT, InteractionTestMode::And)
}

fn static_groups() -> InteractionGroups {
    InteractionGroups::new(G_STATIC, G_OBJECT, InteractionTestMode::And)
}

fn object_groups() -> InteractionGroups {
    InteractionGroups::new(G_OBJECT, G_ARM.union(G_STATIC), InteractionTestMode::And)
}

/// The objects of a row also touch each other (a tile pushed into its neighbour moves it).
fn row_object_groups() -> InteractionGroups {
    InteractionGroups::new(G_OBJECT, G_ARM.union(G_STATIC).union(G_OBJECT), InteractionTestMode::And)
}

/// Handles of one built world.
#[derive(Debug, Clone)]
pub struct Handles {
    /// Link bodies for DH frames 1..=6 (index 0 = frame 1, index 5 = tool0 with the EE).
    pub links: [RigidBodyHandle; 6],
    /// Gripper fingers (left +Y, right −Y), only for BlockGrip/Screw.
    pub fingers: Option<[RigidBodyHandle; 2]>,
    /// The task object: tile, block or nut. With a row, the current one of `row` (the task
    /// logic moves it: TileRow's held tile, else the first one not installed), object 0 as built.
    pub object: RigidBodyHandle,
    /// A row's objects in row order (a spec's `[row]`, TileRow); empty without a row.
    pub row: Vec<RigidBodyHandle>,
}

/// Build a fresh world for the built-in `task` with the object and the pad where `start` puts them.
pub fn build(task: Task, start: &Start) -> (PhysicsWorld, Handles) {
    build_spec(&TaskSpec::builtin(task), start)
}

/// Build a fresh world for the task `spec` describes, the object and the pad where `start` puts them.
pub fn build_spec(spec: &TaskSpec, start: &Start) -> (PhysicsWorld, Handles) {
    let object_pos = start.object_centre(spec);
    let object_at = Pose::from_parts(object_pos, Rotation::from_rotation_z(start.yaw));
    let (table_half, top) = (spec.table.half_extents, spec.table.top_z);
    let mut w = PhysicsWorld::new();
    w.gravity = Vector::new(0.0, 0.0, -9.81);
    w.integration_parameters.dt = CONTROL_DT;
    w.integration_parameters.num_solver_iterations = physics_substeps(spec);
    // Scene scale ~0.2 m: allowed penetration 1 mm, prediction distance 4 mm.
    w.integration_parameters.length_unit = 0.2;
    // ~12 leaves, most of them moving every step: re-optimising the broad-phase tree each step
    // costs more than it saves (measured), so keep the tree as built.
    w.broad_phase = BroadPhaseBvh::with_optimization_strategy(BvhOptimizationStrategy::None);

    // Table (fixed).
    let table = w.insert_body(RigidBodyBuilder::fixed());
    w.insert_collider(
        ColliderBuilder::cuboid(table_half[0], table_half[1], table_half[2])
            .translation(Vector::new(0.0, 0.0, top - table_half[2]))
            .friction(spec.table.friction)
            .collision_groups(static_groups()),
        Some(table),
    );
    // The arm's base housing (fixed cylinder, axis Z).
    let arm = spec.arm();
    let dims = crate::arm::dims(arm).unwrap_or(&crate::arm::SIMULATED[0]);
    let (base_r, base_hh) = (dims.base_radius, dims.base_half_height);
    w.insert_collider(
        ColliderBuilder::cylinder(base_hh, base_r)
            .position(Pose::from_parts(Vector::new(0.0, 0.0, base_hh), Rotation::from_rotation_x(FRAC_PI_2)))
            .collision_groups(static_groups()),
        Some(table),
    );
    match &spec.target {
        TargetSpec::Pad { half_extents: h, friction, .. } => {
            for i in 0..spec.row_len() {
                let pad = start.row_pad_xy(spec, i);
                w.insert_collider(
                    ColliderBuilder::cuboid(h[0], h[1], h[2])
                        .position(Pose::from_parts(
                            Vector::new(pad[0], pad[1], top + h[2]),
                            Rotation::from_rotation_z(start.pad_yaw),
                        ))
                        .friction(*friction)
                        .collision_groups(static_groups()),
                    Some(table),
                );
            }
        }
        TargetSpec::Bolt { plate_half_extents: p, radius, top_z, .. } => {
            // Steel plate with the bolt (the nut is kinematic along the bolt, no contact needed).
            w.insert_collider(
                ColliderBuilder::cuboid(p[0], p[1], p[2])
                    .translation(Vector::new(object_pos.x, object_pos.y, p[2]))
                    .collision_groups(static_groups()),
                Some(table),
            );
            w.insert_collider(
                ColliderBuilder::capsule_from_endpoints(
                    Vector::new(object_pos.x, object_pos.y, 2.0 * p[2]),
                    Vector::new(object_pos.x, object_pos.y, top_z - radius),
                    *radius,
                )
                .collision_groups(static_groups()),
                Some(table),
            );
        }
    }

    // Arm links: kinematic, placed each step from FK; one compound collider per link. The arm
    // only interacts with the task object (group filter), so arm-vs-table/pad/self pairs cost nothing.
    let mut links = [RigidBodyHandle::invalid(); 6];
    for l in links.iter_mut() {
        *l = w.insert_body(RigidBodyBuilder::kinematic_position_based());
    }
    let mut parts: [Vec<(Pose, SharedShape)>; 6] = Default::default();
    for (frame, a, b, r) in crate::arm::capsules_of(arm, dims) {
        parts[frame as usize - 1]
            .push((Pose::IDENTITY, SharedShape::capsule(Vector::from(a), Vector::from(b), r)));
    }
    let mut fingers = None;
    match &spec.effector {
        EffectorSpec::Suction { plate_half_extents: plate, cup_offset, cup_radius, tcp_z, .. } => {
            parts[5].push((
                Pose::from_translation(Vector::new(0.0, 0.0, plate[2])),
                SharedShape::cuboid(plate[0], plate[1], plate[2]),
            ));
            let hh = (tcp_z - 2.0 * plate[2]) / 2.0;
            for (sx, sy) in [(1.0f32, 1.0f32), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)] {
                parts[5].push((
                    Pose::from_parts(
                        Vector::new(sx * cup_offset, sy * cup_offset, 2.0 * plate[2] + hh),
                        Rotation::from_rotation_x(FRAC_PI_2),
                    ),
                    SharedShape::cylinder(hh, *cup_radius),
                ));
            }
        }
        EffectorSpec::Gripper {
            body_half_extents: body, finger_half_extents: fh, finger_friction, ..
        } => {
            parts[5].push((
                Pose::from_translation(Vector::new(0.0, 0.0, body[2])),
                SharedShape::cuboid(body[0], body[1], body[2]),
            ));
            let mut f = [RigidBodyHandle::invalid(); 2];
            for handle in f.iter_mut() {
                *handle = w.insert_body(RigidBodyBuilder::kinematic_position_based());
                w.insert_collider(
                    ColliderBuilder::cuboid(fh[0], fh[1], fh[2])
                        .friction(*finger_friction)
                        .collision_groups(arm_groups()),
                    Some(*handle),
                );
            }
            fingers = Some(f);
        }
    }
    for (i, p) in parts.into_iter().enumerate() {
        if p.is_empty() {
            continue;
        }
        let c = if p.len() == 1 && p[0].0 == Pose::IDENTITY {
            ColliderBuilder::new(p[0].1.clone())
        } else {
            ColliderBuilder::compound(p)
        };
        w.insert_collider(c.collision_groups(arm_groups()), Some(links[i]));
    }

    // The object: dynamic on the table, or (a nut on its bolt) kinematic, placed from the turn
    // count each step.
    let o = &spec.object;
    let mut collider = match object_shape(spec) {
        Shape::Box { half } => ColliderBuilder::cuboid(half[0], half[1], half[2]),
        Shape::Cylinder { radius, half_height } => {
            ColliderBuilder::cylinder(half_height, radius).rotation(Vector::new(FRAC_PI_2, 0.0, 0.0))
        }
        Shape::Capsule { .. } => unreachable!("invariant: objects are boxes or cylinders"),
    };
    if let Some(m) = o.mass {
        collider = collider.mass(m);
    }
    if let Some(f) = o.friction {
        collider = collider.friction(f);
    }
    let body = match &spec.target {
        TargetSpec::Bolt { .. } => RigidBodyBuilder::kinematic_position_based().translation(object_pos),
        TargetSpec::Pad { .. } => RigidBodyBuilder::dynamic().pose(object_at),
    };
    let groups = if spec.row.is_some() { row_object_groups() } else { object_groups() };
    let collider = collider.collision_groups(groups);
    let object = w.insert_body(body);
    w.insert_collider(collider.clone(), Some(object));
    // The rest of a row: copies of the object at their places in the row, turned alike.
    let mut row = Vec::new();
    if spec.row.is_some() {
        row.push(object);
        for i in 1..spec.row_len() {
            let at = Pose::from_parts(start.row_object_centre(spec, i), Rotation::from_rotation_z(start.yaw));
            let h = w.insert_body(RigidBodyBuilder::dynamic().pose(at));
            w.insert_collider(collider.clone(), Some(h));
            row.push(h);
        }
    }
    (w, Handles { links, fingers, object, row })
}

/// Solver substeps of one env step in `spec`'s world: [`PHYSICS_SUBSTEPS`] (2), or
/// [`PLACE_SUBSTEPS`] for the TilePlace logic.
pub fn physics_substeps(spec: &TaskSpec) -> usize {
    if spec.task() == Task::TilePlace { PLACE_SUBSTEPS } else { PHYSICS_SUBSTEPS }
}

/// Solver substeps per env step of a TilePlace world (5 ms each). A tile let go 2 mm above the
/// pad falls 8 mm in one 40 ms step unchecked; with 2 substeps it sank 2.6 mm into the pad and
/// was kicked 3.6 mm and 0.7° sideways by the contact that pushed it out (a placement spoilt by
/// the solver, not the policy), with 4 it still moved 0.5 mm and 0.2°, with 8 it lands within
/// 0.1 mm and 0.03° (measured on a converted demo's release).
pub const PLACE_SUBSTEPS: usize = 8;

/// Target pose (centre of the object when the task is done) for TileSuction/BlockGrip.
pub fn pad_target(task: Task) -> Vector {
    pad_target_of(&TaskSpec::builtin(task))
}

/// The nominal target of a pad task: the object's centre resting on the pad's centre (zero for
/// a bolt target).
pub fn pad_target_of(spec: &TaskSpec) -> Vector {
    match &spec.target {
        TargetSpec::Pad { xy, half_extents, .. } => {
            let top = spec.table.top_z + 2.0 * half_extents[2];
            Vector::new(xy[0], xy[1], top + spec.object_half_height())
        }
        TargetSpec::Bolt { .. } => Vector::ZERO,
    }
}

/// The arm's scene items: its base housing (`<model>_base`, a world cylinder) and its link
/// capsules ([`crate::arm::CAPSULE_NAMES`], each in its DH frame), for a simulated `model`.
pub fn arm_items(model: &ur3_kin::UrModel) -> Vec<SceneItem> {
    let dims = crate::arm::dims(model).unwrap_or(&crate::arm::SIMULATED[0]);
    let grey = [0.6, 0.65, 0.7, 1.0];
    let mut items = vec![item(
        intern(&format!("{}_base", model.name)),
        SceneFrame::World,
        Shape::Cylinder { radius: dims.base_radius, half_height: dims.base_half_height },
        [0.0, 0.0, dims.base_half_height],
        grey,
    )];
    for (k, (frame, a, b, r)) in crate::arm::capsules_of(model, dims).into_iter().enumerate() {
        let shape = Shape::Capsule { a, b, radius: r };
        items.push(item(crate::arm::CAPSULE_NAMES[k], SceneFrame::Link(frame), shape, [0.0; 3], grey));
    }
    items
}

/// The static scene description of the built-in `task` at `start` (the pad, the target and the
/// screw's plate where `start` puts them; the object item is relative to the object,
/// `SceneFrame::Object`).
pub fn scene(task: Task, start: &Start) -> Scene {
    scene_spec(&TaskSpec::builtin(task), start)
}

/// [`scene`] of the task `spec` describes.
pub fn scene_spec(spec: &TaskSpec, start: &Start) -> Scene {
    let task = spec.task();
    let object_pos = start.object_centre(spec);
    let (table_half, top) = (spec.table.half_extents, spec.table.top_z);
    let mut items = vec![item(
        "table",
        SceneFrame::World,
        Shape::Box { half: table_half },
        [0.0, 0.0, top - table_half[2]],
        [0.72, 0.6, 0.45, 1.0],
    )];
    items.extend(arm_items(spec.arm()));
    let tool = SceneFrame::Link(6);
    let object =
        item(intern(&spec.object.name), SceneFrame::Object, object_shape(spec), [0.0; 3], spec.object.rgba);
    match &spec.effector {
        EffectorSpec::Suction { plate_half_extents: plate, cup_offset, cup_radius, tcp_z, .. } => {
            let half = spec.object.half_extents.unwrap_or([0.0; 3]);
            push_pad_and_target(&mut items, spec, start, [half[0], half[1]], 0.0);
            items.push(item(
                "suction_plate",
                tool,
                Shape::Box { half: *plate },
                [0.0, 0.0, plate[2]],
                [0.2, 0.2, 0.2, 1.0],
            ));
            let hh = (tcp_z - 2.0 * plate[2]) / 2.0;
            for (sx, sy) in [(1.0f32, 1.0f32), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)] {
                items.push(item(
                    "cup",
                    tool,
                    Shape::Cylinder { radius: *cup_radius, half_height: hh },
                    [sx * cup_offset, sy * cup_offset, 2.0 * plate[2] + hh],
                    [0.1, 0.1, 0.1, 1.0],
                ));
            }
            match spec.row {
                // A row's tiles, each in its own frame (the snapshot's `row[i].object`).
                Some(_) => items.extend(
                    (0..spec.row_len())
                        .map(|i| SceneItem { frame: SceneFrame::RowObject(i as u8), ..object.clone() }),
                ),
                None => items.push(object),
            }
        }
        EffectorSpec::Gripper {
            body_half_extents: body,
            finger_half_extents: fh,
            finger_z,
            max_width,
            ..
        } => {
            items.push(item(
                "gripper_body",
                tool,
                Shape::Box { half: *body },
                [0.0, 0.0, body[2]],
                [0.2, 0.2, 0.2, 1.0],
            ));
            // Fingers drawn at the open limit; at run time their tool-y offset is
            // ±(gripper_width / 2 + finger_half_extents[1]) with the snapshot's `gripper_width`.
            for (name, sgn) in [("finger_left", 1.0f32), ("finger_right", -1.0)] {
                items.push(item(
                    name,
                    tool,
                    Shape::Box { half: *fh },
                    [0.0, sgn * (max_width / 2.0 + fh[1]), *finger_z],
                    [0.25, 0.25, 0.25, 1.0],
                ));
            }
            match &spec.target {
                TargetSpec::Pad { .. } => {
                    let half = spec.object.half_extents.unwrap_or([0.0; 3]);
                    push_pad_and_target(&mut items, spec, start, [half[0], half[1]], -half[2]);
                    items.push(object);
                }
                TargetSpec::Bolt { plate_half_extents: p, radius, top_z, .. } => {
                    let base = 2.0 * p[2];
                    items.push(item(
                        "plate",
                        SceneFrame::World,
                        Shape::Box { half: *p },
                        [object_pos.x, object_pos.y, p[2]],
                        [0.5, 0.5, 0.5, 1.0],
                    ));
                    items.push(item(
                        "bolt",
                        SceneFrame::World,
                        Shape::Cylinder { radius: *radius, half_height: (top_z - base) / 2.0 },
                        [object_pos.x, object_pos.y, base + (top_z - base) / 2.0],
                        [0.7, 0.7, 0.75, 1.0],
                    ));
                    items.push(object);
                }
            }
        }
    }
    Scene { task, items }
}

/// A scene item as a flat map: `name`, `frame` (`"world"`, `"link<i>"`, `"object"`), `kind`
/// (`"box"` with `half_extents`; `"cylinder"` with `radius`, `half_height`; `"capsule"` with `a`,
/// `b`, `radius`), `translation`, `rotation` `[x, y, z, w]`, `rgba`.
impl serde::Serialize for SceneItem {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let mut m = s.serialize_map(None)?;
        m.serialize_entry("name", self.name)?;
        let frame = match self.frame {
            SceneFrame::World => "world".to_string(),
            SceneFrame::Link(i) => format!("link{i}"),
            SceneFrame::Object => "object".to_string(),
            SceneFrame::RowObject(i) => format!("object{i}"),
        };
        m.serialize_entry("frame", &frame)?;
        match self.shape {
            Shape::Box { half } => {
                m.serialize_entry("kind", "box")?;
                m.serialize_entry("half_extents", &half)?;
            }
            Shape::Cylinder { radius, half_height } => {
                m.serialize_entry("kind", "cylinder")?;
                m.serialize_entry("radius", &radius)?;
                m.serialize_entry("half_height", &half_height)?;
            }
            Shape::Capsule { a, b, radius } => {
                m.serialize_entry("kind", "capsule")?;
                m.serialize_entry("a", &a)?;
                m.serialize_entry("b", &b)?;
                m.serialize_entry("radius", &radius)?;
            }
        }
        m.serialize_entry("translation", &self.translation)?;
        m.serialize_entry("rotation", &self.rotation)?;
        m.serialize_entry("rgba", &self.rgba)?;
        m.end()
    }
}
