//! The test and tool API of [`Env`]: snapshots for recording, the arm's frames, the scene, and
//! teleports of the arm, the object and the nut (tests, demo tools; not part of an episode's
//! dynamics).

use super::{Env, PoseRec, Snapshot, to_pose};
use crate::task::screw;
use crate::world::{self, Scene};
use crate::{SimError, Task};
use rapier3d::prelude::*;
use std::f64::consts::PI;

impl Env {
    /// Everything needed to record or replay the current state.
    pub fn snapshot(&self) -> Snapshot {
        let s = &self.s;
        Snapshot {
            task: self.task,
            q: s.q,
            tool0: PoseRec::from_pose(&s.tool0),
            tcp: PoseRec::from_pose(&s.tcp()),
            object: PoseRec::from_pose(&s.object_pose()),
            target: PoseRec::from_pose(&s.target),
            suction_on: s.suction_on,
            held: s.held,
            gripper_width: self.logic.gripper_width(s),
            spin: s.spin,
            spin_angle: s.turns * 2.0 * PI,
            step: self.step_idx,
            episode_seed: self.episode_seed,
            picked: s.picked,
            done: self.done,
            row: crate::task::tile_row::snapshot_row(s),
        }
    }

    /// Poses of the arm's DH frames 0..=6 in the Base frame (`ur3_kin::fk_all` of the current
    /// joints; 0 = Base, 6 = tool0), for drawing the `SceneFrame::Link(i)` items.
    pub fn link_poses(&self) -> [PoseRec; 7] {
        let f = ur3_kin::fk_all(self.s.arm, &self.s.q);
        std::array::from_fn(|i| PoseRec::from_pose(&to_pose(&f[i])))
    }

    /// Static geometry of this env's scene (the object item is relative to the object pose).
    pub fn scene(&self) -> Scene {
        world::scene_spec(&self.s.spec, &self.s.start)
    }

    /// Test/tool API: teleport the arm to joint angles `q` (rad, each within [-π, π]).
    /// A held object moves with the flange. The observation is refreshed at the next step.
    pub fn set_joints(&mut self, q: [f64; 6]) -> Result<(), SimError> {
        if q.iter().any(|v| !v.is_finite() || v.abs() > PI) {
            return Err(SimError::InvalidState(format!(
                "joint angles must be finite and within [-pi, pi]: {q:?}"
            )));
        }
        // A tile held by a seal (TilePlace) keeps its pose in the flange's frame.
        let sealed = self.s.seal.joint.map(|_| self.s.tool0.inverse() * self.s.object_pose());
        self.teleport_arm(q);
        if let Some(rel) = sealed {
            let p = self.s.tool0 * rel;
            if let Some(b) = self.s.world.bodies.get_mut(self.s.h.object) {
                b.set_position(p, true);
                b.set_linvel(Vector::ZERO, true);
                b.set_angvel(Vector::ZERO, true);
            }
        }
        if self.s.held && self.logic.carries_object() {
            let p = self.s.tool0 * self.s.hold_offset;
            if let Some(b) = self.s.world.bodies.get_mut(self.s.h.object) {
                b.set_position(p, true);
                b.set_next_kinematic_position(p);
            }
        }
        Ok(())
    }

    /// Test/tool API: teleport the object (tile/block; TileRow: the current tile, the snapshot's
    /// `object`) to translation `t` (m) and rotation `q = [x, y, z, w]` with zero velocity; any
    /// hold is released (suction/grip state unchanged).
    /// For Screw, sets the nut's turn count instead (`t` ignored, rotation ignored): use
    /// [`Env::set_turns`].
    pub fn set_object_pose(&mut self, t: [f64; 3], q: [f64; 4]) -> Result<(), SimError> {
        if t.iter().chain(q.iter()).any(|v| !v.is_finite()) {
            return Err(SimError::InvalidState("object pose must be finite".into()));
        }
        if self.task == Task::Screw {
            return Err(SimError::InvalidState("the nut rides the bolt: use set_turns".into()));
        }
        let rot = Rotation::from_xyzw(q[0] as f32, q[1] as f32, q[2] as f32, q[3] as f32);
        if rot.length() < 1e-6 {
            return Err(SimError::InvalidState("zero quaternion".into()));
        }
        let p = Pose::from_parts(Vector::new(t[0] as f32, t[1] as f32, t[2] as f32), rot.normalize());
        if self.s.seal.joint.is_some() {
            self.s.drop_hold();
        } else if self.s.held {
            self.s.held = false;
            self.s.set_object_kinematic(false);
        }
        if let Some(b) = self.s.world.bodies.get_mut(self.s.h.object) {
            b.set_position(p, true);
            b.set_linvel(Vector::ZERO, true);
            b.set_angvel(Vector::ZERO, true);
        }
        Ok(())
    }

    /// Test/tool API (Screw): set the nut's turn count (0 = just caught the thread).
    pub fn set_turns(&mut self, turns: f64) -> Result<(), SimError> {
        if !turns.is_finite() || self.task != Task::Screw {
            return Err(SimError::InvalidState("set_turns needs the Screw task and a finite count".into()));
        }
        self.s.turns = turns;
        screw::place_nut(&mut self.s, true);
        Ok(())
    }

    /// True when every body pose in the world is finite and within 10 m of the base.
    pub fn bodies_sane(&self) -> bool {
        self.s.world.bodies.iter().all(|(_, b)| {
            let p = b.position();
            p.is_finite() && p.translation.length() < 10.0
        })
    }
}
