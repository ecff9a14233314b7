//! TilePlace (issue 46): TileSuction's scene under rules a real cell keeps. Nothing is held
//! without contact, nothing passes through anything, and a success is a tile a tiler would
//! accept. Frame (32 floats): TileSuction's 16, the vacuum switch, tile − cup, target − tile, the
//! yaw error, the yaws as `cos 4ψ, sin 4ψ` and a fine gauge of the last millimetres
//! ([`Task::obs_frame_dim`](crate::Task::obs_frame_dim)).
//!
//! # The hold
//! * **Seal, per cup.** With the suction on, a cup seals when its lip lies on the tile's face:
//!   the lip centre within `seal.gap` of the face's plane (either side: a lip pressed a little
//!   into the face counts, and with spring-mounted cups `seal.stroke` more: the mount gives and
//!   the lip stays on the face), the whole lip inside the face's outline, and the cup's axis within
//!   `seal.angle_deg` of the face's normal. Judged after each physics step, on the poses the step
//!   left (so a held tile lagging its cups is judged where it is).
//! * **Vacuum.** From the first step a cup is sealed the vacuum builds up linearly over
//!   `seal.time` to `seal.vacuum_kpa`; it falls to zero when no cup is sealed or the suction is
//!   off. The observation's vacuum switch is that level times the sealed cups' share.
//! * **Hold.** While a cup is sealed the tile is held by a joint between the last link and the
//!   tile, never by moving the tile: the tile stays a dynamic body, so it collides with the
//!   table, the pad and the arm like any other (but the cups: the joint is their contact with
//!   the sealed face, their compliance). The joint draws the face onto the lips when the hold
//!   begins (as the vacuum does), and each of its six axes is a spring-damper motor whose force
//!   is capped: along the cups' axis (peel) at `vacuum · π · cup_radius² · sealed cups /
//!   safety_factor`, in tilt at that force times `cup_offset`, across the face at `lip_friction`
//!   times that force and in yaw at that times `cup_offset`. Across the face and in yaw the lips
//!   stick and slip: stiff springs reach the friction cap within [`SLIP`] / [`SLIP_ANG`], and a
//!   tile pushed further has slid for good (the hold is re-anchored where it is). A load the
//!   cups cannot hold (the tile's weight and inertia when swung, a push against the table) moves
//!   the tile away from the lips, and once no lip is within `seal.gap` of the face the hold is
//!   gone (the grip broke: the tile falls or stays where it was pushed). Pressed onto a tile
//!   that rests on something, the cups push back with at most [`CUP_PUSH`] each and give up to
//!   `seal.gap + seal.stroke`; pressed further, the arm stops (a protective stop, as a real arm
//!   stops on its force limit): the episode fails.
//! * **Release.** The suction command off takes the hold's forces away; its joint stays, force
//!   free, until the lips are `seal.gap` off the face ([`SealState::parting`]: a lip peels off,
//!   it does not kick). The tile's height at that moment is kept to judge the drop.
//! * **Solver.** A TilePlace world runs [`PLACE_SUBSTEPS`](crate::world::PLACE_SUBSTEPS) solver
//!   substeps per env step: with the default two, a tile let go 2 mm above the pad sank into it
//!   and was kicked sideways by millimetres.
//!
//! # Rules
//! * **Pick** (+1 once, `rewards.pick`): the first hold of the episode.
//! * **Placed** (+1, `rewards.success`, ends the episode): not held, resting (slower than
//!   `thresholds.rest_speed` for `thresholds.rest_steps` steps in a row) with its centre within
//!   `thresholds.rest_height` of the target's height, within `thresholds.success_dist` of the
//!   target in x and y, its yaw within `thresholds.success_yaw_deg` of the target's (modulo 90°
//!   for a square tile, 180° for an oblong one), and let go at most `thresholds.release_height`
//!   above where it rests (a drop is not a placement, even when it lands well).
//! * **Fall** (−0.5, `rewards.fail`, ends the episode): TileSuction's rules.
//!
//! A tile released off target is not a failure: it rests where it is and can be picked again.

use super::suction::{fell, req};
use super::{State, TaskLogic};
use crate::CONTROL_DT;
use crate::env::StepOutcome;
use crate::spec::{EffectorSpec, SealSpec, TaskSpec};
use rapier3d::prelude::*;

/// How far (m) the lips give across the face before the tile slides on them, and how far (rad)
/// in yaw: the hold's springs across the face reach the friction cap there, and a tile pushed
/// further has slid (the hold is re-anchored where it is: stick and slip, no creep back).
const SLIP: f32 = 0.0005;
const SLIP_ANG: f32 = 0.5 * std::f32::consts::PI / 180.0;

/// The force (N) one cup pushes back with when pressed onto the face (its lip's stiffness and
/// its mount's spring; a level compensator's spring pushes with a few newtons over its
/// stroke). A held tile pressed against the table or the pad is pushed by the cups with at most
/// this per cup, while it is pulled by up to the vacuum's peel force.
const CUP_PUSH: f32 = 5.0;

/// TilePlace's seal and placing state.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct SealState {
    /// The joint holding the tile (while a cup is sealed).
    pub(crate) joint: Option<ImpulseJointHandle>,
    /// The joint of a hold just let go, with no force left: it only keeps the cups' colliders
    /// from striking the face they were sealed on until the lips have left it (a lip peels off;
    /// it does not kick the tile). Removed once the lips are `seal.gap` off the face.
    pub(crate) parting: Option<ImpulseJointHandle>,
    /// Cups sealed after the last step.
    pub(crate) sealed: u8,
    /// Vacuum built up, 0 … 1 of `seal.vacuum_kpa`.
    pub(crate) level: f32,
    /// The hold broke (no lip left on the face with the suction on) in the last step.
    pub(crate) broke: bool,
    /// The cups were pressed into the held tile's face beyond `seal.gap + seal.stroke` in
    /// the last step: the arm pushed the tile against something that does not give.
    pub(crate) pressed: bool,
    /// The tile's centre height (m) when it was last let go.
    pub(crate) released_z: Option<f32>,
    /// Steps in a row the released tile has been resting.
    pub(crate) rest_run: u32,
}

/// The TilePlace logic.
#[derive(Debug)]
pub(crate) struct TilePlace;

/// The suction head's numbers the hold needs: (cup offset, cup radius, TCP z, seal).
fn head(spec: &TaskSpec) -> (f32, f32, f32, SealSpec) {
    match &spec.effector {
        EffectorSpec::Suction { cup_offset, cup_radius, tcp_z, seal: Some(seal), .. } => {
            (*cup_offset, *cup_radius, *tcp_z, *seal)
        }
        _ => unreachable!("invariant: the spec check gives TilePlace a suction head with a seal"),
    }
}

/// The tile's face the cups reach (the one turned up): its centre and outward normal.
fn face(tile: &Pose, half_height: f32) -> (Vector, Vector) {
    let up = tile.rotation * Vector::Z;
    let n = if up.z >= 0.0 { up } else { -up };
    (tile.translation + n * half_height, n)
}

/// The signed gap (m) between the TCP (the lips' centre) and the face the cups reach, along the
/// face's normal: positive above the face, negative pressed into it.
pub(crate) fn lip_gap(tcp: Vector, tile: &Pose, half_height: f32) -> f32 {
    let (c, n) = face(tile, half_height);
    (tcp - c).dot(n)
}

/// How many of the four cups on `tool0` are sealed on `tile` (a box of half extents `half`).
fn sealed_cups(spec: &TaskSpec, tool0: &Pose, tile: &Pose, half: [f32; 3]) -> u8 {
    let (off, r, tcp_z, seal) = head(spec);
    let (c, n) = face(tile, half[2]);
    let axis = tool0.rotation * Vector::Z; // out of the flange, towards the face
    if (-axis).dot(n) < seal.angle_deg.to_radians().cos() {
        return 0;
    }
    let inv = tile.inverse();
    let mut k = 0;
    for (sx, sy) in [(1.0f32, 1.0f32), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)] {
        let lip = *tool0 * Vector::new(sx * off, sy * off, tcp_z);
        let gap = (lip - c).dot(n);
        if gap > seal.gap || gap < -seal.give() {
            continue;
        }
        let local = inv * lip;
        if local.x.abs() + r <= half[0] && local.y.abs() + r <= half[1] {
            k += 1;
        }
    }
    k
}

/// The hold's anchor on the tile (`frame2`, world) moved back to within [`SLIP`] of the cups'
/// (`frame1`, world) across the face and within [`SLIP_ANG`] in yaw: what has slid further than
/// the lips give stays slid.
fn slipped(frame1: &Pose, frame2: &Pose) -> Pose {
    let d = frame1.rotation.inverse() * (frame2.translation - frame1.translation);
    let across = (d.x * d.x + d.y * d.y).sqrt();
    let mut t = frame2.translation;
    if across > SLIP {
        let back = Vector::new(d.x, d.y, 0.0) * (1.0 - SLIP / across);
        t -= frame1.rotation * back;
    }
    // The twist of frame2 against frame1 about the cups' axis (swing-twist: the z part).
    let r = frame1.rotation.inverse() * frame2.rotation;
    let twist = 2.0 * r.z.atan2(r.w);
    let twist = (twist + std::f32::consts::PI).rem_euclid(std::f32::consts::TAU) - std::f32::consts::PI;
    let mut rot = frame2.rotation;
    if twist.abs() > SLIP_ANG {
        let back = twist - SLIP_ANG.copysign(twist);
        rot = frame1.rotation * Rotation::from_rotation_z(-back) * r;
    }
    Pose::from_parts(t, rot)
}

/// The hold's force cap (N) along the cups' axis with `cups` sealed at vacuum `level` (0 … 1).
fn peel_force(spec: &TaskSpec, cups: u8, level: f32) -> f32 {
    let (_, r, _, seal) = head(spec);
    level * f32::from(cups) * seal.vacuum_kpa * 1000.0 * std::f32::consts::PI * r * r / seal.safety_factor
}

/// The tile's yaw about Base z (rad) and the symmetry period of a box with `half` extents.
pub(crate) fn yaw_and_period(p: &Pose, half: [f32; 3]) -> (f32, f32) {
    let x = p.rotation * Vector::X;
    let period =
        if (half[0] - half[1]).abs() < 1e-6 { std::f32::consts::FRAC_PI_2 } else { std::f32::consts::PI };
    (x.y.atan2(x.x), period)
}

/// `a` wrapped into `[-period / 2, period / 2)`.
pub(crate) fn wrap(a: f32, period: f32) -> f32 {
    (a + 0.5 * period).rem_euclid(period) - 0.5 * period
}

impl State {
    fn tile_half(&self) -> [f32; 3] {
        self.spec.object.half_extents.unwrap_or([0.0; 3])
    }

    /// The target's yaw minus the tile's, wrapped by the tile's symmetry (rad).
    pub(crate) fn yaw_error(&self) -> f32 {
        let half = self.tile_half();
        let (tile, period) = yaw_and_period(&self.object_pose(), half);
        let (target, _) = yaw_and_period(&self.target, half);
        wrap(target - tile, period)
    }

    /// Remove the hold at once, and any parting one (a teleport of the tile: tools.rs).
    pub(crate) fn drop_hold(&mut self) {
        for j in [self.seal.joint.take(), self.seal.parting.take()].into_iter().flatten() {
            self.world.impulse_joints.remove(j, true);
        }
        self.held = false;
    }

    /// Let go of the held tile: the vacuum falls, the hold's forces go to zero, and its joint
    /// parts once the lips are off the face ([`SealState::parting`]).
    fn let_go(&mut self) {
        self.released();
        self.held = false;
        let Some(h) = self.seal.joint.take() else { return };
        if let Some(j) = self.world.impulse_joints.get_mut(h, true) {
            for axis in [
                JointAxis::LinX,
                JointAxis::LinY,
                JointAxis::LinZ,
                JointAxis::AngX,
                JointAxis::AngY,
                JointAxis::AngZ,
            ] {
                j.data.set_motor_max_force(axis, 0.0);
            }
        }
        self.seal.parting = Some(h);
    }

    /// Remove the parting joint once the lips are `seal.gap` off the face, or the cups' centre
    /// is off the tile's outline (or a new hold begins: `now`).
    fn part(&mut self, now: bool) {
        let Some(h) = self.seal.parting else { return };
        let (_, _, tcp_z, seal) = head(&self.spec);
        let tcp = self.tool0 * Vector::new(0.0, 0.0, tcp_z);
        let (tile, half) = (self.object_pose(), self.tile_half());
        let local = tile.inverse() * tcp;
        let off_face = local.x.abs() > half[0] || local.y.abs() > half[1];
        if now || off_face || lip_gap(tcp, &tile, half[2]) > seal.gap {
            self.world.impulse_joints.remove(h, true);
            self.seal.parting = None;
        }
    }

    /// Make the joint that holds the tile, drawing its face onto the lips (as the vacuum does).
    fn make_hold(&mut self) {
        let (_, _, tcp_z, _) = head(&self.spec);
        let tile = self.object_pose();
        let tcp = self.tool0 * Pose::from_translation(Vector::new(0.0, 0.0, tcp_z));
        let axis = self.tool0.rotation * Vector::Z;
        let gap = lip_gap(tcp.translation, &tile, self.tile_half()[2]);
        // The point of the tile's face under the TCP: the joint draws it onto the TCP.
        let anchor = Pose::from_parts(tcp.translation + axis * gap, tcp.rotation);
        // The cups and the held face touch through the joint (the cups' compliance), not
        // through contacts; every other collider of the arm and the world still collides.
        let joint = GenericJointBuilder::new(JointAxesMask::empty())
            .local_frame1(Pose::from_translation(Vector::new(0.0, 0.0, tcp_z)))
            .local_frame2(tile.inverse() * anchor)
            .contacts_enabled(false)
            .build();
        let h = self.world.impulse_joints.insert(self.h.links[5], self.h.object, joint, true);
        self.seal.joint = Some(h);
        self.held = true;
        self.hold_gaps.push(gap);
    }

    /// Set the hold's motors for `cups` sealed cups at the current vacuum level.
    fn tune_hold(&mut self) {
        let Some(h) = self.seal.joint else { return };
        let (off, _, _, seal) = head(&self.spec);
        let f = peel_force(&self.spec, self.seal.sealed, self.seal.level).max(1e-3);
        let mass = self.spec.object.mass.unwrap_or(1.0);
        let half = self.tile_half();
        let inertia = mass * (half[0] * half[0] + half[1] * half[1]) / 3.0;
        // Springs that reach the cap at the seal gap (linear) or at 2° (angular), damped
        // critically for the tile's mass and inertia.
        let k_lin = f / seal.gap;
        let c_lin = 2.0 * (k_lin * mass).sqrt();
        let torque = f * off;
        let k_ang = torque / 2f32.to_radians();
        let c_ang = 2.0 * (k_ang * inertia).sqrt();
        // Along the cups' axis and in tilt: springs to the pose the hold began with (the cups'
        // elasticity), capped at the peel force and torque. Across the face and in yaw: the lips'
        // friction, stiff springs that reach `lip_friction` times the peel force (and that times
        // `cup_offset` in yaw) within SLIP; beyond it the tile has slid, for good.
        let slide = seal.lip_friction * f;
        let (k_slide, k_twist) = (slide / SLIP, slide * off / SLIP_ANG);
        let (_, _, tcp_z, _) = head(&self.spec);
        let tile = self.object_pose();
        let frame1 = self.tool0 * Pose::from_translation(Vector::new(0.0, 0.0, tcp_z));
        let pressed = lip_gap(frame1.translation, &tile, half[2]) < 0.0;
        let axial = if pressed { CUP_PUSH * f32::from(self.seal.sealed) } else { f };
        let Some(j) = self.world.impulse_joints.get_mut(h, true) else { return };
        let frame2 = slipped(&frame1, &(tile * j.data.local_frame2));
        j.data.set_local_frame2(tile.inverse() * frame2);
        for (axis, k, c, cap) in [
            (JointAxis::LinZ, k_lin, c_lin, axial),
            (JointAxis::AngX, k_ang, c_ang, torque),
            (JointAxis::AngY, k_ang, c_ang, torque),
            (JointAxis::LinX, k_slide, 2.0 * (k_slide * mass).sqrt(), slide),
            (JointAxis::LinY, k_slide, 2.0 * (k_slide * mass).sqrt(), slide),
            (JointAxis::AngZ, k_twist, 2.0 * (k_twist * inertia).sqrt(), slide * off),
        ] {
            j.data.set_motor_model(axis, MotorModel::ForceBased);
            j.data.set_motor(axis, 0.0, 0.0, k, c);
            j.data.set_motor_max_force(axis, cap);
        }
    }

    /// After a physics step: which cups are sealed, the vacuum, the hold made, kept or broken.
    fn update_seal(&mut self, out: &mut StepOutcome) {
        self.seal.broke = false;
        let (_, _, tcp_z, seal) = head(&self.spec);
        if self.seal.joint.is_some() || self.seal.parting.is_some() {
            let tcp = self.tool0 * Vector::new(0.0, 0.0, tcp_z);
            self.seal.pressed = lip_gap(tcp, &self.object_pose(), self.tile_half()[2]) < -seal.give();
        }
        let cups = if self.suction_on {
            sealed_cups(&self.spec, &self.tool0, &self.object_pose(), self.tile_half())
        } else {
            0
        };
        self.seal.sealed = cups;
        if cups == 0 {
            self.seal.level = 0.0;
            if self.seal.joint.is_some() {
                self.seal.broke = true;
                self.let_go();
            }
            self.part(false);
            return;
        }
        let ramp = if seal.time > 0.0 { CONTROL_DT / seal.time } else { 1.0 };
        self.seal.level = (self.seal.level + ramp).min(1.0);
        if self.seal.joint.is_none() {
            self.part(true);
            self.make_hold();
            let reward = self.spec.rewards.pick;
            self.first_pick(out, reward);
        }
        self.tune_hold();
    }

    /// Keep where the tile was let go.
    fn released(&mut self) {
        self.seal.released_z = Some(self.object_pose().translation.z);
        self.seal.rest_run = 0;
    }
}

impl TaskLogic for TilePlace {
    fn obs_frame_dim(&self) -> usize {
        32
    }

    fn act_dim(&self) -> usize {
        7
    }

    fn reset(&self, s: &mut State) {
        s.reset_effector(0.0);
        s.seal = SealState::default();
    }

    fn gripper_width(&self, _s: &State) -> f64 {
        0.0
    }

    fn carries_object(&self) -> bool {
        false
    }

    fn effector(&self, s: &mut State, action: &[f32], _out: &mut StepOutcome) {
        if s.seal.joint.is_some() {
            // A held tile never sleeps: the arm it hangs from moves it through the joint.
            s.world.wake_up(s.h.object, true);
        }
        let cmd = action[6];
        if cmd >= 0.5 {
            s.suction_on = true;
        } else if cmd <= -0.5 && s.suction_on {
            s.suction_on = false;
            s.seal.level = 0.0;
            s.seal.sealed = 0;
            if s.seal.joint.is_some() {
                s.let_go();
            }
        }
    }

    fn evaluate(&self, s: &mut State, out: &mut StepOutcome) {
        s.update_seal(out);
        let t = &s.spec.thresholds;
        let (p, v) = s.object_state();
        let resting = !s.held && v.length() < req(t.rest_speed);
        s.seal.rest_run = if resting { s.seal.rest_run + 1 } else { 0 };
        let d = p.translation - s.target.translation;
        let dropped_from = s.seal.released_z.map_or(f32::INFINITY, |z| z - p.translation.z);
        let placed = s.seal.rest_run >= req(t.rest_steps)
            && d.z.abs() <= req(t.rest_height)
            && (d.x * d.x + d.y * d.y).sqrt() <= req(t.success_dist)
            && s.yaw_error().abs() <= req(t.success_yaw_deg).to_radians()
            && dropped_from <= req(t.release_height);
        if placed {
            out.reward += s.spec.rewards.success;
            out.installed = true;
            out.terminated = true;
        } else if s.seal.pressed || fell(&s.spec, &p, v, s.held) {
            out.reward += s.spec.rewards.fail;
            out.fell = true;
            out.terminated = true;
        }
    }

    fn write_frame(&self, s: &State, f: &mut [f32]) {
        let suction = if s.suction_on { 1.0 } else { -1.0 };
        let k = s.write_frame(&[suction], f);
        let tcp = s.tcp().translation;
        let tile = s.object_pose();
        let tgt = s.target.translation;
        f[k] = s.seal.level * f32::from(s.seal.sealed) / 4.0;
        let (a, b) = (tile.translation - tcp, tgt - tile.translation);
        f[k + 1..k + 7].copy_from_slice(&[a.x, a.y, a.z, b.x, b.y, b.z]);
        let half = s.tile_half();
        let (yt, period) = yaw_and_period(&tile, half);
        let (yg, _) = yaw_and_period(&s.target, half);
        let m = std::f32::consts::TAU / period;
        f[k + 7] = wrap(yg - yt, period);
        f[k + 8..k + 12].copy_from_slice(&[(m * yt).cos(), (m * yt).sin(), (m * yg).cos(), (m * yg).sin()]);
        // The fine gauge: target − tile and the yaw error squashed at 1 cm and 2°.
        let g = |x: f32, scale: f32| (x / scale).tanh();
        let yaw = wrap(yg - yt, period);
        f[k + 12..k + 16].copy_from_slice(&[
            g(b.x, 0.01),
            g(b.y, 0.01),
            g(b.z, 0.01),
            g(yaw, 2f32.to_radians()),
        ]);
    }
}
