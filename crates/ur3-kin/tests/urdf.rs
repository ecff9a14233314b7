//! The generated URDF parses with urdf-rs and its chain reproduces the DH forward kinematics.

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use proptest::prelude::*;
use ur3_kin::{MODELS, UrModel, fk, pose_distance, urdf};

/// FK along the parsed URDF chain from `base` to `tool0`.
fn urdf_fk(robot: &urdf_rs::Robot, q: &[f64; 6]) -> Isometry3<f64> {
    let mut link = "base".to_string();
    let mut t = Isometry3::identity();
    let mut k = 0;
    while link != "tool0" {
        let j = robot.joints.iter().find(|j| j.parent.link == link).expect("chain continues");
        let o = &j.origin;
        // URDF rpy: fixed-axis roll, pitch, yaw, i.e. Rz(yaw)·Ry(pitch)·Rx(roll).
        let rot = UnitQuaternion::from_euler_angles(o.rpy[0], o.rpy[1], o.rpy[2]);
        t *= Isometry3::from_parts(Translation3::new(o.xyz[0], o.xyz[1], o.xyz[2]), rot);
        match j.joint_type {
            urdf_rs::JointType::Revolute => {
                let ax = Vector3::new(j.axis.xyz[0], j.axis.xyz[1], j.axis.xyz[2]);
                t *= UnitQuaternion::from_scaled_axis(ax * q[k]);
                k += 1;
            }
            urdf_rs::JointType::Fixed => {}
            ref other => panic!("unexpected joint type {other:?}"),
        }
        link = j.child.link.clone();
    }
    assert_eq!(k, 6);
    t
}

fn parse(m: &UrModel) -> urdf_rs::Robot {
    urdf_rs::read_from_string(&urdf::to_urdf_string(m)).expect("valid URDF")
}

#[test]
fn urdf_structure() {
    for m in MODELS {
        let r = parse(&m);
        assert_eq!(r.name, m.name);
        assert_eq!(r.links.len(), 9);
        let revolute: Vec<_> =
            r.joints.iter().filter(|j| matches!(j.joint_type, urdf_rs::JointType::Revolute)).collect();
        assert_eq!(revolute.len(), 6);
        for (i, j) in revolute.iter().enumerate() {
            let expect = if j.name == "elbow_joint" { std::f64::consts::PI } else { std::f64::consts::TAU };
            assert!((j.limit.upper - expect).abs() < 1e-12, "{} {}", m.name, j.name);
            assert!((j.limit.lower + expect).abs() < 1e-12);
            assert!(j.limit.velocity > 0.0 && j.limit.effort > 0.0);
            assert_eq!(j.axis.xyz.0, [0.0, 0.0, 1.0], "joint {i}");
        }
        // Every link except the root is a child exactly once (a tree rooted at `base`).
        for l in &r.links {
            let n = r.joints.iter().filter(|j| j.child.link == l.name).count();
            assert_eq!(n, usize::from(l.name != "base"), "{}", l.name);
        }
    }
}

#[test]
fn urdf_zero_pose_equals_dh() {
    for m in MODELS {
        let r = parse(&m);
        let (dp, da) = pose_distance(&urdf_fk(&r, &[0.0; 6]), &fk(&m, &[0.0; 6]));
        assert!(dp < 1e-12 && da < 1e-12, "{}: {dp} {da}", m.name);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1000))]
    #[test]
    fn urdf_fk_equals_dh_fk(q in prop::array::uniform6(-2.0 * std::f64::consts::PI..2.0 * std::f64::consts::PI)) {
        for m in MODELS {
            let r = parse(&m);
            let (dp, da) = pose_distance(&urdf_fk(&r, &q), &fk(&m, &q));
            prop_assert!(dp < 1e-9 && da < 1e-9, "{}: {} m {} rad", m.name, dp, da);
        }
    }
}

proptest::proptest! {
    /// The DH frames sit at a constant pose in their URDF links: link pose · offset = fk_all.
    #[test]
    fn dh_frames_ride_their_urdf_links(q in proptest::array::uniform6(-3.1f64..3.1)) {
        for m in &ur3_kin::MODELS {
            let dh = ur3_kin::fk_all(m, &q);
            let links = ur3_kin::urdf::link_poses(m, &q);
            for (i, (name, off)) in ur3_kin::urdf::dh_frames_in_links(m).into_iter().enumerate() {
                let link = links.iter().find(|(n, _)| *n == name).unwrap().1;
                let got = link * off;
                let want = dh[i + 1];
                proptest::prop_assert!((got.translation.vector - want.translation.vector).norm() < 1e-9);
                proptest::prop_assert!(got.rotation.angle_to(&want.rotation) < 1e-9, "{} {}", m.name, name);
            }
        }
    }
}

#[test]
fn dh_frame_offsets_are_quarter_turns_and_arm_lengths() {
    let offs = ur3_kin::urdf::dh_frames_in_links(&ur3_kin::UR3);
    // tool0 is the DH tool frame exactly
    assert_eq!(offs[5], ("tool0", ur3_kin::Pose::identity()));
    // the upper arm's DH frame (at the elbow) is a2 along the URDF upper arm's x
    let (name, p) = offs[1];
    assert_eq!(name, "upper_arm_link");
    assert!((p.translation.vector.x - ur3_kin::UR3.a2).abs() < 1e-12);
    for (_, p) in offs {
        let a = p.rotation.angle();
        assert!(
            [0.0, std::f64::consts::FRAC_PI_2, std::f64::consts::PI].iter().any(|r| (a - r).abs() < 1e-12)
        );
    }
}
