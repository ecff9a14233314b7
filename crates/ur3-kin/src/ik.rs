//! Inverse kinematics: the paper's Gauss-Newton solver (Table 2), the closed-form UR solver, and
//! the combined [`ik`] that returns the solution nearest a seed.
//!
//! Strategy of [`ik`]:
//! 1. validate the target (finite, proper rotation) and reject points beyond the arm's reach;
//! 2. with a seed (teleoperation warm start): Gauss-Newton from the seed;
//! 3. the closed-form solutions (up to 8) are computed in every case (≈1 µs); if one of them is
//!    nearer the seed than the Gauss-Newton result (or Gauss-Newton failed, or there is no seed),
//!    the nearest are polished by Gauss-Newton in order of distance and the first that converges is
//!    returned. Without a seed "nearest" means nearest the all-zero configuration.
//!    With [`IkOptions::gn_first`] = false the seeded case skips step 2 and goes straight to the
//!    nearest closed-form branch (Gauss-Newton from the seed stays as the fallback).
//!
//! [`IkOptions::use_analytic`] = false reduces [`ik`] to the paper's solver alone.
//!
//! Distances between joint vectors are Euclidean over per-joint wrapped differences.

use crate::KinError;
use crate::fk::{Frame, dh_frame, fk_frame, frames};
use crate::jacobian::jacobian_from_frames;
use crate::{Joints, Pose, UrModel};
use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3, Vector6};
use std::f64::consts::{FRAC_PI_2, PI, TAU};

/// Wrap an angle to [−π, π]. Finite in, finite out (a non-finite input gives 0).
#[inline]
pub fn wrap_angle(x: f64) -> f64 {
    if !x.is_finite() {
        return 0.0;
    }
    if (-PI..=PI).contains(&x) {
        return x;
    }
    let w = (x + PI).rem_euclid(TAU) - PI;
    w.clamp(-PI, PI)
}

/// Wrap every joint to [−π, π].
#[inline]
pub fn wrap_joints(q: &Joints) -> Joints {
    q.map(wrap_angle)
}

/// Distance between two joint vectors, per-joint differences wrapped to [−π, π].
#[inline]
pub fn joint_distance(a: &Joints, b: &Joints) -> f64 {
    a.iter().zip(b).map(|(x, y)| wrap_angle(x - y).powi(2)).sum::<f64>().sqrt()
}

/// Options of the Gauss-Newton solver and of [`ik`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IkOptions {
    /// Stop when the position error is at most this, metres (the paper's e_max, position part).
    pub tol_pos_m: f64,
    /// … and the rotation error (angle of R_target·R_currentᵀ) is at most this, radians.
    pub tol_rot_rad: f64,
    /// Gauss-Newton iterations from the seed.
    pub max_iters: usize,
    /// Gauss-Newton iterations when polishing a closed-form solution.
    pub polish_iters: usize,
    /// Largest joint change of one step (the whole step is scaled down to respect it), radians.
    /// `f64::INFINITY` gives the paper's plain full step.
    pub max_step_rad: f64,
    /// J is treated as invertible (step J⁻¹e by LU) when the smallest/largest |pivot| of its LU
    /// factorisation exceeds this; otherwise the SVD pseudo-inverse is used.
    pub min_pivot_ratio: f64,
    /// Singular values below `pinv_rcond · σ_max` are dropped in the pseudo-inverse.
    pub pinv_rcond: f64,
    /// Use the closed-form solutions (cold-start seeds, fallback and nearest-branch check).
    /// `false` gives the paper's Gauss-Newton alone (a seed is then required).
    pub use_analytic: bool,
    /// With a seed: run Gauss-Newton from the seed first and keep its answer unless a closed-form
    /// branch is nearer (`true`, the paper's warm start), or go straight to the closed-form
    /// branch nearest the seed and polish it, with Gauss-Newton from the seed only as fallback
    /// (`false`, same answers, faster). Ignored when `use_analytic` is false.
    pub gn_first: bool,
}

impl Default for IkOptions {
    fn default() -> Self {
        IkOptions {
            tol_pos_m: 1e-10,
            tol_rot_rad: 1e-10,
            max_iters: 30,
            polish_iters: 12,
            max_step_rad: 1.0,
            min_pivot_ratio: 1e-7,
            pinv_rcond: 1e-9,
            use_analytic: true,
            gn_first: true,
        }
    }
}

impl IkOptions {
    /// The defaults, with both tolerances (position, metres; rotation, radians) set to `tol` when
    /// it is given.
    ///
    /// # Errors
    /// [`KinError::NotPositive`] when `tol` is not a positive finite number.
    pub fn with_tol(tol: Option<f64>) -> Result<IkOptions, KinError> {
        let mut o = IkOptions::default();
        if let Some(t) = tol {
            if !(t.is_finite() && t > 0.0) {
                return Err(KinError::NotPositive { name: "tol", value: t });
            }
            (o.tol_pos_m, o.tol_rot_rad) = (t, t);
        }
        Ok(o)
    }

    /// [`IkOptions::with_tol`] for the paper's Gauss-Newton alone ([`crate::ik_gn`]): no
    /// closed-form start, no step limit, at most `max_iters` iterations.
    ///
    /// # Errors
    /// As [`IkOptions::with_tol`].
    pub fn gauss_newton(tol: Option<f64>, max_iters: usize) -> Result<IkOptions, KinError> {
        let o = IkOptions::with_tol(tol)?;
        Ok(IkOptions { max_iters, use_analytic: false, max_step_rad: f64::INFINITY, ..o })
    }
}

/// Pose error of `current` against `target` in the Base frame:
/// `[p_target − p_current; rotvec(R_target·R_currentᵀ)]`.
#[inline]
pub(crate) fn pose_error(target: &Frame, target_q: &UnitQuaternion<f64>, current: &Frame) -> Vector6<f64> {
    let dp = target.p - current.p;
    let qc = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(current.r));
    let qe = target_q * qc.inverse();
    let w = qe.w;
    let v = qe.imag();
    let (w, v) = if w < 0.0 { (-w, -v) } else { (w, v) };
    let vn = v.norm();
    let rv = if vn < 1e-300 { Vector3::zeros() } else { v * (2.0 * vn.atan2(w) / vn) };
    Vector6::new(dp.x, dp.y, dp.z, rv.x, rv.y, rv.z)
}

#[inline]
fn split_norms(e: &Vector6<f64>) -> (f64, f64) {
    (e.fixed_rows::<3>(0).norm(), e.fixed_rows::<3>(3).norm())
}

/// Position and rotation residual of `q` against `target`: (metres, radians).
pub fn pose_residual(model: &UrModel, q: &Joints, target: &Pose) -> (f64, f64) {
    let t = Frame::from_pose(target);
    split_norms(&pose_error(&t, &target.rotation, &fk_frame(model, q)))
}

/// Error of two poses: (distance between origins in metres, angle of the relative rotation).
pub fn pose_distance(a: &Pose, b: &Pose) -> (f64, f64) {
    ((a.translation.vector - b.translation.vector).norm(), a.rotation.angle_to(&b.rotation))
}

/// A validated target: rotation matrix, quaternion and translation.
struct Target {
    f: Frame,
    q: UnitQuaternion<f64>,
}

fn check_target(target: &Pose) -> Result<Target, KinError> {
    let p = target.translation.vector;
    let c = target.rotation.coords;
    if !(p.iter().all(|x| x.is_finite()) && c.iter().all(|x| x.is_finite())) {
        return Err(KinError::NonFinite("target pose"));
    }
    // A Pose can be built with an unnormalised quaternion (new_unchecked); renormalise it, and
    // refuse a zero or overflowing one.
    let n = c.norm();
    if !(n.is_finite() && n > 1e-12) {
        return Err(KinError::InvalidPose("rotation quaternion has zero or overflowing norm"));
    }
    let q = UnitQuaternion::new_normalize(target.rotation.into_inner());
    let r = q.to_rotation_matrix().into_inner();
    Ok(Target { f: Frame { r, p }, q })
}

/// Build a [`Pose`] from a homogeneous 4×4 matrix, checking that it is a rigid transform
/// (finite, last row 0 0 0 1 within 1e-9, rotation orthonormal within 1e-6 and det = +1).
/// The rotation is re-orthonormalised.
///
/// # Errors
/// [`KinError::NonFinite`] or [`KinError::InvalidPose`].
pub fn pose_from_matrix(m: &nalgebra::Matrix4<f64>) -> Result<Pose, KinError> {
    if !m.iter().all(|x| x.is_finite()) {
        return Err(KinError::NonFinite("pose matrix"));
    }
    let last = [m[(3, 0)], m[(3, 1)], m[(3, 2)], m[(3, 3)] - 1.0];
    if last.iter().any(|x| x.abs() > 1e-9) {
        return Err(KinError::InvalidPose("last row must be [0, 0, 0, 1]"));
    }
    let r: Matrix3<f64> = m.fixed_view::<3, 3>(0, 0).into_owned();
    let ortho = (r.transpose() * r - Matrix3::identity()).abs().max();
    if ortho.is_nan() || ortho > 1e-6 {
        return Err(KinError::InvalidPose("rotation block is not orthonormal (|RᵀR − I| > 1e-6)"));
    }
    if r.determinant() <= 0.0 {
        return Err(KinError::InvalidPose("rotation block has determinant −1 (a reflection)"));
    }
    let q = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r));
    let t = nalgebra::Translation3::new(m[(0, 3)], m[(1, 3)], m[(2, 3)]);
    Ok(Pose::from_parts(t, q))
}

/// One Gauss-Newton run. Returns the final (wrapped) q, iterations used, and final residuals.
fn gauss_newton(
    model: &UrModel,
    t: &Target,
    seed: &Joints,
    max_iters: usize,
    opts: &IkOptions,
) -> (Joints, usize, f64, f64, bool) {
    let mut q = wrap_joints(seed);
    let mut f = frames(model, &q);
    let mut e = pose_error(&t.f, &t.q, &f[6]);
    let (mut ep, mut er) = split_norms(&e);
    let mut best = (q, ep, er);
    for it in 0..max_iters {
        if ep <= opts.tol_pos_m && er <= opts.tol_rot_rad {
            return (q, it, ep, er, true);
        }
        let j = jacobian_from_frames(&f);
        let dq = solve_step(&j, &e, opts);
        let mut dq = match dq {
            Some(d) => d,
            None => break,
        };
        let m = dq.amax();
        if m > opts.max_step_rad {
            dq *= opts.max_step_rad / m;
        }
        for k in 0..6 {
            q[k] = wrap_angle(q[k] + dq[k]);
        }
        f = frames(model, &q);
        e = pose_error(&t.f, &t.q, &f[6]);
        (ep, er) = split_norms(&e);
        if ep + er < best.1 + best.2 {
            best = (q, ep, er);
        }
    }
    let ok = ep <= opts.tol_pos_m && er <= opts.tol_rot_rad;
    if ok {
        return (q, max_iters, ep, er, true);
    }
    (best.0, max_iters, best.1, best.2, false)
}

/// Δq = J⁻¹e when J is well conditioned (LU), else the SVD pseudo-inverse.
#[inline]
fn solve_step(j: &nalgebra::Matrix6<f64>, e: &Vector6<f64>, opts: &IkOptions) -> Option<Vector6<f64>> {
    let lu = j.lu();
    let u = lu.u();
    let d = u.diagonal().abs();
    let (dmin, dmax) = (d.min(), d.max());
    if dmax > 0.0 && dmin / dmax > opts.min_pivot_ratio {
        if let Some(x) = lu.solve(e) {
            if x.iter().all(|v| v.is_finite()) {
                return Some(x);
            }
        }
    }
    let svd = j.svd(true, true);
    let smax = svd.singular_values.max();
    if !(smax.is_finite() && smax > 0.0) {
        return None;
    }
    let x = svd.solve(e, opts.pinv_rcond * smax).ok()?;
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// The paper's inverse kinematics (Table 2) alone: Gauss-Newton on the angle-axis pose error
/// from `seed`, step J⁻¹e (pseudo-inverse when J is singular), angles wrapped to [−π, π] after
/// every step, stop when both error parts are within tolerance.
///
/// # Errors
/// [`KinError::NonFinite`], [`KinError::InvalidPose`], [`KinError::NotConverged`].
pub fn ik_gn(model: &UrModel, target: &Pose, seed: &Joints, opts: &IkOptions) -> Result<Joints, KinError> {
    let t = check_target(target)?;
    if !seed.iter().all(|x| x.is_finite()) {
        return Err(KinError::NonFinite("seed"));
    }
    let (q, iters, ep, er, ok) = gauss_newton(model, &t, seed, opts.max_iters, opts);
    if ok { Ok(q) } else { Err(KinError::NotConverged { iters, pos_residual_m: ep, rot_residual_rad: er }) }
}

/// Below this |sin q5| the wrist is treated as singular and q6 is taken from the reference.
const WRIST_SINGULAR: f64 = 1e-10;

/// Raw closed-form solutions (not verified), plus the reason when there are none.
/// Follows the classic UR decomposition (q1 from the wrist-2 origin, q5 from the approach axis,
/// q6 from the base-side axis seen in the tool frame, then the planar 3R chain for q2, q3, q4).
fn analytic_raw(model: &UrModel, t: &Frame, q6_ref: f64, out: &mut Vec<Joints>) -> Option<&'static str> {
    out.clear();
    let (d4, d6) = (model.d4, model.d6);
    let (a2, a3) = (model.a2, model.a3);
    let r = &t.r;
    let (n, o, a) = (r.column(0), r.column(1), r.column(2));
    let p5 = t.p - a * d6;
    let rxy = p5.x.hypot(p5.y);
    // p5 · z1 = d4 with z1 = (s1, −c1, 0): the wrist-2 origin lies on a cylinder of radius |d4|.
    if rxy < d4.abs() * (1.0 - 1e-12) - 1e-12 {
        return Some("the wrist lies inside the shoulder offset cylinder (|p5_xy| < d4)");
    }
    let ratio = if rxy > 0.0 { (d4 / rxy).clamp(-1.0, 1.0) } else { 1.0 };
    let phi = p5.y.atan2(p5.x);
    let asn = ratio.asin();
    let mut elbow_fail = false;
    for q1 in [phi + asn, phi + PI - asn] {
        let (s1, c1) = q1.sin_cos();
        let c5 = s1 * a.x - c1 * a.y;
        let s5abs = a.z.hypot(a.x * c1 + a.y * s1);
        let q5a = s5abs.atan2(c5);
        for q5 in [q5a, -q5a] {
            let s5 = q5.sin();
            // Planar 3R sub-problem for given q1, q5, q6: the frame-4 origin (x, y) in frame 1 and
            // q2 + q3 + q4. T14 = T01⁻¹ · T06 · (T45·T56)⁻¹.
            let planar = |q6: f64| {
                let t46 = dh_frame(model, 4, q5).mul(&dh_frame(model, 5, q6));
                let t14 = dh_frame(model, 0, q1).inverse().mul(&t.mul(&t46.inverse()));
                (t14.p.x, t14.p.y, t14.r[(1, 0)].atan2(t14.r[(0, 0)]))
            };
            let cos3 = |x: f64, y: f64| (x * x + y * y - a2 * a2 - a3 * a3) / (2.0 * a2 * a3);
            let (q6, (x, y, q234)) = if s5.abs() < WRIST_SINGULAR {
                // Wrist singular: joints 2, 3, 4 and 6 are parallel and only their combination is
                // fixed. Take q6 from the reference unless that leaves the elbow out of range; then
                // take the q6 that brings frame 4 nearest to (c3 > 1) or farthest from (c3 < −1)
                // the shoulder. The frame-4 origin moves on a circle C + A·cos q6 + B·sin q6.
                let pr = planar(q6_ref);
                let c = cos3(pr.0, pr.1);
                if c.abs() <= 1.0 {
                    (q6_ref, pr)
                } else {
                    let (p0, pp, ph) = (planar(0.0), planar(PI), planar(FRAC_PI_2));
                    let cx = 0.5 * (p0.0 + pp.0);
                    let cy = 0.5 * (p0.1 + pp.1);
                    let (ax, ay) = (p0.0 - cx, p0.1 - cy);
                    let (bx, by) = (ph.0 - cx, ph.1 - cy);
                    let far = (cx * bx + cy * by).atan2(cx * ax + cy * ay);
                    let q6 = wrap_angle(if c > 1.0 { far + PI } else { far });
                    (q6, planar(q6))
                }
            } else {
                let zn = s1 * n.x - c1 * n.y;
                let zo = s1 * o.x - c1 * o.y;
                let sg = s5.signum();
                let q6 = (-zo * sg).atan2(zn * sg);
                (q6, planar(q6))
            };
            let c3 = cos3(x, y);
            if !c3.is_finite() || c3.abs() > 1.0 + 1e-9 {
                elbow_fail = true;
                continue;
            }
            let c3 = c3.clamp(-1.0, 1.0);
            let s3abs = (1.0 - c3 * c3).max(0.0).sqrt();
            for s3 in [s3abs, -s3abs] {
                let q3 = s3.atan2(c3);
                let q2 = y.atan2(x) - (a3 * s3).atan2(a2 + a3 * c3);
                let q4 = q234 - q2 - q3;
                out.push(wrap_joints(&[q1, q2, q3, q4, q5, q6]));
                if s3abs == 0.0 {
                    break;
                }
            }
        }
    }
    if out.is_empty() {
        return Some(if elbow_fail {
            "the wrist is out of the elbow's range (|cos q3| > 1)"
        } else {
            "no closed-form solution"
        });
    }
    None
}

/// Every closed-form solution (up to 8) that reproduces `target`, each wrapped to [−π, π] and
/// polished by a few Gauss-Newton steps to the default tolerance (1e-10 m / rad). At a wrist
/// singularity (sin q5 ≈ 0) q6 is set to 0; see [`ik_all_with_q6`]. Unreachable → empty.
/// Near-duplicates (branches that coincide at a singularity) are reported once.
pub fn ik_all(model: &UrModel, target: &Pose) -> Vec<Joints> {
    ik_all_with_q6(model, target, 0.0)
}

/// [`ik_all`] with the q6 to use when the wrist is singular (sin q5 ≈ 0, only q4 + q6 matters).
pub fn ik_all_with_q6(model: &UrModel, target: &Pose, q6_ref: f64) -> Vec<Joints> {
    let Ok(t) = check_target(target) else { return Vec::new() };
    let q6_ref = wrap_angle(q6_ref);
    let opts = IkOptions::default();
    let mut raw = Vec::with_capacity(8);
    analytic_raw(model, &t.f, q6_ref, &mut raw);
    let mut out: Vec<Joints> = Vec::with_capacity(raw.len());
    for s in raw {
        let (q, _, _, _, ok) = gauss_newton(model, &t, &s, opts.polish_iters, &opts);
        if ok && !out.iter().any(|o| joint_distance(o, &q) < 1e-7) {
            out.push(q);
        }
    }
    out
}

/// Inverse kinematics returning the solution nearest `seed` (module docs give the strategy).
/// The result is wrapped to [−π, π] and reproduces `target` to `opts.tol_pos_m` /
/// `opts.tol_rot_rad`.
///
/// # Errors
/// - [`KinError::NonFinite`]: a NaN/∞ in the target or the seed;
/// - [`KinError::InvalidPose`]: a zero/overflowing rotation quaternion;
/// - [`KinError::Unreachable`]: no configuration reaches the target;
/// - [`KinError::NotConverged`]: candidates existed but none converged (residuals reported).
pub fn ik(
    model: &UrModel,
    target: &Pose,
    seed: Option<&Joints>,
    opts: &IkOptions,
) -> Result<Joints, KinError> {
    let t = check_target(target)?;
    if let Some(s) = seed {
        if !s.iter().all(|x| x.is_finite()) {
            return Err(KinError::NonFinite("seed"));
        }
    }
    let shoulder = Vector3::new(0.0, 0.0, model.d1);
    if (t.f.p - shoulder).norm() > model.reach() + 1e-9 {
        return Err(KinError::Unreachable { reason: "farther from the shoulder than the arm's reach" });
    }
    let reference = seed.map(wrap_joints).unwrap_or([0.0; 6]);
    let mut iters_total = 0;
    let mut best_res = (f64::INFINITY, f64::INFINITY);
    let mut gn_solution: Option<(Joints, f64)> = None;
    let gn_first = opts.gn_first || !opts.use_analytic;
    if let (Some(s), true) = (seed, gn_first) {
        let (q, it, ep, er, ok) = gauss_newton(model, &t, s, opts.max_iters, opts);
        iters_total += it;
        if ok {
            gn_solution = Some((q, joint_distance(&q, &reference)));
        } else if ep + er < best_res.0 + best_res.1 {
            best_res = (ep, er);
        }
    }
    if !opts.use_analytic {
        return match gn_solution {
            Some((q, _)) => Ok(q),
            None if seed.is_none() => Err(KinError::NotConverged {
                iters: 0,
                pos_residual_m: f64::INFINITY,
                rot_residual_rad: f64::INFINITY,
            }),
            None => Err(KinError::NotConverged {
                iters: iters_total,
                pos_residual_m: best_res.0,
                rot_residual_rad: best_res.1,
            }),
        };
    }
    let mut raw: Vec<Joints> = Vec::with_capacity(8);
    let reason = analytic_raw(model, &t.f, reference[5], &mut raw);
    let mut cands: Vec<(f64, Joints)> = raw.iter().map(|s| (joint_distance(s, &reference), *s)).collect();
    cands.sort_by(|a, b| a.0.total_cmp(&b.0));
    for (dist, s) in &cands {
        if let Some((q, gd)) = gn_solution {
            // Keep the Gauss-Newton answer unless a closed-form branch is clearly nearer.
            if *dist >= gd - 1e-9 {
                return Ok(q);
            }
        }
        let (q, it, ep, er, ok) = gauss_newton(model, &t, s, opts.polish_iters, opts);
        iters_total += it;
        if ok {
            return Ok(q);
        }
        if ep + er < best_res.0 + best_res.1 {
            best_res = (ep, er);
        }
    }
    if let Some((q, _)) = gn_solution {
        return Ok(q);
    }
    if let (Some(s), false) = (seed, gn_first) {
        let (q, it, ep, er, ok) = gauss_newton(model, &t, s, opts.max_iters, opts);
        iters_total += it;
        if ok {
            return Ok(q);
        }
        if ep + er < best_res.0 + best_res.1 {
            best_res = (ep, er);
        }
    }
    if cands.is_empty() && best_res.0 > 1e-6 {
        return Err(KinError::Unreachable { reason: reason.unwrap_or("no closed-form solution") });
    }
    Err(KinError::NotConverged {
        iters: iters_total,
        pos_residual_m: best_res.0,
        rot_residual_rad: best_res.1,
    })
}

/// [`ik`] over many targets, split into contiguous chunks over `threads` scoped threads
/// (`0` = the machine's available parallelism). `seeds`, when given, pairs with `targets` by
/// index; a missing entry (a shorter slice) means "no seed" and extra entries are ignored.
pub fn ik_batch(
    model: &UrModel,
    targets: &[Pose],
    seeds: Option<&[Joints]>,
    opts: &IkOptions,
    threads: usize,
) -> Vec<Result<Joints, KinError>> {
    let n = targets.len();
    let threads = if threads == 0 {
        std::thread::available_parallelism().map(|x| x.get()).unwrap_or(1)
    } else {
        threads
    };
    let threads = threads.clamp(1, n.max(1));
    let solve = |i: usize| ik(model, &targets[i], seeds.and_then(|s| s.get(i)), opts);
    if threads == 1 || n < 64 {
        return (0..n).map(solve).collect();
    }
    let chunk = n.div_ceil(threads);
    let mut out: Vec<Result<Joints, KinError>> = Vec::with_capacity(n);
    std::thread::scope(|sc| {
        let handles: Vec<_> = (0..threads)
            .map(|k| {
                let lo = (k * chunk).min(n);
                let hi = ((k + 1) * chunk).min(n);
                sc.spawn(move || (lo..hi).map(solve).collect::<Vec<_>>())
            })
            .collect();
        for h in handles {
            match h.join() {
                Ok(v) => out.extend(v),
                // ik never panics; should a thread die anyway, report its share as errors.
                Err(_) => out.extend(std::iter::repeat_n(
                    Err(KinError::NotConverged {
                        iters: 0,
                        pos_residual_m: f64::INFINITY,
                        rot_residual_rad: f64::INFINITY,
                    }),
                    chunk,
                )),
            }
        }
    });
    out.truncate(n);
    out
}
