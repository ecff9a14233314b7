//! The One Euro filter (Casiez, Roussel & Vogel, CHI 2012) on a fixed-size vector.
//!
//! A low-pass filter whose cutoff rises with the signal's speed: strong smoothing while the hand
//! is still (tracking jitter on knuckles 2 cm apart would shake the tool), little lag while it
//! moves. The arithmetic is written out term by term, in the order numpy evaluated it when this
//! filter lived in Python, so a hand log converts to the same bits as before.

use std::f64::consts::PI;

/// One Euro filter on `N` values sampled at irregular times.
#[derive(Debug, Clone, PartialEq)]
pub struct OneEuro<const N: usize> {
    /// Cutoff (Hz) while the signal is still.
    pub min_cutoff: f64,
    /// How fast the cutoff rises with the signal's speed (Hz per unit/s).
    pub beta: f64,
    /// Cutoff (Hz) of the speed estimate.
    pub d_cutoff: f64,
    state: Option<([f64; N], [f64; N], f64)>,
}

fn alpha(cutoff: f64, dt: f64) -> f64 {
    let tau = 1.0 / (2.0 * PI * cutoff);
    1.0 / (1.0 + tau / dt)
}

impl<const N: usize> OneEuro<N> {
    /// A filter with no sample yet.
    pub fn new(min_cutoff: f64, beta: f64, d_cutoff: f64) -> Self {
        OneEuro { min_cutoff, beta, d_cutoff, state: None }
    }

    /// Forget every sample: the next one passes unfiltered.
    pub fn reset(&mut self) {
        self.state = None;
    }

    /// Filter sample `x` taken at time `t` (s). The first sample, and one not after the previous
    /// (`t` ≤ the last time), restarts the filter at `x`.
    pub fn filter(&mut self, x: [f64; N], t: f64) -> [f64; N] {
        let Some((prev, dprev, t_prev)) = self.state.as_mut() else {
            self.state = Some((x, [0.0; N], t));
            return x;
        };
        if t <= *t_prev {
            self.state = Some((x, [0.0; N], t));
            return x;
        }
        let dt = t - *t_prev;
        let a_d = alpha(self.d_cutoff, dt);
        let mut sq = 0.0;
        for i in 0..N {
            let dx = (x[i] - prev[i]) / dt;
            dprev[i] = a_d * dx + (1.0 - a_d) * dprev[i];
            sq += dprev[i] * dprev[i];
        }
        let a = alpha(self.min_cutoff + self.beta * sq.sqrt(), dt);
        for i in 0..N {
            prev[i] = a * x[i] + (1.0 - a) * prev[i];
        }
        *t_prev = t;
        *prev
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_still_signal_stays_put_and_a_step_is_followed_gradually() {
        let mut f = OneEuro::<1>::new(1.0, 0.0, 1.0);
        assert_eq!(f.filter([0.0], 0.0), [0.0]);
        let mut y = 0.0;
        let mut last = 0.0;
        for k in 1..=90 {
            y = f.filter([1.0], k as f64 / 90.0)[0];
            assert!(y > last && y < 1.0, "step response must rise monotonically below 1: {y}");
            last = y;
        }
        // a 1 Hz first-order low pass after 1 s: 1 - exp(-2π) ≈ 0.998 in continuous time;
        // the discrete filter at 90 Hz gets within a percent of that
        assert!((y - (1.0 - (-2.0 * PI).exp())).abs() < 0.01, "{y}");
    }

    #[test]
    fn time_going_backwards_restarts_at_the_sample() {
        let mut f = OneEuro::<2>::new(1.0, 2.0, 1.0);
        f.filter([0.0, 0.0], 1.0);
        f.filter([1.0, 1.0], 1.1);
        assert_eq!(f.filter([5.0, -5.0], 1.05), [5.0, -5.0]);
        assert_eq!(f.filter([5.0, -5.0], 1.05), [5.0, -5.0]);
    }

    #[test]
    fn speed_raises_the_cutoff() {
        let step = |beta| {
            let mut f = OneEuro::<1>::new(1.0, beta, 1.0);
            f.filter([0.0], 0.0);
            f.filter([1.0], 0.1)[0]
        };
        assert!(step(10.0) > step(0.0));
    }
}
