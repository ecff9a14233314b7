//! Batch calls and their per-row failure policy; URDF link poses against the DH FK.

use nalgebra::{Matrix4, Vector3};
use ur3_kin::{
    Calibration, Handedness, IkOptions, KinError, UR3, fk, fk_batch, hand_to_target, hand_to_target_batch,
    ik_batch_matrices, urdf,
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
    let w = vec![Vector3::new(0.0, -0.4, -0.4), Vector3::new(0.0, 0.0, 0.0)];
    let i = vec![Vector3::new(0.03, -0.4, -0.5), Vector3::new(0.0, 0.0, 0.1)];
    let m = vec![Vector3::new(0.0, -0.4, -0.5), Vector3::new(0.0, 0.0, 0.2)]; // row 1 collinear
    let out = hand_to_target_batch(&w, &i, &m, Handedness::Right, &cal).unwrap();
    assert_eq!(
        out[0].as_ref().unwrap(),
        &hand_to_target(&w[0], &i[0], &m[0], Handedness::Right, &cal).unwrap()
    );
    assert!(matches!(out[1], Err(KinError::DegenerateHand(_))));
    assert!(hand_to_target_batch(&w, &i[..1], &m, Handedness::Right, &cal).is_err());
    let pts = cal.points_to_base(&w);
    assert!((pts[0] - cal.point_to_base(&w[0])).norm() == 0.0);
    assert!((pts[1] - Vector3::new(-0.1, 0.0, 0.6)).norm() < 1e-12);
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
