//! Every demo's scene is complete (table, tile locked to `tile`, target, end effector locked to
//! `tool0`) whatever the caller passed; metadata from JSON; frame poses against FK.

mod common;

use common::*;
use demo_log::*;
use serde_json::json;

fn first_scene(path: &std::path::Path) -> Vec<serde_json::Value> {
    let (msgs, _) = salvage(path).unwrap();
    let m = msgs.iter().find(|m| m.topic == TOPIC_SCENE).expect("a /scene message");
    let v: serde_json::Value = serde_json::from_slice(&m.data).unwrap();
    v["entities"].as_array().unwrap().clone()
}

fn find<'a>(ents: &'a [serde_json::Value], id: &str) -> &'a serde_json::Value {
    ents.iter().find(|e| e["id"] == id).unwrap_or_else(|| panic!("no entity {id}"))
}

#[test]
fn a_demo_without_caller_scene_has_the_task_scene() {
    let d = tmpdir("scene-bare");
    for (task, tool_ids, object) in [
        ("TileSuction", vec!["suction_plate", "cup_0", "cup_1", "cup_2", "cup_3"], "tile"),
        ("BlockGrip", vec!["gripper_body", "finger_left", "finger_right"], "block"),
        ("Screw", vec!["gripper_body", "finger_left", "finger_right"], "nut"),
    ] {
        let p = d.join(format!("{task}.mcap"));
        let meta = EpisodeMeta { task: task.into(), seed: 3, ..Default::default() };
        let mut w = DemoWriter::create(&p, &meta).unwrap();
        w.write_step(&step(0, 2, 16, 7)).unwrap();
        w.finish(&EpisodeSummary::default()).unwrap();
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
        // ids are unique within the message
        let mut ids: Vec<_> = ents.iter().map(|e| e["id"].as_str().unwrap().to_string()).collect();
        ids.sort();
        ids.dedup();
        assert_eq!(ids.len(), ents.len());
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
fn caller_entities_replace_task_entities_of_the_same_id() {
    let d = tmpdir("scene-replace");
    let p = d.join("r.mcap");
    let mut w = DemoWriter::create(&p, &meta(0)).unwrap(); // common::scene(): table, tile, target, cup0
    w.write_step(&step(0, 2, 16, 7)).unwrap();
    w.finish(&EpisodeSummary::default()).unwrap();
    let ents = first_scene(&p);
    assert_eq!(ents.iter().filter(|e| e["id"] == "table").count(), 1);
    assert_eq!(find(&ents, "table")["cubes"][0]["size"]["x"], 0.8); // the caller's table
    assert!(ents.iter().any(|e| e["id"] == "cup_0") && ents.iter().any(|e| e["id"] == "cup0"));
}

#[test]
fn unknown_task_gets_the_robot_only() {
    let ents = {
        let d = tmpdir("scene-unknown");
        let p = d.join("u.mcap");
        let meta = EpisodeMeta { task: "juggling".into(), ..Default::default() };
        let mut w = DemoWriter::create(&p, &meta).unwrap();
        w.write_step(&step(0, 2, 16, 7)).unwrap();
        w.finish(&EpisodeSummary::default()).unwrap();
        first_scene(&p)
    };
    assert!(!ents.is_empty());
    assert!(ents.iter().all(|e| e["id"].as_str().unwrap().starts_with("robot/")));
}

#[test]
fn frame_poses_end_at_fk_and_carry_the_tile() {
    let q = [0.3, -1.2, 1.1, -0.4, -1.5, 0.7];
    let tile = Pose { position: [0.1, 0.32, 0.005], orientation: [0.0, 0.0, 0.0, 1.0] };
    let f = frame_poses(&ur3_kin::UR3, &q, &tile);
    let names: Vec<_> = f.iter().map(|x| x.0).collect();
    assert_eq!(&names[..8], &LINK_FRAMES[..]);
    assert_eq!(names[8], TILE_FRAME);
    let t = Pose::from_isometry(&ur3_kin::fk(&ur3_kin::UR3, &q));
    let tool0 = f[7].1;
    for i in 0..3 {
        assert!((tool0.position[i] - t.position[i]).abs() < 1e-12);
    }
    assert_eq!(f[8].1, tile);
}

#[test]
fn episode_meta_from_json() {
    let v = json!({
        "episode": 4, "task": "TileSuction", "seed": 9, "robot_model": "ur3", "control_dt": 0.04,
        "hand": {"layout": "mediapipe", "space": "openxr", "handedness": "left", "units": "m"},
        "scene": [{"id": "m", "kind": "sphere", "size": [0.01, 0.01, 0.01]},
                  {"id": "t", "kind": "cube", "size": [1, 1, 1], "frame_id": "tile",
                   "pose": [[1, 0, 0, 0.5], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]], "color": [1, 0, 0, 1]}],
        "extra": {"note": "x", "n": 3, "flag": true, "rate": 90.0},
        "source_handlog": null
    });
    let m = EpisodeMeta::from_json(&v).unwrap();
    assert_eq!((m.episode, m.seed, m.task.as_str(), m.control_dt), (4, 9, "TileSuction", 0.04));
    assert_eq!(m.hand.unwrap().handedness, ur3_kin::Handedness::Left);
    assert_eq!(m.scene[0].frame_id, BASE_FRAME);
    assert_eq!(m.scene[0].pose, Pose::IDENTITY);
    assert_eq!(m.scene[0].color, DEFAULT_ENTITY_COLOR);
    assert_eq!(m.scene[1].pose.position, [0.5, 0.0, 0.0]);
    assert_eq!(m.extra["n"], "3");
    assert_eq!(m.extra["flag"], "true");
    assert_eq!(m.extra["rate"], "90.0");
    assert_eq!(m.source_handlog, None);
    let e = EpisodeMeta::from_json(&json!({"colour": 1})).unwrap_err().to_string();
    assert!(e.starts_with("unknown episode meta key \"colour\" (known: episode, task"), "{e}");
    assert!(EpisodeMeta::from_json(&json!({"seed": -1})).is_err());
    assert!(
        EpisodeMeta::from_json(&json!({"scene": [{"id": "a", "kind": "cone", "size": [1, 1, 1]}]})).is_err()
    );
    let e = Pose::from_numbers(&[0.0; 3], "ee_pose").unwrap_err().to_string();
    assert_eq!(e, "ee_pose must be [x, y, z, qx, qy, qz, qw] (7 numbers), got 3");
    let mut sheared = [0.0; 16];
    for i in 0..4 {
        sheared[i * 5] = 1.0;
    }
    sheared[1] = 0.4;
    assert!(Pose::from_numbers(&sheared, "T").is_err());
}

#[test]
fn entity_lists_from_json() {
    let v = json!([{"id": "a", "kind": "cube", "size": [1, 2, 3]}, {"id": "b", "kind": "sphere", "size": [1, 1, 1]}]);
    let ents = SceneEntity::list_from_json(&v, "scene").unwrap();
    assert_eq!(ents.iter().map(|e| e.id.as_str()).collect::<Vec<_>>(), ["a", "b"]);
    let e = SceneEntity::list_from_json(&json!({"id": "a"}), "scene").unwrap_err().to_string();
    assert!(e.contains("scene must be a list"), "{e}");
    assert!(SceneEntity::list_from_json(&json!([{"id": "a"}]), "scene").is_err());
}

#[test]
fn scene_json_and_frame_numbers_by_model_name() {
    let ents = episode_scene_json("UR3", Task::Screw, 4).unwrap();
    let want = episode_scene(&ur3_kin::UR3, Task::Screw, 4);
    assert_eq!(ents, want.iter().map(|e| foxglove_entity(e, 0)).collect::<Vec<_>>());
    assert!(
        episode_scene_json("ur4", Task::Screw, 4).unwrap_err().to_string().contains("unknown robot model")
    );
    let q = [0.1, -1.0, 1.2, -0.4, 0.3, 0.9];
    let tile = Pose { position: [0.1, 0.2, 0.3], orientation: [0.0, 0.0, 0.0, 1.0] };
    let f = frame_numbers("ur3", &q, &tile).unwrap();
    for (name, p) in frame_poses(&ur3_kin::UR3, &q, &tile) {
        assert_eq!(f[name], p.to_numbers());
    }
    assert_eq!(f.len(), 9);
    assert!(frame_numbers("nope", &q, &tile).is_err());
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
        let ents = arm_capsule_entities();
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
fn the_ur3_is_drawn_as_capsules_other_models_as_link_cylinders() {
    let ur3 = robot_entities(&ur3_kin::UR3);
    assert_eq!(ur3, arm_capsule_entities());
    assert!(ur3.iter().all(|e| e.extra.len() == 2 && e.extra.iter().all(|p| p.kind == Shape::Sphere)));
    let ur5 = robot_entities(&ur3_kin::UR5);
    assert_eq!(ur5, robot_link_entities(&ur3_kin::UR5));
    // a capsule is one Foxglove entity: one cylinder, two spheres
    let j = foxglove_entity(&ur3[2], 0);
    assert_eq!((j["cylinders"].as_array().unwrap().len(), j["spheres"].as_array().unwrap().len()), (1, 2));
}
