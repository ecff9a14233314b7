//! Engagement: how the hand's pose becomes the tool's target.
//!
//! [`Mapping::Absolute`] is the paper's: the tool goes where the hand is (through the
//! calibration). [`Mapping::Clutch`] is how peers' XR teleoperation engages (a clutch): when the
//! clutch engages, the hand's pose and the tool's pose are captured, and from then on the tool
//! moves by the hand's motion since then (translation in Base, rotation applied in Base), so any
//! comfortable hand orientation drives it and the arm does not jump at engagement. Releasing the
//! clutch lets the person reposition the hand; engaging again captures both poses anew.
//!
//! Under the clutch the tool's commanded pose walks toward the hand's target by at most
//! [`MAX_STEP_M`] and [`MAX_STEP_RAD`] per control step, each intermediate pose solved by IK from
//! the last: a reachable target is reached along a bounded path, never refused because one IK
//! step would be too large; a step IK cannot take leaves the commanded pose where it was.

use ur3_kin::Pose;
use ur3_kin::nalgebra::UnitQuaternion;

/// Largest translation of the commanded pose per control step (0.5 m/s at 25 Hz).
pub const MAX_STEP_M: f64 = 0.02;
/// Largest rotation of the commanded pose per control step (90°/s at 25 Hz).
pub const MAX_STEP_RAD: f64 = std::f64::consts::FRAC_PI_2 * 0.04;

/// How the hand's pose maps to the tool's target.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Mapping {
    /// The tool goes where the hand is (the paper's; hand logs that name no mapping).
    #[default]
    Absolute,
    /// The tool moves by the hand's motion since the clutch engaged.
    Clutch,
}

impl Mapping {
    /// The name hand logs and the protocol use.
    pub fn name(self) -> &'static str {
        match self {
            Mapping::Absolute => "absolute",
            Mapping::Clutch => "clutch",
        }
    }

    /// The mapping called `name` (None: not one).
    pub fn from_name(name: &str) -> Option<Mapping> {
        [Mapping::Absolute, Mapping::Clutch].into_iter().find(|m| m.name() == name)
    }
}

/// A clutch command that comes with a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ClutchInput {
    /// Engage (again) at this frame: the hand's and the tool's poses are captured anew.
    Engage,
    /// Release: the tool stops following until the next engage.
    Release,
}

/// The clutch's state in one session.
#[derive(Debug, Clone, Default)]
pub struct Clutch {
    /// The hand's and the tool's pose when it engaged.
    engaged: Option<(Pose, Pose)>,
    /// Released by the person (no engaging on the next hand frame until an engage).
    released: bool,
    /// Where the tool is asked to be now (walking toward the hand's target).
    commanded: Option<Pose>,
}

impl Clutch {
    /// Apply the frame's command.
    pub fn apply(&mut self, input: Option<ClutchInput>) {
        match input {
            Some(ClutchInput::Engage) => (self.released, self.engaged) = (false, None),
            Some(ClutchInput::Release) => (self.released, self.engaged) = (true, None),
            None => {}
        }
    }

    /// Engaged now.
    pub fn engaged(&self) -> bool {
        self.engaged.is_some()
    }

    /// The tool's target for the hand at `hand` (hand_to_target's pose): engages here if it is not
    /// engaged and not released, capturing `tool()` (the pose the arm is heading to). None while
    /// released.
    pub fn target(&mut self, hand: &Pose, tool: impl FnOnce() -> Pose) -> Option<Pose> {
        if self.released {
            return None;
        }
        let (h0, t0) = match self.engaged {
            Some(e) => e,
            None => {
                let t = tool();
                self.commanded = Some(t);
                *self.engaged.insert((*hand, t))
            }
        };
        let translation = t0.translation.vector + (hand.translation.vector - h0.translation.vector);
        let rotation = (hand.rotation * h0.rotation.inverse()) * t0.rotation;
        Some(Pose::from_parts(translation.into(), rotation))
    }

    /// The next commanded pose toward `target`: at most one bounded step from the current one.
    pub fn next(&self, target: &Pose) -> Pose {
        match &self.commanded {
            Some(c) => step_toward(c, target, MAX_STEP_M, MAX_STEP_RAD),
            None => *target,
        }
    }

    /// The arm can take the commanded pose `p` (IK found it): it is the current one now.
    pub fn commit(&mut self, p: Pose) {
        self.commanded = Some(p);
    }
}

/// `from` moved toward `to` by at most `max_m` of translation and `max_rad` of rotation (the
/// shortest rotation, in Base).
pub fn step_toward(from: &Pose, to: &Pose, max_m: f64, max_rad: f64) -> Pose {
    let mut d = to.translation.vector - from.translation.vector;
    let n = d.norm();
    if n > max_m {
        d *= max_m / n;
    }
    let mut r = from.rotation.rotation_to(&to.rotation);
    let a = r.angle();
    if a > max_rad {
        r = r.powf(max_rad / a);
    }
    // renormalised: a product of unit quaternions drifts off the unit sphere, and each step
    // starts from the last one's result (unrenormalised, its norm would decay geometrically)
    let rotation = UnitQuaternion::new_normalize((r * from.rotation).into_inner());
    Pose::from_parts((from.translation.vector + d).into(), rotation)
}

#[cfg(test)]
mod tests {
    use super::*;
    use ur3_kin::nalgebra::Vector3;

    fn pose(x: f64, y: f64, z: f64, roll: f64, pitch: f64, yaw: f64) -> Pose {
        Pose::from_parts(Vector3::new(x, y, z).into(), UnitQuaternion::from_euler_angles(roll, pitch, yaw))
    }

    #[test]
    fn engaging_captures_both_poses_and_the_tool_moves_by_the_hands_motion() {
        let mut c = Clutch::default();
        let tool = pose(0.1, 0.3, 0.2, std::f64::consts::PI, 0.0, 0.3);
        let h0 = pose(-0.4, 0.9, 1.1, 0.2, -1.0, 2.0); // any orientation
        let t = c.target(&h0, || tool).unwrap();
        assert!((t.translation.vector - tool.translation.vector).norm() < 1e-12);
        assert!(t.rotation.angle_to(&tool.rotation) < 1e-12, "no jump at engagement");
        // the hand moves 5 cm along x and turns 0.2 rad about Base z
        let turn = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 0.2);
        let h1 = Pose::from_parts(
            (h0.translation.vector + Vector3::new(0.05, 0.0, 0.0)).into(),
            turn * h0.rotation,
        );
        let t1 = c.target(&h1, || unreachable!("engaged already")).unwrap();
        assert!(
            (t1.translation.vector - tool.translation.vector - Vector3::new(0.05, 0.0, 0.0)).norm() < 1e-12
        );
        assert!(t1.rotation.angle_to(&(turn * tool.rotation)) < 1e-12);
    }

    #[test]
    fn released_follows_nothing_until_engaged_anew() {
        let mut c = Clutch::default();
        let tool = pose(0.1, 0.3, 0.2, 0.0, 0.0, 0.0);
        c.target(&pose(0.0, 0.0, 0.0, 0.0, 0.0, 0.0), || tool);
        c.apply(Some(ClutchInput::Release));
        assert!(!c.engaged());
        assert!(c.target(&pose(0.5, 0.0, 0.0, 0.0, 0.0, 0.0), || tool).is_none());
        c.apply(Some(ClutchInput::Engage));
        // re-engaged with the hand elsewhere: the tool stays where it is
        let t = c.target(&pose(0.5, 0.0, 0.0, 0.0, 0.0, 0.0), || tool).unwrap();
        assert!((t.translation.vector - tool.translation.vector).norm() < 1e-12);
    }

    #[test]
    fn a_step_is_bounded_and_reaches_the_goal_when_near() {
        let a = pose(0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        let b = pose(0.3, 0.0, 0.0, 0.0, 0.0, 2.0);
        let s = step_toward(&a, &b, MAX_STEP_M, MAX_STEP_RAD);
        assert!(((s.translation.vector - a.translation.vector).norm() - MAX_STEP_M).abs() < 1e-12);
        assert!((s.rotation.angle_to(&a.rotation) - MAX_STEP_RAD).abs() < 1e-12);
        let mut p = a;
        for _ in 0..40 {
            p = step_toward(&p, &b, MAX_STEP_M, MAX_STEP_RAD);
        }
        assert!((p.translation.vector - b.translation.vector).norm() < 1e-12);
        assert!(p.rotation.angle_to(&b.rotation) < 1e-9);
    }

    #[test]
    fn many_steps_keep_the_rotation_a_unit_quaternion() {
        let (a, b) = (pose(0.0, 0.0, 0.0, 0.3, 0.2, 0.1), pose(0.01, 0.0, 0.0, 0.3, 0.2, 0.1 + 1e-9));
        let mut p = a;
        for _ in 0..10_000 {
            p = step_toward(&p, &b, MAX_STEP_M, MAX_STEP_RAD);
        }
        assert!((p.rotation.coords.norm() - 1.0).abs() < 1e-12);
    }
}
