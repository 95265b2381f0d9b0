//! Prescribed motions and the wind: where a moving pin or collider is at time `t`, how fast it
//! goes, and how fast the gusting wind blows. Generic over the precision, with the operations in
//! the order the shaders use (`shaders/wgsl/common.wgsl`, `shaders/glsl/forces.glsl`).

use crate::effects::Effect;
use crate::real::{Real, Vec3};
use crate::scene::Motion;

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
    pub fn of(m: &Motion) -> Self {
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

impl crate::scene::Scene {
    /// Where collider `index`'s centre (its [`crate::colliders::Shape::anchor`]) is at simulated
    /// time `t_s` (s), m: moved by `d(t)` of its [`Motion`] when the scene has
    /// [`Effect::MovingColliders`]. What renderers draw; the solvers evaluate the same motion in
    /// their own precision.
    pub fn collider_offset_at(&self, index: usize, t_s: f64) -> [f64; 3] {
        let collider = &self.colliders[index];
        if !self.effects.contains(Effect::MovingColliders) {
            return [0.0; 3];
        }
        MotionOf::<f64>::of(&collider.motion).displacement(t_s).to_f64()
    }

    /// How far every pin has moved from its start at simulated time `t_s` (s), m: `d(t)` of
    /// `cloth.pin_motion` when the scene has [`Effect::MovingPins`], else zero.
    pub fn pin_displacement_at(&self, t_s: f64) -> [f64; 3] {
        if !self.effects.contains(Effect::MovingPins) {
            return [0.0; 3];
        }
        MotionOf::<f64>::of(&self.cloth.pin_motion).displacement(t_s).to_f64()
    }
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
