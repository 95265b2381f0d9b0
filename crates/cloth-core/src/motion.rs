//! Prescribed motions and the wind: where a moving pin or collider is at time `t`, how fast it
//! goes, and how fast the gusting wind blows. Generic over the precision, with the operations in
//! the order the shaders use (`shaders/wgsl/common.wgsl`, `shaders/glsl/forces.glsl`).

use crate::effects::Effect;
use crate::real::{Real, Vec3};
use crate::scene::Motion;

/// A [`crate::scene::Motion`] in precision `R`: steady velocity (m/s), amplitude (m), angular
/// frequency `ω = 2π f` (rad/s), and the rotation's angular velocity (rad/s) and pivot (m).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MotionOf<R> {
    /// Steady velocity, m/s.
    pub velocity: Vec3<R>,
    /// Amplitude of the oscillation, m.
    pub amplitude: Vec3<R>,
    /// Angular frequency, rad/s.
    pub omega: R,
    /// Angular velocity of the rotation, rad/s (zero: the motion only translates).
    pub angular_velocity: Vec3<R>,
    /// Where the rotation's axis passes at `t = 0`, m.
    pub pivot: Vec3<R>,
}

impl<R: Real> MotionOf<R> {
    /// Converts a scene motion.
    pub fn of(m: &Motion) -> Self {
        Self {
            velocity: Vec3::from_f64(m.velocity),
            amplitude: Vec3::from_f64(m.amplitude),
            omega: R::of(m.angular_frequency()),
            angular_velocity: Vec3::from_f64(m.angular_velocity),
            pivot: Vec3::from_f64(m.pivot),
        }
    }

    fn turns(&self) -> bool {
        self.angular_velocity != Vec3::zero()
    }

    /// Where a point at `x` at time `from` is at time `to`, m: `x + d(to) − d(from)` for a
    /// translation; with a rotation, `p(to) + R(ω (to − from)) (x − p(from))`, `p(t) = pivot +
    /// d(t)` (the shaders' `pin_carry`, operation by operation).
    pub fn carry(&self, x: Vec3<R>, from: R, to: R) -> Vec3<R> {
        if !self.turns() {
            return x + (self.displacement(to) - self.displacement(from));
        }
        let p_from = self.pivot + self.displacement(from);
        let p_to = self.pivot + self.displacement(to);
        p_to + rotate(self.angular_velocity * (to - from), x - p_from)
    }

    /// The velocity of the point at `x` at time `t`, m/s: `d'(t)`, plus `ω × (x − p(t))` with a
    /// rotation (the shaders' `pin_velocity`).
    pub fn point_velocity(&self, x: Vec3<R>, t: R) -> Vec3<R> {
        let v = self.velocity_at(t);
        if !self.turns() {
            return v;
        }
        v + self.angular_velocity.cross(x - (self.pivot + self.displacement(t)))
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

/// The rotation of `v` by the angle `|θ|` about the axis `θ / |θ|` (Rodrigues):
/// `v cos|θ| + (k × v) sin|θ| + k (k · v)(1 − cos|θ|)`, `k = θ / |θ|`.
pub fn rotate<R: Real>(theta: Vec3<R>, v: Vec3<R>) -> Vec3<R> {
    let angle = theta.length();
    if angle == R::zero() {
        return v;
    }
    let k = theta * (R::one() / angle);
    let (sin, cos) = (angle.sin(), angle.cos());
    v * cos + k.cross(v) * sin + k * (k.dot(v) * (R::one() - cos))
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

    /// The motion of pin group `group` (0: `cloth.pin_motion`, `k + 1`: `cloth.pin_groups[k]`),
    /// or none for a group the scene does not have.
    pub fn pin_group_motion(&self, group: usize) -> Option<&Motion> {
        match group {
            0 => Some(&self.cloth.pin_motion),
            g => self.cloth.pin_groups.get(g - 1).map(|g| &g.motion),
        }
    }

    /// Where a pin of group `group` that started at `start` (m) is at simulated time `t_s` (s),
    /// m: carried by its group's motion when the scene has [`Effect::MovingPins`], else `start`.
    pub fn pin_position_at(&self, group: usize, start: [f64; 3], t_s: f64) -> [f64; 3] {
        match self.pin_group_motion(group).filter(|_| self.effects.contains(Effect::MovingPins)) {
            Some(m) => MotionOf::<f64>::of(m).carry(Vec3::from_f64(start), 0.0, t_s).to_f64(),
            None => start,
        }
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
            ..Default::default()
        });
        assert_eq!(m.displacement(0.0), Vec3::zero());
        let d = m.displacement(1.0); // a quarter period: the sine is 1
        assert!((d.x - 1.0).abs() < 1e-12 && (d.y - 0.5).abs() < 1e-12, "{d:?}");
        let v = m.velocity_at(0.0);
        assert!((v.y - 0.5 * 2.0 * std::f64::consts::PI * 0.25).abs() < 1e-12, "{v:?}");
    }

    #[test]
    fn a_turning_motion_carries_points_round_its_moving_pivot() {
        use std::f64::consts::PI;
        // A quarter turn a second about +y through (1, 0, 0), the pivot drifting along +z.
        let m = MotionOf::<f64>::of(&crate::scene::Motion {
            velocity: [0.0, 0.0, 0.5],
            angular_velocity: [0.0, PI / 2.0, 0.0],
            pivot: [1.0, 0.0, 0.0],
            ..Default::default()
        });
        // (2, 0, 0) is 1 m along +x from the pivot; a quarter turn about +y takes +x to −z.
        let x = m.carry(Vec3::new(2.0, 0.0, 0.0), 0.0, 1.0);
        assert!((x - Vec3::new(1.0, 0.0, -0.5)).length() < 1e-12, "{x:?}");
        // In steps it gets to the same place, and the distance to the pivot holds.
        let mut y = Vec3::new(2.0, 0.0, 0.0);
        for k in 0..100 {
            y = m.carry(y, k as f64 * 0.01, (k + 1) as f64 * 0.01);
        }
        assert!((y - x).length() < 1e-12, "{y:?}");
        // Its velocity: the drift plus ω × (x − p) = (0, π/2, 0) × (0, 0, −1) = (−π/2, 0, 0).
        let v = m.point_velocity(x, 1.0);
        assert!((v - Vec3::new(-PI / 2.0, 0.0, 0.5)).length() < 1e-12, "{v:?}");
        // Without a rotation, carry is the displacement's difference.
        let still = MotionOf::<f64>::of(&crate::scene::Motion { velocity: [1.0, 0.0, 0.0], ..Default::default() });
        assert_eq!(still.carry(Vec3::new(0.0, 1.0, 0.0), 0.0, 2.0), Vec3::new(2.0, 1.0, 0.0));
    }
}
