//! The dissertation's baseline: the incremental (velocity-form) PID of eq. 4.9.

use serde::{Deserialize, Serialize};

/// Gains of eq. 4.9, in command units per unit of error (V/mm on the twin). The dissertation set
/// (1.0, 0.8, 0.6) "by trial and error" without stating units; we read them as V per mm.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PidGains {
    pub kp: f64,
    pub ki: f64,
    pub kd: f64,
}

impl Default for PidGains {
    fn default() -> Self {
        PidGains {
            kp: 1.0,
            ki: 0.8,
            kd: 0.6,
        }
    }
}

/// `du(k) = kp [e(k) - e(k-1)] + ki e(k) + kd [e(k) - 2 e(k-1) + e(k-2)]`, `u(k) = u(k-1) +
/// du(k)`, with `e(-1) = e(-2) = 0` and `u(-1) = u0`. Only the last two errors and the last
/// command are kept, which is why the dissertation calls it easy to initialise.
#[derive(Debug, Clone, PartialEq)]
pub struct IncrementalPid {
    gains: PidGains,
    e1: f64,
    e2: f64,
    u: f64,
}

impl IncrementalPid {
    /// A controller at rest holding the command `u0`.
    pub fn new(gains: PidGains, u0: f64) -> Self {
        IncrementalPid {
            gains,
            e1: 0.0,
            e2: 0.0,
            u: u0,
        }
    }

    /// The increment `du(k)` for the error `e(k)`, without changing the state.
    pub fn increment(&self, e: f64) -> f64 {
        let g = &self.gains;
        g.kp * (e - self.e1) + g.ki * e + g.kd * (e - 2.0 * self.e1 + self.e2)
    }

    /// Takes the error `e(k)` and returns the command `u(k)`.
    pub fn step(&mut self, e: f64) -> f64 {
        self.u += self.increment(e);
        self.e2 = self.e1;
        self.e1 = e;
        self.u
    }

    /// The last command.
    pub fn command(&self) -> f64 {
        self.u
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn increments_match_hand_computed_values() {
        // Gains (1.0, 0.8, 0.6), errors 1, 0.5, -0.25, 0 from rest:
        //   du0 = 1(1 - 0) + 0.8(1) + 0.6(1 - 0 + 0)            = 2.4
        //   du1 = 1(0.5 - 1) + 0.8(0.5) + 0.6(0.5 - 2 + 0)      = -0.5 + 0.4 - 0.9 = -1.0
        //   du2 = 1(-0.25 - 0.5) + 0.8(-0.25) + 0.6(-0.25 - 1 + 1) = -0.75 - 0.2 - 0.15 = -1.1
        //   du3 = 1(0 + 0.25) + 0 + 0.6(0 + 0.5 + 0.5)          = 0.25 + 0.6 = 0.85
        let mut pid = IncrementalPid::new(PidGains::default(), 0.5);
        let want_du = [2.4, -1.0, -1.1, 0.85];
        let mut u = 0.5;
        for (e, du) in [1.0, 0.5, -0.25, 0.0].into_iter().zip(want_du) {
            assert!((pid.increment(e) - du).abs() < 1e-12, "e={e}");
            u += du;
            let got = pid.step(e);
            assert!((got - u).abs() < 1e-12, "e={e}: u {got} vs {u}");
        }
        assert!((pid.command() - (0.5 + 2.4 - 1.0 - 1.1 + 0.85)).abs() < 1e-12);
    }

    #[test]
    fn zero_error_holds_the_command() {
        let mut pid = IncrementalPid::new(PidGains::default(), 1.25);
        for _ in 0..5 {
            assert_eq!(pid.step(0.0), 1.25);
        }
    }

    #[test]
    fn constant_error_is_integrated() {
        // After the first two samples the P and D terms vanish: du = ki e.
        let g = PidGains {
            kp: 2.0,
            ki: 0.5,
            kd: 3.0,
        };
        let mut pid = IncrementalPid::new(g, 0.0);
        let u: Vec<f64> = (0..6).map(|_| pid.step(1.0)).collect();
        // du0 = 2 + 0.5 + 3 = 5.5; du1 = 0 + 0.5 + 3(1 - 2) = -2.5; then 0.5 each.
        let want = [5.5, 3.0, 3.5, 4.0, 4.5, 5.0];
        for (a, b) in u.iter().zip(want) {
            assert!((a - b).abs() < 1e-12, "{u:?}");
        }
    }
}
