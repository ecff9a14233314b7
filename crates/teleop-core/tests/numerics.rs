//! The loop's numerics over wide inputs: the joint action, the wrap, the One Euro filter.

use proptest::prelude::*;
use std::f64::consts::PI;
use teleop_core::{OneEuro, joint_action, wrap_to_pi};

proptest! {
    #![proptest_config(ProptestConfig::with_cases(500))]

    #[test]
    fn the_joint_action_takes_the_short_way_and_is_bounded(
        q in prop::array::uniform6(-PI..PI),
        dq in prop::array::uniform6(-10.0f64..10.0),
    ) {
        let target: [f64; 6] = std::array::from_fn(|i| q[i] + dq[i]);
        let a = joint_action(&target, &q, 0.04);
        for i in 0..6 {
            prop_assert!(a[i].abs() <= 1.0);
            let short = wrap_to_pi(dq[i]);
            prop_assert!((-PI..PI).contains(&short));
            if short.abs() < 0.04 {
                prop_assert!((a[i] - short / 0.04).abs() < 1e-6, "{} vs {}", a[i], short / 0.04);
            } else if (short.abs() - PI).abs() > 1e-9 {
                // half a turn either way is equally short: only then may the sign differ
                prop_assert_eq!(a[i].signum(), short.signum());
            }
        }
    }

    #[test]
    fn wrapping_moves_by_whole_turns_only(a in -1e4f64..1e4) {
        let w = wrap_to_pi(a);
        prop_assert!((-PI..PI).contains(&w));
        let turns = (a - w) / (2.0 * PI);
        prop_assert!((turns - turns.round()).abs() < 1e-9);
    }
}

/// A small deterministic generator (no dependency): uniform in [-1, 1).
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }
}

#[test]
fn one_euro_smooths_jitter_and_follows_motion() {
    let mut f = OneEuro::<3>::new(1.0, 2.0, 1.0);
    let mut rng = Lcg(7);
    let t = |k: usize| k as f64 / 90.0;
    // 5 s still with ±1 mm uniform jitter (std 0.577 mm): the output's spread is cut by > 4×
    let mut still = Vec::new();
    for k in 0..450 {
        let x = [0.1 + 0.001 * rng.next(), 0.2 + 0.001 * rng.next(), 0.3 + 0.001 * rng.next()];
        still.push(f.filter(x, t(k)));
    }
    for axis in 0..3 {
        let v: Vec<f64> = still[100..].iter().map(|p| p[axis]).collect();
        let mean = v.iter().sum::<f64>() / v.len() as f64;
        let sd = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / v.len() as f64).sqrt();
        assert!(sd < 0.25 * 0.000_577, "axis {axis}: spread {sd}");
    }
    // a 0.3 m/s move of 0.3 m: the output lags by at most 3 cm and catches up after it stops
    let mut lag: f64 = 0.0;
    let mut last = 0.0;
    for k in 450..900 {
        let m = ((t(k) - t(450)) * 0.3).min(0.3);
        let y = f.filter([0.1 + m, 0.2, 0.3], t(k));
        last = (y[0] - (0.1 + m)).abs();
        lag = lag.max(last);
    }
    assert!(lag < 0.03, "lag {lag}");
    assert!(last < 1e-3, "still behind after stopping: {last}");
}
