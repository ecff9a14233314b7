//! Scripted joint-space experts (a reference policy and a test oracle).
//!
//! The expert reads a [`Snapshot`] and returns the action a human demonstration would record:
//! joint part `clip((q_goal − q)/joint_step, −1, 1)` (the spec's [`TaskSpec::joint_step`],
//! [`MAX_JOINT_STEP`](crate::MAX_JOINT_STEP) unless it sets `robot.joint_step`) towards the current waypoint's joint
//! solution, end-effector command ∈ {−1, 0, +1}. Waypoints are Cartesian TCP poses (flange pointing
//! straight down) solved to joint angles by `ur3_kin::ik` (the project's one IK), seeded with the
//! current joints so consecutive solutions stay on one branch.
//!
//! TileSuction: above the tile's grasp point (+8 cm) → down to 1.2 cm above it → suction →
//! lift 10 cm → carry the tile 8 cm above the target → lower it onto the target (install ends
//! the episode). BlockGrip: above the block (open) → fingers around it → close → lift → above the
//! pad → lower → open (place ends the episode). Screw: above the nut (open) → fingers around it →
//! close → spin (tighten) until done. TileRow: for the current tile (a snapshot's `object`: the
//! first not installed), as TileSuction up to 3 mm above its target → suction off, wait until the
//! tile is installed (at most [`ROW_RELEASE_WAIT`] steps) → lift the cups to 0.14 m → the next
//! tile; a tile that did not install is picked again where it lies.

use crate::Task;
use crate::env::Snapshot;
use crate::spec::TaskSpec;
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use std::f64::consts::PI;

/// TileRow: steps the expert waits with the suction off for a released tile to be installed
/// (it lands and comes to rest within a few) before it lifts the cups and goes on.
pub const ROW_RELEASE_WAIT: u32 = 20;

/// IK to a tool0 pose on the UR3 nearest `seed`: [`ur3_kin::ik`] with its default options
/// (closed form + Gauss-Newton, residual below 1e-10 m / rad, joints wrapped to [−π, π]), so
/// consecutive solutions seeded with the current joints stay on one branch. `None` when the pose
/// is unreachable. (The name is kept from the damped-least-squares solver this replaced.)
pub fn ik_dls(target: &Isometry3<f64>, seed: &[f64; 6]) -> Option<[f64; 6]> {
    ik_on(&ur3_kin::UR3, target, seed)
}

/// [`ik_dls`] on the arm `model`.
pub fn ik_on(model: &ur3_kin::UrModel, target: &Isometry3<f64>, seed: &[f64; 6]) -> Option<[f64; 6]> {
    ur3_kin::ik(model, target, Some(seed), &ur3_kin::IkOptions::default()).ok()
}

/// Flange orientation used by the experts: tool Z straight down, tool X along Base X.
pub fn tool_down() -> UnitQuaternion<f64> {
    UnitQuaternion::from_axis_angle(&Vector3::x_axis(), PI)
}

/// tool0 pose that puts a TCP `tcp_z` m out along the flange axis at `tcp`, flange pointing down.
pub fn tool0_for_tcp(tcp: Vector3<f64>, tcp_z: f64) -> Isometry3<f64> {
    // Tool Z points down, so tool0 sits tcp_z above the TCP.
    Isometry3::from_parts(Translation3::from(tcp + Vector3::new(0.0, 0.0, tcp_z)), tool_down())
}

fn iso(p: &crate::PoseRec) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(p.t[0], p.t[1], p.t[2]),
        UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(p.q[3], p.q[0], p.q[1], p.q[2])),
    )
}

fn v3(a: [f64; 3]) -> Vector3<f64> {
    Vector3::new(a[0], a[1], a[2])
}

/// A scripted expert for one task. Call [`Expert::reset`] at every episode start.
#[derive(Debug, Clone)]
pub struct Expert {
    task: Task,
    /// The arm the waypoints are solved for (the spec's `robot.model`).
    arm: &'static ur3_kin::UrModel,
    /// The TCP's offset along tool0 z and the grasp point's height above the object's centre (m).
    tcp_z: f64,
    grasp_dz: f64,
    /// The task's numbers: how an action moves the arm ([`crate::action::action_toward`]).
    spec: std::sync::Arc<TaskSpec>,
    phase: u8,
    goal: Option<[f64; 6]>,
    /// Steps spent in the current phase.
    ticks: u32,
    /// The current joint goal is the phase's final waypoint (not an intermediate leg).
    final_leg: bool,
    /// TileRow: tiles installed when the current one was picked.
    installed_at_pick: usize,
}

impl Expert {
    pub fn new(task: Task) -> Expert {
        Expert::for_spec(&TaskSpec::builtin(task))
    }

    /// The expert of the task `spec` describes (its logic's script, the spec's TCP and object).
    pub fn for_spec(spec: &TaskSpec) -> Expert {
        let task = spec.task();
        let suction = matches!(task, Task::TileSuction | Task::TileRow | Task::TilePlace);
        let grasp_dz = if suction { spec.object_half_height() as f64 } else { 0.0 };
        Expert {
            task,
            arm: spec.arm(),
            tcp_z: spec.tcp_z() as f64,
            grasp_dz,
            spec: std::sync::Arc::new(spec.clone()),
            phase: 0,
            goal: None,
            ticks: 0,
            final_leg: true,
            installed_at_pick: 0,
        }
    }

    /// Forget the episode's progress.
    pub fn reset(&mut self) {
        self.phase = 0;
        self.goal = None;
        self.ticks = 0;
        self.installed_at_pick = 0;
    }

    /// The current phase index (for diagnostics).
    pub fn phase(&self) -> u8 {
        self.phase
    }

    /// Write the action for state `s` into `out` (length `task.act_dim()`).
    pub fn act(&mut self, s: &Snapshot, out: &mut [f32]) {
        out.iter_mut().for_each(|v| *v = 0.0);
        // Advance phases whose goal has been reached (at most a few per call).
        for _ in 0..4 {
            if self.goal.is_none() {
                self.goal = self.plan(s);
                self.ticks = 0;
            }
            match self.goal {
                Some(g) if reached(&g, &s.q) && self.motion_phase() => {
                    if self.final_leg {
                        self.next();
                    } else {
                        self.goal = None;
                    }
                }
                _ => break,
            }
        }
        self.ticks += 1;
        if let Some(g) = self.goal {
            let a = crate::action::action_toward(&self.spec, &s.q, &g);
            for i in 0..6 {
                out[i] = a[i] as f32;
            }
        }
        self.command(s, out);
    }

    fn next(&mut self) {
        // TileRow's script repeats for each tile.
        self.phase = if self.task == Task::TileRow && self.phase >= 7 { 0 } else { self.phase + 1 };
        self.goal = None;
        self.ticks = 0;
    }

    /// Phases that end when the joint goal is reached (others end on an event).
    fn motion_phase(&self) -> bool {
        match self.task {
            Task::TileSuction => self.phase != 2,
            Task::BlockGrip => !matches!(self.phase, 2 | 6),
            Task::Screw => !matches!(self.phase, 2 | 3),
            Task::TileRow | Task::TilePlace => !matches!(self.phase, 2 | 6),
        }
    }

    fn command(&mut self, s: &Snapshot, out: &mut [f32]) {
        match (self.task, self.phase) {
            (Task::TileSuction, 2) => {
                out[6] = 1.0;
                if s.held {
                    self.next();
                    self.goal = self.plan(s);
                }
            }
            (Task::TileRow, 2) => {
                out[6] = 1.0;
                if s.held {
                    self.installed_at_pick = installed(s);
                    self.next();
                    self.goal = self.plan(s);
                }
            }
            (Task::TileRow, 6) => {
                out[6] = -1.0;
                let done = installed(s) > self.installed_at_pick || self.ticks > ROW_RELEASE_WAIT;
                if !s.held && done {
                    self.next();
                    self.goal = self.plan(s);
                }
            }
            // TilePlace: hold until the vacuum is built up, then lift; let go, then retreat.
            (Task::TilePlace, 2) => {
                out[6] = 1.0;
                if s.held && self.ticks > PLACE_SEAL_WAIT {
                    self.next();
                    self.goal = self.plan(s);
                }
            }
            (Task::TilePlace, 6) => {
                out[6] = -1.0;
                if !s.held {
                    self.next();
                    self.goal = self.plan(s);
                }
            }
            (Task::BlockGrip | Task::Screw, 0 | 1) => out[6] = -1.0,
            (Task::BlockGrip | Task::Screw, 2) => {
                out[6] = 1.0;
                if s.held {
                    self.next();
                    self.goal = self.plan(s);
                }
            }
            (Task::BlockGrip, 6) => out[6] = -1.0,
            (Task::Screw, 3) => {
                out[6] = 1.0;
                out[7] = 1.0;
            }
            _ => {}
        }
    }

    /// Joint goal for a straight Cartesian move of tool0 towards `goal`, in legs of at most
    /// `LEG` metres (joint-space interpolation over short legs stays close to the line).
    fn linear(&mut self, s: &Snapshot, goal: Isometry3<f64>) -> Option<[f64; 6]> {
        const LEG: f64 = 0.02;
        let cur = iso(&s.tool0).translation.vector;
        let d = goal.translation.vector - cur;
        let len = d.norm();
        if len > LEG {
            self.final_leg = false;
            let sub = Isometry3::from_parts(Translation3::from(cur + d * (LEG / len)), goal.rotation);
            ik_on(self.arm, &sub, &s.q)
        } else {
            self.final_leg = true;
            ik_on(self.arm, &goal, &s.q)
        }
    }

    fn plan(&mut self, s: &Snapshot) -> Option<[f64; 6]> {
        self.final_leg = true;
        let obj = v3(s.object.t);
        let tgt = v3(s.target.t);
        let up = Vector3::z();
        let tz = self.tcp_z;
        match self.task {
            Task::TileSuction => {
                let grasp = obj + up * self.grasp_dz;
                match self.phase {
                    0 => ik_on(self.arm, &tool0_for_tcp(grasp + up * 0.08, tz), &s.q),
                    1 => self.linear(s, tool0_for_tcp(grasp + up * 0.012, tz)),
                    2 => Some(s.q),
                    3 => {
                        let t = v3(s.tcp.t);
                        self.linear(s, tool0_for_tcp(Vector3::new(t.x, t.y, 0.13), tz))
                    }
                    4 | 5 => {
                        let lift = if self.phase == 4 { 0.08 } else { 0.0 };
                        let tile_in_tool = iso(&s.tool0).inverse() * iso(&s.object);
                        let tile_goal = Isometry3::from_parts(
                            Translation3::from(tgt + up * lift),
                            iso(&s.object).rotation,
                        );
                        self.linear(s, tile_goal * tile_in_tool.inverse())
                    }
                    _ => Some(s.q),
                }
            }
            Task::BlockGrip => match self.phase {
                0 => ik_on(self.arm, &tool0_for_tcp(obj + up * 0.10, tz), &s.q),
                1 => self.linear(s, tool0_for_tcp(obj, tz)),
                2 => Some(s.q),
                3 => {
                    let t = v3(s.tcp.t);
                    self.linear(s, tool0_for_tcp(Vector3::new(t.x, t.y, 0.14), tz))
                }
                4 | 5 => {
                    let lift = if self.phase == 4 { 0.08 } else { 0.004 };
                    let obj_in_tool = iso(&s.tool0).inverse() * iso(&s.object);
                    let goal =
                        Isometry3::from_parts(Translation3::from(tgt + up * lift), iso(&s.object).rotation);
                    self.linear(s, goal * obj_in_tool.inverse())
                }
                _ => Some(s.q),
            },
            Task::Screw => match self.phase {
                0 => ik_on(self.arm, &tool0_for_tcp(obj + up * 0.08, tz), &s.q),
                1 => self.linear(s, tool0_for_tcp(obj, tz)),
                _ => Some(s.q),
            },
            // TileSuction's script with contact: the lips set on the face (1 mm above it), the
            // tile turned square to its target on the way, lowered to 1.5 mm above its resting
            // height, let go, and the head lifted clear.
            Task::TilePlace => {
                let grasp = obj + up * self.grasp_dz;
                let t = v3(s.tcp.t);
                // The head turned square to the tile (its cups' pattern repeats every 90°), so
                // every lip lands on the face.
                let over = |p: Vector3<f64>| {
                    let g = tool0_for_tcp(p, tz);
                    Isometry3::from_parts(g.translation, square_to(&g.rotation, &iso(&s.object).rotation))
                };
                match self.phase {
                    0 => ik_on(self.arm, &over(grasp + up * 0.08), &s.q),
                    1 => self.linear(s, over(grasp + up * 0.001)),
                    3 => self.linear(s, up_to(s, 0.13 - t.z)),
                    4 | 5 => {
                        let lift = if self.phase == 4 { 0.08 } else { 0.0015 };
                        let tile_in_tool = iso(&s.tool0).inverse() * iso(&s.object);
                        let tile_goal = Isometry3::from_parts(
                            Translation3::from(tgt + up * lift),
                            square_to(&iso(&s.object).rotation, &iso(&s.target).rotation),
                        );
                        self.linear(s, tile_goal * tile_in_tool.inverse())
                    }
                    7 => self.linear(s, up_to(s, 0.05)),
                    _ => Some(s.q),
                }
            }
            // Every move a straight line (legs of 2 cm), so the arm never swings the cups or a
            // held tile through the other tiles.
            Task::TileRow => {
                let grasp = obj + up * self.grasp_dz;
                let t = v3(s.tcp.t);
                match self.phase {
                    0 => self.linear(s, tool0_for_tcp(grasp + up * 0.08, tz)),
                    1 => self.linear(s, tool0_for_tcp(grasp + up * 0.012, tz)),
                    3 => self.linear(s, tool0_for_tcp(Vector3::new(t.x, t.y, 0.13), tz)),
                    4 | 5 => {
                        let lift = if self.phase == 4 { 0.08 } else { 0.003 };
                        let tile_in_tool = iso(&s.tool0).inverse() * iso(&s.object);
                        let tile_goal = Isometry3::from_parts(
                            Translation3::from(tgt + up * lift),
                            iso(&s.object).rotation,
                        );
                        self.linear(s, tile_goal * tile_in_tool.inverse())
                    }
                    7 => self.linear(s, tool0_for_tcp(Vector3::new(t.x, t.y, 0.14), tz)),
                    _ => Some(s.q),
                }
            }
        }
    }
}

/// tool0 moved straight up by `dz` (m), turned as it is.
fn up_to(s: &Snapshot, dz: f64) -> Isometry3<f64> {
    let t0 = iso(&s.tool0);
    Isometry3::from_parts(Translation3::from(t0.translation.vector + Vector3::z() * dz), t0.rotation)
}

/// TilePlace: steps the expert keeps still after the hold began, so the vacuum is built up
/// (the built-in seal time is 0.1 s, 2.5 steps) before it lifts.
const PLACE_SEAL_WAIT: u32 = 4;

/// The rotation that turns `tile` (a square tile, or a head whose cups repeat every 90°) by the
/// least yaw about Base z to lie square to `target` (modulo 90°).
fn square_to(tile: &UnitQuaternion<f64>, target: &UnitQuaternion<f64>) -> UnitQuaternion<f64> {
    let yaw = |r: &UnitQuaternion<f64>| {
        let x = r * Vector3::x();
        x.y.atan2(x.x)
    };
    let q = std::f64::consts::FRAC_PI_2;
    let err = (yaw(target) - yaw(tile) + 0.5 * q).rem_euclid(q) - 0.5 * q;
    UnitQuaternion::from_axis_angle(&Vector3::z_axis(), err) * tile
}

/// TileRow: how many tiles of the row are installed (0 for the other tasks).
fn installed(s: &Snapshot) -> usize {
    s.row.iter().filter(|r| r.installed).count()
}

fn reached(goal: &[f64; 6], q: &[f64; 6]) -> bool {
    goal.iter().zip(q).all(|(g, v)| (g - v).abs() < 1e-5)
}
