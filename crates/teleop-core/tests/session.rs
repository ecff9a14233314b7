//! The session's clock, counts, refusals and recording, with the real simulator.

use demo_log::{DemoError, HandFrame, StepRecord};
use teleop_core::{Frame, Links, Recorder, Session, SessionConfig, TeleopError};
use tile_sim::Task;
use ur3_kin::{Calibration, HandLayout, Handedness};

fn session(task: Task) -> Session {
    let cfg = SessionConfig {
        task,
        layout: HandLayout::WebXr,
        handedness: Handedness::Right,
        calibration: Calibration::default(),
        seed: 3,
    };
    Session::new(cfg).unwrap()
}

/// A right hand in WebXR order: wrist at the origin, fingers along +y, palm down.
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
}

impl Recorder for Count {
    fn hand_frame(&mut self, _: &HandFrame, t: f64) -> Result<(), DemoError> {
        self.hands.push(t);
        Ok(())
    }
    fn step(&mut self, rec: &StepRecord, links: &Links) -> Result<(), DemoError> {
        self.steps.push((rec.step, rec.t, links.len()));
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
        let f = Frame {
            t: 10.0 + k as f64 / 90.0,
            tracked: true,
            joints: &j,
            raw: Some("opening"),
            gesture: Some("opening"),
        };
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
    let f = |t, tracked, joints, raw| Frame { t, tracked, joints, raw, gesture: Some("fixed") };
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
    let e = s.push(&Frame { t: 0.0, tracked: true, joints: &short, raw: None, gesture: None }, None);
    assert!(matches!(e, Err(TeleopError::JointCount { expected: 25, got: 21, .. })));
    let e = s.push(&Frame { t: f64::NAN, tracked: true, joints: &j, raw: None, gesture: None }, None);
    assert!(matches!(e, Err(TeleopError::Time(_))));
    let e =
        s.push(&Frame { t: 0.0, tracked: true, joints: &j, raw: Some("weld"), gesture: Some("weld") }, None);
    assert_eq!(e.unwrap_err().to_string(), "unknown gesture class \"weld\"");
    assert_eq!(s.counts().frames, 0, "a refused frame is not counted");
}

#[test]
fn the_gesture_commands_the_end_effector() {
    let mut s = session(Task::Screw);
    let j = hand();
    let mut cmds = Vec::new();
    for (k, g) in ["closing_tightening", "opening_stopped", "opening_stopped"].iter().enumerate() {
        let f = Frame { t: k as f64 * 0.1, tracked: true, joints: &j, raw: Some(g), gesture: Some(g) };
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
