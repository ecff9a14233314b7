//! The session's clock, counts, refusals and recording, with the real simulator.

use demo_log::{DemoError, HandFrame, StepRecord};
use teleop_core::{ClutchInput, Frame, Links, Mapping, Recorder, Session, SessionConfig, TeleopError};
use tile_sim::Task;
use ur3_kin::nalgebra::{UnitQuaternion, Vector3};
use ur3_kin::{Calibration, HandLayout, Handedness};

fn session(task: Task) -> Session {
    session_with(task, Mapping::Absolute)
}

fn session_with(task: Task, mapping: Mapping) -> Session {
    let cfg = SessionConfig {
        task,
        layout: HandLayout::WebXr,
        handedness: Handedness::Right,
        calibration: Calibration::default(),
        seed: 3,
        mapping,
        spec: None,
    };
    Session::new(cfg).unwrap()
}

/// A right hand in WebXR order: wrist at the origin, fingers along +y, palm down.
/// A tracked frame of `joints` at `t` whose gesture (raw and smoothed) is `gesture`, no clutch.
fn tracked<'a>(t: f64, joints: &'a [[f64; 3]], gesture: &'a str) -> Frame<'a> {
    Frame { t, tracked: true, joints, raw: Some(gesture), gesture: Some(gesture), clutch: None }
}

fn hand() -> Vec<[f64; 3]> {
    let mut j = vec![[0.0; 3]; 25];
    let l = HandLayout::WebXr;
    j[l.index_proximal()] = [0.02, 0.08, 0.0];
    j[l.middle_proximal()] = [0.0, 0.09, 0.0];
    j
}

#[derive(Default)]
struct Count {
    hands: Vec<f64>,
    steps: Vec<(u64, f64, usize)>,
    /// each step's row poses (a row's tiles; empty for one object)
    rows: Vec<Vec<demo_log::Pose>>,
}

impl Recorder for Count {
    fn hand_frame(&mut self, _: &HandFrame, t: f64) -> Result<(), DemoError> {
        self.hands.push(t);
        Ok(())
    }
    fn step(&mut self, rec: &StepRecord, links: &Links) -> Result<(), DemoError> {
        self.steps.push((rec.step, rec.t, links.len()));
        self.rows.push(rec.row_poses.clone());
        Ok(())
    }
}

#[test]
fn steps_run_at_the_control_rate_in_the_hands_clock() {
    let mut s = session(Task::TileSuction);
    let mut rec = Count::default();
    let j = hand();
    let mut steps = 0;
    for k in 0..=90 {
        let f = tracked(10.0 + k as f64 / 90.0, &j, "opening");
        steps += s.push(&f, Some(&mut rec)).unwrap().len();
    }
    // one second of frames: the steps due at 0, 0.04, ..., 0.96 s ran before the last frame
    assert_eq!(steps, 25);
    assert_eq!(s.counts().frames, 91);
    assert_eq!(rec.hands.len(), 91);
    assert_eq!(rec.hands[0], 0.0);
    assert!(s.target().is_some());
    let last = s.finish(Some(&mut rec)).unwrap();
    assert_eq!(last.len(), 2, "the steps up to one period past the last frame (1.00 and 1.04 s)");
    assert_eq!(rec.steps.len(), 27);
    for (i, (step, t, links)) in rec.steps.iter().enumerate() {
        assert_eq!(*step, i as u64);
        assert!((t - i as f64 * 0.04).abs() < 1e-12, "step {i} at {t}");
        assert_eq!(*links, 8);
    }
    assert_eq!(s.counts().gestures, vec![("opening".to_string(), 91)]);
}

#[test]
fn unusable_frames_are_counted_and_keep_the_target() {
    let mut s = session(Task::BlockGrip);
    let j = hand();
    let garbage = vec![[0.0; 3]; 25];
    let f = |t, tracked, joints, raw| Frame { t, tracked, joints, raw, gesture: Some("fixed"), clutch: None };
    // the first frame passes the filter as it is: collinear (collapsed) joints give no target
    s.push(&f(0.0, true, &garbage, Some("fixed")), None).unwrap();
    assert!(s.target().is_none());
    s.push(&f(0.01, true, &j, Some("fixed")), None).unwrap();
    let held = *s.target().unwrap();
    s.push(&f(0.02, false, &garbage, None), None).unwrap();
    s.push(&f(0.03, true, &j, None), None).unwrap(); // the model read nothing
    assert_eq!(*s.target().unwrap(), held);
    let c = s.counts();
    assert_eq!((c.frames, c.untracked, c.degenerate), (4, 1, 2));
    assert_eq!(c.gestures, vec![("fixed".to_string(), 2)]);
}

#[test]
fn bad_frames_are_refused_by_name() {
    let mut s = session(Task::Screw);
    let j = hand();
    let short = vec![[0.0; 3]; 21];
    let e = s
        .push(&Frame { t: 0.0, tracked: true, joints: &short, raw: None, gesture: None, clutch: None }, None);
    assert!(matches!(e, Err(TeleopError::JointCount { expected: 25, got: 21, .. })));
    let e = s.push(
        &Frame { t: f64::NAN, tracked: true, joints: &j, raw: None, gesture: None, clutch: None },
        None,
    );
    assert!(matches!(e, Err(TeleopError::Time(_))));
    let e = s.push(
        &Frame { t: 0.0, tracked: true, joints: &j, raw: Some("weld"), gesture: Some("weld"), clutch: None },
        None,
    );
    assert_eq!(e.unwrap_err().to_string(), "unknown gesture class \"weld\"");
    assert_eq!(s.counts().frames, 0, "a refused frame is not counted");
}

#[test]
fn the_gesture_commands_the_end_effector() {
    let mut s = session(Task::Screw);
    let j = hand();
    let mut cmds = Vec::new();
    for (k, g) in ["closing_tightening", "opening_stopped", "opening_stopped"].iter().enumerate() {
        let f = tracked(k as f64 * 0.1, &j, g);
        for st in s.push(&f, None).unwrap() {
            cmds.push((st.action[6], st.action[7]));
        }
    }
    // the steps at 0, 0.04 and 0.08 s run before the second frame: the first frame's gesture;
    // those at 0.12 and 0.16 s the second's
    assert_eq!(cmds, vec![(1.0, 1.0), (1.0, 1.0), (1.0, 1.0), (-1.0, 0.0), (-1.0, 0.0)]);
    assert_eq!(s.counts().gesture_changes, 1);
    assert_eq!(s.command(), (-1.0, 0.0));
}

/// A right hand at `p` (tracking space) turned by `r`: wrist, index and middle knuckles.
fn hand_at(p: Vector3<f64>, r: &UnitQuaternion<f64>) -> Vec<[f64; 3]> {
    let mut j = vec![[0.0; 3]; 25];
    let l = HandLayout::WebXr;
    let put = |v: Vector3<f64>| [v.x, v.y, v.z];
    j[l.wrist()] = put(p);
    j[l.index_proximal()] = put(p + r * Vector3::new(0.02, 0.08, 0.0));
    j[l.middle_proximal()] = put(p + r * Vector3::new(0.0, 0.09, 0.0));
    j
}

fn tool(s: &Session) -> Vector3<f64> {
    Vector3::from(s.snapshot().tool0.t)
}

/// Drive `s` with the hand moving from `a` to `b` (tracking space) over `secs` at 90 Hz, turned
/// by `r`; returns every step's reason for not following.
fn sweep(
    s: &mut Session,
    t0: f64,
    secs: f64,
    a: Vector3<f64>,
    b: Vector3<f64>,
    r: &UnitQuaternion<f64>,
) -> Vec<Option<&'static str>> {
    let n = (secs * 90.0) as usize;
    let mut why = Vec::new();
    for k in 0..n {
        let u = k as f64 / (n - 1).max(1) as f64;
        let j = hand_at(a + (b - a) * u, r);
        let f = tracked(t0 + k as f64 / 90.0, &j, "fixed");
        why.extend(s.push(&f, None).unwrap().into_iter().map(|st| st.why.map(|w| w.text())));
    }
    why
}

#[test]
fn under_the_clutch_any_hand_orientation_drives_the_tool_by_the_hands_motion() {
    let mut seed = 11u64;
    let mut rnd = || {
        seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 2.0 * std::f64::consts::PI
    };
    let p = Vector3::new(0.1, -0.3, -0.4);
    let calib = Calibration::default();
    for _ in 0..8 {
        let r = UnitQuaternion::from_euler_angles(rnd(), rnd() / 2.0, rnd());
        let mut s = session_with(Task::TileSuction, Mapping::Clutch);
        let start = tool(&s);
        let still = sweep(&mut s, 0.0, 0.5, p, p, &r);
        assert!(still.iter().all(Option::is_none), "{r:?}: {still:?}");
        assert!(
            (tool(&s) - start).norm() < 1e-4,
            "the arm jumped at engagement: {}",
            (tool(&s) - start).norm()
        );
        let d = Vector3::new(0.05, 0.02, -0.03);
        let moving = sweep(&mut s, 0.5, 0.5, p, p + d, &r);
        let rest = sweep(&mut s, 1.0, 1.0, p + d, p + d, &r);
        assert!(moving.iter().chain(&rest).all(Option::is_none), "{r:?}: {moving:?} {rest:?}");
        let want = calib.point_to_base(&(p + d)) - calib.point_to_base(&p);
        assert!((tool(&s) - start - want).norm() < 2e-3, "moved {:?}, asked {want:?}", tool(&s) - start);
    }
}

#[test]
fn a_far_jump_of_the_hand_is_followed_along_a_bounded_path() {
    let r = UnitQuaternion::identity();
    let p = Vector3::new(0.0, -0.3, -0.4);
    let mut s = session_with(Task::BlockGrip, Mapping::Clutch);
    sweep(&mut s, 0.0, 0.3, p, p, &r);
    let start = tool(&s);
    let far = p + Vector3::new(0.08, -0.06, 0.0); // 10 cm in one frame
    let mut last = start;
    let mut steps = 0;
    let mut why = Vec::new();
    for k in 0..180 {
        let j = hand_at(far, &r);
        let f = tracked(0.3 + k as f64 / 90.0, &j, "fixed");
        for st in s.push(&f, None).unwrap() {
            why.push(st.why);
            let now = tool(&s);
            assert!((now - last).norm() < 0.02 + 1e-3, "step {steps} moved {}", (now - last).norm());
            last = now;
            steps += 1;
        }
    }
    assert!(why.iter().all(Option::is_none), "{why:?} at {:?}, q {:?}", tool(&s), s.snapshot().q);
    let calib = Calibration::default();
    let want = calib.point_to_base(&far) - calib.point_to_base(&p);
    assert!((tool(&s) - start - want).norm() < 2e-3);
}

#[test]
fn a_released_clutch_lets_the_hand_reposition() {
    let r = UnitQuaternion::identity();
    let p = Vector3::new(0.0, -0.3, -0.4);
    let mut s = session_with(Task::TileSuction, Mapping::Clutch);
    sweep(&mut s, 0.0, 0.3, p, p, &r);
    let start = tool(&s);
    let j = hand_at(p, &r);
    let release = Frame {
        t: 0.3,
        tracked: true,
        joints: &j,
        raw: Some("fixed"),
        gesture: Some("fixed"),
        clutch: Some(ClutchInput::Release),
    };
    s.push(&release, None).unwrap();
    assert!(!s.engaged());
    let moved = p + Vector3::new(0.1, 0.1, 0.0);
    let mut why = sweep(&mut s, 0.31, 0.5, p, moved, &r);
    why.extend(sweep(&mut s, 0.81, 0.5, moved, moved, &r)); // settled (the filter's lag gone)
    assert!(why[1..].iter().all(|w| *w == Some("not engaged")), "{why:?}");
    assert!((tool(&s) - start).norm() < 1e-3, "the tool followed a released hand");
    let j = hand_at(moved, &r);
    let engage = Frame {
        t: 1.32,
        tracked: true,
        joints: &j,
        raw: Some("fixed"),
        gesture: Some("fixed"),
        clutch: Some(ClutchInput::Engage),
    };
    s.push(&engage, None).unwrap();
    assert!(s.engaged());
    let why = sweep(&mut s, 1.33, 0.5, moved, moved, &r);
    assert!(why.iter().all(Option::is_none));
    assert!((tool(&s) - start).norm() < 1e-3, "the tool jumped at re-engagement");
}

#[test]
fn a_rows_steps_record_and_frame_every_tile() {
    let mut s = session(Task::TileRow);
    let mut rec = Count::default();
    let j = hand();
    for k in 0..=45 {
        let f = tracked(k as f64 / 90.0, &j, "opening");
        s.push(&f, Some(&mut rec)).unwrap();
    }
    assert!(!rec.rows.is_empty());
    let snap = s.snapshot();
    assert_eq!(snap.row.len(), 3);
    let frames = s.frame_numbers();
    for (i, (frame, r)) in demo_log::ROW_FRAMES.iter().zip(&snap.row).enumerate() {
        let want = demo_log::Pose { position: r.object.t, orientation: r.object.q };
        assert_eq!(frames[frame], want.to_numbers(), "frame {frame}");
        // the newest step recorded the tiles where the snapshot has them; they rest on the
        // table (settling by ~1 mm in the first steps), so every step recorded them near it
        assert_eq!(rec.rows.last().unwrap()[i], want);
        for poses in &rec.rows {
            assert_eq!(poses.len(), 3);
            assert!(
                (0..3).all(|k| (poses[i].position[k] - want.position[k]).abs() < 2e-3),
                "tile {i}: {poses:?} vs {want:?}"
            );
        }
    }
    assert!(!frames.contains_key(demo_log::ROW_FRAMES[3]));
    // one object: no row frames
    assert!(!session(Task::TileSuction).frame_numbers().contains_key(demo_log::ROW_FRAMES[0]));
}

#[test]
fn the_joint_action_is_in_units_of_the_specs_joint_step() {
    // A spec with a smaller joint step than the built-in 0.04 rad: an action the session sends
    // that does not saturate puts the arm on its IK answer in that one step (the tool on the
    // target the step used), which it would only half reach if the action were in units of 0.04.
    let step = 0.02;
    let text = tile_sim::TaskSpec::builtin_toml(Task::TileSuction).replacen(
        "model = \"ur3\"\n",
        &format!("model = \"ur3\"\njoint_step = {step}\n"),
        1,
    );
    let spec = std::sync::Arc::new(tile_sim::TaskSpec::from_toml(&text, "slow.toml").unwrap());
    let cfg = SessionConfig {
        task: Task::TileSuction,
        layout: HandLayout::WebXr,
        handedness: Handedness::Right,
        calibration: Calibration::default(),
        seed: 3,
        mapping: Mapping::Clutch,
        spec: Some(spec),
    };
    let mut s = Session::new(cfg).unwrap();
    assert_eq!(s.env().joint_step(), step);
    let r = UnitQuaternion::identity();
    let p = Vector3::new(0.0, -0.3, -0.4);
    let (mut exact, mut saturated) = (0, 0);
    for k in 0..180 {
        // still for 0.3 s, then 3 cm away in one frame, held there
        let at = if k < 27 { p } else { p + Vector3::new(0.03, 0.0, -0.01) };
        let j = hand_at(at, &r);
        let f = tracked(k as f64 / 90.0, &j, "fixed");
        // a push runs the steps that fell due with the target of the frames before it
        let target = s.target_pose();
        let q0 = s.snapshot().q;
        let steps = s.push(&f, None).unwrap();
        assert!(steps.len() <= 1);
        for st in steps {
            assert!(st.why.is_none(), "{:?}", st.why);
            let q1 = s.snapshot().q;
            for i in 0..6 {
                assert!((q1[i] - q0[i] - f64::from(st.action[i]) * step).abs() < 1e-6, "joint {i}");
            }
            if st.action[..6].iter().any(|a| a.abs() >= 1.0) {
                saturated += 1;
            } else if let Some(t) = &target {
                let off = Vector3::from(s.snapshot().tool0.t) - Vector3::from(t.position);
                assert!(off.norm() < 1e-6, "step {}: the tool is {} m off its target", st.index, off.norm());
                exact += 1;
            }
        }
    }
    assert!(saturated > 0 && exact > 20, "saturated {saturated}, exact {exact}");
}
