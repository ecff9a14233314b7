//! A demo records the scene it is handed (after the robot's link cylinders unless it draws the
//! robot); metadata from JSON; frame poses against FK.

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
fn the_handed_scene_is_recorded_after_the_robot() {
    let d = tmpdir("scene-handed");
    let p = d.join("r.mcap");
    let meta = meta(0); // common::scene(): table, tile, target, cup0
    let mut w = DemoWriter::create(&p, &meta).unwrap();
    w.write_step(&step(0, 2, 16, 7)).unwrap();
    w.finish(&EpisodeSummary::default()).unwrap();
    let ents = first_scene(&p);
    let robot = robot_link_entities(&ur3_kin::UR3);
    assert_eq!(ents.len(), robot.len() + meta.scene.len());
    let ids: Vec<_> = ents.iter().map(|e| e["id"].as_str().unwrap()).collect();
    let want: Vec<_> = robot.iter().chain(&meta.scene).map(|e| e.id.as_str()).collect();
    assert_eq!(ids, want);
    assert_eq!(find(&ents, "table")["cubes"][0]["size"]["x"], 0.8); // the caller's table, unchanged
}

#[test]
fn a_scene_that_draws_the_robot_is_recorded_alone() {
    let d = tmpdir("scene-own-robot");
    let p = d.join("o.mcap");
    let mut meta = meta(0);
    let mut arm = meta.scene[0].clone();
    arm.id = "robot/arm".into();
    meta.scene.push(arm);
    let mut w = DemoWriter::create(&p, &meta).unwrap();
    w.write_step(&step(0, 2, 16, 7)).unwrap();
    w.finish(&EpisodeSummary::default()).unwrap();
    let ids: Vec<_> = first_scene(&p).iter().map(|e| e["id"].as_str().unwrap().to_string()).collect();
    assert_eq!(ids, meta.scene.iter().map(|e| e.id.clone()).collect::<Vec<_>>());
}

#[test]
fn a_demo_without_a_scene_draws_the_robot_only() {
    let ents = {
        let d = tmpdir("scene-none");
        let p = d.join("u.mcap");
        let meta = EpisodeMeta { task: "juggling".into(), ..Default::default() };
        let mut w = DemoWriter::create(&p, &meta).unwrap();
        w.write_step(&step(0, 2, 16, 7)).unwrap();
        w.finish(&EpisodeSummary::default()).unwrap();
        first_scene(&p)
    };
    let ids: Vec<_> = ents.iter().map(|e| e["id"].as_str().unwrap()).collect();
    let robot = robot_link_entities(&ur3_kin::UR3);
    assert_eq!(ids, robot.iter().map(|e| e.id.as_str()).collect::<Vec<_>>());
    assert!(ids.iter().all(|id| id.starts_with("robot/")) && ids.len() >= 5, "{ids:?}");
}

#[test]
fn frame_poses_end_at_fk_and_carry_the_tile() {
    let q = [0.3, -1.2, 1.1, -0.4, -1.5, 0.7];
    let tile = Pose { position: [0.1, 0.32, 0.005], orientation: [0.0, 0.0, 0.0, 1.0] };
    let f = frame_poses(&ur3_kin::UR3, &q, &tile, &[]);
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
fn frame_numbers_by_model_name() {
    let q = [0.1, -1.0, 1.2, -0.4, 0.3, 0.9];
    let tile = Pose { position: [0.1, 0.2, 0.3], orientation: [0.0, 0.0, 0.0, 1.0] };
    let f = frame_numbers("ur3", &q, &tile, &[]).unwrap();
    for (name, p) in frame_poses(&ur3_kin::UR3, &q, &tile, &[]) {
        assert_eq!(f[name], p.to_numbers());
    }
    assert_eq!(f.len(), 9);
    assert!(frame_numbers("nope", &q, &tile, &[]).is_err());
}
