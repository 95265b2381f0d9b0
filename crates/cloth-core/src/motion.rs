//! Prescribed motions and the wind: where a moving pin or sphere is at time `t`, how fast it
//! goes, and how fast the gusting wind blows. Generic over the precision, with the operations in
//! the order the shaders use (`shaders/wgsl/common.wgsl`, `shaders/glsl/forces.glsl`).

use crate::real::{Real, Vec3};

/// A [`crate::scene::Motion`] in precision `R`: steady velocity (m/s), amplitude (m) and angular
/// frequency `ω = 2π f` (rad/s).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MotionOf<R> {
    /// Steady velocity, m/s.
    pub velocity: Vec3<R>,
    /// Amplitude of the oscillation, m.
    pub amplitude: Vec3<R>,
    /// Angular frequency, rad/s.
    pub omega: R,
}

impl<R: Real> MotionOf<R> {
    /// Converts a scene motion.
    pub fn of(m: &crate::scene::Motion) -> Self {
        Self {
            velocity: Vec3::from_f64(m.velocity),
            amplitude: Vec3::from_f64(m.amplitude),
            omega: R::of(m.angular_frequency()),
        }
    }

    /// Displacement `d(t) = velocity · t + amplitude · sin(ω t)`, m.
    pub fn displacement(&self, t: R) -> Vec3<R> {
        self.velocity * t + self.amplitude * (self.omega * t).sin()
    }

    /// Velocity `d'(t) = velocity + amplitude · ω cos(ω t)`, m/s.
    pub fn velocity_at(&self, t: R) -> Vec3<R> {
        self.velocity + self.amplitude * (self.omega * (self.omega * t).cos())
    }
}

/// The wind velocity at time `t`, m/s: `velocity · (1 + gust_amplitude · sin(gust_omega · t))`.
pub fn wind_velocity<R: Real>(velocity: Vec3<R>, gust_amplitude: R, gust_omega: R, t: R) -> Vec3<R> {
    velocity * (R::one() + gust_amplitude * (gust_omega * t).sin())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_motion_starts_at_rest_where_it_is_and_moves_as_given() {
        let m = MotionOf::<f64>::of(&crate::scene::Motion {
            velocity: [1.0, 0.0, 0.0],
            amplitude: [0.0, 0.5, 0.0],
            frequency: 0.25,
        });
        assert_eq!(m.displacement(0.0), Vec3::zero());
        let d = m.displacement(1.0); // a quarter period: the sine is 1
        assert!((d.x - 1.0).abs() < 1e-12 && (d.y - 0.5).abs() < 1e-12, "{d:?}");
        let v = m.velocity_at(0.0);
        assert!((v.y - 0.5 * 2.0 * std::f64::consts::PI * 0.25).abs() < 1e-12, "{v:?}");
    }
}
