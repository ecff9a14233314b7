//! The loop's numerics over wide inputs: the wrap, the One Euro filter (the action the loop
//! sends is tile-sim's `action::action_toward`, tested there).

use proptest::prelude::*;
use std::f64::consts::PI;
use teleop_core::{OneEuro, wrap_to_pi};

proptest! {
    #![proptest_config(ProptestConfig::with_cases(500))]

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
