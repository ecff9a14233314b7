//! The hand → end-effector target mapping (paper §3.2); which joints of a frame it reads is the
//! frame's [`HandLayout`]'s.
//!
//! # The hand frame (paper §3.2)
//! From three tracked joint positions, all converted to the robot Base frame first (see
//! [`Calibration`]): origin at the wrist; `y = n(middle_prox − wrist)` (towards the fingers);
//! with `x' = middle_prox − index_prox`, `z = n(x' × y)` and `x = y × z`.
//!
//! **Handedness.** For a right hand `x'` points from the index knuckle towards the little finger,
//! so `z` is the normal out of the *back* of the hand (dorsal) and `x` points to the little-finger
//! side. A left hand is the mirror image, so the paper's formula would give it the palm normal as
//! `z`. We mirror it: for [`Handedness::Left`], `x' = index_prox − middle_prox`. Then, for both
//! hands, `z` is the dorsal normal and `y` points along the fingers: a left hand and a right hand
//! held the same way (palm down, fingers forward) give the same `y` and `z` and hence the same
//! frame (`x = y × z`; for the left hand `x` points to the thumb side).
//!
//! **Hand frame → tool0.** tool0's z axis is the approach axis. We map
//! `tool0.x = hand.y` (along the fingers), `tool0.y = hand.x`, `tool0.z = −hand.z` (out of the
//! palm). A palm-down hand reaching forward therefore gives a tool pointing straight down with its
//! x axis forward: the pose for picking a tile from above with the suction cups.

use crate::fk::Frame;
use crate::layout::HandLayout;
use crate::{KinError, Pose};
use nalgebra::{Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};

/// Which hand a frame belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Handedness {
    /// The left hand.
    Left,
    /// The right hand.
    Right,
}

impl Handedness {
    /// Parse `"left"` / `"right"` (case-insensitive).
    ///
    /// # Errors
    /// [`KinError::UnknownHandedness`] for anything else.
    pub fn from_name(name: &str) -> Result<Handedness, KinError> {
        match name.to_ascii_lowercase().as_str() {
            "left" => Ok(Handedness::Left),
            "right" => Ok(Handedness::Right),
            _ => Err(KinError::UnknownHandedness(name.to_string())),
        }
    }

    /// `"left"` or `"right"`.
    pub fn name(self) -> &'static str {
        match self {
            Handedness::Left => "left",
            Handedness::Right => "right",
        }
    }
}

/// The coordinate space hand positions are given in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Space {
    /// OpenXR / WebXR reference space: right-handed, +Y up, −Z forward, metres.
    OpenXr,
    /// Unity world space: left-handed, +Y up, +Z forward, metres.
    Unity,
    /// The robot's Base frame: right-handed, +Z up, metres.
    RobotBase,
}

impl Space {
    /// `"openxr"` (also accepts `"webxr"`), `"unity"` or `"robot_base"`.
    ///
    /// # Errors
    /// [`KinError::UnknownSpace`] for anything else.
    pub fn from_name(name: &str) -> Result<Space, KinError> {
        match name.to_ascii_lowercase().replace('-', "_").as_str() {
            "openxr" | "webxr" => Ok(Space::OpenXr),
            "unity" => Ok(Space::Unity),
            "robot_base" | "base" => Ok(Space::RobotBase),
            _ => Err(KinError::UnknownSpace(name.to_string())),
        }
    }

    /// The canonical name.
    pub fn name(self) -> &'static str {
        match self {
            Space::OpenXr => "openxr",
            Space::Unity => "unity",
            Space::RobotBase => "robot_base",
        }
    }
}

impl Space {
    /// Convert a point (or a direction) from this space's axes to the right-handed
    /// forward-left-up (FLU, Z up) axes the robot Base uses. The map is fixed per space:
    /// - OpenXR/WebXR (right-handed, +Y up, −Z forward, +X right): `(−z, −x, y)`;
    /// - Unity (left-handed, +Y up, +Z forward, +X right): `(z, −x, y)` (this flips handedness,
    ///   the ROS-TCP-Connector convention);
    /// - RobotBase: identity.
    pub fn to_flu(self, p: &Vector3<f64>) -> Vector3<f64> {
        match self {
            Space::OpenXr => Vector3::new(-p.z, -p.x, p.y),
            Space::Unity => Vector3::new(p.z, -p.x, p.y),
            Space::RobotBase => *p,
        }
    }
}

/// Where the tracking space sits relative to the robot.
///
/// A point `p` given in `space` goes to Base as
/// `p_base = base_from_space · (scale · space.to_flu(p))`: first the fixed axis change of the
/// space to right-handed Z-up axes ([`Space::to_flu`], which also undoes Unity's left-handedness),
/// then the position scale, then the rigid transform `base_from_space` (rotation + offset) from
/// those axes to the robot Base.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Calibration {
    /// Rigid transform from the (FLU-converted, scaled) tracking space to the robot Base frame.
    pub base_from_space: Pose,
    /// Position scale applied to hand positions before `base_from_space` (1 = metres to metres).
    pub scale: f64,
    /// The coordinate space hand positions are given in.
    pub space: Space,
}

impl Default for Calibration {
    /// OpenXR LOCAL space (origin at the head at start-up), operator standing behind the robot and
    /// facing Base +X. A hand 0.4 m in front of and 0.4 m below the head maps to (0.3, 0, 0.2) m in
    /// Base (in front of the UR3's shoulder, above the table): `base_from_space` = translation
    /// (−0.1, 0, 0.6), no rotation; scale 1.
    fn default() -> Self {
        Calibration { base_from_space: Pose::translation(-0.1, 0.0, 0.6), scale: 1.0, space: Space::OpenXr }
    }
}

impl Calibration {
    /// A calibration from its parts: `base_from_space` (`None`: the default's), `scale` and the
    /// name of the space (as [`Space::from_name`]).
    ///
    /// # Errors
    /// [`KinError::UnknownSpace`] for an unknown space; [`KinError::NotPositive`] when `scale` is
    /// not a positive finite number.
    pub fn new(base_from_space: Option<Pose>, scale: f64, space: &str) -> Result<Calibration, KinError> {
        let space = Space::from_name(space)?;
        if !(scale.is_finite() && scale > 0.0) {
            return Err(KinError::NotPositive { name: "scale", value: scale });
        }
        let base_from_space = base_from_space.unwrap_or(Calibration::default().base_from_space);
        Ok(Calibration { base_from_space, scale, space })
    }

    /// Identity calibration for positions already in the robot Base frame.
    pub fn identity() -> Self {
        Calibration { base_from_space: Pose::identity(), scale: 1.0, space: Space::RobotBase }
    }

    /// Convert a point from the calibration's space into the robot Base frame.
    pub fn point_to_base(&self, p: &Vector3<f64>) -> Vector3<f64> {
        let flu = self.space.to_flu(p) * self.scale;
        self.base_from_space.transform_point(&flu.into()).coords
    }
}

/// The three tracked joints the hand frame is built from, in the calibration's space.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HandPoints {
    /// The wrist joint.
    pub wrist: Vector3<f64>,
    /// The index finger's proximal joint (MCP knuckle).
    pub index_proximal: Vector3<f64>,
    /// The middle finger's proximal joint (MCP knuckle).
    pub middle_proximal: Vector3<f64>,
}

impl HandPoints {
    /// From the three positions, in this order.
    pub fn new(wrist: [f64; 3], index_proximal: [f64; 3], middle_proximal: [f64; 3]) -> HandPoints {
        HandPoints {
            wrist: wrist.into(),
            index_proximal: index_proximal.into(),
            middle_proximal: middle_proximal.into(),
        }
    }

    /// The three joints of one frame of a hand log in `layout` (`joints[i]` is joint `i`).
    ///
    /// # Errors
    /// [`KinError::InvalidPose`] when `joints` has fewer entries than the layout needs.
    pub fn from_layout(joints: &[[f64; 3]], layout: HandLayout) -> Result<HandPoints, KinError> {
        if joints.len() < layout.joint_count() {
            return Err(KinError::InvalidPose("hand frame has fewer joints than its layout"));
        }
        Ok(HandPoints::new(
            joints[layout.wrist()],
            joints[layout.index_proximal()],
            joints[layout.middle_proximal()],
        ))
    }
}

/// The hand frame of §3.2 in Base (see the module docs): columns x, y, z, origin at the wrist.
///
/// # Errors
/// [`KinError::NonFinite`] for NaN/∞ input or calibration; [`KinError::Overflow`] (naming the
/// joint) for finite input that overflows in Base or in the joint differences;
/// [`KinError::DegenerateHand`] when the
/// wrist and middle knuckle coincide, the knuckles coincide, or the three joints are collinear
/// (angle between `x'` and `y'` within 1e-3 rad of 0 or π).
pub fn hand_frame(hand: &HandPoints, handedness: Handedness, calib: &Calibration) -> Result<Pose, KinError> {
    let HandPoints { wrist, index_proximal, middle_proximal } = hand;
    let finite = |v: &Vector3<f64>| v.iter().all(|x| x.is_finite());
    if !(finite(wrist) && finite(index_proximal) && finite(middle_proximal)) {
        return Err(KinError::NonFinite("hand joint positions"));
    }
    let bt = calib.base_from_space.translation.vector;
    let bq = calib.base_from_space.rotation.coords;
    if !(calib.scale.is_finite() && bt.iter().all(|x| x.is_finite()) && bq.iter().all(|x| x.is_finite())) {
        return Err(KinError::NonFinite("calibration"));
    }
    if calib.scale <= 0.0 {
        return Err(KinError::InvalidPose("calibration scale must be > 0"));
    }
    let w = calib.point_to_base(wrist);
    let ip = calib.point_to_base(index_proximal);
    let mp = calib.point_to_base(middle_proximal);
    for (p, what) in [
        (&w, "wrist is too large: converted into the Base frame it is not finite"),
        (&ip, "index_proximal is too large: converted into the Base frame it is not finite"),
        (&mp, "middle_proximal is too large: converted into the Base frame it is not finite"),
    ] {
        if !finite(p) {
            return Err(KinError::Overflow(what));
        }
    }
    let yp = mp - w;
    let mut xp = mp - ip;
    if handedness == Handedness::Left {
        xp = -xp;
    }
    // Lengths and directions computed on max-scaled copies, so huge (finite) coordinates neither
    // overflow nor lose the frame.
    let Some((y, ny)) = scaled_unit(&yp) else {
        return Err(KinError::Overflow("middle_proximal − wrist is too large (not finite)"));
    };
    let Some((xu, nx)) = scaled_unit(&xp) else {
        return Err(KinError::Overflow("middle_proximal − index_proximal is too large (not finite)"));
    };
    if ny < 1e-6 {
        return Err(KinError::DegenerateHand("wrist and middle proximal joint coincide"));
    }
    if nx < 1e-6 {
        return Err(KinError::DegenerateHand("index and middle proximal joints coincide"));
    }
    let zc = xu.cross(&y);
    let sin = zc.norm();
    if sin < 1e-3 {
        return Err(KinError::DegenerateHand("wrist, index and middle proximal joints are collinear"));
    }
    let z = zc / sin;
    let x = y.cross(&z);
    let r = Matrix3::from_columns(&[x, y, z]);
    let q = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r));
    Ok(Pose::from_parts(Translation3::from(w), q))
}

/// `v / |v|` and `|v|`, computed without overflow; `None` for a zero or non-finite vector.
fn scaled_unit(v: &Vector3<f64>) -> Option<(Vector3<f64>, f64)> {
    let s = v.amax();
    if !(s.is_finite() && s > 0.0) {
        return if s == 0.0 { Some((Vector3::zeros(), 0.0)) } else { None };
    }
    let u = v / s;
    let n = u.norm();
    Some((u / n, n * s))
}

/// The fixed rotation from the hand frame to tool0: columns are tool0's axes in hand coordinates
/// (`tool0.x = hand.y`, `tool0.y = hand.x`, `tool0.z = −hand.z`).
pub fn tool_from_hand_rotation() -> UnitQuaternion<f64> {
    let r = Matrix3::new(0.0, 1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, -1.0);
    UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r))
}

/// Hand joints → tool0 target pose in Base (paper §3.2): the [`hand_frame`] with its axes mapped
/// to tool0 (see the module docs), origin at the (calibrated) wrist.
///
/// # Errors
/// As [`hand_frame`].
pub fn hand_to_target(
    hand: &HandPoints,
    handedness: Handedness,
    calib: &Calibration,
) -> Result<Pose, KinError> {
    let h = hand_frame(hand, handedness, calib)?;
    let f = Frame::from_pose(&h);
    let r = f.r * tool_from_hand_rotation().to_rotation_matrix().into_inner();
    let q = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r));
    Ok(Pose::from_parts(h.translation, q))
}

/// [`hand_to_target`] on one frame of a hand log in `layout` (`joints[i]` is joint `i`).
///
/// # Errors
/// [`KinError::InvalidPose`] when `joints` has fewer entries than the layout needs; otherwise as
/// [`hand_frame`].
pub fn hand_to_target_layout(
    joints: &[[f64; 3]],
    layout: HandLayout,
    handedness: Handedness,
    calib: &Calibration,
) -> Result<Pose, KinError> {
    hand_to_target(&HandPoints::from_layout(joints, layout)?, handedness, calib)
}
