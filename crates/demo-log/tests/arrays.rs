//! Hand logs, frames and reports in the bindings' array and dict layout.

mod common;

use common::*;
use demo_log::serde_json::{Value, json};
use demo_log::*;
use ur3_kin::{HandLayout, Handedness, Space};

fn log(n: usize, with_orientations: bool) -> HandLog {
    let mut frames: Vec<HandFrame> = (0..n).map(|i| hand_frame(i, HandLayout::MediaPipe)).collect();
    if with_orientations {
        for (i, f) in frames.iter_mut().enumerate() {
            f.orientations = Some((0..21).map(|k| [0.0, 0.0, (i * k) as f64 * 1e-3, 1.0]).collect());
        }
    }
    HandLog { header: HandLogHeader::new(HandLayout::MediaPipe, Space::OpenXr, Handedness::Right), frames }
}

#[test]
fn to_arrays_is_row_major_and_from_arrays_inverts_it() {
    for with_o in [false, true] {
        let l = log(4, with_o);
        let a = l.to_arrays();
        assert_eq!((a.t.shape.as_slice(), a.tracked.shape.as_slice()), (&[4][..], &[4][..]));
        assert_eq!(a.joints.shape, [4, 21, 3]);
        // Element (i, k, c) sits at ((i * 21) + k) * 3 + c.
        for (i, f) in l.frames.iter().enumerate() {
            assert_eq!(a.t.data[i], f.t);
            for (k, p) in f.joints.iter().enumerate() {
                for (c, x) in p.iter().enumerate() {
                    assert_eq!(a.joints.data[(i * 21 + k) * 3 + c], *x);
                }
            }
        }
        match (&a.orientations, with_o) {
            (Some(o), true) => {
                assert_eq!(o.shape, [4, 21, 4]);
                assert!((o.data[(3 * 21 + 5) * 4 + 2] - 0.015).abs() < 1e-15);
            }
            (None, false) => {}
            (o, _) => panic!("orientations {o:?} with_o={with_o}"),
        }
        assert_eq!(HandLog::from_arrays(l.header.clone(), &a).unwrap(), l);
    }
    // No frames: empty arrays of the layout's shape, no orientations.
    let a = log(0, true).to_arrays();
    assert_eq!((a.joints.shape.as_slice(), a.orientations), (&[0, 21, 3][..], None));
}

#[test]
fn from_arrays_names_the_expected_shapes() {
    let l = log(2, true);
    let mut a = l.to_arrays();
    a.joints = NdArray::new(vec![2, 20, 3], vec![0.0; 120]).unwrap();
    let e = HandLog::from_arrays(l.header.clone(), &a).unwrap_err().to_string();
    assert_eq!(
        e,
        "t (T,), tracked (T,), joints (T, 21, 3) expected for layout mediapipe; got [2], [2], [2, 20, 3]"
    );
    let mut a = l.to_arrays();
    a.tracked = NdArray::vector(vec![true]);
    assert!(HandLog::from_arrays(l.header.clone(), &a).is_err());
    let mut a = l.to_arrays();
    a.orientations = Some(NdArray::new(vec![2, 21, 3], vec![0.0; 126]).unwrap());
    assert_eq!(
        HandLog::from_arrays(l.header.clone(), &a).unwrap_err().to_string(),
        "orientations must be (T, 21, 4), got [2, 21, 3]"
    );
}

#[test]
fn header_fields_fill_every_optional_key_and_the_joint_count() {
    let mut l = log(1, false);
    let h = l.header_fields();
    assert_eq!(h["joint_count"], json!(21));
    for k in ["task", "episode_seed", "source", "extra"] {
        assert_eq!(h[k], Value::Null, "{k}");
    }
    assert_eq!(h["layout"], json!("mediapipe"));
    l.header.task = Some("suction".into());
    l.header.episode_seed = Some(7);
    let h = l.header_fields();
    assert_eq!((h["task"].clone(), h["episode_seed"].clone()), (json!("suction"), json!(7)));
}

#[test]
fn hand_frame_from_arrays_checks_shapes() {
    let j = NdArray::new(vec![2, 3], vec![0.1, 0.2, 0.3, 0.4, 0.5, 0.6]).unwrap();
    let o = NdArray::new(vec![2, 4], vec![0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0]).unwrap();
    let f = HandFrame::from_arrays(0.5, true, &j, Some(&o)).unwrap();
    assert_eq!(f.joints, [[0.1, 0.2, 0.3], [0.4, 0.5, 0.6]]);
    assert_eq!(f.orientations.unwrap()[1], [0.0, 0.0, 1.0, 0.0]);
    assert_eq!((f.t, f.tracked), (0.5, true));
    let bad = NdArray::new(vec![3, 2], vec![0.0; 6]).unwrap();
    assert_eq!(
        HandFrame::from_arrays(0.0, true, &bad, None).unwrap_err().to_string(),
        "joints must be (J, 3), got [3, 2]"
    );
    let o3 = NdArray::new(vec![3, 4], vec![0.0; 12]).unwrap();
    assert_eq!(
        HandFrame::from_arrays(0.0, true, &j, Some(&o3)).unwrap_err().to_string(),
        "orientations must be (2, 4), got [3, 4]"
    );
}

#[test]
fn nd_array_shapes() {
    assert!(NdArray::new(vec![2, 3], vec![0; 5]).is_err());
    let m = NdArray::matrix(vec![1, 2, 3, 4, 5, 6], 3).unwrap();
    assert_eq!(m.shape, [2, 3]);
    assert_eq!(m.rows::<3>().unwrap(), [[1, 2, 3], [4, 5, 6]]);
    assert!(m.rows::<2>().is_none());
    assert_eq!(NdArray::<f32>::matrix(vec![], 7).unwrap().shape, [0, 7]);
    assert_eq!(shape_text(&[3]), "(3,)");
    assert_eq!(shape_text(&[2, 7]), "(2, 7)");
    assert_eq!(NdArray::vector(vec![1.0f32; 7]).into_shape(&[7], "action").unwrap().len(), 7);
    assert_eq!(
        m.into_shape(&[4, 7], "actions").unwrap_err().to_string(),
        "actions must have shape (4, 7), got (2, 3)"
    );
}

#[test]
fn pose_numbers_round_trip() {
    let p = Pose { position: [0.1, -0.2, 0.3], orientation: [0.0, 0.6, 0.0, 0.8] };
    let n = p.to_numbers();
    assert_eq!(n, [0.1, -0.2, 0.3, 0.0, 0.6, 0.0, 0.8]);
    assert_eq!(Pose::from_numbers(&n, "p").unwrap(), p);
}

#[test]
fn reports_serialize_with_the_bindings_keys() {
    let c = ChunkCheck {
        index: 2,
        offset: 100,
        length: Some(50),
        messages: None,
        log_times: Some((5, 9)),
        error: Some("CRC".into()),
        recoverable: false,
    };
    let v = serde_json::to_value(&c).unwrap();
    assert_eq!(v["log_time_start"], json!(5));
    assert_eq!(v["log_time_end"], json!(9));
    assert!(v.get("log_times").is_none());
    assert_eq!((v["messages"].clone(), v["recoverable"].clone()), (Value::Null, json!(false)));
    let v = serde_json::to_value(ChunkCheck { log_times: None, ..c }).unwrap();
    assert_eq!((v["log_time_start"].clone(), v["log_time_end"].clone()), (Value::Null, Value::Null));
    let r = SalvageReport { step_gaps: vec![(3, 5)], ..Default::default() };
    assert_eq!(serde_json::to_value(&r).unwrap()["step_gaps"], json!([[3, 5]]));
}

#[test]
fn into_matrix_takes_any_row_count() {
    let a = NdArray::new(vec![2, 3], vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0]).unwrap();
    assert_eq!(a.clone().into_matrix(3, "x").unwrap(), vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0]);
    let e = a.into_matrix(2, "x").unwrap_err().to_string();
    assert!(e.contains("x must have shape (2, 2), got (2, 3)"), "{e}");
    let e = NdArray::vector(vec![1.0, 2.0]).into_matrix(2, "y").unwrap_err().to_string();
    assert!(e.contains("y must have shape (2, 2), got (2,)"), "{e}");
}

#[test]
fn parse_mode_names() {
    assert_eq!(ParseMode::parse("Lenient").unwrap(), ParseMode::Lenient);
    assert_eq!(ParseMode::parse("strict").unwrap(), ParseMode::Strict);
    let e = ParseMode::parse("loose").unwrap_err().to_string();
    assert!(e.contains("mode must be 'strict' or 'lenient', got \"loose\""), "{e}");
}
