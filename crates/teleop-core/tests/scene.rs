//! The simulator's scene as a demo's `/scene`: every built-in task's demo draws its table, pad,
//! target, effector (locked to `tool0`) and object (locked to `tile`); the UR3 as tile-sim's
//! capsules; an env's own start (a wide one) moves what it moves.

use demo_log::serde_json::{self, Value, json};
use demo_log::{
    DemoWriter, EpisodeMeta, EpisodeSummary, Shape, StepRecord, TILE_FRAME, TOPIC_SCENE, foxglove_entity,
    robot_link_entities, salvage,
};
use teleop_core::scene::*;
use tile_sim::Task;

fn tmpdir(name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("teleop-core-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn first_scene(path: &std::path::Path) -> Vec<Value> {
    let (msgs, _) = salvage(path).unwrap();
    let m = msgs.iter().find(|m| m.topic == TOPIC_SCENE).expect("a /scene message");
    let v: Value = serde_json::from_slice(&m.data).unwrap();
    v["entities"].as_array().unwrap().clone()
}

fn find<'a>(ents: &'a [Value], id: &str) -> &'a Value {
    ents.iter().find(|e| e["id"] == id).unwrap_or_else(|| panic!("no entity {id}"))
}

fn write_demo(path: &std::path::Path, meta: &EpisodeMeta) {
    let mut w = DemoWriter::create(path, meta).unwrap();
    let step = StepRecord {
        obs: vec![0.0; 16],
        action: vec![0.0; 7],
        joints: tile_sim::HOME_Q,
        gesture: "fixed".into(),
        ..Default::default()
    };
    w.write_step(&step).unwrap();
    w.finish(&EpisodeSummary::default()).unwrap();
}

#[test]
fn a_demo_handed_demo_scene_draws_the_whole_task() {
    let d = tmpdir("scene-task");
    for (task, tool_ids, object) in [
        ("TileSuction", vec!["suction_plate", "cup_0", "cup_1", "cup_2", "cup_3"], "tile"),
        ("BlockGrip", vec!["gripper_body", "finger_left", "finger_right"], "block"),
        ("Screw", vec!["gripper_body", "finger_left", "finger_right"], "nut"),
    ] {
        let p = d.join(format!("{task}.mcap"));
        let mut meta = EpisodeMeta { task: task.into(), seed: 3, ..Default::default() };
        meta.scene = demo_scene(&ur3_kin::UR3, task, 3, &[]);
        write_demo(&p, &meta);
        let ents = first_scene(&p);
        assert_eq!(find(&ents, "table")["frame_id"], "base");
        for id in &tool_ids {
            assert_eq!(find(&ents, id)["frame_id"], "tool0", "{task} {id}");
        }
        let obj = find(&ents, object);
        assert_eq!(obj["frame_id"], TILE_FRAME);
        assert_eq!(obj["frame_locked"], true);
        if task != "Screw" {
            assert_eq!(find(&ents, "target")["frame_id"], "base");
            assert_eq!(find(&ents, "pad")["frame_id"], "base");
        }
        assert!(ents.iter().any(|e| e["id"] == "robot/upper_arm"));
        assert!(!ents.iter().any(|e| e["id"] == "robot/shoulder_link"), "capsules, not link cylinders");
        let mut ids: Vec<_> = ents.iter().map(|e| e["id"].as_str().unwrap().to_string()).collect();
        ids.sort();
        ids.dedup();
        assert_eq!(ids.len(), ents.len(), "ids are unique");
    }
    // The tile: 0.15 x 0.15 x 0.01 m box, centred on the tile frame.
    let ents = first_scene(&d.join("TileSuction.mcap"));
    let tile = &find(&ents, "tile")["cubes"][0];
    assert_eq!(tile["size"], json!({"x": 0.15, "y": 0.15, "z": 0.01}));
    assert_eq!(tile["pose"]["position"], json!({"x": 0.0, "y": 0.0, "z": 0.0}));
    // Screw: the bolt stands where episode 3 puts the nut (x from the seed, y 0.32).
    let ents = first_scene(&d.join("Screw.mcap"));
    let bolt = &find(&ents, "bolt")["cylinders"][0]["pose"]["position"];
    let start = tile_sim::object_start(Task::Screw, 3);
    assert!((bolt["x"].as_f64().unwrap() - start.x as f64).abs() < 1e-6);
    assert!((bolt["y"].as_f64().unwrap() - 0.32).abs() < 1e-9);
}

#[test]
fn given_entities_replace_those_of_the_same_id_and_add_the_rest() {
    let base = demo_scene(&ur3_kin::UR3, "suction", 0, &[]);
    let mut table = base.iter().find(|e| e.id == "table").unwrap().clone();
    table.size = [0.8, 0.8, 0.04];
    let mut marker = table.clone();
    marker.id = "marker".into();
    let v = demo_scene(&ur3_kin::UR3, "suction", 0, &[table.clone(), marker.clone()]);
    assert_eq!(v.len(), base.len() + 1);
    assert_eq!(v.iter().position(|e| e.id == "table"), base.iter().position(|e| e.id == "table"));
    assert_eq!(v.iter().find(|e| e.id == "table").unwrap().size, [0.8, 0.8, 0.04]);
    assert_eq!(v.last().unwrap(), &marker);
    // the paper's start of each seed, as demo-log drew it when it read the simulator itself
    for task in [Task::TileSuction, Task::BlockGrip, Task::Screw] {
        for seed in [0, 3, 17] {
            let start = tile_sim::Variation::default().start(task, seed);
            assert_eq!(task_scene(task, seed), scene_entities(&tile_sim::world::scene(task, &start)));
        }
    }
    // a task tile-sim does not know: the robot, then the given entities
    let v = demo_scene(&ur3_kin::UR3, "juggling", 0, std::slice::from_ref(&marker));
    assert_eq!(v.len(), arm_capsule_entities(&ur3_kin::UR3).len() + 1);
}

#[test]
fn an_envs_scene_is_its_own_start() {
    let mut env = tile_sim::Env::new(Task::TileSuction, 0);
    env.set_variation(tile_sim::Variation::wide()).unwrap();
    let mut obs = vec![0.0; Task::TileSuction.obs_dim()];
    env.reset(Some(5), &mut obs).unwrap();
    let paper = scene_entities(&tile_sim::episode_scene(Task::TileSuction, 5));
    let wide = scene_entities(&env.scene());
    let pad = |v: &[demo_log::SceneEntity]| v.iter().find(|e| e.id == "pad").unwrap().pose.position;
    let start = env.start();
    let moved = pad(&wide);
    assert!(
        (moved[0] - pad(&paper)[0]).abs() > 1e-4 || (moved[1] - pad(&paper)[1]).abs() > 1e-4,
        "{start:?}"
    );
    let json = scene_json("ur3", &env.scene()).unwrap();
    assert_eq!(
        json,
        episode_entities(&ur3_kin::UR3, &env.scene())
            .iter()
            .map(|e| foxglove_entity(e, 0))
            .collect::<Vec<_>>()
    );
    assert!(scene_json("ur4", &env.scene()).unwrap_err().to_string().contains("unknown robot model"));
}

#[test]
fn the_ur3_is_drawn_as_capsules_other_models_as_link_cylinders() {
    let ur3 = robot_entities(&ur3_kin::UR3);
    assert_eq!(ur3, arm_capsule_entities(&ur3_kin::UR3));
    assert!(ur3.iter().all(|e| e.extra.len() == 2 && e.extra.iter().all(|p| p.kind == Shape::Sphere)));
    let ur5 = robot_entities(&ur3_kin::UR5);
    assert_eq!(ur5, robot_link_entities(&ur3_kin::UR5));
    // a capsule is one Foxglove entity: one cylinder, two spheres
    let j = foxglove_entity(&ur3[2], 0);
    assert_eq!((j["cylinders"].as_array().unwrap().len(), j["spheres"].as_array().unwrap().len()), (1, 2));
}

/// A point `p` of `frame` (a URDF link) in Base at joint angles `q`.
fn in_base(q: &[f64; 6], frame: &str, p: &[f64]) -> ur3_kin::nalgebra::Point3<f64> {
    let links = ur3_kin::urdf::link_poses(&ur3_kin::UR3, q);
    let link = links.iter().find(|(n, _)| *n == frame).unwrap_or_else(|| panic!("no link {frame}")).1;
    link * ur3_kin::nalgebra::Point3::new(p[0], p[1], p[2])
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]
    /// Each arm capsule drawn through its URDF link lies where tile-sim puts it: the end spheres
    /// and the cylinder's ends at tile-sim's capsule end points (its DH frames from the env's own
    /// `link_poses`), same radius, within 1e-6 m.
    #[test]
    fn arm_capsules_coincide_with_tile_sims(q in proptest::array::uniform6(-3.1f64..3.1)) {
        let mut env = tile_sim::Env::new(Task::TileSuction, 0);
        env.set_joints(q).unwrap();
        let frames = env.link_poses();
        let ents = arm_capsule_entities(&ur3_kin::UR3);
        let scene = tile_sim::episode_scene(Task::TileSuction, 0);
        let caps: Vec<_> = scene.items.iter().filter_map(|it| match (it.frame, it.shape) {
            (tile_sim::SceneFrame::Link(i), tile_sim::Shape::Capsule { a, b, radius }) => Some((it.name, i, a, b, radius)),
            _ => None,
        }).collect();
        proptest::prop_assert_eq!(caps.len(), 8);
        proptest::prop_assert_eq!(ents.len(), caps.len());
        for (name, i, a, b, radius) in caps {
            let e = ents.iter().find(|e| e.id == format!("robot/{name}")).unwrap();
            let f = frames[usize::from(i)];
            let dh = ur3_kin::Pose::from_parts(
                ur3_kin::nalgebra::Translation3::new(f.t[0], f.t[1], f.t[2]),
                ur3_kin::nalgebra::UnitQuaternion::new_normalize(ur3_kin::nalgebra::Quaternion::new(f.q[3], f.q[0], f.q[1], f.q[2])),
            );
            let sim = |p: [f32; 3]| dh * ur3_kin::nalgebra::Point3::from(p.map(f64::from));
            let (sa, sb) = (sim(a), sim(b));
            // the two spheres
            let prims: Vec<_> = e.primitives().collect();
            proptest::prop_assert_eq!(prims.len(), 3);
            let (ca, cb) = (in_base(&q, &e.frame_id, &prims[1].pose.position), in_base(&q, &e.frame_id, &prims[2].pose.position));
            proptest::prop_assert!((ca - sa).norm() < 1e-6 && (cb - sb).norm() < 1e-6, "{} spheres", name);
            // the cylinder: centre ± half its height along its z axis
            let c = prims[0];
            let o = c.pose.orientation;
            let rot = ur3_kin::nalgebra::UnitQuaternion::new_normalize(ur3_kin::nalgebra::Quaternion::new(o[3], o[0], o[1], o[2]));
            let half = rot * ur3_kin::nalgebra::Vector3::new(0.0, 0.0, c.size[2] / 2.0);
            let p = c.pose.position;
            let (e0, e1) = ([p[0] - half.x, p[1] - half.y, p[2] - half.z], [p[0] + half.x, p[1] + half.y, p[2] + half.z]);
            proptest::prop_assert!((in_base(&q, &e.frame_id, &e0) - sa).norm() < 1e-6, "{} cylinder end a", name);
            proptest::prop_assert!((in_base(&q, &e.frame_id, &e1) - sb).norm() < 1e-6, "{} cylinder end b", name);
            for pr in &prims {
                proptest::prop_assert!((pr.size[0] - 2.0 * f64::from(radius)).abs() < 1e-6);
                proptest::prop_assert_eq!(pr.size[0], pr.size[1]);
            }
            proptest::prop_assert!(ur3_kin::urdf::LINKS.contains(&e.frame_id.as_str()));
        }
    }
}

#[test]
fn a_rows_tiles_are_drawn_each_in_its_own_frame() {
    let scene = tile_sim::episode_scene(Task::TileRow, 4);
    let ents = scene_entities(&scene);
    for (i, frame) in demo_log::ROW_FRAMES[..3].iter().enumerate() {
        let tile = ents.iter().find(|e| e.id == format!("tile_{i}")).unwrap_or_else(|| panic!("no tile_{i}"));
        assert_eq!(tile.frame_id, *frame);
        assert_eq!(tile.size, [0.15, 0.15, 0.01]);
        assert!(ents.iter().any(|e| e.id == format!("pad_{i}") && e.frame_id == "base"));
    }
    assert!(
        !ents.iter().any(|e| e.frame_id == TILE_FRAME),
        "a row's tiles are not in the current tile's frame"
    );
}
