//! Hand → tool0 target from synthetic hands in known poses.

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use proptest::prelude::*;
use ur3_kin::{
    Calibration, HandLayout, HandPoints, Handedness, KinError, Pose, Space, hand_frame, hand_to_target,
    hand_to_target_layout, pose_distance,
};

/// Canonical right hand in its own frame (x: little-finger side, y: fingers, z: back of hand):
/// wrist at 0, middle knuckle 9 cm along y, index knuckle 2.2 cm to the thumb side.
const WRIST: [f64; 3] = [0.0, 0.0, 0.0];
const MIDDLE: [f64; 3] = [0.0, 0.09, 0.0];
const INDEX_RIGHT: [f64; 3] = [-0.022, 0.085, 0.0];
/// The left hand is the mirror image (x → −x).
const INDEX_LEFT: [f64; 3] = [0.022, 0.085, 0.0];

fn place(frame: &Pose, p: [f64; 3]) -> Vector3<f64> {
    frame.transform_point(&Vector3::from(p).into()).coords
}

fn hp(wrist: &Vector3<f64>, index_proximal: &Vector3<f64>, middle_proximal: &Vector3<f64>) -> HandPoints {
    HandPoints { wrist: *wrist, index_proximal: *index_proximal, middle_proximal: *middle_proximal }
}

fn base_calib() -> Calibration {
    Calibration::identity()
}

fn rot_strategy() -> impl Strategy<Value = UnitQuaternion<f64>> {
    prop::array::uniform3(-3.0..3.0f64).prop_map(|v| UnitQuaternion::from_scaled_axis(Vector3::from(v)))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    /// A hand placed with a known frame gives back exactly that frame, for both hands.
    #[test]
    fn known_frame_recovered(rot in rot_strategy(), t in prop::array::uniform3(-1.0..1.0f64)) {
        let h = Isometry3::from_parts(Translation3::new(t[0], t[1], t[2]), rot);
        for (hd, idx) in [(Handedness::Right, INDEX_RIGHT), (Handedness::Left, INDEX_LEFT)] {
            let f = hand_frame(&hp(&place(&h, WRIST), &place(&h, idx), &place(&h, MIDDLE)), hd, &base_calib()).unwrap();
            let (dp, da) = pose_distance(&f, &h);
            prop_assert!(dp < 1e-12 && da < 1e-9, "{hd:?}: {dp} {da}");
            // tool0: x along the fingers, z out of the palm, origin at the wrist.
            let tt = hand_to_target(&hp(&place(&h, WRIST), &place(&h, idx), &place(&h, MIDDLE)), hd, &base_calib()).unwrap();
            prop_assert!((tt.rotation * Vector3::x() - h.rotation * Vector3::y()).norm() < 1e-9);
            prop_assert!((tt.rotation * Vector3::z() + h.rotation * Vector3::z()).norm() < 1e-9);
            prop_assert!((tt.translation.vector - h.translation.vector).norm() < 1e-12);
        }
    }

    /// Any input: a proper rotation, or a typed error.
    #[test]
    fn any_hand_is_frame_or_typed_error(
        w in prop::array::uniform3(prop_oneof![-1.0..1.0f64, prop::num::f64::ANY]),
        i in prop::array::uniform3(-1.0..1.0f64),
        m in prop::array::uniform3(-1.0..1.0f64),
        left in any::<bool>(),
    ) {
        let hd = if left { Handedness::Left } else { Handedness::Right };
        match hand_to_target(&hp(&Vector3::from(w), &Vector3::from(i), &Vector3::from(m)), hd, &Calibration::default()) {
            Ok(p) => {
                let r = p.rotation.to_rotation_matrix().into_inner();
                prop_assert!((r.transpose() * r - nalgebra::Matrix3::identity()).abs().max() < 1e-9);
                prop_assert!((r.determinant() - 1.0).abs() < 1e-9);
                prop_assert!(p.translation.vector.iter().all(|x| x.is_finite()));
            }
            Err(KinError::NonFinite(_) | KinError::DegenerateHand(_)) => {}
            Err(e) => prop_assert!(false, "{e}"),
        }
    }
}

#[test]
fn palm_down_forward_gives_tool_pointing_down() {
    // Robot Base coordinates: fingers along +X, palm down (back of hand up). Right hand: thumb and
    // index on the left (+Y); left hand: on the right (−Y).
    let w = Vector3::new(0.3, 0.0, 0.2);
    let m = w + Vector3::new(0.09, 0.0, 0.0);
    for (hd, side) in [(Handedness::Right, 1.0), (Handedness::Left, -1.0)] {
        let i = w + Vector3::new(0.085, 0.022 * side, 0.0);
        let t = hand_to_target(&hp(&w, &i, &m), hd, &base_calib()).unwrap();
        assert!((t.rotation * Vector3::z() - Vector3::new(0.0, 0.0, -1.0)).norm() < 1e-12, "{hd:?}");
        assert!((t.rotation * Vector3::x() - Vector3::new(1.0, 0.0, 0.0)).norm() < 1e-12, "{hd:?}");
        assert!((t.translation.vector - w).norm() < 1e-15);
    }
    // Wrong handedness label on the same hand flips the approach axis up: handedness matters.
    let i = w + Vector3::new(0.085, 0.022, 0.0);
    let t = hand_to_target(&hp(&w, &i, &m), Handedness::Left, &base_calib()).unwrap();
    assert!((t.rotation * Vector3::z() - Vector3::z()).norm() < 1e-12);
}

#[test]
fn openxr_and_unity_spaces_map_to_base() {
    // The same physical right hand, palm down, 0.4 m in front of and below the head, fingers
    // forward. OpenXR: +Y up, −Z forward, +X right. Unity: +Y up, +Z forward, +X right.
    let xr = |p: [f64; 3]| Vector3::new(p[0], p[1], p[2]);
    let (w, m, i) = (xr([0.0, -0.4, -0.4]), xr([0.0, -0.4, -0.49]), xr([-0.022, -0.4, -0.485]));
    let cal = Calibration::default();
    let t = hand_to_target(&hp(&w, &i, &m), Handedness::Right, &cal).unwrap();
    assert!((t.translation.vector - Vector3::new(0.3, 0.0, 0.2)).norm() < 1e-12, "{}", t.translation.vector);
    assert!((t.rotation * Vector3::z() + Vector3::z()).norm() < 1e-12);
    assert!((t.rotation * Vector3::x() - Vector3::x()).norm() < 1e-12);
    let unity = |p: Vector3<f64>| Vector3::new(p.x, p.y, -p.z);
    let cal_u = Calibration { space: Space::Unity, ..Calibration::default() };
    let tu = hand_to_target(&hp(&unity(w), &unity(i), &unity(m)), Handedness::Right, &cal_u).unwrap();
    let (dp, da) = pose_distance(&t, &tu);
    assert!(dp < 1e-12 && da < 1e-12);
    // point_to_base and scale.
    let cal2 = Calibration { scale: 2.0, ..Calibration::default() };
    let p = cal2.point_to_base(&xr([0.1, 0.2, -0.3]));
    assert!((p - Vector3::new(-0.1 + 0.6, -0.2, 0.6 + 0.4)).norm() < 1e-12, "{p}");
    // A rotated calibration (robot base turned 90° about Z) turns the target with it.
    let turned = Calibration {
        base_from_space: Isometry3::from_parts(
            Translation3::identity(),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::FRAC_PI_2),
        ),
        scale: 1.0,
        space: Space::OpenXr,
    };
    let tt = hand_to_target(&hp(&w, &i, &m), Handedness::Right, &turned).unwrap();
    assert!((tt.rotation * Vector3::x() - Vector3::y()).norm() < 1e-12);
    assert!((tt.translation.vector - Vector3::new(0.0, 0.4, -0.4)).norm() < 1e-12);
}

#[test]
fn degenerate_hands_are_errors() {
    let c = base_calib();
    let w = Vector3::new(0.1, 0.2, 0.3);
    let m = w + Vector3::new(0.0, 0.09, 0.0);
    let cases = [
        (w, w + Vector3::new(0.02, 0.0, 0.0), w), // middle on the wrist
        (w, m, m),                                // index on the middle
        (w, w + Vector3::new(0.0, 0.05, 0.0), m), // collinear
        (w, w + Vector3::new(0.0, 0.2, 1e-7), m), // nearly collinear
    ];
    for (a, b, cc) in cases {
        for hd in [Handedness::Left, Handedness::Right] {
            assert!(
                matches!(hand_to_target(&hp(&a, &b, &cc), hd, &c), Err(KinError::DegenerateHand(_))),
                "{a} {b} {cc}"
            );
        }
    }
    let nan = Vector3::new(f64::NAN, 0.0, 0.0);
    assert!(matches!(hand_to_target(&hp(&nan, &w, &m), Handedness::Right, &c), Err(KinError::NonFinite(_))));
    let bad_scale = Calibration { scale: 0.0, ..c };
    assert!(
        hand_to_target(&hp(&w, &(w + Vector3::new(0.02, 0.08, 0.0)), &m), Handedness::Right, &bad_scale)
            .is_err()
    );
}

#[test]
fn layout_indices_feed_the_right_joints() {
    // Published indices (OpenXR XrHandJointEXT, WebXR XRHandJoint, Meta OVR legacy BoneId,
    // MediaPipe HandLandmark).
    let expect = [
        (HandLayout::OpenXr, 26, 1, 7, 12),
        (HandLayout::WebXr, 25, 0, 6, 11),
        (HandLayout::MetaOvr, 24, 0, 6, 9),
        (HandLayout::MediaPipe, 21, 0, 5, 9),
    ];
    let h = Isometry3::from_parts(
        Translation3::new(0.2, -0.1, 0.3),
        UnitQuaternion::from_scaled_axis(Vector3::new(0.3, -0.5, 1.1)),
    );
    for (layout, n, wi, ii, mi) in expect {
        assert_eq!(
            (layout.joint_count(), layout.wrist(), layout.index_proximal(), layout.middle_proximal()),
            (n, wi, ii, mi)
        );
        assert_eq!(HandLayout::from_name(layout.name()).unwrap(), layout);
        for (hd, idx) in [(Handedness::Right, INDEX_RIGHT), (Handedness::Left, INDEX_LEFT)] {
            // Every other joint is junk far away: only the three named ones may matter.
            let mut joints: Vec<[f64; 3]> = (0..n).map(|k| [k as f64 * 10.0, -(k as f64), 3.0]).collect();
            joints[wi] = place(&h, WRIST).into();
            joints[ii] = place(&h, idx).into();
            joints[mi] = place(&h, MIDDLE).into();
            let t = hand_to_target_layout(&joints, layout, hd, &base_calib()).unwrap();
            assert!((t.translation.vector - h.translation.vector).norm() < 1e-12);
            assert!(
                (t.rotation * Vector3::z() + h.rotation * Vector3::z()).norm() < 1e-9,
                "{layout:?} {hd:?}"
            );
            assert!(matches!(
                hand_to_target_layout(&joints[..n - 1], layout, hd, &base_calib()),
                Err(KinError::InvalidPose(_))
            ));
        }
    }
}

#[test]
fn huge_coordinates_keep_an_orthonormal_frame() {
    // Regression: a wrist 9e153 m away used to overflow |x' × y'| (≈1e308) and give a zero axis.
    let w = Vector3::new(0.0, 0.0, 9.058229095476689e153);
    let i = Vector3::new(0.0, -0.7651881055772308, 0.0);
    let m = Vector3::new(-0.7059428416528244, 0.711898621697605, 0.0);
    for cal in [Calibration::default(), base_calib()] {
        let p = hand_to_target(&hp(&w, &i, &m), Handedness::Right, &cal).unwrap();
        let r = p.rotation.to_rotation_matrix().into_inner();
        assert!((r.transpose() * r - nalgebra::Matrix3::identity()).abs().max() < 1e-12);
    }
    // Differences that overflow f64 are a typed error.
    let far = Vector3::new(f64::MAX, 0.0, 0.0);
    let m_far = Vector3::new(-f64::MAX, 0.5, 0.0);
    let r = hand_to_target(&hp(&far, &Vector3::new(0.0, 0.3, 0.0), &m_far), Handedness::Right, &base_calib());
    assert!(matches!(r, Err(KinError::Overflow(m)) if m.starts_with("middle_proximal − wrist")), "{r:?}");
    // Finite coordinates that overflow once scaled and moved into Base name the joint; they
    // used to give a target holding an infinity.
    for cal in [Calibration { scale: 10.0, ..Calibration::default() }, {
        let mut c = base_calib();
        c.base_from_space.translation.vector = Vector3::new(1.7e308, 1.7e308, 1.7e308);
        c
    }] {
        for (k, name) in [(0, "wrist"), (1, "index_proximal"), (2, "middle_proximal")] {
            let mut j =
                [Vector3::new(0.0, 0.0, 0.0), Vector3::new(0.1, 0.2, 0.0), Vector3::new(0.0, 0.3, 0.01)];
            j[k] = Vector3::new(1e308, 1e308, 1e308);
            let r = hand_to_target(&hp(&j[0], &j[1], &j[2]), Handedness::Right, &cal);
            match r {
                Err(KinError::Overflow(m)) => assert!(m.starts_with(name), "{m}"),
                other => panic!("{name}: {other:?}"),
            }
        }
    }
}

#[test]
fn calibration_from_parts_checks_scale_and_space() {
    let c = Calibration::new(None, 2.0, "webxr").unwrap();
    assert_eq!(c.base_from_space, Calibration::default().base_from_space);
    assert_eq!((c.scale, c.space), (2.0, Space::OpenXr));
    // p_base = base_from_space · (scale · flu(p)): OpenXR (0, -0.4, -0.4) → FLU (0.4, 0, -0.4).
    let p = c.point_to_base(&Vector3::new(0.0, -0.4, -0.4));
    assert!((p - Vector3::new(0.7, 0.0, -0.2)).norm() < 1e-12, "{p}");
    let b = Pose::translation(1.0, 2.0, 3.0);
    let c = Calibration::new(Some(b), 1.0, "robot_base").unwrap();
    assert!((c.point_to_base(&Vector3::new(0.5, 0.0, 0.0)) - Vector3::new(1.5, 2.0, 3.0)).norm() < 1e-12);
    for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let e = Calibration::new(None, bad, "unity").unwrap_err();
        assert!(matches!(e, KinError::NotPositive { name: "scale", .. }), "{e:?}");
        assert!(e.to_string().starts_with("scale must be a positive finite number, got"), "{e}");
    }
    assert!(matches!(Calibration::new(None, 1.0, "ros"), Err(KinError::UnknownSpace(_))));
}

#[test]
fn hand_points_from_layout_pick_the_layouts_joints() {
    for layout in HandLayout::ALL {
        let joints: Vec<[f64; 3]> =
            (0..layout.joint_count()).map(|k| [k as f64, 0.5 * k as f64, 1.0]).collect();
        let h = HandPoints::from_layout(&joints, layout).unwrap();
        assert_eq!(h.wrist, Vector3::from(joints[layout.wrist()]));
        assert_eq!(h.index_proximal, Vector3::from(joints[layout.index_proximal()]));
        assert_eq!(h.middle_proximal, Vector3::from(joints[layout.middle_proximal()]));
        assert!(matches!(
            HandPoints::from_layout(&joints[..joints.len() - 1], layout),
            Err(KinError::InvalidPose(_))
        ));
    }
}

#[test]
fn every_layout_names_its_joints_and_maps_them_to_openxr() {
    use ur3_kin::OPENXR_JOINTS;
    for layout in HandLayout::ALL {
        let (names, map) = (layout.joint_names(), layout.openxr_joints());
        assert_eq!((names.len(), map.len()), (layout.joint_count(), layout.joint_count()), "{layout:?}");
        let mut seen: Vec<usize> = map.iter().flatten().copied().collect();
        let n = seen.len();
        seen.sort_unstable();
        seen.dedup();
        assert_eq!(seen.len(), n, "{layout:?} maps two joints to one OpenXR joint");
        assert!(seen.iter().all(|&j| j < OPENXR_JOINTS.len()));
        for (name, at) in [
            ("wrist", layout.wrist()),
            ("index_proximal", layout.index_proximal()),
            ("middle_proximal", layout.middle_proximal()),
        ] {
            assert_eq!(layout.index_of(name), Some(at), "{layout:?} {name}");
            assert_eq!(map[at].map(|j| OPENXR_JOINTS[j]), Some(name));
        }
        assert_eq!(layout.index_of("thumb_tip").map(|i| map[i]), Some(Some(5)));
        assert_eq!(layout.index_of("elbow"), None);
    }
    assert_eq!(HandLayout::WebXr.index_of("palm"), None);
    assert_eq!(
        HandLayout::WebXr.joint_names()[HandLayout::WebXr.index_of("thumb_tip").unwrap()],
        "thumb-tip"
    );
    let ovr = HandLayout::MetaOvr;
    let missing: Vec<&str> =
        (0..24).filter(|&i| ovr.openxr_joints()[i].is_none()).map(|i| ovr.joint_names()[i]).collect();
    assert_eq!(missing, ["ForearmStub", "Thumb0"]);
}
