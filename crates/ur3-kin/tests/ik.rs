//! IK, Jacobian and wrap properties over every model.

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};
use proptest::prelude::*;
use std::f64::consts::PI;
use ur3_kin::{
    IkOptions, Joints, KinError, MODELS, Pose, UR3, UrModel, fk, ik, ik_all, ik_all_with_q6, ik_batch, ik_gn,
    jacobian, joint_distance, pose_distance, pose_from_matrix, wrap_angle,
};

const TOL: f64 = 1e-6;

fn in_range(q: &Joints) -> bool {
    q.iter().all(|x| (-PI..=PI).contains(x))
}

fn assert_reproduces(m: &UrModel, q: &Joints, target: &Pose) -> Result<(), TestCaseError> {
    let (dp, da) = pose_distance(&fk(m, q), target);
    prop_assert!(dp < TOL && da < TOL, "{}: residual {dp:e} m {da:e} rad at {q:?}", m.name);
    prop_assert!(in_range(q), "{q:?} not wrapped");
    Ok(())
}

fn angles() -> impl Strategy<Value = Joints> {
    prop::array::uniform6(-PI..PI)
}

fn model() -> impl Strategy<Value = UrModel> {
    prop::sample::select(MODELS.to_vec())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(4000))]

    /// Random q → FK → cold IK → FK reproduces the pose, every model in every case.
    #[test]
    fn cold_round_trip(q in angles()) {
        for m in MODELS {
            let t = fk(&m, &q);
            let s = ik(&m, &t, None, &IkOptions::default());
            prop_assert!(s.is_ok(), "{}: {:?} for q {:?}", m.name, s, q);
            assert_reproduces(&m, &s.unwrap(), &t)?;
        }
    }

    /// Warm start near the true q: the answer reproduces the pose and is no farther from the seed
    /// than the true q (ik returns the solution nearest the seed). Every model in every case.
    #[test]
    fn warm_round_trip_is_nearest(q in angles(), noise in prop::array::uniform6(-0.3..0.3f64)) {
        for m in MODELS {
            let t = fk(&m, &q);
            let seed: Joints = std::array::from_fn(|k| q[k] + noise[k]);
            let s = ik(&m, &t, Some(&seed), &IkOptions::default())
                .map_err(|e| TestCaseError::fail(format!("{}: {e}", m.name)))?;
            assert_reproduces(&m, &s, &t)?;
            prop_assert!(joint_distance(&s, &seed) <= joint_distance(&q, &seed) + 1e-6,
                "{}: returned {:?} farther from seed than the true {:?}", m.name, s, q);
        }
    }

    /// Every closed-form solution reproduces the target, and the true q is among them.
    #[test]
    fn every_analytic_solution_reproduces(m in model(), q in angles()) {
        let t = fk(&m, &q);
        let sols = ik_all_with_q6(&m, &t, q[5]);
        prop_assert!(!sols.is_empty() && sols.len() <= 8, "{} solutions", sols.len());
        for s in &sols {
            assert_reproduces(&m, s, &t)?;
        }
        let nearest = sols.iter().map(|s| joint_distance(s, &q)).fold(f64::INFINITY, f64::min);
        prop_assert!(nearest < 1e-6, "true q not among the {} solutions (nearest {nearest:e})", sols.len());
        // ik_all (q6 = 0 at singularities) also reproduces.
        for s in ik_all(&m, &t) {
            assert_reproduces(&m, &s, &t)?;
        }
    }

    /// Singular configurations (q5 = 0, q3 = 0, both; the wrist on the shoulder's boundary) give a
    /// valid answer or a typed error, never a panic or a NaN.
    #[test]
    fn singular_poses(m in model(), q in angles(), kind in 0..4usize, seeded in any::<bool>()) {
        let mut q = q;
        match kind {
            0 => q[4] = 0.0,
            1 => q[2] = 0.0,
            2 => { q[2] = 0.0; q[4] = 0.0; }
            _ => q[4] = PI,
        }
        let t = fk(&m, &q);
        let seed = seeded.then_some(q.map(|x| x + 0.05));
        match ik(&m, &t, seed.as_ref(), &IkOptions::default()) {
            Ok(s) => assert_reproduces(&m, &s, &t)?,
            Err(KinError::NotConverged { pos_residual_m, rot_residual_rad, .. }) => {
                prop_assert!(!pos_residual_m.is_nan() && !rot_residual_rad.is_nan());
            }
            Err(e) => prop_assert!(false, "unexpected error {e}"),
        }
        for s in ik_all(&m, &t) {
            assert_reproduces(&m, &s, &t)?;
        }
    }

    /// Any finite (even huge, even non-unit-quaternion) pose and seed: no panic; Ok is finite,
    /// wrapped and reproduces the (normalised) target.
    #[test]
    fn arbitrary_finite_inputs_never_panic(
        p in prop::array::uniform3(prop_oneof![-2.0..2.0f64, prop::num::f64::NORMAL, Just(0.0)]),
        c in prop::array::uniform4(prop_oneof![-1.0..1.0f64, prop::num::f64::NORMAL, Just(0.0)]),
        seed in prop::option::of(prop::array::uniform6(prop_oneof![-10.0..10.0f64, prop::num::f64::NORMAL])),
    ) {
        let rot = UnitQuaternion::new_unchecked(Quaternion::new(c[0], c[1], c[2], c[3]));
        let t = Isometry3::from_parts(Translation3::new(p[0], p[1], p[2]), rot);
        let m = UR3;
        match ik(&m, &t, seed.as_ref(), &IkOptions::default()) {
            Ok(s) => {
                prop_assert!(s.iter().all(|x| x.is_finite()));
                let n = Isometry3::from_parts(t.translation, UnitQuaternion::new_normalize(rot.into_inner()));
                assert_reproduces(&m, &s, &n)?;
            }
            Err(KinError::Unreachable { .. } | KinError::InvalidPose(_)) => {}
            Err(KinError::NotConverged { pos_residual_m, rot_residual_rad, .. }) => {
                prop_assert!(!pos_residual_m.is_nan() && !rot_residual_rad.is_nan());
            }
            Err(e) => prop_assert!(false, "unexpected error {e}"),
        }
        for s in ik_all(&m, &t) {
            prop_assert!(in_range(&s));
        }
        // The 4×4 entry point validates instead of guessing.
        let mut mat = nalgebra::Matrix4::<f64>::identity();
        mat[(0, 0)] = c[0];
        mat[(0, 3)] = p[0];
        let _ = pose_from_matrix(&mat);
    }

    /// Jacobian against central finite differences of FK (linear and angular part).
    #[test]
    fn jacobian_matches_finite_differences(m in model(), q in angles()) {
        let j = jacobian(&m, &q);
        let h = 1e-6;
        for i in 0..6 {
            let mut qp = q; qp[i] += h;
            let mut qm = q; qm[i] -= h;
            let (tp, tm) = (fk(&m, &qp), fk(&m, &qm));
            let dv = (tp.translation.vector - tm.translation.vector) / (2.0 * h);
            let dw = (tp.rotation * tm.rotation.inverse()).scaled_axis() / (2.0 * h);
            for r in 0..3 {
                prop_assert!((j[(r, i)] - dv[r]).abs() < 1e-6, "{} J[{r},{i}]", m.name);
                prop_assert!((j[(r + 3, i)] - dw[r]).abs() < 1e-6, "{} J[{},{i}]", m.name, r + 3);
            }
        }
    }

    /// wrap keeps FK and lands in [−π, π].
    #[test]
    fn wrap_preserves_fk(m in model(), q in prop::array::uniform6(-50.0..50.0f64)) {
        let w = q.map(wrap_angle);
        prop_assert!(in_range(&w));
        let (dp, da) = pose_distance(&fk(&m, &q), &fk(&m, &w));
        prop_assert!(dp < 1e-12 && da < 1e-12);
    }
}

#[test]
fn wrap_edge_values() {
    for x in [PI, -PI, 3.0 * PI, -3.0 * PI, 1e300, -1e300, f64::MAX, f64::MIN, 0.0, -0.0] {
        let w = wrap_angle(x);
        assert!((-PI..=PI).contains(&w), "{x} -> {w}");
    }
    assert!((wrap_angle(2.0 * PI + 0.5) - 0.5).abs() < 1e-12);
    assert!((wrap_angle(-2.0 * PI - 0.5) + 0.5).abs() < 1e-12);
}

#[test]
fn shoulder_singularity_and_base_axis() {
    // Wrist-2 origin exactly on the shoulder-offset cylinder (|p5_xy| = d4): both q1 branches
    // coincide. Build it: choose q with the wrist centre placed so, by searching q2.
    for m in MODELS {
        // Tool0 placed on the base axis, tool pointing up: p5 = (0, 0, z) lies inside the cylinder
        // of radius d4 → unreachable by geometry.
        let t = Isometry3::from_parts(Translation3::new(0.0, 0.0, m.d1 + 0.1), UnitQuaternion::identity());
        match ik(&m, &t, None, &IkOptions::default()) {
            Err(KinError::Unreachable { reason }) => assert!(reason.contains("cylinder"), "{reason}"),
            other => panic!("{}: expected Unreachable, got {other:?}", m.name),
        }
        assert!(ik_all(&m, &t).is_empty());
        // Wrist centre on the base axis is reachable when the tool is horizontal: tool0 origin on
        // the axis, approach axis horizontal; whatever ik says, it must be consistent.
        let rot = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), PI / 2.0);
        let t = Isometry3::from_parts(Translation3::new(0.0, 0.0, m.d1), rot);
        match ik(&m, &t, None, &IkOptions::default()) {
            Ok(s) => {
                let (dp, da) = pose_distance(&fk(&m, &s), &t);
                assert!(dp < TOL && da < TOL);
            }
            Err(KinError::Unreachable { .. } | KinError::NotConverged { .. }) => {}
            Err(e) => panic!("{e}"),
        }
        // Shoulder singularity: the wrist-2 origin p5 exactly on the cylinder |p5_xy| = d4 (the
        // two q1 branches coincide, the wrist point sits straight above/below the shoulder in
        // the arm plane). p5 = d4·z1 + (0, 0, d1 + h), z1 = (sin q1, −cos q1, 0).
        let mut ok = 0;
        for k in 0..40 {
            let kf = k as f64;
            let q1 = kf * 0.7 - 3.0;
            let h = 0.3 * (m.a2.abs() + m.a3.abs()) * (kf * 0.3).sin();
            let p5 = Vector3::new(m.d4 * q1.sin(), -m.d4 * q1.cos(), m.d1 + h);
            let rot = UnitQuaternion::from_scaled_axis(Vector3::new(kf.sin(), (2.0 * kf).cos(), 0.5) * 2.0);
            let a = rot * Vector3::z();
            let t = Isometry3::from_parts(Translation3::from(p5 + a * m.d6), rot);
            match ik(&m, &t, None, &IkOptions::default()) {
                Ok(s) => {
                    let (dp, da) = pose_distance(&fk(&m, &s), &t);
                    assert!(dp < TOL && da < TOL, "{} k={k}: {dp} {da}", m.name);
                    ok += 1;
                }
                Err(KinError::Unreachable { .. } | KinError::NotConverged { .. }) => {}
                Err(e) => panic!("{e}"),
            }
            for s in ik_all(&m, &t) {
                let (dp, da) = pose_distance(&fk(&m, &s), &t);
                assert!(dp < TOL && da < TOL);
            }
        }
        eprintln!("{}: {ok}/40 shoulder-singular targets solved", m.name);
        assert_eq!(ok, 40, "{}: only {ok}/40 shoulder-singular targets solved", m.name);
    }
}

#[test]
fn unreachable_targets() {
    for m in MODELS {
        for dir in [Vector3::x(), -Vector3::y(), Vector3::new(1.0, 1.0, 1.0).normalize(), Vector3::z()] {
            for extra in [0.01, 0.5, 1e6, 1e300] {
                let p = Vector3::new(0.0, 0.0, m.d1) + dir * (m.reach() + extra);
                let t = Isometry3::from_parts(Translation3::from(p), UnitQuaternion::identity());
                assert!(
                    matches!(ik(&m, &t, None, &IkOptions::default()), Err(KinError::Unreachable { .. })),
                    "{} at {p:?}",
                    m.name
                );
                assert!(matches!(
                    ik(&m, &t, Some(&[0.1; 6]), &IkOptions::default()),
                    Err(KinError::Unreachable { .. })
                ));
                assert!(ik_all(&m, &t).is_empty());
            }
        }
    }
    // UR3: a point 0.55 m from the shoulder (> 0.5 m) is out of reach in any orientation.
    let t = Isometry3::from_parts(Translation3::new(0.55, 0.0, UR3.d1), UnitQuaternion::identity());
    assert!(matches!(ik(&UR3, &t, None, &IkOptions::default()), Err(KinError::Unreachable { .. })));
}

#[test]
fn non_finite_inputs_are_typed_errors() {
    let good = fk(&UR3, &[0.1, -1.0, 1.0, 0.2, 0.3, 0.4]);
    let mut bad = good;
    bad.translation.vector.x = f64::NAN;
    assert!(matches!(ik(&UR3, &bad, None, &IkOptions::default()), Err(KinError::NonFinite(_))));
    bad.translation.vector.x = f64::INFINITY;
    assert!(matches!(ik(&UR3, &bad, None, &IkOptions::default()), Err(KinError::NonFinite(_))));
    let seed = [0.0, f64::NAN, 0.0, 0.0, 0.0, 0.0];
    assert!(matches!(ik(&UR3, &good, Some(&seed), &IkOptions::default()), Err(KinError::NonFinite(_))));
    assert!(matches!(ik_gn(&UR3, &good, &seed, &IkOptions::default()), Err(KinError::NonFinite(_))));
    let zero_rot = Isometry3::from_parts(
        good.translation,
        UnitQuaternion::new_unchecked(Quaternion::new(0.0, 0.0, 0.0, 0.0)),
    );
    assert!(matches!(ik(&UR3, &zero_rot, None, &IkOptions::default()), Err(KinError::InvalidPose(_))));
}

#[test]
fn pose_from_matrix_validates() {
    let q = [0.3, -0.7, 1.2, -0.4, 0.9, 2.5];
    let m = fk(&UR3, &q).to_homogeneous();
    let p = pose_from_matrix(&m).unwrap();
    let (dp, da) = pose_distance(&p, &fk(&UR3, &q));
    assert!(dp < 1e-15 && da < 1e-12);
    let mut refl = m;
    refl.set_column(0, &(-m.column(0)));
    assert!(matches!(pose_from_matrix(&refl), Err(KinError::InvalidPose(_))));
    let mut scaled = m;
    scaled[(0, 0)] *= 1.01;
    assert!(matches!(pose_from_matrix(&scaled), Err(KinError::InvalidPose(_))));
    let mut row = m;
    row[(3, 0)] = 0.5;
    assert!(matches!(pose_from_matrix(&row), Err(KinError::InvalidPose(_))));
    let mut nan = m;
    nan[(1, 3)] = f64::NAN;
    assert!(matches!(pose_from_matrix(&nan), Err(KinError::NonFinite(_))));
}

#[test]
fn paper_gauss_newton_alone_converges_from_warm_seed() {
    let opts = IkOptions { use_analytic: false, ..IkOptions::default() };
    let q = [0.4, -1.2, 1.0, -1.3, -1.5, 0.2];
    let t = fk(&UR3, &q);
    let seed = q.map(|x| x + 0.1);
    let s = ik_gn(&UR3, &t, &seed, &opts).unwrap();
    assert!(joint_distance(&s, &q) < 1e-8);
    // Without the closed form and without a seed there is nothing to start from.
    assert!(matches!(ik(&UR3, &t, None, &opts), Err(KinError::NotConverged { .. })));
    // A GN run that cannot converge in 1 iteration reports its residual.
    let one = IkOptions { max_iters: 1, ..opts };
    match ik_gn(&UR3, &t, &[0.0; 6], &one) {
        Err(KinError::NotConverged { iters, pos_residual_m, .. }) => {
            assert_eq!(iters, 1);
            assert!(pos_residual_m > 1e-6 && pos_residual_m.is_finite());
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn batch_equals_single() {
    let qs: Vec<Joints> = (0..300)
        .map(|i| {
            let f = i as f64;
            [
                (f * 0.37).sin() * 3.0,
                (f * 0.11).cos() * 3.0,
                (f * 0.23).sin() * 3.0,
                f.cos() * 3.0,
                (f * 0.5).sin() * 3.0,
                (f * 0.7).cos() * 3.0,
            ]
        })
        .collect();
    let mut targets: Vec<Pose> = qs.iter().map(|q| fk(&UR3, q)).collect();
    targets.push(Isometry3::translation(5.0, 0.0, 0.0)); // unreachable entry
    let opts = IkOptions::default();
    let seeds: Vec<Joints> = qs.iter().map(|q| q.map(|x| x + 0.05)).collect();
    for th in [0, 1, 2, 3, 7] {
        let r = ik_batch(&UR3, &targets, None, &opts, th);
        assert_eq!(r.len(), targets.len());
        for (i, t) in targets.iter().enumerate() {
            assert_eq!(r[i], ik(&UR3, t, None, &opts), "entry {i}, {th} threads");
        }
        // Seeds shorter than targets: the last target goes unseeded.
        let rs = ik_batch(&UR3, &targets, Some(&seeds), &opts, th);
        for (i, t) in targets.iter().enumerate() {
            assert_eq!(rs[i], ik(&UR3, t, seeds.get(i), &opts));
        }
        assert!(matches!(r.last(), Some(Err(KinError::Unreachable { .. }))));
    }
    assert!(ik_batch(&UR3, &[], None, &opts, 2).is_empty());
}

#[test]
fn gn_first_and_closed_form_first_agree() {
    let closed_first = IkOptions { gn_first: false, ..IkOptions::default() };
    for m in MODELS {
        for k in 0..300 {
            let kf = k as f64;
            let q: Joints = std::array::from_fn(|j| ((kf + 1.0) * (j as f64 + 1.3)).sin() * 3.1);
            let seed: Joints = std::array::from_fn(|j| q[j] + 0.1 * (kf * 7.0 + j as f64).cos());
            let t = fk(&m, &q);
            let a = ik(&m, &t, Some(&seed), &IkOptions::default()).unwrap();
            let b = ik(&m, &t, Some(&seed), &closed_first).unwrap();
            assert!(joint_distance(&a, &b) < 1e-6, "{} k={k}: {a:?} vs {b:?}", m.name);
        }
    }
}

/// Completeness of the closed form: Gauss-Newton from many random seeds finds no solution that
/// `ik_all` does not list (and ik_all lists nothing GN cannot confirm: checked by reproduction).
#[test]
fn ik_all_is_complete_against_random_restarts() {
    let mut s: u64 = 0x1234_5678;
    let mut rnd = || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64 * 2.0 * PI - PI
    };
    let opts = IkOptions { use_analytic: false, max_iters: 200, ..IkOptions::default() };
    for m in [UR3, ur3_kin::UR10E] {
        let mut found_total = 0;
        for _ in 0..40 {
            let q: Joints = std::array::from_fn(|_| rnd());
            let t = fk(&m, &q);
            let all = ik_all(&m, &t);
            for _ in 0..100 {
                let seed: Joints = std::array::from_fn(|_| rnd());
                if let Ok(x) = ik_gn(&m, &t, &seed, &opts) {
                    found_total += 1;
                    assert!(
                        all.iter().any(|a| joint_distance(a, &x) < 1e-6),
                        "{}: GN found {x:?}, not among {all:?}",
                        m.name
                    );
                }
            }
        }
        assert!(found_total > 1000, "too few GN successes ({found_total}) for the check to mean anything");
    }
}

/// Singular configurations are not only survived but solved: at least 99% of them, every model.
#[test]
fn singular_poses_are_solved() {
    let mut s: u64 = 0xDEAD_BEEF;
    let mut rnd = || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64 * 2.0 * PI - PI
    };
    for m in MODELS {
        for kind in 0..4 {
            let (mut ok, n) = (0, 500);
            for _ in 0..n {
                let mut q: Joints = std::array::from_fn(|_| rnd());
                match kind {
                    0 => q[4] = 0.0,
                    1 => q[2] = 0.0,
                    2 => {
                        q[2] = 0.0;
                        q[4] = 0.0;
                    }
                    _ => q[4] = PI,
                }
                let t = fk(&m, &q);
                let seed = q.map(|x| x + 0.05);
                for sd in [None, Some(&seed)] {
                    if let Ok(s) = ik(&m, &t, sd, &IkOptions::default()) {
                        let (dp, da) = pose_distance(&fk(&m, &s), &t);
                        assert!(dp < TOL && da < TOL);
                        ok += 1;
                    }
                }
            }
            let n = 2 * n;
            eprintln!("{} kind {kind}: {ok}/{n}", m.name);
            assert!(ok * 100 >= n * 99, "{} singular kind {kind}: only {ok}/{n} solved", m.name);
        }
    }
}

#[test]
fn dh_table_and_gauss_newton_options() {
    for m in MODELS {
        let t = m.dh_table();
        let want = [("d1", m.d1), ("a2", m.a2), ("a3", m.a3), ("d4", m.d4), ("d5", m.d5), ("d6", m.d6)];
        assert_eq!(t.len(), 7);
        want.iter().for_each(|(k, v)| assert_eq!(t[k], *v));
        assert_eq!(t["reach"], m.reach());
    }
    let o = IkOptions::gauss_newton(Some(1e-7), 17).unwrap();
    assert_eq!((o.max_iters, o.use_analytic, o.tol_pos_m, o.tol_rot_rad), (17, false, 1e-7, 1e-7));
    assert!(o.max_step_rad.is_infinite());
    assert!(matches!(IkOptions::gauss_newton(Some(0.0), 5), Err(KinError::NotPositive { .. })));
}
