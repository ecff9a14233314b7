//! A flattened UR URDF written from the DH numbers of a [`UrModel`].
//!
//! The chain follows ROS-Industrial's `ur_description` layout (link frames as there, so meshes and
//! tools made for it line up), rooted at the UR controller's `base` frame (= DH frame 0, the frame
//! every pose in this crate is expressed in):
//!
//! `base → shoulder_link → upper_arm_link → forearm_link → wrist_1_link → wrist_2_link →
//! wrist_3_link → flange → tool0`, with six revolute joints (`shoulder_pan_joint` …
//! `wrist_3_joint`, axis z) and two fixed joints. FK along this chain from `base` to `tool0`
//! equals the DH FK ([`crate::fk`]).
//!
//! Joint limits follow ROS-Industrial `config/<model>/joint_limits.yaml`: position ±2π except the
//! elbow ±π (ROS1); velocity and effort per model.

use crate::{Joints, Pose, UrModel};
use nalgebra::{Translation3, UnitQuaternion, Vector3};
use std::f64::consts::{FRAC_PI_2, PI, TAU};
use std::fmt::Write;

/// (lower, upper, velocity rad/s, effort N·m) for each of the six joints.
fn limits(model: &UrModel) -> [(f64, f64, f64, f64); 6] {
    let deg = PI / 180.0;
    let (vel, eff): ([f64; 6], [f64; 6]) = match model.name {
        "ur3" => ([180.0, 180.0, 180.0, 360.0, 360.0, 360.0], [56.0, 56.0, 28.0, 12.0, 12.0, 12.0]),
        "ur3e" => ([180.0, 180.0, 180.0, 360.0, 360.0, 360.0], [54.0, 54.0, 28.0, 9.0, 9.0, 9.0]),
        "ur5" | "ur5e" => ([180.0; 6], [150.0, 150.0, 150.0, 28.0, 28.0, 28.0]),
        _ => ([120.0, 120.0, 180.0, 180.0, 180.0, 180.0], [330.0, 330.0, 150.0, 56.0, 56.0, 56.0]),
    };
    let mut out = [(0.0, 0.0, 0.0, 0.0); 6];
    for i in 0..6 {
        let pos = if i == 2 { PI } else { TAU };
        out[i] = (-pos, pos, vel[i] * deg, eff[i]);
    }
    out
}

/// One URDF joint: (name, parent link, child link, origin xyz, origin rpy).
pub type JointSpec = (&'static str, &'static str, &'static str, [f64; 3], [f64; 3]);

/// The six revolute joints: (name, parent, child, xyz, rpy).
pub fn joint_origins(model: &UrModel) -> [JointSpec; 6] {
    [
        ("shoulder_pan_joint", "base", "shoulder_link", [0.0, 0.0, model.d1], [0.0, 0.0, 0.0]),
        ("shoulder_lift_joint", "shoulder_link", "upper_arm_link", [0.0, 0.0, 0.0], [FRAC_PI_2, 0.0, 0.0]),
        ("elbow_joint", "upper_arm_link", "forearm_link", [model.a2, 0.0, 0.0], [0.0, 0.0, 0.0]),
        ("wrist_1_joint", "forearm_link", "wrist_1_link", [model.a3, 0.0, model.d4], [0.0, 0.0, 0.0]),
        ("wrist_2_joint", "wrist_1_link", "wrist_2_link", [0.0, -model.d5, 0.0], [FRAC_PI_2, 0.0, 0.0]),
        ("wrist_3_joint", "wrist_2_link", "wrist_3_link", [0.0, model.d6, 0.0], [FRAC_PI_2, PI, PI]),
    ]
}

/// The fixed joints after wrist 3: (name, parent, child, xyz, rpy).
pub const FIXED_JOINTS: [JointSpec; 2] = [
    ("wrist_3-flange", "wrist_3_link", "flange", [0.0, 0.0, 0.0], [0.0, -FRAC_PI_2, -FRAC_PI_2]),
    ("flange-tool0", "flange", "tool0", [0.0, 0.0, 0.0], [FRAC_PI_2, 0.0, FRAC_PI_2]),
];

/// Names of the links, root first.
pub const LINKS: [&str; 9] = [
    "base",
    "shoulder_link",
    "upper_arm_link",
    "forearm_link",
    "wrist_1_link",
    "wrist_2_link",
    "wrist_3_link",
    "flange",
    "tool0",
];

/// One joint of the chain: (parent link, child link, origin xyz, origin rpy, index of the
/// revolute joint or `None` for a fixed joint).
pub type ChainJoint = (&'static str, &'static str, [f64; 3], [f64; 3], Option<usize>);

/// The eight joints of the chain in order (six revolute, then the two fixed ones).
pub fn chain(model: &UrModel) -> Vec<ChainJoint> {
    let mut v: Vec<ChainJoint> = joint_origins(model)
        .into_iter()
        .enumerate()
        .map(|(i, (_, parent, child, xyz, rpy))| (parent, child, xyz, rpy, Some(i)))
        .collect();
    v.extend(FIXED_JOINTS.iter().map(|&(_, parent, child, xyz, rpy)| (parent, child, xyz, rpy, None)));
    v
}

fn origin(xyz: &[f64; 3], rpy: &[f64; 3]) -> Pose {
    Pose::from_parts(
        Translation3::new(xyz[0], xyz[1], xyz[2]),
        UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]),
    )
}

/// Parent-to-child transforms of every link at joint angles `q`, in chain order:
/// `(parent, child, pose of child in parent)`. Composed from `base` they give [`crate::fk`] at
/// `tool0`.
pub fn link_transforms(model: &UrModel, q: &Joints) -> Vec<(&'static str, &'static str, Pose)> {
    chain(model)
        .into_iter()
        .map(|(parent, child, xyz, rpy, joint)| {
            let mut p = origin(&xyz, &rpy);
            if let Some(i) = joint {
                p *= UnitQuaternion::from_axis_angle(&Vector3::z_axis(), q[i]);
            }
            (parent, child, p)
        })
        .collect()
}

/// Pose in `base` of every link after `base` (`shoulder_link` … `tool0`) at joint angles `q`:
/// [`link_transforms`] composed down the chain.
pub fn link_poses(model: &UrModel, q: &Joints) -> Vec<(&'static str, Pose)> {
    let mut acc = Pose::identity();
    link_transforms(model, q)
        .into_iter()
        .map(|(_, child, rel)| {
            acc *= rel;
            (child, acc)
        })
        .collect()
}

/// The URDF link each DH frame 1..=6 ([`crate::fk_all`]) is fixed to: the child of revolute
/// joint i, and `tool0` for frame 6 (the DH tool frame is `tool0`).
pub const DH_FRAME_LINKS: [&str; 6] =
    ["shoulder_link", "upper_arm_link", "forearm_link", "wrist_1_link", "wrist_2_link", "tool0"];

/// For each DH frame 1..=6: its URDF link ([`DH_FRAME_LINKS`]) and the frame's constant pose in
/// that link, so that `link_pose · offset` = the DH frame at every `q`. Derived from the two
/// models at `q = 0` (DH [`crate::fk_all`] against [`link_poses`]); components within 1e-12 of 0
/// are set to 0 (the rotations are quarter turns, whose sines and cosines leave 6e-17 behind).
pub fn dh_frames_in_links(model: &UrModel) -> [(&'static str, Pose); 6] {
    let q = [0.0; 6];
    let (dh, links) = (crate::fk_all(model, &q), link_poses(model, &q));
    let link = |name: &str| links.iter().find(|(n, _)| *n == name).map_or(Pose::identity(), |(_, p)| *p);
    let clean = |x: f64| if x.abs() < 1e-12 { 0.0 } else { x };
    std::array::from_fn(|i| {
        let name = DH_FRAME_LINKS[i];
        let off = link(name).inverse() * dh[i + 1];
        let (t, r) = (off.translation.vector.map(clean), off.rotation.into_inner().coords.map(clean));
        let r = UnitQuaternion::new_normalize(nalgebra::Quaternion::new(r.w, r.x, r.y, r.z));
        (name, Pose::from_parts(Translation3::from(t), r))
    })
}

fn v3(v: &[f64; 3]) -> String {
    // 17 significant digits: the file round-trips the f64 values exactly.
    format!("{:.17e} {:.17e} {:.17e}", v[0], v[1], v[2])
}

/// A complete URDF document for `model` (robot name = the model name, e.g. `ur3`).
/// Links carry no geometry or inertia (kinematics only).
pub fn to_urdf_string(model: &UrModel) -> String {
    let mut s = String::new();
    let _ = writeln!(s, r#"<?xml version="1.0"?>"#);
    let _ = writeln!(
        s,
        "<!-- {} kinematic chain written by ur3-kin from the standard DH table \
         (d1={}, a2={}, a3={}, d4={}, d5={}, d6={}). Root link `base` is the UR controller Base \
         frame (DH frame 0); `tool0` is the flange with zero TCP. -->",
        model.name, model.d1, model.a2, model.a3, model.d4, model.d5, model.d6
    );
    let _ = writeln!(s, r#"<robot name="{}">"#, model.name);
    for l in LINKS {
        let _ = writeln!(s, r#"  <link name="{l}"/>"#);
    }
    let lim = limits(model);
    for (i, (name, parent, child, xyz, rpy)) in joint_origins(model).iter().enumerate() {
        let (lo, hi, vel, eff) = lim[i];
        let _ = writeln!(s, r#"  <joint name="{name}" type="revolute">"#);
        let _ = writeln!(s, r#"    <parent link="{parent}"/>"#);
        let _ = writeln!(s, r#"    <child link="{child}"/>"#);
        let _ = writeln!(s, r#"    <origin xyz="{}" rpy="{}"/>"#, v3(xyz), v3(rpy));
        let _ = writeln!(s, r#"    <axis xyz="0 0 1"/>"#);
        let _ = writeln!(
            s,
            r#"    <limit lower="{lo:.17e}" upper="{hi:.17e}" velocity="{vel:.17e}" effort="{eff}"/>"#
        );
        let _ = writeln!(s, "  </joint>");
    }
    for (name, parent, child, xyz, rpy) in FIXED_JOINTS {
        let _ = writeln!(s, r#"  <joint name="{name}" type="fixed">"#);
        let _ = writeln!(s, r#"    <parent link="{parent}"/>"#);
        let _ = writeln!(s, r#"    <child link="{child}"/>"#);
        let _ = writeln!(s, r#"    <origin xyz="{}" rpy="{}"/>"#, v3(&xyz), v3(&rpy));
        let _ = writeln!(s, "  </joint>");
    }
    let _ = writeln!(s, "</robot>");
    s
}
