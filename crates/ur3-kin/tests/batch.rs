//! Batch calls and their per-row failure policy; URDF link poses against the DH FK.

use nalgebra::{Matrix4, Vector3};
use ur3_kin::{
    Calibration, HandPoints, Handedness, IkOptions, KinError, Pose, UR3, fk, fk_batch, hand_to_target,
    hand_to_target_batch, ik_batch_matrices, split_failures, urdf,
};

#[test]
fn fk_batch_equals_fk_row_by_row() {
    let qs: Vec<[f64; 6]> =
        (0..50).map(|i| std::array::from_fn(|k| 0.1 * i as f64 - 0.37 * k as f64)).collect();
    let ts = fk_batch(&UR3, &qs);
    assert_eq!(ts.len(), 50);
    for (q, t) in qs.iter().zip(&ts) {
        assert_eq!(*t, fk(&UR3, q));
    }
}

#[test]
fn ik_batch_matrices_fails_bad_rows_only() {
    let q = [0.3, -1.1, 1.2, -1.6, -1.5, 0.4];
    let good = fk(&UR3, &q).to_homogeneous();
    let mut sheared = good;
    sheared[(0, 1)] += 0.3; // not a rotation
    let far = Matrix4::new_translation(&Vector3::new(2.0, 0.0, 0.0)); // beyond reach
    let rows = [good, sheared, far, good];
    let out = ik_batch_matrices(&UR3, &rows, Some(&[q; 4]), &IkOptions::default(), 2).unwrap();
    assert_eq!(out.len(), 4);
    for i in [0, 3] {
        let s = out[i].as_ref().expect("reachable row solves");
        assert!(s.iter().zip(&q).all(|(a, b)| (a - b).abs() < 1e-8), "row {i}: {s:?}");
    }
    assert!(matches!(out[1], Err(KinError::InvalidPose(_))), "{:?}", out[1]);
    assert!(matches!(out[2], Err(KinError::Unreachable { .. })), "{:?}", out[2]);
    let mut bad_seed = [q; 4];
    bad_seed[2][1] = f64::NAN;
    assert_eq!(
        ik_batch_matrices(&UR3, &rows, Some(&bad_seed), &IkOptions::default(), 1),
        Err(KinError::NonFinite("seeds"))
    );
}

#[test]
fn hand_to_target_batch_matches_single_calls_and_flags_degenerate_frames() {
    let cal = Calibration::default();
    let hands = [
        HandPoints::new([0.0, -0.4, -0.4], [0.03, -0.4, -0.5], [0.0, -0.4, -0.5]),
        HandPoints::new([0.0, 0.0, 0.0], [0.0, 0.0, 0.1], [0.0, 0.0, 0.2]), // collinear
    ];
    let out = hand_to_target_batch(&hands, Handedness::Right, &cal);
    assert_eq!(out.len(), 2);
    assert_eq!(out[0].as_ref().unwrap(), &hand_to_target(&hands[0], Handedness::Right, &cal).unwrap());
    assert!(matches!(out[1], Err(KinError::DegenerateHand(_))));
    let (ts, ok) = split_failures(&out, Pose::identity());
    assert_eq!(ok, [true, false]);
    assert_eq!((ts[0], ts[1]), (*out[0].as_ref().unwrap(), Pose::identity()));
    // The wrist (0, -0.4, -0.4) in OpenXR is 0.4 m ahead and below the head: (0.3, 0, 0.2) in Base.
    assert!((ts[0].translation.vector - Vector3::new(0.3, 0.0, 0.2)).norm() < 1e-12);
    let w = [hands[0].wrist, hands[1].wrist];
    let pts = cal.points_to_base(&w);
    assert!((pts[0] - cal.point_to_base(&w[0])).norm() == 0.0);
    assert!((pts[1] - Vector3::new(-0.1, 0.0, 0.6)).norm() < 1e-12);
}

#[test]
fn split_failures_fills_failed_rows_and_keeps_order() {
    let rows: Vec<Result<[f64; 6], KinError>> =
        vec![Ok([1.0; 6]), Err(KinError::Unreachable { reason: "far" }), Ok([2.0; 6])];
    let (q, ok) = split_failures(&rows, [f64::NAN; 6]);
    assert_eq!(ok, [true, false, true]);
    assert_eq!((q[0], q[2]), ([1.0; 6], [2.0; 6]));
    assert!(q[1].iter().all(|x| x.is_nan()));
    let (none, ok): (Vec<f64>, _) = split_failures(&[], 0.0);
    assert!(none.is_empty() && ok.is_empty());
}

#[test]
fn ik_options_with_tol_sets_both_tolerances_or_refuses() {
    assert_eq!(IkOptions::with_tol(None).unwrap(), IkOptions::default());
    let o = IkOptions::with_tol(Some(1e-6)).unwrap();
    assert_eq!((o.tol_pos_m, o.tol_rot_rad), (1e-6, 1e-6));
    assert_eq!(o.max_iters, IkOptions::default().max_iters);
    for bad in [0.0, -1e-6, f64::NAN, f64::INFINITY] {
        let e = IkOptions::with_tol(Some(bad)).unwrap_err();
        assert!(matches!(e, KinError::NotPositive { name: "tol", .. }), "{e:?}");
    }
    assert_eq!(
        IkOptions::with_tol(Some(-2.0)).unwrap_err().to_string(),
        "tol must be a positive finite number, got -2"
    );
}

#[test]
fn link_poses_end_at_fk_and_follow_link_transforms() {
    for k in 0..20 {
        let q: [f64; 6] = std::array::from_fn(|j| ((k * 7 + j * 3) % 11) as f64 * 0.55 - 2.7);
        let poses = urdf::link_poses(&UR3, &q);
        assert_eq!(poses.iter().map(|p| p.0).collect::<Vec<_>>(), urdf::LINKS[1..].to_vec());
        let tool0 = poses.last().unwrap().1;
        let t = fk(&UR3, &q);
        assert!((tool0.translation.vector - t.translation.vector).norm() < 1e-12);
        assert!(tool0.rotation.angle_to(&t.rotation) < 1e-12);
        let rel = urdf::link_transforms(&UR3, &q);
        let shoulder = poses[0].1;
        assert!((shoulder.translation.vector - rel[0].2.translation.vector).norm() < 1e-15);
    }
}
